//! Floquet exponents of a harmonic-balance contact state by Hill's method on the state's own
//! discretization: the harmonic-balance equations linearized about the state, for a
//! perturbation e^{st} p(t) with p T-periodic in the same H harmonics (docs/method.md,
//! "Stability: Hill's method").
//!
//! Formulas and glossary (real Fourier layout of `fourier`, M = 2H + 1 coefficients):
//! - the contact law at the N samples, linearized (`reduced`'s Jacobian): δλ̃ + Q D P (c δg̃ −
//!   δλ̃) = 0, D = diag(d_n), d_n = 1 where c g − λ > 0 at sample t_n (the node closed), 0
//!   elsewhere. A factor e^{st} is common to every sample, so the law is the same for every
//!   exponent s: only the structure's compliance depends on s;
//! - the compliance W(σ) = B (σ²M + σD + K)⁻¹ Bᵀ split into r modes of the open structure
//!   (θ_j = ω_j², E = BΦ, c_j = α + βθ_j for D = αM + βK) and the rest R:
//!   W(σ) = Σ_j e_j e_jᵀ/(σ² + c_jσ + θ_j) + R(σ). The rest is frozen at each harmonic:
//!   R_k = G_k − Σ_j e_j e_jᵀ/(θ_j − k²ω² + ikωc_j) with G_k the compliance the state was
//!   solved with, so at s = 0 the Hill problem *is* the Newton Jacobian of the solve: a zero
//!   exponent (multiplier +1) is exactly a fold of the harmonic-balance branch;
//! - modal coordinates q̃ (r × M) and v = s q̃, Δ the time derivative on coefficients
//!   ((a_k, b_k) → (kω b_k, −kω a_k)); with δλ̃ = −L q̃, L = c J₀⁻¹ Q D P Ẽ and
//!   J₀ = I + Q D P (c R̃ − I) on the nodes ever closed (the others keep δλ = 0):
//!   s q̃ = v,  s v = −(2Δ + c_j) v − (Δ² + c_jΔ + θ_j) q̃ − Ẽᵀ L q̃ (a real 2rM matrix);
//! - its 2rM eigenvalues are the r·2 physical exponents, each repeated at s + imω: the copy
//!   kept is the one whose eigenvector is centred on harmonic 0 (the weighted harmonic index
//!   κ = Σ k(|c₊ₖ|² − |c₋ₖ|²)/Σ|c|² closest to 0, c±ₖ the exponential coefficients), which is
//!   the copy the truncation to H harmonics resolves best;
//! - multipliers μ = e^{sT}.
//!
//! The verdict belongs to the discrete model whose state is reported (the same H, N, c and
//! compliance): where the harmonic balance is coarse the verdict is that of the coarse model,
//! and the harmonic ladder of the solve says whether the state itself has converged.

use faer::{c64, Mat};
use nalgebra::DMatrix;

use super::basis::TimeBasis;
use super::floquet::Multipliers;
use super::fourier::{cos_index, sin_index};
use super::sampler::ContactSampler;
use super::{ContactSolution, System};
use crate::linalg::Csc;
use crate::{Error, Result};

/// Modes of the open structure computed for the Hill problem (the most any state keeps).
pub const MODES: usize = 24;

/// Modes up to this multiple of ω are kept dynamic (within `ORDER`).
pub const BAND: f64 = 10.0;

/// At least this many modes are kept dynamic.
pub const MIN_MODES: usize = 4;

/// The largest Hill matrix, 2rM.
pub const ORDER: usize = 2400;

/// Hill matrices up to this order get every eigenvalue (dense); larger ones the exponents
/// nearest the shifts `SHIFTS` by shift-invert Arnoldi.
pub const DENSE: usize = 240;

/// Shift-invert Arnoldi's shifts σ/ω: right of the imaginary axis, over the upper half of the
/// strip |Im s| ≤ ω/2 where each exponent has a copy (the lower half mirrors it).
const SHIFTS: [(f64, f64); 2] = [(0.2, 0.125), (0.2, 0.375)];

/// Krylov vectors per shift.
const KRYLOV: usize = 80;

/// The contact law of a state as Hill's method reads it: λ and g coefficients (node-major,
/// M per node), sampled at N instants with the complementarity parameter c.
pub struct SampledLaw<'a> {
    pub harmonics: usize,
    pub samples: usize,
    pub c: f64,
    pub multipliers: &'a [f64],
    pub gaps: &'a [f64],
}

impl<'a> SampledLaw<'a> {
    /// The law of a solved contact state.
    pub fn of(contact: &'a ContactSolution) -> SampledLaw<'a> {
        SampledLaw {
            harmonics: contact.harmonics,
            samples: contact.samples,
            c: contact.c,
            multipliers: &contact.multipliers,
            gaps: &contact.gaps,
        }
    }
}

/// How the exponents are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Eigen {
    /// Dense up to `DENSE`, Arnoldi beyond.
    Auto,
    /// Every eigenvalue of the Hill matrix.
    Dense,
    /// Shift-invert Arnoldi near the imaginary axis.
    Arnoldi,
}

/// The modal part of a scene's compliance (independent of the state and of ω: built once for
/// a run or a sweep).
pub struct HillModel {
    /// θ_j = ω_j² of the kept modes.
    theta: Vec<f64>,
    /// E = BΦ, every contact node × r.
    e: DMatrix<f64>,
    alpha: f64,
    beta: f64,
}

impl HillModel {
    /// The `modes` lowest modes of `system` (free dofs) seen through the contact operator `b`.
    pub fn new(system: &System, b: &Csc, modes: usize) -> Result<HillModel> {
        let (k, m) = (&system.k_ff, &system.m_ff);
        let massive = (0..m.ncols)
            .filter(|&j| (m.col_ptr[j]..m.col_ptr[j + 1]).any(|p| m.values[p] != 0.0))
            .count();
        let count = modes.min(massive);
        let found = crate::fem::modes::modes_near(k, m, count, 0.0, None)?;
        let rows = super::floquet::b_rows(b);
        let theta: Vec<f64> = found.iter().map(|(w2, _)| *w2).collect();
        let e = DMatrix::from_fn(rows.len(), found.len(), |i, j| {
            crate::linalg::dot(&rows[i], &found[j].1)
        });
        let (alpha, beta) = system.rayleigh.unwrap_or((0.0, 0.0));
        Ok(HillModel {
            theta,
            e,
            alpha,
            beta,
        })
    }

    /// A model from its parts: θ of the kept modes, E = BΦ (contact nodes × r), (α, β).
    pub fn from_parts(theta: Vec<f64>, e: DMatrix<f64>, (alpha, beta): (f64, f64)) -> HillModel {
        HillModel {
            theta,
            e,
            alpha,
            beta,
        }
    }

    /// r, the modes kept dynamic.
    pub fn dim(&self) -> usize {
        self.theta.len()
    }

    /// The same model keeping its `r` lowest modes dynamic.
    pub fn truncated(&self, r: usize) -> HillModel {
        let r = r.min(self.dim());
        HillModel {
            theta: self.theta[..r].to_vec(),
            e: self.e.columns(0, r).into_owned(),
            alpha: self.alpha,
            beta: self.beta,
        }
    }

    /// How many of the modes a state at ω with H harmonics keeps dynamic: those below
    /// `BAND`·ω (at least `MIN_MODES`), within the budget 2rM ≤ `ORDER`.
    pub fn modes_for(&self, omega: f64, harmonics: usize) -> usize {
        let m = 2 * harmonics + 1;
        let in_band = self
            .theta
            .iter()
            .filter(|&&t| t.max(0.0).sqrt() <= BAND * omega)
            .count();
        let budget = (ORDER / (2 * m)).max(1);
        in_band.max(MIN_MODES).min(budget).min(self.dim())
    }

    /// The Floquet multipliers of `contact`, a Fourier state at ω = `omega` solved with the
    /// compliance `compliance` (G_k per harmonic, row-major over every contact node).
    pub fn multipliers(
        &self,
        compliance: &[Vec<c64>],
        contact: &ContactSolution,
        omega: f64,
    ) -> Result<Multipliers> {
        self.multipliers_of(compliance, &SampledLaw::of(contact), omega, Eigen::Auto)
    }

    /// The Floquet multipliers of the state whose contact law is `law`, at ω, with the
    /// exponents found as `eigen` says.
    pub fn multipliers_of(
        &self,
        compliance: &[Vec<c64>],
        law: &SampledLaw,
        omega: f64,
        eigen: Eigen,
    ) -> Result<Multipliers> {
        let h = law.harmonics;
        if compliance.len() <= h || compliance.iter().any(|g| g.len() != self.e.nrows().pow(2)) {
            return Err(Error::Model(
                "internal: Hill's method lacks the compliance of a harmonic or node".into(),
            ));
        }
        let (closed, blocks, segments) = activity(law);
        let j0 = self.law_jacobian(compliance, law.c, &closed, &blocks, omega, h);
        let coupling = self.coupling(j0, law.c, &closed, &blocks, h)?;
        let hill = self.hill_matrix(&coupling, omega, h);
        let dense = match eigen {
            Eigen::Auto => hill.nrows() <= DENSE,
            Eigen::Dense => true,
            Eigen::Arnoldi => false,
        };
        let exponents = if dense {
            physical_exponents(&hill, self.dim(), h)?
        } else {
            self.rightmost_exponents(&hill, omega, h)?
        };
        let period = 2.0 * std::f64::consts::PI / omega;
        let mut values: Vec<c64> = exponents
            .iter()
            .map(|s| {
                let m = (s.re * period).exp();
                c64::new(m * (s.im * period).cos(), m * (s.im * period).sin())
            })
            .collect();
        if !values.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
            return Err(Error::Model(
                "Hill's method: a multiplier is not finite".into(),
            ));
        }
        values.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
        Ok(Multipliers { values, segments })
    }

    /// J₀ = I + Q D P (c R̃ − I) on the closed nodes (node-major, M per node).
    fn law_jacobian(
        &self,
        compliance: &[Vec<c64>],
        c: f64,
        closed: &[usize],
        blocks: &[Vec<f64>],
        omega: f64,
        h: usize,
    ) -> Mat<f64> {
        let (na, m) = (closed.len(), 2 * h + 1);
        let nc = self.e.nrows();
        let mut j0 = Mat::<f64>::zeros(na * m, na * m);
        for (k, gk) in compliance.iter().enumerate().take(h + 1) {
            let modal: Vec<c64> = (0..self.dim())
                .map(|j| {
                    let kw = k as f64 * omega;
                    let cj = self.alpha + self.beta * self.theta[j];
                    c64::new(1.0, 0.0) / c64::new(self.theta[j] - kw * kw, kw * cj)
                })
                .collect();
            let cols: Vec<usize> = if k == 0 {
                vec![0]
            } else {
                vec![cos_index(k), sin_index(k)]
            };
            for (a, &ia) in closed.iter().enumerate() {
                for (b, &ib) in closed.iter().enumerate() {
                    let mut r = gk[ia * nc + ib];
                    for (j, w) in modal.iter().enumerate() {
                        r -= *w * (self.e[(ia, j)] * self.e[(ib, j)]);
                    }
                    // Real form of y = R λ on (a_k, b_k): y_a = Re R λ_a + Im R λ_b,
                    // y_b = −Im R λ_a + Re R λ_b.
                    let rr = if k == 0 {
                        [[r.re, 0.0], [0.0, 0.0]]
                    } else {
                        [[r.re, r.im], [-r.im, r.re]]
                    };
                    // (A_a c R̃)[(a, row), (b, col)] = c Σ_{m''} A_a[row, m''] R̃[(a, m''), (b, col)].
                    for row in 0..m {
                        for (ci, &col) in cols.iter().enumerate() {
                            let mut sum = 0.0;
                            for (mi, &mid) in cols.iter().enumerate() {
                                sum += blocks[ia][row * m + mid] * rr[mi][ci];
                            }
                            j0[(a * m + row, b * m + col)] += c * sum;
                        }
                    }
                }
            }
        }
        for (a, &ia) in closed.iter().enumerate() {
            for row in 0..m {
                for col in 0..m {
                    j0[(a * m + row, a * m + col)] -= blocks[ia][row * m + col];
                }
                j0[(a * m + row, a * m + row)] += 1.0;
            }
        }
        j0
    }

    /// Ẽᵀ L = c Ẽᵀ J₀⁻¹ Q D P Ẽ (rM × rM, mode-major): how the modes' motion loads them
    /// back through the closed contacts.
    fn coupling(
        &self,
        j0: Mat<f64>,
        c: f64,
        closed: &[usize],
        blocks: &[Vec<f64>],
        h: usize,
    ) -> Result<Mat<f64>> {
        use faer::linalg::solvers::Solve;
        let (na, m, r) = (closed.len(), 2 * h + 1, self.dim());
        if na == 0 {
            return Ok(Mat::zeros(r * m, r * m));
        }
        let mut rhs = Mat::<f64>::zeros(na * m, r * m);
        for (a, &ia) in closed.iter().enumerate() {
            for j in 0..r {
                let e = self.e[(ia, j)];
                for row in 0..m {
                    for col in 0..m {
                        rhs[(a * m + row, j * m + col)] = e * blocks[ia][row * m + col];
                    }
                }
            }
        }
        let x = j0.partial_piv_lu().solve(&rhs);
        if !x.col_iter().all(|col| col.iter().all(|v| v.is_finite())) {
            return Err(Error::Model(
                "Hill's method: the linearized contact law is singular (the state sits at a fold)"
                    .into(),
            ));
        }
        let mut out = Mat::<f64>::zeros(r * m, r * m);
        for j in 0..r {
            for (a, &ia) in closed.iter().enumerate() {
                let e = c * self.e[(ia, j)];
                if e == 0.0 {
                    continue;
                }
                for row in 0..m {
                    for col in 0..r * m {
                        out[(j * m + row, col)] += e * x[(a * m + row, col)];
                    }
                }
            }
        }
        Ok(out)
    }

    /// The Hill matrix on (q̃, v), 2rM square.
    fn hill_matrix(&self, coupling: &Mat<f64>, omega: f64, h: usize) -> Mat<f64> {
        let (m, r) = (2 * h + 1, self.dim());
        let n = r * m;
        let mut a = Mat::<f64>::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        for j in 0..r {
            let cj = self.alpha + self.beta * self.theta[j];
            let base = j * m;
            for k in 0..=h {
                let kw = k as f64 * omega;
                let stiff = self.theta[j] - kw * kw;
                if k == 0 {
                    a[(n + base, base)] = -stiff;
                    a[(n + base, n + base)] = -cj;
                    continue;
                }
                let (ic, is) = (base + cos_index(k), base + sin_index(k));
                // −(Δ² + c_jΔ + θ_j) on q, −(2Δ + c_j) on v; Δ[cos, sin] = kω, Δ[sin, cos] = −kω.
                a[(n + ic, ic)] = -stiff;
                a[(n + is, is)] = -stiff;
                a[(n + ic, is)] = -cj * kw;
                a[(n + is, ic)] = cj * kw;
                a[(n + ic, n + ic)] = -cj;
                a[(n + is, n + is)] = -cj;
                a[(n + ic, n + is)] = -2.0 * kw;
                a[(n + is, n + ic)] = 2.0 * kw;
            }
        }
        for row in 0..n {
            for col in 0..n {
                a[(n + row, col)] -= coupling[(row, col)];
            }
        }
        a
    }
}

/// The nodes closed at some sample, per node Q D P (M × M row-major; empty when never
/// closed), and the number of runs of constant closed set over the period.
fn activity(law: &SampledLaw) -> (Vec<usize>, Vec<Vec<f64>>, usize) {
    let h = law.harmonics;
    let m = 2 * h + 1;
    let n = law.samples.max(1);
    let sampler = ContactSampler::new(&TimeBasis::Fourier, h, n);
    let mut closed = Vec::new();
    let mut blocks = Vec::new();
    let mut w = vec![0.0; m];
    let mut samples = vec![0.0; n];
    let mut sets = vec![Vec::new(); n];
    for (i, (l, g)) in law
        .multipliers
        .chunks(m)
        .zip(law.gaps.chunks(m))
        .enumerate()
    {
        for q in 0..m {
            w[q] = law.c * g[q] - l[q];
        }
        sampler.to_samples(&w, &mut samples);
        let slopes: Vec<f64> = samples.iter().map(|&v| f64::from(v > 0.0)).collect();
        for (set, _) in sets.iter_mut().zip(&slopes).filter(|(_, &d)| d > 0.0) {
            set.push(i);
        }
        if slopes.iter().any(|&d| d > 0.0) {
            let mut block = vec![0.0; m * m];
            sampler.activity_block(&slopes, &mut block);
            closed.push(i);
            blocks.push(block);
        } else {
            blocks.push(Vec::new());
        }
    }
    let changes = (0..n).filter(|&q| sets[q] != sets[(q + 1) % n]).count();
    (closed, blocks, changes.max(1))
}

/// The 2r exponents whose eigenvectors centre on harmonic 0, from the Hill matrix `a`.
fn physical_exponents(a: &Mat<f64>, r: usize, h: usize) -> Result<Vec<c64>> {
    let eig = a
        .eigen()
        .map_err(|e| Error::Model(format!("Hill's method: eigenvalues failed ({e:?})")))?;
    let (s, u) = (eig.S(), eig.U());
    let m = 2 * h + 1;
    let mut ranked: Vec<(f64, c64)> = (0..a.nrows())
        .map(|i| {
            let col: Vec<c64> = (0..a.nrows()).map(|q| u[(q, i)]).collect();
            (kappa(&col, r, m, h), s[i])
        })
        .collect();
    ranked.sort_by(|x, y| x.0.total_cmp(&y.0));
    Ok(ranked.into_iter().take(2 * r).map(|(_, s)| s).collect())
}

impl HillModel {
    /// The exponents nearest the `SHIFTS` (scaled by ω) by shift-invert Arnoldi on the Hill
    /// matrix `a` = [[0, I], [−K̂, −Ĉ]]: (A − σI)⁻¹ through P(σ) = K̂ + σĈ + σ²I, whose LU is
    /// rM square (Ĉ = 2Δ + c_j per mode, applied by its structure); of the converged Ritz
    /// values those whose eigenvector lies within the inner half of the kept harmonics
    /// (|κ| ≤ H/2: the truncation's edge copies are its artefacts).
    fn rightmost_exponents(&self, a: &Mat<f64>, omega: f64, h: usize) -> Result<Vec<c64>> {
        use faer::linalg::solvers::Solve;
        let n = a.nrows() / 2;
        let (m, r) = (2 * h + 1, self.dim());
        // Ĉ b, by modes and harmonics: c_j b on each coefficient, ±2kω across (cos, sin).
        let damp = |b: &[c64], out: &mut [c64]| {
            for j in 0..r {
                let cj = self.alpha + self.beta * self.theta[j];
                let base = j * m;
                out[base] = b[base] * cj;
                for k in 1..=h {
                    let (ic, is) = (base + cos_index(k), base + sin_index(k));
                    let kw2 = 2.0 * k as f64 * omega;
                    out[ic] = b[ic] * cj + b[is] * kw2;
                    out[is] = b[is] * cj - b[ic] * kw2;
                }
            }
        };
        let mut found: Vec<c64> = Vec::new();
        for (x, y) in SHIFTS {
            let sigma = c64::new(x * omega, y * omega);
            let p = Mat::<c64>::from_fn(n, n, |i, j| {
                let diagonal = if i == j {
                    sigma * sigma
                } else {
                    c64::new(0.0, 0.0)
                };
                c64::new(-a[(n + i, j)], 0.0) + sigma * (-a[(n + i, n + j)]) + diagonal
            });
            let lu = p.partial_piv_lu();
            // (A − σ)(x, y) = (b1, b2): y = b1 + σx, P(σ) x = −b2 − (Ĉ + σ) b1.
            let apply = |b: &[c64]| -> Vec<c64> {
                let (b1, b2) = b.split_at(n);
                let mut cb = vec![c64::new(0.0, 0.0); n];
                damp(b1, &mut cb);
                let rhs = Mat::<c64>::from_fn(n, 1, |i, _| -b2[i] - sigma * b1[i] - cb[i]);
                let xs = lu.solve(&rhs);
                let mut out = vec![c64::new(0.0, 0.0); 2 * n];
                for i in 0..n {
                    out[i] = xs[(i, 0)];
                    out[n + i] = b1[i] + sigma * xs[(i, 0)];
                }
                out
            };
            for (theta, vector) in arnoldi(apply, 2 * n, KRYLOV.min(2 * n))? {
                let s = sigma + c64::new(1.0, 0.0) / theta;
                if kappa(&vector, r, m, h) <= (h as f64 / 2.0).max(1.0)
                    && !found.iter().any(|f| (f - s).norm() <= 1e-8 * omega)
                {
                    found.push(s);
                }
            }
        }
        if found.is_empty() {
            return Err(Error::Model(
                "Hill's method: Arnoldi found no exponent near the imaginary axis".into(),
            ));
        }
        Ok(found)
    }
}

/// The converged Ritz pairs (θ, x) of `apply` from an Arnoldi factorization of `steps` steps
/// (modified Gram–Schmidt, reorthogonalized); converged: |h_{k+1,k} y_k| ≤ 1e-8 |θ|.
fn arnoldi(
    apply: impl Fn(&[c64]) -> Vec<c64>,
    n: usize,
    steps: usize,
) -> Result<Vec<(c64, Vec<c64>)>> {
    let zero = c64::new(0.0, 0.0);
    let norm = |v: &[c64]| v.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
    let start: Vec<c64> = (0..n)
        .map(|i| {
            c64::new(
                1.0 + ((i * 7919) % 97) as f64 / 97.0,
                ((i * 104729) % 89) as f64 / 89.0,
            )
        })
        .collect();
    let s0 = norm(&start);
    let mut basis: Vec<Vec<c64>> = vec![start.iter().map(|z| z / s0).collect()];
    let mut hess = Mat::<c64>::zeros(steps + 1, steps);
    let mut k = 0;
    while k < steps {
        let mut w = apply(&basis[k]);
        for _ in 0..2 {
            for (j, v) in basis.iter().enumerate() {
                let dot: c64 = v.iter().zip(&w).map(|(a, b)| a.conj() * b).sum();
                hess[(j, k)] += dot;
                for (wi, vi) in w.iter_mut().zip(v) {
                    *wi -= dot * vi;
                }
            }
        }
        let beta = norm(&w);
        hess[(k + 1, k)] = c64::new(beta, 0.0);
        k += 1;
        if !beta.is_finite() {
            return Err(Error::Model("Hill's method: Arnoldi broke down".into()));
        }
        if beta <= 1e-14 * hess[(k - 1, k - 1)].norm().max(1e-300) {
            break;
        }
        basis.push(w.iter().map(|z| z / beta).collect());
    }
    let small = Mat::<c64>::from_fn(k, k, |i, j| hess[(i, j)]);
    let eig = small
        .eigen()
        .map_err(|e| Error::Model(format!("Hill's method: Ritz values failed ({e:?})")))?;
    let (values, vectors) = (eig.S(), eig.U());
    let tail = hess[(k, k - 1)].norm();
    let mut out = Vec::new();
    for i in 0..k {
        let theta = values[i];
        let y = vectors.col(i);
        let ynorm = (0..k).map(|j| y[j].norm_sqr()).sum::<f64>().sqrt();
        if tail * y[k - 1].norm() > 1e-8 * theta.norm() * ynorm || theta.norm() == 0.0 {
            continue;
        }
        let mut x = vec![zero; n];
        for (j, v) in basis.iter().take(k).enumerate() {
            for (xi, vi) in x.iter_mut().zip(v) {
                *xi += y[j] * vi;
            }
        }
        out.push((theta, x));
    }
    Ok(out)
}

/// |κ|, the weighted harmonic index of an eigenvector's modal part (r modes × M coefficients).
fn kappa(col: &[c64], r: usize, m: usize, h: usize) -> f64 {
    let (mut moment, mut total) = (0.0, 0.0);
    for j in 0..r {
        total += col[j * m].norm_sqr();
        for k in 1..=h {
            let (ca, cb) = (col[j * m + cos_index(k)], col[j * m + sin_index(k)]);
            let plus = (ca - c64::new(0.0, 1.0) * cb) * 0.5;
            let minus = (ca + c64::new(0.0, 1.0) * cb) * 0.5;
            let (p, q) = (plus.norm_sqr(), minus.norm_sqr());
            moment += k as f64 * (p - q);
            total += p + q;
        }
    }
    if total > 0.0 {
        (moment / total).abs()
    } else {
        f64::INFINITY
    }
}
