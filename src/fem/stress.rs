//! Stress recovery at cell centroids.

use super::Material;
use crate::mesh::Mesh2d;

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
    let _ = (mesh, material, u);
    todo!("fem helper")
}
