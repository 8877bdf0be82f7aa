//! The texts a contact solve gives its user: why a continuation stopped at a fold, the
//! warning after a detour, and, when every attempt failed, the diagnosis of the stall and
//! what to change in the pipeline.

use crate::hbm::basis::TimeBasis;
use crate::hbm::problem::ReducedProblem;
use crate::hbm::reduced::NewtonOutcome;
use crate::hbm::{ContactSolution, HbSettings, System};
use crate::Error;

use super::*;

/// Why a smoothing continuation stopped where its path turned back at μ = `at`·F.
pub(super) fn fold_reason(at: f64) -> String {
    format!(
        "the smoothing path turned back at μ = {at:.1e}·F (a fold: near a resonance the contact \
         problem can have several periodic states)"
    )
}

/// The warning a solve that converged only through the damping continuation, the harmonic
/// ladder or the softer c calls for (`None` for a direct one): the direct continuation
/// folded or stalled, which happens near a resonance where the contact problem has several
/// periodic states, and the detour reached one of them.
pub(in crate::hbm) fn detour_warning(
    problem: &ReducedProblem,
    settings: &HbSettings,
    solution: &ContactSolution,
) -> Option<String> {
    let direct_c = automatic_c(problem, settings).ok()?;
    let route = crate::hbm::solution::detour(&solution.ladder, &solution.damping_path);
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

pub(super) fn stall_diagnosis(
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
pub(super) fn stall_advice(
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
