// The reference strip: a clamped strip [0, L] x [0, H] whose free end face ("tip", x = L)
// can strike a rigid wall x = L + gap ("wall", meshed as line elements only). The top and
// bottom edges are split at L − drive and L/2: "drive" is the top and bottom edges over the
// last `drive` metres (where the axial traction acts), "probe" the top edge's midpoint.
DefineConstant[
  L = {1.0, Name "Parameters/L"},
  H = {0.1, Name "Parameters/H"},
  gap = {1e-5, Name "Parameters/gap"},
  drive = {0.1, Name "Parameters/drive"},
  lc = {0.0125, Name "Parameters/lc"}
];
Point(1) = {0, 0, 0, lc};
Point(2) = {L/2, 0, 0, lc};
Point(3) = {L - drive, 0, 0, lc};
Point(4) = {L, 0, 0, lc};
Point(5) = {L, H, 0, lc};
Point(6) = {L - drive, H, 0, lc};
Point(7) = {L/2, H, 0, lc};
Point(8) = {0, H, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 7};
Line(7) = {7, 8};
Line(8) = {8, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6, 7, 8};
Plane Surface(1) = {1};
Point(10) = {L + gap, -H/2, 0, lc};
Point(11) = {L + gap, 1.5 * H, 0, lc};
Line(10) = {10, 11};
Physical Curve("clamp") = {8};
Physical Curve("tip") = {4};
Physical Curve("drive") = {3, 5};
Physical Curve("free") = {1, 2, 6, 7};
Physical Point("probe") = {7};
Physical Surface("body") = {1};
Physical Curve("wall") = {10};
