//! Element matrices of plane linear elasticity: stiffness ∫ Bᵀ C B t dA, consistent mass
//! ρ t ∫ Nᵀ N dA and its HRZ lumping. Element dofs are node-major: (u_x, u_y) per node.

use nalgebra::{DMatrix, Matrix3};

use super::shapes::{gauss, shape};
use super::{Material, PlaneModel};
use crate::mesh::{Cell, CellKind};
use crate::{Error, Result};

/// The in-plane elasticity matrix (Voigt: xx, yy, 2xy).
pub fn elasticity_matrix(m: &Material) -> Matrix3<f64> {
    let (e, nu) = (m.youngs_modulus, m.poisson_ratio);
    match m.model {
        PlaneModel::PlaneStrain => {
            let f = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
            Matrix3::new(
                f * (1.0 - nu),
                f * nu,
                0.0,
                f * nu,
                f * (1.0 - nu),
                0.0,
                0.0,
                0.0,
                f * (1.0 - 2.0 * nu) / 2.0,
            )
        }
        PlaneModel::PlaneStress => {
            let f = e / (1.0 - nu * nu);
            Matrix3::new(
                f,
                f * nu,
                0.0,
                f * nu,
                f,
                0.0,
                0.0,
                0.0,
                f * (1.0 - nu) / 2.0,
            )
        }
    }
}

/// Physical shape derivatives and det J at a reference point; det J ≤ 0 is an error.
pub fn physical_derivatives(
    index: usize,
    cell: &Cell,
    coords: &[[f64; 2]],
    xi: f64,
    eta: f64,
) -> Result<(Vec<f64>, Vec<[f64; 2]>, f64)> {
    let (n, d) = shape(cell.kind, xi, eta);
    let (mut j00, mut j01, mut j10, mut j11) = (0.0, 0.0, 0.0, 0.0);
    for (a, p) in coords.iter().enumerate() {
        j00 += d[a][0] * p[0];
        j01 += d[a][0] * p[1];
        j10 += d[a][1] * p[0];
        j11 += d[a][1] * p[1];
    }
    let det = j00 * j11 - j01 * j10;
    if !(det > 0.0) || !det.is_finite() {
        let p = coords[0];
        return Err(Error::Input(format!(
            "cell {index} ({:?}, first node at ({}, {})) is inverted or degenerate (Jacobian determinant {det:e}): remesh, or check the mid-side nodes of curved edges",
            cell.kind, p[0], p[1]
        )));
    }
    let inv = [[j11 / det, -j01 / det], [-j10 / det, j00 / det]];
    let dx = d
        .iter()
        .map(|g| {
            [
                inv[0][0] * g[0] + inv[0][1] * g[1],
                inv[1][0] * g[0] + inv[1][1] * g[1],
            ]
        })
        .collect();
    Ok((n, dx, det))
}

fn stiffness_degree(kind: CellKind) -> usize {
    match kind {
        CellKind::Tri3 => 1,
        CellKind::Quad4 => 2,
        CellKind::Tri6 => 2,
        CellKind::Quad8 | CellKind::Quad9 => 4,
    }
}

fn mass_degree(kind: CellKind) -> usize {
    match kind {
        CellKind::Tri3 => 2,
        CellKind::Quad4 => 3,
        _ => 5,
    }
}

pub fn element_stiffness(
    index: usize,
    cell: &Cell,
    coords: &[[f64; 2]],
    m: &Material,
) -> Result<DMatrix<f64>> {
    let c = elasticity_matrix(m);
    let nn = coords.len();
    let mut k = DMatrix::zeros(2 * nn, 2 * nn);
    for (xi, eta, w) in gauss(cell.kind, stiffness_degree(cell.kind)) {
        let (_, dx, det) = physical_derivatives(index, cell, coords, xi, eta)?;
        let mut b = DMatrix::zeros(3, 2 * nn);
        for a in 0..nn {
            b[(0, 2 * a)] = dx[a][0];
            b[(1, 2 * a + 1)] = dx[a][1];
            b[(2, 2 * a)] = dx[a][1];
            b[(2, 2 * a + 1)] = dx[a][0];
        }
        let cb = DMatrix::from_iterator(3, 3, c.iter().copied()) * &b;
        k += b.transpose() * cb * (w * det * m.thickness);
    }
    Ok(k)
}

/// Consistent mass per component (nn × nn; the same for x and y).
pub fn element_mass_scalar(
    index: usize,
    cell: &Cell,
    coords: &[[f64; 2]],
    m: &Material,
) -> Result<DMatrix<f64>> {
    let nn = coords.len();
    let mut mm = DMatrix::zeros(nn, nn);
    for (xi, eta, w) in gauss(cell.kind, mass_degree(cell.kind)) {
        let (n, _, det) = physical_derivatives(index, cell, coords, xi, eta)?;
        let f = w * det * m.density * m.thickness;
        for a in 0..nn {
            for b in 0..nn {
                mm[(a, b)] += f * n[a] * n[b];
            }
        }
    }
    Ok(mm)
}

/// HRZ lumping: the consistent diagonal scaled to the element's total mass. Positive for
/// every element kind (unlike row summing, which gives negative corner masses for Tri6).
pub fn hrz_lumped(consistent: &DMatrix<f64>) -> Vec<f64> {
    let total: f64 = consistent.iter().sum();
    let diag: Vec<f64> = (0..consistent.nrows())
        .map(|i| consistent[(i, i)])
        .collect();
    let s: f64 = diag.iter().sum();
    diag.iter().map(|d| d * total / s).collect()
}
