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

use std::collections::BTreeMap;

use faer::c64;

use super::problem::ReducedProblem;
use super::reduced::NewtonOutcome;
use super::{fourier, knobs};
use super::{measure_complementarity, ContactSolution, HbSettings, System};
use crate::contact::ContactOperator;
use crate::fem::modes::rayleigh_damping_ratio;
use crate::progress::Reporter;
use crate::{Error, Result};

mod advice;
mod attempts;
mod levels;

pub(super) use advice::detour_warning;
use advice::*;
use attempts::*;
use levels::*;

/// Per harmonic k, one phasor per dof or row.
type Phasors = BTreeMap<usize, Vec<c64>>;

/// The linear gap r = B z_lin + B_p u_p − g̃0 as real coefficients, node-major: g̃0 is g0 at
/// k = 0 and the obstacle's gap harmonics ĝ_k, times the basis' projection factor γ_k.
pub(super) fn linear_gap(
    op: &ContactOperator,
    harmonics: usize,
    (free, motion): (&Phasors, &Phasors),
    basis: &crate::hbm::basis::TimeBasis,
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
        let moving = op.gap_harmonics.get(&k);
        let gamma = basis.load_factor(k).unwrap_or(c64::new(1.0, 0.0));
        for (i, z) in bz.into_iter().enumerate() {
            let g0 = match (k, moving) {
                (0, _) => c64::new(op.g0[i], 0.0),
                (_, Some(g)) => g[i] * gamma,
                _ => c64::new(0.0, 0.0),
            };
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
    let iterations = (attempts.iterations, attempts.log);
    let found = Found {
        outcome,
        c,
        route,
        hint: attempts.krylov_hint,
    };
    Ok(finish(problem, settings, found, iterations, reporter))
}

/// A converged Newton outcome at c, how it was reached and the Krylov hint its last step
/// used.
struct Found {
    outcome: NewtonOutcome,
    c: f64,
    route: Route,
    hint: crate::hbm::step::KrylovHint,
}

/// The knob checks on a converged outcome and the contact solution they leave, its Newton
/// account the `iterations` and log of everything that led to it.
fn finish(
    problem: &ReducedProblem,
    settings: &HbSettings,
    found: Found,
    (iterations, log): (usize, Vec<crate::hbm::IterationLog>),
    reporter: &dyn Reporter,
) -> ContactSolution {
    let Found {
        outcome,
        c,
        route,
        hint,
    } = found;
    let (samples, mut outcome, knob_check) = knobs::adapt_samples(
        problem,
        outcome,
        settings.samples,
        c,
        settings.tolerance,
        &hint,
        reporter,
    );
    outcome.iterations = iterations;
    outcome.log = log;
    let gaps = problem.gap(&outcome.multipliers);
    let complementarity = measure_complementarity(problem, &outcome.multipliers, &gaps, samples);
    ContactSolution {
        harmonics: problem.harmonics,
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
        friction: None,
        harmonics_chosen: None,
    }
}

/// The exact law's Newton at the problem's H and N = `settings.samples` from `start` (a
/// neighbouring H's multipliers, padded or truncated), with the knob checks where it
/// converges; `None` where it does not (the caller then solves from scratch).
pub(super) fn solve_contact_from(
    problem: &ReducedProblem,
    settings: &HbSettings,
    c: f64,
    start: &[f64],
    reporter: &dyn Reporter,
) -> Option<ContactSolution> {
    let newton = crate::hbm::NewtonSettings {
        samples: settings.samples,
        c,
        tolerance: settings.tolerance,
        max_iterations: settings.max_iterations.min(WARM_ITERATIONS),
        hover: WARM_HOVER,
        ..Default::default()
    };
    let outcome = crate::hbm::reduced::newton(problem, &newton, start, reporter);
    if !outcome.converged {
        return None;
    }
    let account = (outcome.iterations, outcome.log.clone());
    let found = Found {
        outcome,
        c,
        route: Route {
            ladder: vec![problem.harmonics],
            damping: Vec::new(),
        },
        hint: newton.krylov_hint,
    };
    Some(finish(problem, settings, found, account, reporter))
}

/// Newton iterations of a warm start from a neighbouring H before the solve starts afresh.
pub(super) const WARM_ITERATIONS: usize = 60;
/// Steps without halving the residual after which a warm start gives up.
pub(super) const WARM_HOVER: usize = 10;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hbm::basis::TimeBasis;
    use crate::hbm::reduced::IterationLog;

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
