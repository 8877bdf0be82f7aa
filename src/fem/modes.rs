//! Natural frequencies and mode shapes: K φ = ω² M φ on already-reduced (free-dof) matrices, by
//! shift-invert subspace iteration with Rayleigh–Ritz (Bathe, Finite Element Procedures,
//! §11.6), and the modal quantities an engineer reads next to them.
//!
//! Glossary:
//! - σ the shift (an ω²): the iteration converges first to the eigenvalues nearest σ;
//! - p the subspace size, max(2·count, count + 8);
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
    let p = (2 * count).max(count + 8);
    let mut modes = subspace_iteration(k, m, count, shift, (p, TOLERANCE), None)?;
    modes.truncate(count);
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes)
}

/// A quick look near `shift`: the `count` eigenpairs nearest it from a subspace of only
/// count + 4 vectors, their ω² to 1e-6 (frequencies to 5e-7), ascending in ω². For deciding
/// how near a frequency sits to a mode, at the cost of one factorization and a few dozen
/// solves; `pattern`, when given, is a symbolic analysis of K's pattern to reuse.
pub fn modes_near(
    k: &Csc,
    m: &Csc,
    count: usize,
    shift: f64,
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let mut modes = subspace_iteration(k, m, count, shift, (count + 4, 1e-6), pattern)?;
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

/// Iterate Y = (K − σM)⁻¹ M X with p vectors, Rayleigh–Ritz on span(Y), until the `count`
/// Ritz values nearest σ settle to `tolerance`, or stagnate below 1e-6 (round-off in ill-conditioned K,
/// where the lowest values jitter at 1e-9 on a slender beam); returns every Ritz pair ordered
/// by distance to σ (nearest first).
fn subspace_iteration(
    k: &Csc,
    m: &Csc,
    count: usize,
    shift: f64,
    (p, tolerance): (usize, f64),
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let n = k.nrows;
    let count = count.min(n);
    let p = p.min(n);
    let a = shifted(k, m, shift)?;
    let lu = match pattern {
        Some(pattern) => SparseLu::factor_real(pattern, &a)?,
        None => SparseLu::factor_real(&LuPattern::analyse(&a)?, &a)?,
    };
    let mut x = start_vectors(n, p, 0);
    let mut values = Vec::new();
    let mut previous = vec![f64::INFINITY; count];
    let (mut best, mut stalled) = (f64::INFINITY, 0);
    for iteration in 1..=200 {
        let rhs: Vec<Vec<c64>> = x
            .iter()
            .map(|col| {
                m.mul_vec(col)
                    .into_iter()
                    .map(|v| c64::new(v, 0.0))
                    .collect()
            })
            .collect();
        let y: Vec<Vec<f64>> = lu
            .solve_many(&rhs)
            .into_iter()
            .map(|col| col.into_iter().map(|z| z.re).collect())
            .collect();
        let (eigenvalues, vectors) = rayleigh_ritz(k, m_orthonormal(m, y, iteration))?;
        let mut order: Vec<usize> = (0..eigenvalues.len()).collect();
        order.sort_by(|&i, &j| {
            (eigenvalues[i] - shift)
                .abs()
                .total_cmp(&(eigenvalues[j] - shift).abs())
        });
        x = order.iter().map(|&c| vectors[c].clone()).collect();
        values = order.iter().map(|&i| eigenvalues[i]).collect::<Vec<f64>>();
        let change = values
            .iter()
            .zip(&previous)
            .map(|(a, b)| ((a - b) / a).abs())
            .fold(0.0, f64::max);
        previous = values.iter().take(count).copied().collect();
        if change < best {
            (best, stalled) = (change, 0);
        } else {
            stalled += 1;
        }
        if change < tolerance || (change < 1e-6 && stalled >= 3) {
            break;
        }
    }
    Ok(values.into_iter().zip(x).collect())
}

/// An M-orthonormal basis of span(Y) (modified Gram–Schmidt, twice): a column that is
/// (numerically) in the span of the previous ones, as happens when a shift sits next to an
/// eigenvalue and every column turns toward its mode, is replaced by a fresh start vector.
fn m_orthonormal(m: &Csc, mut y: Vec<Vec<f64>>, seed: usize) -> Vec<Vec<f64>> {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let n = y.first().map_or(0, Vec::len);
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(y.len());
    let mut mbasis: Vec<Vec<f64>> = Vec::with_capacity(y.len());
    for (j, col) in y.iter_mut().enumerate() {
        for attempt in 0..3 {
            let before = dot(col, &m.mul_vec(col)).max(0.0).sqrt();
            for _ in 0..2 {
                for (b, mb) in basis.iter().zip(&mbasis) {
                    let c = dot(mb, col);
                    col.iter_mut().zip(b).for_each(|(v, bv)| *v -= c * bv);
                }
            }
            let mcol = m.mul_vec(col);
            let norm = dot(col, &mcol).max(0.0).sqrt();
            if norm > 1e-10 * before && norm > 0.0 {
                col.iter_mut().for_each(|v| *v /= norm);
                mbasis.push(mcol.into_iter().map(|v| v / norm).collect());
                basis.push(std::mem::take(col));
                break;
            }
            if attempt < 2 {
                *col = start_vectors(n, 1, seed * 7 + j + attempt + 1).remove(0);
            }
        }
    }
    basis
}

/// The Ritz values and M-orthonormal Ritz vectors of K, M on span(Q), Q M-orthonormal.
fn rayleigh_ritz(k: &Csc, q: Vec<Vec<f64>>) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    let (p, n) = (q.len(), q.first().map_or(0, Vec::len));
    if p == 0 {
        return Err(Error::Model(
            "mode extraction: the mass matrix is zero on every trial vector (massless dofs?)"
                .into(),
        ));
    }
    let kq: Vec<Vec<f64>> = q.iter().map(|c| k.mul_vec(c)).collect();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let kr = DMatrix::from_fn(p, p, |i, j| dot(&q[i], &kq[j]));
    let eig = SymmetricEigen::new((&kr + kr.transpose()) * 0.5);
    // Ritz vectors: Q · s.
    let vectors = (0..p)
        .map(|c| {
            let mut v = vec![0.0; n];
            for (r, qr) in q.iter().enumerate() {
                let w = eig.eigenvectors[(r, c)];
                v.iter_mut().zip(qr).for_each(|(vi, qi)| *vi += w * qi);
            }
            v
        })
        .collect();
    Ok((eig.eigenvalues.iter().copied().collect(), vectors))
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
