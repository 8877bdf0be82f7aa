//! Answers that do not depend on solver knobs. The sampled complementarity (23) is exact only
//! in the limit: at finite H its root moves with the number of samples N and, by the
//! truncation error, with the parameter c. After a converged solve:
//! - N is doubled while the answer changes by more than `SAMPLES_TOLERANCE` (at most
//!   `MAX_DOUBLINGS` times), each solve warm-started from the last; the N used is reported;
//! - the solution is re-solved once at c/3 at the final N, and the change is reported (a
//!   warning above `C_TOLERANCE`). That re-solve starts from the first converged λ, side by
//!   side with the first doubling, and is redone from the final λ when N moves on. Where it
//!   does not converge, the solution is re-solved at the next of `C_ALTERNATIVES` (3c, c/2,
//!   2c) instead (the c that converges is a band: on the 0.5%-damped strip at H = 40 the
//!   Newton at c/3 cycles between active sets, at c/2 and 3c it converges in two steps; at
//!   H = 45 only c/2 does).
//!
//! "The answer" is what a user reads: the contact nodes' vibration and the mean contact
//! force. The change between solutions a and b is the larger of
//! ‖g̃_b − g̃_a‖ / ‖g̃_a‖ (g̃ the gap coefficients of harmonics k ≥ 1, i.e. the contact nodes'
//! normal vibration, g = Gλ + r) and |Σ_i λ0_b − Σ_i λ0_a| / |Σ_i λ0_a| (the mean total
//! force). The multipliers' own high harmonics (the Gibbs ripple of an impact) move more
//! and are not the answer: at H = 40 on the reference strip they move 5% where these
//! move 0.1%. The vibration's norm is floored at `VIBRATION_FLOOR` × ‖r̃‖ (r the linear gap,
//! the vibration with the obstacle away): a face closed all period barely vibrates, and a
//! change of round-off size relative to nothing is not a change of the answer.

use super::basis::{SplineBasis, TimeBasis};
use super::fourier::harmonic_of;
use super::problem::ReducedProblem;
use super::reduced::{self, NewtonOutcome, NewtonSettings};
use super::step::KrylovHint;
use crate::linalg::norm2;
use crate::progress::Reporter;

/// Relative change of the answer below which a doubled N counts as converged.
pub const SAMPLES_TOLERANCE: f64 = 1e-3;
/// Doublings of N tried at most (N grows at most 4×).
pub const MAX_DOUBLINGS: usize = 2;
/// Relative change of the answer between c and the second c above which the run warns.
pub const C_TOLERANCE: f64 = 1e-2;
/// The second c's re-solve tolerance (at least; the solve's own where that is looser):
/// its answer only enters a relative change compared with `C_TOLERANCE`, so a residual three
/// orders below that threshold is enough. On the reference strip at H = 40 it saves that
/// re-solve's last iteration and moves the reported change from 0.1351% to 0.1321%.
const C_RESOLVE_TOLERANCE: f64 = 1e-3 * C_TOLERANCE;
/// The smallest vibration norm a change is measured against, relative to the linear gap's.
const VIBRATION_FLOOR: f64 = 1e-3;

/// What the knob checks found (serialized into the summary).
#[derive(Clone, Debug, serde::Serialize, schemars::JsonSchema)]
pub struct KnobCheck {
    /// N the first converged solve used.
    pub samples_initial: usize,
    /// Relative change of the answer at each doubling of N (the last is the one that met the
    /// tolerance, or the last tried).
    pub samples_changes: Vec<f64>,
    /// The second c [N/m]: the first of c/3, 3c, c/2, 2c whose re-solve converged (the last
    /// tried where none did).
    pub c_alternative: f64,
    /// Relative change of the answer from c to `c_alternative`; `None` when neither re-solve
    /// converged.
    pub c_change: Option<f64>,
    /// Newton iterations the checks took.
    pub iterations: usize,
    /// Wall time of the checks [s]: the run's `knob_check` stage, apart from its `newton`.
    pub seconds: f64,
    /// Spline basis only: the share of the contact nodes' vibration (gap coefficients of the
    /// frequencies j ≥ 1, in norm) carried by discrete frequencies whose damping symbol keeps
    /// less than `DAMPED_SYMBOL` of the exact jω (see `underdamped_share`). Absent for
    /// Fourier, whose damping symbol is exact.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub underdamped_share: Option<f64>,
}

/// The share of the vibration in underdamped spline frequencies above which the run warns:
/// on the strip at 1300 Hz, 9.9% at S = 40 (peak force 5.3e5 N/m against 2.9e5 at S = 160,
/// 647 Newton iterations), 1.2% at S = 80 and 0.6% at S = 160 (test
/// `spline_runs_warn_when_the_response_lives_in_the_bases_underdamped_frequencies`).
pub const UNDERDAMPED_TOLERANCE: f64 = 0.05;

/// The fraction of the exact damping symbol jω a spline frequency must keep to count as
/// damped.
const DAMPED_SYMBOL: f64 = 0.95;

/// A spline basis' upper discrete frequencies are nearly undamped (σ_j/jω → 0 at Nyquist):
/// where the contact response lives there, a structural mode they meet resonates with the
/// damping the basis lost, not the physical one. The share of the vibration ‖g̃‖ in them,
/// from the gap coefficients `g` of a solution.
pub fn underdamped_share(problem: &ReducedProblem, g: &[f64]) -> Option<f64> {
    let TimeBasis::Spline(basis) = &problem.basis else {
        return None;
    };
    let m = problem.coefficients();
    let (mut upper, mut all) = (0.0, 0.0);
    for i in 0..problem.nodes {
        for q in 1..m {
            let v = g[i * m + q].powi(2);
            all += v;
            if basis.damping_ratio(harmonic_of(q)) < DAMPED_SYMBOL {
                upper += v;
            }
        }
    }
    Some(if all > 0.0 { (upper / all).sqrt() } else { 0.0 })
}

/// The lowest discrete frequency of `s` whose damping symbol keeps less than
/// `DAMPED_SYMBOL` of jω: where the basis' underdamped band starts.
pub fn underdamped_from(s: &SplineBasis) -> usize {
    (1..s.frequencies())
        .find(|&j| s.damping_ratio(j) < DAMPED_SYMBOL)
        .unwrap_or(s.segments / 2)
}

/// The mean contact force's change from the solution `coarse` of a problem at a lower H to
/// `fine` (multipliers each), measured against the larger of the coarse mean and
/// `FORCE_FLOOR` of the closing force: grazing contact's few newtons change by tens of
/// percent from H/2 to H, and that is not a change of the answer. 0 where it is not finite.
pub fn mean_force_change(coarse_problem: &ReducedProblem, coarse: &[f64], fine: &[f64]) -> f64 {
    let nodes = coarse_problem.nodes;
    let mean = |x: &[f64], m: usize| (0..nodes).map(|i| x[i * m]).sum::<f64>();
    let (a, b) = (
        mean(coarse, coarse_problem.coefficients()),
        mean(fine, fine.len() / nodes.max(1)),
    );
    let floor = FORCE_FLOOR * closing_force(coarse_problem);
    let change = (a - b).abs() / a.abs().max(floor);
    if change.is_finite() {
        change
    } else {
        0.0
    }
}

/// The share of the closing force below which a mean contact force's change is measured
/// against the floor instead of itself.
const FORCE_FLOOR: f64 = 1e-2;

/// The force that closes the linear gap statically: ‖r‖ over the mean static compliance of
/// a contact node, mean|G_0,ii|.
fn closing_force(problem: &ReducedProblem) -> f64 {
    let nc = problem.nodes;
    let compliance = (0..nc)
        .map(|i| problem.compliance[0][i * nc + i].re.abs())
        .sum::<f64>()
        / nc.max(1) as f64;
    let r = norm2(&problem.linear_gap);
    if compliance > 0.0 {
        r / compliance
    } else {
        0.0
    }
}

/// The change of the answer from multipliers `a` to `b` of `problem` (see the header).
fn relative_change(problem: &ReducedProblem, a: &[f64], b: &[f64]) -> f64 {
    let (ga, gb) = (problem.gap(a), problem.gap(b));
    let m = problem.coefficients();
    let free = &problem.linear_gap;
    let (mut diff, mut norm, mut norm_free, mut mean_a, mut mean_b) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..problem.nodes {
        mean_a += a[i * m];
        mean_b += b[i * m];
        for q in i * m + 1..(i + 1) * m {
            diff += (ga[q] - gb[q]).powi(2);
            norm += ga[q].powi(2);
            norm_free += free[q].powi(2);
        }
    }
    let norm = norm.sqrt().max(VIBRATION_FLOOR * norm_free.sqrt());
    let ratio = |d: f64, n: f64| if n > 0.0 { d / n } else { d };
    let force = ratio((mean_a - mean_b).abs(), f64::abs(mean_a));
    ratio(diff.sqrt(), norm).max(force)
}

/// Newton iterations of a re-solve at doubled N.
const RESOLVE_ITERATIONS: usize = 50;
/// Newton iterations of a re-solve at a second c before the other c is tried: a warm-started
/// re-solve that converges takes 1–6 on the shipped and hard-case scenes at H up to 80 (12
/// for both re-solves of the 0.5%-damped strip at H = 60); one that cycles does not converge
/// in 50 (the 0.5%-damped strip at c/3, H = 40).
const C_RESOLVE_ITERATIONS: usize = 20;
/// Steps a re-solve at a second c may take without halving its residual before the other c
/// is tried: a warm-started re-solve that converges halves it at nearly every step, one that
/// cycles between active sets (the 0.5%-damped strip at c/3, H = 40) never does.
const C_RESOLVE_HOVER: usize = 8;

/// The second c's, tried in turn until a re-solve converges: c/3 and 3c change c enough to
/// show a dependence on it; c/2 and 2c, nearer, converge from some solutions where those
/// cycle (the 0.5%-damped strip at H = 45: c/3 and 3c do not converge, c/2 does, with a
/// change of 2.2%, where the run used to warn that the check was unverified).
const C_ALTERNATIVES: [f64; 4] = [1.0 / 3.0, 3.0, 0.5, 2.0];

/// A second c by its ratio to c, as the warnings and the benches print it: "c/3", "3c".
pub fn c_label(ratio: f64) -> String {
    if ratio < 1.0 {
        format!("c/{:.0}", 1.0 / ratio)
    } else {
        format!("{ratio:.0}c")
    }
}

/// The exact-law Newton at (N, c) from `start`, at most `max_iterations` steps and at most
/// `hover` without halving its residual (0: no such bound), its Krylov steps starting with
/// the preconditioner `hint` names (a copy: runs side by side do not steer each other).
fn resolve(
    problem: &ReducedProblem,
    (samples, c, tolerance): (usize, f64, f64),
    (max_iterations, hover): (usize, usize),
    start: &[f64],
    hint: &KrylovHint,
    reporter: &dyn Reporter,
) -> NewtonOutcome {
    let settings = NewtonSettings {
        samples,
        c,
        tolerance,
        max_iterations,
        min_iterations: 1,
        hover,
        krylov_hint: hint.detached(),
        ..Default::default()
    };
    reduced::newton(problem, &settings, start, reporter)
}

/// The re-solves of one check: the solve's problem, c, tolerance and Krylov hint.
struct Resolves<'a> {
    problem: &'a ReducedProblem,
    c: f64,
    tolerance: f64,
    hint: &'a KrylovHint,
    reporter: &'a dyn Reporter,
}

impl Resolves<'_> {
    /// The exact law at N = `n` and the solve's c, from `start`.
    fn at_samples(&self, n: usize, start: &[f64]) -> NewtonOutcome {
        resolve(
            self.problem,
            (n, self.c, self.tolerance),
            (RESOLVE_ITERATIONS, 0),
            start,
            self.hint,
            self.reporter,
        )
    }

    /// The first of `C_ALTERNATIVES` whose re-solve at N = `n` converges from `start`: its
    /// outcome (with the iterations of all tried) and its c; the last tried where none does.
    fn second_c(&self, n: usize, start: &[f64]) -> (NewtonOutcome, f64) {
        let loose = self.tolerance.max(C_RESOLVE_TOLERANCE);
        let mut spent = 0;
        let mut last = None;
        for factor in C_ALTERNATIVES {
            let mut o = resolve(
                self.problem,
                (n, factor * self.c, loose),
                (C_RESOLVE_ITERATIONS, C_RESOLVE_HOVER),
                start,
                self.hint,
                self.reporter,
            );
            spent += o.iterations;
            o.iterations = spent;
            let converged = o.converged;
            last = Some((o, factor * self.c));
            if converged {
                break;
            }
        }
        last.expect("C_ALTERNATIVES is not empty")
    }

    /// N doubled from `samples` (the first doubling's outcome given) while the answer
    /// changes by more than `SAMPLES_TOLERANCE`, at most `MAX_DOUBLINGS` times: the final N
    /// and outcome, the changes and iterations recorded in `check`.
    fn double_samples(
        &self,
        samples: usize,
        solved: NewtonOutcome,
        first: NewtonOutcome,
        check: &mut KnobCheck,
    ) -> (usize, NewtonOutcome) {
        let (mut n, mut best) = (samples, solved);
        let mut next = Some(first);
        for _ in 0..MAX_DOUBLINGS {
            let o = next
                .take()
                .unwrap_or_else(|| self.at_samples(2 * n, &best.multipliers));
            check.iterations += o.iterations;
            if !o.converged {
                break;
            }
            let change = relative_change(self.problem, &best.multipliers, &o.multipliers);
            check.samples_changes.push(change);
            (n, best) = (2 * n, o);
            if change <= SAMPLES_TOLERANCE {
                break;
            }
        }
        (n, best)
    }
}

/// Raise N from `samples` until λ settles; returns the final (N, outcome) and the check.
/// `hint`: the preconditioner the solve's last Krylov step used, which the re-solves start
/// with.
pub fn adapt_samples(
    problem: &ReducedProblem,
    solved: NewtonOutcome,
    samples: usize,
    c: f64,
    tolerance: f64,
    hint: &KrylovHint,
    reporter: &dyn Reporter,
) -> (usize, NewtonOutcome, KnobCheck) {
    let clock = std::time::Instant::now();
    let mut check = KnobCheck {
        samples_initial: samples,
        samples_changes: Vec::new(),
        c_alternative: c / 3.0,
        c_change: None,
        iterations: 0,
        seconds: 0.0,
        underdamped_share: None,
    };
    let resolves = Resolves {
        problem,
        c,
        tolerance,
        hint,
        reporter,
    };
    // The first doubling and the second c's re-solve at its N run side by side (the Newton is
    // sequential, the machine has a second core); the latter stands when the doublings stop
    // at that N, else it is redone at the N they reach.
    let (first, (mut alt, mut c_alt)) = rayon::join(
        || resolves.at_samples(2 * samples, &solved.multipliers),
        || resolves.second_c(2 * samples, &solved.multipliers),
    );
    check.iterations += alt.iterations;
    let (n, best) = resolves.double_samples(samples, solved, first, &mut check);
    if n != 2 * samples {
        (alt, c_alt) = resolves.second_c(n, &best.multipliers);
        check.iterations += alt.iterations;
    }
    check.c_alternative = c_alt;
    if alt.converged {
        check.c_change = Some(relative_change(
            problem,
            &best.multipliers,
            &alt.multipliers,
        ));
    }
    check.underdamped_share = underdamped_share(problem, &problem.gap(&best.multipliers));
    check.seconds = clock.elapsed().as_secs_f64();
    (n, best, check)
}

/// The warning of a frictional solve whose re-solve at 2N samples moved its multipliers by
/// `change` (relative) past `SAMPLES_TOLERANCE`, or did not converge (∞); `None` for NaN
/// (not checked).
pub fn friction_warning(change: f64, samples: usize, basis: &TimeBasis) -> Option<String> {
    let refine = basis.refine_key();
    if change == f64::INFINITY {
        return Some(format!(
            "the frictional re-solve at N = {} samples did not converge from this state: its independence of harmonic_balance.samples is unverified; raise {refine} and compare",
            2 * samples
        ));
    }
    (change > SAMPLES_TOLERANCE).then(|| format!(
        "the frictional state still changes by {change:.2e} (relative) from N = {samples} to N = {} samples: the answer depends on harmonic_balance.samples; raise it, or raise {refine}",
        2 * samples
    ))
}

/// The warnings a check calls for, with its numbers.
pub fn warnings(check: &KnobCheck, samples: usize, basis: &TimeBasis) -> Vec<String> {
    let refine = basis.refine_key();
    let mut out = Vec::new();
    if let Some(&last) = check.samples_changes.last() {
        if last > SAMPLES_TOLERANCE {
            out.push(format!(
                "the contact response still changes by {:.2e} (relative) from N = {} to N = {samples} samples: the answer depends on harmonic_balance.samples; raise it, or raise {refine}",
                last,
                samples / 2
            ));
        }
    }
    let underdamped = check
        .underdamped_share
        .filter(|&share| share > UNDERDAMPED_TOLERANCE);
    if let (Some(share), TimeBasis::Spline(s)) = (underdamped, basis) {
        let from = underdamped_from(s);
        out.push(format!(
                "{:.1}% of the contact nodes' vibration lies in the spline basis' discrete frequencies j ≥ {from} (of {}), whose damping its time derivative loses (σ_j/jω below {DAMPED_SYMBOL}, 0 at j = S/2): a structural mode they meet resonates with too little damping, and the answer is not the physical one; raise {refine} (the share falls as S grows) or use basis: fourier, and compare",
                100.0 * share,
                s.segments / 2
            ));
    }
    match check.c_change {
        Some(change) if change > C_TOLERANCE => out.push(format!(
            "the contact response changes by {:.1}% between c and the second c ({:.3e} N/m): at this H the answer depends on the complementarity parameter (a truncation effect, or several periodic states); raise {refine} and compare",
            100.0 * change,
            check.c_alternative
        )),
        None => {
            let tried: Vec<String> = C_ALTERNATIVES.iter().map(|&f| c_label(f)).collect();
            let (last, first) = tried.split_last().expect("C_ALTERNATIVES is not empty");
            out.push(format!(
                "the checks at {} and {last} (the last {:.3e} N/m) did not converge from this solution: its independence of c is unverified",
                first.join(", "),
                check.c_alternative
            ));
        }
        _ => {}
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a knob check whose answer moves with N and with c says so, and tells the
    /// user to refine the basis the run used: the harmonics for Fourier, the segments for a
    /// spline basis (never the harmonics, which a spline run does not read).
    #[test]
    fn knob_warnings_name_the_key_that_refines_the_runs_basis() {
        let check = KnobCheck {
            samples_initial: 64,
            samples_changes: vec![0.1],
            c_alternative: 1e9,
            c_change: Some(0.5),
            iterations: 0,
            seconds: 0.0,
            underdamped_share: None,
        };
        let spline = TimeBasis::Spline(SplineBasis::new(3, 40));
        for (basis, key) in [
            (TimeBasis::Fourier, "harmonic_balance.harmonics"),
            (spline, "harmonic_balance.basis.spline.segments"),
        ] {
            let w = warnings(&check, 128, &basis);
            assert_eq!(w.len(), 2, "{w:?}");
            assert!(w.iter().all(|m| m.contains(key)), "{key}: {w:?}");
        }
        let w = warnings(&check, 128, &TimeBasis::Spline(SplineBasis::new(3, 40)));
        assert!(w.iter().all(|m| !m.contains("harmonic_balance.harmonics")));
    }

    /// TEST GOAL: the warning of an unverified c names every second c tried, in the order
    /// tried, from the one list the check runs (`C_ALTERNATIVES`), by the labels the benches
    /// print.
    #[test]
    fn an_unverified_c_names_every_second_c_tried() {
        assert_eq!(c_label(1.0 / 3.0), "c/3");
        assert_eq!(c_label(3.0), "3c");
        let check = KnobCheck {
            samples_initial: 64,
            samples_changes: vec![0.0],
            c_alternative: 2e9,
            c_change: None,
            iterations: 0,
            seconds: 0.0,
            underdamped_share: None,
        };
        let w = warnings(&check, 64, &TimeBasis::Fourier);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("the checks at c/3, 3c, c/2 and 2c (the last 2.000e9 N/m)"));
    }
}
