//! Explicit time marching to the periodic steady state: the independent cross-check of
//! harmonic balance, and the baseline that shows what harmonic balance saves.
//!
//! Central differences with a diagonal mass (Belytschko, Liu, Moran, Nonlinear Finite
//! Elements, §6.2), mass-proportional damping treated semi-implicitly (second order),
//! started from rest and run period by period until the state at t = kT repeats.
//! Contact:
//! - massless contact dofs (mass redistribution) are condensed statically at every step,
//!   K_zz u_z = f_z − K_zm u_m + B_zᵀλ, a small linear complementarity problem;
//! - massive contact dofs (plain lumped mass) get forward-increment Lagrange multipliers
//!   (Carpenter, Taylor, Katona, IJNME 32, 1991): the predicted penetration is removed by λ
//!   with W = Δt² B M⁻¹ Bᵀ.
//!
//! Both give an LCP: find p = −λ ≥ 0 with w = W p − q ≥ 0, p·w = 0 (q: the predicted
//! penetration), solved by a primal–dual active set method warm-started from the last step.

pub mod setup;

use std::time::{Duration, Instant};

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

use crate::linalg::Csc;
use crate::progress::Reporter;
use crate::{Error, Result};

pub struct TransientProblem<'a> {
    /// K on the free dofs (symmetric).
    pub stiffness: &'a Csc,
    /// Diagonal mass; zero entries are massless dofs.
    pub mass: &'a [f64],
    /// D = αM + βK.
    pub rayleigh: Option<(f64, f64)>,
    /// Writes f(t) on the free dofs.
    pub force: &'a (dyn Fn(f64, &mut [f64]) + Sync),
    pub contact: Option<ContactRows<'a>>,
    pub period: f64,
    /// Free dofs whose displacement is recorded at every step of the last period.
    pub probes: Vec<usize>,
}

/// Unilateral rows: B u − g0 ≤ 0, λ ≤ 0, complementary; the force on the body is Bᵀλ.
pub struct ContactRows<'a> {
    pub b: &'a Csc,
    pub g0: &'a [f64],
}

#[derive(Clone, Debug)]
pub struct TransientSettings {
    pub courant: f64,
    pub periodic_tolerance: f64,
    pub max_periods: usize,
    pub samples_per_period: usize,
}

pub struct TransientResult {
    pub dt: f64,
    pub steps_per_period: usize,
    pub periods: usize,
    pub converged: bool,
    pub periodicity_error: f64,
    /// Sample times (phases in [0, T)) of the last period.
    pub times: Vec<f64>,
    pub displacement: Vec<Vec<f64>>,
    pub velocity: Vec<Vec<f64>>,
    pub acceleration: Vec<Vec<f64>>,
    /// λ at the samples (one per contact row).
    pub contact_force: Vec<Vec<f64>>,
    /// Per probe, u at every step of the last period.
    pub probe_history: Vec<Vec<f64>>,
    /// Σλ at every step of the last period.
    pub total_contact_history: Vec<f64>,
    pub wall_time: Duration,
}

/// y = K x for symmetric K stored by columns (a gather per column, no scatter).
fn sym_mul(k: &Csc, x: &[f64], y: &mut [f64]) {
    for (j, yj) in y.iter_mut().enumerate() {
        let mut s = 0.0;
        for p in k.col_ptr[j]..k.col_ptr[j + 1] {
            s += k.values[p] * x[k.row_idx[p]];
        }
        *yj = s;
    }
}

/// The largest ω² of M⁻¹K over the massive dofs, by power iteration (an upper bound of the
/// condensed system's, whose Schur complement is softer).
pub fn estimate_max_eigenvalue(k: &Csc, mass: &[f64]) -> f64 {
    let n = mass.len();
    let mut x: Vec<f64> = (0..n)
        .map(|i| {
            if mass[i] > 0.0 {
                1.0 + ((i * 7919) % 13) as f64 / 13.0
            } else {
                0.0
            }
        })
        .collect();
    let mut y = vec![0.0; n];
    let mut lambda = 0.0;
    for _ in 0..300 {
        sym_mul(k, &x, &mut y);
        for i in 0..n {
            y[i] = if mass[i] > 0.0 { y[i] / mass[i] } else { 0.0 };
        }
        let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 || xn == 0.0 {
            break;
        }
        let next = norm / xn;
        let done = ((next - lambda) / next).abs() < 1e-6;
        lambda = next;
        for i in 0..n {
            x[i] = y[i] / norm;
        }
        if done {
            break;
        }
    }
    lambda
}

/// The LCP p ≥ 0, w = W p − q ≥ 0, p·w = 0 by primal–dual active sets (exact, finite for
/// the P-matrices met here), with projected Gauss–Seidel as the fallback.
fn solve_lcp(w: &DMatrix<f64>, q: &[f64], active: &mut [bool]) -> Result<Vec<f64>> {
    let n = q.len();
    let mut p = vec![0.0; n];
    for _ in 0..50 {
        let idx: Vec<usize> = (0..n).filter(|&i| active[i]).collect();
        p.iter_mut().for_each(|v| *v = 0.0);
        if !idx.is_empty() {
            let waa = DMatrix::from_fn(idx.len(), idx.len(), |a, b| w[(idx[a], idx[b])]);
            let qa = DVector::from_iterator(idx.len(), idx.iter().map(|&i| q[i]));
            let sol = match Cholesky::<f64, Dyn>::new(waa.clone()) {
                Some(c) => c.solve(&qa),
                None => waa
                    .lu()
                    .solve(&qa)
                    .unwrap_or_else(|| DVector::zeros(idx.len())),
            };
            for (a, &i) in idx.iter().enumerate() {
                p[i] = sol[a];
            }
        }
        let mut changed = false;
        for i in 0..n {
            let wi: f64 = (0..n).map(|j| w[(i, j)] * p[j]).sum::<f64>() - q[i];
            let now = p[i] - wi > 0.0;
            if now != active[i] {
                active[i] = now;
                changed = true;
            }
        }
        if !changed {
            return Ok(p);
        }
    }
    // Projected Gauss–Seidel from the last iterate.
    for v in p.iter_mut() {
        *v = v.max(0.0);
    }
    for _ in 0..20_000 {
        let mut delta: f64 = 0.0;
        for i in 0..n {
            let wi: f64 = (0..n).map(|j| w[(i, j)] * p[j]).sum::<f64>() - q[i];
            let next = (p[i] - wi / w[(i, i)]).max(0.0);
            delta = delta.max((next - p[i]).abs());
            p[i] = next;
        }
        let scale = p
            .iter()
            .fold(0.0f64, |a, &v| a.max(v))
            .max(f64::MIN_POSITIVE);
        if delta <= 1e-13 * scale {
            for i in 0..n {
                active[i] = p[i] > 0.0;
            }
            return Ok(p);
        }
    }
    Err(Error::NotConverged(
        "time marching: the contact LCP of a step did not converge; reduce transient.courant"
            .into(),
    ))
}

struct Condensation {
    /// Massless dofs.
    z: Vec<usize>,
    /// K_zz⁻¹ (dense).
    kzz_inv: DMatrix<f64>,
    /// Contact rows restricted to z (dense nc × nz).
    bz: DMatrix<f64>,
    /// W = B_z K_zz⁻¹ B_zᵀ.
    w: DMatrix<f64>,
}

/// Contact rows as small sparse vectors over the dofs they touch; all on massless dofs
/// (condensed) or all on massive ones (forward-increment multipliers).
fn contact_rows(problem: &TransientProblem, is_z: &[bool]) -> Result<Vec<Vec<(usize, f64)>>> {
    let Some(c) = &problem.contact else {
        return Ok(Vec::new());
    };
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); c.g0.len()];
    for j in 0..c.b.ncols {
        for p in c.b.col_ptr[j]..c.b.col_ptr[j + 1] {
            rows[c.b.row_idx[p]].push((j, c.b.values[p]));
        }
    }
    let on_z = rows.iter().flatten().filter(|(d, _)| is_z[*d]).count();
    let total = rows.iter().map(Vec::len).sum::<usize>();
    if on_z != 0 && on_z != total {
        return Err(Error::Model("time marching: contact rows touch both massless and massive dofs; use one mass model for all contact nodes".into()));
    }
    Ok(rows)
}

impl Condensation {
    /// K_zz⁻¹, B_z and W for the massless dofs `z` (none: `None`).
    fn new(k: &Csc, z: Vec<usize>, rows: &[Vec<(usize, f64)>]) -> Result<Option<Self>> {
        if z.is_empty() {
            return Ok(None);
        }
        let pos: std::collections::HashMap<usize, usize> =
            z.iter().enumerate().map(|(a, &d)| (d, a)).collect();
        let mut kzz = DMatrix::zeros(z.len(), z.len());
        for (b, &j) in z.iter().enumerate() {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                if let Some(&a) = pos.get(&k.row_idx[p]) {
                    kzz[(a, b)] += k.values[p];
                }
            }
        }
        let Some(chol) = Cholesky::new(kzz) else {
            return Err(Error::Model("time marching: the stiffness among the massless dofs is singular (a massless node without stiffness?)".into()));
        };
        let kzz_inv = chol.inverse();
        let mut bz = DMatrix::zeros(rows.len(), z.len());
        for (i, row) in rows.iter().enumerate() {
            for &(d, v) in row {
                if let Some(&a) = pos.get(&d) {
                    bz[(i, a)] = v;
                }
            }
        }
        let w = &bz * &kzz_inv * bz.transpose();
        Ok(Some(Condensation { z, kzz_inv, bz, w }))
    }
}

/// Δt stable for central differences (with stiffness damping), fitted to the period and the
/// samples: (Δt, steps per period, steps per sample).
fn time_step(
    problem: &TransientProblem,
    settings: &TransientSettings,
    beta: f64,
) -> Result<(f64, usize, usize)> {
    let omega_max = estimate_max_eigenvalue(problem.stiffness, problem.mass).sqrt() * 1.05;
    if !(omega_max > 0.0 && omega_max.is_finite()) {
        return Err(Error::Model(
            "time marching: no massive dof or no stiffness".into(),
        ));
    }
    let xi = beta * omega_max / 2.0;
    let dt_stable = settings.courant * (2.0 / omega_max) * ((1.0 + xi * xi).sqrt() - xi);
    let s = settings.samples_per_period.max(1);
    let per_sample = ((problem.period / dt_stable) / s as f64).ceil().max(1.0) as usize;
    let steps = per_sample * s;
    Ok((problem.period / steps as f64, steps, per_sample))
}

/// W = Δt² B M⁻¹ Bᵀ / (1 + αΔt/2) for forward-increment multipliers on massive dofs.
fn lumped_w(rows: &[Vec<(usize, f64)>], mass: &[f64], dt: f64, alpha: f64) -> DMatrix<f64> {
    let nc = rows.len();
    let mut w = DMatrix::zeros(nc, nc);
    for a in 0..nc {
        for b in 0..nc {
            let mut sum = 0.0;
            for &(d, va) in &rows[a] {
                for &(e, vb) in &rows[b] {
                    if d == e {
                        sum += va * vb / mass[d];
                    }
                }
            }
            w[(a, b)] = dt * dt * sum / (1.0 + alpha * dt / 2.0);
        }
    }
    w
}

/// ‖state − previous‖ / ‖state‖ between the states at two successive period starts.
fn relative_change(state: &[f64], previous: &[f64]) -> f64 {
    let diff = state
        .iter()
        .zip(previous)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let norm = state
        .iter()
        .map(|a| a * a)
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE);
    diff / norm
}

pub fn run_to_periodic(
    problem: &TransientProblem,
    settings: &TransientSettings,
    reporter: &dyn Reporter,
) -> Result<TransientResult> {
    let start = Instant::now();
    let k = problem.stiffness;
    let n = problem.mass.len();
    let mass = problem.mass;
    let (alpha, beta) = problem.rayleigh.unwrap_or((0.0, 0.0));
    let z: Vec<usize> = (0..n).filter(|&i| mass[i] <= 0.0).collect();
    let is_z: Vec<bool> = (0..n).map(|i| mass[i] <= 0.0).collect();
    let nc = problem.contact.as_ref().map_or(0, |c| c.g0.len());
    let rows = contact_rows(problem, &is_z)?;
    let condensed_contact = nc > 0 && rows.iter().flatten().all(|(d, _)| is_z[*d]);

    // Static condensation of the massless dofs.
    let condensation = Condensation::new(k, z, &rows)?;

    let (dt, steps, per_sample) = time_step(problem, settings, beta)?;
    let s = settings.samples_per_period.max(1);

    let mut u = vec![0.0; n];
    let mut u_prev = vec![0.0; n];
    // Three rotating buffers: no allocation in the time loop.
    let mut u_next = vec![0.0; n];
    let mut v_half = vec![0.0; n];
    let mut f = vec![0.0; n];
    let mut ku = vec![0.0; n];
    let mut kv = vec![0.0; n];
    let mut lambda = vec![0.0; nc];
    let mut active = vec![false; nc];
    let mut last_state: Option<Vec<f64>> = None;
    let mut periods = 0;
    let mut converged = false;
    let mut change = f64::INFINITY;
    let mut times = Vec::new();
    let mut displacement = vec![Vec::new(); s];
    let mut velocity = vec![Vec::new(); s];
    let mut acceleration = vec![Vec::new(); s];
    let mut contact_force = vec![vec![0.0; nc]; s];
    let mut probe_history = vec![vec![0.0; steps]; problem.probes.len()];
    let mut total_contact_history = vec![0.0; steps];
    let lumped_w = (nc > 0 && !condensed_contact).then(|| lumped_w(&rows, mass, dt, alpha));
    for i in 0..s {
        times.push(i as f64 * problem.period / s as f64);
    }

    // Condense the massless dofs. Their rows carry no inertia but do carry stiffness-
    // proportional damping: K_z·(u + βu̇) = f_z + B_zᵀλ is static in w = u + βu̇, and u_z
    // follows from w_z by backward Euler, u_z' = s w_z + (1 − s) u_z with s = 1/(1 + β/Δt).
    // `w` holds u + βu̇ on the massive dofs; `uz_old` the massless dofs' last values.
    let condense = |w: &[f64],
                    out: &mut [f64],
                    uz_old: &[f64],
                    s_weight: f64,
                    f: &[f64],
                    lambda: &mut [f64],
                    active: &mut [bool]|
     -> Result<()> {
        let Some(c) = &condensation else {
            return Ok(());
        };
        let nz = c.z.len();
        let mut rhs = DVector::zeros(nz);
        for (a, &j) in c.z.iter().enumerate() {
            let mut sum = f[j];
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                let r = k.row_idx[p];
                if !is_z[r] {
                    sum -= k.values[p] * w[r];
                }
            }
            rhs[a] = sum;
        }
        let mut wz = &c.kzz_inv * &rhs;
        let old = DVector::from_iterator(nz, c.z.iter().map(|&j| uz_old[j]));
        if condensed_contact {
            let predicted = (&wz * s_weight) + (&old * (1.0 - s_weight));
            let gap = &c.bz * &predicted;
            let q: Vec<f64> = (0..nc)
                .map(|i| gap[i] - problem.contact.as_ref().map_or(0.0, |cr| cr.g0[i]))
                .collect();
            let p = solve_lcp(&(&c.w * s_weight), &q, active)?;
            for i in 0..nc {
                lambda[i] = -p[i];
            }
            let lam = DVector::from_iterator(nc, lambda.iter().copied());
            wz += &c.kzz_inv * (c.bz.transpose() * lam);
        }
        let uz = (&wz * s_weight) + (&old * (1.0 - s_weight));
        for (a, &j) in c.z.iter().enumerate() {
            out[j] = uz[a];
        }
        Ok(())
    };
    let s_weight = 1.0 / (1.0 + beta / dt);
    let mut w_massive = vec![0.0; n];

    let mut t = 0.0;
    (problem.force)(t, &mut f);
    // At rest: the static state of the massless dofs (s = 1).
    let rest = u.clone();
    condense(&rest, &mut u, &rest, 1.0, &f, &mut lambda, &mut active)?;
    u_prev.copy_from_slice(&u);
    while periods < settings.max_periods {
        for step in 0..steps {
            t = (periods * steps + step) as f64 * dt;
            (problem.force)(t, &mut f);
            sym_mul(k, &u, &mut ku);
            if beta != 0.0 {
                sym_mul(k, &v_half, &mut kv);
            }
            let damp = alpha * dt / 2.0;
            for i in 0..n {
                if is_z[i] {
                    continue;
                }
                let r = f[i] - ku[i] - beta * kv[i];
                let v = ((1.0 - damp) * v_half[i] + dt * r / mass[i]) / (1.0 + damp);
                u_next[i] = u[i] + dt * v;
            }
            if let Some(w) = &lumped_w {
                // Forward-increment multipliers on massive contact dofs.
                let c = problem.contact.as_ref().map(|c| c.g0).unwrap_or(&[]);
                let q: Vec<f64> = (0..nc)
                    .map(|a| rows[a].iter().map(|&(d, v)| v * u_next[d]).sum::<f64>() - c[a])
                    .collect();
                let p = solve_lcp(w, &q, &mut active)?;
                for a in 0..nc {
                    lambda[a] = -p[a];
                    for &(d, v) in &rows[a] {
                        u_next[d] += dt * dt * v * lambda[a] / mass[d] / (1.0 + damp);
                    }
                }
            }
            let t_next = t + dt;
            if condensation.is_some() {
                (problem.force)(t_next, &mut f);
                for i in 0..n {
                    w_massive[i] = if is_z[i] {
                        0.0
                    } else {
                        u_next[i] + beta * (u_next[i] - u[i]) / dt
                    };
                }
                condense(
                    &w_massive,
                    &mut u_next,
                    &u,
                    s_weight,
                    &f,
                    &mut lambda,
                    &mut active,
                )?;
            }
            for i in 0..n {
                v_half[i] = (u_next[i] - u[i]) / dt;
            }
            // Record the state at the step (u at `step`, centred differences around it).
            if step.is_multiple_of(per_sample) {
                let j = step / per_sample;
                displacement[j] = u.clone();
                velocity[j] = (0..n)
                    .map(|i| (u_next[i] - u_prev[i]) / (2.0 * dt))
                    .collect();
                acceleration[j] = (0..n)
                    .map(|i| (u_next[i] - 2.0 * u[i] + u_prev[i]) / (dt * dt))
                    .collect();
            }
            for (history, &d) in probe_history.iter_mut().zip(&problem.probes) {
                history[step] = u[d];
            }
            // λ belongs to the end of this step (it enforced u_next); book it at step + 1.
            let next = (step + 1) % steps;
            total_contact_history[next] = lambda.iter().sum();
            if next.is_multiple_of(per_sample) {
                contact_force[next / per_sample] = lambda.clone();
            }
            // Rotate: (prev, current, next) ← (current, next, old prev).
            std::mem::swap(&mut u_prev, &mut u);
            std::mem::swap(&mut u, &mut u_next);
        }
        periods += 1;
        if u.iter().any(|v| !v.is_finite()) {
            return Err(Error::NotConverged(format!(
                "time marching blew up in period {periods} (dt = {dt:e} s): lower transient.courant (now {})",
                settings.courant
            )));
        }
        let state: Vec<f64> = u
            .iter()
            .copied()
            .chain(v_half.iter().map(|v| v * problem.period))
            .collect();
        if let Some(prev) = &last_state {
            change = relative_change(&state, prev);
            reporter.progress(
                "periods",
                periods as u64,
                Some(settings.max_periods as u64),
                &format!("change {change:.2e}"),
            );
            if change < settings.periodic_tolerance {
                converged = true;
                break;
            }
        }
        last_state = Some(state);
    }
    Ok(TransientResult {
        dt,
        steps_per_period: steps,
        periods,
        converged,
        periodicity_error: change,
        times,
        displacement,
        velocity,
        acceleration,
        contact_force,
        probe_history,
        total_contact_history,
        wall_time: start.elapsed(),
    })
}
