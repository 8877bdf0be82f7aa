// A blade standing on its root, [-w/2, w/2] x [R0, R0 + Lb], inside a circular casing arc
// ("casing", line elements only) of centre (casing_offset, 0) whose radius leaves `clearance`
// straight above the middle of the blade tip.
DefineConstant[
  w = {0.01, Name "Parameters/w"},
  R0 = {0.1, Name "Parameters/R0"},
  Lb = {0.1, Name "Parameters/Lb"},
  clearance = {1e-4, Name "Parameters/clearance"},
  casing_offset = {0.0, Name "Parameters/casing_offset"},
  span_deg = {25, Name "Parameters/span_deg"},
  lc = {0.0025, Name "Parameters/lc"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {-w/2, R0, 0, lc};
Point(2) = {w/2, R0, 0, lc};
Point(3) = {w/2, R0 + Lb, 0, lc/2};
Point(4) = {-w/2, R0 + Lb, 0, lc/2};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
If (quads)
  Recombine Surface{1};
EndIf
rc = Sqrt(casing_offset^2 + (R0 + Lb + clearance)^2);
a = span_deg * Pi / 180;
Point(10) = {casing_offset, 0, 0, lc};
Point(11) = {casing_offset + rc * Sin(a), rc * Cos(a), 0, lc/2};
Point(12) = {casing_offset, rc, 0, lc/2};
Point(13) = {casing_offset - rc * Sin(a), rc * Cos(a), 0, lc/2};
Circle(10) = {11, 10, 12};
Circle(11) = {12, 10, 13};
Physical Curve("root") = {1};
Physical Curve("right") = {2};
Physical Curve("tip") = {3};
Physical Curve("left") = {4};
Physical Point("probe") = {4};
Physical Surface("body") = {1};
Physical Curve("casing") = {10, 11};
