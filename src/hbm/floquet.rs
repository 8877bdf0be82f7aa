//! Floquet multipliers of a harmonic-balance contact state, on the scene's own discrete model
//! (docs/method.md, "Stability: Floquet multipliers").
//!
//! Formulas and glossary:
//! - K, M (diagonal; the contact nodes massless after mass redistribution), D = αM + βK on
//!   the free dofs; B the contact normals (n_c × free);
//! - φ_q, θ_q = ω_q² the `MODES` lowest modes of the open structure (every contact open),
//!   φᵀMφ = 1: the motion the perturbation may have, δu = Σ φ_q y_q + (static rest);
//! - E = BΦ (the modes' gaps), G = B K⁻¹ Bᵀ − E Θ⁻¹ Eᵀ the residual compliance: the higher
//!   modes answer the contact forces statically (they lie above the band the modes cover);
//! - node j is closed at the contact law's time sample t_n when c g_j − λ_j > 0 (the note's
//!   (21) then says g_j = 0, so δg_j = 0), open otherwise (δλ_j = 0); the closed set A_n holds
//!   over the sample's share T/N of the period, centred on t_n;
//! - closed A: δg_A = E_A y + G_AA δλ_A = 0, so δλ_A = −G_AA⁻¹ E_A y and
//!   ÿ + (α + βK_A) ẏ + K_A y = 0 with K_A = Θ + E_Aᵀ G_AA⁻¹ E_A = Q Λ Qᵀ, decoupled into
//!   scalar oscillators ÿ + c_k ẏ + Λ_k y = 0 (c_k = α + βΛ_k), exact over a segment of
//!   constant A (`transition`);
//! - the monodromy Φ_T = Π_s exp(A_s τ_s) (later segments on the left), its eigenvalues the
//!   Floquet multipliers μ: every |μ| < 1, asymptotically stable; one |μ| > 1, unstable, lost
//!   through +1 (fold), −1 (period doubling: a motion at half the drive frequency) or as a
//!   complex pair (Neimark–Sacker: a second frequency |arg μ|/(2π)·f);
//! - no saltation: the contact nodes carry no mass, so the contact force starts and ends at
//!   zero and the state is continuous when a node closes or opens.
//!
//! With β ≠ 0 the stiffness-proportional damping acts on the modal model (βK_A), the static
//! rest is undamped. Why static above the modes: with dynamic attachment vectors instead (a
//! Craig–Bampton-like basis) the leading multiplier of the reference strip moved between
//! 0.80 and 3.0 as the basis grew (parametric excitation of the contact's local pseudo-modes,
//! far above the band the harmonic balance resolves); with the static rest it settles (16
//! and 32 modes: 0.826/0.825 at H = 10, 0.779/0.797 at H = 20, 0.804/0.810 at H = 40).

use std::collections::HashMap;

use faer::c64;
use nalgebra::{Cholesky, DMatrix, DVector, SymmetricEigen};

use super::basis::TimeBasis;
use super::sampler::evaluate;
use super::{ContactSolution, System};
use crate::linalg::{Csc, LuPattern, SparseLu};
use crate::{Error, Result};

/// Modes of the open structure kept dynamic (the rest answers statically).
pub const MODES: usize = 16;

/// |μ| within 1 ± this decides nothing: a multiplier on the unit circle (undamped, or at a
/// bifurcation).
pub const MARGIN: f64 = 1e-6;

/// A multiplier with |Im μ| below this fraction of |μ| is real (Hill's method splits a real
/// multiplier into a pair 1e-5 apart: its two exponent copies σ ± iω/2 are computed apart).
const REAL: f64 = 1e-3;

/// The closed contact nodes over one part of the period: (node indices, duration [s]).
pub type Segment = (Vec<usize>, f64);

/// How the leading multiplier leaves (or would leave) the unit circle.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Crossing {
    /// Real, through +1: a fold of the branch.
    Fold,
    /// Real, through −1: a period doubling (a motion at half the drive frequency).
    PeriodDoubling,
    /// A complex pair: a Neimark–Sacker bifurcation (a second, incommensurate frequency).
    NeimarkSacker,
}

impl Crossing {
    pub fn describe(self) -> &'static str {
        match self {
            Crossing::Fold => "a real multiplier through +1 (a fold)",
            Crossing::PeriodDoubling => {
                "a real multiplier through −1 (a period doubling: motion at half the drive frequency)"
            }
            Crossing::NeimarkSacker => {
                "a complex pair (a Neimark–Sacker bifurcation: a second frequency)"
            }
        }
    }
}

/// The multipliers of one state.
#[derive(Clone, Debug)]
pub struct Multipliers {
    /// Every multiplier, largest modulus first.
    pub values: Vec<c64>,
    /// Segments of constant closed set over the period.
    pub segments: usize,
    /// Hill's method: the leading multiplier's Floquet vector on the structure.
    pub leading_vector: Option<super::hill::FloquetVector>,
}

impl Multipliers {
    /// The multiplier of largest modulus.
    pub fn leading(&self) -> c64 {
        self.values.first().copied().unwrap_or(c64::new(0.0, 0.0))
    }

    /// How the leading multiplier crosses (or would cross) the unit circle.
    pub fn crossing(&self) -> Crossing {
        let mu = self.leading();
        if mu.im.abs() <= REAL * mu.norm() {
            if mu.re >= 0.0 {
                Crossing::Fold
            } else {
                Crossing::PeriodDoubling
            }
        } else {
            Crossing::NeimarkSacker
        }
    }
}

/// The reduced linearization of a scene about its contact states (independent of the state
/// and of ω: built once for a run or a whole sweep).
pub struct FloquetModel {
    /// The contact nodes that may close (ascending).
    nodes: Vec<usize>,
    /// θ_q = ω_q², the kept modes'.
    theta: Vec<f64>,
    /// E = BΦ on `nodes`, |nodes| × r.
    e: DMatrix<f64>,
    /// G, the residual compliance on `nodes`.
    g: DMatrix<f64>,
    alpha: f64,
    beta: f64,
}

/// The free dofs without mass, from a diagonal M (an error otherwise).
fn massless_dofs(m: &Csc) -> Result<Vec<bool>> {
    let mut massless = vec![true; m.ncols];
    for (j, free) in massless.iter_mut().enumerate() {
        for p in m.col_ptr[j]..m.col_ptr[j + 1] {
            if m.values[p] != 0.0 {
                if m.row_idx[p] != j {
                    return Err(Error::Model(
                        "Floquet multipliers need a diagonal mass (contact.mass: redistributed)"
                            .into(),
                    ));
                }
                *free = false;
            }
        }
    }
    Ok(massless)
}

/// An error unless every dof B acts on is massless.
fn check_massless_contact(b: &Csc, massless: &[bool]) -> Result<()> {
    let massive_contact = massless.iter().enumerate().any(|(j, &without)| {
        !without && (b.col_ptr[j]..b.col_ptr[j + 1]).any(|p| b.values[p] != 0.0)
    });
    if massive_contact {
        return Err(Error::Model(
            "Floquet multipliers need massless contact nodes (contact.mass: redistributed): with mass at the contact nodes impacts need saltation matrices".into(),
        ));
    }
    Ok(())
}

/// G = B K⁻¹ Bᵀ − E Θ⁻¹ Eᵀ on `nodes` (`bt` the rows of B): the compliance the modes leave.
fn residual_compliance(
    k: &Csc,
    bt: &[Vec<f64>],
    nodes: &[usize],
    theta: &[f64],
    e: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let mut g = DMatrix::zeros(nodes.len(), nodes.len());
    if nodes.is_empty() {
        return Ok(g);
    }
    let lu = SparseLu::factor_real(&LuPattern::analyse(k)?, k)?;
    for (jj, &j) in nodes.iter().enumerate() {
        let rhs: Vec<c64> = bt[j].iter().map(|&v| c64::new(v, 0.0)).collect();
        let x: Vec<f64> = lu.solve(&rhs).iter().map(|z| z.re).collect();
        for (ii, &i) in nodes.iter().enumerate() {
            g[(ii, jj)] = crate::linalg::dot(&bt[i], &x);
        }
    }
    for (q, th) in theta.iter().enumerate() {
        let col = e.column(q);
        g -= col * col.transpose() / *th;
    }
    Ok((&g + g.transpose()) * 0.5)
}

impl FloquetModel {
    /// The reduction of `system` (free dofs, diagonal mass with massless contact dofs) for
    /// the contact operator `b` (n_c × free) and the contact nodes `nodes` that may close.
    pub fn new(system: &System, b: &Csc, nodes: &[usize]) -> Result<FloquetModel> {
        refuse_gyroscopic(system)?;
        let (k, m) = (&system.k_ff, &system.m_ff);
        let massless = massless_dofs(m)?;
        check_massless_contact(b, &massless)?;
        let massive = massless.iter().filter(|&&z| !z).count();
        let modes = crate::fem::modes::modes_near(k, m, MODES.min(massive), 0.0, None)?;
        let bt = b_rows(b);
        let theta: Vec<f64> = modes.iter().map(|(w2, _)| *w2).collect();
        let e = DMatrix::from_fn(nodes.len(), modes.len(), |i, j| {
            crate::linalg::dot(&bt[nodes[i]], &modes[j].1)
        });
        let g = residual_compliance(k, &bt, nodes, &theta, &e)?;
        let (alpha, beta) = system.rayleigh.unwrap_or((0.0, 0.0));
        Ok(FloquetModel {
            nodes: nodes.to_vec(),
            theta,
            e,
            g,
            alpha,
            beta,
        })
    }

    /// A model from its parts (tests, and scenes reduced elsewhere): the kept modes' θ, their
    /// gaps E = BΦ on `nodes` (|nodes| × r), the residual compliance G on `nodes`, and the
    /// Rayleigh coefficients.
    pub fn from_parts(
        nodes: Vec<usize>,
        theta: Vec<f64>,
        e: DMatrix<f64>,
        g: DMatrix<f64>,
        (alpha, beta): (f64, f64),
    ) -> FloquetModel {
        FloquetModel {
            nodes,
            theta,
            e,
            g,
            alpha,
            beta,
        }
    }

    /// r, the reduced dimension.
    pub fn dim(&self) -> usize {
        self.theta.len()
    }

    /// The monodromy matrix over the `segments` (in time order), on (y, ẏ).
    pub fn monodromy(&self, segments: &[Segment]) -> Result<DMatrix<f64>> {
        let r = self.dim();
        let mut phi = DMatrix::<f64>::identity(2 * r, 2 * r);
        let mut cache: HashMap<Vec<usize>, (DMatrix<f64>, Vec<f64>)> = HashMap::new();
        for (closed, tau) in segments {
            if !cache.contains_key(closed) {
                let eig = self.closed_stiffness(closed)?;
                cache.insert(closed.clone(), eig);
            }
            let (q, lambda) = &cache[closed];
            phi = self.advance(q, lambda, *tau, &phi);
        }
        Ok(phi)
    }

    /// The multipliers over the `segments`, largest modulus first.
    pub fn multipliers(&self, segments: &[Segment]) -> Result<Multipliers> {
        let phi = self.monodromy(segments)?;
        if !phi.iter().all(|v| v.is_finite()) {
            return Err(Error::Model(
                "Floquet: the monodromy matrix is not finite".into(),
            ));
        }
        let mut values: Vec<c64> = phi
            .complex_eigenvalues()
            .iter()
            .map(|z| c64::new(z.re, z.im))
            .collect();
        values.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
        Ok(Multipliers {
            values,
            segments: segments.len(),
            leading_vector: None,
        })
    }

    /// Q, Λ of K_A = diag(θ) + E_Aᵀ G_AA⁻¹ E_A for the closed nodes `closed`.
    fn closed_stiffness(&self, closed: &[usize]) -> Result<(DMatrix<f64>, Vec<f64>)> {
        let r = self.dim();
        let mut ka = DMatrix::from_diagonal(&DVector::from_vec(self.theta.clone()));
        if !closed.is_empty() {
            let rows: Vec<usize> = closed
                .iter()
                .map(|n| self.nodes.binary_search(n))
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| Error::Model("internal: Floquet basis lacks a closed node".into()))?;
            let ea = DMatrix::from_fn(rows.len(), r, |i, j| self.e[(rows[i], j)]);
            let gaa = DMatrix::from_fn(rows.len(), rows.len(), |i, j| self.g[(rows[i], rows[j])]);
            let x = Cholesky::new(gaa)
                .ok_or_else(|| Error::Model("Floquet: contact compliance not definite".into()))?
                .solve(&ea);
            ka += ea.transpose() * x;
        }
        let ka = (&ka + ka.transpose()) * 0.5;
        let eig = SymmetricEigen::new(ka);
        Ok((eig.eigenvectors, eig.eigenvalues.iter().copied().collect()))
    }

    /// exp(A τ) Φ for the segment with K_A = Q diag(Λ) Qᵀ.
    fn advance(
        &self,
        q: &DMatrix<f64>,
        lambda: &[f64],
        tau: f64,
        phi: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        let r = self.dim();
        let top = q.transpose() * phi.rows(0, r);
        let bottom = q.transpose() * phi.rows(r, r);
        let (mut new_top, mut new_bottom) = (DMatrix::zeros(r, 2 * r), DMatrix::zeros(r, 2 * r));
        for k in 0..r {
            let t = transition(lambda[k], self.alpha + self.beta * lambda[k], tau);
            for j in 0..2 * r {
                new_top[(k, j)] = t[0] * top[(k, j)] + t[1] * bottom[(k, j)];
                new_bottom[(k, j)] = t[2] * top[(k, j)] + t[3] * bottom[(k, j)];
            }
        }
        let mut out = DMatrix::zeros(2 * r, 2 * r);
        out.rows_mut(0, r).copy_from(&(q * new_top));
        out.rows_mut(r, r).copy_from(&(q * new_bottom));
        out
    }
}

/// The rows of B as dense free-dof vectors.
pub(super) fn b_rows(b: &Csc) -> Vec<Vec<f64>> {
    let mut rows = vec![vec![0.0; b.ncols]; b.nrows];
    for (j, window) in b.col_ptr.windows(2).enumerate() {
        for p in window[0]..window[1] {
            rows[b.row_idx[p]][j] += b.values[p];
        }
    }
    rows
}

/// [y(τ), ẏ(τ)] = T [y(0), ẏ(0)] of ÿ + c ẏ + λ y = 0, row-major: with μ = c/2, d = λ − μ²,
/// C = cos(√d τ), S = sin(√d τ)/√d (cosh, sinh for d < 0, their series near d = 0),
/// T = e^{−μτ} [[C + μS, S], [−λS, C − μS]].
pub fn transition(lambda: f64, c: f64, tau: f64) -> [f64; 4] {
    let mu = 0.5 * c;
    let d = lambda - mu * mu;
    let x = d * tau * tau;
    let (cc, s) = if x.abs() < 1e-4 {
        (
            1.0 - x / 2.0 + x * x / 24.0,
            tau * (1.0 - x / 6.0 + x * x / 120.0),
        )
    } else if d > 0.0 {
        let nu = d.sqrt();
        ((nu * tau).cos(), (nu * tau).sin() / nu)
    } else {
        let kappa = (-d).sqrt();
        ((kappa * tau).cosh(), (kappa * tau).sinh() / kappa)
    };
    let e = (-mu * tau).exp();
    [e * (cc + mu * s), e * s, -e * lambda * s, e * (cc - mu * s)]
}

/// The closed nodes at the contact law's N uniform instants t_n = nT/N (c g − λ > 0 there),
/// merged into segments of constant closed set, each sample holding over [t_n − T/2N,
/// t_n + T/2N); the period starts at −T/2N.
pub fn segments(basis: &TimeBasis, omega: f64, contact: &ContactSolution) -> Vec<Segment> {
    let n = contact.samples.max(1);
    let period = 2.0 * std::f64::consts::PI / omega;
    let width = period / n as f64;
    let m = contact.coefficients();
    let lambda: Vec<&[f64]> = contact.multipliers.chunks(m).collect();
    let gaps: Vec<&[f64]> = contact.gaps.chunks(m).collect();
    let mut out: Vec<Segment> = Vec::new();
    for s in 0..n {
        let t = s as f64 * width;
        let closed: Vec<usize> = (0..lambda.len())
            .filter(|&j| {
                let l = evaluate(basis, lambda[j], omega, t);
                let g = evaluate(basis, gaps[j], omega, t);
                contact.c * g - l > 0.0
            })
            .collect();
        match out.last_mut() {
            Some((last, tau)) if *last == closed => *tau += width,
            _ => out.push((closed, width)),
        }
    }
    out
}

/// The contact nodes closed in any of the segments, ascending.
pub fn closed_nodes<'a>(segments: impl IntoIterator<Item = &'a Segment>) -> Vec<usize> {
    let mut nodes: Vec<usize> = segments
        .into_iter()
        .flat_map(|(closed, _)| closed.iter().copied())
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    nodes
}

/// The modal Floquet models (this one and Hill's) keep each mode's damping to itself; the
/// Coriolis force couples the modes, so a gyroscopic system is refused (its states are then
/// judged by marching).
pub fn refuse_gyroscopic(system: &System) -> Result<()> {
    match system.gyroscopic {
        Some(_) => Err(Error::Model(
            "the Floquet models (Hill's and the monodromy's modal reduction) do not take the \
             Coriolis force yet"
                .into(),
        )),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: the scalar transition matches the closed forms of the under-, over- and
    /// critically damped oscillator, and composes: T(τ₁)T(τ₂) = T(τ₁ + τ₂) to 1e-12.
    #[test]
    fn the_scalar_transition_is_exact_and_composes() {
        for (lambda, c) in [(4.0, 0.4), (1.0, 3.0), (1.0, 2.0), (0.0, 0.5), (2.0, 0.0)] {
            let (a, b) = (transition(lambda, c, 0.3), transition(lambda, c, 0.7));
            let ab = [
                b[0] * a[0] + b[1] * a[2],
                b[0] * a[1] + b[1] * a[3],
                b[2] * a[0] + b[3] * a[2],
                b[2] * a[1] + b[3] * a[3],
            ];
            let whole = transition(lambda, c, 1.0);
            for k in 0..4 {
                assert!(
                    (ab[k] - whole[k]).abs() < 1e-12,
                    "λ {lambda} c {c}: {ab:?} {whole:?}"
                );
            }
        }
        // Undamped: cos and sin.
        let t = transition(4.0, 0.0, 0.25);
        assert!((t[0] - 0.5f64.cos()).abs() < 1e-15 && (t[1] - 0.5f64.sin() / 2.0).abs() < 1e-15);
    }
}
