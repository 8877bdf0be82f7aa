//! Coulomb friction at the contact nodes (docs/method.md §17): the tangential law on the
//! reduced problem whose rows are the nc normal rows followed by nc tangential rows, row
//! nc + i being t_i = ẑ × n_i at node i, so (B_t u)_i is the node's tangential displacement
//! relative to the obstacle and w = (G λ + r)_t its series.
//!
//! Per node i and sample t_n, with c > 0 the complementarity stiffness and μ_i the
//! coefficient:
//!
//! Λ_n = min(0, λ_n − c g),   Λ_t = proj_[−μ|Λ_n|, μ|Λ_n|](λ_t − c_t ẇ/ω),  c_t = c/H,
//! R = (λ_n − Q Λ_n, λ_t − Q Λ_t),
//!
//! whose root is Signorini's law in the normal and Coulomb's in the tangent: |λ_t| < μ|λ_n|
//! ⇒ ẇ = 0 (stick), else λ_t = −μ|λ_n| sign(ẇ) (slip), and λ_t = 0 where the node is open.
//! ẇ/ω is the derivative of w on the Fourier basis, a rotation of each harmonic:
//! (ẇ/ω)_k = i k w_k, i.e. (a_k, b_k) ↦ (k b_k, −k a_k). A node stuck at every sample leaves
//! its mean tangential force undetermined (ẇ has no mean): its mean row is replaced by
//! `StuckRow`'s, c w_0 = 0 (the node held where the unloaded body has it, the bonded limit
//! μ → ∞) while that state's force stays in the cone, else the force touching the cone on
//! the side it would leave it.
//!
//! The semi-smooth Newton's Jacobian J = I − E + c F G is formed dense: per node the M × M
//! blocks A(s) = Q diag(s) P of the normal slopes s_n (normal rows), of the stick indicator
//! s_t (tangential rows, on λ_t; in F times D, the derivative) and of the slip's dependence
//! s_u = −μ σ s_n on the normal force (tangential rows, on λ_n and g), σ = sign(Λ_t).
//!
//! Glossary: nc contact nodes, M = 2H + 1 coefficients per row, N samples, x = (λ_n, λ_t)
//! node-major within each half.

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::{Accum, Mat, Par};
use std::time::{Duration, Instant};

use crate::linalg::norm2;

use super::fourier::{cos_index, sin_index};
use super::problem::ReducedProblem;
use super::reduced::{IterationLog, NewtonOutcome};
use super::sampler::ContactSampler;

/// Newton iterations a continuation step may take (`solve`).
const STEP_BUDGET: usize = 40;

/// c_t of the attempt that looks for a stuck state, in units of c/H (`solve`).
const STIFF_SCALE: f64 = 10.0;

/// What a frictional Newton says when its deadline passed (`solve`'s time budget,
/// harmonic_balance.solver.max_seconds).
pub const OUT_OF_TIME: &str = "the time budget harmonic_balance.solver.max_seconds ran out";

/// μ's scale in the bonded attempt of `solve`: every closed sample sticks.
const BONDED: f64 = 1e6;

/// Residual norms the non-monotone line search looks back over.
const WINDOW: usize = 8;
/// The shortest step the line search tries before taking it anyway.
const SHORTEST: f64 = 1.0 / 1024.0;
/// Steps taken without sufficient decrease before the Newton gives up.
const MAX_FORCED_STEPS: usize = 10;

/// The law's data beside the reduced problem: μ per node and the stiffness c.
pub struct Law<'a> {
    pub coefficients: &'a [f64],
    pub c: f64,
    /// c_t in units of c/H (1 but in `solve`'s stuck attempt).
    pub tangential_scale: f64,
}

impl Law<'_> {
    /// c_t = c/H, the stiffness of the tangential trial force λ_t − c_t ẇ/ω: ẇ/ω weighs
    /// harmonic k of w by k, so c_t ẇ/ω weighs the highest harmonic as c w does. With c_t = c
    /// the block of tests/friction.rs took 179 iterations at H = 10 and did not converge in
    /// 200 at H = 40, with c/H 10 and 17.
    pub fn tangential_c(&self, harmonics: usize) -> f64 {
        self.tangential_scale * self.c / harmonics.max(1) as f64
    }
}

/// P (N × M), Q (M × N) and D (M × M, the derivative divided by ω) as dense matrices.
struct Maps {
    p: Mat<f64>,
    q: Mat<f64>,
    d: Mat<f64>,
}

impl Maps {
    fn new(sampler: &ContactSampler) -> Maps {
        let (m, n) = (sampler.coefficients(), sampler.samples());
        let mut p = Mat::zeros(n, m);
        let mut unit = vec![0.0; m];
        let mut column = vec![0.0; n];
        for b in 0..m {
            unit[b] = 1.0;
            sampler.to_samples(&unit, &mut column);
            column.iter().enumerate().for_each(|(r, v)| p[(r, b)] = *v);
            unit[b] = 0.0;
        }
        let mut q = Mat::zeros(m, n);
        let mut sample = vec![0.0; n];
        let mut coefficients = vec![0.0; m];
        for s in 0..n {
            sample[s] = 1.0;
            sampler.to_coefficients(&sample, &mut coefficients);
            coefficients
                .iter()
                .enumerate()
                .for_each(|(r, v)| q[(r, s)] = *v);
            sample[s] = 0.0;
        }
        let mut d = Mat::zeros(m, m);
        for k in 1..=sampler.harmonics() {
            let (a, b) = (cos_index(k), sin_index(k));
            d[(a, b)] = k as f64;
            d[(b, a)] = -(k as f64);
        }
        Maps { p, q, d }
    }

    /// P x into `out`.
    fn sample(&self, x: &[f64], out: &mut [f64]) {
        mat_vec(&self.p, x, out);
    }

    /// Q s into `out`.
    fn project(&self, s: &[f64], out: &mut [f64]) {
        mat_vec(&self.q, s, out);
    }

    /// D x (the derivative divided by ω).
    fn derivative(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; x.len()];
        mat_vec(&self.d, x, &mut out);
        out
    }

    /// A(s) = Q diag(s) P.
    fn block(&self, s: &[f64]) -> Mat<f64> {
        let (m, n) = (self.q.nrows(), self.q.ncols());
        let scaled = Mat::from_fn(m, n, |r, j| self.q[(r, j)] * s[j]);
        let mut out = Mat::zeros(m, m);
        matmul(
            out.as_mut(),
            Accum::Replace,
            scaled.as_ref(),
            self.p.as_ref(),
            1.0,
            Par::Seq,
        );
        out
    }
}

/// out = A x for a dense A.
fn mat_vec(a: &Mat<f64>, x: &[f64], out: &mut [f64]) {
    for (r, o) in out.iter_mut().enumerate() {
        *o = x.iter().enumerate().map(|(b, v)| a[(r, b)] * v).sum();
    }
}

/// G in real form (rows·M square), for the Jacobian.
fn real_compliance(problem: &ReducedProblem) -> Mat<f64> {
    let m = problem.coefficients();
    let dim = problem.nodes * m;
    Mat::from_fn(dim, dim, |r, s| {
        problem.real_entry(r / m, r % m, s / m, s % m)
    })
}

/// The residual at one x, with the per-sample slopes its Jacobian needs.
pub struct Evaluation {
    pub x: Vec<f64>,
    pub residual: Vec<f64>,
    /// Per node and sample: the normal slope s_n, the stick indicator s_t and −μσ s_n.
    normal: Vec<f64>,
    stick: Vec<f64>,
    slip: Vec<f64>,
    /// Per node stuck at every sample, which side of its mean row (`StuckRow`) is taken;
    /// `None` where it is not stuck at every sample.
    stuck: Vec<Option<StuckRow>>,
    /// Peak |Λ_n| over nodes and samples.
    pub peak: f64,
}

/// The sampled state of one node: λ_n, g, λ_t and ẇ/ω at the samples.
struct NodeSamples {
    lambda_n: Vec<f64>,
    gap: Vec<f64>,
    lambda_t: Vec<f64>,
    velocity: Vec<f64>,
}

/// What the law makes of one sample: (Λ_n, Λ_t) and the slopes (s_n, s_t, s_u).
pub fn law_at(
    mu: f64,
    c: [f64; 2],
    lambda: [f64; 2],
    gap: f64,
    velocity: f64,
) -> ([f64; 2], [f64; 3]) {
    let trial_n = lambda[0] - c[0] * gap;
    let (force_n, s_n) = if trial_n < 0.0 {
        (trial_n, 1.0)
    } else {
        (0.0, 0.0)
    };
    let bound = -mu * force_n;
    let trial_t = lambda[1] - c[1] * velocity;
    if bound <= 0.0 {
        ([force_n, 0.0], [s_n, 0.0, 0.0])
    } else if trial_t.abs() <= bound {
        ([force_n, trial_t], [s_n, 1.0, 0.0])
    } else {
        let sigma = trial_t.signum();
        ([force_n, sigma * bound], [s_n, 0.0, -mu * sigma * s_n])
    }
}

struct Solver<'a> {
    problem: &'a ReducedProblem,
    law: &'a Law<'a>,
    maps: Maps,
}

impl<'a> Solver<'a> {
    fn new(problem: &'a ReducedProblem, law: &'a Law<'a>, samples: usize) -> Solver<'a> {
        let maps = Maps::new(&problem.sampler(samples));
        Solver { problem, law, maps }
    }

    fn nodes(&self) -> usize {
        self.problem.nodes / 2
    }

    fn node_samples(&self, x: &[f64], g: &[f64], i: usize) -> NodeSamples {
        let (nc, m, n) = (
            self.nodes(),
            self.problem.coefficients(),
            self.maps.p.nrows(),
        );
        let mut out = NodeSamples {
            lambda_n: vec![0.0; n],
            gap: vec![0.0; n],
            lambda_t: vec![0.0; n],
            velocity: vec![0.0; n],
        };
        let (ni, ti) = (i * m..(i + 1) * m, (nc + i) * m..(nc + i + 1) * m);
        self.maps.sample(&x[ni.clone()], &mut out.lambda_n);
        self.maps.sample(&g[ni], &mut out.gap);
        self.maps.sample(&x[ti.clone()], &mut out.lambda_t);
        let v = self.maps.derivative(&g[ti]);
        self.maps.sample(&v, &mut out.velocity);
        out
    }

    fn evaluate(&self, x: Vec<f64>) -> Evaluation {
        let (nc, m, n) = (
            self.nodes(),
            self.problem.coefficients(),
            self.maps.p.nrows(),
        );
        let (c, mu) = (self.law.c, self.law.coefficients);
        let g = self.problem.gap(&x);
        let mut e = Evaluation {
            residual: x.clone(),
            x,
            normal: vec![0.0; nc * n],
            stick: vec![0.0; nc * n],
            slip: vec![0.0; nc * n],
            stuck: vec![None; nc],
            peak: 0.0,
        };
        let (mut force_n, mut force_t) = (vec![0.0; n], vec![0.0; n]);
        let mut projected = vec![0.0; m];
        for (i, &mu) in mu.iter().enumerate().take(nc) {
            let s = self.node_samples(&e.x, &g, i);
            for j in 0..n {
                let lambda = [s.lambda_n[j], s.lambda_t[j]];
                let cs = [c, self.law.tangential_c(self.problem.harmonics)];
                let (force, slopes) = law_at(mu, cs, lambda, s.gap[j], s.velocity[j]);
                (force_n[j], force_t[j]) = (force[0], force[1]);
                e.peak = e.peak.max(force[0].abs());
                e.normal[i * n + j] = slopes[0];
                e.stick[i * n + j] = slopes[1];
                e.slip[i * n + j] = slopes[2];
            }
            self.maps.project(&force_n, &mut projected);
            for (r, p) in e.residual[i * m..(i + 1) * m].iter_mut().zip(&projected) {
                *r -= p;
            }
            let t = (nc + i) * m;
            self.maps.project(&force_t, &mut projected);
            for (r, p) in e.residual[t..t + m].iter_mut().zip(&projected) {
                *r -= p;
            }
            if e.stick[i * n..(i + 1) * n].iter().all(|&s| s == 1.0) {
                let (row, side) = StuckRow::at(c * g[t], mu, &s.lambda_t, &s.lambda_n);
                e.residual[t] = row;
                e.stuck[i] = Some(side);
            }
        }
        e
    }

    /// J = I − E + c F G at `e`'s slopes (module header), G in real form (`real_compliance`).
    fn jacobian(&self, e: &Evaluation, g: &Mat<f64>) -> Mat<f64> {
        let (nc, m, n) = (
            self.nodes(),
            self.problem.coefficients(),
            self.maps.p.nrows(),
        );
        let dim = 2 * nc * m;
        let c = self.law.c;
        let mut j = Mat::<f64>::identity(dim, dim);
        for i in 0..nc {
            let samples = i * n..(i + 1) * n;
            let a_n = self.maps.block(&e.normal[samples.clone()]);
            let a_t = self.maps.block(&e.stick[samples.clone()]);
            let a_u = self.maps.block(&e.slip[samples]);
            let mut a_td = Mat::zeros(m, m);
            matmul(
                a_td.as_mut(),
                Accum::Replace,
                a_t.as_ref(),
                self.maps.d.as_ref(),
                self.law.tangential_c(self.problem.harmonics) / c,
                Par::Seq,
            );
            let (ni, ti) = (i * m, (nc + i) * m);
            let blocks = [
                (ni, ni, &a_n, &a_n),
                (ti, ti, &a_t, &a_td),
                (ti, ni, &a_u, &a_u),
            ];
            for (row, col, e_block, f_block) in blocks {
                let mut target = j.as_mut().submatrix_mut(row, col, m, m);
                for r in 0..m {
                    for s in 0..m {
                        target[(r, s)] -= e_block[(r, s)];
                    }
                }
                matmul(
                    j.as_mut().submatrix_mut(row, 0, m, dim),
                    Accum::Add,
                    f_block.as_ref(),
                    g.as_ref().submatrix(col, 0, m, dim),
                    c,
                    Par::Seq,
                );
            }
            match e.stuck[i] {
                Some(StuckRow::Held) => {
                    for s in 0..dim {
                        j[(ti, s)] = c * g[(ti, s)];
                    }
                }
                Some(StuckRow::Touching {
                    sample,
                    upper,
                    closed,
                }) => {
                    // ∂(±λ_t,j − b_j)/∂x, b_j = μ max(0, −λ_n,j), signed so that the row is
                    // λ_t,j − b_j (upper) or λ_t,j + b_j (lower).
                    let mu = if closed {
                        self.law.coefficients[i]
                    } else {
                        0.0
                    };
                    let along_n = if upper { mu } else { -mu };
                    for col in 0..dim {
                        j[(ti, col)] = 0.0;
                    }
                    for b in 0..m {
                        let p = self.maps.p[(sample, b)];
                        j[(ti, ti + b)] = p;
                        j[(ti, ni + b)] = along_n * p;
                    }
                }
                None => {}
            }
        }
        j
    }

    /// R_ω = c F ∂g/∂ω at `e`'s slopes: the derivative of R in ω at fixed x, F the same
    /// blocks as in `jacobian` (`dg` the gaps' rate, node-major as g).
    fn rate(&self, e: &Evaluation, dg: &[f64]) -> Vec<f64> {
        let (nc, m, n) = (
            self.nodes(),
            self.problem.coefficients(),
            self.maps.p.nrows(),
        );
        let c = self.law.c;
        let ct = self.law.tangential_c(self.problem.harmonics);
        let mut out = vec![0.0; dg.len()];
        let mut product = vec![0.0; m];
        for i in 0..nc {
            let samples = i * n..(i + 1) * n;
            let (ni, ti) = (i * m..(i + 1) * m, (nc + i) * m..(nc + i + 1) * m);
            let a_n = self.maps.block(&e.normal[samples.clone()]);
            mat_vec(&a_n, &dg[ni.clone()], &mut product);
            (out[ni.clone()].iter_mut().zip(&product)).for_each(|(o, p)| *o = c * p);
            let a_t = self.maps.block(&e.stick[samples.clone()]);
            mat_vec(&a_t, &self.maps.derivative(&dg[ti.clone()]), &mut product);
            (out[ti.clone()].iter_mut().zip(&product)).for_each(|(o, p)| *o = ct * p);
            let a_u = self.maps.block(&e.slip[samples]);
            mat_vec(&a_u, &dg[ni], &mut product);
            (out[ti.clone()].iter_mut().zip(&product)).for_each(|(o, p)| *o += c * p);
            match e.stuck[i] {
                Some(StuckRow::Held) => out[ti.start] = c * dg[ti.start],
                Some(StuckRow::Touching { .. }) => out[ti.start] = 0.0,
                None => {}
            }
        }
        out
    }
}

/// The mean row of a node stuck at every sample, whose mean tangential force the law leaves
/// undetermined (ẇ has no mean; a stuck node stays wherever its history left it). The row
/// picks the state a quasi-static rise of the drive from rest reaches: held where the
/// unloaded body has it (c w_0 = 0, the bonded limit μ → ∞) while that state's force stays
/// in the cone; where it would leave the cone on one side, shifted just enough to touch it
/// there (the node slipped that far once, and sticks again). With e₊ = max_j (λ_t,j − b_j)
/// and e₋ = max_j (−λ_t,j − b_j), b_j = μ max(0, −λ_n,j), over the node's samples:
///
/// r = min(max(c w_0, e₊), −e₋),
///
/// zero at w_0 = 0 inside the cone, at e₊ = 0 (w_0 < 0) and at e₋ = 0 (w_0 > 0). A force
/// that grows touches both sides at once where slipping both ways begins, so the stuck
/// states run on continuously into the slipping ones; a state held at w_0 = 0 whose force
/// left the cone on one side would instead be a root of the law with that one sample
/// slipping, at exactly zero excess (a periodic state slips as far forward as back): a root
/// on the law's kink, where the Newton cycles.
#[derive(Clone, Copy, Debug, PartialEq)]
enum StuckRow {
    /// c w_0.
    Held,
    /// λ_t,j − b_j at `sample` (upper side) or λ_t,j + b_j (lower side); `closed`: λ_n,j < 0
    /// there (b_j depends on λ_n).
    Touching {
        sample: usize,
        upper: bool,
        closed: bool,
    },
}

impl StuckRow {
    /// The row r and the side it takes, from `held` = c w_0 and the node's sampled λ_t and
    /// λ_n.
    fn at(held: f64, mu: f64, lambda_t: &[f64], lambda_n: &[f64]) -> (f64, StuckRow) {
        let b = |j: usize| mu * (-lambda_n[j]).max(0.0);
        let (mut plus, mut minus) = ((f64::NEG_INFINITY, 0), (f64::NEG_INFINITY, 0));
        for (j, &l) in lambda_t.iter().enumerate() {
            if l - b(j) > plus.0 {
                plus = (l - b(j), j);
            }
            if -l - b(j) > minus.0 {
                minus = (-l - b(j), j);
            }
        }
        let upper = StuckRow::Touching {
            sample: plus.1,
            upper: true,
            closed: lambda_n[plus.1] < 0.0,
        };
        let lower = StuckRow::Touching {
            sample: minus.1,
            upper: false,
            closed: lambda_n[minus.1] < 0.0,
        };
        let (inner, side) = if held >= plus.0 {
            (held, StuckRow::Held)
        } else {
            (plus.0, upper)
        };
        if inner <= -minus.0 {
            (inner, side)
        } else {
            (-minus.0, lower)
        }
    }
}

/// The residual R at x and its size relative to the force scale (the peak normal force, at
/// least `force_floor`): what `newton` stops on.
pub fn residual(
    problem: &ReducedProblem,
    law: &Law,
    samples: usize,
    x: &[f64],
    force_floor: f64,
) -> (Vec<f64>, f64) {
    let e = Solver::new(problem, law, samples).evaluate(x.to_vec());
    let relative = norm_inf(&e.residual) / e.peak.max(force_floor).max(f64::MIN_POSITIVE);
    (e.residual, relative)
}

/// J = ∂R/∂x and R_ω = ∂R/∂ω at x, the latter from `dg`, the rate ∂g/∂ω at fixed x (the
/// continuation's bordered corrector and tangent: the law holds no ω of its own, ẇ/ω being
/// D w).
pub fn linearization(
    problem: &ReducedProblem,
    law: &Law,
    samples: usize,
    x: &[f64],
    dg: &[f64],
) -> (Mat<f64>, Vec<f64>) {
    let solver = Solver::new(problem, law, samples);
    let e = solver.evaluate(x.to_vec());
    let jac = solver.jacobian(&e, &real_compliance(problem));
    (jac, solver.rate(&e, dg))
}

fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, x| a.max(x.abs()))
}

/// Semi-smooth Newton on the frictional residual from `start` (2 nc M values), at N =
/// `samples`, until ‖R‖∞ ≤ `tolerance` · force scale (the peak normal force, at least
/// `force_floor`), globalized by a non-monotone backtracking line search on ‖R‖₂. No
/// iteration starts after `deadline` (the reason is then `OUT_OF_TIME`).
pub fn newton(
    problem: &ReducedProblem,
    law: &Law,
    samples: usize,
    (tolerance, max_iterations, force_floor): (f64, usize, f64),
    start: Vec<f64>,
    deadline: Option<Instant>,
) -> NewtonOutcome {
    let solver = Solver::new(problem, law, samples);
    let mut e = solver.evaluate(start);
    let relative =
        |e: &Evaluation| norm_inf(&e.residual) / e.peak.max(force_floor).max(f64::MIN_POSITIVE);
    let mut history = vec![norm2(&e.residual)];
    let mut log = Vec::new();
    let mut forced = 0;
    let mut reason = String::new();
    let mut iterations = 0;
    // Formed at the first step: a start within the tolerance (the N-check's) needs none.
    let mut g = None;
    while relative(&e) > tolerance {
        if iterations >= max_iterations {
            reason = format!("{max_iterations} Newton iterations were not enough");
            break;
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            reason = OUT_OF_TIME.into();
            break;
        }
        iterations += 1;
        let g = g.get_or_insert_with(|| real_compliance(problem));
        let jac = solver.jacobian(&e, g);
        let rhs = Mat::from_fn(e.residual.len(), 1, |r, _| -e.residual[r]);
        let d = jac.partial_piv_lu().solve(&rhs);
        if (0..d.nrows()).any(|r| !d[(r, 0)].is_finite()) {
            reason = "the Newton matrix of the frictional law is singular".into();
            break;
        }
        let reference = history
            .iter()
            .rev()
            .take(WINDOW)
            .fold(0.0f64, |a, &b| a.max(b));
        let mut alpha = 1.0;
        let next = loop {
            let x: Vec<f64> = (e.x.iter().enumerate())
                .map(|(r, v)| v + alpha * d[(r, 0)])
                .collect();
            let trial = solver.evaluate(x);
            let norm = norm2(&trial.residual);
            if norm <= (1.0 - 1e-4 * alpha) * reference || alpha <= SHORTEST {
                if norm > (1.0 - 1e-4 * alpha) * reference {
                    forced += 1;
                }
                break trial;
            }
            alpha *= 0.5;
        };
        e = next;
        history.push(norm2(&e.residual));
        log.push(IterationLog {
            residual: relative(&e),
            active_samples: e.normal.iter().filter(|&&s| s > 0.5).count(),
            step: alpha,
        });
        if forced > MAX_FORCED_STEPS {
            reason = format!("{forced} steps without a sufficient decrease of the residual");
            break;
        }
    }
    let converged = relative(&e) <= tolerance;
    NewtonOutcome {
        relative_residual: relative(&e),
        multipliers: e.x,
        converged,
        iterations,
        log,
        reason,
    }
}

/// The sampled tangential state of one node at a solution: λ_t (the law's Λ_t), ẇ/ω and the
/// status per sample (0 open, 1 stick, 2 slip).
pub struct NodeState {
    pub force: Vec<f64>,
    pub velocity: Vec<f64>,
    pub status: Vec<u8>,
}

/// Each node's sampled tangential force, slip velocity (divided by ω) and status at `x`.
pub fn node_states(
    problem: &ReducedProblem,
    law: &Law,
    samples: usize,
    x: &[f64],
) -> Vec<NodeState> {
    let solver = Solver::new(problem, law, samples);
    let g = problem.gap(x);
    (0..solver.nodes())
        .map(|i| {
            let s = solver.node_samples(x, &g, i);
            let mut state = NodeState {
                force: Vec::with_capacity(samples),
                velocity: s.velocity.clone(),
                status: Vec::with_capacity(samples),
            };
            for j in 0..samples {
                let lambda = [s.lambda_n[j], s.lambda_t[j]];
                let cs = [law.c, law.tangential_c(problem.harmonics)];
                let (force, slopes) =
                    law_at(law.coefficients[i], cs, lambda, s.gap[j], s.velocity[j]);
                state.force.push(force[1]);
                state.status.push(match (slopes[0], slopes[1]) {
                    (0.0, _) => 0,
                    (_, 1.0) => 1,
                    _ => 2,
                });
            }
            state
        })
        .collect()
}

/// The continuation in μ of `solve`: from the frictionless state, the coefficient scaled by
/// s = 1/16, doubling after each converged step and halving the step after a failed one,
/// down to steps of 1/256.
fn continuation(
    run: &dyn Fn(f64, usize, Vec<f64>) -> NewtonOutcome,
    samples: usize,
    start: Vec<f64>,
    spent: usize,
) -> NewtonOutcome {
    let (mut x, mut at, mut step, mut total) = (start, 0.0f64, 1.0f64 / 16.0, spent);
    loop {
        let scale = (at + step).min(1.0);
        let mut outcome = run(scale, samples, x.clone());
        total += outcome.iterations;
        outcome.iterations = total;
        match (outcome.converged, scale == 1.0) {
            (true, true) => return outcome,
            (true, false) => {
                x = outcome.multipliers;
                (at, step) = (scale, 2.0 * step);
            }
            (false, _) if step <= 1.0 / 256.0 || outcome.reason == OUT_OF_TIME => {
                outcome.reason = format!(
                    "the continuation in the friction coefficient stopped at {at:.4} μ: {}",
                    outcome.reason
                );
                return outcome;
            }
            (false, _) => step *= 0.5,
        }
    }
}

/// The bonded start from `start` = (λ_n, ·): λ_t such that every node's tangential gap w
/// vanishes at every harmonic, G_tt λ_t = −(r_t + G_tn λ_n) (the μ → ∞ limit's tangential
/// force under the normal force λ_n). `None` where G_tt is singular.
fn bonded_start(problem: &ReducedProblem, start: &[f64]) -> Option<Vec<f64>> {
    let half = start.len() / 2;
    let mut x = start.to_vec();
    x[half..].fill(0.0);
    let gap = problem.gap(&x);
    let m = problem.coefficients();
    let entry = |r: usize, s: usize| problem.real_entry(r / m, r % m, s / m, s % m);
    let g_tt = Mat::from_fn(half, half, |r, s| entry(half + r, half + s));
    let rhs = Mat::from_fn(half, 1, |r, _| -gap[half + r]);
    let solved = g_tt.partial_piv_lu().solve(&rhs);
    for (r, v) in x[half..].iter_mut().enumerate() {
        *v = solved[(r, 0)];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The normal half of a frictional problem (rows 0..nc): the frictionless problem.
pub fn normal_part(problem: &ReducedProblem) -> ReducedProblem {
    let (rows, m) = (problem.nodes, problem.coefficients());
    let nc = rows / 2;
    ReducedProblem {
        nodes: nc,
        harmonics: problem.harmonics,
        compliance: (problem.compliance.iter())
            .map(|gk| (0..nc * nc).map(|r| gk[(r / nc) * rows + r % nc]).collect())
            .collect(),
        linear_gap: problem.linear_gap[..nc * m].to_vec(),
        basis: problem.basis.clone(),
    }
}

/// The frictional solve from the frictionless solution `frictionless` (its λ_n, N and c):
/// Newton from (λ_n, 0) at μ; where that fails, the continuation in μ (`continuation`); where
/// that fails too, the continuation with a stiff c_t, polished at the plain one. Returns the
/// outcome (x = (λ_n, λ_t)) and the relative change of x from N to 2N. No Newton iteration
/// starts after `max_seconds` (harmonic_balance.solver.max_seconds, counted from here; the
/// frictionless solve before it has its own): the outcome's reason is then `OUT_OF_TIME`.
pub fn solve(
    problem: &ReducedProblem,
    coefficients: &[f64],
    frictionless: &super::ContactSolution,
    (tolerance, max_iterations, max_seconds): (f64, usize, f64),
) -> (NewtonOutcome, f64) {
    let deadline = Instant::now() + Duration::from_secs_f64(max_seconds.clamp(0.0, 1e9));
    let m = problem.coefficients();
    let nc = problem.nodes / 2;
    let floor = frictionless
        .complementarity
        .force_scale
        .max(f64::MIN_POSITIVE);
    let mut start = frictionless.multipliers.clone();
    start.resize(2 * nc * m, 0.0);
    // A continuation step starts near its root: a step that needs more than STEP_BUDGET
    // iterations is halved instead.
    let attempt = |scale: f64, samples: usize, start: Vec<f64>, tangential_scale: f64| {
        let mu: Vec<f64> = coefficients.iter().map(|m| m * scale).collect();
        let law = Law {
            coefficients: &mu,
            c: frictionless.c,
            tangential_scale,
        };
        let budget = if scale != 1.0 || tangential_scale != 1.0 {
            max_iterations.min(STEP_BUDGET)
        } else {
            max_iterations
        };
        let knobs = (tolerance, budget, floor);
        newton(problem, &law, samples, knobs, start, Some(deadline))
    };
    let timed_out = |o: &NewtonOutcome| o.reason == OUT_OF_TIME;
    let run = |scale: f64, samples: usize, start: Vec<f64>| attempt(scale, samples, start, 1.0);
    let n = frictionless.samples;
    let mut outcome = run(1.0, n, start.clone());
    let mut spent = outcome.iterations;
    if !outcome.converged && !timed_out(&outcome) {
        // Where the sliding state ends below μ (a state sticking more), the bonded one is
        // the nearer start: its own Newton (μ scaled by `BONDED`, every closed sample stuck)
        // from the bonded start, then the plain one from there.
        if let Some(bonded) = bonded_start(problem, &start) {
            let stuck = run(BONDED, n, bonded);
            spent += stuck.iterations;
            if stuck.converged {
                let from_bonded = run(1.0, n, stuck.multipliers);
                spent += from_bonded.iterations;
                if from_bonded.converged {
                    outcome = from_bonded;
                }
            }
        }
    }
    if !outcome.converged && Instant::now() < deadline {
        outcome = continuation(&run, n, start.clone(), spent);
        spent = outcome.iterations;
    }
    if !outcome.converged && Instant::now() < deadline {
        // A state stuck at every sample is a root whatever c_t: the continuation with a
        // stiffer c_t reaches one where the plain one cycles on the sliding branch, and the
        // plain c_t then polishes it (the friction damper of pipelines/scenes at μ = 0.3,
        // whose sliding state ends near 0.21).
        let stiff = |scale: f64, samples: usize, start: Vec<f64>| {
            attempt(scale, samples, start, STIFF_SCALE)
        };
        let found = continuation(&stiff, n, start, spent);
        spent = found.iterations;
        if found.converged {
            outcome = run(1.0, n, found.multipliers);
            spent += outcome.iterations;
        }
    }
    outcome.iterations = spent;
    if !outcome.converged {
        return (outcome, f64::NAN);
    }
    let doubled = run(1.0, 2 * n, outcome.multipliers.clone());
    let change = relative_change(&outcome, &doubled);
    (outcome, change)
}

/// The largest change of the multipliers from `base` to `doubled` (the re-solve at 2N),
/// relative to the largest of `base`'s; ∞ where the re-solve did not converge.
fn relative_change(base: &NewtonOutcome, doubled: &NewtonOutcome) -> f64 {
    if !doubled.converged {
        return f64::INFINITY;
    }
    let scale = norm_inf(&base.multipliers).max(f64::MIN_POSITIVE);
    (doubled.multipliers.iter().zip(&base.multipliers))
        .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()))
        / scale
}

/// The shares of (node, sample) pairs open, stuck and slipping, and the peak over the
/// samples of the total tangential force |Σ_i λ_t,i|.
pub fn statistics(states: &[NodeState]) -> ([f64; 3], f64) {
    let mut counts = [0usize; 3];
    let samples = states.first().map_or(0, |s| s.force.len());
    let mut total = vec![0.0; samples];
    for s in states {
        s.status.iter().for_each(|&k| counts[k as usize] += 1);
        total.iter_mut().zip(&s.force).for_each(|(t, f)| *t += f);
    }
    let all = counts.iter().sum::<usize>().max(1) as f64;
    let shares = counts.map(|c| c as f64 / all);
    (shares, norm_inf(&total))
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::c64;

    /// One node pressed 1 µm into its obstacle and driven 1 µm along it (H = 1), compliance
    /// 1e-9 m/N in both directions: μN = 300 N against a stuck force of 1 kN, so it slips.
    fn pressed_and_driven() -> ReducedProblem {
        let mut p = ReducedProblem::from_compliance(2, 1, |_, i, j| {
            c64::new(if i == j { 1e-9 } else { 0.0 }, 0.0)
        });
        p.linear_gap = vec![1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0];
        p
    }

    #[test]
    fn a_frictional_newton_starts_no_iteration_after_its_deadline() {
        let problem = pressed_and_driven();
        let law = Law {
            coefficients: &[0.3],
            c: 1e9,
            tangential_scale: 1.0,
        };
        let start = vec![0.0; 6];
        let knobs = (1e-10, 50, 1.0);
        let free = newton(&problem, &law, 16, knobs, start.clone(), None);
        assert!(free.converged && free.iterations > 0, "{}", free.reason);
        // Pressed: the mean normal force closes the 1 µm, −1 kN.
        assert!(
            (free.multipliers[0] + 1000.0).abs() < 1e-6,
            "{:?}",
            free.multipliers
        );
        let late = newton(&problem, &law, 16, knobs, start, Some(Instant::now()));
        assert!(!late.converged && late.iterations == 0);
        assert_eq!(late.reason, OUT_OF_TIME);
    }
}
