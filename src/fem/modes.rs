//! Natural frequencies and mode shapes: K φ = ω² M φ on already-reduced (free-dof) matrices, by
//! shift-invert block Lanczos with full reorthogonalization and Rayleigh–Ritz (Golub & Van
//! Loan, Matrix Computations, §10.3; Ericsson & Ruhe's spectral transformation), and the modal
//! quantities an engineer reads next to them.
//!
//! Glossary:
//! - σ the shift (an ω²): the iteration converges first to the eigenvalues nearest σ;
//! - Q the M-orthonormal basis of the block Krylov space of (K − σM)⁻¹M, grown `BLOCK`
//!   vectors at a time; the Ritz pairs are those of QᵀKQ;
//! - r_d the influence vector of direction d (1 on every free dof of component d, 0 elsewhere);
//! - Γ_d = φᵀ M r_d / φᵀ M φ the participation factor, m_eff,d = (φᵀ M r_d)² / φᵀ M φ the
//!   effective modal mass; summed over all modes it is r_dᵀ M r_d, the mass the supports let
//!   move in d (Chopra, Dynamics of Structures, §13.2);
//! - ζ_n = α/(2ω_n) + β ω_n/2 the modal damping ratio of Rayleigh damping D = αM + βK.
//!
//! Used by `hbcontact modes`, by the resonance check of every run and by the tests against
//! beam theory.

use faer::c64;
use nalgebra::{DMatrix, SymmetricEigen};

use crate::linalg::{Csc, LuPattern, SparseLu};
use crate::{Error, Result};

/// An eigenpair (ω², φ) with φ M-normalized (φᵀ M φ = 1).
pub type Mode = (f64, Vec<f64>);

/// The `count` eigenpairs whose ω² lie nearest `shift` (on either side; 0 gives the lowest),
/// ascending in ω².
pub fn lowest_modes(k: &Csc, m: &Csc, count: usize, shift: f64) -> Result<Vec<Mode>> {
    let mut modes = block_krylov(k, m, count, shift, TOLERANCE, None)?;
    modes.truncate(count);
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes)
}

/// A quick look near `shift`: the `count` eigenpairs nearest it, their ω² settled to 1e-6
/// (frequencies to 5e-7), ascending in ω². For deciding
/// how near a frequency sits to a mode, at the cost of one factorization and a few dozen
/// solves; `pattern`, when given, is a symbolic analysis of K's pattern to reuse.
pub fn modes_near(
    k: &Csc,
    m: &Csc,
    count: usize,
    shift: f64,
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let mut modes = block_krylov(k, m, count, shift, 1e-6, pattern)?;
    modes.truncate(count);
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes)
}

/// K − σM on the common pattern of K and M (K's own when M shares it, as `System`'s do).
fn shifted(k: &Csc, m: &Csc, shift: f64) -> Result<Csc> {
    if k.col_ptr == m.col_ptr && k.row_idx == m.row_idx {
        let mut a = k.clone();
        a.values
            .iter_mut()
            .zip(&m.values)
            .for_each(|(v, w)| *v -= shift * w);
        return Ok(a);
    }
    let mut common = Csc::on_common_pattern(&[k, m]).into_iter();
    let (Some(mut a), Some(mm)) = (common.next(), common.next()) else {
        return Err(Error::Model("internal: modes pattern".into()));
    };
    for (v, w) in a.values.iter_mut().zip(&mm.values) {
        *v -= shift * w;
    }
    Ok(a)
}

/// Deterministic pseudo-random start vectors (`seed` shifts the sequence).
fn start_vectors(n: usize, p: usize, seed: usize) -> Vec<Vec<f64>> {
    (seed..seed + p)
        .map(|j| {
            (0..n)
                .map(|i| {
                    (((i * 7919 + j * 104_729) % 1000) as f64 / 1000.0) - 0.5
                        + if i % p.max(1) == j % p.max(1) {
                            1.0
                        } else {
                            0.0
                        }
                })
                .collect()
        })
        .collect()
}

/// Relative change of the Ritz values below which they count as converged (frequencies to
/// 5e-9: far below any discretization error).
const TOLERANCE: f64 = 1e-8;

/// Vectors per block of the Krylov space: a mode of multiplicity up to `BLOCK` is found with
/// all its copies (a single-vector Lanczos sees one direction of each eigenspace).
const BLOCK: usize = 6;

/// Block Lanczos with full reorthogonalization: an M-orthonormal basis Q of the block Krylov
/// space of (K − σM)⁻¹ M grows by `BLOCK` vectors at a time; Rayleigh–Ritz on span(Q) gives
/// the Ritz values, checked after each block, until the `count` nearest σ settle to
/// `tolerance` (or the space stops growing: then it holds every mode M can excite, and
/// its Ritz pairs are exact). Returns every Ritz pair ordered by distance to σ (nearest
/// first). The Krylov space converges where subspace iteration stalls on the ratio of the
/// wanted to the first unwanted eigenvalue: a few dozen solves instead of hundreds.
fn block_krylov(
    k: &Csc,
    m: &Csc,
    count: usize,
    shift: f64,
    tolerance: f64,
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let n = k.nrows;
    let count = count.min(n);
    let a = shifted(k, m, shift)?;
    let lu = match pattern {
        Some(pattern) => SparseLu::factor_real(pattern, &a)?,
        None => SparseLu::factor_real(&LuPattern::analyse(&a)?, &a)?,
    };
    let apply = |x: &[Vec<f64>]| -> Vec<Vec<f64>> {
        let rhs: Vec<Vec<c64>> = x
            .iter()
            .map(|col| {
                m.mul_vec(col)
                    .into_iter()
                    .map(|v| c64::new(v, 0.0))
                    .collect()
            })
            .collect();
        lu.solve_many(&rhs)
            .into_iter()
            .map(|col| col.into_iter().map(|z| z.re).collect())
            .collect()
    };
    let limit = (6 * count + 60).min(n);
    let mut space = MSpace::default();
    let mut block = apply(&start_vectors(n, BLOCK.min(n), 0));
    let mut previous: Vec<f64> = Vec::new();
    loop {
        let added = space.extend(k, m, block);
        if added.is_empty() || space.q.len() >= limit {
            break;
        }
        if space.q.len() >= count + BLOCK {
            let values = space.values_nearest(shift, count);
            let settled = values.len() == previous.len()
                && values
                    .iter()
                    .zip(&previous)
                    .all(|(a, b)| ((a - b) / a).abs() < tolerance);
            if settled {
                break;
            }
            previous = values;
        }
        block = apply(&added);
    }
    space.ritz_pairs(shift)
}

/// An M-orthonormal basis Q with M Q and the projection QᵀKQ kept beside it, grown a column
/// at a time (Rayleigh–Ritz without recomputing what earlier blocks gave).
#[derive(Default)]
struct MSpace {
    q: Vec<Vec<f64>>,
    mq: Vec<Vec<f64>>,
    /// QᵀKQ, row i the products of q_i with K q_0 … K q_i.
    kr: Vec<Vec<f64>>,
}

impl MSpace {
    /// Orthonormalize `y` against Q and itself (modified Gram–Schmidt, twice, in the M inner
    /// product) and append what is left; a column (numerically) in the span already is
    /// dropped. Returns the appended columns.
    fn extend(&mut self, k: &Csc, m: &Csc, y: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        let first = self.q.len();
        for mut col in y {
            let before = dot(&col, &m.mul_vec(&col)).max(0.0).sqrt();
            for _ in 0..2 {
                for (b, mb) in self.q.iter().zip(&self.mq) {
                    let c = dot(mb, &col);
                    col.iter_mut().zip(b).for_each(|(v, bv)| *v -= c * bv);
                }
            }
            let mcol = m.mul_vec(&col);
            let norm = dot(&col, &mcol).max(0.0).sqrt();
            if norm > 1e-10 * before && norm > 0.0 {
                col.iter_mut().for_each(|v| *v /= norm);
                self.mq.push(mcol.into_iter().map(|v| v / norm).collect());
                let kcol = k.mul_vec(&col);
                let mut row: Vec<f64> = self.q.iter().map(|qi| dot(qi, &kcol)).collect();
                row.push(dot(&col, &kcol));
                self.kr.push(row);
                self.q.push(col);
            }
        }
        self.q[first..].to_vec()
    }

    /// The symmetric eigen-decomposition of QᵀKQ (the Ritz problem: Q is M-orthonormal).
    fn projected(&self) -> SymmetricEigen<f64, nalgebra::Dyn> {
        let p = self.q.len();
        let kr = DMatrix::from_fn(p, p, |i, j| self.kr[i.max(j)][i.min(j)]);
        SymmetricEigen::new(kr)
    }

    /// The `count` Ritz values nearest σ, nearest first.
    fn values_nearest(&self, shift: f64, count: usize) -> Vec<f64> {
        let mut values: Vec<f64> = self.projected().eigenvalues.iter().copied().collect();
        values.sort_by(|a, b| (a - shift).abs().total_cmp(&(b - shift).abs()));
        values.truncate(count);
        values
    }

    /// Every Ritz pair, nearest σ first, the vectors M-orthonormal.
    fn ritz_pairs(&self, shift: f64) -> Result<Vec<Mode>> {
        let n = self.q.first().map_or(0, Vec::len);
        if self.q.is_empty() {
            return Err(Error::Model(
                "mode extraction: the mass matrix is zero on every trial vector (massless dofs?)"
                    .into(),
            ));
        }
        let eig = self.projected();
        let mut pairs: Vec<Mode> = (0..self.q.len())
            .map(|c| {
                let mut v = vec![0.0; n];
                for (r, qr) in self.q.iter().enumerate() {
                    let w = eig.eigenvectors[(r, c)];
                    v.iter_mut().zip(qr).for_each(|(vi, qi)| *vi += w * qi);
                }
                (eig.eigenvalues[c], v)
            })
            .collect();
        pairs.sort_by(|a, b| (a.0 - shift).abs().total_cmp(&(b.0 - shift).abs()));
        Ok(pairs)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The modal damping ratio ζ = α/(2ω) + βω/2 of Rayleigh damping at angular frequency ω
/// (0 without damping).
pub fn rayleigh_damping_ratio(rayleigh: Option<(f64, f64)>, omega: f64) -> f64 {
    match rayleigh {
        Some((alpha, beta)) if omega > 0.0 => alpha / (2.0 * omega) + beta * omega / 2.0,
        _ => 0.0,
    }
}

/// The effective modal mass (φᵀ M r)² / φᵀ M φ of mode φ in direction `component` (0 x, 1 y),
/// with `component_of[i]` the component of free dof i.
pub fn effective_mass(m: &Csc, phi: &[f64], component_of: &[usize], component: usize) -> f64 {
    let r: Vec<f64> = component_of
        .iter()
        .map(|&c| if c == component { 1.0 } else { 0.0 })
        .collect();
    let mphi = m.mul_vec(phi);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let modal_mass = dot(phi, &mphi);
    if modal_mass > 0.0 {
        dot(&mphi, &r).powi(2) / modal_mass
    } else {
        0.0
    }
}

/// r_dᵀ M r_d: the mass the supports let move in direction `component` (what the effective
/// masses of all modes sum to).
pub fn free_mass(m: &Csc, component_of: &[usize], component: usize) -> f64 {
    let r: Vec<f64> = component_of
        .iter()
        .map(|&c| if c == component { 1.0 } else { 0.0 })
        .collect();
    m.mul_vec(&r).iter().zip(&r).map(|(a, b)| a * b).sum()
}
