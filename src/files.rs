//! Files written whole or not at all: under a temporary name beside the target, then renamed
//! over it (a rename within one directory is atomic on POSIX file systems), so a reader —
//! ParaView, a study's merge, another process sharing the mesh cache — never sees half a file.
//! The one home of the temporary names' convention.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

static TEMP_COUNTER: AtomicUsize = AtomicUsize::new(0);

/// `<pid>-<n>`, unique to this call across processes and the threads of one process
/// (parallel tests, a study's points) that may write beside one another at once.
pub fn unique_tag() -> String {
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    format!("{}-{n}", std::process::id())
}

/// The text of `path` when it holds at most `limit` bytes (None beyond: refused before more
/// than `limit` + 1 bytes are read), for files read back that a user may have replaced.
pub fn read_capped(path: &Path, limit: u64) -> std::io::Result<Option<String>> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(limit + 1)
        .read_to_string(&mut text)?;
    Ok((text.len() as u64 <= limit).then_some(text))
}

/// A temporary name beside `path`, unique to this process and call, with `path`'s extension
/// kept last (gmsh picks its output format by it): `mesh.msh` → `mesh.tmp-<pid>-<n>.msh`.
pub fn temp_beside(path: &Path) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let tag = format!("tmp-{}", unique_tag());
    let name = match path.extension() {
        Some(ext) => format!("{stem}.{tag}.{}", ext.to_string_lossy()),
        None => format!("{stem}.{tag}"),
    };
    path.with_file_name(name)
}

/// Write `bytes` to `path` under a temporary name, then rename it over `path`; on failure
/// the temporary is removed and `path` is as it was.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = temp_beside(path);
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: an atomic write replaces the file whole and leaves no temporary behind, a
    /// failed one (its directory missing) leaves nothing, and temporary names beside one
    /// target differ per call and keep the extension last.
    #[test]
    fn atomic_writes_replace_whole_files_and_leave_no_temporaries() {
        let dir = std::env::temp_dir().join(format!("hbcontact-files-{}", unique_tag()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("summary.json");
        write_atomic(&path, b"old").unwrap();
        write_atomic(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert_eq!(names.len(), 1, "{names:?}");
        assert!(write_atomic(&dir.join("missing/summary.json"), b"x").is_err());
        let (a, b) = (temp_beside(&path), temp_beside(&path));
        assert_ne!(a, b);
        assert_eq!(a.extension().unwrap(), "json");
        assert_eq!(a.parent(), path.parent());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
