//! Node-to-segment pairing of a contact boundary with the boundary of another meshed body, in
//! the reference configuration (small deformation; Wriggers, Computational Contact Mechanics,
//! §4.1 and §8.3).
//!
//! Glossary and formulas, for a contact (slave) node x of the first body:
//! - target surface: the second body's boundary curve, as straight pieces (a 3-node edge as
//!   two pieces through its middle node), each with its outward unit normal ν (away from the
//!   cell that owns it);
//! - closest point x̄ = the nearest point of the pieces; at a vertex shared by two pieces, ν is
//!   the normalized mean of their normals;
//! - normal n = −ν (from the slave body into the target), gap g0 = (x̄ − x)·n (> 0 open);
//! - weights N_a(ξ) of the target edge at x̄: (1 − s, s) on a 2-node edge at fraction s; on a
//!   3-node edge [a, b, m] at ξ ∈ [−1, 1] (ξ = s − 1 on the first piece, s on the second):
//!   N_a = ξ(ξ − 1)/2, N_b = ξ(ξ + 1)/2, N_m = 1 − ξ²;
//! - B row: n on the slave node's dofs and −N_a n on each target node a's, so
//!   (B u) = (u_x − Σ N_a u_a)·n is the slave's approach toward the target surface.
//!
//! A node whose closest point is a free end of the target curve, and not straight across from
//! it, or whose own boundary faces away from the target (outward normal · n ≤ 0), is off the
//! target.

use std::collections::HashMap;

use super::geometry::{dot, free_ends, same_point, sub};
use crate::mesh::Mesh2d;
use crate::{Error, Result};

fn unit(v: [f64; 2]) -> [f64; 2] {
    let l = dot(v, v).sqrt();
    if l > 0.0 {
        [v[0] / l, v[1] / l]
    } else {
        v
    }
}

/// One straight piece of the target: its ends, outward normal, the edge's nodes and where the
/// piece lies on the edge (`None`: a 2-node edge; `Some(first)`: a half of a 3-node edge).
struct Piece {
    a: [f64; 2],
    b: [f64; 2],
    outward: [f64; 2],
    nodes: Vec<usize>,
    half: Option<bool>,
}

/// The paired target: its pieces and the curve's free ends.
pub struct TargetSurface {
    pieces: Vec<Piece>,
    ends: Vec<[f64; 2]>,
}

/// Where a slave node meets the target: closest point, normal into the target, the target
/// nodes' weights.
pub struct Projection {
    pub closest: [f64; 2],
    pub normal: [f64; 2],
    pub weights: Vec<(usize, f64)>,
}

/// The centroid of the cell holding both `a` and `b`, if any.
fn owner_centroid(
    mesh: &Mesh2d,
    cells_of: &HashMap<usize, Vec<usize>>,
    a: usize,
    b: usize,
) -> Option<[f64; 2]> {
    let c = cells_of
        .get(&a)?
        .iter()
        .find(|c| mesh.cells[**c].nodes.contains(&b))?;
    let nodes = &mesh.cells[*c].nodes;
    let k = nodes.len() as f64;
    Some(nodes.iter().fold([0.0, 0.0], |s, &m| {
        [s[0] + mesh.nodes[m][0] / k, s[1] + mesh.nodes[m][1] / k]
    }))
}

impl TargetSurface {
    /// The target boundary `group`, a curve of a body that shares no node with `slaves`.
    pub fn new(mesh: &Mesh2d, group: &str, slaves: &[usize]) -> Result<Self> {
        let field = "contact.obstacle.body";
        let Some(edges) = mesh.edge_groups.get(group) else {
            return Err(Error::Input(format!(
                "{field}: no curve group `{group}` in the mesh.{}",
                mesh.group_hint(group)
            )));
        };
        let mut cells_of: HashMap<usize, Vec<usize>> = HashMap::new();
        for (i, c) in mesh.cells.iter().enumerate() {
            for &n in &c.nodes {
                cells_of.entry(n).or_default().push(i);
            }
        }
        let mut pieces = Vec::new();
        for e in edges {
            let (a, b) = (e.nodes[0], e.nodes[1]);
            if let Some(n) = e.nodes.iter().find(|n| slaves.binary_search(n).is_ok()) {
                return Err(Error::Input(format!("{field}: `{group}` shares node {n} with contact.boundary; a target must be another body's boundary, apart from the contact boundary")));
            }
            let Some(centroid) = owner_centroid(mesh, &cells_of, a, b) else {
                return Err(Error::Input(format!("{field}: the edge {a}–{b} of `{group}` bounds no 2-D cell: name a boundary of a meshed body (a rigid curve is `{{curve: {group}}}`)")));
            };
            let p: Vec<[f64; 2]> = e.nodes.iter().map(|&n| mesh.nodes[n]).collect();
            let t = sub(p[1], p[0]);
            let mut outward = unit([t[1], -t[0]]);
            if dot(outward, sub(p[0], centroid)) < 0.0 {
                outward = [-outward[0], -outward[1]];
            }
            let piece = |a, b, half| Piece {
                a,
                b,
                outward,
                nodes: e.nodes.clone(),
                half,
            };
            if p.len() == 3 {
                pieces.push(piece(p[0], p[2], Some(true)));
                pieces.push(piece(p[2], p[1], Some(false)));
            } else {
                pieces.push(piece(p[0], p[1], None));
            }
        }
        let ends = free_ends(pieces.iter().flat_map(|p| [p.a, p.b]));
        Ok(TargetSurface { pieces, ends })
    }

    /// The projection of slave x (whose own outward normal is `outward`, if known); `None`
    /// when off the target.
    pub fn project(&self, x: [f64; 2], outward: Option<[f64; 2]>) -> Option<Projection> {
        let at = |p: &Piece| {
            let t = sub(p.b, p.a);
            let l2 = dot(t, t);
            let s = if l2 > 0.0 {
                (dot(sub(x, p.a), t) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let c = [p.a[0] + s * t[0], p.a[1] + s * t[1]];
            (dot(sub(x, c), sub(x, c)), s, c)
        };
        let (best, s, closest) = self
            .pieces
            .iter()
            .map(|p| (p, at(p)))
            .min_by(|(_, u), (_, v)| u.0.total_cmp(&v.0))
            .map(|(p, (_, s, c))| (p, s, c))?;
        // Every piece through the closest point (a vertex shared by two) votes for ν.
        let scale = dot(sub(best.b, best.a), sub(best.b, best.a)).sqrt();
        let mean = self
            .pieces
            .iter()
            .filter(|p| {
                let (_, _, c) = at(p);
                dot(sub(c, closest), sub(c, closest)).sqrt() <= 1e-12 * scale
            })
            .fold([0.0, 0.0], |m, p| {
                [m[0] + p.outward[0], m[1] + p.outward[1]]
            });
        let nu = unit(mean);
        let normal = [-nu[0], -nu[1]];
        let v = sub(closest, x);
        let vl = dot(v, v).sqrt();
        let at_end = self.ends.iter().any(|e| same_point(*e, closest));
        if at_end && vl > 0.0 && (dot(v, normal) / vl).abs() < 1.0 - 1e-9 {
            return None;
        }
        if outward.is_some_and(|o| dot(o, normal) <= 0.0) {
            return None;
        }
        Some(Projection {
            closest,
            normal,
            weights: weights(best, s),
        })
    }
}

/// The target edge's shape-function weights at fraction s of `piece`.
fn weights(piece: &Piece, s: f64) -> Vec<(usize, f64)> {
    let n = &piece.nodes;
    let w = match piece.half {
        None => vec![(n[0], 1.0 - s), (n[1], s)],
        Some(first) => {
            let xi = if first { s - 1.0 } else { s };
            vec![
                (n[0], 0.5 * xi * (xi - 1.0)),
                (n[1], 0.5 * xi * (xi + 1.0)),
                (n[2], 1.0 - xi * xi),
            ]
        }
    };
    w.into_iter().filter(|&(_, v)| v != 0.0).collect()
}
