//! CSV tables and JSON summaries.
use std::path::Path;

use crate::Result;

pub fn write_csv(path: &Path, header: &[String], rows: &[Vec<f64>]) -> Result<()> {
    let _ = (path, header, rows);
    todo!("output helper")
}

pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let _ = (path, value);
    todo!("output helper")
}
