// Slender cantilever: [0, L] x [-H/2, H/2], clamped at x = 0. The tip edge is split at its
// middle so that a node ("tip_point") sits on the neutral axis.
DefineConstant[
  L = {1.0, Name "Parameters/L"},
  H = {0.02, Name "Parameters/H"},
  lc = {0.01, Name "Parameters/lc"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {0, -H/2, 0, lc};
Point(2) = {L, -H/2, 0, lc};
Point(3) = {L, 0, 0, lc};
Point(4) = {L, H/2, 0, lc};
Point(5) = {0, H/2, 0, lc};
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
Physical Curve("bottom") = {1};
Physical Curve("tip") = {2, 3};
Physical Curve("top") = {4};
Physical Curve("clamp") = {5};
Physical Point("tip_point") = {3};
Physical Surface("body") = {1};
