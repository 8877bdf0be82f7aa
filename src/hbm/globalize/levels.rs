//! The continuation levels of the contact solve: the smoothing μ of the contact law from
//! 0.3 F (F the linear solution's force) down by a factor of 0.3 per level to below
//! 0.1 × tolerance × F, a failed level narrowing the factor to its square root while that
//! stays ≤ 0.95; the joint damping scale, falling linearly in ln μ to the scene's own; and
//! the iteration rules of a level.

use crate::hbm::problem::ReducedProblem;
use crate::hbm::reduced::IterationLog;
use crate::Result;

/// Newton iterations one smoothing level may take before the continuation narrows its step.
pub(super) const LEVEL_ITERATIONS: usize = 30;

/// Steps of length ≥ 1/2 a smoothing level may take without halving its residual before the
/// continuation narrows its step: a level cycling between active sets (the 0.5%-damped strip
/// at H = 60) fails early, one creeping by short steps through many active-set changes (the
/// undamped strip at H = 40, 15 iterations) goes on. 5 instead of 8: the 0.5%-damped strip
/// at H = 60 and 70 22 and 25 iterations instead of 24 and 28, the case matrix 409 instead of
/// 414, the same answers; 4 sent the 0.11%-damped strip at H = 60 to another state.
pub(super) const LEVEL_STAGNATION: usize = 5;

/// Newton iterations a smoothing level may take without halving its residual, whatever its
/// steps, where a fallback follows (`OnFold::Stop`): the 0.5%-damped strip's direct path at
/// H = 80 and 100 hovers at one residual by short steps, 30 iterations per failed level
/// before this bound, 8 with it (4 stops `strip_wall` with α = 1500, β = 0 at H = 40
/// mid-creep: its direct solve has one level of 7 short steps).
pub(super) const LEVEL_HOVER: usize = 8;

/// Newton steps after which a smoothing level whose every step ended above its starting
/// residual fails, where a fallback follows (`OnFold::Stop`), and is taken as the fold at
/// once: no solution lies near its start. The 0.5%-damped strip's direct path at H = 80 and
/// 100 detects its fold in 2 iterations instead of the 8 of `LEVEL_HOVER`; the solves that
/// converge directly (the shipped and hard scenes, the strip at H = 5 to 70) are unchanged.
pub(super) const LEVEL_RISE: usize = 2;

/// Newton iterations the exact law may take from a smoothing level whose active set has
/// settled (`Attempts::settled_exact`) before the levels go on: once a level converges in
/// one step without changing its active samples, the smoothing left to remove no longer
/// moves the active set, and the semi-smooth Newton on the exact law converges in a step or
/// two from there. Measured on the 31-case matrix: 464 → 414 iterations, knob checks
/// included, with the same answers to the digits printed (at most 2: 418; 5: 414; any level
/// of at most one step, active set changed or not: 414, but the 0.5%-damped strip at H = 70
/// and 80 then takes 37 and 39 against 28 and 33).
pub(super) const SETTLED_EXACT_ITERATIONS: usize = 3;

/// The smoothing μ/F at or below which a settled level ends the continuation: at larger μ a
/// level's active set can look settled and the exact law's try fails (without this bound the
/// 0.5%-damped strip at H = 70 takes 31 iterations, 28 with it; at 10⁻³, 424 on the case
/// matrix against 414, and the strip at H = 60 26 against 24).
pub(super) const SETTLED_SMOOTHING: f64 = 3e-3;

/// The joint continuation brings the damping down to the scene's own over this many
/// smoothing levels (μ from 0.3 F to 0.3⁷ F ≈ 2·10⁻⁴ F): on the 0.5%-damped strip at H = 80,
/// 20 Newton iterations; over 4 levels its exact law's path still folds there, over 8 H = 40
/// and 60 need more narrowed levels.
pub(super) const JOINT_LEVELS: i32 = 6;

/// The damping ratio at the fundamental the damping continuation starts from: where the
/// reference strip's direct solve converges at every H from 5 to 80.
pub(super) const DAMPED_START: f64 = 0.05;

/// The reduced problem of the same scene with its damping D scaled by a factor s > 1 (the
/// damping continuation's heavier-damped problems).
pub(super) type Heavier<'h> = &'h (dyn Fn(f64) -> Result<ReducedProblem> + Sync);

/// The joint continuation's damping scale at μ = `relative`·F: `top` at the first level
/// (μ = 0.3 F), falling linearly in ln μ to 1 at μ = 0.3^(`JOINT_LEVELS` + 1) F, and 1
/// below (exactly: round-off in μ must not make a heavier problem of the scene's own).
pub(super) fn joint_scale(top: f64, relative: f64) -> f64 {
    let span = 0.3f64.powi(JOINT_LEVELS).ln();
    let w = (1.0 - (relative / 0.3).ln() / span).clamp(0.0, 1.0);
    if w < 1e-9 {
        1.0
    } else {
        top.powf(w)
    }
}

/// Whether a failed Newton run's steps were short: their geometric mean below 1/2. A run
/// that cannot reduce its residual even by short steps has no solution near it (the path
/// folded); full steps that overshoot are cured by a narrower step in μ. Measured on the
/// 0.5%-damped strip: the failing levels at H = 80 have means 0.25 and 0.03, the levels that
/// one narrowing passes at H = 60 and 70 0.74 and 0.63.
pub(super) fn short_steps(log: &[IterationLog]) -> bool {
    let steps: Vec<f64> = log.iter().skip(1).map(|l| l.step.max(1e-6)).collect();
    !steps.is_empty() && steps.iter().map(|s| s.log2()).sum::<f64>() / (steps.len() as f64) < -1.0
}

/// The smoothing levels of a continuation (docs/method.md, "Globalization", step 2): μ from
/// 0.3 F (F the linear solution's force) down by a factor of 0.3 per level to below
/// 0.1 × tolerance × F, each level from the last one's solution; a failed level narrows the
/// factor to its square root, until that would exceed 0.95 (the path turned back). The one
/// schedule of `smoothed_on` and `joint`.
pub(super) struct Levels {
    pub(super) force: f64,
    floor: f64,
    pub(super) ratio: f64,
    /// μ of the last level passed (F before any), and its solution (the start before any).
    pub(super) last: f64,
    pub(super) x: Vec<f64>,
}

impl Levels {
    pub(super) fn new(force: f64, tolerance: f64, start: Vec<f64>) -> Levels {
        Levels {
            force,
            floor: 0.1 * tolerance * force,
            ratio: 0.3,
            last: force,
            x: start,
        }
    }

    /// μ of the next level; `None` once below the floor, or when nothing penetrates (F = 0).
    pub(super) fn next(&self) -> Option<f64> {
        let mu = self.last * self.ratio;
        (self.force > 0.0 && mu > self.floor).then_some(mu)
    }

    /// The level at μ converged to `x`.
    pub(super) fn passed(&mut self, mu: f64, x: Vec<f64>) {
        (self.last, self.x) = (mu, x);
    }

    /// Whether a failed level can be retried with a narrower step.
    pub(super) fn can_narrow(&self) -> bool {
        self.ratio.sqrt() <= 0.95
    }

    /// Narrow the step after a failed level (`can_narrow` first).
    pub(super) fn narrow(&mut self) {
        self.ratio = self.ratio.sqrt();
    }

    /// Widen the step back towards 0.3 after an easy level.
    pub(super) fn widen(&mut self) {
        self.ratio = (self.ratio * self.ratio).max(0.3);
    }

    /// The last level passed, μ/F.
    pub(super) fn reached(&self) -> f64 {
        self.last / self.force
    }
}
