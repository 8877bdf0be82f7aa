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
//! - its 2rM eigenvalues are the r·2 physical exponents, each repeated at s + imω: the copies
//!   kept are those whose eigenvector is centred on harmonic 0 (the weighted harmonic index
//!   κ = Σ k(|c₊ₖ|² − |c₋ₖ|²)/Σ|c|² within `CENTRED` of 0, c±ₖ the exponential
//!   coefficients), which the truncation to H harmonics resolves best;
//! - P(σ) = K̂ + σĈ + σ²I = D(σ) + U J₀⁻¹ R, the Hill operator at a real shift, solved by
//!   Woodbury through the closed nodes (`ShiftedSolve`);
//! - multipliers μ = e^{sT}.
//!
//! The verdict belongs to the discrete model whose state is reported (the same H, N, c and
//! compliance): where the harmonic balance is coarse the verdict is that of the coarse model,
//! and the harmonic ladder of the solve says whether the state itself has converged.

mod arnoldi;

use std::sync::Arc;

use faer::{c64, Mat};
use nalgebra::DMatrix;

use super::basis::TimeBasis;
use super::floquet::Multipliers;
use super::fourier::{cos_index, sin_index};
use super::sampler::ContactSampler;
use super::{ContactSolution, Spin, System};
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
/// nearest the shift `SHIFT` by shift-invert Arnoldi.
pub const DENSE: usize = 240;

/// Hill matrices up to this order get every eigenvalue when Arnoldi finds no centred exponent.
pub const DENSE_FALLBACK: usize = 1200;

/// Arnoldi steps, plus 4 per dynamic mode (the strip holds 2r exponents): on the coarse strip
/// sweep 60 + 4r and 200 + 10r steps gave the dense eigenvalues' leading multiplier on all 28
/// rows checked, 30 + 3r missed it on 11. 30 + 4r gives the leading multiplier of 60 + 4r
/// within 7e-6 on every row of the coarse strip sweep (223 rows), within 2e-9 on the
/// cantilever against its stop and 3e-8 on the vibro-impact bar (`pipelines/scenes/`), at
/// half the cost; 20 + 4r and 40 + 3r move it by up to 0.11 and 0.04.
const KRYLOV: usize = 30;

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
    /// Dense up to `DENSE`, Arnoldi beyond (dense up to `DENSE_FALLBACK` where Arnoldi finds
    /// no centred exponent).
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
    /// A frame whose speed follows ω (its centrifugal load left out): θ_j at ω is θ_j + s,
    /// s = `Spin::shift` (the modes of K + sM are those of K).
    spin: Option<Spin>,
    /// Φ, the modes on the free dofs (empty for a model built from its parts; the first r
    /// are kept dynamic), shared by the truncated models: what maps a Floquet vector's modal
    /// coordinates to the structure (`FloquetVector::coefficients`).
    phi: Arc<Vec<Vec<f64>>>,
}

/// The leading exponent's Floquet vector: a perturbation grows as Re(e^{st} p(t)),
/// p(t) = Σ_j φ_j q̃_j(t) over the r modes kept dynamic. Cheap to keep (q̃ and a shared Φ);
/// `coefficients` forms it on the structure.
#[derive(Clone, Debug)]
pub struct FloquetVector {
    pub exponent: c64,
    pub harmonics: usize,
    /// q̃, r modes × M coefficients (real Fourier layout of `fourier`).
    modal: Vec<c64>,
    phi: Arc<Vec<Vec<f64>>>,
}

impl FloquetVector {
    /// p's coefficients in the real Fourier layout (M = 2H + 1 complex vectors on the free
    /// dofs), p_c = Σ_j φ_j q̃_{j,c}, scaled so that the largest entry has modulus 1.
    pub fn coefficients(&self) -> Vec<Vec<c64>> {
        let m = 2 * self.harmonics + 1;
        let n = self.phi.first().map_or(0, Vec::len);
        let mut coefficients = vec![vec![c64::new(0.0, 0.0); n]; m];
        for (j, phi) in self.phi.iter().take(self.modal.len() / m).enumerate() {
            for (c, field) in coefficients.iter_mut().enumerate() {
                let a = self.modal[j * m + c];
                field.iter_mut().zip(phi).for_each(|(f, p)| *f += a * *p);
            }
        }
        let largest = coefficients
            .iter()
            .flatten()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        if largest > 0.0 && largest.is_finite() {
            coefficients
                .iter_mut()
                .flatten()
                .for_each(|z| *z /= largest);
        }
        coefficients
    }
}

impl HillModel {
    /// The `modes` lowest modes of `system` (free dofs) seen through the contact operator `b`
    /// (a sweep's model, for every frequency it passes).
    pub fn new(system: &System, b: &Csc, modes: usize) -> Result<HillModel> {
        super::floquet::refuse_gyroscopic(system)?;
        let (k, m) = (&system.k_ff, &system.m_ff);
        let massive = (0..m.ncols)
            .filter(|&j| (m.col_ptr[j]..m.col_ptr[j + 1]).any(|p| m.values[p] != 0.0))
            .count();
        let count = modes.min(massive);
        let found = crate::fem::modes::lowest_modes(k, m, count, 0.0)?;
        HillModel::with_modes(system, b, &found)
    }

    /// The model of `system` seen through `b` on the open structure's modes `found` (ω², φ),
    /// ascending: for a state at ω, `band_modes(system, ω)`.
    pub fn with_modes(
        system: &System,
        b: &Csc,
        found: &[crate::fem::modes::Mode],
    ) -> Result<HillModel> {
        super::floquet::refuse_gyroscopic(system)?;
        let rows = super::floquet::b_rows(b);
        let theta: Vec<f64> = found.iter().map(|(w2, _)| *w2).collect();
        let phi = Arc::new(found.iter().map(|(_, v)| v.clone()).collect());
        let e = DMatrix::from_fn(rows.len(), found.len(), |i, j| {
            crate::linalg::dot(&rows[i], &found[j].1)
        });
        let (alpha, beta) = system.rayleigh.unwrap_or((0.0, 0.0));
        let spin = Self::spin_of(system);
        Ok(HillModel {
            theta,
            e,
            alpha,
            beta,
            spin,
            phi,
        })
    }

    /// The modes a state at ω keeps dynamic (`modes_for`) and the next one above them: those
    /// below `BAND`·ω (a following speed's softening taken into account), at least
    /// `MIN_MODES`, at most `MODES`.
    pub fn band_modes(system: &System, omega: f64) -> Result<Vec<crate::fem::modes::Mode>> {
        let softening = Self::spin_of(system).map_or(0.0, |s| s.shift(omega).0);
        let bound = (BAND * omega).powi(2) - softening.min(0.0);
        crate::fem::modes::modes_below(
            (&system.k_ff, &system.m_ff),
            bound,
            (MIN_MODES, MODES),
            None,
        )
    }

    /// The model of a following speed's spin softening (`None` without rotation).
    fn spin_of(system: &System) -> Option<Spin> {
        system.spin.as_ref().map(|s| Spin {
            turns: s.turns,
            reference: s.reference,
            softening: s.softening,
            centrifugal: None,
        })
    }

    /// A model from its parts: θ of the kept modes, E = BΦ (contact nodes × r), (α, β).
    pub fn from_parts(theta: Vec<f64>, e: DMatrix<f64>, (alpha, beta): (f64, f64)) -> HillModel {
        HillModel {
            theta,
            e,
            alpha,
            beta,
            spin: None,
            phi: Arc::new(Vec::new()),
        }
    }

    /// r, the modes kept dynamic.
    pub fn dim(&self) -> usize {
        self.theta.len()
    }

    /// The shift of every θ_j at ω (zero unless the speed follows ω).
    fn shift(&self, omega: f64) -> f64 {
        self.spin.as_ref().map_or(0.0, |s| s.shift(omega).0)
    }

    /// The model at ω keeping its `r` lowest modes dynamic (a following speed's spin
    /// softening applied at ω).
    pub fn truncated(&self, r: usize, omega: f64) -> HillModel {
        let r = r.min(self.dim());
        let shift = self.shift(omega);
        HillModel {
            theta: self.theta[..r].iter().map(|t| t + shift).collect(),
            e: self.e.columns(0, r).into_owned(),
            alpha: self.alpha,
            beta: self.beta,
            spin: None,
            phi: Arc::clone(&self.phi),
        }
    }

    /// The Floquet vector of exponent `s` whose modal part is `q` (r × M); `None` without Φ.
    fn floquet_vector(&self, s: c64, q: Vec<c64>, h: usize) -> Option<FloquetVector> {
        let (r, m) = (self.dim(), 2 * h + 1);
        if self.phi.len() < r || q.len() != r * m {
            return None;
        }
        Some(FloquetVector {
            exponent: s,
            harmonics: h,
            modal: q,
            phi: Arc::clone(&self.phi),
        })
    }

    /// How many of the modes a state at ω with H harmonics keeps dynamic: those below
    /// `BAND`·ω (at least `MIN_MODES`, at most `MODES`: `band_modes`'s last one only bounds
    /// the others), within the budget 2rM ≤ `ORDER`.
    pub fn modes_for(&self, omega: f64, harmonics: usize) -> usize {
        let m = 2 * harmonics + 1;
        let shift = self.shift(omega);
        let in_band = self
            .theta
            .iter()
            .filter(|&&t| (t + shift).max(0.0).sqrt() <= BAND * omega)
            .count();
        let budget = (ORDER / (2 * m)).max(1);
        in_band.clamp(MIN_MODES, MODES).min(budget).min(self.dim())
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
        let (r, m) = (self.dim(), 2 * h + 1);
        let dense = match eigen {
            Eigen::Auto => 2 * r * m <= DENSE,
            Eigen::Dense => true,
            Eigen::Arnoldi => false,
        };
        let law = Linearized {
            j0,
            c: law.c,
            closed: &closed,
            blocks: &blocks,
        };
        let all = || -> Result<Vec<Exponent>> {
            let stiffness = self.stiffness(self.coupling(&law, h)?, omega, h);
            physical_exponents(&self.hill_matrix(&stiffness, omega, h), r, h, omega)
        };
        let exponents = match (dense, eigen) {
            (true, _) => all()?,
            // Arnoldi finds the copies nearest its shift; where the dynamic modes lie far above
            // it (a drive well below them, or many harmonics) none of those is centred: the
            // strips of the modes' own frequencies then, and where those find none either,
            // every eigenvalue of a Hill matrix of moderate order.
            (false, Eigen::Auto) => match self.rightmost_exponents(&law, omega, h) {
                Err(_) => match self.exponents_by_mode_strips(&law, omega, h) {
                    Err(_) if 2 * r * m <= DENSE_FALLBACK => all()?,
                    found => found?,
                },
                Ok(found) => found,
            },
            (false, _) => self.rightmost_exponents(&law, omega, h)?,
        };
        let period = 2.0 * std::f64::consts::PI / omega;
        let mut exponents = real_at_half(exponents, omega);
        let multiplier = |s: &c64| {
            let m = (s.re * period).exp();
            c64::new(m * (s.im * period).cos(), m * (s.im * period).sin())
        };
        exponents.sort_by(|a, b| multiplier(&b.0).norm().total_cmp(&multiplier(&a.0).norm()));
        let values: Vec<c64> = exponents.iter().map(|(s, _)| multiplier(s)).collect();
        if !values.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
            return Err(Error::Model(
                "Hill's method: a multiplier is not finite".into(),
            ));
        }
        let leading = exponents.into_iter().next();
        Ok(Multipliers {
            values,
            segments,
            leading_vector: leading.and_then(|(s, q)| self.floquet_vector(s, q, h)),
        })
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
    fn coupling(&self, law: &Linearized, h: usize) -> Result<Mat<f64>> {
        use faer::linalg::solvers::Solve;
        let Linearized {
            j0,
            c,
            closed,
            blocks,
        } = law;
        let (c, na, m, r) = (*c, closed.len(), 2 * h + 1, self.dim());
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

    /// K̂ = Δ² + c_jΔ + θ_j + Ẽᵀ L on the modal coefficients (rM square, mode-major), made
    /// from the coupling Ẽᵀ L in place.
    fn stiffness(&self, mut coupling: Mat<f64>, omega: f64, h: usize) -> Mat<f64> {
        let m = 2 * h + 1;
        for j in 0..self.dim() {
            let cj = self.alpha + self.beta * self.theta[j];
            let base = j * m;
            coupling[(base, base)] += self.theta[j];
            for k in 1..=h {
                let kw = k as f64 * omega;
                let (ic, is) = (base + cos_index(k), base + sin_index(k));
                // Δ[cos, sin] = kω, Δ[sin, cos] = −kω; Δ² = −k²ω².
                coupling[(ic, ic)] += self.theta[j] - kw * kw;
                coupling[(is, is)] += self.theta[j] - kw * kw;
                coupling[(ic, is)] += cj * kw;
                coupling[(is, ic)] -= cj * kw;
            }
        }
        coupling
    }

    /// Adds `scale`·Ĉ, Ĉ = 2Δ + c_j on the modal coefficients, to `target` (rM square).
    fn add_damping(&self, mut target: faer::MatMut<'_, f64>, scale: f64, omega: f64, h: usize) {
        let m = 2 * h + 1;
        for j in 0..self.dim() {
            let cj = scale * (self.alpha + self.beta * self.theta[j]);
            let base = j * m;
            target[(base, base)] += cj;
            for k in 1..=h {
                let kw2 = scale * 2.0 * k as f64 * omega;
                let (ic, is) = (base + cos_index(k), base + sin_index(k));
                target[(ic, ic)] += cj;
                target[(is, is)] += cj;
                target[(ic, is)] += kw2;
                target[(is, ic)] -= kw2;
            }
        }
    }

    /// The Hill matrix [[0, ωI], [−K̂/ω, −Ĉ]] on (q̃, v/ω), 2rM square: the first-order form
    /// scaled so both rows of blocks are of the size of the exponents. Unscaled, K̂ (up to
    /// (`BAND`·ω)²) dwarfs the identity, and the dense eigenvalues moved the phase of a
    /// multiplier by 1e-6 when θ moved by 3e-13.
    fn hill_matrix(&self, stiffness: &Mat<f64>, omega: f64, h: usize) -> Mat<f64> {
        let n = stiffness.nrows();
        let mut a = Mat::<f64>::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = omega;
        }
        a.as_mut()
            .submatrix_mut(n, 0, n, n)
            .copy_from(stiffness.as_ref() * faer::Scale(-1.0 / omega));
        self.add_damping(a.as_mut().submatrix_mut(n, n, n, n), -1.0, omega, h);
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

/// An eigenpair as the copies are told apart: |κ|, the exponent s and the eigenvector's modal
/// part q̃ (r modes × M coefficients).
type Ranked = (f64, c64, Vec<c64>);

/// An exponent with its eigenvector's modal part.
type Exponent = (c64, Vec<c64>);

/// The 2r exponents whose eigenvectors centre on harmonic 0, from the Hill matrix `a`.
fn physical_exponents(a: &Mat<f64>, r: usize, h: usize, omega: f64) -> Result<Vec<Exponent>> {
    let (s, u) = crate::linalg::eigen_real(a.as_ref())
        .map_err(|e| Error::Model(format!("Hill's method: {e}")))?;
    let m = 2 * h + 1;
    let ranked: Vec<Ranked> = (0..a.nrows())
        .map(|i| {
            let col: Vec<c64> = (0..r * m).map(|q| u[(q, i)]).collect();
            (kappa(&col, r, m, h), s[i], col)
        })
        .collect();
    Ok(centred(ranked, omega))
}

/// The largest |κ| of a copy taken as centred. The copies s + ikω of one exponent have κ
/// about κ₀ + k, so one of them lies within ½ of harmonic 0; near a period doubling two do
/// (s and s − iω, |κ| ≈ ½ each, the same multiplier), and the truncation moves κ by a few
/// hundredths. The copies further out are the truncation's less resolved ones: on the coarse
/// strip sweep (H = 10) taking copies up to |κ| = H/2 made the leading multiplier depend on
/// how many Arnoldi steps were run (0.85 with 112 steps, 0.71 with 330 at 1134 Hz), and
/// taking the 2r smallest |κ| dropped the near-period-doubling pair whenever 2r other
/// exponents had a smaller |κ| (0.71 at 1030 Hz where the same pair is 0.85 at H = 20 and
/// 0.81 at H = 40).
const CENTRED: f64 = 0.6;

/// The exponents whose copy is centred (|κ| ≤ `CENTRED`), each once.
fn centred(ranked: Vec<Ranked>, omega: f64) -> Vec<Exponent> {
    let mut kept: Vec<Exponent> = Vec::new();
    for (k, s, q) in ranked {
        if k <= CENTRED && !kept.iter().any(|(t, _)| (t - s).norm() <= 1e-8 * omega) {
            kept.push((s, q));
        }
    }
    kept
}

/// How far from κ = ½ (in harmonics) a lone conjugate pair of exponents is still one real
/// negative multiplier blurred by the truncation, and how close (in σT and κ) a mirror copy
/// must lie to make it a complex pair instead.
const HALF_BLUR: f64 = 0.02;
const MIRROR: f64 = 0.01;

/// A real negative multiplier −e^{σT} has the exponents σ + iω/2 + ikω: its two centred
/// copies σ ± iω/2 are conjugates, and the truncation to H harmonics moves them to
/// σ ± i(½ + ε)ω. A complex pair near −1, −e^{σT}e^{±iδT}, has four centred copies,
/// σ ± i(½ ± δ/ω)ω, at one σ. So a conjugate pair within `HALF_BLUR` of κ = ½ with no mirror
/// copy σ ± i(½ − ε)ω is put back on ±iω/2 (a real multiplier, whose crossing is a period
/// doubling); measured on the coarse strip at 1053.3 Hz: ε = 0.0090 at H = 10, 0.0010 at
/// H = 20, while the complex pairs there keep both copies (κ 0.533 and 0.467, σT within
/// 0.002).
fn real_at_half(exponents: Vec<Exponent>, omega: f64) -> Vec<Exponent> {
    let period = 2.0 * std::f64::consts::PI / omega;
    let kappa = |s: &c64| s.im.abs() / omega;
    let mirrored = |s: &c64| {
        exponents.iter().any(|(t, _)| {
            ((t.re - s.re) * period).abs() < MIRROR
                && (kappa(t) - (1.0 - kappa(s))).abs() < MIRROR
                && (kappa(t) - kappa(s)).abs() > MIRROR
        })
    };
    let moved: Vec<c64> = (exponents.iter())
        .map(|(s, _)| {
            if (kappa(s) - 0.5).abs() < HALF_BLUR && !mirrored(s) {
                c64::new(s.re, 0.5 * omega * s.im.signum())
            } else {
                *s
            }
        })
        .collect();
    moved
        .into_iter()
        .zip(exponents)
        .map(|(s, (_, q))| (s, q))
        .collect()
}

/// The sampled contact law linearized about a state, on the nodes it ever closes.
struct Linearized<'a> {
    /// J₀ = I + Q D P (c R̃ − I) (node-major over `closed`, M per node).
    j0: Mat<f64>,
    c: f64,
    closed: &'a [usize],
    /// Q D P per contact node (M × M row-major; empty when never closed).
    blocks: &'a [Vec<f64>],
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
