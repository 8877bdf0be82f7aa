// A blade standing on its root, [-w/2, w/2] x [R0, R0 + Lb], inside an elastic casing: an
// annular sector of inner radius R0 + Lb + clearance (so `clearance` lies straight above the
// middle of the blade tip), thickness tc and half-span span_deg, centred on the origin, held
// at its two end faces ("casing_ends"). The casing's inner arc ("casing_inner") is the
// contact target of the blade tip ("tip").
DefineConstant[
  w = {0.01, Name "Parameters/w"},
  R0 = {0.1, Name "Parameters/R0"},
  Lb = {0.1, Name "Parameters/Lb"},
  clearance = {1e-4, Name "Parameters/clearance"},
  tc = {0.003, Name "Parameters/tc"},
  span_deg = {25, Name "Parameters/span_deg"},
  lc = {0.0025, Name "Parameters/lc"}
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
ri = R0 + Lb + clearance;
ro = ri + tc;
a = span_deg * Pi / 180;
Point(10) = {0, 0, 0, lc};
Point(11) = {ri * Sin(a), ri * Cos(a), 0, lc};
Point(12) = {0, ri, 0, lc/2};
Point(13) = {-ri * Sin(a), ri * Cos(a), 0, lc};
Point(14) = {-ro * Sin(a), ro * Cos(a), 0, lc};
Point(15) = {0, ro, 0, lc/2};
Point(16) = {ro * Sin(a), ro * Cos(a), 0, lc};
Circle(10) = {11, 10, 12};
Circle(11) = {12, 10, 13};
Line(12) = {13, 14};
Circle(13) = {14, 10, 15};
Circle(14) = {15, 10, 16};
Line(15) = {16, 11};
Curve Loop(2) = {10, 11, 12, 13, 14, 15};
Plane Surface(2) = {2};
Physical Curve("root") = {1};
Physical Curve("right") = {2};
Physical Curve("tip") = {3};
Physical Curve("left") = {4};
Physical Point("probe") = {4};
Physical Surface("body") = {1};
Physical Curve("casing_inner") = {10, 11};
Physical Curve("casing_outer") = {13, 14};
Physical Curve("casing_ends") = {12, 15};
Physical Point("casing_probe") = {15};
Physical Surface("casing") = {2};
