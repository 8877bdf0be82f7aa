// A small bracket: plate [0, 0.2] x [0, 0.05] with a hole, clamped at x = 0, loaded at x = 0.2.
DefineConstant[
  W = {0.2, Name "Parameters/W"},
  D = {0.05, Name "Parameters/D"},
  r = {0.01, Name "Parameters/r"},
  lc = {0.005, Name "Parameters/lc"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {0, 0, 0, lc};
Point(2) = {W, 0, 0, lc};
Point(3) = {W, D, 0, lc};
Point(4) = {0, D, 0, lc};
Point(5) = {W/2, D/2, 0, lc};
Point(6) = {W/2 + r, D/2, 0, lc/2};
Point(7) = {W/2, D/2 + r, 0, lc/2};
Point(8) = {W/2 - r, D/2, 0, lc/2};
Point(9) = {W/2, D/2 - r, 0, lc/2};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Circle(5) = {6, 5, 7};
Circle(6) = {7, 5, 8};
Circle(7) = {8, 5, 9};
Circle(8) = {9, 5, 6};
Curve Loop(1) = {1, 2, 3, 4};
Curve Loop(2) = {5, 6, 7, 8};
Plane Surface(1) = {1, 2};
If (quads)
  Recombine Surface{1};
EndIf
Physical Curve("clamp") = {4};
Physical Curve("load") = {2};
Physical Curve("hole") = {5, 6, 7, 8};
Physical Point("probe") = {3};
Physical Surface("body") = {1};
