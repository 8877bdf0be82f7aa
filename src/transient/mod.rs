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

pub mod budget;
pub mod characterize;
pub mod late;
pub mod setup;

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

use crate::linalg::norm2;
use crate::linalg::Csc;
use crate::progress::Reporter;
use crate::{Error, Result};

/// Whether a history of period-to-period changes and departures decided a question.
pub type Decided<'a> = dyn Fn(&[f64], &[f64]) -> bool + Sync + 'a;

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
    /// The state at t = 0 (`None`: rest).
    pub initial: Option<InitialState>,
    /// The Coriolis force of a rotating frame (`None`: none).
    pub coriolis: Option<Coriolis>,
    /// Stop early once this says the history so far decided the question (it gets the
    /// period-to-period changes and the departures, `TransientResult`).
    pub decided: Option<&'a Decided<'a>>,
}

/// The Coriolis force 2Ω m ẑ × u̇ on each node whose two dofs are free: Ω [rad/s] and the
/// (x, y) free-dof pairs. With the lumped mass it couples only a node's own two dofs, so the
/// trapezoidal rule on it (`Stepper::coriolis`) is a 2 × 2 solve per node: implicit, so it
/// does not shorten the step, and it keeps the gyroscopic force workless as the exact one.
#[derive(Clone, Debug)]
pub struct Coriolis {
    pub speed: f64,
    pub pairs: Vec<(usize, usize)>,
}

/// A state to start the marching from: u and u̇ at t = 0 on the free dofs (the massless
/// dofs' values are recomputed from the massive ones, as they are at every step).
#[derive(Clone, Debug)]
pub struct InitialState {
    pub displacement: Vec<f64>,
    pub velocity: Vec<f64>,
}

impl InitialState {
    /// The state times `scale` (a perturbation of a start).
    pub fn scaled(self, scale: f64) -> Self {
        InitialState {
            displacement: self.displacement.iter().map(|v| scale * v).collect(),
            velocity: self.velocity.iter().map(|v| scale * v).collect(),
        }
    }
}

/// Unilateral rows: B u − g0(t) ≤ 0, λ ≤ 0, complementary; the force on the body is Bᵀλ.
/// g0(t) = g0 + Σ_k Re(ĝ_k e^{ikωt}) (a moving or out-of-round obstacle; no harmonics: fixed).
#[derive(Clone, Copy)]
pub struct ContactRows<'a> {
    pub b: &'a Csc,
    pub g0: &'a [f64],
    pub gap_harmonics: &'a std::collections::BTreeMap<usize, Vec<faer::c64>>,
    pub omega: f64,
    /// Coulomb friction: the tangential rows B_t (one per contact row) and μ per row.
    pub friction: Option<(&'a Csc, &'a [f64])>,
}

impl ContactRows<'_> {
    /// g0(t) into `out`.
    fn gap_at(&self, t: f64, out: &mut [f64]) {
        crate::contact::operator::periodic_gap(self.g0, self.gap_harmonics, self.omega, t, out);
    }
}

#[derive(Clone, Debug)]
pub struct TransientSettings {
    pub courant: f64,
    pub periodic_tolerance: f64,
    pub max_periods: usize,
    pub samples_per_period: usize,
}

pub struct TransientResult {
    /// What friction did over the last whole period (frictional scenes).
    pub friction: Option<MarchedFriction>,
    pub dt: f64,
    pub steps_per_period: usize,
    /// Whole periods marched.
    pub periods: usize,
    /// `Some(k)` when an interruption (`request_stop`) ended the march k steps into the period
    /// after the last whole one (0 ≤ k < `steps_per_period`): the samples are then the last
    /// period of time marched (phase-indexed, so `times` still hold; ending k steps into that
    /// period), the end state and the periodicity those of the last whole period.
    pub interrupted: Option<usize>,
    pub converged: bool,
    pub periodicity_error: f64,
    /// Per period k = 1, 2, …: ‖x_k − x_{k−1}‖/‖x_k‖, x = (u, T u̇) at the period start (the
    /// first entry compares with the start state).
    pub changes: Vec<f64>,
    /// Per period k = 1, 2, …: ‖u_k − u_0‖/(‖u_0‖² + ‖u̇_0/ω‖²)^½, the displacements' distance
    /// from the start relative to its amplitude (displacements only: a truncated Fourier
    /// start differs from the marched orbit mostly in the velocities of the waves impacts
    /// send).
    pub departures: Vec<f64>,
    /// The state at the end of the last whole period (u and the half-step velocity).
    pub end_state: InitialState,
    /// Sample times (phases in [0, T)) of the last period.
    pub times: Vec<f64>,
    pub displacement: Vec<Vec<f64>>,
    pub velocity: Vec<Vec<f64>>,
    pub acceleration: Vec<Vec<f64>>,
    /// λ at the samples (one per contact row).
    pub contact_force: Vec<Vec<f64>>,
    /// With friction, λ_t and the slip velocity at the samples (one per contact row; empty
    /// without).
    pub tangential_force: Vec<Vec<f64>>,
    pub slip_velocity: Vec<Vec<f64>>,
    /// Per probe, u at every step of the last period.
    pub probe_history: Vec<Vec<f64>>,
    /// Σλ at every step of the last period.
    pub total_contact_history: Vec<f64>,
    /// The last whole periods (`late::PERIODS_KEPT`) of the probes and the contact force,
    /// for `characterize`.
    pub late: late::LateRecord,
    pub wall_time: Duration,
}

/// Symmetric K laid out for the marching's product y = K x, the bulk of its time: rows
/// grouped in pairs that share their column pattern (a node's two dofs, in an assembly), so
/// each column index and x entry is read once for both rows; rows without a partner stand
/// alone. The same sums, in the same order, as a gather per column of K stored by columns
/// (the test's `sym_mul`). The one product of the marching and its step-size estimate.
struct RowPairs {
    /// Per group: its first row, whether it is a pair, and its columns' range in `cols`.
    groups: Vec<(usize, bool, std::ops::Range<usize>)>,
    cols: Vec<usize>,
    /// A pair's values interleaved per column (row, row + 1); a single row's one per column.
    values: Vec<f64>,
    /// Where each group's values start.
    value_start: Vec<usize>,
}

impl RowPairs {
    fn new(k: &Csc) -> Self {
        let n = k.ncols;
        let column = |j: usize| k.col_ptr[j]..k.col_ptr[j + 1];
        let mut pairs = RowPairs {
            groups: Vec::new(),
            cols: Vec::with_capacity(k.row_idx.len()),
            values: Vec::with_capacity(k.values.len()),
            value_start: Vec::new(),
        };
        let mut j = 0;
        while j < n {
            let pair = j + 1 < n && k.row_idx[column(j)] == k.row_idx[column(j + 1)];
            let start = pairs.cols.len();
            pairs.cols.extend_from_slice(&k.row_idx[column(j)]);
            pairs.value_start.push(pairs.values.len());
            if pair {
                let (a, b) = (&k.values[column(j)], &k.values[column(j + 1)]);
                pairs
                    .values
                    .extend(a.iter().zip(b).flat_map(|(&x, &y)| [x, y]));
            } else {
                pairs.values.extend_from_slice(&k.values[column(j)]);
            }
            pairs.groups.push((j, pair, start..pairs.cols.len()));
            j += if pair { 2 } else { 1 };
        }
        pairs
    }

    fn mul(&self, x: &[f64], y: &mut [f64]) {
        for ((row, pair, range), &v0) in self.groups.iter().zip(&self.value_start) {
            let cols = &self.cols[range.clone()];
            if *pair {
                let values = &self.values[v0..v0 + 2 * cols.len()];
                let (mut s0, mut s1) = (0.0, 0.0);
                for (&c, v) in cols.iter().zip(values.chunks_exact(2)) {
                    let xc = x[c];
                    s0 += v[0] * xc;
                    s1 += v[1] * xc;
                }
                y[*row] = s0;
                y[row + 1] = s1;
            } else {
                let values = &self.values[v0..v0 + cols.len()];
                y[*row] = cols.iter().zip(values).map(|(&c, v)| v * x[c]).sum();
            }
        }
    }
}

/// The largest ω² of M⁻¹K over the massive dofs, by power iteration (an upper bound of the
/// condensed system's, whose Schur complement is softer).
fn estimate_max_eigenvalue(k: &RowPairs, mass: &[f64]) -> f64 {
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
        k.mul(&x, &mut y);
        for i in 0..n {
            y[i] = if mass[i] > 0.0 { y[i] / mass[i] } else { 0.0 };
        }
        let norm = norm2(&y);
        let xn = norm2(&x);
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

struct Condensation<'a> {
    k: &'a Csc,
    /// Per dof: massless.
    is_z: Vec<bool>,
    /// Whether the contact rows act on the massless dofs.
    condensed_contact: bool,
    /// Massless dofs.
    z: Vec<usize>,
    /// K_zz⁻¹ (dense).
    kzz_inv: DMatrix<f64>,
    /// Contact rows restricted to z (dense nc × nz).
    bz: DMatrix<f64>,
    /// W = B_z K_zz⁻¹ B_zᵀ.
    w: DMatrix<f64>,
    /// With friction: B_t on z, the blocks W_nt, W_tn, W_tt of [B_z; B_t] K_zz⁻¹ [B_z; B_t]ᵀ
    /// and μ per row.
    friction: Option<CondensedFriction>,
}

/// The condensed tangential rows (`Condensation::friction`).
struct CondensedFriction {
    bt: DMatrix<f64>,
    w_nt: DMatrix<f64>,
    w_tn: DMatrix<f64>,
    w_tt: DMatrix<f64>,
    mu: Vec<f64>,
}

/// The frictional contact problem of one step by projected Gauss–Seidel over the nodes:
/// find λ_n ≤ 0, λ_t with g = q + W_nn λ_n + W_nt λ_t ≤ 0 complementary to λ_n, and the slip
/// increment s = p + W_tn λ_n + W_tt λ_t zero where |λ_t| < μ|λ_n| (stick), opposite to λ_t
/// where |λ_t| = μ|λ_n| (slip), every W times `scale` (the massless dofs' backward-Euler
/// weight). Each node's update is exact for its own rows with the others held:
/// λ_n ← min(0, λ_n − g/W_nn,ii), then λ_t ← clamp(λ_t − s/W_tt,ii, ±μ|λ_n|).
/// Warm-started from `lambda`.
fn solve_frictional_step(
    w: [&DMatrix<f64>; 4],
    scale: f64,
    (q, p): (&[f64], &[f64]),
    mu: &[f64],
    (lambda_n, lambda_t): (&mut [f64], &mut [f64]),
) -> Result<()> {
    let [w_nn, w_nt, w_tn, w_tt] = w;
    let nc = q.len();
    for _ in 0..MAX_FRICTION_SWEEPS {
        let mut delta = 0.0f64;
        for i in 0..nc {
            let mut g = q[i];
            let mut slip = p[i];
            for j in 0..nc {
                g += scale * (w_nn[(i, j)] * lambda_n[j] + w_nt[(i, j)] * lambda_t[j]);
                slip += scale * (w_tn[(i, j)] * lambda_n[j] + w_tt[(i, j)] * lambda_t[j]);
            }
            let n_new = (lambda_n[i] - g / (scale * w_nn[(i, i)])).min(0.0);
            let slip = slip + scale * w_tn[(i, i)] * (n_new - lambda_n[i]);
            let bound = -mu[i] * n_new;
            let t_new = (lambda_t[i] - slip / (scale * w_tt[(i, i)])).clamp(-bound, bound);
            delta = delta.max((n_new - lambda_n[i]).abs().max((t_new - lambda_t[i]).abs()));
            lambda_n[i] = n_new;
            lambda_t[i] = t_new;
        }
        let scale = lambda_n.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if delta <= 1e-13 * scale.max(f64::MIN_POSITIVE) {
            return Ok(());
        }
    }
    Err(Error::NotConverged(
        "time marching: the frictional contact problem of a step did not converge (projected \
         Gauss–Seidel); reduce transient.courant"
            .into(),
    ))
}

/// Sweeps the frictional step's Gauss–Seidel takes before giving up.
const MAX_FRICTION_SWEEPS: usize = 20_000;

/// Rows as small sparse vectors (dof, value) over the dofs they touch.
type SparseRows = [Vec<(usize, f64)>];

/// The rows of `b` (`count` of them) as small sparse vectors over the dofs they touch.
fn sparse_rows(b: &Csc, count: usize) -> Vec<Vec<(usize, f64)>> {
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); count];
    for j in 0..b.ncols {
        for p in b.col_ptr[j]..b.col_ptr[j + 1] {
            rows[b.row_idx[p]].push((j, b.values[p]));
        }
    }
    rows
}

/// Contact rows as small sparse vectors over the dofs they touch; all on massless dofs
/// (condensed) or all on massive ones (forward-increment multipliers).
fn contact_rows(problem: &TransientProblem, is_z: &[bool]) -> Result<Vec<Vec<(usize, f64)>>> {
    let Some(c) = &problem.contact else {
        return Ok(Vec::new());
    };
    let rows = sparse_rows(c.b, c.g0.len());
    let on_z = rows.iter().flatten().filter(|(d, _)| is_z[*d]).count();
    let total = rows.iter().map(Vec::len).sum::<usize>();
    if on_z != 0 && on_z != total {
        return Err(Error::Model("time marching: contact rows touch both massless and massive dofs; use one mass model for all contact nodes".into()));
    }
    Ok(rows)
}

impl<'a> Condensation<'a> {
    /// K_zz⁻¹, B_z and W for the massless dofs (none: `None`); `condensed_contact`: the
    /// contact rows act on the massless dofs.
    fn new(
        k: &'a Csc,
        is_z: &[bool],
        rows: &SparseRows,
        condensed_contact: bool,
        friction: Option<(&SparseRows, &[f64])>,
    ) -> Result<Option<Self>> {
        let z: Vec<usize> = (0..is_z.len()).filter(|&i| is_z[i]).collect();
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
        // Rows restricted to z, dense.
        let on_z = |rows: &SparseRows| {
            let mut b = DMatrix::zeros(rows.len(), z.len());
            for (i, row) in rows.iter().enumerate() {
                for &(d, v) in row {
                    if let Some(&a) = pos.get(&d) {
                        b[(i, a)] = v;
                    }
                }
            }
            b
        };
        let bz = on_z(rows);
        let w = &bz * &kzz_inv * bz.transpose();
        let friction = friction.map(|(bt_rows, mu)| {
            let bt = on_z(bt_rows);
            let kbt = &kzz_inv * bt.transpose();
            CondensedFriction {
                w_nt: &bz * &kbt,
                w_tn: &bt * &kzz_inv * bz.transpose(),
                w_tt: &bt * &kbt,
                bt,
                mu: mu.to_vec(),
            }
        });
        Ok(Some(Condensation {
            k,
            is_z: is_z.to_vec(),
            condensed_contact,
            z,
            kzz_inv,
            bz,
            w,
            friction,
        }))
    }

    /// Condense the massless dofs. Their rows carry no inertia but do carry stiffness-
    /// proportional damping: K_z·(u + βu̇) = f_z + B_zᵀλ is static in w = u + βu̇, and u_z
    /// follows from w_z by backward Euler, u_z' = s w_z + (1 − s) u_z with s = 1/(1 + β/Δt).
    /// `w` holds u + βu̇ on the massive dofs; `uz_old` the massless dofs' last values; the
    /// result goes to `out`'s massless dofs, and the contact multipliers (against the gaps
    /// `contact.g0`) to `contact`.
    fn condense(
        &self,
        w: &[f64],
        out: &mut [f64],
        uz_old: &[f64],
        s_weight: f64,
        f: &[f64],
        contact: &mut ContactState,
    ) -> Result<()> {
        let (k, nz) = (self.k, self.z.len());
        let mut rhs = DVector::zeros(nz);
        for (a, &j) in self.z.iter().enumerate() {
            let mut sum = f[j];
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                let r = k.row_idx[p];
                if !self.is_z[r] {
                    sum -= k.values[p] * w[r];
                }
            }
            rhs[a] = sum;
        }
        let mut wz = &self.kzz_inv * &rhs;
        let old = DVector::from_iterator(nz, self.z.iter().map(|&j| uz_old[j]));
        if self.condensed_contact {
            let g0 = &contact.g0;
            let predicted = (&wz * s_weight) + (&old * (1.0 - s_weight));
            let gap = &self.bz * &predicted;
            let q: Vec<f64> = (0..g0.len()).map(|i| gap[i] - g0[i]).collect();
            if let Some(fr) = &self.friction {
                let slip = &fr.bt * (&predicted - &old);
                let w = [&self.w, &fr.w_nt, &fr.w_tn, &fr.w_tt];
                let lambdas = (&mut contact.lambda[..], &mut contact.lambda_t[..]);
                solve_frictional_step(w, s_weight, (&q, slip.as_slice()), &fr.mu, lambdas)?;
            } else {
                let p = solve_lcp(&(&self.w * s_weight), &q, &mut contact.active)?;
                for (l, pi) in contact.lambda.iter_mut().zip(&p) {
                    *l = -pi;
                }
            }
            let mut force = self.bz.transpose() * DVector::from_column_slice(&contact.lambda);
            if let Some(fr) = &self.friction {
                force += fr.bt.transpose() * DVector::from_column_slice(&contact.lambda_t);
            }
            wz += &self.kzz_inv * force;
        }
        let uz = (&wz * s_weight) + (&old * (1.0 - s_weight));
        if let Some(fr) = &self.friction {
            let increment = &fr.bt * (&uz - &old);
            contact.book_friction(increment.as_slice(), &fr.mu);
        }
        for (a, &j) in self.z.iter().enumerate() {
            out[j] = uz[a];
        }
        Ok(())
    }
}

/// The contact multipliers of the current step and the LCP's active set (warm start).
struct ContactState {
    lambda: Vec<f64>,
    active: Vec<bool>,
    /// The gaps g0(t) of the step being solved.
    g0: Vec<f64>,
    /// With friction: the tangential multipliers, the last step's slip increments Δw, and
    /// what the period so far dissipated.
    lambda_t: Vec<f64>,
    slip: Vec<f64>,
    period: MarchedFriction,
}

/// What friction did over one marched period: energy −Σ λ_t Δw, the peak of |Σ λ_t|, and
/// the (row, step) pairs open, stuck and slipping.
#[derive(Clone, Debug, Default)]
pub struct MarchedFriction {
    /// The energy per contact row [J].
    pub node_energy: Vec<f64>,
    pub peak_force: f64,
    pub counts: [usize; 3],
}

impl MarchedFriction {
    /// The energy all rows dissipated [J].
    pub fn energy(&self) -> f64 {
        self.node_energy.iter().sum()
    }
}

impl ContactState {
    /// Book one step's tangential increments `increment` (stick where below the round-off of
    /// the step's largest one, and |λ_t| < μ|λ_n|).
    fn book_friction(&mut self, increment: &[f64], mu: &[f64]) {
        let p = &mut self.period;
        let largest = increment.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        self.slip.clear();
        self.slip.extend_from_slice(increment);
        p.node_energy.resize(increment.len(), 0.0);
        for (i, (&lt, &dw)) in self.lambda_t.iter().zip(increment).enumerate() {
            p.node_energy[i] -= lt * dw;
            let bound = -mu[i] * self.lambda[i];
            let state = if self.lambda[i] >= 0.0 {
                0
            } else if lt.abs() < bound * (1.0 - 1e-9) || dw.abs() <= 1e-12 * largest {
                1
            } else {
                2
            };
            p.counts[state] += 1;
        }
        p.peak_force = p.peak_force.max(self.lambda_t.iter().sum::<f64>().abs());
    }
}

/// What the last period records: states at the output samples, probes and total force at
/// every step.
struct LastPeriod {
    per_sample: usize,
    displacement: Vec<Vec<f64>>,
    velocity: Vec<Vec<f64>>,
    acceleration: Vec<Vec<f64>>,
    contact_force: Vec<Vec<f64>>,
    /// With friction, λ_t and the slip velocity Δw/Δt at the output samples (booked as λ).
    tangential_force: Vec<Vec<f64>>,
    slip_velocity: Vec<Vec<f64>>,
    probe_history: Vec<Vec<f64>>,
    total_contact_history: Vec<f64>,
}

impl LastPeriod {
    fn new(samples: usize, steps: usize, per_sample: usize, nc: usize, probes: usize) -> Self {
        LastPeriod {
            per_sample,
            displacement: vec![Vec::new(); samples],
            velocity: vec![Vec::new(); samples],
            acceleration: vec![Vec::new(); samples],
            contact_force: vec![vec![0.0; nc]; samples],
            tangential_force: vec![Vec::new(); samples],
            slip_velocity: vec![Vec::new(); samples],
            probe_history: vec![vec![0.0; steps]; probes],
            total_contact_history: vec![0.0; steps],
        }
    }

    /// Record step `step` (u at it, centred differences around it); λ belongs to the end of
    /// the step (it enforced u_next), so it is booked at step + 1.
    fn record(
        &mut self,
        step: usize,
        dt: f64,
        [u_prev, u, u_next]: [&[f64]; 3],
        (lambda, lambda_t, slip): (&[f64], &[f64], &[f64]),
        probes: &[usize],
    ) {
        if step.is_multiple_of(self.per_sample) {
            let j = step / self.per_sample;
            self.displacement[j] = u.to_vec();
            self.velocity[j] = (0..u.len())
                .map(|i| (u_next[i] - u_prev[i]) / (2.0 * dt))
                .collect();
            self.acceleration[j] = (0..u.len())
                .map(|i| (u_next[i] - 2.0 * u[i] + u_prev[i]) / (dt * dt))
                .collect();
        }
        for (history, &d) in self.probe_history.iter_mut().zip(probes) {
            history[step] = u[d];
        }
        let steps = self.total_contact_history.len();
        let next = (step + 1) % steps;
        self.total_contact_history[next] = lambda.iter().sum();
        if next.is_multiple_of(self.per_sample) {
            self.contact_force[next / self.per_sample] = lambda.to_vec();
            self.tangential_force[next / self.per_sample] = lambda_t.to_vec();
            self.slip_velocity[next / self.per_sample] = slip.iter().map(|w| w / dt).collect();
        }
    }
}

/// Δt stable for central differences (with stiffness damping), fitted to the period and the
/// samples: (Δt, steps per period, steps per sample); a march beyond the machine's limits
/// (`budget`) is refused here, before anything sized by its steps is allocated.
fn time_step(
    problem: &TransientProblem,
    product: &RowPairs,
    settings: &TransientSettings,
) -> Result<(f64, usize, usize)> {
    let estimate = estimate_with(problem, product, settings)?;
    let (steps, per_sample) = estimate.admit(&budget::Limits::of_machine())?;
    Ok((problem.period / steps as f64, steps, per_sample))
}

/// The cost of marching `problem` with `settings` (`budget`), without marching: what
/// `check` and `run` ask before they solve.
pub fn estimate(
    problem: &TransientProblem,
    settings: &TransientSettings,
) -> Result<budget::Estimate> {
    estimate_with(problem, &RowPairs::new(problem.stiffness), settings)
}

fn estimate_with(
    problem: &TransientProblem,
    product: &RowPairs,
    settings: &TransientSettings,
) -> Result<budget::Estimate> {
    let omega_max = estimate_max_eigenvalue(product, problem.mass).sqrt() * 1.05;
    if !(omega_max > 0.0 && omega_max.is_finite()) {
        return Err(Error::Model(
            "time marching: no massive dof or no stiffness".into(),
        ));
    }
    let beta = problem.rayleigh.map_or(0.0, |(_, b)| b);
    let sizes = budget::Sizes {
        free: problem.mass.len(),
        contact_rows: problem.contact.as_ref().map_or(0, |c| c.g0.len()),
        massless: problem.mass.iter().filter(|&&m| m <= 0.0).count(),
        probes: problem.probes.len(),
        stiffness_entries: problem.stiffness.values.len(),
    };
    Ok(budget::Estimate::new(
        omega_max,
        beta,
        problem.period,
        settings,
        sizes,
    ))
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

fn norm(x: &[f64]) -> f64 {
    norm2(x).max(f64::MIN_POSITIVE)
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// ‖state − previous‖ / ‖state‖ between the states at two successive period starts.
fn relative_change(state: &[f64], previous: &[f64]) -> f64 {
    distance(state, previous) / norm(state)
}

/// The periodicity of a march, period by period: the state x = (u, T u̇) at each period
/// start against the last one (`changes`), and the displacements against the start's
/// (`departures`).
struct Periodicity {
    period: f64,
    /// The displacements at the start.
    start: Vec<f64>,
    /// (‖u‖² + ‖u̇/ω‖²)^½ of the start: the displacement amplitude of a harmonic motion,
    /// whatever its phase.
    start_amplitude: f64,
    last_state: Vec<f64>,
    changes: Vec<f64>,
    departures: Vec<f64>,
}

impl Periodicity {
    fn new(period: f64, u: &[f64], v: &[f64]) -> Self {
        let last_state = state_of(period, u, v);
        let n = u.len();
        let start_amplitude = (norm(&last_state[..n]).powi(2)
            + (norm(&last_state[n..]) / (2.0 * std::f64::consts::PI)).powi(2))
        .sqrt();
        Periodicity {
            period,
            start: u.to_vec(),
            last_state,
            start_amplitude,
            changes: Vec::new(),
            departures: Vec::new(),
        }
    }

    /// Record the state at the end of a period; returns its change from the last.
    fn observe(&mut self, u: &[f64], v: &[f64]) -> f64 {
        let state = state_of(self.period, u, v);
        let change = relative_change(&state, &self.last_state);
        self.changes.push(change);
        self.departures
            .push(distance(u, &self.start) / self.start_amplitude);
        self.last_state = state;
        change
    }
}

/// The state x = (u, T v) a march's periodicity is measured on.
fn state_of(period: f64, u: &[f64], v: &[f64]) -> Vec<f64> {
    u.iter()
        .copied()
        .chain(v.iter().map(|v| v * period))
        .collect()
}

/// Marches under way that keep their work on an interruption (`StopOnInterrupt`).
static ARMED: AtomicUsize = AtomicUsize::new(0);
/// An interruption asked them to stop.
static STOP: AtomicBool = AtomicBool::new(false);

thread_local! {
    /// This thread's march is one of them (a march runs on the thread that calls
    /// `run_to_periodic`; marches on other threads, such as a study's, go on).
    static ARMED_HERE: Cell<bool> = const { Cell::new(false) };
}

/// Ask the march under way to stop at its next step and keep what it marched (the command
/// line's Ctrl-C or SIGTERM during `hbcontact transient`). Returns false when no such march
/// runs (`StopOnInterrupt`), or one was already asked: the caller then ends the process itself.
pub fn request_stop() -> bool {
    ARMED.load(Ordering::SeqCst) > 0 && !STOP.swap(true, Ordering::SeqCst)
}

/// While it lives, `request_stop` stops the marches this thread runs at their next step
/// instead of letting the caller end the process, and `run_to_periodic` returns the whole
/// periods marched so far (`TransientResult::interrupted`). Only `hbcontact transient` arms
/// it: a study's or a stability check's march is not a result of its own to keep.
pub struct StopOnInterrupt(());

impl StopOnInterrupt {
    pub fn arm() -> Self {
        STOP.store(false, Ordering::SeqCst);
        ARMED.fetch_add(1, Ordering::SeqCst);
        ARMED_HERE.with(|a| a.set(true));
        StopOnInterrupt(())
    }
}

impl Drop for StopOnInterrupt {
    fn drop(&mut self) {
        ARMED_HERE.with(|a| a.set(false));
        ARMED.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Steps between two reports within a period (a period can take 10⁵ steps and minutes; a
/// report costs about a microsecond, a step at least that).
const STEPS_PER_REPORT: usize = 1024;

/// March `problem` period by period until the state at a period start changes by less than
/// `settings.periodic_tolerance` from the last (not after the first period from rest), its
/// `decided` rule stops it, `settings.max_periods` are marched, or an interruption stops it
/// (`StopOnInterrupt`: checked before every step; the whole periods so far are returned,
/// `Error::Interrupted` when there is none); the last period sampled.
pub fn run_to_periodic(
    problem: &TransientProblem,
    settings: &TransientSettings,
    reporter: &dyn Reporter,
) -> Result<TransientResult> {
    let start = Instant::now();
    let (stepper, steps, per_sample) = Stepper::new(problem, settings)?;
    let dt = stepper.dt;
    let mut s = stepper.start(problem)?;
    let samples = settings.samples_per_period.max(1);
    let nc = s.contact.lambda.len();
    let mut record = LastPeriod::new(samples, steps, per_sample, nc, problem.probes.len());
    let mut late = late::LateRecord::new(problem.probes.len(), steps, problem.period);
    let mut watch = Periodicity::new(problem.period, &s.u, &s.v_half);
    let (mut periods, mut converged, mut change) = (0, false, f64::INFINITY);
    // The state at the end of the last whole period (an interruption may come within one).
    let mut end_state = InitialState {
        displacement: s.u.clone(),
        velocity: s.v_half.clone(),
    };
    let mut interrupted = None;
    let mut friction = MarchedFriction::default();
    let stop_requested = stop_requested();
    while periods < settings.max_periods {
        let records = (&mut record, &mut late);
        interrupted = stepper.march_period(
            &mut s,
            problem,
            (periods, steps),
            records,
            (&stop_requested, reporter, settings.max_periods),
        )?;
        if interrupted.is_some() {
            break;
        }
        periods += 1;
        friction.clone_from(&s.contact.period);
        late.end_period();
        check_finite(&s.u, periods, dt, settings)?;
        end_state.displacement.copy_from_slice(&s.u);
        end_state.velocity.copy_from_slice(&s.v_half);
        change = watch.observe(&s.u, &s.v_half);
        let (done, of) = (periods as u64, Some(settings.max_periods as u64));
        reporter.progress("periods", done, of, &format!("change {change:.2e}"));
        // The first period from rest compares with a zero state: not a verdict.
        let from_rest = periods == 1 && problem.initial.is_none();
        if change < settings.periodic_tolerance && !from_rest {
            converged = true;
            break;
        }
        if (problem.decided).is_some_and(|decided| decided(&watch.changes, &watch.departures)) {
            break;
        }
    }
    nothing_to_keep(interrupted, periods, steps)?;
    Ok(TransientResult {
        dt,
        steps_per_period: steps,
        periods,
        interrupted,
        converged,
        periodicity_error: change,
        changes: watch.changes,
        departures: watch.departures,
        end_state,
        times: sample_times(samples, problem.period),
        displacement: record.displacement,
        velocity: record.velocity,
        acceleration: record.acceleration,
        contact_force: record.contact_force,
        tangential_force: record.tangential_force,
        slip_velocity: record.slip_velocity,
        probe_history: record.probe_history,
        total_contact_history: record.total_contact_history,
        friction: problem.contact.and_then(|c| c.friction).map(|_| friction),
        late,
        wall_time: start.elapsed(),
    })
}

/// An interruption within the first period leaves no whole period to keep: an error.
fn nothing_to_keep(interrupted: Option<usize>, periods: usize, steps: usize) -> Result<()> {
    match (interrupted, periods) {
        (Some(step), 0) => Err(Error::Interrupted(format!(
            "interrupted in the first period of the march (step {step} of {steps}): no whole \
             period marched to keep"
        ))),
        _ => Ok(()),
    }
}

/// Whether an interruption asks the march to stop (`StopOnInterrupt`; never where it is not
/// armed). One load per step (no measurable cost): within a step of the request.
fn stop_requested() -> impl Fn() -> bool {
    let armed = ARMED_HERE.with(Cell::get);
    move || armed && STOP.load(Ordering::Relaxed)
}

/// A march whose displacements are no longer finite (in period `periods`, at step `dt`) blew
/// up: an explicit step above its stability limit.
fn check_finite(u: &[f64], periods: usize, dt: f64, settings: &TransientSettings) -> Result<()> {
    if u.iter().any(|v| !v.is_finite()) {
        return Err(Error::NotConverged(format!(
            "time marching blew up in period {periods} (dt = {dt:e} s): lower transient.courant (now {})",
            settings.courant
        )));
    }
    Ok(())
}

/// The `samples` phases t_i = i T / samples of a period T.
fn sample_times(samples: usize, period: f64) -> Vec<f64> {
    (0..samples)
        .map(|i| i as f64 * period / samples as f64)
        .collect()
}

/// What a march keeps fixed: the product with K, the step's coefficients and the contact
/// treatment (the condensation of the massless dofs, or W of the massive contact dofs).
struct Stepper<'a> {
    force: &'a (dyn Fn(f64, &mut [f64]) + Sync),
    mass: &'a [f64],
    product: RowPairs,
    is_z: Vec<bool>,
    rows: Vec<Vec<(usize, f64)>>,
    gaps: Option<ContactRows<'a>>,
    condensation: Option<Condensation<'a>>,
    lumped_w: Option<DMatrix<f64>>,
    /// The update of a massive dof is v = keep·v_half + push_i·r with push_i =
    /// Δt / (m_i (1 + αΔt/2)); massless dofs get push 0 and a value the condensation then
    /// overwrites, so that the update runs over contiguous slices.
    push: Vec<f64>,
    /// Ω Δt and the massive nodes' (x, y) free-dof pairs, with a Coriolis force.
    coriolis: Option<(f64, Vec<(usize, usize)>)>,
    keep: f64,
    dt: f64,
    beta: f64,
    damp: f64,
    /// The massless dofs' backward-Euler weight 1/(1 + β/Δt).
    s_weight: f64,
}

/// The march's state and buffers (no allocation in the time loop): u at the previous,
/// current and next step (rotated after each), v at the half step, f at the step's start
/// (`f_ready`: the condensation's f(t + Δt) of the step before), K u, K v, the massive
/// dofs' u + βu̇, and the contact multipliers.
struct MarchState {
    u_prev: Vec<f64>,
    u: Vec<f64>,
    u_next: Vec<f64>,
    v_half: Vec<f64>,
    f: Vec<f64>,
    f_next: Vec<f64>,
    f_ready: bool,
    ku: Vec<f64>,
    kv: Vec<f64>,
    w_massive: Vec<f64>,
    contact: ContactState,
}

impl MarchState {
    /// (prev, current, next) ← (current, next, old prev).
    fn rotate(&mut self) {
        std::mem::swap(&mut self.u_prev, &mut self.u);
        std::mem::swap(&mut self.u, &mut self.u_next);
    }
}

impl<'a> Stepper<'a> {
    /// Period `period` (of `steps` steps) from `s`, each step recorded in the last period's
    /// samples and the late record: `Some(step)` when `stop_requested` stops it before that
    /// step (the period unfinished).
    fn march_period(
        &self,
        s: &mut MarchState,
        problem: &TransientProblem,
        (period, steps): (usize, usize),
        (record, late): (&mut LastPeriod, &mut late::LateRecord),
        (stop_requested, reporter, max_periods): (&dyn Fn() -> bool, &dyn Reporter, usize),
    ) -> Result<Option<usize>> {
        s.contact.period = MarchedFriction::default();
        for step in 0..steps {
            if stop_requested() {
                return Ok(Some(step));
            }
            self.step(s, period * steps + step)?;
            if (step + 1) % STEPS_PER_REPORT == 0 {
                let (done, of) = (period as u64, Some(max_periods as u64));
                let status = format!("period {}: step {}/{steps}", period + 1, step + 1);
                reporter.progress("periods", done, of, &status);
            }
            let us = [&s.u_prev[..], &s.u, &s.u_next];
            let c = &s.contact;
            let forces = (&c.lambda[..], &c.lambda_t[..], &c.slip[..]);
            record.record(step, self.dt, us, forces, &problem.probes);
            let probe_values = problem.probes.iter().map(|&d| s.u[d]);
            late.record(step, probe_values, &s.contact.lambda);
            s.rotate();
        }
        Ok(None)
    }

    /// The stepper, the steps per period and the steps per output sample.
    fn new(
        problem: &TransientProblem<'a>,
        settings: &TransientSettings,
    ) -> Result<(Self, usize, usize)> {
        let (k, mass) = (problem.stiffness, problem.mass);
        let n = mass.len();
        let (alpha, beta) = problem.rayleigh.unwrap_or((0.0, 0.0));
        let product = RowPairs::new(k);
        let (dt, steps, per_sample) = time_step(problem, &product, settings)?;
        let is_z: Vec<bool> = (0..n).map(|i| mass[i] <= 0.0).collect();
        let nc = problem.contact.as_ref().map_or(0, |c| c.g0.len());
        let rows = contact_rows(problem, &is_z)?;
        let condensed_contact = nc > 0 && rows.iter().flatten().all(|(d, _)| is_z[*d]);
        let gaps = problem.contact;
        let friction_rows = match problem.contact.and_then(|c| c.friction) {
            Some(_) if !condensed_contact => {
                return Err(Error::Model(
                    "time marching with friction needs massless contact nodes; remove \
                     contact.mass: lumped (the default redistributes their mass)"
                        .into(),
                ))
            }
            Some((bt, mu)) => Some((sparse_rows(bt, nc), mu)),
            None => None,
        };
        let friction = friction_rows.as_ref().map(|(r, mu)| (&r[..], *mu));
        let condensation = Condensation::new(k, &is_z, &rows, condensed_contact, friction)?;
        let lumped_w = (nc > 0 && !condensed_contact).then(|| lumped_w(&rows, mass, dt, alpha));
        if lumped_w.is_some() && problem.coriolis.is_some() {
            return Err(Error::Model(
                "time marching with the Coriolis force needs massless contact nodes; remove \
                 contact.mass: lumped (the default redistributes their mass)"
                    .into(),
            ));
        }
        let coriolis = problem.coriolis.as_ref().map(|c| {
            let massive = |&&(x, y): &&(usize, usize)| mass[x] > 0.0 && mass[y] > 0.0;
            (
                c.speed * dt,
                c.pairs.iter().filter(massive).copied().collect(),
            )
        });
        let damp = alpha * dt / 2.0;
        let push = (0..n)
            .map(|i| {
                if is_z[i] {
                    0.0
                } else {
                    dt / (mass[i] * (1.0 + damp))
                }
            })
            .collect();
        let stepper = Stepper {
            force: problem.force,
            mass,
            product,
            is_z,
            rows,
            gaps,
            condensation,
            lumped_w,
            push,
            coriolis,
            keep: (1.0 - damp) / (1.0 + damp),
            dt,
            beta,
            damp,
            s_weight: 1.0 / (1.0 + beta / dt),
        };
        Ok((stepper, steps, per_sample))
    }

    /// The state at t = 0: rest or the problem's initial state, the massless dofs condensed.
    fn start(&self, problem: &TransientProblem) -> Result<MarchState> {
        let n = self.mass.len();
        let nc = self.rows.len();
        let zeros = || vec![0.0; n];
        let mut s = MarchState {
            u_prev: zeros(),
            u: zeros(),
            u_next: zeros(),
            v_half: zeros(),
            f: zeros(),
            f_next: zeros(),
            f_ready: false,
            ku: zeros(),
            kv: zeros(),
            w_massive: zeros(),
            contact: ContactState {
                lambda: vec![0.0; nc],
                active: vec![false; nc],
                g0: vec![0.0; nc],
                lambda_t: vec![0.0; nc],
                slip: vec![0.0; nc],
                period: MarchedFriction::default(),
            },
        };
        self.gaps_at(0.0, &mut s.contact.g0);
        if let Some(init) = &problem.initial {
            if init.displacement.len() != n || init.velocity.len() != n {
                return Err(Error::Model(
                    "internal: the initial state has the wrong size".into(),
                ));
            }
            s.u.copy_from_slice(&init.displacement);
            s.v_half.copy_from_slice(&init.velocity);
        }
        (self.force)(0.0, &mut s.f);
        if let Some(c) = &self.condensation {
            // The static state of the massless dofs under the massive ones (s = 1); at rest
            // w = 0.
            let w: Vec<f64> = (0..n)
                .map(|i| {
                    if self.is_z[i] {
                        0.0
                    } else {
                        s.u[i] + self.beta * s.v_half[i]
                    }
                })
                .collect();
            let start = s.u.clone();
            c.condense(&w, &mut s.u, &start, 1.0, &s.f, &mut s.contact)?;
        }
        for i in 0..n {
            s.u_prev[i] = s.u[i] - self.dt * s.v_half[i];
        }
        Ok(s)
    }

    /// Step `index` (t = index · Δt): u_next, the contact multipliers and v_half.
    fn step(&self, s: &mut MarchState, index: usize) -> Result<()> {
        let (dt, beta, inv_dt) = (self.dt, self.beta, 1.0 / self.dt);
        if !s.f_ready {
            (self.force)(index as f64 * dt, &mut s.f);
        }
        self.product.mul(&s.u, &mut s.ku);
        if beta != 0.0 {
            self.product.mul(&s.v_half, &mut s.kv);
        }
        let lanes = s.u_next.iter_mut().zip(&s.u).zip(&s.v_half).zip(&self.push);
        let loads = s.f.iter().zip(s.ku.iter().zip(&s.kv));
        for ((((un, &u), &v), &push), (&f, (&ku, &kv))) in lanes.zip(loads) {
            *un = u + dt * (self.keep * v + push * (f - ku - beta * kv));
        }
        self.coriolis(s);
        self.gaps_at((index + 1) as f64 * dt, &mut s.contact.g0);
        if let Some(w) = &self.lumped_w {
            self.forward_increment(w, s)?;
        }
        if let Some(c) = &self.condensation {
            (self.force)((index + 1) as f64 * dt, &mut s.f_next);
            let rate = beta * inv_dt;
            let lanes = s.w_massive.iter_mut().zip(&self.is_z);
            for ((w, &z), (&un, &u)) in lanes.zip(s.u_next.iter().zip(&s.u)) {
                *w = if z { 0.0 } else { un + rate * (un - u) };
            }
            c.condense(
                &s.w_massive,
                &mut s.u_next,
                &s.u,
                self.s_weight,
                &s.f_next,
                &mut s.contact,
            )?;
            std::mem::swap(&mut s.f, &mut s.f_next);
            s.f_ready = true;
        }
        for ((v, &un), &u) in s.v_half.iter_mut().zip(&s.u_next).zip(&s.u) {
            *v = (un - u) * inv_dt;
        }
        Ok(())
    }

    /// The Coriolis force on the step just predicted, by the trapezoidal rule per node: with
    /// a = 1 + αΔt/2, c = ΩΔt and v₀ the velocity the step took without it,
    /// (a I + c J) v⁺ = a v₀ − c J v⁻, J(x, y) = (−y, x), solved as
    /// v⁺ = (a I − c J)(a v₀ − c J v⁻)/(a² + c²).
    fn coriolis(&self, s: &mut MarchState) {
        let Some((c, pairs)) = &self.coriolis else {
            return;
        };
        let (a, dt) = (1.0 + self.damp, self.dt);
        let det = a * a + c * c;
        for &(x, y) in pairs {
            let v0 = [(s.u_next[x] - s.u[x]) / dt, (s.u_next[y] - s.u[y]) / dt];
            let r = [a * v0[0] + c * s.v_half[y], a * v0[1] - c * s.v_half[x]];
            let v = [(a * r[0] + c * r[1]) / det, (a * r[1] - c * r[0]) / det];
            s.u_next[x] = s.u[x] + dt * v[0];
            s.u_next[y] = s.u[y] + dt * v[1];
        }
    }

    /// The contact gaps g0(t) into `out` (fixed gaps are written once, at t = 0).
    fn gaps_at(&self, t: f64, out: &mut [f64]) {
        if let Some(g) = &self.gaps {
            if t == 0.0 || !g.gap_harmonics.is_empty() {
                g.gap_at(t, out);
            }
        }
    }

    /// Forward-increment multipliers on massive contact dofs: remove the predicted
    /// penetration of u_next.
    fn forward_increment(&self, w: &DMatrix<f64>, s: &mut MarchState) -> Result<()> {
        let (rows, g0) = (&self.rows, &s.contact.g0);
        let q: Vec<f64> = (0..rows.len())
            .map(|a| rows[a].iter().map(|&(d, v)| v * s.u_next[d]).sum::<f64>() - g0[a])
            .collect();
        let p = solve_lcp(w, &q, &mut s.contact.active)?;
        let (dt, damp) = (self.dt, self.damp);
        for (a, row) in rows.iter().enumerate() {
            s.contact.lambda[a] = -p[a];
            for &(d, v) in row {
                s.u_next[d] += dt * dt * v * s.contact.lambda[a] / self.mass[d] / (1.0 + damp);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = K x for symmetric K stored by columns (a gather per column, no scatter): the
    /// plain product the marching used before `RowPairs`.
    fn sym_mul(k: &Csc, x: &[f64], y: &mut [f64]) {
        for (j, yj) in y.iter_mut().enumerate() {
            let mut s = 0.0;
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                s += k.values[p] * x[k.row_idx[p]];
            }
            *yj = s;
        }
    }

    /// A march of the unit-mass oscillator of stiffness 4 driven by sin 2πt (period 1 s, 8
    /// samples a period) for at most `periods` periods; an interruption is requested from the
    /// load at the first step at or after `stop_at` seconds.
    fn oscillator(periods: usize, stop_at: Option<f64>) -> Result<TransientResult> {
        let stiffness = Csc::from_entries(1, 1, &[(0, 0, 4.0)]);
        let force = move |t: f64, f: &mut [f64]| {
            f[0] = (2.0 * std::f64::consts::PI * t).sin();
            if stop_at.is_some_and(|s| t >= s) {
                request_stop();
            }
        };
        let problem = TransientProblem {
            stiffness: &stiffness,
            mass: &[1.0],
            rayleigh: Some((0.1, 0.0)),
            force: &force,
            contact: None,
            period: 1.0,
            probes: vec![0],
            initial: None,
            coriolis: None,
            decided: None,
        };
        let settings = TransientSettings {
            courant: 0.5,
            periodic_tolerance: 1e-30,
            max_periods: periods,
            samples_per_period: 8,
        };
        run_to_periodic(&problem, &settings, &crate::Silent)
    }

    /// TEST GOAL: an interruption half-way through the fourth period of an armed march
    /// (`StopOnInterrupt`) returns the three whole periods: their count, periodicity history
    /// and end state bit for bit those of a march of three periods, `interrupted` the steps
    /// into the fourth; the samples and the probe's history are the last period of time
    /// marched, phase by phase: those before the stop from the fourth period (as a march of
    /// four has them), the rest from the third. One within the first period keeps nothing
    /// (`Error::Interrupted`, exit 130); without `arm` the request is refused and the march
    /// runs its course.
    #[test]
    fn an_interrupted_march_keeps_its_whole_periods_and_the_last_period_of_time() {
        let (three, four) = (oscillator(3, None).unwrap(), oscillator(4, None).unwrap());
        let armed = StopOnInterrupt::arm();
        let stopped = oscillator(10, Some(3.5)).unwrap();
        drop(armed);
        let steps = stopped.steps_per_period;
        let k = stopped.interrupted.expect("interrupted");
        assert!(k > steps / 3 && k < steps, "{k} of {steps}");
        assert_eq!((stopped.periods, &stopped.changes), (3, &three.changes));
        assert_eq!(stopped.end_state.displacement, three.end_state.displacement);
        assert_eq!(stopped.end_state.velocity, three.end_state.velocity);
        let per_sample = steps / 8;
        for j in 0..8 {
            let from = if j * per_sample < k { &four } else { &three };
            assert_eq!(stopped.displacement[j], from.displacement[j], "sample {j}");
            assert_eq!(stopped.velocity[j], from.velocity[j], "sample {j}");
        }
        for (step, &u) in stopped.probe_history[0].iter().enumerate() {
            let from = if step < k { &four } else { &three };
            assert_eq!(u, from.probe_history[0][step], "step {step}");
        }
        let armed = StopOnInterrupt::arm();
        let e = oscillator(10, Some(0.5)).err().expect("nothing to keep");
        drop(armed);
        assert_eq!(e.exit_code(), 130);
        assert!(e.to_string().contains("first period"), "{e}");
        let unarmed = oscillator(4, Some(0.5)).unwrap();
        assert_eq!((unarmed.periods, unarmed.interrupted), (4, None));
    }

    /// TEST GOAL: the paired-row product is `sym_mul`, bit for bit (the same sums in the same
    /// order), on a pattern with node pairs and a lone dof (a node with one dof held):
    /// nodes 0-3 in a ring with two dofs each, dof 8 alone and coupled to node 0.
    #[test]
    fn paired_rows_multiply_like_the_column_gather() {
        let node = |d: usize| if d < 8 { d / 2 } else { 4 };
        let linked = |a: usize, b: usize| {
            let (a, b) = (a.min(b), a.max(b));
            a == b || (b < 4 && (b - a == 1 || (a == 0 && b == 3))) || (a == 0 && b == 4)
        };
        let mut entries = Vec::new();
        for i in 0..9 {
            for j in 0..9 {
                if linked(node(i), node(j)) {
                    let (lo, hi) = (i.min(j), i.max(j));
                    entries.push((i, j, 1.0 + ((lo * 13 + hi * 7) % 11) as f64 / 3.0));
                }
            }
        }
        let k = Csc::from_entries(9, 9, &entries);
        let pairs = RowPairs::new(&k);
        let paired = pairs.groups.iter().filter(|g| g.1).count();
        assert_eq!((paired, pairs.groups.len()), (4, 5));
        let x: Vec<f64> = (0..9).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut a, mut b) = (vec![0.0; 9], vec![0.0; 9]);
        sym_mul(&k, &x, &mut a);
        pairs.mul(&x, &mut b);
        assert_eq!(a, b);
    }
}
