//! The contact solve around the semi-smooth Newton of `reduced`: the linear gap r of (20),
//! the automatic complementarity parameter c, and the globalization that makes the Newton
//! converge on hard cases (docs/method.md, "Globalization"), cheapest first:
//! 1. the plain Newton from λ = 0 (by a continuation in a smoothing μ of the law);
//! 2. on a lightly damped scene, continuation in the damping: the same scene with its
//!    damping scaled up to ζ₀ = 5% at the fundamental (ζ the Rayleigh damping ratio) at the
//!    first smoothing level, brought down to the scene's own together with μ over the next
//!    levels, each level a Newton from the last state (each heavier-damped level is a new
//!    factorization);
//! 3. the harmonic ladder H/8, H/4, H/2, H, each rung warm-starting the next (the low
//!    harmonics of an impact response are found first);
//! 4. all again with c ten times smaller (a softer penalty on the gap: the c that converges
//!    is a band).
//!
//! If all fail, the error says what to change. Two budgets bound the whole: each Newton run
//! stops at `max_iterations`, and no Newton iteration (so no run) starts once `max_seconds`
//! of wall time are spent; a failure that ran out of either budget says so, with the
//! iterations reached (rather than blaming the scene).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use faer::c64;

use super::basis::TimeBasis;
use super::problem::ReducedProblem;
use super::reduced::{self, IterationLog, NewtonOutcome, NewtonSettings};
use super::step::KrylovHint;
use super::{fourier, knobs};
use super::{measure_complementarity, ContactSolution, HbSettings, System};
use crate::contact::ContactOperator;
use crate::fem::modes::rayleigh_damping_ratio;
use crate::progress::Reporter;
use crate::{Error, Result};

/// The linear gap r = B z_lin + B_p u_p − g0 δ_k0 as real coefficients, node-major.
pub(super) fn linear_gap(
    op: &ContactOperator,
    harmonics: usize,
    free: &BTreeMap<usize, Vec<c64>>,
    motion: &BTreeMap<usize, Vec<c64>>,
) -> Vec<f64> {
    let (nc, m) = (op.nodes(), 2 * harmonics + 1);
    let mut r = vec![0.0; nc * m];
    for k in 0..=harmonics {
        let mut bz = op.b_free.mul_complex(&free[&k]);
        if op.b_prescribed.ncols > 0 {
            for (a, b) in bz.iter_mut().zip(op.b_prescribed.mul_complex(&motion[&k])) {
                *a += b;
            }
        }
        for (i, z) in bz.into_iter().enumerate() {
            let g0 = if k == 0 { op.g0[i] } else { 0.0 };
            fourier::set_phasor(&mut r[i * m..(i + 1) * m], k, z - g0);
        }
    }
    r
}

/// c = c_scale / mean|G_0,ii|: a stiffness of the order of the contact nodes' own.
pub(super) fn automatic_c(problem: &ReducedProblem, settings: &HbSettings) -> Result<f64> {
    let nc = problem.nodes;
    let mean_compliance = (0..nc)
        .map(|i| problem.compliance[0][i * nc + i].re.abs())
        .sum::<f64>()
        / nc as f64;
    if !(mean_compliance.is_finite() && mean_compliance > 0.0) {
        return Err(Error::Model(
            "the contact nodes' static compliance B K⁻¹ Bᵀ is zero or not finite: are the contact \
             nodes held by boundaries.fixed? Contact on held nodes does nothing"
                .into(),
        ));
    }
    Ok(settings.c_scale / mean_compliance)
}

/// Newton iterations one smoothing level may take before the continuation narrows its step.
const LEVEL_ITERATIONS: usize = 30;
/// Steps of length ≥ 1/2 a smoothing level may take without halving its residual before the
/// continuation narrows its step: a level cycling between active sets (the 0.5%-damped strip
/// at H = 60) fails early, one creeping by short steps through many active-set changes (the
/// undamped strip at H = 40, 15 iterations) goes on. 5 instead of 8: the 0.5%-damped strip
/// at H = 60 and 70 22 and 25 iterations instead of 24 and 28, the case matrix 409 instead of
/// 414, the same answers; 4 sent the 0.11%-damped strip at H = 60 to another state.
const LEVEL_STAGNATION: usize = 5;

/// Newton iterations a smoothing level may take without halving its residual, whatever its
/// steps, where a fallback follows (`OnFold::Stop`): the 0.5%-damped strip's direct path at
/// H = 80 and 100 hovers at one residual by short steps, 30 iterations per failed level
/// before this bound, 8 with it (4 stops `strip_wall` with α = 1500, β = 0 at H = 40
/// mid-creep: its direct solve has one level of 7 short steps).
const LEVEL_HOVER: usize = 8;

/// Newton steps after which a smoothing level whose every step ended above its starting
/// residual fails, where a fallback follows (`OnFold::Stop`), and is taken as the fold at
/// once: no solution lies near its start. The 0.5%-damped strip's direct path at H = 80 and
/// 100 detects its fold in 2 iterations instead of the 8 of `LEVEL_HOVER`; the solves that
/// converge directly (the shipped and hard scenes, the strip at H = 5 to 70) are unchanged.
const LEVEL_RISE: usize = 2;

/// Newton iterations the exact law may take from a smoothing level whose active set has
/// settled (`Attempts::settled_exact`) before the levels go on: once a level converges in
/// one step without changing its active samples, the smoothing left to remove no longer
/// moves the active set, and the semi-smooth Newton on the exact law converges in a step or
/// two from there. Measured on the 31-case matrix: 464 → 414 iterations, knob checks
/// included, with the same answers to the digits printed (at most 2: 418; 5: 414; any level
/// of at most one step, active set changed or not: 414, but the 0.5%-damped strip at H = 70
/// and 80 then takes 37 and 39 against 28 and 33).
const SETTLED_EXACT_ITERATIONS: usize = 3;

/// The smoothing μ/F at or below which a settled level ends the continuation: at larger μ a
/// level's active set can look settled and the exact law's try fails (without this bound the
/// 0.5%-damped strip at H = 70 takes 31 iterations, 28 with it; at 10⁻³, 424 on the case
/// matrix against 414, and the strip at H = 60 26 against 24).
const SETTLED_SMOOTHING: f64 = 3e-3;

/// The joint continuation brings the damping down to the scene's own over this many
/// smoothing levels (μ from 0.3 F to 0.3⁷ F ≈ 2·10⁻⁴ F): on the 0.5%-damped strip at H = 80,
/// 20 Newton iterations; over 4 levels its exact law's path still folds there, over 8 H = 40
/// and 60 need more narrowed levels.
const JOINT_LEVELS: i32 = 6;

/// The damping ratio at the fundamental the damping continuation starts from: where the
/// reference strip's direct solve converges at every H from 5 to 80.
const DAMPED_START: f64 = 0.05;

/// The reduced problem of the same scene with its damping D scaled by a factor s > 1 (the
/// damping continuation's heavier-damped problems).
pub(super) type Heavier<'h> = &'h (dyn Fn(f64) -> Result<ReducedProblem> + Sync);

/// The joint continuation's damping scale at μ = `relative`·F: `top` at the first level
/// (μ = 0.3 F), falling linearly in ln μ to 1 at μ = 0.3^(`JOINT_LEVELS` + 1) F, and 1
/// below (exactly: round-off in μ must not make a heavier problem of the scene's own).
fn joint_scale(top: f64, relative: f64) -> f64 {
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
fn short_steps(log: &[IterationLog]) -> bool {
    let steps: Vec<f64> = log.iter().skip(1).map(|l| l.step.max(1e-6)).collect();
    !steps.is_empty() && steps.iter().map(|s| s.log2()).sum::<f64>() / (steps.len() as f64) < -1.0
}

/// Why a smoothing continuation stopped where its path turned back at μ = `at`·F.
fn fold_reason(at: f64) -> String {
    format!(
        "the smoothing path turned back at μ = {at:.1e}·F (a fold: near a resonance the contact \
         problem can have several periodic states)"
    )
}

/// The smoothing levels of a continuation (docs/method.md, "Globalization", step 2): μ from
/// 0.3 F (F the linear solution's force) down by a factor of 0.3 per level to below
/// 0.1 × tolerance × F, each level from the last one's solution; a failed level narrows the
/// factor to its square root, until that would exceed 0.95 (the path turned back). The one
/// schedule of `smoothed_on` and `joint`.
struct Levels {
    force: f64,
    floor: f64,
    ratio: f64,
    /// μ of the last level passed (F before any), and its solution (the start before any).
    last: f64,
    x: Vec<f64>,
}

impl Levels {
    fn new(force: f64, tolerance: f64, start: Vec<f64>) -> Levels {
        Levels {
            force,
            floor: 0.1 * tolerance * force,
            ratio: 0.3,
            last: force,
            x: start,
        }
    }

    /// μ of the next level; `None` once below the floor, or when nothing penetrates (F = 0).
    fn next(&self) -> Option<f64> {
        let mu = self.last * self.ratio;
        (self.force > 0.0 && mu > self.floor).then_some(mu)
    }

    /// The level at μ converged to `x`.
    fn passed(&mut self, mu: f64, x: Vec<f64>) {
        (self.last, self.x) = (mu, x);
    }

    /// Whether a failed level can be retried with a narrower step.
    fn can_narrow(&self) -> bool {
        self.ratio.sqrt() <= 0.95
    }

    /// Narrow the step after a failed level (`can_narrow` first).
    fn narrow(&mut self) {
        self.ratio = self.ratio.sqrt();
    }

    /// Widen the step back towards 0.3 after an easy level.
    fn widen(&mut self) {
        self.ratio = (self.ratio * self.ratio).max(0.3);
    }

    /// The last level passed, μ/F.
    fn reached(&self) -> f64 {
        self.last / self.force
    }
}

/// What the smoothing continuation does where its path turns back (a fold in μ).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum OnFold {
    /// Try the exact law from the last point reached.
    ExactLaw,
    /// Give up: the caller has a better fallback.
    Stop,
}

/// How a converged contact solve got there: the harmonic ladder it climbed ([H] when direct)
/// and the damping ratios at the fundamental it continued through (empty when it did not).
struct Route {
    ladder: Vec<usize>,
    damping: Vec<f64>,
}

impl Route {
    /// Up the ladder `ladder` (just [H]: direct), without the damping continuation.
    fn laddered(ladder: Vec<usize>) -> Route {
        let damping = Vec::new();
        Route { ladder, damping }
    }
}

/// Every Newton run of one contact solve: iterations, log and why each attempt failed.
struct Attempts<'a> {
    problem: &'a ReducedProblem,
    settings: &'a HbSettings,
    reporter: &'a dyn Reporter,
    iterations: usize,
    log: Vec<IterationLog>,
    reasons: Vec<String>,
    /// When the time budget ends.
    deadline: Instant,
    /// The budget a failed run ran out of, if any.
    exhausted: Option<Budget>,
    /// The preconditioner every run's matrix-free steps start with: the one that served the
    /// last step (`step::KrylovHint`).
    krylov_hint: KrylovHint,
}

/// The budgets of one contact solve, as a failed solve ran out of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Budget {
    /// A Newton run used up `max_iterations` while still converging (`converging`).
    Iterations,
    /// Every Newton run that used up `max_iterations` had stopped converging: more would
    /// not have helped (the 0.28%-damped reference strip at H = 70 and 90 stops so with 200,
    /// and with 1000 after 19 and 54 s).
    IterationsStuck,
    Time,
}

/// Whether a Newton run that used up its iterations was still converging: fewer than
/// `STUCK_AFTER` steps (too few to tell), or its residual halved over its last quarter of
/// steps (at least the last 4).
fn converging(log: &[IterationLog]) -> bool {
    let steps = log.len().saturating_sub(1);
    if steps < STUCK_AFTER {
        return true;
    }
    let span = (steps / 4).max(4);
    log[steps].residual <= 0.5 * log[steps - span].residual
}

/// Newton steps below which a run that used up its iterations counts as converging.
const STUCK_AFTER: usize = 8;

impl<'a> Attempts<'a> {
    /// No run yet; the time budget starts now.
    fn new(
        problem: &'a ReducedProblem,
        settings: &'a HbSettings,
        reporter: &'a dyn Reporter,
    ) -> Self {
        Attempts {
            problem,
            settings,
            reporter,
            iterations: 0,
            log: Vec::new(),
            reasons: Vec::new(),
            deadline: Instant::now() + Duration::from_secs_f64(settings.max_seconds.min(1e9)),
            exhausted: None,
            krylov_hint: KrylovHint::default(),
        }
    }

    /// Newton settings for rung `h` of the ladder (the same oversampling ratio as at H).
    fn newton_settings(&self, h: usize, c: f64, smoothing: f64) -> NewtonSettings {
        let (top, samples) = (self.settings.harmonics, self.settings.samples);
        let spline = matches!(self.problem.basis, TimeBasis::Spline(_));
        NewtonSettings {
            // A spline basis samples at its Gauss points on every rung (N stays a multiple
            // of S); the rungs keep its low discrete frequencies.
            samples: if h == top || spline {
                samples
            } else {
                (samples * h).div_ceil(top.max(1)).max(2 * h + 1)
            },
            c,
            tolerance: self.settings.tolerance,
            max_iterations: self.settings.max_iterations,
            smoothing,
            krylov_hint: self.krylov_hint.clone(),
            ..Default::default()
        }
    }

    /// The problem at rung h: the full one borrowed, a truncation owned.
    fn problem_at(&self, h: usize) -> Cow<'a, ReducedProblem> {
        if h == self.problem.harmonics {
            Cow::Borrowed(self.problem)
        } else {
            Cow::Owned(self.problem.truncate(h))
        }
    }

    fn run(
        &mut self,
        problem: &ReducedProblem,
        settings: &NewtonSettings,
        start: &[f64],
    ) -> NewtonOutcome {
        if Instant::now() >= self.deadline {
            self.exhausted = Some(Budget::Time);
            return NewtonOutcome {
                multipliers: start.to_vec(),
                converged: false,
                iterations: 0,
                relative_residual: f64::NAN,
                log: Vec::new(),
                reason: format!(
                    "the time budget harmonic_balance.solver.max_seconds = {} s ran out after {} Newton iterations, before a new Newton run",
                    self.settings.max_seconds, self.iterations
                ),
            };
        }
        let o = reduced::newton_until(problem, settings, start, self.reporter, Some(self.deadline));
        // The pipeline's own limits (not a smoothing level's shorter one) are what ran out.
        if !o.converged && Instant::now() >= self.deadline {
            self.exhausted = Some(Budget::Time);
        } else if !o.converged && o.iterations >= self.settings.max_iterations {
            // A run still converging makes the budget the cause, whatever ran out before.
            let budget = if converging(&o.log) {
                Budget::Iterations
            } else {
                Budget::IterationsStuck
            };
            if self.exhausted.is_none_or(|e| e == Budget::IterationsStuck) {
                self.exhausted = Some(budget);
            }
        }
        self.iterations += o.iterations;
        self.log.extend(o.log.iter().cloned());
        o
    }

    /// Continuation in the smoothing μ at harmonic h, from μ = 0.3 F (F the linear solution's
    /// implied force) by a factor 0.3 per level down to below the tolerance; each level starts
    /// from the last solution, a failed level narrows the factor. The last step solves the
    /// exact law (μ = 0), which then starts within the tolerance. If the path turns back (a
    /// fold in μ, where no nearby smoothed solution exists), the exact law is tried from the
    /// last point reached, or with `OnFold::Stop` the run fails there.
    fn smoothed(&mut self, h: usize, c: f64, start: &[f64], on_fold: OnFold) -> NewtonOutcome {
        let problem = self.problem_at(h);
        self.smoothed_on(&problem, c, start, on_fold)
    }

    /// `smoothed` on a given problem (a ladder rung, a heavier-damped scene).
    fn smoothed_on(
        &mut self,
        problem: &ReducedProblem,
        c: f64,
        start: &[f64],
        on_fold: OnFold,
    ) -> NewtonOutcome {
        let mut settings = self.newton_settings(problem.harmonics, c, 0.0);
        let force = reduced::linear_force(problem, settings.samples, c);
        let mut levels = Levels::new(force, self.settings.tolerance, start.to_vec());
        let mut fold = None;
        // Levels failed so far: with a fallback at hand (`OnFold::Stop`), the second failure,
        // or a first one by short steps (`short_steps`) or rising ones (`LEVEL_RISE`), is
        // taken as the fold (one narrowing lets the 0.5%-damped strip pass a level that
        // cycles by full steps at H = 60 and 70; at H = 80 and 100 the path folds, and every
        // narrowed level fails again).
        let mut failures = 0;
        while let Some(mu) = levels.next() {
            self.level(&mut settings, mu, force);
            if on_fold == OnFold::Stop {
                (settings.hover, settings.rise) = (LEVEL_HOVER, LEVEL_RISE);
            }
            let o = self.run(problem, &settings, &levels.x);
            if self.exhausted == Some(Budget::Time) {
                return o; // its reason names the iteration the time ran out at
            }
            if o.converged {
                if let Some(exact) = self.settled_exact(problem, c, &o, mu / force) {
                    return exact;
                }
                levels.passed(mu, o.multipliers);
            } else if o.iterations >= self.settings.max_iterations {
                break; // this run is out of the budget: no fold to report
            } else if !levels.can_narrow()
                || (on_fold == OnFold::Stop
                    && (failures >= 1 || short_steps(&o.log) || reduced::rose(&o.log)))
            {
                fold = Some(levels.reached());
                break;
            } else {
                failures += 1;
                levels.narrow();
            }
        }
        let x = levels.x;
        if let (Some(at), OnFold::Stop) = (fold, on_fold) {
            return NewtonOutcome {
                multipliers: x,
                converged: false,
                iterations: 0,
                relative_residual: f64::NAN,
                log: Vec::new(),
                reason: fold_reason(at),
            };
        }
        let mut o = self.exact_law_at_end(problem, c, &x, force);
        if let (false, Some(at)) = (o.converged, fold) {
            o.reason = format!(
                "{}, and the exact law from there: {}",
                fold_reason(at),
                o.reason
            );
        }
        o
    }

    /// `settings` for one smoothing level at μ (F the linear solution's force): solved to
    /// max(tol, 0.1 μ/F) in at most `LEVEL_ITERATIONS`, failing early when cycling by full
    /// steps (`LEVEL_STAGNATION`). The one definition for `smoothed_on` and `joint`.
    fn level(&self, settings: &mut NewtonSettings, mu: f64, force: f64) {
        settings.smoothing = mu;
        settings.tolerance = self.settings.tolerance.max(0.1 * mu / force);
        settings.max_iterations = LEVEL_ITERATIONS.min(self.settings.max_iterations);
        settings.stagnation = LEVEL_STAGNATION;
    }

    /// Why a smoothing level run with `settings` failed, naming a level's own iteration limit
    /// (`LEVEL_ITERATIONS`) as such, not as the pipeline's `max_iterations`.
    fn level_reason(&self, o: &NewtonOutcome, settings: &NewtonSettings) -> String {
        let own = settings.max_iterations;
        if o.iterations >= own && own < self.settings.max_iterations {
            format!("its {own} iterations, a smoothing level's limit, ran out")
        } else {
            o.reason.clone()
        }
    }

    /// The exact law from the solution of a smoothing level `level` at μ = `relative_mu`·F on
    /// `problem` whose active set has settled (converged in at most one step, its active
    /// samples unchanged, μ ≤ `SETTLED_SMOOTHING` F), in at most `SETTLED_EXACT_ITERATIONS`;
    /// `None` when the level had not settled, the pipeline's `max_iterations` leaves no room
    /// for the try, or the exact law did not converge within it (the levels then go on from
    /// `level`).
    fn settled_exact(
        &mut self,
        problem: &ReducedProblem,
        c: f64,
        level: &NewtonOutcome,
        relative_mu: f64,
    ) -> Option<NewtonOutcome> {
        let active = |l: Option<&IterationLog>| l.map(|l| l.active_samples);
        let settled = level.iterations <= 1
            && active(level.log.first()) == active(level.log.last())
            && relative_mu <= SETTLED_SMOOTHING;
        if !settled || self.settings.max_iterations <= SETTLED_EXACT_ITERATIONS {
            return None;
        }
        let o = self.exact_law(
            problem,
            c,
            &level.multipliers,
            (1, SETTLED_EXACT_ITERATIONS),
        );
        o.converged.then_some(o)
    }

    /// The Newton on the exact law (μ = 0) from a smoothing level's solution `x`, taking at
    /// least `min_iterations` and at most `max_iterations` steps.
    fn exact_law(
        &mut self,
        problem: &ReducedProblem,
        c: f64,
        x: &[f64],
        (min_iterations, max_iterations): (usize, usize),
    ) -> NewtonOutcome {
        let mut settings = self.newton_settings(problem.harmonics, c, 0.0);
        (settings.min_iterations, settings.max_iterations) = (min_iterations, max_iterations);
        self.run(problem, &settings, x)
    }

    /// `exact_law` from a continuation's end point `x`, with the pipeline's `max_iterations`
    /// and at least one step to polish it onto the exact law's active set (none when nothing
    /// penetrates, `force` = 0: λ = 0 is then exact).
    fn exact_law_at_end(
        &mut self,
        problem: &ReducedProblem,
        c: f64,
        x: &[f64],
        force: f64,
    ) -> NewtonOutcome {
        let bounds = (usize::from(force > 0.0), self.settings.max_iterations);
        self.exact_law(problem, c, x, bounds)
    }

    /// The joint continuation (docs/method.md, "Globalization"): the smoothing levels of
    /// `smoothed_on` from λ = 0, with the damping scaled by `joint_scale`, so each level is a
    /// heavier-damped problem until the damping is the scene's own. A failed level narrows
    /// the step in μ (and so in the damping), unless it ran out of `max_iterations`; a level
    /// converged in two iterations or fewer widens it back towards 0.3. Returns the ratios ζ
    /// passed through.
    fn joint(&mut self, c: f64, heavier: Heavier, zeta: f64) -> Option<(NewtonOutcome, Vec<f64>)> {
        let (own, top) = (self.problem, DAMPED_START / zeta);
        let mut settings = self.newton_settings(own.harmonics, c, 0.0);
        let force = reduced::linear_force(own, settings.samples, c);
        let start = vec![0.0; own.linear_gap.len()];
        let mut levels = Levels::new(force, self.settings.tolerance, start);
        let (mut path, mut heavy) = (Vec::new(), None);
        while let Some(mu) = levels.next() {
            let scale = joint_scale(top, mu / force);
            self.level(&mut settings, mu, force);
            let o = self.run_scaled(&mut heavy, heavier, scale, &settings, &levels.x)?;
            if o.converged {
                if path.last() != Some(&(zeta * scale)) {
                    path.push(zeta * scale);
                }
                if o.iterations <= 2 {
                    levels.widen();
                }
                if scale == 1.0 {
                    if let Some(exact) = self.settled_exact(own, c, &o, mu / force) {
                        return Some((exact, path));
                    }
                }
                levels.passed(mu, o.multipliers);
            } else if !levels.can_narrow() || o.iterations >= self.settings.max_iterations {
                self.reasons.push(format!(
                    "continuation in the damping with the smoothing: no level below μ = {:.1e}·F \
                     at ζ = {:.2e}: {}",
                    levels.reached(),
                    zeta * scale,
                    self.level_reason(&o, &settings)
                ));
                return None;
            } else {
                levels.narrow();
            }
        }
        let o = self.exact_law_at_end(own, c, &levels.x, force);
        if !o.converged {
            self.reasons.push(format!(
                "continuation in the damping with the smoothing, the exact law from its end: {}",
                o.reason
            ));
            return None;
        }
        if path.is_empty() {
            path.push(zeta * top); // nothing penetrated: λ = 0 at every level
        }
        if path.last() != Some(&zeta) {
            path.push(zeta);
        }
        Some((o, path))
    }

    /// One Newton run on the scene with its damping scaled by `scale` (the scene's own at 1),
    /// the heavier problem kept in `heavy` for the next level at the same scale; `None` when
    /// it cannot be formed or the time budget is spent (the reason recorded).
    fn run_scaled(
        &mut self,
        heavy: &mut Option<(f64, ReducedProblem)>,
        heavier: Heavier,
        scale: f64,
        settings: &NewtonSettings,
        x: &[f64],
    ) -> Option<NewtonOutcome> {
        let o = if scale == 1.0 {
            self.run(self.problem, settings, x)
        } else {
            let problem = match heavy.take() {
                Some((s, p)) if s == scale => p,
                _ => self.heavier_problem(heavier, scale)?,
            };
            let o = self.run(&problem, settings, x);
            *heavy = Some((scale, problem));
            o
        };
        (self.exhausted != Some(Budget::Time)).then_some(o)
    }

    /// The plain Newton, then the damping continuation, then the harmonic ladder, at one c.
    fn at(&mut self, c: f64, heavier: Option<(Heavier, f64)>) -> Option<(NewtonOutcome, Route)> {
        let (h, nc) = (self.problem.harmonics, self.problem.nodes);
        let zero = vec![0.0; nc * (2 * h + 1)];
        // Past a fold, the damping continuation is a better bet than the exact law from there.
        let on_fold = match heavier {
            Some(_) => OnFold::Stop,
            None => OnFold::ExactLaw,
        };
        let o = self.smoothed(h, c, &zero, on_fold);
        if o.converged {
            return Some((o, Route::laddered(vec![h])));
        }
        self.reasons
            .push(format!("direct at c = {c:.3e}: {}", o.reason));
        if let Some((heavier, zeta)) = heavier {
            if let Some((o, damping)) = self.joint(c, heavier, zeta) {
                let ladder = vec![h];
                return Some((o, Route { ladder, damping }));
            }
        }
        let (o, ladder) = self.ladder(c)?;
        Some((o, Route::laddered(ladder)))
    }

    /// `heavier(scale)`, or `None` with the reason recorded (or the time budget spent).
    fn heavier_problem(&mut self, heavier: Heavier, scale: f64) -> Option<ReducedProblem> {
        if Instant::now() >= self.deadline {
            self.exhausted = Some(Budget::Time);
            return None;
        }
        heavier(scale)
            .map_err(|e| self.reasons.push(format!("damping continuation: {e}")))
            .ok()
    }

    /// The harmonic ladder H/8, H/4, H/2, H from λ = 0, each rung warm-starting the next.
    fn ladder(&mut self, c: f64) -> Option<(NewtonOutcome, Vec<usize>)> {
        let (h, nc) = (self.problem.harmonics, self.problem.nodes);
        if h < 2 || self.exhausted == Some(Budget::Time) {
            return None;
        }
        let mut rungs: Vec<usize> = [h / 8, h / 4, h / 2]
            .into_iter()
            .filter(|&r| r >= 1)
            .collect();
        rungs.dedup();
        rungs.push(h);
        let (mut x, mut prev) = (vec![0.0; nc * 3], 1);
        for &rung in &rungs {
            let start = reduced::pad(&x, nc, prev, rung);
            let o = self.smoothed(rung, c, &start, OnFold::ExactLaw);
            if !o.converged {
                self.reasons.push(format!(
                    "ladder at c = {c:.3e} failed at H = {rung}: {}",
                    o.reason
                ));
                return None;
            }
            if rung == h {
                return Some((o, rungs));
            }
            (x, prev) = (o.multipliers, rung);
        }
        None
    }
}

/// The smoothing continuation alone at the problem's own H, from `start`, with c and the
/// settings' N fixed: a sweep's fixed-ω corrector where the plain Newton fails (where contact
/// starts on a lightly damped resonance, the exact law's Newton from the open state cycles).
pub(super) fn smoothed_from(
    problem: &ReducedProblem,
    settings: &HbSettings,
    c: f64,
    start: &[f64],
    reporter: &dyn Reporter,
) -> NewtonOutcome {
    let mut attempts = Attempts::new(problem, settings, reporter);
    let mut o = attempts.smoothed(problem.harmonics, c, start, OnFold::ExactLaw);
    o.iterations = attempts.iterations;
    o
}

/// Solve the reduced contact problem (23) with the globalization above; `heavier` gives the
/// damping continuation its problems (`None`: no continuation in the damping).
pub(super) fn solve_contact(
    system: &System,
    problem: &ReducedProblem,
    settings: &HbSettings,
    heavier: Option<Heavier>,
    reporter: &dyn Reporter,
) -> Result<ContactSolution> {
    let c = automatic_c(problem, settings)?;
    let zeta = rayleigh_damping_ratio(system.rayleigh, system.omega);
    let heavier = heavier.filter(|_| zeta > 0.0 && zeta < DAMPED_START);
    let mut attempts = Attempts::new(problem, settings, reporter);
    let found = [c, 0.1 * c].into_iter().find_map(|c_try| {
        // Out of time: no further attempt can start.
        if attempts.exhausted == Some(Budget::Time) {
            return None;
        }
        let at = attempts.at(c_try, heavier.map(|h| (h, zeta)));
        at.map(|(o, route)| (o, route, c_try))
    });
    reporter.task_done("contact Newton");
    let Some((outcome, route, c)) = found else {
        let failed = NewtonOutcome {
            multipliers: Vec::new(),
            converged: false,
            iterations: attempts.iterations,
            relative_residual: attempts.log.last().map_or(f64::NAN, |l| l.residual),
            log: attempts.log,
            reason: attempts.reasons.join("; "),
        };
        return Err(stall_diagnosis(
            system,
            settings,
            &failed,
            attempts.exhausted,
        ));
    };
    let (samples, mut outcome, knob_check) = knobs::adapt_samples(
        problem,
        outcome,
        settings.samples,
        c,
        settings.tolerance,
        &attempts.krylov_hint,
        reporter,
    );
    outcome.iterations = attempts.iterations;
    outcome.log = attempts.log;
    let gaps = problem.gap(&outcome.multipliers);
    let complementarity = measure_complementarity(problem, &outcome.multipliers, &gaps, samples);
    Ok(ContactSolution {
        harmonics: settings.harmonics,
        samples,
        c,
        multipliers: outcome.multipliers.clone(),
        gaps,
        newton: outcome,
        ladder: route.ladder,
        damping_path: route.damping,
        complementarity,
        knob_check,
        compliance: Some(std::sync::Arc::new(problem.compliance.clone())),
    })
}

/// The warning a solve that converged only through the damping continuation, the harmonic
/// ladder or the softer c calls for (`None` for a direct one): the direct continuation
/// folded or stalled, which happens near a resonance where the contact problem has several
/// periodic states, and the detour reached one of them.
pub(super) fn detour_warning(
    problem: &ReducedProblem,
    settings: &HbSettings,
    solution: &ContactSolution,
) -> Option<String> {
    let direct_c = automatic_c(problem, settings).ok()?;
    let route = super::solution::detour(&solution.ladder, &solution.damping_path);
    let softer = (solution.c < direct_c).then(|| format!("the softer c = {:.3e} N/m", solution.c));
    let how: Vec<String> = [route, softer].into_iter().flatten().collect();
    if how.is_empty() {
        return None;
    }
    Some(format!(
        "the direct solve at H = {} did not converge and the answer was reached through {} \
         ({} Newton iterations): near a resonance the contact problem can have several periodic \
         states, and this is one of them; `hbcontact sweep` shows the branches through this \
         frequency and the stability check whether this one is stable; a lower \
         harmonic_balance.harmonics, or stiffness damping (damping.beta) where the scene has \
         none, can make the solve direct",
        problem.harmonics,
        how.join(" at "),
        solution.newton.iterations
    ))
}

fn stall_diagnosis(
    system: &System,
    settings: &HbSettings,
    outcome: &NewtonOutcome,
    exhausted: Option<Budget>,
) -> Error {
    let advice = stall_advice(settings, system.rayleigh, &system.basis, outcome, exhausted);
    let last = outcome.log.last();
    let what = match exhausted {
        Some(Budget::Iterations) => "ran out of iterations",
        Some(Budget::Time) => "ran out of time",
        Some(Budget::IterationsStuck) | None => "stalled",
    };
    Error::NotConverged(format!(
        "the contact Newton {what} after {} iterations: {}; relative residual {}, {} active \
         samples. To fix: {}",
        outcome.iterations,
        outcome.reason,
        if outcome.relative_residual.is_finite() {
            format!("{:.3e}", outcome.relative_residual)
        } else {
            "not evaluated".to_string()
        },
        last.map_or(0, |l| l.active_samples),
        advice.join("; ")
    ))
}

/// What to change after a failed contact solve, most specific first: the budget it ran out
/// of, a Newton step whose linear solve stalled, then the scene's knobs.
fn stall_advice(
    settings: &HbSettings,
    rayleigh: Option<(f64, f64)>,
    basis: &TimeBasis,
    outcome: &NewtonOutcome,
    exhausted: Option<Budget>,
) -> Vec<String> {
    let mut advice = Vec::new();
    let h = settings.harmonics;
    match exhausted {
        Some(Budget::Iterations) => advice.push(format!(
            "raise harmonic_balance.solver.max_iterations (now {}, the default 200): it ran out before the Newton converged",
            settings.max_iterations
        )),
        Some(Budget::Time) => advice.push(format!(
            "raise harmonic_balance.solver.max_seconds (now {} s): the solve ran out of time after {} Newton iterations",
            settings.max_seconds, outcome.iterations
        )),
        Some(Budget::IterationsStuck) | None => {}
    }
    if outcome.reason.contains(crate::linalg::KRYLOV_STALL) {
        advice.push(
            "the Newton steps' linear solve stalled (GMRES with both of its preconditioners, \
             and the dense step too large to fall back on), so a fold reported with it may be \
             the solver's: use fewer harmonics or fewer contact nodes (a coarser mesh at the \
             contact), where the dense step is affordable"
                .to_string(),
        );
    }
    if settings.samples < 16 * h {
        advice.push(format!(
            "raise harmonic_balance.samples (now {}; 16·H = {} converges reliably)",
            settings.samples,
            16 * h
        ));
    }
    // The scene's own changes, in the order they were measured to help: on the 0.28%-damped
    // reference strip at H = 70 and 90 (mass-proportional damping only), damping.beta = 1e-8
    // or a lower H converge, c_scale 0.3 does not (nor 0.1 at H = 70).
    match rayleigh {
        None => advice.push("add damping (the scene has none): damping.beta damps the mesh's high modes that impacts excite".into()),
        Some((_, 0.0)) => advice.push(
            "add stiffness-proportional damping damping.beta (e.g. 1e-8 to 1e-7 s for steel at mm-size elements): with mass-proportional damping alone the mesh's high modes, which every impact excites, stay undamped".into(),
        ),
        _ => {}
    }
    advice.push(match basis {
        TimeBasis::Spline(s) => format!(
            "lower harmonic_balance.basis.spline.segments (now {})",
            s.segments
        ),
        TimeBasis::Fourier => format!("lower harmonic_balance.harmonics (now {h})"),
    });
    if settings.c_scale >= 1.0 {
        advice.push(format!(
            "lower harmonic_balance.solver.c_scale (now {}; try 0.3 or 0.1)",
            settings.c_scale
        ));
    }
    advice.push(
        "make sure contact.mass is `redistributed` (contact nodes with inertia make impacts that \
         no truncated Fourier series resolves)"
            .to_string(),
    );
    if exhausted == Some(Budget::IterationsStuck) {
        advice.push(format!(
            "raising harmonic_balance.solver.max_iterations (now {}) is unlikely to help: each Newton run that used them up had stopped converging (its last quarter of steps did not halve its residual)",
            settings.max_iterations
        ));
    }
    advice
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a Newton run that used up its iterations counts as converging when its
    /// last quarter of steps (at least 4) halved its residual, or it took fewer than 8; one
    /// hovering does not, and then the diagnosis does not open with "raise max_iterations"
    /// but says it is unlikely to help, after the scene's changes, which lead with
    /// stiffness damping where the scene has none (measured on the 0.28%-damped strip at
    /// H = 70 and 90: β = 1e-8 converges there, 1000 iterations or c_scale 0.3 do not;
    /// tests/hard.rs `a_lightly_damped_strip_that_stops_is_told_the_change_that_converges_it`).
    #[test]
    fn a_hovering_newton_is_not_told_to_take_more_iterations() {
        let log = |residuals: &[f64]| -> Vec<IterationLog> {
            let entry = |&residual: &f64| IterationLog {
                residual,
                active_samples: 0,
                step: 1.0,
            };
            residuals.iter().map(entry).collect()
        };
        let falling: Vec<f64> = (0..13).map(|i| 0.7f64.powi(i)).collect();
        let hovering: Vec<f64> = (0..13)
            .map(|i| 1e-3 * (1.0 + 0.1 * (i % 3) as f64))
            .collect();
        assert!(converging(&log(&falling)));
        assert!(!converging(&log(&hovering)));
        assert!(converging(&log(&hovering[..8])), "7 steps: too few to tell");
        let settings = HbSettings {
            harmonics: 70,
            samples: 1120,
            c_scale: 1.0,
            tolerance: 1e-8,
            max_iterations: 200,
            max_seconds: 1e9,
        };
        let failed = NewtonOutcome {
            multipliers: Vec::new(),
            converged: false,
            iterations: 872,
            relative_residual: 3e-4,
            log: log(&hovering),
            reason: "reached max_iterations = 200".into(),
        };
        let fourier = TimeBasis::Fourier;
        let stuck = Some(Budget::IterationsStuck);
        let advice = stall_advice(&settings, Some((43.0, 0.0)), &fourier, &failed, stuck);
        assert!(advice[0].contains("damping.beta"), "{advice:?}");
        assert!(
            advice[1].contains("harmonic_balance.harmonics"),
            "{advice:?}"
        );
        let last = advice.last().expect("advice");
        assert!(last.contains("unlikely to help"), "{advice:?}");
        assert!(!advice
            .iter()
            .any(|a| a.starts_with("raise harmonic_balance.solver.max_it")));
        let budget = Some(Budget::Iterations);
        let advice = stall_advice(&settings, Some((43.0, 0.0)), &fourier, &failed, budget);
        assert!(advice[0].starts_with("raise harmonic_balance.solver.max_iterations"));
    }

    /// TEST GOAL: a failed solve whose Newton steps' Krylov solves stalled is told so first
    /// (the fold it may report is then the solver's) with what makes the dense step
    /// affordable; a failure without such a stall gets the scene's knobs only, and a scene
    /// damped by mass alone is told to add damping.beta.
    #[test]
    fn a_stalled_linear_solve_is_diagnosed_before_the_scenes_knobs() {
        let settings = HbSettings {
            harmonics: 40,
            samples: 640,
            c_scale: 1.0,
            tolerance: 1e-8,
            max_iterations: 200,
            max_seconds: 10.0,
        };
        let failed = |reason: String| NewtonOutcome {
            multipliers: Vec::new(),
            converged: false,
            iterations: 199,
            relative_residual: 1e-5,
            log: Vec::new(),
            reason,
        };
        let stalled = failed(format!(
            "direct at c = 1e10: {} at relative residual 2.9e-2",
            crate::linalg::KRYLOV_STALL
        ));
        let fourier = TimeBasis::Fourier;
        let advice = stall_advice(&settings, Some((10.0, 0.0)), &fourier, &stalled, None);
        assert!(advice[0].contains("linear solve stalled"), "{advice:?}");
        assert!(advice[0].contains("fewer contact nodes"), "{advice:?}");
        assert!(
            advice.iter().any(|a| a.contains("damping.beta")),
            "{advice:?}"
        );
        let folded = failed("the smoothing path turned back".into());
        let advice = stall_advice(&settings, Some((10.0, 1e-7)), &fourier, &folded, None);
        assert!(
            !advice.iter().any(|a| a.contains("linear solve")),
            "{advice:?}"
        );
        assert!(
            !advice.iter().any(|a| a.contains("damping.beta")),
            "{advice:?}"
        );
    }

    /// TEST GOAL: a smoothing level that ran out of its own `LEVEL_ITERATIONS` is reported as
    /// such, not as the pipeline's `max_iterations` (which it is not); a run that reached the
    /// pipeline's limit keeps the Newton's own reason naming it.
    #[test]
    fn a_levels_own_iteration_limit_is_not_named_as_the_pipelines() {
        let problem = ReducedProblem::from_compliance(1, 1, |_, _, _| c64::new(1.0, 0.0));
        let settings = HbSettings {
            harmonics: 1,
            samples: 16,
            c_scale: 1.0,
            tolerance: 1e-8,
            max_iterations: 200,
            max_seconds: 10.0,
        };
        let attempts = Attempts::new(&problem, &settings, &crate::Silent);
        let mut level = attempts.newton_settings(1, 1.0, 0.0);
        attempts.level(&mut level, 0.1, 1.0);
        let failed = |iterations: usize| NewtonOutcome {
            multipliers: Vec::new(),
            converged: false,
            iterations,
            relative_residual: 1.0,
            log: Vec::new(),
            reason: format!("reached max_iterations = {iterations}"),
        };
        let own = attempts.level_reason(&failed(LEVEL_ITERATIONS), &level);
        assert!(own.contains("a smoothing level's limit"), "{own}");
        assert!(!own.contains("max_iterations"), "{own}");
        level.max_iterations = 200;
        let pipelines = attempts.level_reason(&failed(200), &level);
        assert_eq!(pipelines, "reached max_iterations = 200");
    }

    /// TEST GOAL: the smoothing levels follow docs/method.md's step 2: μ = 0.3^k F until
    /// below 0.1 × tolerance × F (13 levels at 1e-6), none when nothing penetrates; a failed
    /// level narrows the factor to its square root four times (0.548, 0.740, 0.860, 0.927),
    /// then no more (the fifth would exceed 0.95: the path turned back), and an easy level
    /// widens it back to 0.3 in steps of squaring.
    #[test]
    fn smoothing_levels_fall_by_0_3_and_narrow_to_square_roots_until_0_95() {
        let mut levels = Levels::new(2.0, 1e-6, vec![0.0]);
        let mut mus = Vec::new();
        while let Some(mu) = levels.next() {
            mus.push(mu / 2.0);
            levels.passed(mu, vec![mu]);
        }
        assert_eq!(mus.len(), 13, "{mus:?}");
        assert!(mus
            .iter()
            .enumerate()
            .all(|(k, &m)| (m / 0.3f64.powi(k as i32 + 1) - 1.0).abs() < 1e-12));
        assert!(mus[12] * 0.3 <= 1e-7 && mus[12] > 1e-7);
        assert_eq!(levels.x, vec![2.0 * mus[12]]);
        assert!(Levels::new(0.0, 1e-6, vec![]).next().is_none());
        let mut narrowed = Vec::new();
        while levels.can_narrow() {
            levels.narrow();
            narrowed.push(levels.ratio);
        }
        let expected = [0.548, 0.740, 0.860, 0.927];
        assert_eq!(narrowed.len(), 4, "{narrowed:?}");
        assert!(
            narrowed
                .iter()
                .zip(expected)
                .all(|(a, b)| (a - b).abs() < 1e-3),
            "{narrowed:?}"
        );
        levels.widen();
        assert!((levels.ratio - 0.860).abs() < 1e-3);
        (0..3).for_each(|_| levels.widen());
        assert_eq!(levels.ratio, 0.3);
    }

    /// TEST GOAL: the joint continuation's damping starts at the 5% scene on its first level
    /// (μ = 0.3 F), falls monotonically, reaches the scene's own exactly `JOINT_LEVELS`
    /// levels of 0.3 later and stays there (the scale is exactly 1, so no heavier problem is
    /// factored for the scene's own levels).
    #[test]
    fn joint_damping_falls_from_the_top_to_the_scenes_own_over_its_levels() {
        let top = 8.95;
        assert!((joint_scale(top, 0.3) / top - 1.0).abs() < 1e-12);
        let levels: Vec<f64> = (0..=JOINT_LEVELS + 3)
            .map(|j| joint_scale(top, 0.3 * 0.3f64.powi(j)))
            .collect();
        assert!(levels
            .windows(2)
            .take(JOINT_LEVELS as usize)
            .all(|w| w[1] < w[0]));
        let own = &levels[JOINT_LEVELS as usize..];
        assert!(own.iter().all(|&s| s == 1.0), "{levels:?}");
        // Halfway in ln μ, halfway in ln s.
        let half = joint_scale(top, 0.3 * 0.3f64.powf(JOINT_LEVELS as f64 / 2.0));
        assert!((half / top.sqrt() - 1.0).abs() < 1e-12, "{half}");
    }
}
