// A block [0, W] x [0, H] resting on a rigid floor y = 0 ("floor", meshed as line elements
// only): its bottom edge "base" is the contact boundary, its top edge "top" carries the normal
// load and the tangential drive, "probe" is the top edge's midpoint. Structured quadrilaterals
// (nx × ny), so every base node sees the same share of the load.
DefineConstant[
  W = {0.1, Name "Parameters/W"},
  H = {0.01, Name "Parameters/H"},
  nx = {20, Name "Parameters/nx"},
  ny = {2, Name "Parameters/ny"}
];
Point(1) = {0, 0, 0};
Point(2) = {W/2, 0, 0};
Point(3) = {W, 0, 0};
Point(4) = {W, H, 0};
Point(5) = {W/2, H, 0};
Point(6) = {0, H, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6};
Plane Surface(1) = {1};
Transfinite Curve{1, 2, 4, 5} = nx/2 + 1;
Transfinite Curve{3, 6} = ny + 1;
Transfinite Surface{1} = {1, 3, 4, 6};
Recombine Surface{1};
Point(10) = {-W/2, 0, 0};
Point(11) = {1.5 * W, 0, 0};
Line(10) = {10, 11};
Physical Curve("base") = {1, 2};
Physical Curve("top") = {4, 5};
Physical Curve("sides") = {3, 6};
Physical Point("probe") = {5};
Physical Surface("body") = {1};
Physical Curve("floor") = {10};
