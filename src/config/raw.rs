//! The YAML schema as written by users, and its validation into `Pipeline`.

use std::path::Path;

use super::Pipeline;
use crate::Result;

/// Read `path`, apply `--set key.path=value` overrides, and validate.
pub fn load_pipeline(path: &Path, overrides: &[String]) -> Result<Pipeline> {
    let _ = (path, overrides);
    todo!("config helper")
}
