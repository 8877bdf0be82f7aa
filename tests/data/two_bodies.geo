// tests/hard.rs: strip_wall.geo with a second, unconnected body (see the end).
// A clamped strip [0, L] x [0, H] whose free end face ("tip", x = L) can strike a rigid wall
// x = L + gap, drawn as a separate curve ("wall", meshed as line elements only). The top edge
// is split at L/2 so that a node ("probe") sits there.
DefineConstant[
  L = {0.2, Name "Parameters/L"},
  H = {0.01, Name "Parameters/H"},
  gap = {1e-7, Name "Parameters/gap"},
  lc = {0.00125, Name "Parameters/lc"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {0, 0, 0, lc};
Point(2) = {L, 0, 0, lc};
Point(3) = {L, H, 0, lc};
Point(4) = {L/2, H, 0, lc};
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
Point(10) = {L + gap, -H/2, 0, lc};
Point(11) = {L + gap, 1.5 * H, 0, lc};
Line(10) = {10, 11};
Physical Curve("bottom") = {1};
Physical Curve("tip") = {2};
Physical Curve("top") = {3, 4};
Physical Curve("clamp") = {5};
Physical Point("probe") = {4};
Physical Point("tip_corner") = {3};
Physical Surface("body") = {1};
Physical Curve("wall") = {10};
// A second body overlapping the strip's left half but sharing no node with it (issue #9:
// overlapping, unconnected bodies ran as if one).
Point(20) = {0.02, 0.002, 0, lc};
Point(21) = {0.1, 0.002, 0, lc};
Point(22) = {0.1, 0.008, 0, lc};
Point(23) = {0.02, 0.008, 0, lc};
Line(20) = {20, 21};
Line(21) = {21, 22};
Line(22) = {22, 23};
Line(23) = {23, 20};
Curve Loop(21) = {20, 21, 22, 23};
Plane Surface(21) = {21};
Physical Surface("second") = {21};
