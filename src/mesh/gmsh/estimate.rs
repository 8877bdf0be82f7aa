//! The element count a mesh will have, estimated before meshing. From the unrolled geometry
//! (gmsh `-0`): its bounding box of area A and the smallest size h it asks for bound it by
//! n ≤ `TRIANGLES_PER_AREA` · A / h². Above `TRIAL_ELEMENTS`, trial meshes at the mesh size
//! scaled up by s (aiming at `TRIAL_ELEMENTS` elements) with n_s elements estimate
//! n ≈ n_s s² (at most four trials, s shrunk while a trial is too coarse).

use std::collections::BTreeMap;
use std::path::Path;

use crate::progress::Reporter;
use crate::Result;

use super::*;

/// The elements a trial mesh aims at: enough that gmsh's per-curve minimum node counts are
/// negligible, few enough that it takes a fraction of a second.
pub(super) const TRIAL_ELEMENTS: f64 = 4000.0;

/// Elements of an equilateral-triangle mesh of size h per unit area: 4/(√3 h²).
const TRIANGLES_PER_AREA: f64 = 2.31;

/// What the geometry looks like before meshing (from gmsh `-0`): the bounding box of its points
/// and the smallest size it asks for anywhere (point sizes, field sizes, `-clmax`).
#[derive(Clone, Copy, Debug)]
struct Extent {
    area: f64,
    diagonal: f64,
    smallest_size: Option<f64>,
}

/// Read the points and sizes of an unrolled `.geo` (what gmsh `-0` writes: numbers and
/// `cl__N` variables).
fn parse_unrolled(text: &str) -> Option<Extent> {
    let mut vars: BTreeMap<String, f64> = BTreeMap::new();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut smallest = f64::INFINITY;
    let value = |vars: &BTreeMap<String, f64>, t: &str| -> Option<f64> {
        let t = t.trim();
        t.parse::<f64>().ok().or_else(|| vars.get(t).copied())
    };
    for line in text.lines() {
        let line = line.trim().trim_end_matches(';');
        let Some((lhs, rhs)) = line.split_once('=') else {
            continue;
        };
        let (lhs, rhs) = (lhs.trim(), rhs.trim());
        if lhs.starts_with("Point(") {
            let inner = rhs.trim_start_matches('{').trim_end_matches('}');
            let parts: Vec<&str> = inner.split(',').collect();
            let (Some(x), Some(y)) = (
                parts.first().and_then(|t| value(&vars, t)),
                parts.get(1).and_then(|t| value(&vars, t)),
            ) else {
                continue;
            };
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
            if let Some(lc) = parts.get(3).and_then(|t| value(&vars, t)) {
                if lc > 0.0 && lc < 1e20 {
                    smallest = smallest.min(lc);
                }
            }
        } else if let Some(field) = lhs.strip_prefix("Field[") {
            let attribute = field.split_once("].").map(|(_, a)| a).unwrap_or("");
            let is_size = attribute.starts_with("Size")
                || attribute.starts_with("Lc")
                || attribute == "VIn"
                || attribute == "VOut";
            if let (true, Some(v)) = (is_size, value(&vars, rhs)) {
                if v > 0.0 && v < 1e20 {
                    smallest = smallest.min(v);
                }
            }
        } else if !lhs.contains(['(', '[', '.', ' ']) {
            if let Ok(v) = rhs.parse::<f64>() {
                vars.insert(lhs.to_string(), v);
            }
        }
    }
    if !(lo[0].is_finite() && hi[0].is_finite()) {
        return None;
    }
    let (dx, dy) = (hi[0] - lo[0], hi[1] - lo[1]);
    let diagonal = (dx * dx + dy * dy).sqrt();
    let area = if dx > 0.0 && dy > 0.0 {
        dx * dy
    } else {
        diagonal * diagonal
    };
    Some(Extent {
        area,
        diagonal,
        smallest_size: smallest.is_finite().then_some(smallest),
    })
}

/// An estimate of the 2-D elements gmsh would make for `request`, without making them.
///
/// 1. gmsh `-0` (parse only) gives the points and every size the geometry asks for; with the
///    smallest size h (also `-clmax`) over the points' bounding box A, `2.31·A/h²` bounds the
///    count from above (fields may refine below h only where they name a smaller size, which is
///    counted). When that is below 4000 it is the estimate.
/// 2. Otherwise gmsh meshes with every size scaled by s (`-clscale`, applied after `-clmax`
///    and fields), s chosen for about 4000 elements by the bound; with n elements the estimate is
///    n·s² (2-D: the count scales with 1/size²). When n is small (gmsh's minimum nodes per curve
///    dominate), s is lowered (at most 10× per step) and gmsh meshes again, at most 4 times.
pub fn estimate_elements(
    cmd: &GmshCommand,
    request: &MeshRequest,
    scratch: &Path,
    limits: &MeshLimits,
    reporter: &dyn Reporter,
) -> Result<f64> {
    let out = scratch.join(format!("estimate-{}.msh", crate::files::unique_tag()));
    with_gmsh(cmd, request, limits, reporter, &out, |steps| {
        estimate_with(steps, request, scratch)
    })
}

/// The estimate (`estimate_elements`) through `steps`.
pub(super) fn estimate_with(
    steps: &mut dyn GmshSteps,
    request: &MeshRequest,
    scratch: &Path,
) -> std::result::Result<f64, Stop> {
    let base = format!("estimate-{}", crate::files::unique_tag());
    let unrolled = scratch.join(format!("{base}.geo_unrolled"));
    steps.unroll(&unrolled)?;
    let text = std::fs::read_to_string(&unrolled).unwrap_or_default();
    let _ = std::fs::remove_file(&unrolled);
    let extent = parse_unrolled(&text);
    let mut scale = match extent {
        Some(e) => {
            let h = [e.smallest_size, request.mesh_size, Some(e.diagonal)]
                .into_iter()
                .flatten()
                .filter(|h| *h > 0.0)
                .fold(f64::INFINITY, f64::min);
            let bound = TRIANGLES_PER_AREA * e.area / (h * h);
            if bound <= TRIAL_ELEMENTS {
                return Ok(bound);
            }
            (bound / TRIAL_ELEMENTS).sqrt()
        }
        // No points read (an OpenCASCADE geometry, say): start coarse and refine.
        None => 1e6,
    };
    let trial = scratch.join(format!("{base}.msh"));
    let mut estimate = 0.0;
    for _ in 0..4 {
        let meshed = steps.mesh(scale, &trial);
        let cells = meshed.map(|()| crate::mesh::msh::read_msh(&trial).map(|m| m.cells.len()));
        let _ = std::fs::remove_file(&trial);
        let n = cells?.map_err(Stop::Error)? as f64;
        estimate = n * scale * scale;
        if n >= TRIAL_ELEMENTS / 8.0 || scale <= 1.0 {
            break;
        }
        scale = (scale * (n.max(1.0) / TRIAL_ELEMENTS).sqrt())
            .max(scale / 10.0)
            .max(1.0);
    }
    Ok(estimate)
}
