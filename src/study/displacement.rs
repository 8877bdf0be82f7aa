//! The displacement L2 error over space and period between two harmonic-balance runs, from
//! the harmonic amplitudes each wrote on its nodes (`amplitudes.vtu`).
//!
//! Glossary: a_0 the static part (`static`), a_k and b_k the cosine and sine amplitudes of
//! harmonic k (`harmonic_k_cos`, `harmonic_k_sin`), all 2-vectors per node; T the period.
//! Parseval: (1/T)∫₀ᵀ|u(t)|² dt = |a_0|² + ½ Σ_k (|a_k|² + |b_k|²), so with a harmonic that
//! one run lacks counted as zero,
//!   e_L2 = √( Σ_n (1/T)∫|u_n − u_ref,n|² dt ) / √( Σ_n (1/T)∫|u_ref,n|² dt ),
//! n over the nodes compared, each weighted equally: every node when both runs have the same
//! nodes, else the nodes at the same coordinates in both (to 1e-9 of the reference's size).

use std::collections::BTreeMap;
use std::path::Path;

use vtkio::model::{Attribute, DataSet};
use vtkio::Vtk;

/// The amplitudes of one run: node coordinates and each field's values (3 per node).
pub struct Amplitudes {
    pub nodes: Vec<[f64; 2]>,
    pub fields: BTreeMap<String, Vec<f64>>,
}

/// Read `amplitudes.vtu` (None when missing or unreadable).
pub fn read_amplitudes(path: &Path) -> Option<Amplitudes> {
    let vtk = Vtk::import(path).ok()?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return None;
    };
    let piece = pieces
        .into_iter()
        .next()?
        .into_loaded_piece_data(None)
        .ok()?;
    let points: Vec<f64> = piece.points.cast_into()?;
    let nodes = points.chunks(3).map(|p| [p[0], p[1]]).collect();
    let mut fields = BTreeMap::new();
    for attribute in piece.data.point {
        if let Attribute::DataArray(a) = attribute {
            fields.insert(a.name.clone(), a.data.cast_into::<f64>()?);
        }
    }
    Some(Amplitudes { nodes, fields })
}

/// The Parseval weight of a field: 1 for the static part, ½ for a harmonic's cos or sin.
fn weight(name: &str) -> Option<f64> {
    match name {
        "static" => Some(1.0),
        n if n.starts_with("harmonic_") => Some(0.5),
        _ => None,
    }
}

/// Pairs (rung node, reference node) compared: all nodes when the meshes agree, else the
/// nodes at the same coordinates.
fn node_pairs(rung: &[[f64; 2]], reference: &[[f64; 2]]) -> Vec<(usize, usize)> {
    let (lo, hi) = reference.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        },
    );
    let tol = 1e-9 * (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    let same =
        |a: &[f64; 2], b: &[f64; 2]| (a[0] - b[0]).abs() <= tol && (a[1] - b[1]).abs() <= tol;
    if rung.len() == reference.len() && rung.iter().zip(reference).all(|(a, b)| same(a, b)) {
        return (0..rung.len()).map(|i| (i, i)).collect();
    }
    let mut by_x: Vec<usize> = (0..reference.len()).collect();
    by_x.sort_by(|&i, &j| reference[i][0].total_cmp(&reference[j][0]));
    let mut pairs = Vec::new();
    for (i, p) in rung.iter().enumerate() {
        let from = by_x.partition_point(|&j| reference[j][0] < p[0] - tol);
        let hit = by_x[from..]
            .iter()
            .take_while(|&&j| reference[j][0] <= p[0] + tol)
            .find(|&&j| same(p, &reference[j]));
        if let Some(&j) = hit {
            pairs.push((i, j));
        }
    }
    pairs
}

/// e_L2 of `rung` against `reference` and the number of nodes compared (None: no node in
/// common, or a reference at rest).
pub fn relative_l2(rung: &Amplitudes, reference: &Amplitudes) -> Option<(f64, usize)> {
    let pairs = node_pairs(&rung.nodes, &reference.nodes);
    let names: std::collections::BTreeSet<&String> =
        rung.fields.keys().chain(reference.fields.keys()).collect();
    let (mut difference, mut norm) = (0.0, 0.0);
    for name in names {
        let Some(w) = weight(name) else { continue };
        let (a, b) = (rung.fields.get(name), reference.fields.get(name));
        for &(i, j) in &pairs {
            for c in 0..2 {
                let u = a.map_or(0.0, |v| v[3 * i + c]);
                let r = b.map_or(0.0, |v| v[3 * j + c]);
                difference += w * (u - r) * (u - r);
                norm += w * r * r;
            }
        }
    }
    (!pairs.is_empty() && norm > 0.0).then(|| ((difference / norm).sqrt(), pairs.len()))
}
