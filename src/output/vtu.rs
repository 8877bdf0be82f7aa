//! VTU (XML unstructured grid) files and PVD collections.
use std::path::Path;

use crate::mesh::Mesh2d;
use crate::Result;

/// A named array: `values.len() == count * components`.
#[derive(Clone, Debug)]
pub struct Field {
    pub name: String,
    pub components: usize,
    pub values: Vec<f64>,
}

pub fn write_vtu(path: &Path, mesh: &Mesh2d, point_fields: &[Field], cell_fields: &[Field]) -> Result<()> {
    let _ = (path, mesh, point_fields, cell_fields);
    todo!("output helper")
}

pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<()> {
    let _ = (path, entries);
    todo!("output helper")
}
