//! Harmonics chosen per point of a curve (`harmonic_balance.harmonics: {min, max}`): the
//! continuation runs at one level H at a time and moves to another where the truncation
//! estimate asks for it.
//!
//! Glossary and formulas (the estimate is `adaptive::estimate_of`):
//! - e(H) at an accepted point x: the change of the answer (the recovered field, by the
//!   frame's solves, and the mean contact force) from the state at ⌊H/2⌋ (a Newton on the
//!   point's frame truncated to ⌊H/2⌋, from x truncated, at N/2 samples) to x;
//! - raise: e(H) > τ (or e could not be formed) and H < H_max: the point is not kept; the
//!   curve restarts at min(2H, H_max) from it;
//! - lower: e(H) ≤ `LOWER` τ at `CALM` points in a row and H > H_min: restart at
//!   max(⌊H/2⌋, H_min) from the last (where e(H) ≤ τ/4, the error of H/2 is at most τ for
//!   an error falling as 1/H^p with p ≤ 2). A raise right after a lower (the level below did
//!   not hold after all) doubles the calm points the next lower needs, so the curve does not
//!   go back and forth between two levels;
//! - a restart carries the point's state over to the new level (`carried`): λ, the tangent's
//!   λ-part and the trail padded with zeros (or truncated), the tangent normalised again,
//!   N scaled with H; its first point is the state re-solved at the new H on an exact frame
//!   (a Newton from the carried λ, the smoothing continuation where that fails), and the
//!   reduced model is built again for the new H.
//!
//! A restarted point is checked for a raise again (never for a lower), so each kept point meets
//! τ or is at H_max.

use super::frame::Frame;
use super::start::Restart;
use super::trail::Trail;
use super::{Continuation, ContinuationState, OnPoint, Point, SweepOutcome, SweepSettings};
use crate::contact::ContactOperator;
use crate::hbm::adaptive::{self, HarmonicRange};
use crate::hbm::reduced::{self, NewtonSettings};
use crate::hbm::{HbSettings, System};
use crate::linalg::norm2;
use crate::progress::Reporter;
use crate::Result;

/// The share of the tolerance below which a point counts as calm (H could be halved).
const LOWER: f64 = 0.25;
/// Calm points in a row before H is halved.
const CALM: usize = 3;
/// Newton iterations of the ⌊H/2⌋ state of an estimate.
const HALF_ITERATIONS: usize = 40;
/// Steps without halving the residual after which that Newton gives up.
const HALF_HOVER: usize = 8;

/// The state of a level change: where the curve restarts and at which H.
#[derive(Clone, Debug)]
pub(super) struct LevelChange {
    pub(super) state: ContinuationState,
    pub(super) harmonics: usize,
}

/// The sweep of a frictionless contact scene with H chosen per point in `range`: segments of
/// the continuation at one H each, chained by `LevelChange`s, their outcomes summed.
pub(super) fn sweep_levels(
    system: &mut System,
    op: &ContactOperator,
    hb: &HbSettings,
    s: &SweepSettings,
    range: HarmonicRange,
    reporter: &dyn Reporter,
    on_point: &mut OnPoint,
) -> Result<SweepOutcome> {
    let mut level = hb.clone();
    if let Some(r) = &s.resume {
        level.harmonics = state_harmonics(r, op.nodes());
    }
    let mut total = SweepOutcome::default();
    let mut settings = s.clone();
    let (mut restart, mut calm_needed, mut lowered) = (None, CALM, false);
    loop {
        let mut c = Continuation::start(system, (op, op), &level, &settings, reporter, restart)?;
        reporter.task_done("harmonics");
        c.levels = Some(Levels {
            range,
            calm: 0,
            calm_needed,
            last: None,
        });
        let outcome = c.run(on_point)?;
        let change = add_segment(&mut total, outcome);
        let Some(change) = change else {
            return Ok(total);
        };
        reporter.progress(
            "harmonics",
            0,
            None,
            &format!("H = {} → {}", level.harmonics, change.harmonics),
        );
        let raised = change.harmonics > level.harmonics;
        if raised && lowered {
            calm_needed *= 2;
        }
        lowered = !raised;
        level.harmonics = change.harmonics;
        level.samples = change.state.samples;
        settings.resume = Some(change.state);
        restart = Some(Restart);
    }
}

/// Add a segment's outcome to the sweep's; the segment's level change, if it ended on one.
fn add_segment(total: &mut SweepOutcome, mut o: SweepOutcome) -> Option<LevelChange> {
    total.points = o.points;
    total.folds.append(&mut o.folds);
    total.stopped = o.stopped;
    total.timings += &o.timings;
    let r = &mut total.reduced;
    r.dimension = o.reduced.dimension;
    r.frames += o.reduced.frames;
    r.replaced += o.reduced.replaced;
    r.largest_error = r.largest_error.max(o.reduced.largest_error);
    total.level_changes += o.level_changes + usize::from(o.level_change.is_some());
    total.slivers += o.slivers;
    o.level_change
}

/// H of a saved state, from its multipliers' length (nc (2H + 1)).
fn state_harmonics(r: &ContinuationState, nodes: usize) -> usize {
    (r.multipliers.len() / nodes.max(1)).saturating_sub(1) / 2
}

/// Where a continuation running with H chosen per point stands.
#[derive(Clone, Copy)]
pub(super) struct Levels {
    pub(super) range: HarmonicRange,
    /// Calm points in a row, and how many a lower needs.
    pub(super) calm: usize,
    pub(super) calm_needed: usize,
    /// The last point's estimate (what its `PointInfo` reports).
    pub(super) last: Option<f64>,
}

impl Continuation<'_> {
    /// After the accepted point `next` (solved on `frame`, index `index`, next step `ds`):
    /// the level change its estimate asks for, if any (`lower`: a halving may be asked).
    pub(super) fn level_change(
        &mut self,
        (next, frame): (&Point, &Frame),
        (index, ds): (usize, f64),
        trail: &Trail,
        lower: bool,
    ) -> Option<LevelChange> {
        let mut levels = self.levels?;
        let h = self.hb.harmonics;
        let estimate = self.half_estimate(frame, &next.x);
        levels.last = estimate;
        let tolerance = levels.range.tolerance;
        let calm = estimate.is_some_and(|e| e <= LOWER * tolerance);
        levels.calm = if calm { levels.calm + 1 } else { 0 };
        self.levels = Some(levels);
        let to = if estimate.is_none_or(|e| e > tolerance) && h < levels.range.max {
            (2 * h).min(levels.range.max)
        } else if lower && levels.calm >= levels.calm_needed && h > levels.range.min {
            (h / 2).max(levels.range.min)
        } else {
            return None;
        };
        let mut state = self.state(next, ds, index, false);
        state.trail = trail.points().to_vec();
        let nodes = self.op.nodes();
        Some(LevelChange {
            state: carried(state, nodes, h, to),
            harmonics: to,
        })
    }

    /// e(H) at x on `frame` (see the header); `None` where ⌊H/2⌋ cannot carry the loads or
    /// its Newton does not converge.
    fn half_estimate(&mut self, frame: &Frame, x: &[f64]) -> Option<f64> {
        let clock = std::time::Instant::now();
        let problem = &frame.problem;
        let half = problem.harmonics / 2;
        let excited = self.system.inputs.keys().copied().max().unwrap_or(0);
        if half == 0 || half < excited {
            return None;
        }
        let newton = NewtonSettings {
            samples: (self.newton.samples / 2).max(2 * half + 1),
            c: self.newton.c,
            tolerance: self.newton.tolerance,
            max_iterations: HALF_ITERATIONS,
            hover: HALF_HOVER,
            ..Default::default()
        };
        let (coarse, _) = adaptive::half_state(problem, x, &newton, self.reporter);
        let change = coarse
            .map(|(p, c)| adaptive::estimate_of((&p, &c), (problem, x), &frame.linear, self.op));
        self.timings.knob_check += clock.elapsed().as_secs_f64();
        change
    }
}

/// The state `r` at H = `from` carried over to H = `to` (see the header).
fn carried(mut r: ContinuationState, nodes: usize, from: usize, to: usize) -> ContinuationState {
    let lam = |y: &[f64]| {
        let n = y.len() - 1;
        let mut out = reduced::pad(&y[..n], nodes, from, to);
        out.push(y[n]);
        out
    };
    r.multipliers = reduced::pad(&r.multipliers, nodes, from, to);
    let mut tangent = lam(&r.tangent);
    let norm = norm2(&tangent);
    if norm > 0.0 {
        tangent.iter_mut().for_each(|v| *v /= norm);
    }
    r.tangent = tangent;
    r.trail = r.trail.iter().map(|y| lam(y)).collect();
    r.samples = (r.samples * to / from.max(1)).max(HbSettings::default_samples(to));
    r.reduced_frame = false;
    r.enriched_at.clear();
    r
}
