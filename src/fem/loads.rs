//! Nodal forces from edge tractions and point forces.

use crate::mesh::{Edge, Mesh2d};

/// Consistent nodal forces (length 2·nodes) of a constant traction `t` (force per area) on
/// `edges`, times `thickness`.
pub fn edge_traction_load(mesh: &Mesh2d, edges: &[Edge], traction: [f64; 2], thickness: f64) -> Vec<f64> {
    let _ = (mesh, edges, traction, thickness);
    todo!("fem helper")
}

/// A total force `force` shared equally by `nodes` (length 2·nodes of the mesh).
pub fn point_force_load(mesh: &Mesh2d, nodes: &[usize], force: [f64; 2]) -> Vec<f64> {
    let _ = (mesh, nodes, force);
    todo!("fem helper")
}
