//! Nodal forces from edge tractions, point forces and body forces.

use super::elasticity::physical_derivatives;
use super::shapes::{edge_shape, gauss, gauss_line};
use super::Material;
use crate::mesh::{Edge, Mesh2d};

/// Consistent nodal forces (length 2·nodes) of a constant traction `t` (force per area) on
/// `edges`, times `thickness`. Curved (3-node) edges are integrated on their parabola.
pub fn edge_traction_load(
    mesh: &Mesh2d,
    edges: &[Edge],
    traction: [f64; 2],
    thickness: f64,
) -> Vec<f64> {
    let mut f = vec![0.0; 2 * mesh.nodes.len()];
    for e in edges {
        let nn = e.nodes.len();
        for (t, w) in gauss_line(4) {
            let (n, d) = edge_shape(nn, t);
            let (mut dx, mut dy) = (0.0, 0.0);
            for (a, &node) in e.nodes.iter().enumerate() {
                dx += d[a] * mesh.nodes[node][0];
                dy += d[a] * mesh.nodes[node][1];
            }
            let jac = (dx * dx + dy * dy).sqrt();
            for (a, &node) in e.nodes.iter().enumerate() {
                for c in 0..2 {
                    f[2 * node + c] += w * jac * n[a] * traction[c] * thickness;
                }
            }
        }
    }
    f
}

/// A total force `force` shared equally by `nodes` (length 2·nodes of the mesh).
pub fn point_force_load(mesh: &Mesh2d, nodes: &[usize], force: [f64; 2]) -> Vec<f64> {
    let mut f = vec![0.0; 2 * mesh.nodes.len()];
    if nodes.is_empty() {
        return f;
    }
    let share = 1.0 / nodes.len() as f64;
    for &n in nodes {
        f[2 * n] += force[0] * share;
        f[2 * n + 1] += force[1] * share;
    }
    f
}

/// Consistent nodal forces of a body force density b(x) (force per volume), × thickness.
/// Cells whose Jacobian is invalid are skipped here (assembly reports them).
pub fn body_force_load(
    mesh: &Mesh2d,
    material: &Material,
    body: impl Fn([f64; 2]) -> [f64; 2],
) -> Vec<f64> {
    let mut f = vec![0.0; 2 * mesh.nodes.len()];
    for (i, cell) in mesh.cells.iter().enumerate() {
        let coords: Vec<[f64; 2]> = cell.nodes.iter().map(|&n| mesh.nodes[n]).collect();
        for (xi, eta, w) in gauss(cell.kind, 5) {
            let Ok((n, _, det)) = physical_derivatives(i, cell, &coords, xi, eta) else {
                continue;
            };
            let mut x = [0.0; 2];
            for (a, p) in coords.iter().enumerate() {
                x[0] += n[a] * p[0];
                x[1] += n[a] * p[1];
            }
            let b = body(x);
            for (a, &node) in cell.nodes.iter().enumerate() {
                for c in 0..2 {
                    f[2 * node + c] += w * det * n[a] * b[c] * material.thickness;
                }
            }
        }
    }
    f
}
