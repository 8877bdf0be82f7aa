//! The attempts of one contact solve, cheapest first (see `globalize`): the smoothing
//! continuation from λ = 0, the joint continuation in damping and μ, the harmonic ladder
//! H/8, H/4, H/2, H, each under the two budgets (iterations per run, wall time in all).

use std::borrow::Cow;
use std::time::{Duration, Instant};

use crate::hbm::basis::TimeBasis;
use crate::hbm::problem::ReducedProblem;
use crate::hbm::reduced::{self, IterationLog, NewtonOutcome, NewtonSettings};
use crate::hbm::step::KrylovHint;
use crate::hbm::HbSettings;
use crate::progress::Reporter;

use super::*;

/// What the smoothing continuation does where its path turns back (a fold in μ).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum OnFold {
    /// Try the exact law from the last point reached.
    ExactLaw,
    /// Give up: the caller has a better fallback.
    Stop,
}

/// How a converged contact solve got there: the harmonic ladder it climbed ([H] when direct)
/// and the damping ratios at the fundamental it continued through (empty when it did not).
pub(super) struct Route {
    pub(super) ladder: Vec<usize>,
    pub(super) damping: Vec<f64>,
}

impl Route {
    /// Up the ladder `ladder` (just [H]: direct), without the damping continuation.
    fn laddered(ladder: Vec<usize>) -> Route {
        let damping = Vec::new();
        Route { ladder, damping }
    }
}

/// Every Newton run of one contact solve: iterations, log and why each attempt failed.
pub(super) struct Attempts<'a> {
    pub(super) problem: &'a ReducedProblem,
    pub(super) settings: &'a HbSettings,
    pub(super) reporter: &'a dyn Reporter,
    pub(super) iterations: usize,
    pub(super) log: Vec<IterationLog>,
    pub(super) reasons: Vec<String>,
    /// When the time budget ends.
    deadline: Instant,
    /// The budget a failed run ran out of, if any.
    pub(super) exhausted: Option<Budget>,
    /// The preconditioner every run's matrix-free steps start with: the one that served the
    /// last step (`step::KrylovHint`).
    pub(super) krylov_hint: KrylovHint,
}

/// The budgets of one contact solve, as a failed solve ran out of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Budget {
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
pub(super) fn converging(log: &[IterationLog]) -> bool {
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
    pub(super) fn new(
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
    pub(super) fn newton_settings(&self, h: usize, c: f64, smoothing: f64) -> NewtonSettings {
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

    pub(super) fn run(
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
    pub(super) fn smoothed(
        &mut self,
        h: usize,
        c: f64,
        start: &[f64],
        on_fold: OnFold,
    ) -> NewtonOutcome {
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
    pub(super) fn level(&self, settings: &mut NewtonSettings, mu: f64, force: f64) {
        settings.smoothing = mu;
        settings.tolerance = self.settings.tolerance.max(0.1 * mu / force);
        settings.max_iterations = LEVEL_ITERATIONS.min(self.settings.max_iterations);
        settings.stagnation = LEVEL_STAGNATION;
    }

    /// Why a smoothing level run with `settings` failed, naming a level's own iteration limit
    /// (`LEVEL_ITERATIONS`) as such, not as the pipeline's `max_iterations`.
    pub(super) fn level_reason(&self, o: &NewtonOutcome, settings: &NewtonSettings) -> String {
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
    pub(super) fn at(
        &mut self,
        c: f64,
        heavier: Option<(Heavier, f64)>,
    ) -> Option<(NewtonOutcome, Route)> {
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
    pub(super) fn ladder(&mut self, c: f64) -> Option<(NewtonOutcome, Vec<usize>)> {
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
