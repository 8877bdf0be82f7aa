// A clamped strip [0, L] x [0, H] meshed as a structured grid of nx x ny quadrilaterals
// split into triangles (or kept as quads): each cell is (L/nx) by (H/ny), so the aspect
// ratio (L/nx)/(H/ny) is set by the parameters. The free end face ("tip", x = L) faces a
// rigid wall x = L + gap ("wall", line elements only); "probe" is the top edge's end.
DefineConstant[
  L = {0.2, Name "Parameters/L"},
  H = {0.002, Name "Parameters/H"},
  gap = {1e-7, Name "Parameters/gap"},
  nx = {40, Name "Parameters/nx"},
  ny = {8, Name "Parameters/ny"},
  quads = {0, Name "Parameters/quads"}
];
Point(1) = {0, 0, 0};
Point(2) = {L, 0, 0};
Point(3) = {L, H, 0};
Point(4) = {0, H, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 3} = nx + 1;
Transfinite Curve{2, 4} = ny + 1;
Transfinite Surface{1};
If (quads)
  Recombine Surface{1};
EndIf
Point(10) = {L + gap, -H/2, 0, H};
Point(11) = {L + gap, 1.5 * H, 0, H};
Line(10) = {10, 11};
Physical Curve("bottom") = {1};
Physical Curve("tip") = {2};
Physical Curve("top") = {3};
Physical Curve("clamp") = {4};
Physical Point("probe") = {3};
Physical Surface("body") = {1};
Physical Curve("wall") = {10};
