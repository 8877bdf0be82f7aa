// tests/body_loads.rs: a quarter of a solid disc of radius R (centre at the origin), its
// straight edges on the axes ("x_axis": y = 0, "y_axis": x = 0), its rim ("rim") and the rim's
// points on the axes ("rim_x" at (R, 0), "rim_y" at (0, R)).
DefineConstant[
  R = {0.1, Name "Parameters/R"},
  lc = {0.004, Name "Parameters/lc"}
];
Point(1) = {0, 0, 0, lc};
Point(2) = {R, 0, 0, lc};
Point(3) = {0, R, 0, lc};
Line(1) = {1, 2};
Circle(2) = {2, 1, 3};
Line(3) = {3, 1};
Curve Loop(1) = {1, 2, 3};
Plane Surface(1) = {1};
Physical Curve("x_axis") = {1};
Physical Curve("rim") = {2};
Physical Curve("y_axis") = {3};
Physical Point("rim_x") = {2};
Physical Point("rim_y") = {3};
Physical Surface("disc") = {1};
