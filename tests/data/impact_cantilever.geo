// A short cantilever whose tip strikes a rigid stop below it: the impact oscillator of
// period-doubling studies in one mode's worth of a beam. The beam is [0, L] x [-H/2, H/2],
// clamped at x = 0; its bottom edge's last `pad` metres ("stop") can touch the rigid line
// y = -H/2 - gap under it ("floor", line elements only); "tip" is the free end face (the
// drive), "tip_point" its mid node (the probe).
DefineConstant[
  L = {0.2, Name "Parameters/L"},
  H = {0.02, Name "Parameters/H"},
  pad = {0.005, Name "Parameters/pad"},
  gap = {0.0, Name "Parameters/gap"},
  lc = {0.005, Name "Parameters/lc"}
];
Point(1) = {0, -H/2, 0, lc};
Point(2) = {L - pad, -H/2, 0, lc};
Point(3) = {L, -H/2, 0, lc};
Point(4) = {L, 0, 0, lc};
Point(5) = {L, H/2, 0, lc};
Point(6) = {0, H/2, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6};
Plane Surface(1) = {1};
Point(10) = {L - 2 * pad, -H/2 - gap, 0, lc};
Point(11) = {L + pad, -H/2 - gap, 0, lc};
Line(10) = {10, 11};
Physical Curve("clamp") = {6};
Physical Curve("stop") = {2};
Physical Curve("tip") = {3, 4};
Physical Curve("free") = {1, 5};
Physical Point("tip_point") = {4};
Physical Surface("body") = {1};
Physical Curve("floor") = {10};
