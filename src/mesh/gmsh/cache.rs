//! The mesh cache: entries keyed by the SHA-256 of the geometry's contents, its parameters,
//! the mesh options and gmsh's version; a checksum beside each .msh, a size bound of
//! `CACHED_BYTES_PER_ELEMENT` per allowed element, and a lock per entry.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::{Error, Result};

use super::*;

pub(super) fn cache_key(request: &MeshRequest, contents: &[u8], version: &str) -> String {
    let mut h = Sha256::new();
    h.update(contents);
    for (k, v) in &request.parameters {
        h.update(format!("|{k}={v:e}").as_bytes());
    }
    h.update(
        format!(
            "|size={:?}|order={}|quads={}|gmsh={version}",
            request.mesh_size, request.order, request.quads
        )
        .as_bytes(),
    );
    let digest = h.finalize();
    digest.iter().take(8).map(|b| format!("{b:02x}")).collect()
}

/// The SHA-256 of a cached mesh is kept beside it, in `<mesh>.msh.sha256`.
pub(super) fn checksum_path(msh: &Path) -> PathBuf {
    let mut name = msh.as_os_str().to_owned();
    name.push(".sha256");
    PathBuf::from(name)
}

pub(super) fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The largest cached mesh read back, per element `geometry.max_elements` allows [bytes]: an
/// element of a second-order mesh, with its share of nodes, takes about 200 bytes in MSH 4.1.
const CACHED_BYTES_PER_ELEMENT: u64 = 1024;

/// Whether a cached mesh is the one gmsh wrote: at most `CACHED_BYTES_PER_ELEMENT` per
/// element `max_elements` allows, and its SHA-256 equals the one stored beside it (a
/// 64-digit line). The error says why not (for the warning).
pub(super) fn verify_cached(msh: &Path, max_elements: u64) -> std::result::Result<(), String> {
    let stored = read_at_most(&checksum_path(msh), 1024)
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .ok_or_else(|| "has no checksum (written by an older hbcontact, or damaged)".to_string())?;
    let max = max_elements
        .saturating_mul(CACHED_BYTES_PER_ELEMENT)
        .max(1 << 20);
    let bytes = read_at_most(msh, max).ok_or_else(|| {
        format!("cannot be read or is larger than {max} bytes, more than geometry.max_elements = {max_elements} elements take")
    })?;
    if stored == sha256_hex(&bytes) {
        Ok(())
    } else {
        Err("does not match its checksum (changed or damaged since gmsh wrote it)".into())
    }
}

/// An exclusive advisory lock (flock) on `<mesh>.msh.lock`, held until dropped: separate
/// opens conflict, so it orders threads of one process as well as processes.
pub(super) fn lock_entry(msh: &Path) -> Result<std::fs::File> {
    let mut name = msh.as_os_str().to_owned();
    name.push(".lock");
    let path = PathBuf::from(name);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| Error::io(&path, e))?;
    file.lock().map_err(|e| Error::io(&path, e))?;
    Ok(file)
}

/// Remove a cached mesh and its checksum (so that it is made again).
pub fn evict(msh: &Path) {
    let _ = std::fs::remove_file(msh);
    let _ = std::fs::remove_file(checksum_path(msh));
}
