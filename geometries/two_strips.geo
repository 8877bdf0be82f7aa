// Two clamped strips face to face: A = [0, L] x [0, H] and B = [L + 2 gap, L + 2 gap + LB] x
// [0, H], clamped at their outer ends, so A's free end face ("tip", x = L) and B's ("tip_b",
// x = L + 2 gap) are 2 gap apart; with LB = L (the default) B is A's mirror image about
// x = L + gap; lcB (default lc) is B's element size, so B's face nodes need not face A's.
// With second = 0, B is replaced by a rigid wall curve ("wall") at x = L + gap: the
// mirror plane; with split in (0, 1) that wall is two segments meeting at y = split H,
// "wall_low" and "wall_high" ("wall" is both). Structured meshes (transfinite), so B's nodes
// mirror A's exactly.
DefineConstant[
  L = {0.2, Name "Parameters/L"},
  H = {0.01, Name "Parameters/H"},
  gap = {1e-7, Name "Parameters/gap"},
  lc = {0.0025, Name "Parameters/lc"},
  second = {1, Name "Parameters/second"},
  LB = {-1, Name "Parameters/LB"},
  lcB = {-1, Name "Parameters/lcB"},
  split = {-1, Name "Parameters/split"}
];
If (LB <= 0)
  LB = L;
EndIf
If (lcB <= 0)
  lcB = lc;
EndIf
For side In {0 : second}
  s = 1 - 2 * side;            // +1 for A, -1 for B (mirrored)
  len = (side == 0) ? L : LB;
  x0 = side * (L + 2 * gap + LB); // the clamped end
  size = (side == 0) ? lc : lcB;
  nx = Ceil(len / size / 2) * 2;
  ny = Ceil(H / size);
  p = newp;
  Point(p) = {x0, 0, 0, lc};
  Point(p + 1) = {x0 + s * len, 0, 0, lc};
  Point(p + 2) = {x0 + s * len, H, 0, lc};
  Point(p + 3) = {x0 + s * len / 2, H, 0, lc};
  Point(p + 4) = {x0, H, 0, lc};
  l = newl;
  Line(l) = {p, p + 1};
  Line(l + 1) = {p + 1, p + 2};
  Line(l + 2) = {p + 2, p + 3};
  Line(l + 3) = {p + 3, p + 4};
  Line(l + 4) = {p + 4, p};
  Transfinite Curve{l} = nx + 1;
  Transfinite Curve{l + 2, l + 3} = nx / 2 + 1;
  Transfinite Curve{l + 1, l + 4} = ny + 1;
  cl = newll;
  Curve Loop(cl) = {l, l + 1, l + 2, l + 3, l + 4};
  sf = news;
  Plane Surface(sf) = {cl};
  Transfinite Surface{sf} = {p, p + 1, p + 2, p + 4};
  If (side == 0)
    Physical Curve("bottom") = {l};
    Physical Curve("tip") = {l + 1};
    Physical Curve("clamp") = {l + 4};
    Physical Point("probe") = {p + 3};
    Physical Surface("body") = {sf};
  Else
    Physical Curve("tip_b") = {l + 1};
    Physical Curve("clamp_b") = {l + 4};
    Physical Point("probe_b") = {p + 3};
    Physical Surface("body_b") = {sf};
  EndIf
EndFor
If (second == 0 && split <= 0)
  w = newp;
  Point(w) = {L + gap, -H / 2, 0, lc};
  Point(w + 1) = {L + gap, 1.5 * H, 0, lc};
  wl = newl;
  Line(wl) = {w, w + 1};
  Physical Curve("wall") = {wl};
EndIf
If (second == 0 && split > 0)
  w = newp;
  Point(w) = {L + gap, -H / 2, 0, lc};
  Point(w + 1) = {L + gap, split * H, 0, lc};
  Point(w + 2) = {L + gap, 1.5 * H, 0, lc};
  wl = newl;
  Line(wl) = {w, w + 1};
  Line(wl + 1) = {w + 1, w + 2};
  Physical Curve("wall") = {wl, wl + 1};
  Physical Curve("wall_low") = {wl};
  Physical Curve("wall_high") = {wl + 1};
EndIf
