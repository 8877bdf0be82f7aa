// A beam [0, L] x [-h/2, h/2] with contact pads and rigid stops, for the user scenes of
// pipelines/scenes/. The bottom edge (and, with `top_stop = 1`, the top edge) is split at
// a = xc - pad/2 and b = xc + pad/2: the segment between is a contact pad ("pads"). A rigid
// stop ("stops", line elements only, no node shared with the body) lies `gap` below the
// bottom pad (and `gap` above the top pad), reaching `pad` beyond each end of it so that no
// pad node projects onto a free end of the stop. With b = L the pad ends at the tip corner.
// The top edge is split at xc too: "probe" is the top point above the pad's centre.
DefineConstant[
  L = {0.2, Name "Parameters/L"},
  h = {0.01, Name "Parameters/h"},
  gap = {3e-4, Name "Parameters/gap"},
  pad = {0.01, Name "Parameters/pad"},
  xc = {0.195, Name "Parameters/xc"},
  top_stop = {0, Name "Parameters/top_stop"},
  lc = {0.0033, Name "Parameters/lc"}
];
a = xc - pad / 2;
b = xc + pad / 2;
tip = (b > L - 1e-9 * L);
// bottom edge, left to right
Point(1) = {0, -h/2, 0, lc};
Point(2) = {a, -h/2, 0, lc};
Point(3) = {b, -h/2, 0, lc};
// top edge, right to left
Point(5) = {L, h/2, 0, lc};
Point(7) = {xc, h/2, 0, lc};
Point(8) = {a, h/2, 0, lc};
Point(9) = {0, h/2, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
If (tip)
  Line(4) = {3, 5};
  Line(6) = {5, 7};
  Curve Loop(1) = {1, 2, 4, 6, 7, 8, 9};
  bottom[] = {1, 2};
  right[] = {4};
  top[] = {6, 7, 8};
  toppad[] = {6, 7};
Else
  Point(4) = {L, -h/2, 0, lc};
  Point(6) = {b, h/2, 0, lc};
  Line(3) = {3, 4};
  Line(4) = {4, 5};
  Line(5) = {5, 6};
  Line(6) = {6, 7};
  Curve Loop(1) = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  bottom[] = {1, 2, 3};
  right[] = {4};
  top[] = {5, 6, 7, 8};
  toppad[] = {6, 7};
EndIf
Line(7) = {7, 8};
Line(8) = {8, 9};
Line(9) = {9, 1};
Plane Surface(1) = {1};
// the stops
Point(20) = {a - pad, -h/2 - gap, 0, lc};
Point(21) = {b + pad, -h/2 - gap, 0, lc};
Line(20) = {20, 21};
stops[] = {20};
pads[] = {2};
If (top_stop)
  Point(22) = {a - pad, h/2 + gap, 0, lc};
  Point(23) = {b + pad, h/2 + gap, 0, lc};
  Line(21) = {22, 23};
  stops[] += {21};
  pads[] += toppad[];
EndIf
Physical Curve("left") = {9};
Physical Curve("right") = right[];
Physical Curve("top") = top[];
Physical Curve("bottom") = bottom[];
Physical Curve("pads") = pads[];
Physical Curve("stops") = stops[];
Physical Point("probe") = {7};
Physical Surface("body") = {1};
