//! A curve that runs back onto itself along a sliver of the sampled law, and the way around it.
//!
//! Glossary (y, Δs as in the module `continuation`; the trail as in `trail`): a sliver is a
//! thin sheet of the sampled law's solutions that leaves the curve, turns within a fraction
//! of a step and runs back along it, so that a later point lies on an earlier segment
//! y_{j−1}–y_j of the trail. The sliver left the curve at y_{j−1}: the continuation steps
//! again from there with `FACTORS` times the step that reached y_j, the trail cut back to
//! y_{j−1}, and takes the first point that lies neither on the cut trail nor on the sliver
//! (the segments from y_{j−1} on). The points found on the sliver stay in the curve (they are
//! solutions). At most `MAX_SLIVERS` per curve; where no step gets round, the curve stops as
//! `trail` says.
//!
//! The first-mode blade of `pipelines/scenes/` swept from 603 Hz instead of 602.9 Hz reaches
//! its upper fold (916.81 Hz) on a sliver at 916.82 Hz that runs back along its upper branch.

use std::collections::VecDeque;

use super::frame::Frame;
use super::trail::Trail;
use super::{hz, Continuation, Point, PointInfo};

/// The steps tried from where a sliver left the curve, as multiples of the step that reached
/// the sliver's first point: shorter first (to stay on the curve's side of the kink), then
/// longer (to step over it).
const FACTORS: [f64; 4] = [0.25, 0.0625, 2.0, 4.0];

/// The most slivers a curve is led round.
const MAX_SLIVERS: usize = 8;

/// The last points kept to step again from.
const KEEP: usize = 16;

/// The last `KEEP` points of the curve: (index in the trail, point, the step that reached
/// it), and the slivers gone round so far.
pub(super) struct Recent {
    points: VecDeque<(usize, Point, f64)>,
    slivers: usize,
}

impl Recent {
    /// From the first point, number `t` in the trail.
    pub(super) fn new(t: usize, first: &Point) -> Self {
        Recent {
            points: VecDeque::from([(t, first.clone(), 0.0)]),
            slivers: 0,
        }
    }

    /// Point number `t` of the trail, reached by a step `step`.
    pub(super) fn push(&mut self, t: usize, p: &Point, step: f64) {
        self.points.push_back((t, p.clone(), step));
        if self.points.len() > KEEP {
            self.points.pop_front();
        }
    }

    fn at(&self, t: usize) -> Option<&(usize, Point, f64)> {
        self.points.iter().find(|(k, _, _)| *k == t)
    }
}

/// Where the curve goes on after a sliver: the point it steps from, the next point, its frame
/// and account, and the step to try after it.
type Around = (Point, Point, Frame, PointInfo, f64);

impl Continuation<'_> {
    /// The curve led round the sliver that ran back onto segment `j` of `trail` (cut back to
    /// its point j − 1 when found), or `None`.
    pub(super) fn around_sliver(
        &mut self,
        recent: &mut Recent,
        trail: &mut Trail,
        j: usize,
        index: usize,
    ) -> Option<Around> {
        if recent.slivers >= MAX_SLIVERS || j == 0 {
            return None;
        }
        let (_, from, _) = recent.at(j - 1)?.clone();
        let step = recent.at(j)?.2;
        recent.slivers += 1;
        let cut = trail.cut(j);
        for factor in FACTORS {
            let mut ds = (factor * step).clamp(self.s.min_step, self.s.max_step);
            let status = format!(
                "from {:.3} Hz, round a sliver: step {ds:.2e}",
                hz(from.omega)
            );
            self.reporter.progress("sweep", index as u64, None, &status);
            let Ok((next, frame, info)) = self.next_point(&from, &mut ds, index) else {
                continue;
            };
            let y = self.scaled(&next);
            let back = cut.retraced(&y, info.step).is_some();
            if back || trail.on_since(j - 1, &y, info.step) {
                continue;
            }
            *trail = cut;
            recent.points.retain(|(t, _, _)| *t < j);
            return Some((from, next, frame, info, ds));
        }
        None
    }
}
