//! Sanity checks that name the real cause of a bad scene before (or right after) a solve, so
//! that a mesh or geometry mistake is bad input (exit code 2) rather than a "singular" or
//! "resonant" solve, and a suspicious result carries a warning.
//!
//! Glossary and formulas:
//! - aspect ratio α of a cell = L² / (k A): L its longest corner edge, A the area of its
//!   corner polygon, k = 2 for triangles and 1 for quadrilaterals, so α = a/b for an a × b
//!   rectangle or either of its halves (an equilateral triangle: 1.15). Warned above
//!   `WARN_ASPECT`, refused above `geometry.max_aspect_ratio` (default `config::DEFAULT_MAX_ASPECT`).
//! - inverted cell: det J ≤ 0 at a Gauss point (a mid-side node beyond the opposite side).
//! - c_s = √(G/ρ), G = E / (2(1 + ν)): the shear wave speed, the slowest bulk wave.
//! - f_res = p c_s / (2 h): the highest frequency the mesh resolves, two elements of the
//!   longest edge h (order p) per shear wavelength. A load or motion harmonic k f above it is
//!   refused; a contact solve's top harmonic H f above it warns.
//! - S: the body's size, the diagonal of its nodes' bounding box. Initial penetration deeper
//!   than `SMALL_STRAIN` S, or a sampled penetration deeper than that, stretches small-strain
//!   elasticity: warned, naming the strain.
//! - parts: the cells' connected components (cells sharing a node are connected); more than
//!   one is refused unless `geometry.allow_disconnected`.
//! - empty groups: physical groups the .msh names but gives no element (warned; refused when
//!   the pipeline names one).
//! - locking: in plane strain λ/μ = 2ν/(1 − 2ν); from ν = `LOCKING_POISSON` (λ/μ = 49) the
//!   volumetric stiffness of displacement elements stiffens bending and shear (warned; the
//!   config refuses λ/μ ≥ 1e6).
//! - rigid-body motions of a part: u = (a − θ(y − y_c), b + θ(x − x_c)). Those that vanish on
//!   every held dof (`boundaries.fixed`, `boundaries.prescribed`) are free: the null space of
//!   A = Σ r rᵀ over the held dofs' rows r = (1, 0, −(y − y_c)/L) or (0, 1, (x − x_c)/L), L the
//!   part's size. Free motions warn; where harmonic balance needs the static stiffness (contact,
//!   or a static load or motion) they make K singular: an error naming them.
//! - spline scene (`check_spline_scene`, when the pipeline is loaded): with a spline basis of
//!   degree p and S segments, given samples N a multiple of S with at least p + 1 per segment
//!   (the contact quadrature), S odd in a sweep with contact (at S/2 an undamped Nyquist
//!   frequency), and S > 2k for every harmonic k of the loads and motions.
//! - initial penetration: contact nodes with a negative initial gap. Deeper than
//!   `SMALL_STRAIN` S it is refused unless `contact.allow_initial_penetration` (then warned).
//! - thin for its cells: at a boundary node, the thickness t is the distance along the inward
//!   normal (the mean of its boundary edges' inward normals; a boundary edge is a corner edge
//!   of one cell only) to the first boundary edge beyond, and h the longest corner edge of the
//!   node's cells. Where t < `THIN_CELLS` h (fewer than two cell lengths through the
//!   thickness) and t < S / `SLENDER` (a slender member, not a chunky body meshed coarsely),
//!   at `MIN_THIN_NODES` nodes or more, a first-order mesh warns: linear elements so coarse
//!   across a thickness are far too stiff in bending. The first natural frequency against
//!   the converged one, measured: a clamped 0.2 m × 2 mm strip in structured triangles, one
//!   through in 5 mm cells 3.2×, 2 to 20 through in 5 mm cells 2.8×, one through in 0.5 mm
//!   cells 1.9×; in quadrilaterals one through in 5 mm cells 1.8×; a clamped 100 mm × 5 mm
//!   beam in 6 mm unstructured triangles (one through) 1.37×, in 1 mm ones 1.03×; second
//!   order, one element through: within 0.3% on both.

use super::model::{Model, Purpose};
use std::collections::HashMap;
use std::path::Path;

use crate::config::{config_error, BasisSpec, Pipeline, PlaneModelSpec};
use crate::contact::geometry::ContactSet;
use crate::fem::{self, Material};
use crate::hbm::basis::TimeBasis;
use crate::hbm::sampler::SPLINE_SAMPLES_PER_SEGMENT;
use crate::hbm::Solution;
use crate::mesh::{CellKind, Mesh2d};
use crate::{Error, Result};

/// Aspect ratio above which a run warns.
pub const WARN_ASPECT: f64 = 20.0;
/// A strain beyond which small-strain elasticity is stretched (0.1%).
pub const SMALL_STRAIN: f64 = 1e-3;
/// Complementarity violation above which a contact run warns.
pub const VIOLATION_WARN: f64 = 0.15;
/// Poisson's ratio from which plane strain warns of locking (λ/μ = 49).
pub const LOCKING_POISSON: f64 = 0.49;
/// A body is thin for its cells where its thickness is below this many cell lengths.
pub const THIN_CELLS: f64 = 2.0;
/// ... and slender where its thickness is below its size over this.
pub const SLENDER: f64 = 5.0;
/// The thin boundary nodes from which a first-order mesh warns (fewer: a corner or a short
/// ligament, not a member that bends).
pub const MIN_THIN_NODES: usize = 4;

fn input(p: &Pipeline, message: String) -> Error {
    Error::Config {
        path: p.source.clone(),
        message,
    }
}

/// The diagonal of the bounding box of the nodes that carry cells [m].
pub fn body_size(mesh: &Mesh2d) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for n in mesh.body_nodes() {
        for c in 0..2 {
            lo[c] = lo[c].min(mesh.nodes[n][c]);
            hi[c] = hi[c].max(mesh.nodes[n][c]);
        }
    }
    ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt()
}

/// A cell's aspect ratio α and its longest corner edge.
fn aspect(mesh: &Mesh2d, cell: &crate::mesh::Cell) -> (f64, f64) {
    let k = cell.kind.corners();
    let (mut longest, mut area2) = (0.0f64, 0.0);
    for a in 0..k {
        let p = mesh.nodes[cell.nodes[a]];
        let q = mesh.nodes[cell.nodes[(a + 1) % k]];
        longest = longest.max((q[0] - p[0]).hypot(q[1] - p[1]));
        area2 += p[0] * q[1] - q[0] * p[1];
    }
    let area = 0.5 * area2.abs();
    let factor = if matches!(cell.kind, CellKind::Tri3 | CellKind::Tri6) {
        2.0
    } else {
        1.0
    };
    (longest * longest / (factor * area), longest)
}

/// Every cell's Jacobian positive at its Gauss points; the worst aspect ratio within the
/// limit. Returns the warnings and the longest cell edge.
fn cell_quality(p: &Pipeline, mesh: &Mesh2d, warnings: &mut Vec<String>) -> Result<f64> {
    let (mut worst, mut at, mut longest) = (0.0f64, 0usize, 0.0f64);
    for (i, cell) in mesh.cells.iter().enumerate() {
        let coords: Vec<[f64; 2]> = cell.nodes.iter().map(|&n| mesh.nodes[n]).collect();
        for (xi, eta, _) in fem::shapes::gauss(cell.kind, 2 * cell.kind.order()) {
            fem::elasticity::physical_derivatives(i, cell, &coords, xi, eta)?;
        }
        let (alpha, edge) = aspect(mesh, cell);
        longest = longest.max(edge);
        if !(alpha <= worst) {
            (worst, at) = (alpha, i);
        }
    }
    let where_ = mesh.nodes[mesh.cells[at].nodes[0]];
    let limit = p.geometry.max_aspect_ratio;
    if !(worst <= limit) {
        return Err(input(p, format!(
            "cell {at} (first node at ({:.4e}, {:.4e})) has aspect ratio {worst:.3e}, above geometry.max_aspect_ratio = {limit}: a degenerate element (its stiffness is ill-conditioned by about the ratio squared); remesh with a size near the body's thickness, or raise geometry.max_aspect_ratio",
            where_[0], where_[1]
        )));
    }
    if worst > WARN_ASPECT {
        warnings.push(format!(
            "the mesh's worst cell (cell {at}, first node at ({:.4e}, {:.4e})) has aspect ratio {worst:.1} (warned above {WARN_ASPECT}): stresses and thin-direction bending lose accuracy; refine across the thin direction",
            where_[0], where_[1]
        ));
    }
    Ok(longest)
}

/// The number of connected parts of the cells and one node of each part.
fn parts(mesh: &Mesh2d) -> Vec<(usize, usize)> {
    let roots_of = mesh.part_roots();
    let mut roots: std::collections::BTreeMap<usize, (usize, usize)> = Default::default();
    for (i, cell) in mesh.cells.iter().enumerate() {
        roots.entry(roots_of[cell.nodes[0]]).or_insert((0, i)).0 += 1;
    }
    roots.into_values().collect()
}

/// Whether the scene's contact is between two bodies and every part of the mesh holds a node
/// of its boundary or of its target (the parts are the bodies that contact joins).
fn contact_joins_parts(p: &Pipeline, mesh: &Mesh2d) -> bool {
    let groups: Vec<&String> = p
        .contact
        .iter()
        .flat_map(|c| &c.pairs)
        .filter_map(|pair| match &pair.obstacle {
            crate::config::ObstacleSpec::Body { group } => Some([&pair.boundary, group]),
            _ => None,
        })
        .flatten()
        .collect();
    if groups.is_empty() {
        return false;
    }
    let roots_of = mesh.part_roots();
    let touched: std::collections::BTreeSet<usize> = groups
        .into_iter()
        .filter_map(|g| mesh.node_groups.get(g))
        .flatten()
        .map(|&n| roots_of[n])
        .collect();
    mesh.cells
        .iter()
        .all(|cell| touched.contains(&roots_of[cell.nodes[0]]))
}

/// The highest harmonic a load or a prescribed motion excites.
fn top_load_harmonic(p: &Pipeline) -> usize {
    let loads = p
        .boundaries
        .loads
        .iter()
        .flat_map(|l| &l.signal.harmonics)
        .map(|h| h.0);
    let motions = p
        .boundaries
        .prescribed
        .iter()
        .flat_map(|m| &m.signal.harmonics)
        .map(|h| h.0);
    loads.chain(motions).max().unwrap_or(0)
}

/// f_res of the header [Hz].
fn resolvable_frequency(p: &Pipeline, material: &Material, longest_edge: f64) -> f64 {
    let shear = material.youngs_modulus / (2.0 * (1.0 + material.poisson_ratio));
    let c_s = (shear / material.density).sqrt();
    f64::from(p.geometry.order) * c_s / (2.0 * longest_edge)
}

/// The checks of the mesh before assembly: inverted or degenerate cells, disconnected
/// parts, loads beyond the mesh's resolution (errors: bad input); warnings otherwise.
pub fn check_mesh(p: &Pipeline, mesh: &Mesh2d) -> Result<Vec<String>> {
    let mut warnings = Vec::new();
    let longest = cell_quality(p, mesh, &mut warnings)?;
    let found = parts(mesh);
    if found.len() > 1 && !p.geometry.allow_disconnected && !contact_joins_parts(p, mesh) {
        let list: Vec<String> = found
            .iter()
            .map(|&(cells, first)| {
                let n = mesh.nodes[mesh.cells[first].nodes[0]];
                format!("{cells} cells near ({:.4e}, {:.4e})", n[0], n[1])
            })
            .collect();
        return Err(input(p, format!(
            "the mesh of {} has {} disconnected parts ({}): overlapping or separate bodies do not touch in a mesh; join them in the .geo (BooleanFragments, shared curves), or set geometry.allow_disconnected: true if each part is held on its own",
            p.geometry.file.display(),
            found.len(),
            list.join("; ")
        )));
    }
    let empty: Vec<&str> = mesh
        .node_groups
        .iter()
        .filter(|(_, nodes)| nodes.is_empty())
        .map(|(name, _)| name.as_str())
        .collect();
    if !empty.is_empty() {
        warnings.push(format!(
            "the physical groups {} of {} are empty (declared with no elements): a group named in the .geo but given nothing; the cells then belong to no named surface",
            empty.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", "),
            p.geometry.file.display()
        ));
    }
    warnings.extend(check_locking(p));
    warnings.extend(check_thickness(p, mesh));
    let material = super::model::material(p);
    let f_res = resolvable_frequency(p, &material, longest);
    let f = p.harmonic_balance.frequency;
    let k = top_load_harmonic(p);
    if k as f64 * f > f_res {
        return Err(input(p, format!(
            "harmonic {k} of the loads is at {:.4e} Hz, beyond the highest frequency the mesh resolves, {f_res:.4e} Hz (two elements of its longest edge {longest:.3e} m per shear wavelength): refine geometry.mesh_size below {:.3e} m, or lower harmonic_balance.frequency (is the unit Hz?)",
            k as f64 * f,
            longest * f_res / (k as f64 * f)
        )));
    }
    // The highest frequency the time basis holds: H, or ⌊S/2⌋ for S spline segments.
    let basis = super::model::time_basis(p, super::Purpose::HarmonicBalance);
    let (h, what) = match &basis {
        TimeBasis::Spline(s) => (
            s.frequencies() - 1,
            format!("the spline basis of {} segments", s.segments),
        ),
        TimeBasis::Fourier => {
            let hb = &p.harmonic_balance;
            let h = hb.harmonics_max;
            let key = if h > hb.harmonics {
                "harmonics.max"
            } else {
                "harmonics"
            };
            (h, format!("harmonic_balance.{key} = {h}"))
        }
    };
    if p.contact.is_some() && h as f64 * f > f_res {
        warnings.push(format!(
            "{what} reaches {:.4e} Hz, beyond the mesh's resolution {f_res:.4e} Hz: the top harmonics describe the mesh, not the body; refine geometry.mesh_size or lower {}",
            h as f64 * f,
            basis.refine_key()
        ));
    }
    Ok(warnings)
}

/// Near-incompressible plane strain: a warning naming locking and what to do.
fn check_locking(p: &Pipeline) -> Option<String> {
    let nu = p.material.poisson_ratio;
    if p.material.model != PlaneModelSpec::PlaneStrain || nu < LOCKING_POISSON {
        return None;
    }
    let ratio = 2.0 * nu / (1.0 - 2.0 * nu);
    let order = if p.geometry.order == 1 {
        "use geometry.order: 2 (linear elements lock worst) and "
    } else {
        ""
    };
    Some(format!(
        "material.poisson_ratio = {nu} in plane strain is near-incompressible (λ/μ = {ratio:.3e}, warned from ν = {LOCKING_POISSON}): displacement elements lock, their volumetric stiffness stiffens bending and shear, so displacements come out too small and natural frequencies too high; {order}check the answer on a finer mesh, or use a smaller ν if the material allows (mixed u–p elements are not available)"
    ))
}

/// A boundary node where the body is thin for its cells (see the header): where, the
/// thickness across it and the longest cell edge there [m], and the cells the thickness
/// crosses (one more than the interior edges the ray crosses).
#[derive(Clone, Copy, Debug)]
pub struct ThinSpot {
    pub node: usize,
    pub thickness: f64,
    pub size: f64,
    pub through: usize,
}

/// The boundary nodes where the body is thinner than `THIN_CELLS` of its cells there and
/// than `SLENDER` of its size: from each boundary corner node a ray along the inward normal
/// (the mean of its boundary edges' inward normals) to the first boundary edge it meets, at
/// most `THIN_CELLS` h away, h the longest corner edge of the node's cells.
pub fn thin_spots(mesh: &Mesh2d) -> Vec<ThinSpot> {
    let nodes = &mesh.nodes;
    let size = body_size(mesh);
    if !(size > 0.0 && size.is_finite()) {
        return Vec::new();
    }
    let (edges, boundary, longest) = corner_edges(mesh);
    if boundary == 0 {
        return Vec::new();
    }
    let normal = inward_normals(nodes, &edges[..boundary]);
    let grid = EdgeGrid::new(nodes, edges, boundary, size);
    let mut spots = Vec::new();
    let mut on_boundary: Vec<usize> = grid.edges.iter().flat_map(|&(p, q, _)| [p, q]).collect();
    on_boundary.sort_unstable();
    on_boundary.dedup();
    for n in on_boundary {
        let [nx, ny] = normal[n];
        let l = nx.hypot(ny);
        let h = longest[n];
        if !(l > 1e-6 && h > 0.0) {
            continue;
        }
        let reach = (THIN_CELLS * h).min(size / SLENDER);
        let (Some(t), mut crossed) = grid.cast(n, nodes[n], [nx / l, ny / l], reach) else {
            continue;
        };
        // Interior edges crossed before the far side, one per place (a ray through a node
        // crosses each of its edges there).
        crossed.retain(|&s| s < t * (1.0 - 1e-9));
        crossed.sort_by(f64::total_cmp);
        crossed.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * t);
        spots.push(ThinSpot {
            node: n,
            thickness: t,
            size: h,
            through: crossed.len() + 1,
        });
    }
    spots
}

/// A corner edge (p, q) with the centroid of a cell it bounds (the inside).
type CornerEdge = (usize, usize, [f64; 2]);

fn edge_length(nodes: &[[f64; 2]], a: usize, b: usize) -> f64 {
    (nodes[b][0] - nodes[a][0]).hypot(nodes[b][1] - nodes[a][1])
}

/// Every corner edge of the cells, the boundary ones (of one cell only) first, with their
/// count; and per node the longest corner edge of its cells.
fn corner_edges(mesh: &Mesh2d) -> (Vec<CornerEdge>, usize, Vec<f64>) {
    let nodes = &mesh.nodes;
    let mut uses: HashMap<(usize, usize), (u32, [f64; 2])> = HashMap::new();
    let mut longest = vec![0.0f64; nodes.len()];
    for cell in &mesh.cells {
        let k = &cell.nodes[..cell.kind.corners()];
        let mut centre = [0.0; 2];
        for &n in k {
            centre[0] += nodes[n][0] / k.len() as f64;
            centre[1] += nodes[n][1] / k.len() as f64;
        }
        let edge = (0..k.len())
            .map(|a| edge_length(nodes, k[a], k[(a + 1) % k.len()]))
            .fold(0.0f64, f64::max);
        for a in 0..k.len() {
            let (p, q) = (k[a], k[(a + 1) % k.len()]);
            let entry = uses.entry((p.min(q), p.max(q))).or_insert((0, centre));
            entry.0 += 1;
            longest[p] = longest[p].max(edge);
        }
    }
    let mut edges: Vec<CornerEdge> = Vec::with_capacity(uses.len());
    let mut interior = Vec::new();
    for ((p, q), (n, c)) in uses {
        if n == 1 {
            edges.push((p, q, c));
        } else {
            interior.push((p, q, c));
        }
    }
    let boundary = edges.len();
    edges.extend(interior);
    (edges, boundary, longest)
}

/// The inward unit normals of the `boundary` edges, summed per node.
fn inward_normals(nodes: &[[f64; 2]], boundary: &[CornerEdge]) -> Vec<[f64; 2]> {
    let mut normal = vec![[0.0f64; 2]; nodes.len()];
    for &(p, q, c) in boundary {
        let (a, b) = (nodes[p], nodes[q]);
        let l = edge_length(nodes, p, q);
        if !(l > 0.0) {
            continue;
        }
        let mut n = [-(b[1] - a[1]) / l, (b[0] - a[0]) / l];
        let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        if n[0] * (c[0] - mid[0]) + n[1] * (c[1] - mid[1]) < 0.0 {
            n = [-n[0], -n[1]];
        }
        for m in [p, q] {
            normal[m][0] += n[0];
            normal[m][1] += n[1];
        }
    }
    normal
}

/// The corner edges binned on a grid of cells the median boundary edge long (`g`), for
/// casting rays; edges longer than `LONG` cells are tested by every ray.
struct EdgeGrid<'a> {
    nodes: &'a [[f64; 2]],
    edges: Vec<CornerEdge>,
    /// The first `boundary` edges are on the boundary.
    boundary: usize,
    size: f64,
    g: f64,
    grid: HashMap<(i64, i64), Vec<usize>>,
    long: Vec<usize>,
}

impl<'a> EdgeGrid<'a> {
    const LONG: f64 = 8.0;

    fn new(nodes: &'a [[f64; 2]], edges: Vec<CornerEdge>, boundary: usize, size: f64) -> Self {
        let mut lengths: Vec<f64> = edges[..boundary]
            .iter()
            .map(|&(p, q, _)| edge_length(nodes, p, q))
            .collect();
        lengths.sort_by(f64::total_cmp);
        let g = lengths[lengths.len() / 2].max(1e-9 * size);
        let mut index = EdgeGrid {
            nodes,
            edges,
            boundary,
            size,
            g,
            grid: HashMap::new(),
            long: Vec::new(),
        };
        for i in 0..index.edges.len() {
            let (p, q, _) = index.edges[i];
            if edge_length(nodes, p, q) > Self::LONG * g {
                index.long.push(i);
                continue;
            }
            let (a, b) = (index.key(nodes[p]), index.key(nodes[q]));
            for x in a.0.min(b.0)..=a.0.max(b.0) {
                for y in a.1.min(b.1)..=a.1.max(b.1) {
                    index.grid.entry((x, y)).or_default().push(i);
                }
            }
        }
        index
    }

    fn key(&self, [x, y]: [f64; 2]) -> (i64, i64) {
        ((x / self.g).floor() as i64, (y / self.g).floor() as i64)
    }

    /// Along the ray o + s d, 0 < s ≤ reach: the distance to the nearest boundary edge not
    /// at node `from`, and the distances at which it crosses interior edges.
    fn cast(&self, from: usize, o: [f64; 2], d: [f64; 2], reach: f64) -> (Option<f64>, Vec<f64>) {
        let mut best: Option<f64> = None;
        let mut crossed = Vec::new();
        let mut test = |i: usize| {
            let Some(s) = self.hit(i, from, o, d, reach) else {
                return;
            };
            if i < self.boundary {
                best = Some(best.map_or(s, |b: f64| b.min(s)));
            } else {
                crossed.push(s);
            }
        };
        self.long.iter().for_each(|&i| test(i));
        let steps = (2.0 * reach / self.g).ceil() as usize;
        let mut seen = std::collections::HashSet::new();
        for k in 0..=steps {
            let s = reach * k as f64 / steps.max(1) as f64;
            let c = self.key([o[0] + s * d[0], o[1] + s * d[1]]);
            for x in c.0 - 1..=c.0 + 1 {
                for y in c.1 - 1..=c.1 + 1 {
                    if seen.insert((x, y)) {
                        self.grid
                            .get(&(x, y))
                            .into_iter()
                            .flatten()
                            .for_each(|&i| test(i));
                    }
                }
            }
        }
        (best, crossed)
    }

    /// Where the ray o + s d meets edge `i` (not one at node `from`), 0 < s ≤ reach.
    fn hit(&self, i: usize, from: usize, o: [f64; 2], d: [f64; 2], reach: f64) -> Option<f64> {
        let (p, q, _) = self.edges[i];
        if p == from || q == from {
            return None;
        }
        let (a, b) = (self.nodes[p], self.nodes[q]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let det = d[0] * (-e[1]) - d[1] * (-e[0]);
        if det.abs() <= 1e-300 {
            return None;
        }
        let r = [a[0] - o[0], a[1] - o[1]];
        let s = (r[0] * (-e[1]) - r[1] * (-e[0])) / det;
        let u = (d[0] * r[1] - d[1] * r[0]) / det;
        (s > 1e-9 * self.size && s <= reach && (0.0..=1.0).contains(&u)).then_some(s)
    }
}

/// A first-order mesh thin for its cells where the body is slender (`thin_spots`, at least
/// `MIN_THIN_NODES` boundary nodes): a warning with the thickness, the element size, where,
/// the error it may make in bending and the fix (second order).
fn check_thickness(p: &Pipeline, mesh: &Mesh2d) -> Option<String> {
    if p.geometry.order != 1 {
        return None;
    }
    let spots = thin_spots(mesh);
    if spots.len() < MIN_THIN_NODES {
        return None;
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let thickness = median(spots.iter().map(|s| s.thickness).collect());
    let size = median(spots.iter().map(|s| s.size).collect());
    let through = median(spots.iter().map(|s| s.through as f64).collect());
    let at = mesh.nodes[spots[0].node];
    let kind = if mesh.cells.iter().all(|c| c.kind.corners() == 3) {
        "triangles"
    } else if mesh.cells.iter().all(|c| c.kind.corners() == 4) {
        "quadrilaterals"
    } else {
        "elements"
    };
    let through = match through as usize {
        1 => "1 element".to_string(),
        n => format!("{n} elements"),
    };
    Some(format!(
        "geometry: {through} through a thickness of {thickness:.3e} m, in cells up to {size:.3e} m long (fewer than {THIN_CELLS} cell lengths through; at {} boundary nodes, the first at ({:.4e}, {:.4e})): linear {kind} are far too stiff in bending, so if that part bends its natural frequencies come out too high (the first measured 1.4× on a 100 mm × 5 mm cantilever in 6 mm triangles, 3.2× on a 0.2 m × 2 mm one in 5 mm structured triangles, 1.8× in 5 mm quadrilaterals); set geometry.order: 2 (within 0.3% on both, even one element through), or refine to cells no longer than a quarter of the thickness (within a few percent)",
        spots.len(),
        at[0],
        at[1]
    ))
}

/// The rigid-body motions that the held dofs leave free, per connected part of the mesh (the
/// part named by its cells and a node when there are several), described.
pub fn free_rigid_motions(p: &Pipeline, mesh: &Mesh2d) -> Vec<(String, Vec<String>)> {
    let roots = mesh.part_roots();
    let mut held = vec![[false; 2]; mesh.nodes.len()];
    for g in &p.boundaries.fixed {
        for &n in mesh.node_groups.get(g).into_iter().flatten() {
            held[n] = [true; 2];
        }
    }
    for pr in &p.boundaries.prescribed {
        for &n in mesh.node_groups.get(&pr.group).into_iter().flatten() {
            held[n][pr.component] = true;
        }
    }
    // Per part: its nodes (of cells), in first-cell order.
    let mut members: std::collections::BTreeMap<usize, (usize, Vec<usize>)> = Default::default();
    let mut seen = vec![false; mesh.nodes.len()];
    for (i, cell) in mesh.cells.iter().enumerate() {
        for &n in &cell.nodes {
            if !seen[n] {
                seen[n] = true;
                members
                    .entry(roots[n])
                    .or_insert_with(|| (i, Vec::new()))
                    .1
                    .push(n);
            }
        }
    }
    let several = members.len() > 1;
    let mut found = Vec::new();
    for (first_cell, nodes) in members.values() {
        let free = part_free_motions(mesh, nodes, &held);
        if free.is_empty() {
            continue;
        }
        let name = if several {
            let cells = mesh
                .cells
                .iter()
                .filter(|c| roots[c.nodes[0]] == roots[nodes[0]])
                .count();
            let at = mesh.nodes[mesh.cells[*first_cell].nodes[0]];
            format!(
                "the part of {cells} cells near ({:.4e}, {:.4e})",
                at[0], at[1]
            )
        } else {
            "the body".to_string()
        };
        found.push((name, free));
    }
    found
}

/// The free rigid-body motions of one part (`nodes`), described.
fn part_free_motions(mesh: &Mesh2d, nodes: &[usize], held: &[[bool; 2]]) -> Vec<String> {
    use nalgebra::{Matrix3, SymmetricEigen, Vector3};
    let count = nodes.len() as f64;
    let mut centre = [0.0; 2];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &n in nodes {
        for c in 0..2 {
            centre[c] += mesh.nodes[n][c] / count;
            lo[c] = lo[c].min(mesh.nodes[n][c]);
            hi[c] = hi[c].max(mesh.nodes[n][c]);
        }
    }
    let size = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    if !(size > 0.0 && size.is_finite()) {
        return Vec::new();
    }
    let mut a = Matrix3::<f64>::zeros();
    let mut rows = 0usize;
    for &n in nodes {
        let (dx, dy) = (
            (mesh.nodes[n][0] - centre[0]) / size,
            (mesh.nodes[n][1] - centre[1]) / size,
        );
        for (c, r) in [
            (0, Vector3::new(1.0, 0.0, -dy)),
            (1, Vector3::new(0.0, 1.0, dx)),
        ] {
            if held[n][c] {
                a += r * r.transpose();
                rows += 1;
            }
        }
    }
    let all = ["translation along x", "translation along y"]
        .map(str::to_string)
        .to_vec();
    if rows == 0 {
        let mut all = all;
        all.push(format!(
            "rotation about ({:.4e}, {:.4e})",
            centre[0], centre[1]
        ));
        return all;
    }
    let eigen = SymmetricEigen::new(a);
    let scale = eigen.eigenvalues.iter().cloned().fold(0.0f64, f64::max);
    let null: Vec<Vector3<f64>> = (0..3)
        .filter(|&i| eigen.eigenvalues[i] <= 1e-9 * scale)
        .map(|i| eigen.eigenvectors.column(i).into_owned())
        .collect();
    let describe = |v: Vector3<f64>| describe_rigid_motion([v[0], v[1], v[2]], centre, size);
    match null.as_slice() {
        [] => Vec::new(),
        [v] => vec![describe(*v)],
        [v, w] => {
            // The plane of free motions holds a translation (θ = 0): name it and the rotation
            // orthogonal to it.
            let translation = v * w[2] - w * v[2];
            let rotation = v * v[2] + w * w[2];
            vec![describe(translation), describe(rotation)]
        }
        _ => {
            let mut all = all;
            all.push(format!(
                "rotation about ({:.4e}, {:.4e})",
                centre[0], centre[1]
            ));
            all
        }
    }
}

/// The rigid motion (a, b, θ·size) about `centre` of a part `size` across, in words: a
/// translation (along x, y or a direction) or a rotation about the point it leaves fixed.
fn describe_rigid_motion(v: [f64; 3], centre: [f64; 2], size: f64) -> String {
    let (a, b, theta) = (v[0], v[1], v[2] / size);
    let t = a.hypot(b);
    if (v[2]).abs() <= 1e-6 * t {
        if b.abs() <= 1e-6 * t {
            "translation along x".to_string()
        } else if a.abs() <= 1e-6 * t {
            "translation along y".to_string()
        } else {
            format!("translation along ({:.3}, {:.3})", a / t, b / t)
        }
    } else {
        format!(
            "rotation about ({:.4e}, {:.4e})",
            centre[0] - b / theta,
            centre[1] + a / theta
        )
    }
}

/// Whether harmonic balance solves with the static stiffness K: contact couples harmonic 0
/// in, and a static load or motion is harmonic 0.
fn needs_static_stiffness(p: &Pipeline, purpose: Purpose) -> bool {
    let b = &p.boundaries;
    purpose == Purpose::HarmonicBalance
        && (p.contact.is_some()
            || b.loads.iter().any(|l| l.signal.static_part != [0.0; 2])
            || b.prescribed.iter().any(|m| m.signal.static_part != [0.0]))
}

/// Supports: rigid-body motions no held dof stops. A warning when the scene can still be
/// solved (a dynamic load on a free body); an error naming them where harmonic balance needs
/// the static stiffness, which they make singular.
pub fn check_supports(p: &Pipeline, mesh: &Mesh2d, purpose: Purpose) -> Result<Option<String>> {
    // A misspelt support group is that error (exit 2), not a free body.
    super::model::check_groups(p, mesh)?;
    let free = free_rigid_motions(p, mesh);
    if free.is_empty() {
        return Ok(None);
    }
    let list = free
        .iter()
        .map(|(part, motions)| {
            let verb = if motions.len() == 1 { "is" } else { "are" };
            format!("for {part}, {} {verb} free", motions.join(", "))
        })
        .collect::<Vec<_>>()
        .join("; ");
    let fix = "hold it with boundaries.fixed, or boundaries.prescribed on the free components, on a group";
    if needs_static_stiffness(p, purpose) {
        let why = if p.contact.is_some() {
            "a contact solve includes the static harmonic, and the obstacle alone does not hold a body in harmonic balance"
        } else {
            "the static load or motion has no equilibrium"
        };
        return Err(Error::Model(format!(
            "the body is not held against rigid-body motion ({list}: no dof of boundaries.fixed or boundaries.prescribed stops it), so the static stiffness K is singular and {why}; {fix}"
        )));
    }
    Ok(Some(format!(
        "the body is not held against rigid-body motion ({list}: no dof of boundaries.fixed or boundaries.prescribed stops it): it responds as a free body, with natural frequencies at 0 Hz and a response that grows as 1/ω² below its first elastic mode; if a support is meant, {fix}"
    )))
}

/// Contact nodes that start inside the obstacle: how many and the deepest penetration (≥ 0).
pub fn initial_penetration(set: &ContactSet) -> (usize, f64) {
    let count = set.gaps.iter().filter(|&&g| g < 0.0).count();
    let deepest = set.gaps.iter().cloned().fold(0.0f64, f64::min);
    (count, -deepest)
}

/// An initial penetration deeper than a small strain of the body's size: bad input (an
/// obstacle on the wrong side, a unit slip) unless `contact.allow_initial_penetration`, then
/// a warning.
pub fn check_initial_penetration(p: &Pipeline, model: &Model) -> Result<Option<String>> {
    match &model.contact {
        Some(contact) => check_penetration_of(p, &model.mesh, &contact.set),
        None => Ok(None),
    }
}

/// `check_initial_penetration` on a contact set.
pub fn check_penetration_of(
    p: &Pipeline,
    mesh: &Mesh2d,
    set: &ContactSet,
) -> Result<Option<String>> {
    let (count, depth) = initial_penetration(set);
    let size = body_size(mesh);
    if !(depth > SMALL_STRAIN * size) {
        return Ok(None);
    }
    let strain = 100.0 * depth / size;
    let allowed = p
        .contact
        .as_ref()
        .is_some_and(|c| c.allow_initial_penetration);
    if !allowed {
        let boundaries: Vec<String> = p
            .contact
            .iter()
            .flat_map(|c| &c.pairs)
            .map(|pair| format!("`{}`", pair.boundary))
            .collect();
        let boundary = boundaries.join(", ");
        return Err(input(p, format!(
            "{count} of {} contact nodes of {boundary} start inside the obstacle, the deepest by {depth:.3e} m (a strain of {strain:.2}% of the body's size {size:.3e} m, beyond small-strain elasticity's {}%): is the obstacle on the wrong side of the body (a line's normal points out of the obstacle toward the body; a circle's body_inside), or the geometry off by a unit or a sign? If the interference is meant (a preload), set contact.allow_initial_penetration: true",
            set.gaps.len(),
            100.0 * SMALL_STRAIN
        )));
    }
    Ok(Some(format!(
        "{count} contact nodes start inside the obstacle (contact.allow_initial_penetration), the deepest by {depth:.3e} m, a strain of {strain:.2}% of the body's size {size:.3e} m, beyond small-strain elasticity ({}%): expect the linear-elastic answer to be only indicative",
        100.0 * SMALL_STRAIN
    )))
}

/// Warnings on a harmonic-balance contact result: a sampled penetration beyond a small
/// strain of the body, and a complementarity violation above `VIOLATION_WARN`.
pub fn check_contact_result(model: &Model, solution: &Solution) -> Vec<String> {
    let mut warnings = Vec::new();
    let Some(c) = solution.contact.as_ref() else {
        return warnings;
    };
    let size = body_size(&model.mesh);
    let depth = c.complementarity.max_penetration;
    if depth > SMALL_STRAIN * size {
        warnings.push(format!(
            "the sampled solution penetrates the obstacle by up to {depth:.3e} m, a strain of {:.2}% of the body's size {size:.3e} m (beyond {}%): the loads are too large for small-strain elasticity, or the scene is too soft (material.youngs_modulus); check units and magnitudes",
            100.0 * depth / size,
            100.0 * SMALL_STRAIN
        ));
    }
    let violation = c.complementarity.violation;
    if violation > VIOLATION_WARN {
        warnings.push(format!(
            "the contact law holds only loosely at the samples (complementarity violation {violation:.3}, above {VIOLATION_WARN}): typical near grazing, where the contact is short; raise {} and compare",
            model.system.basis.refine_key()
        ));
    }
    warnings
}

/// A spline basis: samples (if given) a multiple of the segments with at least degree + 1
/// per segment, an odd number of segments in a sweep with contact, and more than two segments
/// per period of every harmonic the loads excite.
pub fn check_spline_scene(path: &Path, p: &Pipeline) -> Result<()> {
    let BasisSpec::Spline { degree, segments } = p.harmonic_balance.basis else {
        return Ok(());
    };
    if let Some(n) = p.harmonic_balance.samples {
        let per = SPLINE_SAMPLES_PER_SEGMENT;
        if !n.is_multiple_of(segments) || n / segments < degree + 1 {
            return Err(config_error(
                path,
                format!("harmonic_balance.samples = {n} must be a multiple of harmonic_balance.basis.spline.segments = {segments} with at least degree + 1 = {} per segment (the contact terms sample each segment at its Gauss points): use {} ({per} per segment, the default), or leave samples out", degree + 1, per * segments),
            ));
        }
    }
    if p.sweep.is_some() && p.contact.is_some() && segments.is_multiple_of(2) {
        return Err(config_error(
            path,
            format!("harmonic_balance.basis.spline.segments = {segments} is even: a sweep with contact needs an odd number of segments (with even S the Nyquist frequency S/2 has no damping, σ = 0, and somewhere in a sweep's range S/2·ω meets a mesh mode and the branch climbs without bound: docs/method.md §16); use segments = {}", segments + 1),
        ));
    }
    let b = &p.boundaries;
    let loads = b
        .loads
        .iter()
        .flat_map(|l| &l.signal.harmonics)
        .map(|h| h.0);
    let motions = b
        .prescribed
        .iter()
        .flat_map(|m| &m.signal.harmonics)
        .map(|h| h.0);
    if let Some(k) = loads.chain(motions).max().filter(|&k| 2 * k >= segments) {
        return Err(config_error(
            path,
            format!("harmonic_balance.basis.spline.segments = {segments} cannot carry harmonic k = {k} of the loads: use more than {} segments (several times more for accuracy)", 2 * k),
        ));
    }
    let gap = p
        .contact
        .iter()
        .flat_map(|c| c.gap_harmonics().map(|(_, k)| k));
    if let Some(k) = gap.max().filter(|&k| 2 * k >= segments) {
        return Err(config_error(
            path,
            format!("harmonic_balance.basis.spline.segments = {segments} cannot carry harmonic k = {k} of the obstacle's gap (contact.motion or lobes): use more than {} segments (several times more for accuracy)", 2 * k),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Cell;

    /// A structured strip [0, length] × [0, thickness] of nx × ny rectangles, each split into
    /// two triangles.
    fn strip(length: f64, thickness: f64, nx: usize, ny: usize) -> Mesh2d {
        let node = |i: usize, j: usize| j * (nx + 1) + i;
        let nodes = (0..=ny)
            .flat_map(|j| {
                (0..=nx).map(move |i| {
                    [
                        length * i as f64 / nx as f64,
                        thickness * j as f64 / ny as f64,
                    ]
                })
            })
            .collect();
        let mut cells = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let (a, b, c, d) = (
                    node(i, j),
                    node(i + 1, j),
                    node(i + 1, j + 1),
                    node(i, j + 1),
                );
                for nodes in [vec![a, b, c], vec![a, c, d]] {
                    cells.push(Cell {
                        kind: CellKind::Tri3,
                        nodes,
                    });
                }
            }
        }
        Mesh2d {
            nodes,
            cells,
            cell_groups: Default::default(),
            edge_groups: Default::default(),
            node_groups: Default::default(),
        }
    }

    /// TEST GOAL: the thickness rays measure what a structured strip is: 0.2 × 0.002 in
    /// 5 mm cells one row thick is thin at every long-side node but the ends' (thickness
    /// 2 mm away from the corners, one element through), four rows thick the rays cross
    /// three interior rows (four elements through), in 0.25 mm cells eight rows thick it is
    /// not thin, and a square meshed as coarsely as the strip is not slender.
    #[test]
    fn thickness_rays_count_the_elements_through_a_strip() {
        let spots = thin_spots(&strip(0.2, 0.002, 40, 1));
        let inner: Vec<&ThinSpot> = spots
            .iter()
            .filter(|s| (s.thickness - 0.002).abs() < 1e-12)
            .collect();
        assert_eq!(inner.len(), 2 * 39, "{spots:?}");
        assert!(inner.iter().all(|s| s.through == 1), "{inner:?}");
        assert!(inner
            .iter()
            .all(|s| (s.size - 0.005f64.hypot(0.002)).abs() < 1e-12));
        let four = thin_spots(&strip(0.2, 0.002, 40, 4));
        assert!(four
            .iter()
            .filter(|s| (s.thickness - 0.002).abs() < 1e-12)
            .all(|s| s.through == 4));
        assert!(thin_spots(&strip(0.2, 0.002, 800, 8)).is_empty());
        assert!(thin_spots(&strip(0.2, 0.2, 1, 1)).is_empty());
    }
}
