//! Harmonic balance: the periodic steady state of M ü + D u̇ + K u = Bᵀλ + f(t) with
//! unilateral contact B u − g0 ≤ 0, λ ≤ 0, λ·(B u − g0) = 0.
//!
//! The formulation and its equation numbers (n) are those of `docs/method.md`. Glossary:
//! - ω = 2πf the fundamental angular frequency, T = 2π/ω the period;
//! - H the highest harmonic kept, M = 2H + 1 Fourier coefficients per scalar;
//! - N time samples per period for the contact terms (N > 2H; default 16H);
//! - Z_k = K − k²ω²M + ikωD the dynamic stiffness of harmonic k, z_k = a_k − i b_k the complex
//!   amplitude, so u(t) = Re Σ_k z_k e^{ikωt};
//! - the time basis (`basis`): Fourier, or periodic splines whose discrete frequencies j take
//!   the place of k, with Z_j = K + s_j D + q_j M (with contact all j = 0..⌊S/2⌋, whose
//!   phasors stand in the contact unknowns where the harmonics' do, `sampler`);
//! - G_k = B Z_k⁻¹ Bᵀ the contact nodes' dynamic compliance, r the linear gap;
//! - c > 0 the complementarity parameter (a stiffness; default 1/mean|G_0,ii|).
//!
//! A scene pays only for what it contains: a linear scene factors only the harmonics its loads
//! excite (no static solve without static load), undamped scenes factor real matrices, and
//! the contact reduction runs only when there is an obstacle.

pub mod adaptive;
pub mod basis;
pub mod continuation;
pub mod floquet;
pub mod fourier;
pub mod frames;
pub mod friction;
mod globalize;
pub mod hill;
pub mod knobs;
pub mod problem;
pub mod reduced;
pub mod sampler;
pub mod solution;
pub mod step;
pub mod subharmonic;
pub mod system;

use std::collections::BTreeMap;
use std::time::Instant;

use faer::c64;

use crate::contact::ContactOperator;
use crate::linalg::Factor;
use crate::progress::Reporter;
use crate::{Error, Result};
pub use problem::ReducedProblem;
pub use reduced::{IterationLog, NewtonOutcome, NewtonSettings};
pub use solution::{
    Complementarity, ContactSolution, FrictionSolution, Snapshot, Solution, Tangential, Timings,
};
pub use system::{HarmonicInput, Spin, System};

#[derive(Clone, Debug)]
pub struct HbSettings {
    /// Highest harmonic of the contact solve.
    pub harmonics: usize,
    /// Samples per period (N > 2H).
    pub samples: usize,
    pub c_scale: f64,
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Wall-time budget of the contact solve [s], checked before each Newton iteration.
    pub max_seconds: f64,
}

impl HbSettings {
    /// N = 16H converged where 2H+1 and 4H did not (docs/method.md §6); static needs one sample.
    pub fn default_samples(harmonics: usize) -> usize {
        if harmonics == 0 {
            1
        } else {
            (16 * harmonics).max(64)
        }
    }
}

fn is_zero(v: &[c64]) -> bool {
    v.iter().all(|z| z.re == 0.0 && z.im == 0.0)
}

/// Run `f`, adding its wall time to `slot`.
fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    *slot += start.elapsed().as_secs_f64();
    out
}

/// Solve for the periodic steady state: factor Z_k per harmonic, solve the linear response,
/// reduce to the contact nodes (19)–(20), solve the contact problem (23), recover (24).
pub fn solve(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
    reporter: &dyn Reporter,
) -> Result<Solution> {
    solve_within(system, contact, settings, None, reporter)
}

/// `solve`, with H chosen in [settings.harmonics, range.max] where a range is given and the
/// scene has frictionless contact on the Fourier basis (`adaptive`); the reduction is formed
/// at H_max once and each level solves its truncation.
pub fn solve_within(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
    range: Option<adaptive::HarmonicRange>,
    reporter: &dyn Reporter,
) -> Result<Solution> {
    let settings = &contact_settings(system, contact.is_some(), settings)?;
    let adapting = range.filter(|r| {
        r.max > settings.harmonics
            && matches!(system.basis, basis::TimeBasis::Fourier)
            && contact.is_some_and(|op| op.tangential.is_none())
    });
    let mut timings = Timings::default();
    let stacked = contact.and_then(ContactOperator::stacked);
    let reduction = stacked.as_ref().or(contact);
    let reduced_at = HbSettings {
        harmonics: adapting.map_or(settings.harmonics, |r| r.max),
        ..settings.clone()
    };
    let (mut linear, problem) = prepare(system, reduction, &reduced_at, reporter, &mut timings)?;
    let contact_solution = match (contact, problem) {
        (Some(op), Some(problem)) if op.tangential.is_some() => {
            let solution =
                solve_frictional(system, op, &problem, settings, reporter, &mut timings)?;
            let mut x = solution.multipliers.clone();
            x.extend_from_slice(
                solution
                    .friction
                    .as_ref()
                    .map_or(&[][..], |f| &f.tangential),
            );
            let m = solution.coefficients();
            timed(&mut timings.recover, || {
                linear.recover(reduction.unwrap_or(op), &x, m)
            });
            let change = solution
                .friction
                .as_ref()
                .map_or(f64::NAN, |f| f.samples_change);
            let samples = solution.samples;
            let warning = knobs::friction_warning(change, samples, &system.basis);
            linear.warnings.extend(warning);
            Some(solution)
        }
        (Some(op), Some(problem)) => {
            let solution = frictionless(
                system,
                (op, &problem, &linear),
                settings,
                adapting,
                reporter,
                &mut timings,
            )?;
            let chosen = solution.harmonics_chosen.as_ref();
            linear.warnings.extend(chosen.and_then(|c| c.warning()));
            timed(&mut timings.recover, || {
                linear.recover(op, &solution.multipliers, solution.coefficients())
            });
            linear.warnings.extend(knobs::warnings(
                &solution.knob_check,
                solution.samples,
                &system.basis,
            ));
            linear
                .warnings
                .extend(globalize::detour_warning(&problem, settings, &solution));
            Some(solution)
        }
        _ => None,
    };
    let solution = linear.into_solution(system, contact_solution, timings);
    // Its factors are dropped: what the plans kept of them is not needed after one solve.
    system.release_factor_memory();
    Ok(solution)
}

/// The frictionless contact solve at the settings' H, or with H chosen in `adapting`.
fn frictionless(
    system: &System,
    (op, problem, linear): (&ContactOperator, &ReducedProblem, &LinearResponse),
    settings: &HbSettings,
    adapting: Option<adaptive::HarmonicRange>,
    reporter: &dyn Reporter,
    timings: &mut Timings,
) -> Result<ContactSolution> {
    match adapting {
        Some(range) => {
            let with = (op, linear);
            adaptive::solve(system, with, problem, settings, range, reporter, timings)
        }
        None => solve_contact_timed(system, op, problem, settings, reporter, timings),
    }
}

/// The most factor memory `touch_factor_memory` touches ahead [bytes]: the reference strip
/// at H = 60 needs 55 MB, the 601-node half-disc 100 MB per harmonic.
const TOUCH_LIMIT: usize = 64 << 20;

/// Touch, on a pool thread, the memory that `solve`'s factorizations will fill, so that a
/// caller with a single-threaded stage before the solve (the run's resonance check) has
/// the page faults taken on its idle core. Only contact scenes on the kept LDLᵀ keep a
/// factor per harmonic (a linear scene drops each at once). A solve that starts before the
/// touching is done takes fresh memory as before (docs/method.md §4 has the measurements).
/// Only up to `TOUCH_LIMIT` bytes in all: larger factors have larger fronts, whose flops
/// outweigh their page faults, and their touching would outlast the check and compete with
/// the factorizations for the cores.
pub fn touch_factor_memory(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
) {
    let Some(op) = contact else { return };
    // The rows the solve reduces to (with friction the stacked ones), whose plan the model
    // built: another B would analyse anew.
    let Some(plan) = system
        .schur_plan(&op.reduction_rows())
        .filter(|p| p.preferred())
    else {
        return;
    };
    let count = contact_settings(system, true, settings)
        .and_then(|s| harmonics_to_compute(system, contact, &s))
        .map_or(0, |h| h.len());
    if count * plan.panel_bytes() <= TOUCH_LIMIT {
        rayon::spawn(move || plan.touch_panels(count));
    }
}

/// `globalize::solve_contact` with its wall time in `timings`: the knob check's share as
/// `knob_check`, the rest (with the damping continuation's factorizations) as `newton`.
fn solve_contact_timed(
    system: &System,
    op: &ContactOperator,
    problem: &ReducedProblem,
    settings: &HbSettings,
    reporter: &dyn Reporter,
    timings: &mut Timings,
) -> Result<ContactSolution> {
    let heavier = |scale: f64| heavier_damped(system, op, settings, scale);
    let solution = timed(&mut timings.newton, || {
        globalize::solve_contact(system, problem, settings, Some(&heavier), reporter)
    })?;
    timings.knob_check += solution.knob_check.seconds;
    timings.newton -= solution.knob_check.seconds;
    Ok(solution)
}

/// The frictional contact solve (`friction`) on the stacked problem: the frictionless solve
/// of its normal rows (with all of `globalize`'s help), then the frictional Newton from it.
fn solve_frictional(
    system: &System,
    op: &ContactOperator,
    problem: &ReducedProblem,
    settings: &HbSettings,
    reporter: &dyn Reporter,
    timings: &mut Timings,
) -> Result<ContactSolution> {
    if !matches!(system.basis, basis::TimeBasis::Fourier) {
        return Err(Error::Input(
            "contact.friction needs the Fourier time basis (harmonic_balance.basis: fourier): \
             the slip velocity of a spline basis is not formed"
                .into(),
        ));
    }
    let normal = friction::normal_part(problem);
    let frictionless = solve_contact_timed(system, op, &normal, settings, reporter, timings)?;
    let coefficients = op
        .tangential
        .as_ref()
        .map_or(Vec::new(), |t| t.coefficients.clone());
    let full = problem.truncate(frictionless.harmonics);
    let knobs = (
        settings.tolerance,
        settings.max_iterations,
        settings.max_seconds,
    );
    let (outcome, change) = timed(&mut timings.newton, || {
        friction::solve(&full, &coefficients, &frictionless, knobs)
    });
    if !outcome.converged {
        let advice = if outcome.reason == friction::OUT_OF_TIME {
            format!(
                "raise harmonic_balance.solver.max_seconds (now {} s)",
                settings.max_seconds
            )
        } else {
            "lower contact.friction.coefficient to find where it stops, or raise damping".into()
        };
        return Err(Error::NotConverged(format!(
            "the frictional contact solve did not converge at {:.6} Hz: {} after {} iterations \
             (from the frictionless state, which converged); {advice}",
            system.omega / (2.0 * std::f64::consts::PI),
            outcome.reason,
            outcome.iterations
        )));
    }
    let x = &outcome.multipliers;
    let counts = (change, outcome.iterations);
    let mut solution = with_friction(frictionless, &full, coefficients, x, counts);
    solution.newton.iterations += outcome.iterations;
    Ok(solution)
}

/// The contact solution at x = (λ_n, λ_t) of the stacked problem `full`: `normal`'s (its N,
/// c, knob checks and Newton account) with the normal part's multipliers, gaps and
/// complementarity taken from x, and the tangential result (`FrictionSolution`, its
/// `samples_change` and `iterations` as given; NaN: the samples were not checked).
pub(super) fn with_friction(
    mut normal: ContactSolution,
    full: &ReducedProblem,
    coefficients: Vec<f64>,
    x: &[f64],
    (samples_change, iterations): (f64, usize),
) -> ContactSolution {
    let (m, samples) = (full.coefficients(), normal.samples);
    let nc = full.nodes / 2;
    let gaps = full.gap(x);
    let part = friction::normal_part(full);
    normal.complementarity = measure_complementarity(&part, &x[..nc * m], &gaps[..nc * m], samples);
    normal.multipliers = x[..nc * m].to_vec();
    normal.gaps = gaps[..nc * m].to_vec();
    normal.compliance = None;
    normal.newton.multipliers = normal.multipliers.clone();
    let law = friction::Law {
        coefficients: &coefficients,
        c: normal.c,
        tangential_scale: 1.0,
    };
    let states = friction::node_states(full, &law, samples, x);
    let (shares, peak_force) = friction::statistics(&states);
    normal.friction = Some(FrictionSolution {
        coefficients,
        tangential: x[nc * m..].to_vec(),
        slips: gaps[nc * m..].to_vec(),
        samples_change,
        iterations,
        shares,
        peak_force,
    });
    normal
}

/// The reduced problem of the scene with its damping scaled by `scale` (the damping
/// continuation's): factored anew, each factor dropped once its G_k is formed.
fn heavier_damped(
    system: &System,
    op: &ContactOperator,
    settings: &HbSettings,
    scale: f64,
) -> Result<ReducedProblem> {
    let scaled = system.with_damping_scaled(scale);
    let mut timings = Timings::default();
    let silent = &crate::Silent;
    let dropped = Source::FactorsDropped;
    let (_, problem) = prepare_with(&scaled, Some(op), settings, silent, &mut timings, dropped)?;
    problem.ok_or_else(|| Error::Model("internal: no reduced problem".into()))
}

/// The settings of a solve: with contact and a spline basis, the contact unknowns are all
/// ⌊S/2⌋ + 1 discrete frequencies (H = ⌊S/2⌋, S unknowns per node) at N = `samples`, which
/// must be a multiple of S with at least p + 1 Gauss points per segment (`sampler`).
pub(crate) fn contact_settings(
    system: &System,
    contact: bool,
    settings: &HbSettings,
) -> Result<HbSettings> {
    let basis::TimeBasis::Spline(s) = &system.basis else {
        return Ok(settings.clone());
    };
    if !contact {
        return Ok(settings.clone());
    }
    let n = settings.samples;
    if !n.is_multiple_of(s.segments) || n / s.segments < s.degree + 1 {
        return Err(Error::Input(format!(
            "harmonic_balance.samples = {n} must be a multiple of the spline's {} segments with at least {} per segment (degree + 1): use {} (8 per segment, the default)",
            s.segments,
            s.degree + 1,
            sampler::SPLINE_SAMPLES_PER_SEGMENT * s.segments
        )));
    }
    Ok(HbSettings {
        harmonics: s.segments / 2,
        ..settings.clone()
    })
}

/// The periodic state at the system's ω by a plain Newton on the exact contact law from
/// `start`, the contact solution of a nearby problem (the same contact nodes; e.g. another
/// discretization of the mass, or a neighbouring frequency), at its H, N and c. No
/// globalization: from a start this close it converges, or the nearby state is gone (beyond
/// a fold), which is an error.
pub fn solve_from(
    system: &System,
    contact: &ContactOperator,
    settings: &HbSettings,
    start: &ContactSolution,
    reporter: &dyn Reporter,
) -> Result<Solution> {
    let mut timings = Timings::default();
    let settings = HbSettings {
        harmonics: start.harmonics,
        ..settings.clone()
    };
    let (mut linear, problem) = prepare(system, Some(contact), &settings, reporter, &mut timings)?;
    let problem = problem.ok_or_else(|| Error::Model("internal: no reduced problem".into()))?;
    let newton = NewtonSettings {
        samples: start.samples,
        c: start.c,
        tolerance: settings.tolerance,
        max_iterations: settings.max_iterations.min(50),
        min_iterations: 1,
        ..Default::default()
    };
    let outcome = timed(&mut timings.newton, || {
        reduced::newton(&problem, &newton, &start.multipliers, reporter)
    });
    reporter.task_done("contact Newton");
    if !outcome.converged {
        return Err(Error::NotConverged(format!(
            "no periodic state near the given one at {:.6} Hz: {} after {} iterations",
            system.omega / (2.0 * std::f64::consts::PI),
            outcome.reason,
            outcome.iterations
        )));
    }
    let m = problem.coefficients();
    timed(&mut timings.recover, || {
        linear.recover(contact, &outcome.multipliers, m)
    });
    let solution = ContactSolution::unchecked(&problem, start.samples, start.c, outcome);
    Ok(linear.into_solution(system, Some(solution), timings))
}

/// Everything of a solve at the system's ω before the contact Newton: the factorizations,
/// the linear response and, with contact, the reduced problem (G_k and r). The harmonics are
/// independent here, so they run in parallel on the current rayon pool (a study's points
/// bring their own pool, so its cores go to points or to harmonics, never to both at once).
fn prepare(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
    reporter: &dyn Reporter,
    timings: &mut Timings,
) -> Result<(LinearResponse, Option<ReducedProblem>)> {
    prepare_with(
        system,
        contact,
        settings,
        reporter,
        timings,
        Source::Factors,
    )
}

/// Where `prepare_with` takes each harmonic's solves from.
#[derive(Clone, Copy)]
enum Source<'m> {
    /// Factorizations of Z_k, kept (with contact) for the recovery.
    Factors,
    /// Factorizations dropped as soon as G_k is formed: a problem that is never recovered
    /// (the damping continuation's) holds no factor memory beside the solve's own.
    FactorsDropped,
    /// A reduced model: no factorization; the caller checks the point it keeps
    /// (`frames::point_backward_error`).
    Reduced(&'m frames::ReducedModel),
}

/// `prepare`, with the harmonics' solves from `source`.
fn prepare_with(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
    reporter: &dyn Reporter,
    timings: &mut Timings,
    source: Source,
) -> Result<(LinearResponse, Option<ReducedProblem>)> {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicU64, Ordering};
    let harmonics = harmonics_to_compute(system, contact, settings)?;
    let total = Some(harmonics.len() as u64);
    let done = AtomicU64::new(0);
    let wall = Instant::now();
    let b = contact.map(|op| &op.b_free);
    let results: Vec<Result<Harmonic>> = harmonics
        .par_iter()
        .map(|&k| {
            let h = match (source, b) {
                (Source::Reduced(model), Some(b)) => Harmonic::reduced(system, b, k, model),
                (Source::FactorsDropped, _) => {
                    Harmonic::compute(system, b, k).map(|h| Harmonic { factor: None, ..h })
                }
                _ => Harmonic::compute(system, b, k),
            };
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            reporter.progress("factor", d, total, &format!("harmonic {k}"));
            h
        })
        .collect();
    reporter.task_done("factor");
    let mut linear = LinearResponse::default();
    let mut cpu = Timings::default();
    for h in results {
        let h = h?;
        cpu.factor += h.seconds[0];
        cpu.linear_solve += h.seconds[1];
        cpu.reduce += h.seconds[2];
        linear.residuals.insert(h.k, h.residual);
        linear.free.insert(h.k, h.free);
        linear.motion.insert(h.k, system.motion(h.k));
        if let Some(gk) = h.compliance {
            linear.compliance.push(gk);
        }
        if let Some(factor) = h.factor {
            linear.factors.insert(h.k, factor);
        }
    }
    // Each phase's share of the parallel block's wall time.
    let cpu_total = cpu.factor + cpu.linear_solve + cpu.reduce;
    let scale = if cpu_total > 0.0 {
        wall.elapsed().as_secs_f64() / cpu_total
    } else {
        0.0
    };
    timings.factor += cpu.factor * scale;
    timings.linear_solve += cpu.linear_solve * scale;
    timings.reduce += cpu.reduce * scale;
    let problem = contact.map(|op| {
        timed(&mut timings.reduce, || ReducedProblem {
            nodes: op.nodes(),
            harmonics: settings.harmonics,
            linear_gap: globalize::linear_gap(
                op,
                settings.harmonics,
                (&linear.free, &linear.motion),
                &system.basis,
            ),
            compliance: std::mem::take(&mut linear.compliance),
            basis: system.basis.clone(),
        })
    });
    Ok((linear, problem))
}

/// One harmonic of `prepare`: the linear response z_k and, with contact (`b`), G_k and the
/// factorization of Z_k (kept for the recovery; without contact it is dropped at once, so a
/// linear scene holds one factorization per thread, not one per harmonic); the seconds of the
/// three phases.
struct Harmonic {
    k: usize,
    factor: Option<Factor>,
    free: Vec<c64>,
    residual: f64,
    compliance: Option<Vec<c64>>,
    seconds: [f64; 3],
}

impl Harmonic {
    fn compute(system: &System, b: Option<&crate::linalg::Csc>, k: usize) -> Result<Harmonic> {
        let mut seconds = [0.0; 3];
        let factor = timed(&mut seconds[0], || system.factor(k, b))?;
        let (free, residual) = timed(&mut seconds[1], || linear_solve(system, k, &factor))?;
        let (compliance, factor) = match b {
            Some(b) => {
                let gk = timed(&mut seconds[2], || reduce(system, b, k, &factor))?;
                (Some(gk), Some(factor))
            }
            None => (None, None),
        };
        Ok(Harmonic {
            k,
            factor,
            free,
            residual,
            compliance,
            seconds,
        })
    }
}

impl Harmonic {
    /// The harmonic from a reduced model: Galerkin solves, no factorization; the linear
    /// solve's backward error is recorded, not checked (the point is).
    fn reduced(
        system: &System,
        b: &crate::linalg::Csc,
        k: usize,
        model: &frames::ReducedModel,
    ) -> Result<Harmonic> {
        let mut seconds = [0.0; 3];
        let rhs = system.load(k);
        let modal = model
            .factor(system, k, &rhs)
            .ok_or_else(|| singular_diagnosis(system, k))?;
        let (free, residual) = timed(&mut seconds[1], || {
            if is_zero(&rhs) {
                return (rhs.clone(), 0.0);
            }
            let z = modal.load_response();
            let r = system.residual(k, &z, &rhs);
            let res = system::backward_error(system, k, &r, &z, &rhs);
            (z, res)
        });
        let factor = Factor::Modal(modal);
        let compliance = timed(&mut seconds[2], || reduce(system, b, k, &factor))?;
        Ok(Harmonic {
            k,
            factor: Some(factor),
            free,
            residual,
            compliance: Some(compliance),
            seconds,
        })
    }
}

/// Contact scenes compute every harmonic up to H (contact couples them); linear scenes only
/// the harmonics their loads excite.
fn harmonics_to_compute(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
) -> Result<Vec<usize>> {
    let harmonics: Vec<usize> = match contact {
        Some(_) => (0..=settings.harmonics).collect(),
        None => system
            .inputs
            .iter()
            .filter(|(_, input)| !is_zero(&input.force) || !is_zero(&input.motion))
            .map(|(&k, _)| k)
            .collect(),
    };
    let excited_max = system.inputs.keys().copied().max().unwrap_or(0);
    if let basis::TimeBasis::Spline(s) = &system.basis {
        if 2 * excited_max >= s.segments {
            return Err(Error::Input(format!(
                "harmonic_balance.basis: {} segments cannot carry harmonic {excited_max} of the loads: use more than {} segments",
                s.segments,
                2 * excited_max
            )));
        }
    }
    if contact.is_some() && excited_max > settings.harmonics {
        return Err(Error::Model(format!(
            "the loads excite harmonic {excited_max} but harmonic_balance.harmonics = {}: raise it to at least {excited_max} (contact couples all harmonics up to H, and a load above H would be dropped)",
            settings.harmonics
        )));
    }
    if harmonics.first() == Some(&0) && system.dofs.prescribed.is_empty() {
        // Nothing holds the body against rigid motion: K is singular by construction.
        return Err(singular_diagnosis(system, 0));
    }
    Ok(harmonics)
}

/// The linear response per harmonic and, for contact, what the reduction keeps.
#[derive(Default)]
struct LinearResponse {
    free: BTreeMap<usize, Vec<c64>>,
    motion: BTreeMap<usize, Vec<c64>>,
    residuals: BTreeMap<usize, f64>,
    warnings: Vec<String>,
    /// The factorizations of Z_k, kept for the recovery (24) and the sweep's ω-derivatives
    /// (contact scenes only).
    factors: BTreeMap<usize, Factor>,
    /// G_k = B Z_k⁻¹ Bᵀ per harmonic (row-major nc × nc).
    compliance: Vec<Vec<c64>>,
}

/// z_k = Z_k⁻¹ (f_k − Z_k,fp u_p,k), refined iteratively and checked for singularity; with
/// its relative residual.
fn linear_solve(system: &System, k: usize, lu: &Factor) -> Result<(Vec<c64>, f64)> {
    let rhs = system.load(k);
    if is_zero(&rhs) {
        // An unloaded harmonic: its linear response is zero, exactly.
        return Ok((rhs, 0.0));
    }
    let mut z = lu.solution_of(&rhs).unwrap_or_else(|| lu.solve(&rhs));
    let mut r = system.residual(k, &z, &rhs);
    let mut res = system::backward_error(system, k, &r, &z, &rhs);
    // Iterative refinement: large, badly conditioned systems (slender parts, fine
    // meshes) lose digits in the factorization; a few cheap solves win them back.
    for _ in 0..3 {
        if !(res > 1e-14) || !res.is_finite() {
            break;
        }
        for (zi, di) in z.iter_mut().zip(&lu.solve(&r)) {
            *zi += di;
        }
        r = system.residual(k, &z, &rhs);
        res = system::backward_error(system, k, &r, &z, &rhs);
    }
    check_solve(system, k, res, system::amplification(system, &z, &rhs), &z)?;
    Ok((z, res))
}

/// G_k = B Z_k⁻¹ Bᵀ, (19)–(20).
fn reduce(system: &System, b: &crate::linalg::Csc, k: usize, lu: &Factor) -> Result<Vec<c64>> {
    let gk = lu.compliance(b);
    if gk.iter().any(|z| !z.re.is_finite() || !z.im.is_finite()) {
        return Err(singular_diagnosis(system, k));
    }
    Ok(gk)
}

impl LinearResponse {
    /// Recovery (24): z_k = z_lin,k + Z_k⁻¹ Bᵀ λ_k, one solve per harmonic (the harmonics in
    /// parallel); `multipliers` node-major with `m` coefficients per node. Harmonics above
    /// the multipliers' (a range's level below the H the response was formed at) have λ_k = 0.
    fn recover(&mut self, op: &ContactOperator, multipliers: &[f64], m: usize) {
        use rayon::prelude::*;
        let updates: Vec<(usize, Vec<c64>)> = self
            .factors
            .par_iter()
            .filter(|(&k, _)| 2 * k < m)
            .filter_map(|(&k, lu)| {
                let lam = fourier::node_phasors(multipliers, m, k);
                contact_part(op, lu, &lam).map(|(_, dz)| (k, dz))
            })
            .collect();
        for (k, dz) in updates {
            if let Some(z) = self.free.get_mut(&k) {
                z.iter_mut().zip(dz).for_each(|(zi, di)| *zi += di);
            }
        }
    }
}

/// Bᵀλ_k and the field's contact part Z_k⁻¹ Bᵀλ_k by `factor`, for harmonic k's phasors
/// `lam` of the multipliers (`None` where every λ_k is zero: nothing to solve).
fn contact_part(
    op: &ContactOperator,
    factor: &Factor,
    lam: &[c64],
) -> Option<(Vec<c64>, Vec<c64>)> {
    let touching = lam.iter().any(|l| l.norm() != 0.0);
    touching.then(|| {
        let force = op.b_free.mul_transpose_complex(lam);
        let dz = factor.solve(&force);
        (force, dz)
    })
}

impl LinearResponse {
    /// The solution these responses make, with the contact part (if any) already recovered.
    fn into_solution(
        self,
        system: &System,
        contact: Option<ContactSolution>,
        timings: Timings,
    ) -> Solution {
        let complex = (system.rayleigh.is_some() || system.gyroscopic.is_some())
            && self.free.keys().any(|&k| k > 0);
        Solution {
            omega: system.omega,
            basis: system.basis.clone(),
            free: self.free,
            motion: self.motion,
            contact,
            residuals: self.residuals,
            complex_arithmetic: complex,
            timings,
            warnings: self.warnings,
        }
    }
}

fn check_solve(
    system: &System,
    k: usize,
    backward_error: f64,
    amplification: f64,
    z: &[c64],
) -> Result<()> {
    let finite = z.iter().all(|v| v.re.is_finite() && v.im.is_finite());
    // A stable LU of a regular matrix leaves a backward error near round-off; a singular one
    // shows up as a non-finite or enormous solution.
    if finite && backward_error < 1e-10 && amplification < 1e14 {
        return Ok(());
    }
    Err(singular_diagnosis(system, k))
}

fn singular_diagnosis(system: &System, k: usize) -> Error {
    if k == 0 {
        Error::Model(
            "the static stiffness K is singular: the body can move as a rigid body (only contact, \
             or nothing, holds it). Hold it with boundaries.fixed or boundaries.prescribed on a \
             group, or add a soft support"
                .into(),
        )
    } else {
        let f = k as f64 * system.omega / (2.0 * std::f64::consts::PI);
        let damping = if system.rayleigh.is_none() {
            "the scene has no damping, so the response there is unbounded: add `damping` \
             (e.g. alpha or beta giving 1% modal damping) or "
        } else {
            ""
        };
        Error::Model(format!(
            "the dynamic stiffness of harmonic {k} (at {f:.6} Hz) is singular: a natural \
             frequency of the structure sits at that frequency; {damping}move \
             harmonic_balance.frequency away from it"
        ))
    }
}

/// Violation of λ ≤ 0, g ≤ 0, λg = 0 by the basis functions at the N samples.
pub fn measure_complementarity(
    problem: &ReducedProblem,
    lambda: &[f64],
    gaps: &[f64],
    samples: usize,
) -> Complementarity {
    let sampler = problem.sampler(samples);
    let (nc, m) = (problem.nodes, problem.coefficients());
    let (mut ls, mut gs, mut rs) = (vec![0.0; samples], vec![0.0; samples], vec![0.0; samples]);
    let (mut force_scale, mut gap_scale) = (0.0f64, 0.0f64);
    let (mut pen, mut adh, mut prod) = (0.0f64, 0.0f64, 0.0f64);
    for i in 0..nc {
        sampler.to_samples(&lambda[i * m..(i + 1) * m], &mut ls);
        sampler.to_samples(&problem.linear_gap[i * m..(i + 1) * m], &mut rs);
        force_scale = ls.iter().fold(force_scale, |a, &v| a.max(v.abs()));
        gap_scale = rs.iter().fold(gap_scale, |a, &v| a.max(v.abs()));
    }
    for i in 0..nc {
        sampler.to_samples(&lambda[i * m..(i + 1) * m], &mut ls);
        sampler.to_samples(&gaps[i * m..(i + 1) * m], &mut gs);
        for n in 0..samples {
            pen = pen.max(gs[n]);
            adh = adh.max(ls[n]);
            prod = prod.max((ls[n] * gs[n]).abs());
        }
    }
    let fs = force_scale.max(f64::MIN_POSITIVE);
    let gsc = gap_scale.max(f64::MIN_POSITIVE);
    let penetration = pen.max(0.0) / gsc;
    let adhesion = adh.max(0.0) / fs;
    let product = prod / (fs * gsc);
    Complementarity {
        penetration,
        adhesion,
        product,
        violation: penetration.max(adhesion).max(product),
        max_penetration: pen.max(0.0),
        force_scale,
        gap_scale,
    }
}
