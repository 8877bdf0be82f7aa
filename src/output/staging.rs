//! Atomic output directories: a run writes into `<name>.partial-<pid>` and renames it onto
//! `<name>` only when everything is written, so a failed run never leaves a series that looks
//! complete (and keeps the previous complete one).
use std::path::{Path, PathBuf};

use crate::progress::Reporter;
use crate::{Error, Result};

/// Remove the `<name>.partial-<pid>` directories that runs which no longer exist left next to
/// `final_dir` (a run killed outright cannot clean up after itself), telling the reporter about
/// each. Only directories whose pid has no `/proc/<pid>` go: a partial output of a run still
/// going is kept, and so is everything when `/proc` is not there to tell. Returns what went.
pub fn remove_stale_partials(final_dir: &Path, reporter: &dyn Reporter) -> Vec<PathBuf> {
    let proc_fs = Path::new("/proc");
    if !proc_fs.join("self").exists() {
        return Vec::new();
    }
    let parent = match final_dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let Ok(entries) = std::fs::read_dir(&parent) else {
        return Vec::new();
    };
    let mut removed = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().to_string();
        let Some((_, pid)) = name.rsplit_once(".partial-") else {
            continue;
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        let path = entry.path();
        if pid == std::process::id() || proc_fs.join(pid.to_string()).exists() || !path.is_dir() {
            continue;
        }
        match std::fs::remove_dir_all(&path) {
            Ok(()) => {
                reporter.warning(&format!(
                    "removed {}, the partial output of a run (pid {pid}) that no longer exists",
                    path.display()
                ));
                removed.push(path);
            }
            Err(e) => reporter.warning(&format!(
                "cannot remove the stale partial output {}: {e}",
                path.display()
            )),
        }
    }
    removed
}

/// A directory written under a temporary name and renamed onto its final name by `commit`.
pub struct StagedDir {
    pub final_dir: PathBuf,
    pub temp_dir: PathBuf,
    committed: bool,
}

impl StagedDir {
    pub fn create(final_dir: &Path) -> Result<Self> {
        let name = final_dir
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .ok_or_else(|| {
                Error::Model(format!(
                    "output directory {} has no name",
                    final_dir.display()
                ))
            })?;
        let parent = final_dir
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        if !parent.as_os_str().is_empty() {
            std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        }
        let temp_dir = parent.join(format!("{name}.partial-{}", std::process::id()));
        if temp_dir.exists() {
            std::fs::remove_dir_all(&temp_dir).map_err(|e| Error::io(&temp_dir, e))?;
        }
        std::fs::create_dir(&temp_dir).map_err(|e| Error::io(&temp_dir, e))?;
        Ok(StagedDir {
            final_dir: final_dir.to_path_buf(),
            temp_dir,
            committed: false,
        })
    }

    pub fn path(&self) -> &Path {
        &self.temp_dir
    }

    /// Replace any previous output by the staged one.
    pub fn commit(mut self) -> Result<PathBuf> {
        if self.final_dir.exists() {
            std::fs::remove_dir_all(&self.final_dir).map_err(|e| Error::io(&self.final_dir, e))?;
        }
        std::fs::rename(&self.temp_dir, &self.final_dir)
            .map_err(|e| Error::io(&self.final_dir, e))?;
        self.committed = true;
        Ok(self.final_dir.clone())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp_dir);
        }
    }
}
