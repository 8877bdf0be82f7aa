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

/// The largest `amplitudes.vtu` read back [bytes]: 3 values per node of each of 2H + 1
/// fields, in base64 binary, is about 100 MB for 100 000 nodes at H = 20.
pub const MAX_AMPLITUDES_BYTES: u64 = 1 << 30;

/// Read `amplitudes.vtu` like user input (a file anyone may edit): None when it is missing;
/// an error (exit 2) naming the file, with the fix, when it is larger than
/// `MAX_AMPLITUDES_BYTES`, does not read as an unstructured grid, or its points or fields
/// are not finite with 3 values per node, or none is an amplitude field.
pub fn read_amplitudes(path: &Path) -> crate::Result<Option<Amplitudes>> {
    let bad = |why: String| {
        let dir = path.parent().unwrap_or(path);
        crate::Error::Input(format!(
            "{} {why}: it was not written by this study's run or was changed since; delete the folder {} to run the rung again",
            path.display(),
            dir.display()
        ))
    };
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(crate::Error::io(path, e)),
        Ok(m) if m.len() > MAX_AMPLITUDES_BYTES => {
            return Err(bad(format!(
                "is larger than {} MiB, more than any rung writes",
                MAX_AMPLITUDES_BYTES >> 20
            )))
        }
        Ok(_) => {}
    }
    // The VTK reader is a dependency: a malformed file it cannot handle is refused, not a
    // crash of the study.
    let imported = std::panic::catch_unwind(|| Vtk::import(path))
        .map_err(|_| bad("does not read as VTK XML (the reader failed on it)".into()))?;
    let vtk = imported.map_err(|e| {
        bad(format!(
            "does not read as VTK XML ({})",
            crate::error::excerpt(&e.to_string())
        ))
    })?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Err(bad("is not an unstructured grid".into()));
    };
    let piece = pieces
        .into_iter()
        .next()
        .ok_or_else(|| bad("holds no piece".into()))?
        .into_loaded_piece_data(None)
        .map_err(|e| {
            bad(format!(
                "has a piece that does not load ({})",
                crate::error::excerpt(&e.to_string())
            ))
        })?;
    let points: Vec<f64> = piece
        .points
        .cast_into()
        .ok_or_else(|| bad("has points that are not numbers".into()))?;
    if !points.len().is_multiple_of(3) || points.iter().any(|v| !v.is_finite()) {
        return Err(bad(format!(
            "has {} point coordinates, not finite (x, y, z) triples",
            points.len()
        )));
    }
    let nodes: Vec<[f64; 2]> = points.chunks(3).map(|p| [p[0], p[1]]).collect();
    let mut fields = BTreeMap::new();
    for attribute in piece.data.point {
        if let Attribute::DataArray(a) = attribute {
            let name = crate::error::excerpt(&a.name);
            let values: Vec<f64> = a
                .data
                .cast_into()
                .ok_or_else(|| bad(format!("field `{name}` is not numbers")))?;
            if values.len() != 3 * nodes.len() || values.iter().any(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "field `{name}` has {} values, not finite 3 per node of its {} nodes",
                    values.len(),
                    nodes.len()
                )));
            }
            fields.insert(a.name.clone(), values);
        }
    }
    if !fields.keys().any(|name| weight(name).is_some()) {
        return Err(bad(
            "has no amplitude field (`static` or `harmonic_K_cos`, `harmonic_K_sin`) with 3 values per node".into(),
        ));
    }
    Ok(Some(Amplitudes { nodes, fields }))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An ASCII `amplitudes.vtu` of two nodes with one field, `static`, holding `values`.
    fn write_vtu(name: &str, values: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "hbcontact-amplitudes-{}",
            crate::files::unique_tag()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        let text = format!(
            r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
<UnstructuredGrid><Piece NumberOfPoints="2" NumberOfCells="1">
<PointData><DataArray type="Float64" Name="static" NumberOfComponents="3" format="ascii">{values}</DataArray></PointData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0 1 0 0</DataArray></Points>
<Cells><DataArray type="UInt64" Name="connectivity" format="ascii">0 1</DataArray>
<DataArray type="UInt64" Name="offsets" format="ascii">2</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">3</DataArray></Cells>
</Piece></UnstructuredGrid></VTKFile>
"#
        );
        std::fs::write(&path, text).unwrap();
        path
    }

    /// TEST GOAL: amplitudes.vtu is read back like user input: a well-formed file reads; a
    /// missing one is None; a field with fewer values than 3 per node (dropped by the VTK
    /// reader, leaving no amplitude field) or a NaN value is an error of exit class 2 naming the
    /// file, the field and the fix.
    #[test]
    fn amplitude_files_are_validated_before_the_l2_error_indexes_them() {
        let good = write_vtu("amplitudes.vtu", "1 2 0 3 4 0");
        let a = read_amplitudes(&good).unwrap().unwrap();
        assert_eq!(a.nodes, [[0.0, 0.0], [1.0, 0.0]]);
        assert_eq!(a.fields["static"], [1.0, 2.0, 0.0, 3.0, 4.0, 0.0]);
        assert!(relative_l2(&a, &a).is_some_and(|(e, n)| e == 0.0 && n == 2));
        assert!(read_amplitudes(&good.with_file_name("none.vtu"))
            .unwrap()
            .is_none());
        for (values, why) in [
            ("1 2 0", "has no amplitude field"),
            ("1 2 0 nan 4 0", "field `static` has 6 values"),
        ] {
            let bad = write_vtu("amplitudes.vtu", values);
            let e = match read_amplitudes(&bad) {
                Err(e) => e,
                Ok(a) => panic!("{values}: read {:?}", a.map(|a| a.fields)),
            };
            assert_eq!(e.exit_code(), 2);
            let text = e.to_string();
            assert!(
                text.contains(&bad.display().to_string())
                    && text.contains(why)
                    && text.contains("delete the folder"),
                "{text}"
            );
        }
    }
}
