//! VTU (XML unstructured grid) files and PVD collections for ParaView.

use std::path::Path;

use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, IOBuffer, UnstructuredGridPiece,
    Version, VertexNumbers,
};
use vtkio::Vtk;

use crate::mesh::{CellKind, Mesh2d};
use crate::{Error, Result};

/// A named array: `values.len() == count * components`.
#[derive(Clone, Debug)]
pub struct Field {
    pub name: String,
    pub components: usize,
    pub values: Vec<f64>,
}

fn cell_type(kind: CellKind) -> CellType {
    // gmsh and VTK agree on the node order of these five kinds (corners, mid-edges, centre).
    match kind {
        CellKind::Tri3 => CellType::Triangle,
        CellKind::Tri6 => CellType::QuadraticTriangle,
        CellKind::Quad4 => CellType::Quad,
        CellKind::Quad8 => CellType::QuadraticQuad,
        CellKind::Quad9 => CellType::BiquadraticQuad,
    }
}

fn check(path: &Path, f: &Field, count: usize) -> Result<()> {
    if f.values.len() != count * f.components {
        return Err(Error::Model(format!(
            "internal: field {} has {} values for {count} × {} ({})",
            f.name,
            f.values.len(),
            f.components,
            path.display()
        )));
    }
    Ok(())
}

/// Write the body cells with point and cell fields. Every mesh node is a point (obstacle nodes
/// simply belong to no cell), so point fields have one tuple per mesh node.
pub fn write_vtu(
    path: &Path,
    mesh: &Mesh2d,
    point_fields: &[Field],
    cell_fields: &[Field],
) -> Result<()> {
    let points: Vec<f64> = mesh.nodes.iter().flat_map(|p| [p[0], p[1], 0.0]).collect();
    let mut connectivity = Vec::new();
    let mut offsets = Vec::with_capacity(mesh.cells.len());
    let mut types = Vec::with_capacity(mesh.cells.len());
    for c in &mesh.cells {
        connectivity.extend(c.nodes.iter().map(|&n| n as u64));
        offsets.push(connectivity.len() as u64);
        types.push(cell_type(c.kind));
    }
    let mut data = Attributes::new();
    for f in point_fields {
        check(path, f, mesh.nodes.len())?;
        data.point.push(
            Attribute::generic(f.name.clone(), f.components as u32).with_data(f.values.clone()),
        );
    }
    for f in cell_fields {
        check(path, f, mesh.cells.len())?;
        data.cell.push(
            Attribute::generic(f.name.clone(), f.components as u32).with_data(f.values.clone()),
        );
    }
    export(path, points.into(), connectivity, offsets, types, data)
}

/// Write 2-node line cells between `points` (z = 0), without data: the obstacle outline.
pub fn write_lines_vtu(path: &Path, points: &[[f64; 2]], segments: &[[usize; 2]]) -> Result<()> {
    let coordinates: Vec<f64> = points.iter().flat_map(|p| [p[0], p[1], 0.0]).collect();
    let connectivity: Vec<u64> = segments.iter().flatten().map(|&i| i as u64).collect();
    let offsets: Vec<u64> = (1..=segments.len()).map(|i| 2 * i as u64).collect();
    let types = vec![CellType::Line; segments.len()];
    export(
        path,
        coordinates.into(),
        connectivity,
        offsets,
        types,
        Attributes::new(),
    )
}

/// One unstructured grid piece written as a `.vtu`, file version 1.0 (as fenris does) so that
/// ParaView reads 64-bit offsets without a warning.
fn export(
    path: &Path,
    points: IOBuffer,
    connectivity: Vec<u64>,
    offsets: Vec<u64>,
    types: Vec<CellType>,
    data: Attributes,
) -> Result<()> {
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points,
            cells: Cells {
                cell_verts: VertexNumbers::XML {
                    connectivity,
                    offsets,
                },
                types,
            },
            data,
        }),
    };
    // Written through a writer that keeps the first I/O error, whose kind vtkio's error
    // would lose (a full disk says so), and flushed explicitly (a failed flush on drop would
    // go unnoticed).
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = std::io::BufWriter::new(Recording {
        inner: file,
        first: None,
    });
    let written = vtk.write_xml(&mut out);
    let flushed = std::io::Write::flush(&mut out);
    let first = out.get_ref().first;
    match (written, flushed, first) {
        (Ok(()), Ok(()), _) => Ok(()),
        (_, _, Some((_, Some(raw)))) => {
            Err(Error::io(path, std::io::Error::from_raw_os_error(raw)))
        }
        (_, _, Some((kind, None))) => Err(Error::io(path, std::io::Error::from(kind))),
        (Err(e), _, None) => Err(Error::io(path, std::io::Error::other(format!("{e:?}")))),
        (Ok(()), Err(e), None) => Err(Error::io(path, e)),
    }
}

/// A writer that keeps the kind and OS code of the first error its inner writer gave.
struct Recording<W> {
    inner: W,
    first: Option<(std::io::ErrorKind, Option<i32>)>,
}

impl<W: std::io::Write> std::io::Write for Recording<W> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        let result = self.inner.write(bytes);
        if let Err(e) = &result {
            self.first.get_or_insert((e.kind(), e.raw_os_error()));
        }
        result
    }
    fn flush(&mut self) -> std::io::Result<()> {
        let result = self.inner.flush();
        if let Err(e) = &result {
            self.first.get_or_insert((e.kind(), e.raw_os_error()));
        }
        result
    }
}

/// A ParaView collection of (time, file relative to the .pvd) entries.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<()> {
    let mut s = String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n");
    for (t, file) in entries {
        s.push_str(&format!(
            "    <DataSet timestep=\"{t:e}\" group=\"\" part=\"0\" file=\"{file}\"/>\n"
        ));
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    std::fs::write(path, s).map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a VTU written to a full disk (Linux's /dev/full, whose every write fails
    /// with ENOSPC) fails saying the disk is full and naming the file, rather than vtkio's
    /// opaque error; a VTU small enough to sit in the write buffer fails too (its flush is
    /// checked).
    #[test]
    fn a_vtu_written_to_a_full_disk_says_the_disk_is_full() {
        let full = Path::new("/dev/full");
        assert!(full.exists(), "Linux provides /dev/full");
        let points = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]];
        let e = write_lines_vtu(full, &points, &[[0, 1], [1, 2]]).unwrap_err();
        let text = e.to_string();
        assert!(
            text.starts_with("/dev/full: the disk is full (") && text.contains("free space"),
            "{text}"
        );
        assert_eq!(e.exit_code(), 5);
        let many: Vec<[f64; 2]> = (0..10_000).map(|i| [i as f64, 0.0]).collect();
        let segments: Vec<[usize; 2]> = (1..many.len()).map(|i| [i - 1, i]).collect();
        let e = write_lines_vtu(full, &many, &segments).unwrap_err();
        assert!(e.to_string().contains("the disk is full"), "{e}");
    }
}
