//! The lowest natural frequencies: K φ = ω² M φ on already-reduced (free-dof) matrices, by
//! shift-invert subspace iteration with Rayleigh–Ritz (Bathe, Finite Element Procedures,
//! §11.6). Used by tests against beam theory and by diagnostics near resonance.

use faer::c64;
use nalgebra::{DMatrix, SymmetricEigen};

use crate::linalg::{Csc, LuPattern, SparseLu};
use crate::{Error, Result};

/// The `count` eigenpairs (ω², φ) nearest above `shift` (use 0 for the lowest), ascending.
pub fn lowest_modes(k: &Csc, m: &Csc, count: usize, shift: f64) -> Result<Vec<(f64, Vec<f64>)>> {
    let n = k.nrows;
    let p = (2 * count).max(count + 8).min(n);
    let shifted = {
        let mut common = Csc::on_common_pattern(&[k, m]).into_iter();
        let (Some(mut a), Some(mm)) = (common.next(), common.next()) else {
            return Err(Error::Model("internal: modes pattern".into()));
        };
        for (v, w) in a.values.iter_mut().zip(&mm.values) {
            *v -= shift * w;
        }
        a
    };
    let pattern = LuPattern::analyse(&shifted)?;
    let lu = SparseLu::factor_real(&pattern, &shifted)?;
    // Start vectors: M-weighted deterministic pseudo-random columns.
    let mut x: Vec<Vec<f64>> = (0..p)
        .map(|j| {
            (0..n)
                .map(|i| {
                    (((i * 7919 + j * 104_729) % 1000) as f64 / 1000.0) - 0.5
                        + if i % p == j { 1.0 } else { 0.0 }
                })
                .collect()
        })
        .collect();
    let mut previous = vec![f64::INFINITY; count];
    for _ in 0..200 {
        // Y = (K − σM)⁻¹ M X
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
        // Rayleigh–Ritz on span(Y).
        let ky: Vec<Vec<f64>> = y.iter().map(|c| k.mul_vec(c)).collect();
        let my: Vec<Vec<f64>> = y.iter().map(|c| m.mul_vec(c)).collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let kr = DMatrix::from_fn(p, p, |i, j| dot(&y[i], &ky[j]));
        let mr = DMatrix::from_fn(p, p, |i, j| dot(&y[i], &my[j]));
        let kr = (&kr + kr.transpose()) * 0.5;
        let mr = (&mr + mr.transpose()) * 0.5;
        let Some(chol) = mr.clone().cholesky() else {
            return Err(Error::Model(
                "mode extraction: the mass matrix is not positive on the subspace (massless dofs?)"
                    .into(),
            ));
        };
        let l_inv = chol
            .l()
            .try_inverse()
            .ok_or_else(|| Error::Model("mode extraction: singular subspace".into()))?;
        let a = &l_inv * kr * l_inv.transpose();
        let eig = SymmetricEigen::new((&a + a.transpose()) * 0.5);
        let mut order: Vec<usize> = (0..p).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
        // Ritz vectors: Y · L⁻ᵀ · q.
        let coeffs = l_inv.transpose() * &eig.eigenvectors;
        x = order
            .iter()
            .map(|&c| {
                let mut v = vec![0.0; n];
                for (r, yr) in y.iter().enumerate() {
                    let w = coeffs[(r, c)];
                    for (vi, yi) in v.iter_mut().zip(yr) {
                        *vi += w * yi;
                    }
                }
                v
            })
            .collect();
        let values: Vec<f64> = order
            .iter()
            .take(count)
            .map(|&i| eig.eigenvalues[i])
            .collect();
        let converged = values
            .iter()
            .zip(&previous)
            .all(|(a, b)| ((a - b) / a).abs() < 1e-12);
        previous = values;
        if converged {
            break;
        }
    }
    Ok(previous.into_iter().zip(x).take(count).collect())
}
