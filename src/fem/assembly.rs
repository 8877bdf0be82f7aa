//! Global assembly of stiffness and mass into sparse triplets over all dofs.

use super::elasticity::{element_mass_scalar, element_stiffness, hrz_lumped};
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

fn coords(mesh: &Mesh2d, nodes: &[usize]) -> Vec<[f64; 2]> {
    nodes.iter().map(|&n| mesh.nodes[n]).collect()
}

/// Global stiffness K (2·nodes square). Errors name the first inverted or degenerate cell.
pub fn assemble_stiffness(mesh: &Mesh2d, material: &Material) -> Result<Triplets> {
    let mut t = Triplets::new(2 * mesh.nodes.len());
    t.entries.reserve(
        mesh.cells
            .iter()
            .map(|c| 4 * c.nodes.len() * c.nodes.len())
            .sum(),
    );
    for (i, cell) in mesh.cells.iter().enumerate() {
        let ke = element_stiffness(i, cell, &coords(mesh, &cell.nodes), material)?;
        for (a, &na) in cell.nodes.iter().enumerate() {
            for (b, &nb) in cell.nodes.iter().enumerate() {
                for ca in 0..2 {
                    for cb in 0..2 {
                        t.push(2 * na + ca, 2 * nb + cb, ke[(2 * a + ca, 2 * b + cb)]);
                    }
                }
            }
        }
    }
    Ok(t)
}

/// Global mass M (2·nodes square).
pub fn assemble_mass(mesh: &Mesh2d, material: &Material, kind: MassKind) -> Result<Triplets> {
    let mut t = Triplets::new(2 * mesh.nodes.len());
    for (i, cell) in mesh.cells.iter().enumerate() {
        let me = element_mass_scalar(i, cell, &coords(mesh, &cell.nodes), material)?;
        match kind {
            MassKind::Consistent => {
                for (a, &na) in cell.nodes.iter().enumerate() {
                    for (b, &nb) in cell.nodes.iter().enumerate() {
                        for c in 0..2 {
                            t.push(2 * na + c, 2 * nb + c, me[(a, b)]);
                        }
                    }
                }
            }
            MassKind::Lumped => {
                for (a, m) in hrz_lumped(&me).into_iter().enumerate() {
                    let n = cell.nodes[a];
                    t.push(2 * n, 2 * n, m);
                    t.push(2 * n + 1, 2 * n + 1, m);
                }
            }
        }
    }
    Ok(t)
}
