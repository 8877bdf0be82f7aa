//! Harmonics chosen per solve: `harmonic_balance.harmonics: {min, max}` with a tolerance τ on
//! the answer (the body's vibration and the mean contact force), instead of one H fixed in
//! advance.
//!
//! Glossary and formulas:
//! - levels H_0 = H_min, H_{j+1} = min(2 H_j, H_max), each at N_j = 16 H_j samples (at
//!   least 64);
//! - the truncation estimate e_j of level j: the change of the answer from the level below
//!   to H_j (at H_0 from ⌊H_0/2⌋, a Newton from the truncated λ), `estimate_of`: the larger
//!   of the recovered field's change ‖z_j − z_{j−1}‖ / ‖z_j‖ (every free dof, RMS over the
//!   period; the coarser state carries no harmonics above its H, so they count in full) and
//!   the mean contact force's (`knobs::mean_force_change`, floored where contact grazes);
//! - the solve stops at the first level whose e_j ≤ τ and whose knob check finds the answer
//!   independent of c (change ≤ `knobs::C_TOLERANCE`: the c-dependence of the sampled law is
//!   a truncation error too, and raising H is what the check advises), or at H_max, with a
//!   warning naming the estimate.
//!
//! e_j measures the error of the level below against H_j. Where the error falls at least as
//! 1/H, the error of H_j is at most e_j: the estimate is conservative for the state reported.
//! The field's change bounds what a probe reads only in the RMS over the body: the contact
//! face's own deformation moves more than a probe away from it (on the strip's upper branch
//! the field changes 2.3% in its first harmonic from H = 20 to 40 where the probe moves
//! 0.1%). The peak contact force of an impact converges more slowly and is not held to τ.
//!
//! Each level above H_0 starts its Newton from the level below, padded with zeros (the low
//! harmonics of a contact response change little with H); where that does not converge within
//! `globalize`'s warm budget, the globalized solve runs at that level from scratch.

use super::globalize;
use super::knobs::{self, C_TOLERANCE};
use super::problem::ReducedProblem;
use super::reduced::{self, NewtonSettings};
use super::{fourier, ContactSolution, HbSettings, LinearResponse, System, Timings};
use crate::contact::ContactOperator;
use crate::progress::Reporter;
use crate::Result;
use faer::c64;

/// A range of H to choose from and the tolerance the answer must meet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarmonicRange {
    /// The smallest and largest H tried (a single run starts at the settings' `harmonics`).
    pub min: usize,
    pub max: usize,
    /// The relative change of the answer from one level to the next that settles H.
    pub tolerance: f64,
}

/// How H was chosen (serialized into the summary).
#[derive(Clone, Debug, serde::Serialize, schemars::JsonSchema)]
pub struct HarmonicsChosen {
    /// The range and tolerance asked for.
    pub min: usize,
    pub max: usize,
    pub tolerance: f64,
    /// The levels solved, in order; the last is the H reported.
    pub levels: Vec<Level>,
    /// The last level's estimate met the tolerance and its knob check found no c-dependence.
    pub met: bool,
}

/// One level of the choice.
#[derive(Clone, Debug, serde::Serialize, schemars::JsonSchema)]
pub struct Level {
    pub harmonics: usize,
    /// The truncation estimate e: the relative change of the answer from the level below
    /// (from H/2 for the first); `None` where that state could not be solved.
    pub estimate: Option<f64>,
    /// The knob check's relative change from c to the second c at this level.
    pub c_change: Option<f64>,
    /// Newton iterations of the level (its knob checks and the first level's H/2 included).
    pub iterations: usize,
}

impl HarmonicsChosen {
    /// The H reported.
    pub fn chosen(&self) -> usize {
        self.levels.last().map_or(self.min, |l| l.harmonics)
    }

    /// "H = 40 of 10–80: the answer changes 0.62% from H = 20 (tolerance 1%)".
    pub fn describe(&self) -> String {
        let h = self.chosen();
        let from = match self.levels.len() {
            1 => h / 2,
            n => self.levels[n - 2].harmonics,
        };
        let change = match self.levels.last().and_then(|l| l.estimate) {
            Some(e) => format!("the answer changes {:.2}% from H = {from}", 100.0 * e),
            None => format!("the change from H = {from} is unknown"),
        };
        format!(
            "H = {h} of {}–{}: {change} (tolerance {}%)",
            self.min,
            self.max,
            100.0 * self.tolerance
        )
    }

    /// The warning of a choice that reached H_max without meeting the tolerance.
    pub fn warning(&self) -> Option<String> {
        if self.met {
            return None;
        }
        let last = self.levels.last()?;
        let below = self
            .levels
            .iter()
            .rev()
            .nth(1)
            .map_or(last.harmonics / 2, |l| l.harmonics);
        let estimate = match last.estimate {
            Some(e) if e > self.tolerance => format!(
                "the answer still changes by {:.2}% from H = {below} to H = {} (harmonic_balance.tolerance = {:.2}%)",
                100.0 * e,
                last.harmonics,
                100.0 * self.tolerance
            ),
            Some(_) => return None,
            None => format!(
                "the state at H = {below} could not be solved, so the truncation error at H = {} is not estimated",
                last.harmonics
            ),
        };
        Some(format!(
            "{estimate}: raise harmonic_balance.harmonics.max (now {}) or the damping",
            self.max
        ))
    }
}

/// The contact solve with H chosen in [settings.harmonics, range.max] (see the header);
/// `problem` is reduced at H_max at least, the levels are its truncations.
pub(super) fn solve(
    system: &System,
    (op, linear): (&ContactOperator, &LinearResponse),
    problem: &ReducedProblem,
    settings: &HbSettings,
    range: HarmonicRange,
    reporter: &dyn Reporter,
    timings: &mut Timings,
) -> Result<ContactSolution> {
    let mut h = settings.harmonics;
    let mut level = problem.truncate(h);
    let mut solution = super::solve_contact_timed(
        system,
        op,
        &level,
        &at_level(settings, h),
        reporter,
        timings,
    )?;
    let estimate = timed_check(timings, || {
        half_estimate((&level, linear, op), &solution, settings, reporter)
    });
    let mut chosen = HarmonicsChosen {
        min: h,
        max: range.max,
        tolerance: range.tolerance,
        levels: vec![level_of(&solution, estimate.0, estimate.1)],
        met: false,
    };
    let mut iterations = solution.newton.iterations + estimate.1;
    loop {
        chosen.met = settled(&chosen, range.tolerance);
        if chosen.met || h >= range.max {
            break;
        }
        let next = (2 * h).min(range.max);
        let finer = problem.truncate(next);
        let s = at_level(settings, next);
        reporter.progress("harmonics", 0, None, &format!("H = {h} → {next}"));
        let start = reduced::pad(&solution.multipliers, problem.nodes, h, next);
        let clock = std::time::Instant::now();
        let warm = globalize::solve_contact_from(&finer, &s, solution.c, &start, reporter);
        timings.newton += clock.elapsed().as_secs_f64();
        reporter.task_done("harmonics");
        let found = match warm {
            Some(found) => {
                timings.knob_check += found.knob_check.seconds;
                timings.newton -= found.knob_check.seconds;
                found
            }
            None => super::solve_contact_timed(system, op, &finer, &s, reporter, timings)?,
        };
        let change = timed_check(timings, || {
            let coarse = (&level, &solution.multipliers[..]);
            (
                estimate_of(coarse, (&finer, &found.multipliers), linear, op),
                0,
            )
        });
        chosen.levels.push(level_of(&found, Some(change.0), 0));
        iterations += found.newton.iterations;
        (h, level, solution) = (next, finer, found);
    }
    solution.newton.iterations = iterations;
    solution.harmonics_chosen = Some(chosen);
    Ok(solution)
}

/// The settings of level H (N = 16H, at least 64).
fn at_level(settings: &HbSettings, h: usize) -> HbSettings {
    HbSettings {
        harmonics: h,
        samples: HbSettings::default_samples(h),
        ..settings.clone()
    }
}

/// The level's estimate met the tolerance and its knob check found no c-dependence (or could
/// not tell).
fn settled(chosen: &HarmonicsChosen, tolerance: f64) -> bool {
    chosen.levels.last().is_some_and(|l| {
        l.estimate.is_some_and(|e| e <= tolerance) && l.c_change.is_none_or(|c| c <= C_TOLERANCE)
    })
}

fn level_of(solution: &ContactSolution, estimate: Option<f64>, extra: usize) -> Level {
    Level {
        harmonics: solution.harmonics,
        estimate,
        c_change: solution.knob_check.c_change,
        iterations: solution.newton.iterations + extra,
    }
}

/// The first level's estimate: the state at ⌊H/2⌋ by a Newton from the truncated λ, and
/// the change of the answer from it to the solution (with its Newton iterations); `None`
/// where ⌊H/2⌋ is 0 or its Newton does not converge.
fn half_estimate(
    (level, linear, op): (&ReducedProblem, &LinearResponse, &ContactOperator),
    solution: &ContactSolution,
    settings: &HbSettings,
    reporter: &dyn Reporter,
) -> (Option<f64>, usize) {
    let half = level.harmonics / 2;
    if half == 0 {
        return (None, 0);
    }
    let newton = NewtonSettings {
        samples: HbSettings::default_samples(half),
        c: solution.c,
        tolerance: settings.tolerance,
        max_iterations: settings.max_iterations.min(globalize::WARM_ITERATIONS),
        hover: globalize::WARM_HOVER,
        ..Default::default()
    };
    let x = &solution.multipliers;
    let (coarse, iterations) = half_state(level, x, &newton, reporter);
    let fine = (level, &x[..]);
    let change = coarse.map(|(p, c)| estimate_of((&p, &c), fine, linear, op));
    (change, iterations)
}

/// The state at ⌊H/2⌋ (≥ 1) of `problem` by the Newton `newton` from `x` truncated, with the
/// truncated problem and the Newton's iterations; `None` where that Newton does not
/// converge. Runs and sweep points alike.
pub(super) fn half_state(
    problem: &ReducedProblem,
    x: &[f64],
    newton: &NewtonSettings,
    reporter: &dyn Reporter,
) -> (Option<(ReducedProblem, Vec<f64>)>, usize) {
    let half = problem.harmonics / 2;
    let coarse = problem.truncate(half);
    let start = reduced::pad(x, problem.nodes, problem.harmonics, half);
    let o = reduced::newton(&coarse, newton, &start, reporter);
    (o.converged.then_some((coarse, o.multipliers)), o.iterations)
}

/// e: the change of the answer from the solution `coarse` of a truncation to `fine` (see the
/// header): the larger of the recovered field's change and the mean contact force's.
pub(super) fn estimate_of(
    (coarse_problem, coarse): (&ReducedProblem, &[f64]),
    (problem, fine): (&ReducedProblem, &[f64]),
    linear: &LinearResponse,
    op: &ContactOperator,
) -> f64 {
    let (mc, mf) = (coarse_problem.coefficients(), problem.coefficients());
    let field = field_change(linear, op, (coarse, mc), (fine, mf));
    let force = knobs::mean_force_change(coarse_problem, coarse, fine);
    field.max(force)
}

/// Run a check, its wall time counted as the knob check's.
fn timed_check<T>(timings: &mut Timings, f: impl FnOnce() -> (T, usize)) -> (T, usize) {
    let start = std::time::Instant::now();
    let out = f();
    timings.knob_check += start.elapsed().as_secs_f64();
    out
}

/// The field's change from the coarse multipliers `coarse` (`mc` coefficients per node) to
/// `fine` (`mf`), relative to the fine field, both in the RMS over the period and over every
/// free dof: ‖Δz‖ / ‖z‖ with Δz_k = Z_k⁻¹ Bᵀ (λ_k − λ'_k) (λ'_k = 0 above the coarse H) and
/// z_k = z_lin,k + Z_k⁻¹ Bᵀ λ_k, |z_0|² + ½ Σ_k≥1 |z_k|² (Parseval for z = Re Σ z_k e^{ikωt}).
/// `linear` holds z_lin and the solves with Z_k, not yet recovered.
pub(super) fn field_change(
    linear: &LinearResponse,
    op: &ContactOperator,
    (coarse, mc): (&[f64], usize),
    (fine, mf): (&[f64], usize),
) -> f64 {
    use rayon::prelude::*;
    let sq = |z: &[c64]| z.iter().map(|v| v.norm_sqr()).sum::<f64>();
    let (change, norm) = linear
        .factors
        .par_iter()
        .filter(|(&k, _)| 2 * k < mf)
        .map(|(&k, factor)| {
            let lam = fourier::node_phasors(fine, mf, k);
            let mut rhs = vec![op.b_free.mul_transpose_complex(&lam)];
            if 2 * k < mc {
                let below = fourier::node_phasors(coarse, mc, k);
                let diff: Vec<c64> = lam.iter().zip(below).map(|(a, b)| a - b).collect();
                rhs.push(op.b_free.mul_transpose_complex(&diff));
            }
            let mut solved = factor.solve_many(&rhs);
            let part = solved.swap_remove(0);
            let delta = solved.pop().unwrap_or_else(|| part.clone());
            let mut z = linear.free.get(&k).cloned().unwrap_or_default();
            z.resize(part.len().max(z.len()), c64::new(0.0, 0.0));
            z.iter_mut().zip(&part).for_each(|(zi, pi)| *zi += pi);
            let weight = if k == 0 { 1.0 } else { 0.5 };
            (weight * sq(&delta), weight * sq(&z))
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    if norm > 0.0 {
        (change / norm).sqrt()
    } else {
        change.sqrt()
    }
}
