//! Sanity checks that name the real cause of a bad scene before (or right after) a solve, so
//! that a mesh or geometry mistake is bad input (exit code 2) rather than a "singular" or
//! "resonant" solve, and a suspicious result carries a warning.
//!
//! Glossary and formulas:
//! - aspect ratio α of a cell = L² / (k A): L its longest corner edge, A the area of its
//!   corner polygon, k = 2 for triangles and 1 for quadrilaterals, so α = a/b for an a × b
//!   rectangle or either of its halves (an equilateral triangle: 1.15). Warned above
//!   `WARN_ASPECT`, refused above `geometry.max_aspect_ratio` (default `DEFAULT_MAX_ASPECT`).
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

use super::model::Model;
use crate::config::Pipeline;
use crate::fem::{self, Material};
use crate::hbm::basis::TimeBasis;
use crate::hbm::Solution;
use crate::mesh::{CellKind, Mesh2d};
use crate::{Error, Result};

/// Aspect ratio above which a run warns.
pub const WARN_ASPECT: f64 = 20.0;
/// Default of `geometry.max_aspect_ratio`, above which a mesh is refused.
pub const DEFAULT_MAX_ASPECT: f64 = 1e3;
/// A strain beyond which small-strain elasticity is stretched (0.1%).
pub const SMALL_STRAIN: f64 = 1e-3;
/// Complementarity violation above which a contact run warns.
pub const VIOLATION_WARN: f64 = 0.15;

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
    let mut parent: Vec<usize> = (0..mesh.nodes.len()).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for cell in &mesh.cells {
        let a = find(&mut parent, cell.nodes[0]);
        for &n in &cell.nodes[1..] {
            let b = find(&mut parent, n);
            parent[b] = a;
        }
    }
    let mut roots: std::collections::BTreeMap<usize, (usize, usize)> = Default::default();
    for (i, cell) in mesh.cells.iter().enumerate() {
        let r = find(&mut parent, cell.nodes[0]);
        roots.entry(r).or_insert((0, i)).0 += 1;
    }
    roots.into_values().collect()
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
    if found.len() > 1 && !p.geometry.allow_disconnected {
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
            let h = p.harmonic_balance.harmonics;
            (h, format!("harmonic_balance.harmonics = {h}"))
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

/// An initial penetration beyond a small strain of the body's size (warning).
pub fn check_initial_penetration(model: &Model) -> Option<String> {
    let contact = model.contact.as_ref()?;
    let deepest = contact.set.gaps.iter().cloned().fold(0.0f64, f64::min);
    let size = body_size(&model.mesh);
    (-deepest > SMALL_STRAIN * size).then(|| format!(
        "the body starts {:.3e} m inside the obstacle, a strain of {:.2}% of its size {size:.3e} m, beyond small-strain elasticity ({}%): check the geometry's position (a unit or sign slip?), or expect the linear-elastic answer to be only indicative",
        -deepest,
        100.0 * -deepest / size,
        100.0 * SMALL_STRAIN
    ))
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
