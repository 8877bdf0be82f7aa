//! The exponents of a Hill matrix nearest a shift σ, by shift-invert Arnoldi, in real
//! arithmetic for a real σ and complex arithmetic for a complex one.
//!
//! Formulas and glossary (those of `hill`):
//! - A = [[0, I], [−K̂, −Ĉ]] on (q̃, v), K̂ = Δ² + c_jΔ + θ_j and Ĉ = 2Δ + c_j per mode plus the
//!   contact law's coupling; (A − σI)(x, y) = (b1, b2) is y = b1 + σx, P(σ) x = −b2 − (Ĉ + σ) b1
//!   with P(σ) = K̂ + σĈ + σ²I (`ShiftedSolve`);
//! - a Ritz value θ of (A − σI)⁻¹ is the exponent s = σ + 1/θ;
//! - every exponent has a copy s + ikω in each strip |Im s − kω| ≤ ω/2, and the copy the
//!   truncation to H harmonics resolves best is the one centred on harmonic 0 (|κ| ≤
//!   `CENTRED`), which lies in the strip of the exponent's own frequency. A real σ = 0.2ω
//!   (`SHIFT`) finds the centred copies of the exponents whose frequency is below ω/2; the
//!   centred copy of one whose frequency is near mω is found from σ = 0.2ω + imω;
//! - on a centred copy's error: on the elastic-casing blade (drive 700 Hz, its modes far
//!   above) the copies one and two harmonics off centre put the leading |μ| at 0.8642 and
//!   0.8764 where the centred one is 0.8671: a copy off centre is not the same multiplier.

use faer::linalg::matmul::matmul_with_conj;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{c64, Accum, Conj, Mat, MatRef, Par};

use super::{centred, kappa, Exponent, HillModel, Linearized, Ranked, KRYLOV};
use crate::hbm::fourier::{cos_index, sin_index};
use crate::linalg::norm2;
use crate::{Error, Result};

/// The scalar of a shift-invert Arnoldi run: f64 for a real shift, c64 for a complex one.
pub(super) trait Scalar:
    faer::traits::ComplexField<Real = f64>
    + Copy
    + From<f64>
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
    + std::ops::AddAssign
    + std::ops::SubAssign
{
    /// The eigenpairs of a square matrix.
    fn eigen(a: MatRef<'_, Self>) -> Result<(Vec<c64>, Mat<c64>)>;
    /// The Ritz vectors V y, one per column of `y`.
    fn ritz_vectors(v: MatRef<'_, Self>, y: &Mat<c64>) -> Mat<c64>;
    /// The value as a complex number.
    fn complex(self) -> c64;
}

impl Scalar for f64 {
    fn eigen(a: MatRef<'_, f64>) -> Result<(Vec<c64>, Mat<c64>)> {
        crate::linalg::eigen_real(a)
    }

    /// As two real products.
    fn ritz_vectors(v: MatRef<'_, f64>, y: &Mat<c64>) -> Mat<c64> {
        let (re, im) = (
            Mat::<f64>::from_fn(y.nrows(), y.ncols(), |i, j| y[(i, j)].re),
            Mat::<f64>::from_fn(y.nrows(), y.ncols(), |i, j| y[(i, j)].im),
        );
        let (xr, xi) = (v * &re, v * &im);
        Mat::from_fn(v.nrows(), y.ncols(), |i, j| {
            c64::new(xr[(i, j)], xi[(i, j)])
        })
    }

    fn complex(self) -> c64 {
        c64::new(self, 0.0)
    }
}

impl Scalar for c64 {
    fn eigen(a: MatRef<'_, c64>) -> Result<(Vec<c64>, Mat<c64>)> {
        crate::linalg::eigen_complex(a)
    }

    fn ritz_vectors(v: MatRef<'_, c64>, y: &Mat<c64>) -> Mat<c64> {
        v * y
    }

    fn complex(self) -> c64 {
        self
    }
}

/// Shift-invert Arnoldi's real shift σ/ω: right of the imaginary axis, nearer the rightmost
/// exponents of the strip |Im s| ≤ ω/2, where each exponent has a copy, than any copy outside
/// it. A complex shift adds imω to it.
const SHIFT: f64 = 0.2;

/// The most strips of modes' own frequencies searched (one Arnoldi run each): beyond, the
/// dense eigenvalues cost less.
const MAX_STRIPS: usize = 8;

impl HillModel {
    /// The exponents nearest the real shift σ = `SHIFT`·ω whose copy there is centred:
    /// `centred_near` at m = 0.
    pub(super) fn rightmost_exponents(
        &self,
        law: &Linearized,
        omega: f64,
        h: usize,
    ) -> Result<Vec<Exponent>> {
        let found = self.centred_near::<f64>(law, omega, h, SHIFT * omega)?;
        if found.is_empty() {
            return Err(Error::Model(
                "Hill's method: Arnoldi found no exponent near the imaginary axis".into(),
            ));
        }
        Ok(found)
    }

    /// The centred exponents of the strips of the dynamic modes' own frequencies, with their
    /// conjugates: σ = `SHIFT`·ω + imω, m the nearest multiple of ω to each mode's, once each.
    /// Where the modes lie far above the drive, the real shift finds only copies off centre.
    pub(super) fn exponents_by_mode_strips(
        &self,
        law: &Linearized,
        omega: f64,
        h: usize,
    ) -> Result<Vec<Exponent>> {
        let mut strips: Vec<usize> = (self.theta.iter())
            .map(|t| (t.max(0.0).sqrt() / omega).round() as usize)
            .filter(|&m| m >= 1)
            .collect();
        strips.sort_unstable();
        strips.dedup();
        if strips.len() > MAX_STRIPS {
            return Err(Error::Model(format!(
                "Hill's method: the dynamic modes span {} strips",
                strips.len()
            )));
        }
        let mut found: Vec<Exponent> = Vec::new();
        for m in strips {
            let sigma = c64::new(SHIFT * omega, m as f64 * omega);
            for (s, q) in self.centred_near::<c64>(law, omega, h, sigma)? {
                let conjugate = (s.conj(), q.iter().map(|z| z.conj()).collect());
                for (s, q) in [(s, q), conjugate] {
                    if !found.iter().any(|(t, _)| (t - s).norm() <= 1e-8 * omega) {
                        found.push((s, q));
                    }
                }
            }
        }
        if found.is_empty() {
            return Err(Error::Model(
                "Hill's method: Arnoldi found no centred exponent in the modes' strips".into(),
            ));
        }
        Ok(found)
    }

    /// The converged Ritz pairs of shift-invert Arnoldi at σ whose copy is centred
    /// (`centred`), as exponents s = σ + 1/θ.
    fn centred_near<T: Scalar>(
        &self,
        law: &Linearized,
        omega: f64,
        h: usize,
        sigma: T,
    ) -> Result<Vec<Exponent>> {
        let (m, r) = (2 * h + 1, self.dim());
        let n = r * m;
        let solve = ShiftedSolve::new(self, law, sigma, omega, h)?;
        let apply = |b: &[T]| -> Vec<T> {
            let (b1, b2) = b.split_at(n);
            let mut rhs: Vec<T> = (0..n).map(|i| -b2[i] - sigma * b1[i]).collect();
            self.sub_damping(b1, &mut rhs, omega, h);
            let x = solve.apply(rhs);
            let y: Vec<T> = (0..n).map(|i| b1[i] + sigma * x[i]).collect();
            [x, y].concat()
        };
        let steps = (KRYLOV + 4 * r).min(2 * n);
        let shift = sigma.complex();
        let ranked: Vec<Ranked> = arnoldi(apply, 2 * n, steps)?
            .into_iter()
            .map(|(theta, mut vector)| {
                let s = shift + c64::new(1.0, 0.0) / theta;
                vector.truncate(n);
                (kappa(&vector, r, m, h), s, vector)
            })
            .collect();
        Ok(centred(ranked, omega))
    }

    /// out −= Ĉ b by its structure: c_j on each coefficient, ±2kω across (cos, sin).
    fn sub_damping<T: Scalar>(&self, b: &[T], out: &mut [T], omega: f64, h: usize) {
        let m = 2 * h + 1;
        for j in 0..self.dim() {
            let cj = T::from(self.alpha + self.beta * self.theta[j]);
            let base = j * m;
            out[base] -= cj * b[base];
            for k in 1..=h {
                let (ic, is) = (base + cos_index(k), base + sin_index(k));
                let kw2 = T::from(2.0 * k as f64 * omega);
                out[ic] -= cj * b[ic] + kw2 * b[is];
                out[is] -= cj * b[is] - kw2 * b[ic];
            }
        }
    }
}

/// x = P(σ)⁻¹ b for P(σ) = K̂ + σĈ + σ²I = D(σ) + U J₀⁻¹ R, with D(σ) the modes' own
/// operator (a 2 × 2 block per mode and harmonic), U = c Ẽᵀ (rM × n_a M) and R = Q D P Ẽ
/// (n_a M × rM): by Woodbury, P⁻¹ = D⁻¹ − D⁻¹ U W⁻¹ R D⁻¹ with W = J₀ + R D⁻¹ U, whose
/// LU is n_a M square (the closed nodes' coefficients) where P's would be rM square, and
/// W = J₀ + c (Q D P)_a Σ_j e_aj e_bj D_j⁻¹ is assembled from the modal compliance at σ
/// without forming J₀⁻¹ R. D is invertible for every σ right of the imaginary axis: its
/// blocks are those of the damped open structure, whose exponents lie left of it (for a
/// real σ > 0 each 2 × 2 block has determinant a² + b², b = (c_j + 2σ) kω ≠ 0, and
/// θ_j + σc_j + σ² > 0 at k = 0).
struct ShiftedSolve<'a, T: Scalar> {
    model: &'a HillModel,
    law: &'a Linearized<'a>,
    h: usize,
    /// D⁻¹ per mode and harmonic: (p, q) with D⁻¹ = [[p, −q], [q, p]] on (cos, sin), p alone at
    /// k = 0; mode-major, H + 1 per mode.
    inverse: Vec<(T, T)>,
    /// W's LU.
    w: faer::linalg::solvers::PartialPivLu<T>,
}

impl<'a, T: Scalar> ShiftedSolve<'a, T> {
    fn new(
        model: &'a HillModel,
        law: &'a Linearized<'a>,
        sigma: T,
        omega: f64,
        h: usize,
    ) -> Result<ShiftedSolve<'a, T>> {
        let r = model.dim();
        let mut inverse = Vec::with_capacity(r * (h + 1));
        for j in 0..r {
            let cj = T::from(model.alpha + model.beta * model.theta[j]);
            for k in 0..=h {
                let kw = k as f64 * omega;
                let a = T::from(model.theta[j] - kw * kw) + sigma * cj + sigma * sigma;
                let b = (cj + T::from(2.0) * sigma) * T::from(kw);
                let det = a * a + b * b;
                inverse.push((a / det, b / det));
            }
        }
        let w = capacitance(model, law, &inverse, h);
        if !(0..w.nrows()).all(|i| (0..w.ncols()).all(|j| w[(i, j)].complex().is_finite())) {
            return Err(Error::Model(
                "Hill's method: the shifted operator is singular".into(),
            ));
        }
        Ok(ShiftedSolve {
            model,
            law,
            h,
            inverse,
            w: w.partial_piv_lu(),
        })
    }

    /// x ← D⁻¹ x.
    fn modal_solve(&self, x: &mut [T]) {
        let (h, m) = (self.h, 2 * self.h + 1);
        for j in 0..self.model.dim() {
            let base = j * m;
            let inv = &self.inverse[j * (h + 1)..(j + 1) * (h + 1)];
            x[base] *= inv[0].0;
            for (k, &(p, q)) in inv.iter().enumerate().skip(1) {
                let (ic, is) = (base + cos_index(k), base + sin_index(k));
                let (xc, xs) = (x[ic], x[is]);
                x[ic] = p * xc - q * xs;
                x[is] = q * xc + p * xs;
            }
        }
    }

    /// P(σ)⁻¹ b.
    fn apply(&self, mut b: Vec<T>) -> Vec<T> {
        use faer::linalg::solvers::Solve;
        let (model, law) = (self.model, self.law);
        let (r, m) = (model.dim(), 2 * self.h + 1);
        self.modal_solve(&mut b);
        if law.closed.is_empty() {
            return b;
        }
        let zero = T::from(0.0);
        // t = R y: per closed node a, (Q D P)_a Σ_j e_aj y_j.
        let mut t = Mat::<T>::from_fn(law.closed.len() * m, 1, |_, _| zero);
        let mut u = vec![zero; m];
        for (ai, &a) in law.closed.iter().enumerate() {
            u.iter_mut().for_each(|v| *v = zero);
            for j in 0..r {
                let e = T::from(model.e[(a, j)]);
                u.iter_mut()
                    .zip(&b[j * m..(j + 1) * m])
                    .for_each(|(ui, &yi)| *ui += e * yi);
            }
            let block = &law.blocks[a];
            for row in 0..m {
                t[(ai * m + row, 0)] = (0..m).fold(zero, |acc, col| {
                    acc + T::from(block[row * m + col]) * u[col]
                });
            }
        }
        let z = self.w.solve(&t);
        // v = U z = c Ẽᵀ z, then x = y − D⁻¹ v.
        let mut v = vec![zero; r * m];
        for (ai, &a) in law.closed.iter().enumerate() {
            for j in 0..r {
                let e = T::from(law.c * model.e[(a, j)]);
                for row in 0..m {
                    v[j * m + row] += e * z[(ai * m + row, 0)];
                }
            }
        }
        self.modal_solve(&mut v);
        b.iter_mut().zip(&v).for_each(|(bi, &vi)| *bi -= vi);
        b
    }
}

/// W = J₀ + c (Q D P)_a Σ_j e_aj e_bj D_j⁻¹ over the closed nodes (`ShiftedSolve`).
fn capacitance<T: Scalar>(
    model: &HillModel,
    law: &Linearized,
    inverse: &[(T, T)],
    h: usize,
) -> Mat<T> {
    let (r, m, c) = (model.dim(), 2 * h + 1, T::from(law.c));
    let zero = T::from(0.0);
    let mut w = Mat::<T>::from_fn(law.j0.nrows(), law.j0.ncols(), |i, j| {
        T::from(law.j0[(i, j)])
    });
    for (ai, &a) in law.closed.iter().enumerate() {
        let block = &law.blocks[a];
        for (bi, &b) in law.closed.iter().enumerate() {
            // G_ab = Σ_j e_aj e_bj D_j⁻¹, per harmonic (P, Q).
            let mut g = vec![(zero, zero); h + 1];
            for j in 0..r {
                let ee = T::from(model.e[(a, j)] * model.e[(b, j)]);
                for (gk, &(p, q)) in g.iter_mut().zip(&inverse[j * (h + 1)..]) {
                    *gk = (gk.0 + ee * p, gk.1 + ee * q);
                }
            }
            for row in 0..m {
                let at = |col: usize| T::from(block[row * m + col]);
                let (ra, rb) = (ai * m + row, bi * m);
                w[(ra, rb)] += c * at(0) * g[0].0;
                for (k, &(p, q)) in g.iter().enumerate().skip(1) {
                    let (ic, is) = (cos_index(k), sin_index(k));
                    w[(ra, rb + ic)] += c * (at(ic) * p + at(is) * q);
                    w[(ra, rb + is)] += c * (at(is) * p - at(ic) * q);
                }
            }
        }
    }
    w
}

/// The converged Ritz pairs (θ, x) of the operator `apply` from an Arnoldi factorization
/// of `steps` steps (classical Gram–Schmidt, twice); a real operator's complex Ritz values
/// come in conjugate pairs; converged: |h_{k+1,k} y_k| ≤ 1e-8 |θ|.
fn arnoldi<T: Scalar>(
    apply: impl Fn(&[T]) -> Vec<T>,
    n: usize,
    steps: usize,
) -> Result<Vec<(c64, Vec<c64>)>> {
    let (basis, hess, k) = arnoldi_factorization(apply, n, steps)?;
    converged_ritz_pairs(&basis, &hess, k)
}

/// The Arnoldi factorization A V_k = V_{k+1} H̄_k of `apply` from a fixed start vector: the
/// basis V (n × (steps + 1)), the Hessenberg matrix H̄ ((steps + 1) × steps) and the steps k
/// taken (fewer than `steps` when h_{k+1,k} ≤ 1e-14 |h_{k,k}|, an invariant subspace).
fn arnoldi_factorization<T: Scalar>(
    apply: impl Fn(&[T]) -> Vec<T>,
    n: usize,
    steps: usize,
) -> Result<(Mat<T>, Mat<T>, usize)> {
    let zero = T::from(0.0);
    let mut basis = Mat::<T>::from_fn(n, steps + 1, |_, _| zero);
    let start: Vec<f64> = (0..n)
        .map(|i| 1.0 + ((i * 7919) % 97) as f64 / 97.0 - ((i * 104729) % 89) as f64 / 89.0)
        .collect();
    let s0 = norm2(&start);
    for (i, v) in start.iter().enumerate() {
        basis[(i, 0)] = T::from(v / s0);
    }
    let mut hess = Mat::<T>::from_fn(steps + 1, steps, |_, _| zero);
    let mut dots = Mat::<T>::from_fn(steps + 1, 1, |_, _| zero);
    let mut k = 0;
    while k < steps {
        let current: Vec<T> = basis.col(k).iter().copied().collect();
        let mut w = Mat::<T>::from_fn(n, 1, |_, _| zero);
        for (i, v) in apply(&current).into_iter().enumerate() {
            w[(i, 0)] = v;
        }
        let done = basis.as_ref().subcols(0, k + 1);
        for _ in 0..2 {
            let mut h = dots.as_mut().subrows_mut(0, k + 1);
            let (one, minus) = (T::from(1.0), T::from(-1.0));
            let (t, no) = (done.transpose(), Conj::No);
            matmul_with_conj(
                h.rb_mut(),
                Accum::Replace,
                t,
                Conj::Yes,
                w.as_ref(),
                no,
                one,
                Par::Seq,
            );
            matmul_with_conj(
                w.as_mut(),
                Accum::Add,
                done,
                no,
                h.rb(),
                no,
                minus,
                Par::Seq,
            );
            for j in 0..=k {
                hess[(j, k)] += h[(j, 0)];
            }
        }
        let beta = w.col(0).norm_l2();
        hess[(k + 1, k)] = T::from(beta);
        k += 1;
        if !beta.is_finite() {
            return Err(Error::Model("Hill's method: Arnoldi broke down".into()));
        }
        if beta <= 1e-14 * hess[(k - 1, k - 1)].complex().norm().max(1e-300) {
            break;
        }
        for i in 0..n {
            basis[(i, k)] = w[(i, 0)] * T::from(1.0 / beta);
        }
    }
    Ok((basis, hess, k))
}

/// The Ritz pairs (θ, V_k y) of the factorization's k × k Hessenberg matrix H_k whose
/// residual |h_{k+1,k} y_k| is at most 1e-8 |θ| ‖y‖ (θ ≠ 0).
fn converged_ritz_pairs<T: Scalar>(
    basis: &Mat<T>,
    hess: &Mat<T>,
    k: usize,
) -> Result<Vec<(c64, Vec<c64>)>> {
    let n = basis.nrows();
    let (values, vectors) = T::eigen(hess.as_ref().submatrix(0, 0, k, k))
        .map_err(|e| Error::Model(format!("Hill's method: Ritz values: {e}")))?;
    let tail = hess[(k, k - 1)].complex().norm();
    let converged: Vec<usize> = (0..values.len())
        .filter(|&i| {
            let (theta, y) = (values[i], vectors.col(i));
            let ynorm = (0..k).map(|j| y[j].norm_sqr()).sum::<f64>().sqrt();
            tail * y[k - 1].norm() <= 1e-8 * theta.norm() * ynorm && theta.norm() > 0.0
        })
        .collect();
    let y = Mat::<c64>::from_fn(k, converged.len(), |j, c| vectors[(j, converged[c])]);
    let x = T::ritz_vectors(basis.as_ref().subcols(0, k), &y);
    Ok(converged
        .iter()
        .enumerate()
        .map(|(c, &i)| (values[i], (0..n).map(|q| x[(q, c)]).collect()))
        .collect())
}
