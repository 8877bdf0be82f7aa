//! Two-dimensional meshes: the types the rest of the program sees, reading gmsh's .msh files
//! (`msh`), and running gmsh on a parametrised `.geo` with a cache (`gmsh`).

pub mod geo;
pub mod gmsh;
pub mod guard;
pub mod msh;

use std::collections::BTreeMap;

/// Shapes of the 2-D (body) cells we support. Node ordering follows gmsh.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellKind {
    /// 3-node triangle (gmsh type 2).
    Tri3,
    /// 6-node triangle (gmsh type 9): corners, then mid-edge nodes 0-1, 1-2, 2-0.
    Tri6,
    /// 4-node quadrilateral (gmsh type 3).
    Quad4,
    /// 8-node serendipity quadrilateral (gmsh type 16).
    Quad8,
    /// 9-node Lagrange quadrilateral (gmsh type 10).
    Quad9,
}

impl CellKind {
    pub fn nodes_per_cell(self) -> usize {
        match self {
            CellKind::Tri3 => 3,
            CellKind::Tri6 => 6,
            CellKind::Quad4 => 4,
            CellKind::Quad8 => 8,
            CellKind::Quad9 => 9,
        }
    }

    /// Polynomial order of the shape functions (1 or 2).
    pub fn order(self) -> usize {
        match self {
            CellKind::Tri3 | CellKind::Quad4 => 1,
            _ => 2,
        }
    }

    /// Number of corner nodes (the first nodes of the connectivity).
    pub fn corners(self) -> usize {
        match self {
            CellKind::Tri3 | CellKind::Tri6 => 3,
            _ => 4,
        }
    }
}

/// A 2-D cell: its shape and node indices (into `Mesh2d::nodes`).
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    pub kind: CellKind,
    pub nodes: Vec<usize>,
}

/// A boundary edge (a 1-D element): 2 nodes (linear) or 3 nodes (end, end, middle: gmsh order).
#[derive(Clone, Debug, PartialEq)]
pub struct Edge {
    pub nodes: Vec<usize>,
}

/// A mesh of the plane with its named (physical) groups.
///
/// Nodes that belong to no cell (for example the nodes of a rigid obstacle curve meshed as 1-D
/// elements only) are kept in `nodes` but carry no degrees of freedom.
#[derive(Clone, Debug, Default)]
pub struct Mesh2d {
    pub nodes: Vec<[f64; 2]>,
    pub cells: Vec<Cell>,
    /// 2-D physical groups: name → indices into `cells`.
    pub cell_groups: BTreeMap<String, Vec<usize>>,
    /// 1-D physical groups: name → edges.
    pub edge_groups: BTreeMap<String, Vec<Edge>>,
    /// Every physical group of any dimension (0-D points, 1-D curves, 2-D surfaces):
    /// name → sorted, unique node indices.
    pub node_groups: BTreeMap<String, Vec<usize>>,
}

impl Mesh2d {
    /// Sorted, unique indices of the nodes used by at least one cell.
    pub fn body_nodes(&self) -> Vec<usize> {
        let mut used = vec![false; self.nodes.len()];
        for c in &self.cells {
            for &n in &c.nodes {
                used[n] = true;
            }
        }
        (0..self.nodes.len()).filter(|&i| used[i]).collect()
    }

    /// Every node's root in the union of the cells sharing nodes (a node of no cell is its own).
    pub fn part_roots(&self) -> Vec<usize> {
        let mut parent: Vec<usize> = (0..self.nodes.len()).collect();
        fn find(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for cell in &self.cells {
            let a = find(&mut parent, cell.nodes[0]);
            for &n in &cell.nodes[1..] {
                let b = find(&mut parent, n);
                parent[b] = a;
            }
        }
        (0..parent.len()).map(|i| find(&mut parent, i)).collect()
    }

    /// The names of all physical groups, for "did you mean" messages.
    pub fn group_names(&self) -> Vec<&str> {
        self.node_groups.keys().map(String::as_str).collect()
    }

    /// " Did you mean `x`? Groups in the mesh: …" for a group name that is not in the mesh.
    pub fn group_hint(&self, name: &str) -> String {
        let names = self.group_names();
        let best = names
            .iter()
            .map(|n| (strsim::jaro_winkler(n, name), *n))
            .filter(|(s, _)| *s > 0.7)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let hint = best
            .map(|(_, n)| format!(" Did you mean `{n}`?"))
            .unwrap_or_default();
        format!("{hint} Groups in the mesh: {}", names.join(", "))
    }

    /// The smallest edge length over all cells (a mesh-size measure for messages and tests).
    pub fn min_edge_length(&self) -> f64 {
        let mut h = f64::INFINITY;
        for c in &self.cells {
            let k = c.kind.corners();
            for a in 0..k {
                let p = self.nodes[c.nodes[a]];
                let q = self.nodes[c.nodes[(a + 1) % k]];
                h = h.min(((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt());
            }
        }
        h
    }
}
