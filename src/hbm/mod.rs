//! Harmonic balance: the periodic steady state of M ü + D u̇ + K u = Bᵀλ + f(t) with
//! unilateral contact B u − g0 ≤ 0, λ ≤ 0, λ·(B u − g0) = 0.
//!
//! Glossary (as in `../shared/design/method.md`):
//! - ω = 2πf the fundamental angular frequency, T = 2π/ω the period;
//! - H the highest harmonic kept, M = 2H + 1 Fourier coefficients per scalar;
//! - N time samples per period for the contact terms (N > 2H; default 16H);
//! - Z_k = K − k²ω²M + ikωD the dynamic stiffness of harmonic k, z_k = a_k − i b_k the complex
//!   amplitude, so u(t) = Re Σ_k z_k e^{ikωt};
//! - G_k = B Z_k⁻¹ Bᵀ the contact nodes' dynamic compliance, r the linear gap;
//! - c > 0 the complementarity parameter (a stiffness; default 1/mean|G_0,ii|).
//!
//! A scene pays only for what it contains: a linear scene factors only the harmonics its loads
//! excite (no static solve without static load), undamped scenes factor real matrices, and
//! the contact reduction runs only when there is an obstacle.

pub mod fourier;
pub mod reduced;
pub mod system;

use std::collections::BTreeMap;
use std::time::Instant;

use faer::c64;

use crate::linalg::Csc;
use crate::{Error, Result};
pub use reduced::{IterationLog, NewtonOutcome, NewtonSettings, ReducedProblem};
pub use system::{DofMap, HarmonicInput, System};

/// The contact operator on the reduced dofs.
#[derive(Clone, Debug)]
pub struct ContactOperator {
    /// B restricted to the free dofs (nc × free).
    pub b_free: Csc,
    /// B restricted to the prescribed dofs (nc × prescribed): prescribed motion moves gaps.
    pub b_prescribed: Csc,
    /// Initial gaps along the normals.
    pub g0: Vec<f64>,
}

impl ContactOperator {
    pub fn nodes(&self) -> usize {
        self.g0.len()
    }
}

#[derive(Clone, Debug)]
pub struct HbSettings {
    /// Highest harmonic of the contact solve.
    pub harmonics: usize,
    /// Samples per period (N > 2H).
    pub samples: usize,
    pub c_scale: f64,
    pub tolerance: f64,
    pub max_iterations: usize,
}

impl HbSettings {
    /// N = 16H converged where 2H+1 and 4H did not (method.md); static needs one sample.
    pub fn default_samples(harmonics: usize) -> usize {
        if harmonics == 0 {
            1
        } else {
            (16 * harmonics).max(64)
        }
    }
}

/// Wall time per stage of the solve.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Timings {
    pub factor: f64,
    pub linear_solve: f64,
    pub reduce: f64,
    pub newton: f64,
    pub recover: f64,
}

/// How far the Fourier-series λ and g miss complementarity at the samples, each relative to
/// its own scale (the peak contact force, the linear gap range).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Complementarity {
    /// max(0, g) / gap scale: sampled penetration.
    pub penetration: f64,
    /// max(0, λ) / force scale: sampled adhesion (pulling) force.
    pub adhesion: f64,
    /// max |λ g| / (force scale · gap scale).
    pub product: f64,
    /// The largest of the three.
    pub violation: f64,
    /// Absolute sampled penetration (length).
    pub max_penetration: f64,
    pub force_scale: f64,
    pub gap_scale: f64,
}

/// The contact part of a solution.
#[derive(Clone, Debug)]
pub struct ContactSolution {
    pub harmonics: usize,
    pub samples: usize,
    pub c: f64,
    /// λ coefficients, node-major, 2H+1 per node.
    pub multipliers: Vec<f64>,
    /// Gap coefficients g = B u − g0, node-major.
    pub gaps: Vec<f64>,
    pub newton: NewtonOutcome,
    /// The harmonic ladder actually climbed (just [H] when the direct solve converged).
    pub ladder: Vec<usize>,
    pub complementarity: Complementarity,
}

/// A periodic steady state.
pub struct Solution {
    pub omega: f64,
    /// Harmonic index → complex amplitude on the free dofs.
    pub free: BTreeMap<usize, Vec<c64>>,
    /// Harmonic index → prescribed motion amplitudes.
    pub motion: BTreeMap<usize, Vec<c64>>,
    pub contact: Option<ContactSolution>,
    /// Relative residual of each harmonic's linear solve.
    pub residuals: BTreeMap<usize, f64>,
    /// "real" or "complex" factorizations.
    pub complex_arithmetic: bool,
    pub timings: Timings,
    /// Things the user should know although the solve succeeded (near resonance, …).
    pub warnings: Vec<String>,
}

impl Solution {
    pub fn harmonics(&self) -> Vec<usize> {
        self.free.keys().copied().collect()
    }

    /// Displacement (derivative 0), velocity (1) or acceleration (2) at time t on all dofs.
    pub fn field_at(&self, dofs: &DofMap, t: f64, derivative: u32) -> Vec<f64> {
        let mut u = vec![0.0; dofs.total()];
        let factor = |k: usize| -> c64 {
            let kw = k as f64 * self.omega;
            let rot = c64::from_polar(1.0, kw * t);
            let d = c64::new(0.0, kw).powu(derivative);
            rot * d
        };
        for (&k, z) in &self.free {
            let f = factor(k);
            for (i, &d) in dofs.free.iter().enumerate() {
                u[d] += (z[i] * f).re;
            }
        }
        for (&k, z) in &self.motion {
            let f = factor(k);
            for (i, &d) in dofs.prescribed.iter().enumerate() {
                u[d] += (z[i] * f).re;
            }
        }
        u
    }

    /// The complex amplitude of harmonic k on all dofs.
    pub fn amplitude(&self, dofs: &DofMap, k: usize) -> Vec<c64> {
        let mut z = vec![c64::new(0.0, 0.0); dofs.total()];
        if let Some(zf) = self.free.get(&k) {
            for (i, &d) in dofs.free.iter().enumerate() {
                z[d] = zf[i];
            }
        }
        if let Some(zp) = self.motion.get(&k) {
            for (i, &d) in dofs.prescribed.iter().enumerate() {
                z[d] = zp[i];
            }
        }
        z
    }
}

fn is_zero(v: &[c64]) -> bool {
    v.iter().all(|z| z.re == 0.0 && z.im == 0.0)
}

fn to_coefficients(z: c64) -> (f64, f64) {
    (z.re, -z.im)
}

/// Solve for the periodic steady state. `progress` receives short status lines.
pub fn solve(
    system: &System,
    contact: Option<&ContactOperator>,
    settings: &HbSettings,
    progress: &dyn Fn(&str),
) -> Result<Solution> {
    let nf = system.free_count();
    let mut timings = Timings::default();
    let harmonics: Vec<usize> = match contact {
        Some(_) => (0..=settings.harmonics).collect(),
        None => system
            .inputs
            .iter()
            .filter(|(_, input)| !is_zero(&input.force) || !is_zero(&input.motion))
            .map(|(&k, _)| k)
            .collect(),
    };
    let complex_arithmetic = system.rayleigh.is_some() && harmonics.iter().any(|&k| k > 0);
    if contact.is_some() {
        let excited_max = system.inputs.keys().copied().max().unwrap_or(0);
        if excited_max > settings.harmonics {
            return Err(Error::Model(format!(
                "the loads excite harmonic {excited_max} but harmonic_balance.harmonics = {}: raise it to at least {excited_max} (contact couples all harmonics up to H, and a load above H would be dropped)",
                settings.harmonics
            )));
        }
    }

    let mut free = BTreeMap::new();
    let mut motion = BTreeMap::new();
    let mut residuals = BTreeMap::new();
    let mut warnings = Vec::new();
    // Z_k⁻¹ Bᵀ per harmonic, kept for the recovery (24).
    let mut compliance_columns: BTreeMap<usize, Vec<Vec<c64>>> = BTreeMap::new();
    let mut compliance = Vec::new();
    let bt_columns: Vec<Vec<c64>> = contact
        .map(|op| transpose_rows(&op.b_free))
        .unwrap_or_default();

    if harmonics.first() == Some(&0) && system.dofs.prescribed.is_empty() {
        // Nothing holds the body against rigid motion: K is singular by construction.
        return Err(singular_diagnosis(system, 0));
    }
    for &k in &harmonics {
        progress(&format!("harmonic {k}: factor"));
        let start = Instant::now();
        let lu = system.factor(k)?;
        timings.factor += start.elapsed().as_secs_f64();

        let start = Instant::now();
        let rhs = system.load(k);
        let mut z = if is_zero(&rhs) {
            rhs.clone()
        } else {
            lu.solve(&rhs)
        };
        let mut res = system::relative_residual(system, k, &z, &rhs);
        // Iterative refinement: large, badly conditioned systems (slender parts, fine
        // meshes) lose digits in the LU; a few cheap solves win them back.
        for _ in 0..3 {
            if !(res > 1e-14) || !res.is_finite() {
                break;
            }
            let zz = system.apply(k, &z);
            let r: Vec<c64> = rhs.iter().zip(&zz).map(|(b, a)| b - a).collect();
            let dz = lu.solve(&r);
            for (zi, di) in z.iter_mut().zip(&dz) {
                *zi += di;
            }
            res = system::relative_residual(system, k, &z, &rhs);
        }
        check_solve(system, k, res, system::amplification(system, &z, &rhs), &z)?;
        if let Some(w) = resonance_warning(system, k, &z, &rhs) {
            warnings.push(w);
        }
        residuals.insert(k, res);
        timings.linear_solve += start.elapsed().as_secs_f64();

        if let Some(op) = contact {
            let start = Instant::now();
            let cols = lu.solve_many(&bt_columns);
            for col in &cols {
                if col.iter().any(|z| !z.re.is_finite() || !z.im.is_finite()) {
                    return Err(singular_diagnosis(system, k));
                }
            }
            let nc = op.nodes();
            let mut gk = vec![c64::new(0.0, 0.0); nc * nc];
            for (j, col) in cols.iter().enumerate() {
                let (re, im): (Vec<f64>, Vec<f64>) = col.iter().map(|z| (z.re, z.im)).unzip();
                let (bre, bim) = (op.b_free.mul_vec(&re), op.b_free.mul_vec(&im));
                for i in 0..nc {
                    gk[i * nc + j] = c64::new(bre[i], bim[i]);
                }
            }
            compliance.push(gk);
            compliance_columns.insert(k, cols);
            timings.reduce += start.elapsed().as_secs_f64();
        }
        free.insert(k, z);
        motion.insert(k, system.motion(k));
    }
    debug_assert_eq!(free.values().next().map_or(nf, Vec::len), nf);

    let contact_solution = match contact {
        None => None,
        Some(op) => {
            let solution = solve_contact(
                system,
                op,
                settings,
                &free,
                &motion,
                compliance,
                &mut timings,
                progress,
            )?;
            // Recovery (24): z_k = Z_k⁻¹(f_k + Bᵀλ_k) = z_lin,k + (Z_k⁻¹Bᵀ) λ_k.
            let start = Instant::now();
            let m = 2 * settings.harmonics + 1;
            for (&k, cols) in &compliance_columns {
                let Some(z) = free.get_mut(&k) else { continue };
                for (j, col) in cols.iter().enumerate() {
                    let lam = if k == 0 {
                        c64::new(solution.multipliers[j * m], 0.0)
                    } else {
                        c64::new(
                            solution.multipliers[j * m + 2 * k - 1],
                            -solution.multipliers[j * m + 2 * k],
                        )
                    };
                    if lam.norm() == 0.0 {
                        continue;
                    }
                    for (zi, ci) in z.iter_mut().zip(col) {
                        *zi += ci * lam;
                    }
                }
            }
            timings.recover += start.elapsed().as_secs_f64();
            Some(solution)
        }
    };
    Ok(Solution {
        omega: system.omega,
        free,
        motion,
        contact: contact_solution,
        residuals,
        complex_arithmetic,
        timings,
        warnings,
    })
}

/// Columns of Bᵀ (= rows of B) as dense complex vectors.
fn transpose_rows(b: &Csc) -> Vec<Vec<c64>> {
    let mut rows = vec![vec![c64::new(0.0, 0.0); b.ncols]; b.nrows];
    for (j, window) in b.col_ptr.windows(2).enumerate() {
        for p in window[0]..window[1] {
            rows[b.row_idx[p]][j] = c64::new(b.values[p], 0.0);
        }
    }
    rows
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

/// The dynamic amplification ‖K z‖ / ‖f‖ of harmonic k: far above 1 means the forcing sits
/// near a natural frequency, where an undamped answer is set by the distance to resonance
/// alone and a lightly damped one by the damping alone.
fn resonance_warning(system: &System, k: usize, z: &[c64], f: &[c64]) -> Option<String> {
    if k == 0 {
        return None;
    }
    let (re, im): (Vec<f64>, Vec<f64>) = z.iter().map(|v| (v.re, v.im)).unzip();
    let (kr, ki) = (system.k_ff.mul_vec(&re), system.k_ff.mul_vec(&im));
    let num: f64 = kr
        .iter()
        .zip(&ki)
        .map(|(a, b)| a * a + b * b)
        .sum::<f64>()
        .sqrt();
    let den: f64 = f.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
    let amplification = if den > 0.0 { num / den } else { 0.0 };
    let f_hz = k as f64 * system.omega / (2.0 * std::f64::consts::PI);
    (amplification > 100.0).then(|| {
        format!(
            "harmonic {k} ({f_hz:.4} Hz) is amplified {amplification:.0}× over its static response: the \
             forcing is close to a natural frequency. The amplitude there is set by {}; check that \
             this is intended",
            if system.rayleigh.is_some() { "the damping" } else { "the distance to resonance alone (no damping)" }
        )
    })
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

#[allow(clippy::too_many_arguments)]
fn solve_contact(
    system: &System,
    op: &ContactOperator,
    settings: &HbSettings,
    free: &BTreeMap<usize, Vec<c64>>,
    motion: &BTreeMap<usize, Vec<c64>>,
    compliance: Vec<Vec<c64>>,
    timings: &mut Timings,
    progress: &dyn Fn(&str),
) -> Result<ContactSolution> {
    let start = Instant::now();
    let (nc, h) = (op.nodes(), settings.harmonics);
    let m = 2 * h + 1;
    // The linear gap r = B z_lin + B_p u_p − g0 δ_k0, as real coefficients.
    let mut r = vec![0.0; nc * m];
    for k in 0..=h {
        let z = &free[&k];
        let (re, im): (Vec<f64>, Vec<f64>) = z.iter().map(|v| (v.re, v.im)).unzip();
        let (mut bre, mut bim) = (op.b_free.mul_vec(&re), op.b_free.mul_vec(&im));
        if op.b_prescribed.ncols > 0 {
            let up = &motion[&k];
            let (pre, pim): (Vec<f64>, Vec<f64>) = up.iter().map(|v| (v.re, v.im)).unzip();
            for (a, b) in bre.iter_mut().zip(op.b_prescribed.mul_vec(&pre)) {
                *a += b;
            }
            for (a, b) in bim.iter_mut().zip(op.b_prescribed.mul_vec(&pim)) {
                *a += b;
            }
        }
        for i in 0..nc {
            if k == 0 {
                r[i * m] = bre[i] - op.g0[i];
            } else {
                let (a, b) = to_coefficients(c64::new(bre[i], bim[i]));
                r[i * m + 2 * k - 1] = a;
                r[i * m + 2 * k] = b;
            }
        }
    }
    let problem = ReducedProblem {
        nodes: nc,
        harmonics: h,
        compliance,
        linear_gap: r,
    };
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
    let c = settings.c_scale / mean_compliance;
    timings.reduce += start.elapsed().as_secs_f64();

    let start = Instant::now();
    let newton_settings = |hh: usize, c: f64| NewtonSettings {
        samples: if hh == h {
            settings.samples
        } else {
            // Keep the same oversampling ratio on the lower rungs.
            (settings.samples * hh).div_ceil(h.max(1)).max(2 * hh + 1)
        },
        c,
        tolerance: settings.tolerance,
        max_iterations: settings.max_iterations,
        dense_limit: reduced::DENSE_LIMIT,
    };
    // Globalization, cheapest first: the plain Newton; then climbing the harmonic ladder from
    // a low H (each rung warm-starting the next: the low harmonics of an impact response are
    // found first); then both again with c ten times smaller (a softer penalty on the gap,
    // method.md: the c that converges is a band).
    let attempt = |c: f64,
                   total: &mut usize,
                   log: &mut Vec<IterationLog>,
                   reasons: &mut Vec<String>|
     -> Option<(NewtonOutcome, Vec<usize>)> {
        progress(&format!(
            "contact Newton: H = {h}, N = {}, {nc} nodes, c = {c:.3e}",
            settings.samples
        ));
        let o = reduced::newton(&problem, &newton_settings(h, c), &vec![0.0; nc * m]);
        *total += o.iterations;
        log.extend(o.log.iter().cloned());
        if o.converged {
            return Some((o, vec![h]));
        }
        reasons.push(format!("direct at c = {c:.3e}: {}", o.reason));
        if h < 2 {
            return None;
        }
        let mut rungs: Vec<usize> = [h / 8, h / 4, h / 2]
            .into_iter()
            .filter(|&r| r >= 1)
            .collect();
        rungs.dedup();
        rungs.push(h);
        progress(&format!("contact Newton: climbing H = {rungs:?}"));
        let mut x = vec![0.0; nc * 3];
        let mut prev = 1;
        for &rung in &rungs {
            let start_x = reduced::pad(&x, nc, prev, rung);
            let o = reduced::newton(&problem.truncate(rung), &newton_settings(rung, c), &start_x);
            *total += o.iterations;
            log.extend(o.log.iter().cloned());
            if !o.converged {
                reasons.push(format!(
                    "ladder at c = {c:.3e} failed at H = {rung}: {}",
                    o.reason
                ));
                return None;
            }
            x = o.multipliers.clone();
            prev = rung;
            if rung == h {
                return Some((o, rungs));
            }
        }
        None
    };
    let (mut total, mut log, mut reasons) = (0usize, Vec::new(), Vec::new());
    let mut found = None;
    for c_try in [c, 0.1 * c] {
        if let Some((o, ladder)) = attempt(c_try, &mut total, &mut log, &mut reasons) {
            found = Some((o, ladder, c_try));
            break;
        }
    }
    timings.newton += start.elapsed().as_secs_f64();
    let Some((mut outcome, ladder, c)) = found else {
        let last = log.last().cloned();
        let failed = NewtonOutcome {
            multipliers: Vec::new(),
            converged: false,
            iterations: total,
            relative_residual: last.as_ref().map_or(f64::NAN, |l| l.residual),
            log,
            reason: reasons.join("; "),
        };
        return Err(stall_diagnosis(system, settings, &failed));
    };
    outcome.iterations = total;
    outcome.log = log;
    let gaps = problem.gap(&outcome.multipliers);
    let complementarity =
        measure_complementarity(&problem, &outcome.multipliers, &gaps, settings.samples);
    Ok(ContactSolution {
        harmonics: h,
        samples: settings.samples,
        c,
        multipliers: outcome.multipliers.clone(),
        gaps,
        newton: outcome,
        ladder,
        complementarity,
    })
}

fn stall_diagnosis(system: &System, settings: &HbSettings, outcome: &NewtonOutcome) -> Error {
    let mut advice = Vec::new();
    let h = settings.harmonics;
    if settings.samples < 16 * h {
        advice.push(format!(
            "raise harmonic_balance.samples (now {}; 16·H = {} converges reliably)",
            settings.samples,
            16 * h
        ));
    }
    advice.push(
        "make sure contact.mass is `redistributed` (contact nodes with inertia make impacts that \
         no truncated Fourier series resolves)"
            .to_string(),
    );
    if settings.c_scale >= 1.0 {
        advice.push(format!(
            "lower harmonic_balance.solver.c_scale (now {}; try 0.3 or 0.1)",
            settings.c_scale
        ));
    }
    match system.rayleigh {
        None => advice.push("add damping (the scene has none): damping.beta damps the mesh's high modes that impacts excite".into()),
        Some((_, 0.0)) => advice.push(
            "add stiffness-proportional damping damping.beta (e.g. 1e-7 s for steel at mm-size elements): with mass-proportional damping alone the mesh's high modes, which every impact excites, stay undamped".into(),
        ),
        _ => {}
    }
    advice.push(format!("or lower harmonic_balance.harmonics (now {h})"));
    let last = outcome.log.last();
    Error::NotConverged(format!(
        "the contact Newton stalled after {} iterations: {}; relative residual {:.3e}, {} active \
         samples. To fix: {}",
        outcome.iterations,
        outcome.reason,
        outcome.relative_residual,
        last.map_or(0, |l| l.active_samples),
        advice.join("; ")
    ))
}

/// Violation of λ ≤ 0, g ≤ 0, λg = 0 by the Fourier series at the N samples.
pub fn measure_complementarity(
    problem: &ReducedProblem,
    lambda: &[f64],
    gaps: &[f64],
    samples: usize,
) -> Complementarity {
    let sampler = fourier::Sampler::new(problem.harmonics, samples);
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
