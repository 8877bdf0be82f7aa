//! Stress recovery at cell centroids.

use super::elasticity::{elasticity_matrix, physical_derivatives};
use super::{Material, PlaneModel};
use crate::mesh::{CellKind, Mesh2d};

/// Cauchy stress at a cell's centroid; `zz` is ν(xx+yy) in plane strain and 0 in plane stress.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CellStress {
    pub xx: f64,
    pub yy: f64,
    pub zz: f64,
    pub xy: f64,
}

impl CellStress {
    pub fn von_mises(&self) -> f64 {
        let (a, b, c) = (self.xx - self.yy, self.yy - self.zz, self.zz - self.xx);
        (0.5 * (a * a + b * b + c * c) + 3.0 * self.xy * self.xy).sqrt()
    }
}

/// Stress in every cell for the displacement `u` (length 2·nodes).
pub fn cell_stresses(mesh: &Mesh2d, material: &Material, u: &[f64]) -> Vec<CellStress> {
    let c = elasticity_matrix(material);
    mesh.cells
        .iter()
        .enumerate()
        .map(|(i, cell)| {
            let (xi, eta) = match cell.kind {
                CellKind::Tri3 | CellKind::Tri6 => (1.0 / 3.0, 1.0 / 3.0),
                _ => (0.0, 0.0),
            };
            let coords: Vec<[f64; 2]> = cell.nodes.iter().map(|&n| mesh.nodes[n]).collect();
            let Ok((_, dx, _)) = physical_derivatives(i, cell, &coords, xi, eta) else {
                return CellStress::default();
            };
            let (mut exx, mut eyy, mut gxy) = (0.0, 0.0, 0.0);
            for (a, &n) in cell.nodes.iter().enumerate() {
                exx += dx[a][0] * u[2 * n];
                eyy += dx[a][1] * u[2 * n + 1];
                gxy += dx[a][1] * u[2 * n] + dx[a][0] * u[2 * n + 1];
            }
            let s = c * nalgebra::Vector3::new(exx, eyy, gxy);
            let zz = match material.model {
                PlaneModel::PlaneStrain => material.poisson_ratio * (s[0] + s[1]),
                PlaneModel::PlaneStress => 0.0,
            };
            CellStress {
                xx: s[0],
                yy: s[1],
                zz,
                xy: s[2],
            }
        })
        .collect()
}
