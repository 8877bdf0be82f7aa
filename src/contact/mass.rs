//! The mass redistribution method (Khenous, Laborde, Renard, Eur. J. Mech. A/Solids 27, 2008):
//! the contact nodes get no inertia, so a rigid obstacle stops them without an impulse and the
//! periodic contact force has a converging Fourier series. Total mass and centre of mass are
//! kept; the change of the moment of inertia is reported.
//!
//! On a diagonal mass: each contact node's mass moves to the non-contact nodes of the cells
//! around it, in proportion to their own mass; then a minimum-norm, mass-weighted correction of
//! the nodal masses of each body (each connected set of cells: Σδm = 0, Σδm·x = Δ over that
//! body) restores every body's mass and centre of mass exactly.

use nalgebra::{Matrix3, Vector3};

use crate::mesh::Mesh2d;
use crate::{Error, Result};

pub struct Redistribution {
    /// Diagonal mass over all dofs; exactly zero on the contact nodes' dofs.
    pub mass: Vec<f64>,
    /// The mass moved off the contact nodes (per unit thickness times thickness, as given).
    pub moved_mass: f64,
    /// `moved_mass` over the total mass.
    pub moved_fraction: f64,
    /// Relative change of the polar moment of inertia about the centre of mass.
    pub inertia_change: f64,
}

/// The cells around each node (compressed rows): a node's neighbours are the other nodes of
/// its cells.
struct CellsOfNode {
    start: Vec<usize>,
    cells: Vec<usize>,
}

impl CellsOfNode {
    fn new(mesh: &Mesh2d) -> Self {
        let mut start = vec![0usize; mesh.nodes.len() + 1];
        for c in &mesh.cells {
            for &a in &c.nodes {
                start[a + 1] += 1;
            }
        }
        for n in 0..mesh.nodes.len() {
            start[n + 1] += start[n];
        }
        let mut next = start.clone();
        let mut cells = vec![0usize; start[mesh.nodes.len()]];
        for (i, c) in mesh.cells.iter().enumerate() {
            for &a in &c.nodes {
                cells[next[a]] = i;
                next[a] += 1;
            }
        }
        CellsOfNode { start, cells }
    }

    /// The nodes sharing a cell with `node`, ascending, without `node`.
    fn neighbours(&self, mesh: &Mesh2d, node: usize) -> Vec<usize> {
        let mut out: Vec<usize> = self.cells[self.start[node]..self.start[node + 1]]
            .iter()
            .flat_map(|&c| mesh.cells[c].nodes.iter().copied())
            .filter(|&n| n != node)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }
}

fn moments(mesh: &Mesh2d, m: &[f64]) -> (f64, [f64; 2]) {
    let mut total = 0.0;
    let mut first = [0.0; 2];
    for (n, p) in mesh.nodes.iter().enumerate() {
        total += m[2 * n];
        first[0] += m[2 * n] * p[0];
        first[1] += m[2 * n] * p[1];
    }
    (total, first)
}

fn polar_inertia(mesh: &Mesh2d, m: &[f64], centre: [f64; 2]) -> f64 {
    mesh.nodes
        .iter()
        .enumerate()
        .map(|(n, p)| m[2 * n] * ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)))
        .sum()
}

/// The redistributed diagonal mass of a mesh whose lumped diagonal mass is `lumped` (2 dofs
/// per node, equal), with no inertia on `massless_nodes` (the contact nodes): their mass to
/// their rings, then the centre of mass restored (see the header).
pub fn redistribute_mass(
    mesh: &Mesh2d,
    lumped: &[f64],
    massless_nodes: &[usize],
) -> Result<Redistribution> {
    let mut massless: Vec<usize> = massless_nodes.to_vec();
    massless.sort_unstable();
    massless.dedup();
    let mut is_massless = vec![false; mesh.nodes.len()];
    for &c in &massless {
        is_massless[c] = true;
    }
    let adjacency = CellsOfNode::new(mesh);
    let (total, first) = moments(mesh, lumped);
    if !(total > 0.0) {
        return Err(Error::Model(
            "mass redistribution: the body has no mass".into(),
        ));
    }
    let centre = [first[0] / total, first[1] / total];
    let inertia_before = polar_inertia(mesh, lumped, centre);

    let mut m: Vec<f64> = (0..mesh.nodes.len()).map(|n| lumped[2 * n]).collect();
    let mut moved = 0.0;
    for &c in &massless {
        let mc = m[c];
        if mc == 0.0 {
            continue;
        }
        let ring = receiving_ring(mesh, &adjacency, &is_massless, c);
        let weight: f64 = ring.iter().map(|&n| lumped[2 * n]).sum();
        if ring.is_empty() || !(weight > 0.0) {
            return Err(Error::Model(format!(
                "mass redistribution: contact node {c} has no non-contact neighbour to take its mass; refine the mesh near the contact boundary (at least two elements through the thickness)"
            )));
        }
        for &n in &ring {
            m[n] += mc * lumped[2 * n] / weight;
        }
        m[c] = 0.0;
        moved += mc;
    }
    if moved > 0.0 {
        let lumped_nodal: Vec<f64> = (0..mesh.nodes.len()).map(|n| lumped[2 * n]).collect();
        let roots = mesh.part_roots();
        let bodies: std::collections::BTreeSet<usize> =
            mesh.cells.iter().map(|c| roots[c.nodes[0]]).collect();
        for body in bodies {
            let in_body = |n: usize| roots[n] == body;
            let target = first_moment(mesh, &lumped_nodal, in_body);
            restore_first_moment(mesh, &mut m, &is_massless, target, in_body);
        }
    }
    if let Some((n, v)) = m
        .iter()
        .enumerate()
        .find(|&(n, v)| !is_massless[n] && lumped[2 * n] > 0.0 && *v <= 0.0)
    {
        return Err(Error::Model(format!(
            "mass redistribution made node {n}'s mass non-positive ({v:e}): refine the mesh near the contact boundary"
        )));
    }
    let mass: Vec<f64> = m.iter().flat_map(|&v| [v, v]).collect();
    let inertia_after = polar_inertia(mesh, &mass, centre);
    Ok(Redistribution {
        mass,
        moved_mass: moved,
        moved_fraction: moved / total,
        inertia_change: (inertia_after - inertia_before) / inertia_before,
    })
}

/// The nodes contact node `c`'s mass goes to: its first ring of non-contact nodes, widened
/// once where the cells around it are all contact nodes.
fn receiving_ring(
    mesh: &Mesh2d,
    adjacency: &CellsOfNode,
    is_massless: &[bool],
    c: usize,
) -> Vec<usize> {
    let near = adjacency.neighbours(mesh, c);
    let ring: Vec<usize> = near.iter().copied().filter(|&n| !is_massless[n]).collect();
    if !ring.is_empty() {
        return ring;
    }
    let mut ring: Vec<usize> = near
        .into_iter()
        .flat_map(|n| adjacency.neighbours(mesh, n))
        .filter(|&n| !is_massless[n])
        .collect();
    ring.sort_unstable();
    ring.dedup();
    ring
}

/// The first moment Σ m_j x_j of the nodal masses `m` over the nodes where `keep` holds.
fn first_moment(mesh: &Mesh2d, m: &[f64], keep: impl Fn(usize) -> bool) -> [f64; 2] {
    let mut first = [0.0; 2];
    for (n, p) in mesh.nodes.iter().enumerate() {
        if keep(n) {
            first[0] += m[n] * p[0];
            first[1] += m[n] * p[1];
        }
    }
    first
}

/// Restore the first moment `first` of the nodal masses `m` of the nodes where `in_body`
/// holds: δ_j = w_j (μ0 + μ1 x_j + μ2 y_j), w_j = m_j over the body's massive nodes.
/// (Correcting the receiving ring alone can need negative masses: on a flat contact face
/// every receiver lies on the same side of the moved mass.)
fn restore_first_moment(
    mesh: &Mesh2d,
    m: &mut [f64],
    is_massless: &[bool],
    first: [f64; 2],
    in_body: impl Fn(usize) -> bool,
) {
    let weights: Vec<f64> = m
        .iter()
        .enumerate()
        .map(|(n, &v)| {
            if is_massless[n] || !in_body(n) {
                0.0
            } else {
                v
            }
        })
        .collect();
    let first_now = first_moment(mesh, m, &in_body);
    let delta = [first[0] - first_now[0], first[1] - first_now[1]];
    let mut a = Matrix3::zeros();
    for (n, &w) in weights.iter().enumerate() {
        if w == 0.0 {
            continue;
        }
        let v = Vector3::new(1.0, mesh.nodes[n][0], mesh.nodes[n][1]);
        a += v * v.transpose() * w;
    }
    let rhs = Vector3::new(0.0, delta[0], delta[1]);
    let mu = a.lu().solve(&rhs).unwrap_or_else(Vector3::zeros);
    for (n, &w) in weights.iter().enumerate() {
        if w > 0.0 {
            m[n] += w * (mu[0] + mu[1] * mesh.nodes[n][0] + mu[2] * mesh.nodes[n][1]);
        }
    }
}
