// Half-disc of radius R, centre (0, R), flat face "top" on y = R, touching the plane y = 0 at
// the origin. The arc within +-theta_c of the bottom is "contact", refined to lc_contact and
// graded out to lc.
DefineConstant[
  R = {1.0, Name "Parameters/R"},
  theta_c = {0.15, Name "Parameters/theta_c"},
  lc = {0.1, Name "Parameters/lc"},
  lc_contact = {0.002, Name "Parameters/lc_contact"},
  grade = {0.25, Name "Parameters/grade"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {0, R, 0, lc};
Point(2) = {R, R, 0, lc};
Point(3) = {R * Sin(theta_c), R - R * Cos(theta_c), 0, lc_contact};
Point(4) = {0, 0, 0, lc_contact};
Point(5) = {-R * Sin(theta_c), R - R * Cos(theta_c), 0, lc_contact};
Point(6) = {-R, R, 0, lc};
Circle(1) = {2, 1, 3};
Circle(2) = {3, 1, 4};
Circle(3) = {4, 1, 5};
Circle(4) = {5, 1, 6};
Line(5) = {6, 2};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
If (quads)
  Recombine Surface{1};
EndIf
Field[1] = Distance;
Field[1].CurvesList = {2, 3};
Field[1].Sampling = 400;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = lc_contact;
Field[2].SizeMax = lc;
Field[2].DistMin = 0.02 * R;
Field[2].DistMax = grade * R;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Physical Curve("top") = {5};
Physical Curve("contact") = {2, 3};
Physical Curve("arc") = {1, 4};
Physical Surface("body") = {1};
