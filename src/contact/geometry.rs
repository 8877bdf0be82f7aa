//! Contact candidates against an obstacle (rigid, or another meshed body's boundary, paired
//! node to segment in `pairing`): for each node of the tagged body boundary, the closest
//! obstacle point, the unit normal n_i pointing from the body into the obstacle, and the
//! initial gap g0_i = (closest − x_i)·n_i (negative: initial penetration, a preload);
//! the obstacle's outline for the output; and the arc length s_i of boundary nodes along the
//! boundary's edges (for plots against position on the contact boundary).

use std::collections::HashMap;

use super::pairing::TargetSurface;
use crate::mesh::{Edge, Mesh2d};
use crate::{Error, Result};

/// An obstacle: rigid, or the boundary of another meshed body.
#[derive(Clone, Debug, PartialEq)]
pub enum Obstacle {
    /// A curve of the geometry (a physical group meshed as 1-D elements only).
    Curve { group: String },
    /// The half-plane behind the line through `point`; `normal` (unit) points out of the
    /// obstacle, into the free space where the body is.
    Line { point: [f64; 2], normal: [f64; 2] },
    /// A circle; `body_inside` = the body lies inside it (a casing), else outside (a cylinder).
    Circle {
        center: [f64; 2],
        radius: f64,
        body_inside: bool,
    },
    /// The boundary curve `boundary` of another meshed body (elastic–elastic contact).
    Body { boundary: String },
}

/// Where contact is sought: the body boundary whose nodes are the candidates, the obstacle,
/// and how far from it a candidate may be (`None` keeps all).
#[derive(Clone, Debug)]
pub struct ContactScene {
    pub boundary: String,
    pub obstacle: Obstacle,
    pub search_distance: Option<f64>,
}

#[derive(Clone, Debug)]
pub struct ContactSet {
    /// Mesh node indices of the kept candidates, sorted within each contact pair (a node of
    /// two pairs has a row in each).
    pub nodes: Vec<usize>,
    /// Unit normals from the body toward (into) the obstacle.
    pub normals: Vec<[f64; 2]>,
    /// Initial gaps along the normals.
    pub gaps: Vec<f64>,
    /// Closest obstacle points.
    pub closest: Vec<[f64; 2]>,
    /// Boundary length attributed to each node: pressure = force / (tributary × thickness).
    /// 2-node edges give half their length to each end; 3-node edges their consistent weights
    /// (1/6, 1/6, 2/3 of the length to end, end, middle), or against a rigid obstacle, where
    /// the law acts on the corners (`mortar`), half of each adjacent edge (∫φ_a ds).
    pub tributary: Vec<f64>,
    /// Nodes of the boundary group.
    pub candidates: usize,
    pub dropped_off_obstacle: usize,
    pub dropped_beyond_search: usize,
    /// Candidates whose normal motion is fully held by boundary conditions: a support, not a
    /// contact (their multiplier would be undetermined).
    pub dropped_held: usize,
    /// Per kept node, the target body's nodes and their weights N_a at the closest point
    /// (B's row is n on the node and −N_a n on each target node); empty for a rigid obstacle.
    pub targets: Vec<Vec<(usize, f64)>>,
    /// Per kept node of a boundary of 3-node edges against a rigid obstacle, the middle nodes
    /// of its edges and their mortar weights w_m (`mortar_weights`; the node itself takes
    /// 1 − Σ w_m); empty when no row has any.
    pub mortar: Vec<Vec<(usize, f64)>>,
    /// The target boundary's nodes any row touches (sorted) and their tributary lengths.
    pub target_nodes: Vec<usize>,
    pub target_tributary: Vec<f64>,
}

impl ContactSet {
    /// Drop the nodes that cannot move along their normal (every dof the normal touches is
    /// held); `is_free(dof)` says whether a global dof is free.
    pub fn drop_held(&mut self, is_free: impl Fn(usize) -> bool) {
        let keep: Vec<bool> = (0..self.nodes.len())
            .map(|i| {
                let normal = self.normals[i];
                self.row_nodes(i)
                    .any(|(n, _)| (0..2).any(|c| normal[c] != 0.0 && is_free(2 * n + c)))
            })
            .collect();
        retain_by(&mut self.nodes, &keep);
        retain_by(&mut self.normals, &keep);
        retain_by(&mut self.gaps, &keep);
        retain_by(&mut self.closest, &keep);
        retain_by(&mut self.tributary, &keep);
        if !self.mortar.is_empty() {
            retain_by(&mut self.mortar, &keep);
        }
        if !self.targets.is_empty() {
            retain_by(&mut self.targets, &keep);
            let used: std::collections::BTreeSet<usize> =
                self.targets.iter().flatten().map(|&(a, _)| a).collect();
            let kept: Vec<bool> = self.target_nodes.iter().map(|a| used.contains(a)).collect();
            retain_by(&mut self.target_nodes, &kept);
            retain_by(&mut self.target_tributary, &kept);
        }
        self.dropped_held += keep.iter().filter(|&&k| !k).count();
    }

    /// A set without rows, of `candidates` boundary nodes.
    fn empty(candidates: usize) -> ContactSet {
        ContactSet {
            nodes: Vec::new(),
            normals: Vec::new(),
            gaps: Vec::new(),
            closest: Vec::new(),
            tributary: Vec::new(),
            candidates,
            dropped_off_obstacle: 0,
            dropped_beyond_search: 0,
            dropped_held: 0,
            targets: Vec::new(),
            mortar: Vec::new(),
            target_nodes: Vec::new(),
            target_tributary: Vec::new(),
        }
    }

    /// The sets of several contact pairs as one, their rows in order (a rigid pair's rows get
    /// no targets; a target node several pairs touch keeps its largest tributary length).
    pub fn concat(sets: &[ContactSet]) -> ContactSet {
        let mut out = ContactSet::empty(0);
        let any_targets = sets.iter().any(|s| !s.targets.is_empty());
        let any_mortar = sets.iter().any(|s| !s.mortar.is_empty());
        let mut tributary = std::collections::BTreeMap::new();
        for s in sets {
            out.nodes.extend(&s.nodes);
            out.normals.extend(&s.normals);
            out.gaps.extend(&s.gaps);
            out.closest.extend(&s.closest);
            out.tributary.extend(&s.tributary);
            out.candidates += s.candidates;
            out.dropped_off_obstacle += s.dropped_off_obstacle;
            out.dropped_beyond_search += s.dropped_beyond_search;
            out.dropped_held += s.dropped_held;
            for (any, own, all) in [
                (any_targets, &s.targets, &mut out.targets),
                (any_mortar, &s.mortar, &mut out.mortar),
            ] {
                if any {
                    match own.is_empty() {
                        true => all.extend(s.nodes.iter().map(|_| Vec::new())),
                        false => all.extend(own.iter().cloned()),
                    }
                }
            }
            for (&a, &l) in s.target_nodes.iter().zip(&s.target_tributary) {
                let t: &mut f64 = tributary.entry(a).or_insert(0.0);
                *t = t.max(l);
            }
        }
        (out.target_nodes, out.target_tributary) = tributary.into_iter().unzip();
        out
    }

    /// The nodes of row i of B and their weights: (node_i, 1 − Σ w_m) and each middle
    /// node's (m, w_m) of a mortar row, then each target node's (a, −N_a); B's entries are
    /// these weights times n_i.
    pub fn row_nodes(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let targets = self.targets.get(i).map_or(&[][..], |t| &t[..]);
        let mortar = self.mortar.get(i).map_or(&[][..], |m| &m[..]);
        let own = 1.0 - mortar.iter().map(|&(_, w)| w).sum::<f64>();
        std::iter::once((self.nodes[i], own))
            .chain(mortar.iter().copied())
            .chain(targets.iter().map(|&(a, w)| (a, -w)))
    }

    /// Every node a row of B touches (the contact nodes, the middle nodes of mortar rows and
    /// the target nodes), sorted.
    pub fn touched_nodes(&self) -> Vec<usize> {
        let middles = self.mortar.iter().flatten().map(|&(m, _)| m);
        let mut all: Vec<usize> = self
            .nodes
            .iter()
            .chain(&self.target_nodes)
            .copied()
            .chain(middles)
            .collect();
        all.sort_unstable();
        all.dedup();
        all
    }
}

/// Keep the entries whose flag is set.
fn retain_by<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut flags = keep.iter();
    v.retain(|_| flags.next().copied().unwrap_or(true));
}

pub(super) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

pub(super) fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// Outward unit normals of the body boundary at each candidate, averaged over its edges.
fn outward_normals(mesh: &Mesh2d, group: &str) -> HashMap<usize, [f64; 2]> {
    // Which cell owns each boundary edge: the cell containing both end nodes.
    let mut cells_of: HashMap<usize, Vec<usize>> = HashMap::new();
    for (i, c) in mesh.cells.iter().enumerate() {
        for &n in &c.nodes {
            cells_of.entry(n).or_default().push(i);
        }
    }
    let mut normals: HashMap<usize, [f64; 2]> = HashMap::new();
    for e in mesh
        .edge_groups
        .get(group)
        .map(Vec::as_slice)
        .unwrap_or(&[])
    {
        let (a, b) = (e.nodes[0], e.nodes[1]);
        let (pa, pb) = (mesh.nodes[a], mesh.nodes[b]);
        let t = sub(pb, pa);
        let mut n = [t[1], -t[0]];
        let owner = cells_of
            .get(&a)
            .and_then(|ca| ca.iter().find(|c| mesh.cells[**c].nodes.contains(&b)));
        if let Some(&c) = owner {
            let k = mesh.cells[c].nodes.len() as f64;
            let centroid = mesh.cells[c].nodes.iter().fold([0.0, 0.0], |s, &m| {
                [s[0] + mesh.nodes[m][0] / k, s[1] + mesh.nodes[m][1] / k]
            });
            if dot(n, sub(pa, centroid)) < 0.0 {
                n = [-n[0], -n[1]];
            }
        }
        for &m in &e.nodes {
            let acc = normals.entry(m).or_insert([0.0, 0.0]);
            acc[0] += n[0];
            acc[1] += n[1];
        }
    }
    for v in normals.values_mut() {
        let l = dot(*v, *v).sqrt();
        if l > 0.0 {
            *v = [v[0] / l, v[1] / l];
        }
    }
    normals
}

/// The obstacle curve as straight segments (3-node edges as two), with its free ends.
struct Polyline {
    segments: Vec<([f64; 2], [f64; 2])>,
    /// End points used by one segment only: a closest point there is "off the obstacle".
    ends: Vec<[f64; 2]>,
}

pub(super) fn same_point(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 1e-14 && (a[1] - b[1]).abs() < 1e-14
}

/// The segment ends (given as each segment's two ends in turn) that one segment uses alone:
/// the free ends of a curve.
pub(super) fn free_ends(points: impl Iterator<Item = [f64; 2]>) -> Vec<[f64; 2]> {
    let mut count: Vec<([f64; 2], usize)> = Vec::new();
    for p in points {
        match count.iter_mut().find(|(q, _)| same_point(*q, p)) {
            Some(e) => e.1 += 1,
            None => count.push((p, 1)),
        }
    }
    count
        .into_iter()
        .filter(|(_, c)| *c == 1)
        .map(|(p, _)| p)
        .collect()
}

impl Polyline {
    fn from_curve(mesh: &Mesh2d, group: &str, body: &[usize]) -> Result<Self> {
        if mesh.cell_groups.contains_key(group) {
            return Err(Error::Input(format!("contact.obstacle.curve: `{group}` has 2-D cells; an obstacle must be a curve meshed as line elements only")));
        }
        let Some(edges) = mesh.edge_groups.get(group) else {
            return Err(Error::Input(format!(
                "contact.obstacle.curve: no curve group `{group}` in the mesh.{}",
                mesh.group_hint(group)
            )));
        };
        if let Some(n) = mesh
            .node_groups
            .get(group)
            .and_then(|g| g.iter().find(|n| body.binary_search(n).is_ok()))
        {
            return Err(Error::Input(format!("contact.obstacle.curve: `{group}` shares node {n} with the body; draw the obstacle as a separate curve")));
        }
        let mut segments = Vec::new();
        for e in edges {
            let p: Vec<[f64; 2]> = e.nodes.iter().map(|&n| mesh.nodes[n]).collect();
            if p.len() == 3 {
                segments.extend([(p[0], p[2]), (p[2], p[1])]);
            } else {
                segments.push((p[0], p[1]));
            }
        }
        let ends = free_ends(segments.iter().flat_map(|(a, b)| [*a, *b]));
        Ok(Polyline { segments, ends })
    }

    /// The closest point to x, the unit normal there oriented along `outward` (into the
    /// obstacle), or `None` when x is off the obstacle (its closest point is a free end and x
    /// does not lie straight across from it).
    fn project(&self, x: [f64; 2], outward: Option<[f64; 2]>) -> Option<([f64; 2], [f64; 2])> {
        let mut best = (f64::INFINITY, [0.0; 2], [0.0; 2]);
        for (a, b) in &self.segments {
            let t = sub(*b, *a);
            let l2 = dot(t, t);
            let s = if l2 > 0.0 {
                (dot(sub(x, *a), t) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let c = [a[0] + s * t[0], a[1] + s * t[1]];
            let d = dot(sub(x, c), sub(x, c));
            if d < best.0 {
                let l = l2.sqrt().max(1e-300);
                best = (d, c, [t[1] / l, -t[0] / l]);
            }
        }
        let (_, c, mut nrm) = best;
        if dot(nrm, outward.unwrap_or(sub(c, x))) < 0.0 {
            nrm = [-nrm[0], -nrm[1]];
        }
        let v = sub(c, x);
        let vl = dot(v, v).sqrt();
        let at_end = self.ends.iter().any(|e| same_point(*e, c));
        if at_end && vl > 0.0 && (dot(v, nrm) / vl).abs() < 1.0 - 1e-9 {
            return None;
        }
        Some((c, nrm))
    }
}

/// An edge's length: end to end, or through its middle node (a 3-node edge as two pieces).
fn edge_length(mesh: &Mesh2d, e: &Edge) -> f64 {
    let length = |p: [f64; 2], q: [f64; 2]| dot(sub(q, p), sub(q, p)).sqrt();
    let (pa, pb) = (mesh.nodes[e.nodes[0]], mesh.nodes[e.nodes[1]]);
    match e.nodes.get(2) {
        Some(&m) => length(pa, mesh.nodes[m]) + length(mesh.nodes[m], pb),
        None => length(pa, pb),
    }
}

/// Boundary length attributed to each node of the edges (see `ContactSet::tributary`).
fn tributary_lengths(mesh: &Mesh2d, edges: &[Edge]) -> HashMap<usize, f64> {
    let mut tributary = HashMap::new();
    for e in edges {
        let len = edge_length(mesh, e);
        let weights: &[f64] = match e.nodes.len() {
            3 => &[1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
            _ => &[0.5, 0.5],
        };
        for (&n, w) in e.nodes.iter().zip(weights) {
            *tributary.entry(n).or_insert(0.0) += w * len;
        }
    }
    tributary
}

/// The contact boundary's nodes and edges, checked to be a curve of the body.
fn boundary<'m>(
    mesh: &'m Mesh2d,
    spec: &ContactScene,
    body: &[usize],
) -> Result<(&'m [usize], &'m [Edge])> {
    let Some(candidates) = mesh.node_groups.get(&spec.boundary) else {
        return Err(Error::Input(format!(
            "contact.boundary: no group `{}` in the mesh.{}",
            spec.boundary,
            mesh.group_hint(&spec.boundary)
        )));
    };
    let Some(edges) = mesh.edge_groups.get(&spec.boundary) else {
        return Err(Error::Input(format!(
            "contact.boundary: `{}` has no edges: it must be a curve of the body's boundary",
            spec.boundary
        )));
    };
    if candidates.iter().any(|n| body.binary_search(n).is_err()) {
        return Err(Error::Input(format!(
            "contact.boundary: `{}` has nodes outside the body (is it the obstacle curve?)",
            spec.boundary
        )));
    }
    Ok((candidates, edges))
}

/// The closest obstacle point and the normal into the obstacle for node `n` at x; `None` when
/// off a curve obstacle.
fn closest_point(
    spec: &Obstacle,
    polyline: Option<&Polyline>,
    n: usize,
    x: [f64; 2],
    outward: Option<[f64; 2]>,
) -> Result<Option<([f64; 2], [f64; 2])>> {
    Ok(match (spec, polyline) {
        (Obstacle::Line { point, normal }, _) => {
            let d = dot(sub(x, *point), *normal);
            Some((
                [x[0] - d * normal[0], x[1] - d * normal[1]],
                [-normal[0], -normal[1]],
            ))
        }
        (
            Obstacle::Circle {
                center,
                radius,
                body_inside,
            },
            _,
        ) => {
            let r = sub(x, *center);
            let len = dot(r, r).sqrt();
            if len < 1e-300 {
                return Err(Error::Input(format!("contact.obstacle.circle: node {n} sits at the centre of the circle obstacle; its normal is undefined")));
            }
            let u = [r[0] / len, r[1] / len];
            let c = [center[0] + radius * u[0], center[1] + radius * u[1]];
            Some((c, if *body_inside { u } else { [-u[0], -u[1]] }))
        }
        (Obstacle::Curve { .. }, Some(polyline)) => polyline.project(x, outward),
        (Obstacle::Curve { .. } | Obstacle::Body { .. }, None) => None,
        (Obstacle::Body { .. }, Some(_)) => None,
    })
}

/// A corner's middle nodes and their mortar weights.
type MortarRow = Vec<(usize, f64)>;

/// A node's closest obstacle point, the normal into the obstacle and (against a body) the
/// target weights.
type Projection = ([f64; 2], [f64; 2], Option<Vec<(usize, f64)>>);

/// The mortar weights of a boundary of 3-node edges (docs/method.md, "Quadratic elements"):
/// the law acts on the corners, each corner a's gap the average of the edge's gap over its
/// halves of the adjacent edges with the linear hat φ_a, g_a = Σ_j w_j g_j with
/// w_j = ∫φ_a N_j ds / ∫φ_a ds (∫φ_a N_a = L/6, ∫φ_a N_m = L/3, ∫φ_a N_b = 0 on an edge of
/// length L, ∫φ_a = L/2): the corner takes 1/3 and each adjacent middle node (L_e/3)/Σ(L/2).
struct Mortar {
    middles: std::collections::HashSet<usize>,
    /// Per corner, its edges' middle nodes and their weights.
    weights: HashMap<usize, Vec<(usize, f64)>>,
    /// Per corner, ∫φ_a ds: half of each adjacent edge (its force over this is a pressure).
    tributary: HashMap<usize, f64>,
}

impl Mortar {
    /// Corner `n`'s row (its middle nodes' weights), its weighted gap and ∫φ_a ds, from its
    /// own gap and each middle node's (`gap_of`; `None`: the middle node does not face the
    /// obstacle, and its weight stays with the corner).
    fn row(
        &self,
        n: usize,
        own_gap: f64,
        gap_of: impl Fn(usize) -> Result<Option<f64>>,
    ) -> Result<(MortarRow, f64, f64)> {
        let mut row = Vec::new();
        let mut gap = own_gap;
        for &(m, w) in self.weights.get(&n).map_or(&[][..], |v| &v[..]) {
            if let Some(g) = gap_of(m)? {
                gap += w * (g - own_gap);
                row.push((m, w));
            }
        }
        Ok((row, gap, self.tributary.get(&n).copied().unwrap_or(0.0)))
    }
}

/// The mortar weights of `edges` (`None` when none has 3 nodes: a linear boundary keeps its
/// node-wise law).
fn mortar_weights(mesh: &Mesh2d, edges: &[Edge]) -> Option<Mortar> {
    if !edges.iter().any(|e| e.nodes.len() == 3) {
        return None;
    }
    let mut mortar = Mortar {
        middles: edges
            .iter()
            .filter_map(|e| e.nodes.get(2).copied())
            .collect(),
        weights: HashMap::new(),
        tributary: HashMap::new(),
    };
    let mut raw: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    for e in edges {
        let (len, middle) = (edge_length(mesh, e), e.nodes.get(2).copied());
        for corner in [e.nodes[0], e.nodes[1]] {
            *mortar.tributary.entry(corner).or_insert(0.0) += 0.5 * len;
            if let Some(m) = middle {
                raw.entry(corner).or_default().push((m, len / 3.0));
            }
        }
    }
    for (corner, entries) in raw {
        let total = mortar.tributary.get(&corner).copied().unwrap_or(1.0);
        let weights = entries.into_iter().map(|(m, v)| (m, v / total)).collect();
        mortar.weights.insert(corner, weights);
    }
    Some(mortar)
}

/// Build the candidates' normals and gaps (and, against a body, the target weights).
pub fn build_contact_set(mesh: &Mesh2d, spec: &ContactScene) -> Result<ContactSet> {
    let body = mesh.body_nodes();
    let (candidates, edges) = boundary(mesh, spec, &body)?;
    let tributary = tributary_lengths(mesh, edges);
    let polyline = match &spec.obstacle {
        Obstacle::Curve { group } => Some(Polyline::from_curve(mesh, group, &body)?),
        _ => None,
    };
    let target = match &spec.obstacle {
        Obstacle::Body { boundary } => Some(TargetSurface::new(mesh, boundary, candidates)?),
        _ => None,
    };
    let outward = outward_normals(mesh, &spec.boundary);
    // A rigid obstacle against 3-node edges: the law on the corners, mortar-weighted.
    let mortar = match target {
        None => mortar_weights(mesh, edges),
        Some(_) => None,
    };
    let is_middle = |n: &usize| mortar.as_ref().is_some_and(|m| m.middles.contains(n));
    let corners = candidates.iter().filter(|n| !is_middle(n)).count();
    let mut set = ContactSet::empty(corners);
    let mut smallest_gap = f64::INFINITY;
    let project = |n: usize| -> Result<Option<Projection>> {
        let x = mesh.nodes[n];
        Ok(match &target {
            Some(t) => t
                .project(x, outward.get(&n).copied())
                .map(|p| (p.closest, p.normal, Some(p.weights))),
            None => closest_point(
                &spec.obstacle,
                polyline.as_ref(),
                n,
                x,
                outward.get(&n).copied(),
            )?
            .map(|(c, nrm)| (c, nrm, None)),
        })
    };
    for &n in candidates.iter().filter(|n| !is_middle(n)) {
        let x = mesh.nodes[n];
        let Some((mut closest, normal, weights)) = project(n)? else {
            set.dropped_off_obstacle += 1;
            continue;
        };
        let mut gap = dot(sub(closest, x), normal);
        let mut tributary_n = tributary.get(&n).copied().unwrap_or(0.0);
        let mut mortar_row = None;
        if let Some(m) = &mortar {
            let gap_of = |j: usize| {
                let found = project(j)?;
                Ok(found.map(|(c, nrm, _)| dot(sub(c, mesh.nodes[j]), nrm)))
            };
            let row;
            (row, gap, tributary_n) = m.row(n, gap, gap_of)?;
            mortar_row = Some(row);
            // The corner's point at the weighted gap (x + g n still holds).
            closest = [x[0] + gap * normal[0], x[1] + gap * normal[1]];
        }
        smallest_gap = smallest_gap.min(gap);
        if spec.search_distance.is_some_and(|limit| gap > limit) {
            set.dropped_beyond_search += 1;
            continue;
        }
        set.nodes.push(n);
        set.normals.push(normal);
        set.gaps.push(gap);
        set.closest.push(closest);
        set.tributary.push(tributary_n);
        set.mortar.extend(mortar_row);
        if let Some(w) = weights {
            set.targets.push(w);
        }
    }
    finished(mesh, spec, set, smallest_gap)
}

/// The set built, with its target nodes indexed; refused when no candidate is left.
fn finished(
    mesh: &Mesh2d,
    spec: &ContactScene,
    mut set: ContactSet,
    smallest_gap: f64,
) -> Result<ContactSet> {
    if set.nodes.is_empty() {
        return Err(Error::Input(format!(
            "contact: none of the {} nodes of `{}` faces the obstacle ({} off the obstacle, {} farther than search_distance; smallest gap {smallest_gap:e}): extend the obstacle, raise contact.search_distance, or check the geometry",
            set.candidates, spec.boundary, set.dropped_off_obstacle, set.dropped_beyond_search
        )));
    }
    if let Obstacle::Body { boundary } = &spec.obstacle {
        set.index_targets(mesh, boundary);
    }
    Ok(set)
}

impl ContactSet {
    /// `target_nodes` and `target_tributary` from `targets` (the target group's edges).
    fn index_targets(&mut self, mesh: &Mesh2d, group: &str) {
        let edges = mesh.edge_groups.get(group).map_or(&[][..], Vec::as_slice);
        let tributary = tributary_lengths(mesh, edges);
        let mut nodes: Vec<usize> = self.targets.iter().flatten().map(|&(a, _)| a).collect();
        nodes.sort_unstable();
        nodes.dedup();
        self.target_tributary = nodes
            .iter()
            .map(|a| tributary.get(a).copied().unwrap_or(0.0))
            .collect();
        self.target_nodes = nodes;
    }
}

/// Circle arcs and closed circles drawn with this many segments.
pub const ARC_SEGMENTS: usize = 64;

/// The obstacle as line segments for the output (`obstacle.vtu`): the points and the segments
/// between them (indices into the points).
#[derive(Clone, Debug, Default)]
pub struct ObstacleOutline {
    pub points: Vec<[f64; 2]>,
    pub segments: Vec<[usize; 2]>,
}

/// What to draw of the obstacle: a line as the segment spanning the contact nodes' closest
/// points plus a margin of a tenth of that span on each side (at least 1% of the mesh's size);
/// a circle as the arc over the closest points' angular extent plus a tenth of it on each
/// side (at least 1°), in `ARC_SEGMENTS` segments (the whole circle if the arc would close);
/// a curve as its mesh edges (a 3-node edge as two segments through its middle node). Every
/// point lies on the obstacle (a line or circle to round-off; a curve's are its mesh nodes).
pub fn obstacle_outline(mesh: &Mesh2d, obstacle: &Obstacle, set: &ContactSet) -> ObstacleOutline {
    match obstacle {
        Obstacle::Line { point, normal } => line_outline(mesh, set, *point, *normal),
        Obstacle::Circle { center, radius, .. } => circle_outline(set, *center, *radius),
        Obstacle::Curve { group } => curve_outline(mesh, group),
        Obstacle::Body { .. } => ObstacleOutline::default(),
    }
}

/// The line's segment under the contact nodes, 10% longer at each end (at least 1% of the
/// mesh's size).
fn line_outline(
    mesh: &Mesh2d,
    set: &ContactSet,
    point: [f64; 2],
    normal: [f64; 2],
) -> ObstacleOutline {
    let tangent = [-normal[1], normal[0]];
    let s: Vec<f64> = set
        .closest
        .iter()
        .map(|c| dot(sub(*c, point), tangent))
        .collect();
    let lo = s.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = s.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
    let margin = (0.1 * (hi - lo)).max(0.01 * mesh_size(mesh));
    let at = |s: f64| [point[0] + s * tangent[0], point[1] + s * tangent[1]];
    ObstacleOutline {
        points: vec![at(lo - margin), at(hi + margin)],
        segments: vec![[0, 1]],
    }
}

/// The circle's arc under the contact nodes (the circle minus the largest empty gap between
/// their angles), 10% wider at each end (at least 1°), in `ARC_SEGMENTS` segments.
fn circle_outline(set: &ContactSet, center: [f64; 2], radius: f64) -> ObstacleOutline {
    let mut angles: Vec<f64> = set
        .closest
        .iter()
        .map(|c| (c[1] - center[1]).atan2(c[0] - center[0]))
        .collect();
    angles.sort_by(f64::total_cmp);
    let tau = 2.0 * std::f64::consts::PI;
    let (mut start, mut span) = (0.0, tau);
    if let (Some(&first), Some(&last)) = (angles.first(), angles.last()) {
        let mut gap = (first + tau - last, last);
        for w in angles.windows(2) {
            if w[1] - w[0] > gap.0 {
                gap = (w[1] - w[0], w[0]);
            }
        }
        let extent = tau - gap.0;
        let margin = (0.1 * extent).max(1f64.to_radians());
        span = extent + 2.0 * margin;
        start = gap.1 + gap.0 - margin;
    }
    let closed = span >= tau;
    let span = span.min(tau);
    let n = ARC_SEGMENTS;
    let count = if closed { n } else { n + 1 };
    let points = (0..count)
        .map(|j| {
            let a = start + span * j as f64 / n as f64;
            [center[0] + radius * a.cos(), center[1] + radius * a.sin()]
        })
        .collect();
    let segments = (0..n).map(|j| [j, (j + 1) % count]).collect();
    ObstacleOutline { points, segments }
}

/// The obstacle curve's edges as the mesh holds them (a quadratic edge as two segments).
fn curve_outline(mesh: &Mesh2d, group: &str) -> ObstacleOutline {
    let mut index: HashMap<usize, usize> = HashMap::new();
    let mut outline = ObstacleOutline::default();
    let edges = mesh
        .edge_groups
        .get(group)
        .map(Vec::as_slice)
        .unwrap_or(&[]);
    for e in edges {
        let ids: Vec<usize> = e
            .nodes
            .iter()
            .map(|&n| {
                *index.entry(n).or_insert_with(|| {
                    outline.points.push(mesh.nodes[n]);
                    outline.points.len() - 1
                })
            })
            .collect();
        if ids.len() == 3 {
            outline
                .segments
                .extend([[ids[0], ids[2]], [ids[2], ids[1]]]);
        } else if ids.len() == 2 {
            outline.segments.push([ids[0], ids[1]]);
        }
    }
    outline
}

/// The diagonal of the mesh's bounding box.
fn mesh_size(mesh: &Mesh2d) -> f64 {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in &mesh.nodes {
        for c in 0..2 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let d = sub(hi, lo);
    if d[0].is_finite() {
        dot(d, d).sqrt()
    } else {
        1.0
    }
}

/// Arc length s_i [m] of each of `nodes` along the undeformed edges of the boundary group
/// `boundary` (a 3-node edge as two straight pieces through its middle node): the shortest
/// distance along the edges from a start node, which on an open curve is its end with the
/// smallest x (then y), so s runs from that end to the other; a closed curve starts at its
/// node of smallest x. A group of several separate curves is measured curve after curve, each
/// starting where the previous one's largest s ended. Nodes not on the group's edges get NaN.
pub fn arc_lengths(mesh: &Mesh2d, boundary: &str, nodes: &[usize]) -> Vec<f64> {
    let mut neighbours: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    let length = |a: usize, b: usize| {
        let d = sub(mesh.nodes[b], mesh.nodes[a]);
        dot(d, d).sqrt()
    };
    for e in mesh.edge_groups.get(boundary).into_iter().flatten() {
        let pieces: &[[usize; 2]] = match e.nodes.as_slice() {
            [a, b, m] => &[[*a, *m], [*m, *b]],
            [a, b, ..] => &[[*a, *b]],
            _ => &[],
        };
        for &[a, b] in pieces {
            neighbours.entry(a).or_default().push((b, length(a, b)));
            neighbours.entry(b).or_default().push((a, length(a, b)));
        }
    }
    let mut s: HashMap<usize, f64> = HashMap::new();
    let mut offset = 0.0;
    loop {
        let left = neighbours.keys().filter(|n| !s.contains_key(n));
        let ends = left.clone().filter(|n| neighbours[n].len() == 1);
        let leftmost = |a: &&usize, b: &&usize| {
            let (p, q) = (mesh.nodes[**a], mesh.nodes[**b]);
            p[0].total_cmp(&q[0])
                .then(p[1].total_cmp(&q[1]))
                .then(a.cmp(b))
        };
        let Some(&start) = ends.min_by(leftmost).or_else(|| left.min_by(leftmost)) else {
            break;
        };
        let reached = distances_from(&neighbours, start);
        let end = reached.values().fold(0.0f64, |a, &d| a.max(d));
        s.extend(reached.into_iter().map(|(n, d)| (n, offset + d)));
        offset += end;
    }
    nodes
        .iter()
        .map(|n| s.get(n).copied().unwrap_or(f64::NAN))
        .collect()
}

/// Dijkstra: the shortest distance along the graph from `start` to every node it reaches.
fn distances_from(
    neighbours: &HashMap<usize, Vec<(usize, f64)>>,
    start: usize,
) -> HashMap<usize, f64> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    // Non-negative finite f64 order like their bit patterns, so the heap can key on the bits.
    let mut heap = BinaryHeap::from([Reverse((0f64.to_bits(), start))]);
    let mut done: HashMap<usize, f64> = HashMap::new();
    while let Some(Reverse((bits, n))) = heap.pop() {
        if done.contains_key(&n) {
            continue;
        }
        let d = f64::from_bits(bits);
        done.insert(n, d);
        for &(m, w) in neighbours.get(&n).into_iter().flatten() {
            if !done.contains_key(&m) {
                heap.push(Reverse(((d + w).to_bits(), m)));
            }
        }
    }
    done
}
