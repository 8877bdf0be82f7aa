//! The trail: the points of the curve so far in the scaled unknowns y = (λ/F, ω/Ω), to notice
//! a continuation that runs back along its own path (turned round at a kink of the sampled
//! law) or circles.
//!
//! Glossary: a new point y reached by a step Δs retraces the curve when its distance from an
//! earlier segment y_{j−1}–y_j is below `RETRACE` Δs; the last `RECENT` segments are not
//! compared (a kink's back-and-forth). The distance from a segment a–b is ‖q − a − t(b − a)‖
//! with t = clamp((q − a)·(b − a)/‖b − a‖², 0, 1).

use super::{hz, Point};

/// The last segments of the trail a new point is not compared with (a kink's back-and-forth).
const RECENT: usize = 4;

/// A point closer than this many steps to an earlier segment of the curve retraces it.
const RETRACE: f64 = 0.05;

/// The points of the curve so far, in the scaled unknowns, to notice a continuation that runs
/// back along its own path (turned round at a kink of the sampled law) or circles.
#[derive(Default)]
pub(super) struct Trail {
    points: Vec<Vec<f64>>,
}

impl Trail {
    /// The points so far.
    pub(super) fn points(&self) -> &[Vec<f64>] {
        &self.points
    }

    pub(super) fn push(&mut self, y: Vec<f64>) {
        self.points.push(y);
    }

    /// The index of an earlier segment (all but the last `RECENT`) that `y`, reached by a
    /// step `ds`, lies on within `RETRACE` × ds.
    pub(super) fn retraced(&self, y: &[f64], ds: f64) -> Option<usize> {
        let older = self.points.len().checked_sub(RECENT)?;
        self.near(1..older, y, ds)
    }

    /// The first segment j (from point j − 1 to j) among `segments` that `y` lies within
    /// `RETRACE` × ds of.
    fn near(&self, segments: std::ops::Range<usize>, y: &[f64], ds: f64) -> Option<usize> {
        segments
            .into_iter()
            .find(|&j| segment_distance(&self.points[j - 1], &self.points[j], y) < RETRACE * ds)
    }

    /// The trail up to point `k`, exclusive (its first `k` points).
    pub(super) fn cut(&self, k: usize) -> Trail {
        Trail {
            points: self.points[..k.min(self.points.len())].to_vec(),
        }
    }

    /// `y`, reached by a step `ds`, lies within `RETRACE` × ds of a segment from point `k` on.
    pub(super) fn on_since(&self, k: usize, y: &[f64], ds: f64) -> bool {
        self.near(k + 1..self.points.len(), y, ds).is_some()
    }
}

/// Distance of `q` from the segment a–b.
fn segment_distance(a: &[f64], b: &[f64], q: &[f64]) -> f64 {
    let ab: f64 = a.iter().zip(b).map(|(a, b)| (b - a).powi(2)).sum();
    let along: f64 = a
        .iter()
        .zip(b)
        .zip(q)
        .map(|((a, b), q)| (q - a) * (b - a))
        .sum();
    let t = if ab > 0.0 {
        (along / ab).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d2: f64 = a
        .iter()
        .zip(b)
        .zip(q)
        .map(|((a, b), q)| (q - a - t * (b - a)).powi(2))
        .sum();
    d2.sqrt()
}

/// Why a sweep that runs back along its own path stops (`samples` the contact law's samples
/// per period).
pub(super) fn retrace_reason(
    p: &Point,
    (index, j): (usize, usize),
    refine_key: &str,
    samples: usize,
) -> String {
    format!(
        "at {:.6} Hz (point {index}) the continuation ran back onto the curve it had traced \
         (between points {} and {j}), so it would retrace the curve instead of following it: \
         a sharp kink of the sampled contact law turned it round, or the curve closes on \
         itself. Raise harmonic_balance.samples (now {samples}: finer samples make the law's \
         kinks smaller), {refine_key} or the damping, lower sweep.max_step, or sweep a \
         narrower range",
        hz(p.omega),
        j - 1
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trail out along the first axis to x = 6, in unit steps.
    fn trail_out() -> Trail {
        let mut trail = Trail::default();
        for i in 0..=6 {
            trail.push(vec![i as f64, 0.0]);
        }
        trail
    }

    /// TEST GOAL: a point landing on an earlier segment of the curve (a continuation walking
    /// back along it) is found, with that segment's index; a point off the curve, or on one of
    /// the last `RECENT` segments (a kink's back-and-forth), is not.
    #[test]
    fn trail_finds_a_point_back_on_an_earlier_segment_only() {
        let trail = trail_out();
        assert_eq!(trail.retraced(&[1.5, 0.01], 1.0), Some(2));
        assert_eq!(trail.retraced(&[1.5, 0.2], 1.0), None, "off the curve");
        assert_eq!(trail.retraced(&[5.5, 0.0], 1.0), None, "a recent segment");
        assert_eq!(Trail::default().retraced(&[0.0, 0.0], 1.0), None);
    }

    /// TEST GOAL: a trail cut at point k keeps the points before it; a point lies on the
    /// segments from point k on only within `RETRACE` steps of one of them.
    #[test]
    fn a_cut_trail_keeps_its_first_points_and_a_point_lies_on_the_segments_after_k_only_near_one() {
        let trail = trail_out();
        assert_eq!(
            trail.cut(3).points(),
            &[vec![0.0, 0.0], vec![1.0, 0.0], vec![2.0, 0.0]]
        );
        assert!(trail.on_since(4, &[4.5, 0.01], 1.0));
        assert!(!trail.on_since(4, &[3.5, 0.0], 1.0), "before point 4");
        assert!(!trail.on_since(4, &[4.5, 0.2], 1.0), "off the segments");
    }

    /// TEST GOAL: the distance from a segment is the perpendicular one inside it and the
    /// distance to the nearer end outside.
    #[test]
    fn segment_distance_is_perpendicular_inside_and_to_the_end_outside() {
        let (a, b) = ([0.0, 0.0], [2.0, 0.0]);
        assert!((segment_distance(&a, &b, &[1.0, 0.5]) - 0.5).abs() < 1e-15);
        assert!((segment_distance(&a, &b, &[3.0, 0.0]) - 1.0).abs() < 1e-15);
        assert!((segment_distance(&a, &b, &[-3.0, 4.0]) - 5.0).abs() < 1e-15);
    }
}
