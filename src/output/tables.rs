//! CSV tables and JSON summaries, each written under a temporary name and renamed.
use std::fmt::Write as _;
use std::path::Path;

use crate::{Error, Result};

fn write_atomic(path: &Path, text: &str) -> Result<()> {
    crate::files::write_atomic(path, text.as_bytes()).map_err(|e| Error::io(path, e))
}

/// Numbers are written in the shortest form that reads back to the same f64.
pub fn write_csv(path: &Path, header: &[String], rows: &[Vec<f64>]) -> Result<()> {
    let mut s = header.join(",");
    s.push('\n');
    for row in rows {
        for (i, v) in row.iter().enumerate() {
            if i > 0 {
                s.push(',');
            }
            let _ = write!(s, "{v:e}");
        }
        s.push('\n');
    }
    write_atomic(path, &s)
}

pub fn write_json<T: serde::Serialize + ?Sized>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Model(format!("internal: JSON: {e}")))?;
    write_atomic(path, &(text + "\n"))
}

/// Any text file (a CSV with text columns, say), written under a temporary name and renamed.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomic(path, text)
}

/// A number as the CSV writes it: an integer as an integer (`8`, `1000`), any other value in
/// its shortest round-trip form (`1.5e-7`), empty for NaN.
pub fn csv_number(v: f64) -> String {
    /// Integers below this are exact in an f64 and read better written out.
    const WHOLE: f64 = 1e15;
    if v.is_finite() && v.fract() == 0.0 && v.abs() < WHOLE {
        format!("{}", v as i64)
    } else if v.is_finite() {
        format!("{v:e}")
    } else {
        String::new()
    }
}
