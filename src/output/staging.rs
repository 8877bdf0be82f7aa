//! Atomic output directories.
use std::path::{Path, PathBuf};

use crate::Result;

/// A directory written under a temporary name and renamed onto its final name by `commit`.
pub struct StagedDir {
    pub final_dir: PathBuf,
    pub temp_dir: PathBuf,
}

impl StagedDir {
    pub fn create(final_dir: &Path) -> Result<Self> {
        let _ = final_dir;
        todo!("output helper")
    }
    pub fn path(&self) -> &Path {
        &self.temp_dir
    }
    pub fn commit(self) -> Result<PathBuf> {
        todo!("output helper")
    }
}
