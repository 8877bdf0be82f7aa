//! Global assembly of stiffness and mass into sparse triplets over all dofs.

use super::Material;
use crate::linalg::Triplets;
use crate::mesh::Mesh2d;
use crate::Result;

/// Consistent or diagonal (lumped) mass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MassKind {
    Consistent,
    /// Diagonal by HRZ (diagonal scaling), positive for every element type.
    Lumped,
}

/// Global stiffness K (2·nodes square). Errors name the first inverted or degenerate cell.
pub fn assemble_stiffness(mesh: &Mesh2d, material: &Material) -> Result<Triplets> {
    let _ = (mesh, material);
    todo!("fem helper")
}

/// Global mass M (2·nodes square).
pub fn assemble_mass(mesh: &Mesh2d, material: &Material, kind: MassKind) -> Result<Triplets> {
    let _ = (mesh, material, kind);
    todo!("fem helper")
}
