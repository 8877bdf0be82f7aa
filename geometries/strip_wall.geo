// A clamped strip [0, L] x [0, H] whose underside near the free end ("contact", the last
// contact_length of the bottom edge) can strike a rigid wall y = -gap, drawn as a separate
// curve ("wall", meshed as line elements only).
DefineConstant[
  L = {0.2, Name "Parameters/L"},
  H = {0.01, Name "Parameters/H"},
  contact_length = {0.02, Name "Parameters/contact_length"},
  gap = {2e-4, Name "Parameters/gap"},
  lc = {0.0025, Name "Parameters/lc"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {0, 0, 0, lc};
Point(2) = {L - contact_length, 0, 0, lc/2};
Point(3) = {L, 0, 0, lc/2};
Point(4) = {L, H, 0, lc};
Point(5) = {0, H, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 1};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
If (quads)
  Recombine Surface{1};
EndIf
Point(10) = {L - 2*contact_length, -gap, 0, lc/2};
Point(11) = {L + contact_length, -gap, 0, lc/2};
Line(10) = {10, 11};
Physical Curve("bottom") = {1};
Physical Curve("contact") = {2};
Physical Curve("tip") = {3};
Physical Curve("top") = {4};
Physical Curve("clamp") = {5};
Physical Point("probe") = {4};
Physical Surface("body") = {1};
Physical Curve("wall") = {10};
