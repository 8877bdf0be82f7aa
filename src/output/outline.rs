//! A mesh's outline for pictures: its boundary edges (an edge that belongs to exactly one
//! cell) chained into polylines of node indices.
//!
//! A cell's edges are the sides between consecutive corners; an edge is identified by its
//! two corner nodes (unordered), so an edge shared by two cells is counted twice and is
//! inside, one counted once is on the boundary. On order-2 cells (Tri6, Quad8, Quad9, gmsh
//! node order: corners, then the mid-edge nodes of sides 0-1, 1-2, …) a boundary edge keeps
//! its middle node, so a curved side draws as two segments. Nodes of no cell (rigid
//! obstacles meshed as line elements only) are not part of the outline.

use std::collections::{BTreeMap, HashMap};

use crate::mesh::{Cell, Mesh2d};

/// The nodes of side `j` of `cell` in the cell's own order: corner j, its middle node (order
/// 2), corner j + 1.
fn side(cell: &Cell, j: usize) -> Vec<usize> {
    let k = cell.kind.corners();
    let (a, b) = (cell.nodes[j], cell.nodes[(j + 1) % k]);
    match cell.nodes.get(k + j) {
        Some(&m) if cell.kind.order() == 2 => vec![a, m, b],
        _ => vec![a, b],
    }
}

/// The mesh's boundary edges, each as its nodes in the order of the cell it belongs to
/// (2 nodes, or 3 with the middle one on order-2 cells), sorted by their corner nodes.
pub fn boundary_edges(mesh: &Mesh2d) -> Vec<Vec<usize>> {
    let mut count: BTreeMap<(usize, usize), (usize, Vec<usize>)> = BTreeMap::new();
    for cell in &mesh.cells {
        for j in 0..cell.kind.corners() {
            let nodes = side(cell, j);
            let (a, b) = (nodes[0], nodes[nodes.len() - 1]);
            let entry = count.entry((a.min(b), a.max(b))).or_insert((0, nodes));
            entry.0 += 1;
        }
    }
    count
        .into_values()
        .filter(|(n, _)| *n == 1)
        .map(|(_, nodes)| nodes)
        .collect()
}

/// The boundary edges chained into polylines of node indices: each polyline follows edges
/// that meet end to end as far as it goes both ways; a closed loop ends on its first node.
/// Where more than two boundary edges meet at a node (bodies touching at a corner) a
/// polyline ends there and another one starts.
pub fn outline_polylines(mesh: &Mesh2d) -> Vec<Vec<usize>> {
    let edges = boundary_edges(mesh);
    let mut at: HashMap<usize, Vec<usize>> = HashMap::new();
    for (e, nodes) in edges.iter().enumerate() {
        at.entry(nodes[0]).or_default().push(e);
        at.entry(nodes[nodes.len() - 1]).or_default().push(e);
    }
    let mut used = vec![false; edges.len()];
    let mut lines = Vec::new();
    for start in 0..edges.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let mut line = edges[start].clone();
        extend(&mut line, &edges, &at, &mut used);
        line.reverse();
        extend(&mut line, &edges, &at, &mut used);
        lines.push(line);
    }
    lines
}

/// Append to `line` the unused edges that continue it from its last node, one after the
/// other, while exactly one continues it.
fn extend(
    line: &mut Vec<usize>,
    edges: &[Vec<usize>],
    at: &HashMap<usize, Vec<usize>>,
    used: &mut [bool],
) {
    loop {
        let Some(&end) = line.last() else { return };
        let next: Vec<usize> = at
            .get(&end)
            .map(|es| es.iter().copied().filter(|&e| !used[e]).collect())
            .unwrap_or_default();
        let [e] = next[..] else { return };
        used[e] = true;
        let nodes = &edges[e];
        if nodes[0] == end {
            line.extend(&nodes[1..]);
        } else {
            line.extend(nodes.iter().rev().skip(1));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CellKind;

    fn square(kind: CellKind, cells: Vec<Vec<usize>>, nodes: Vec<[f64; 2]>) -> Mesh2d {
        Mesh2d {
            nodes,
            cells: cells
                .into_iter()
                .map(|nodes| Cell { kind, nodes })
                .collect(),
            ..Default::default()
        }
    }

    /// TEST GOAL: a unit square of two triangles split along its diagonal 0-2 has 4 boundary
    /// edges, its 4 sides, and not the diagonal; they chain into one closed polyline through
    /// all 4 corners.
    #[test]
    fn two_triangle_square_has_its_four_sides_as_boundary_and_not_the_diagonal() {
        let nodes = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let mesh = square(CellKind::Tri3, vec![vec![0, 1, 2], vec![0, 2, 3]], nodes);
        let edges = boundary_edges(&mesh);
        assert_eq!(edges.len(), 4, "{edges:?}");
        let mut sides: Vec<(usize, usize)> = edges
            .iter()
            .map(|e| (e[0].min(e[1]), e[0].max(e[1])))
            .collect();
        sides.sort();
        assert_eq!(sides, vec![(0, 1), (0, 3), (1, 2), (2, 3)]);
        assert!(!sides.contains(&(0, 2)));
        let lines = outline_polylines(&mesh);
        assert_eq!(lines.len(), 1, "{lines:?}");
        let line = &lines[0];
        assert_eq!(line.len(), 5, "{line:?}");
        assert_eq!(line.first(), line.last());
        let mut corners = line[..4].to_vec();
        corners.sort();
        assert_eq!(corners, vec![0, 1, 2, 3]);
    }

    /// TEST GOAL: on the same square of two Tri6 cells each boundary edge keeps its middle
    /// node between its ends (3 nodes), and the closed outline passes all 8 boundary nodes,
    /// never the diagonal's middle node.
    #[test]
    fn order_two_boundary_edges_keep_their_middle_node() {
        // Corners 0-3, mid-nodes: 4 (0-1), 5 (1-2), 6 (2-0, the diagonal), 7 (2-3), 8 (3-0).
        let nodes = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [0.5, 0.0],
            [1.0, 0.5],
            [0.5, 0.5],
            [0.5, 1.0],
            [0.0, 0.5],
        ];
        let cells = vec![vec![0, 1, 2, 4, 5, 6], vec![0, 2, 3, 6, 7, 8]];
        let mesh = square(CellKind::Tri6, cells, nodes);
        let edges = boundary_edges(&mesh);
        assert_eq!(edges.len(), 4);
        for e in &edges {
            assert_eq!(e.len(), 3, "{e:?}");
            let [a, m, b] = [0, 1, 2].map(|i| mesh.nodes[e[i]]);
            assert_eq!([(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0], m);
        }
        let lines = outline_polylines(&mesh);
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0].len(), 9);
        assert!(!lines[0].contains(&6));
    }
}
