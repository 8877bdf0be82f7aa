// A body [0, 1] x [0, 0.5] whose right face ("right") faces a slanted rigid wall ("wall",
// meshed as line elements only) that covers only its upper part: tests/obstacles.rs.
lc = 0.05;
Point(1) = {0, 0, 0, lc};
Point(2) = {1, 0, 0, lc};
Point(3) = {1, 0.5, 0, lc};
Point(4) = {0, 0.5, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Point(10) = {1.05, 0.2, 0, lc};
Point(11) = {1.15, 0.7, 0, lc};
Line(10) = {10, 11};
Physical Curve("right") = {2};
Physical Surface("body") = {1};
Physical Curve("wall") = {10};
