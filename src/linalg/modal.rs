//! A reduced model of the pencil (K, M) that answers the solves of Z = a K + b M for any complex
//! (a, b) without factoring Z: Rayleigh–Ritz on a rational Krylov space (Ruhe; Grimme's
//! moment matching). Every harmonic of every frequency of a sweep with Rayleigh damping is
//! such a Z, so one model serves them all (docs/method.md, "Reduced frames").
//!
//! Glossary and formulas:
//! - W the start block (real columns: Bᵀ's rows, the parts of the loads), σ_j real shifts;
//! - V = span{(K − σ_j M)⁻¹ W}, made M-orthonormal with dependent columns dropped;
//! - Φ, θ the Ritz pairs of (K, M) on V: Φᵀ M Φ = I, Φᵀ K Φ = diag(θ), r = dim V;
//! - the Galerkin solve Z x = f on span Φ: x = Φ diag(d) Φᵀ f, d_j = 1/(a θ_j + b);
//! - G = B Z⁻¹ Bᵀ ≈ (BΦ) diag(d) (BΦ)ᵀ, which interpolates the exact G at every shift (and
//!   its σ-derivative: the space holds both sides' solves of a symmetric pencil);
//! - the residual ρ = f − Z x satisfies Φᵀρ = 0 and nothing more: the caller judges a
//!   reduced solve by ρ against the scale of Z x and f (a backward error), the same test a
//!   factorization's solves pass.

use faer::c64;
use faer::linalg::matmul::matmul;
use faer::{Accum, Par};
use nalgebra::{DMatrix, SymmetricEigen};

use super::{dot, Csc};
use crate::{Error, Result};

/// Columns below this fraction of their norm before orthogonalization are dependent.
const DEPENDENT: f64 = 1e-10;

/// An M-orthonormal basis Q of a growing space, with KQ and Q ᵀK Q, so adding columns costs
/// their orthogonalization against Q only.
#[derive(Clone, Debug, Default)]
pub struct ModalSpace {
    q: Vec<Vec<f64>>,
    mq: Vec<Vec<f64>>,
    kq: Vec<Vec<f64>>,
}

impl ModalSpace {
    /// Add `columns` (real, length n), M-orthogonalized against the space and each other;
    /// columns that fall below `DEPENDENT` of their M-norm are dropped.
    pub fn extend(&mut self, k: &Csc, m: &Csc, columns: Vec<Vec<f64>>) {
        for mut col in columns {
            let before = dot(&col, &m.mul_vec(&col)).max(0.0).sqrt();
            if !(before > 0.0) || !before.is_finite() {
                continue;
            }
            for _ in 0..2 {
                for (b, mb) in self.q.iter().zip(&self.mq) {
                    let c = dot(mb, &col);
                    col.iter_mut().zip(b).for_each(|(v, bv)| *v -= c * bv);
                }
            }
            let mcol = m.mul_vec(&col);
            let norm = dot(&col, &mcol).max(0.0).sqrt();
            if norm > DEPENDENT * before {
                col.iter_mut().for_each(|v| *v /= norm);
                self.mq.push(mcol.into_iter().map(|v| v / norm).collect());
                self.kq.push(k.mul_vec(&col));
                self.q.push(col);
            }
        }
    }

    pub fn dim(&self) -> usize {
        self.q.len()
    }
}

/// The Ritz basis Φ, θ of (K, M) on a `ModalSpace`, with BΦ.
#[derive(Debug)]
pub struct ModalBasis {
    n: usize,
    /// Φ, n × r.
    phi: faer::Mat<f64>,
    theta: Vec<f64>,
    /// BΦ row-major, n_c × r.
    b_phi: Vec<f64>,
    b: Csc,
}

impl ModalBasis {
    /// The Ritz pairs on `space`, for the contact operator `b` (n_c × n).
    pub fn new(space: &ModalSpace, b: &Csc) -> Result<ModalBasis> {
        let r = space.dim();
        if r == 0 {
            return Err(Error::Model(
                "reduced model: no independent vector (zero loads and contact?)".into(),
            ));
        }
        let n = space.q[0].len();
        let kr = DMatrix::from_fn(r, r, |i, j| dot(&space.q[i], &space.kq[j]));
        let eig = SymmetricEigen::new((&kr + kr.transpose()) * 0.5);
        let q = faer::Mat::<f64>::from_fn(n, r, |i, j| space.q[j][i]);
        let s = faer::Mat::<f64>::from_fn(r, r, |i, j| eig.eigenvectors[(i, j)]);
        let mut phi = faer::Mat::<f64>::zeros(n, r);
        matmul(
            phi.as_mut(),
            Accum::Replace,
            q.as_ref(),
            s.as_ref(),
            1.0,
            Par::Seq,
        );
        let theta: Vec<f64> = eig.eigenvalues.iter().copied().collect();
        let nc = b.nrows;
        let mut b_phi = vec![0.0; nc * r];
        for c in 0..r {
            let col: Vec<f64> = (0..n).map(|i| phi[(i, c)]).collect();
            let bc = b.mul_vec(&col);
            for (i, v) in bc.into_iter().enumerate() {
                b_phi[i * r + c] = v;
            }
        }
        Ok(ModalBasis {
            n,
            phi,
            theta,
            b_phi,
            b: b.clone(),
        })
    }

    /// r, the dimension of the space.
    pub fn dim(&self) -> usize {
        self.theta.len()
    }

    /// θ, the Ritz values (Φᵀ K Φ = diag(θ)).
    pub fn theta(&self) -> &[f64] {
        &self.theta
    }

    /// BΦ, row-major n_c × r.
    pub fn b_phi(&self) -> &[f64] {
        &self.b_phi
    }

    /// Whether BΦ was formed for this B.
    pub fn built_for(&self, b: &Csc) -> bool {
        self.b == *b
    }

    /// The reduced solve of Z = a K + b M (`None` when a θ_j + b vanishes: Z singular on the
    /// space), with the load `f` projected (Φᵀ f) for its response and rates.
    pub fn at(self: &std::sync::Arc<Self>, a: c64, b: c64, f: &[c64]) -> Option<ModalFactor> {
        let d: Vec<c64> = self.theta.iter().map(|&t| (a * t + b).inv()).collect();
        let finite = d.iter().all(|z| z.re.is_finite() && z.im.is_finite());
        finite.then(|| {
            let mut factor = ModalFactor {
                basis: std::sync::Arc::clone(self),
                d,
                load: Vec::new(),
            };
            factor.load = factor.project(f);
            factor
        })
    }
}

/// Z⁻¹ ≈ Φ diag(d) Φᵀ for one (a, b).
#[derive(Clone, Debug)]
pub struct ModalFactor {
    basis: std::sync::Arc<ModalBasis>,
    d: Vec<c64>,
    /// Φᵀ f of the load it was made with.
    load: Vec<c64>,
}

impl ModalFactor {
    pub fn dim(&self) -> usize {
        self.basis.n
    }

    /// x = Φ diag(d) Φᵀ f.
    pub fn solve(&self, f: &[c64]) -> Vec<c64> {
        self.solve_many(std::slice::from_ref(&f.to_vec()))
            .pop()
            .unwrap_or_default()
    }

    /// `solve` for several right-hand sides at once (two dense products with Φ).
    pub fn solve_many(&self, rhs: &[Vec<c64>]) -> Vec<Vec<c64>> {
        let (n, m) = (self.basis.n, rhs.len());
        let phi = &self.basis.phi;
        let f = faer::Mat::<f64>::from_fn(n, 2 * m, |i, j| {
            let z = rhs[j / 2][i];
            if j % 2 == 0 {
                z.re
            } else {
                z.im
            }
        });
        let mut c = faer::Mat::<f64>::zeros(phi.ncols(), 2 * m);
        matmul(
            c.as_mut(),
            Accum::Replace,
            phi.transpose(),
            f.as_ref(),
            1.0,
            Par::Seq,
        );
        let y = faer::Mat::<f64>::from_fn(phi.ncols(), 2 * m, |i, j| {
            let z = self.d[i] * c64::new(c[(i, 2 * (j / 2))], c[(i, 2 * (j / 2) + 1)]);
            if j % 2 == 0 {
                z.re
            } else {
                z.im
            }
        });
        let mut x = faer::Mat::<f64>::zeros(n, 2 * m);
        matmul(
            x.as_mut(),
            Accum::Replace,
            phi.as_ref(),
            y.as_ref(),
            1.0,
            Par::Seq,
        );
        (0..m)
            .map(|j| {
                (0..n)
                    .map(|i| c64::new(x[(i, 2 * j)], x[(i, 2 * j + 1)]))
                    .collect()
            })
            .collect()
    }

    /// Φᵀ f.
    pub fn project(&self, f: &[c64]) -> Vec<c64> {
        let phi = &self.basis.phi;
        (0..phi.ncols())
            .map(|c| {
                let col = phi.col(c);
                f.iter()
                    .enumerate()
                    .fold(c64::new(0.0, 0.0), |acc, (i, z)| acc + z * col[i])
            })
            .collect()
    }

    /// The response to the load: Φ diag(d) Φᵀ f, column by column of Φ.
    pub fn load_response(&self) -> Vec<c64> {
        let phi = &self.basis.phi;
        let mut x = vec![c64::new(0.0, 0.0); self.basis.n];
        for (c, (l, d)) in self.load.iter().zip(&self.d).enumerate() {
            let (y, col) = (l * d, phi.col(c));
            x.iter_mut()
                .enumerate()
                .for_each(|(i, xi)| *xi += y * col[i]);
        }
        x
    }

    /// ∂(B u)/∂ω at fixed λ for u = Z⁻¹(f + Bᵀλ) on the space, whose pencil moves at
    /// (a', b'): −BΦ diag(d) [(a'θ + b') ∘ y + p'], y = d ∘ (Φᵀf + (BΦ)ᵀλ), p' = Φᵀ∂f/∂ω
    /// (`None`: f does not move with ω).
    pub fn contact_rate(
        &self,
        lambda: &[c64],
        rate: (c64, c64),
        load_rate: Option<&[c64]>,
    ) -> Vec<c64> {
        let basis = &*self.basis;
        let (nc, r) = (basis.b.nrows, basis.dim());
        let mut v: Vec<c64> = (0..r)
            .map(|c| {
                let bl: c64 = (0..nc).map(|i| lambda[i] * basis.b_phi[i * r + c]).sum();
                let y = self.d[c] * (self.load[c] + bl);
                (rate.0 * basis.theta[c] + rate.1) * y
            })
            .collect();
        if let Some(p) = load_rate {
            v.iter_mut().zip(self.project(p)).for_each(|(a, b)| *a += b);
        }
        (0..nc)
            .map(|i| {
                let row = &basis.b_phi[i * r..(i + 1) * r];
                -(0..r).map(|c| self.d[c] * v[c] * row[c]).sum::<c64>()
            })
            .collect()
    }

    /// G = (BΦ) diag(d) (BΦ)ᵀ, row-major n_c².
    pub fn compliance(&self) -> Vec<c64> {
        let basis = &*self.basis;
        let (nc, r) = (basis.b.nrows, basis.dim());
        let mut g = vec![c64::new(0.0, 0.0); nc * nc];
        for i in 0..nc {
            let bi = &basis.b_phi[i * r..(i + 1) * r];
            for j in 0..=i {
                let bj = &basis.b_phi[j * r..(j + 1) * r];
                let v: c64 = (0..r).map(|c| self.d[c] * (bi[c] * bj[c])).sum();
                g[i * nc + j] = v;
                g[j * nc + i] = v;
            }
        }
        g
    }

    /// Whether this factor's basis formed BΦ for `b`.
    pub fn built_for(&self, b: &Csc) -> bool {
        self.basis.built_for(b)
    }
}
