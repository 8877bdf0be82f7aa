//! Running gmsh on a parametrised .geo, with a cache keyed by contents, parameters and version.
//!
//! gmsh is bounded: before meshing, the element count is estimated (`estimate_elements`) and a
//! mesh beyond `MeshLimits::max_elements` is refused; gmsh runs in its own process group with a
//! time limit, its whole group is killed on timeout, and it dies with hbcontact (a parent-death
//! signal; `kill_running` for SIGINT/SIGTERM handlers).
//!
//! gmsh's memory is bounded too (`MemoryLimit`, its address space by setrlimit(RLIMIT_AS) in
//! the child before exec): B + b·n bytes for n elements, B = `GMSH_BASE_BYTES` (the program
//! and its libraries: the pip wheel's Python session peaks at 0.21 GB before any element) and
//! b = `GMSH_BYTES_PER_ELEMENT` (measured: 0.74 kB of address space per element from 2 000 to
//! 560 000 elements, first or second order; b is 8 kB, room for an estimate a few times low).
//! Reading the geometry and estimating run under the limit for `ESTIMATE_ELEMENTS` (the trial
//! meshes aim at `TRIAL_ELEMENTS`); the mesh runs under the limit for its estimate. A geometry
//! out of scale (`r = 1e29` in the quickstart took gmsh to 2.3 GB in 20 s reading it) stops at
//! the limit, and the error says so (`out_of_memory`).
//!
//! One gmsh process per geometry: the pip wheel's gmsh (a Python script) is not run as a
//! command per step but as one session (`SESSION_DRIVER`, its Python API): started with the
//! mesh's command line, it opens the geometry once and answers `unroll`, `mesh SCALE PATH` on
//! stdin, so the estimate, its refusal and the mesh happen in one process (starting Python and
//! loading gmsh cost about 0.3 s, more than meshing a small geometry). A native gmsh binary
//! runs one command per step (`-0`, trial meshes, the mesh). Both make the same file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::progress::Reporter;
use crate::{Error, Result, Silent};

mod cache;
mod estimate;
mod locate;
mod process;
mod session;

pub use cache::*;
pub use estimate::*;
pub use locate::*;
pub use process::*;
use session::*;

/// The default of `geometry.max_elements`.
pub const DEFAULT_MAX_ELEMENTS: u64 = 2_000_000;

/// The default of `geometry.gmsh_timeout`, in seconds.
pub const DEFAULT_GMSH_TIMEOUT: f64 = 600.0;

/// The address space gmsh may take before its first element [bytes] (`MemoryLimit`).
pub const GMSH_BASE_BYTES: u64 = 1 << 30;

/// The address space gmsh may take per element [bytes] (`MemoryLimit`).
pub const GMSH_BYTES_PER_ELEMENT: u64 = 8 << 10;

/// The elements the memory limit allows while gmsh reads the geometry and makes the
/// estimate's trial meshes: ten times what a trial mesh aims at.
pub const ESTIMATE_ELEMENTS: f64 = 10.0 * TRIAL_ELEMENTS;

/// The address space one more thread of gmsh may reserve (its stack and a malloc arena)
/// [bytes], for a user's `OMP_NUM_THREADS` above 1.
const GMSH_BYTES_PER_THREAD: u64 = 128 << 20;

/// The memory gmsh may use (its address space, `RLIMIT_AS`): `GMSH_BASE_BYTES` plus
/// `GMSH_BYTES_PER_ELEMENT` per element of `elements` (and `GMSH_BYTES_PER_THREAD` per
/// thread a user's `OMP_NUM_THREADS` adds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryLimit {
    /// The elements the limit is for.
    pub elements: f64,
    /// Whether `elements` is the mesh's estimate (else the allowance for reading the geometry
    /// and estimating, `ESTIMATE_ELEMENTS`).
    pub from_estimate: bool,
}

impl MemoryLimit {
    /// The limit while gmsh reads the geometry and estimates its elements.
    pub const READING: MemoryLimit = MemoryLimit {
        elements: ESTIMATE_ELEMENTS,
        from_estimate: false,
    };

    /// The limit for a mesh estimated at `estimate` elements (never below `READING`'s).
    pub fn for_estimate(estimate: f64) -> MemoryLimit {
        MemoryLimit {
            elements: estimate.max(ESTIMATE_ELEMENTS),
            from_estimate: true,
        }
    }

    /// The limit in bytes.
    pub fn bytes(&self) -> u64 {
        let threads = std::env::var("OMP_NUM_THREADS")
            .ok()
            .and_then(|t| t.trim().parse::<u64>().ok())
            .unwrap_or(1)
            .clamp(1, 1024);
        let elements = (self.elements.max(0.0) as u64).saturating_mul(GMSH_BYTES_PER_ELEMENT);
        GMSH_BASE_BYTES
            .saturating_add((threads - 1) * GMSH_BYTES_PER_THREAD)
            .saturating_add(elements)
    }

    /// `1.34 GB`.
    fn shown(&self) -> String {
        format!("{:.2} GB", self.bytes() as f64 / 1e9)
    }
}

/// Bounds on one meshing.
#[derive(Clone, Copy, Debug)]
pub struct MeshLimits {
    /// Refuse to mesh when the estimated number of 2-D elements exceeds this.
    pub max_elements: u64,
    /// Kill gmsh (its whole process group) when one run takes longer than this.
    pub timeout: Duration,
}

impl Default for MeshLimits {
    fn default() -> Self {
        MeshLimits {
            max_elements: DEFAULT_MAX_ELEMENTS,
            timeout: Duration::from_secs_f64(DEFAULT_GMSH_TIMEOUT),
        }
    }
}

/// What to mesh.
#[derive(Clone, Debug)]
pub struct MeshRequest {
    pub geo: PathBuf,
    pub parameters: BTreeMap<String, f64>,
    pub mesh_size: Option<f64>,
    pub order: u8,
    pub quads: bool,
    pub gmsh: Option<PathBuf>,
    /// Skip the scan of the `.geo` for statements that run programs or touch other files
    /// (`super::guard`; `--trust-geometry`).
    pub trusted: bool,
}

/// The mesh file made (or found in the cache).
#[derive(Clone, Debug)]
pub struct MeshedGeometry {
    pub msh: PathBuf,
    pub cache_hit: bool,
    pub gmsh_version: String,
}

/// The refusal of a mesh estimated at `estimate` elements: the estimate, the limit, a size
/// that fits and how to raise the limit.
fn too_many_elements(request: &MeshRequest, limits: &MeshLimits, estimate: f64) -> Error {
    let ratio = (estimate / limits.max_elements as f64).sqrt();
    let (size, fix) = match request.mesh_size {
        Some(h) => (
            format!("geometry.mesh_size = {h:e}"),
            format!("geometry.mesh_size ≥ {:.2e} fits", h * ratio),
        ),
        None => (
            "the .geo's sizes".to_string(),
            format!(
                "sizes {ratio:.1}× larger fit (geometry.mesh_size or the .geo's size parameters)"
            ),
        ),
    };
    let parameters = if request.parameters.is_empty() {
        String::new()
    } else {
        let list: Vec<String> = request
            .parameters
            .iter()
            .map(|(k, v)| format!("{k} = {v:e}"))
            .collect();
        format!(" and geometry.parameters {}", list.join(", "))
    };
    Error::Input(format!(
        "meshing {} with {size}{parameters} would make about {estimate:.2e} elements (estimated from a coarsened gmsh mesh), more than geometry.max_elements = {}: {fix}; or raise geometry.max_elements if the machine has the memory (gmsh needs about 1 kB per element, the solver several times more)",
        request.geo.display(),
        limits.max_elements,
    ))
}

/// Mesh `request.geo` with gmsh (or take it as is when it is already a `.msh`), with the
/// default limits and no progress reports.
pub fn mesh_geometry(request: &MeshRequest, cache_dir: &Path) -> Result<MeshedGeometry> {
    mesh_geometry_with(request, &MeshLimits::default(), cache_dir, &Silent)
}

/// Mesh `request.geo` with gmsh (or take it as is when it is already a `.msh`): from the cache
/// when it holds the mesh, else after checking the estimated element count against `limits`.
pub fn mesh_geometry_with(
    request: &MeshRequest,
    limits: &MeshLimits,
    cache_dir: &Path,
    reporter: &dyn Reporter,
) -> Result<MeshedGeometry> {
    let geo = &request.geo;
    if geo.extension().is_some_and(|e| e == "geo") {
        super::guard::check_geometry(geo, request.trusted)?;
        super::geo::check_parameters(geo, &request.parameters)?;
    }
    if geo.extension().is_some_and(|e| e == "msh") {
        return given_mesh(geo);
    }
    let contents = std::fs::read(geo)
        .map_err(|e| Error::Gmsh(format!("cannot read geometry {}: {e}", geo.display())))?;
    let cmd = find_gmsh(request.gmsh.as_deref(), geo.parent())?;
    let version = gmsh_version(&cmd, Some(cache_dir))?;
    let msh = cache_entry(request, &contents, &version, cache_dir);
    // One mesher per cache entry at a time, across threads and processes (a study's points,
    // Slurm shards on a shared file system): the others wait here, then find it cached.
    std::fs::create_dir_all(cache_dir).map_err(|e| Error::io(cache_dir, e))?;
    let _lock = lock_entry(&msh)?;
    if from_cache(&msh, limits, reporter) {
        return Ok(MeshedGeometry {
            msh,
            cache_hit: true,
            gmsh_version: version,
        });
    }
    mesh_into_cache(&cmd, request, limits, cache_dir, reporter, &msh)?;
    Ok(MeshedGeometry {
        msh,
        cache_hit: false,
        gmsh_version: version,
    })
}

/// A `.msh` geometry, taken as it is.
fn given_mesh(msh: &Path) -> Result<MeshedGeometry> {
    if !msh.is_file() {
        return Err(Error::Gmsh(format!(
            "mesh file {} does not exist",
            msh.display()
        )));
    }
    Ok(MeshedGeometry {
        msh: msh.to_path_buf(),
        cache_hit: true,
        gmsh_version: String::new(),
    })
}

/// The cache file of the mesh of `request` (the geometry's `contents`, gmsh `version`):
/// `<stem>-<key>.msh` in `cache_dir`.
fn cache_entry(request: &MeshRequest, contents: &[u8], version: &str, cache_dir: &Path) -> PathBuf {
    let stem = request
        .geo
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "mesh".into());
    cache_dir.join(format!(
        "{stem}-{}.msh",
        cache_key(request, contents, version)
    ))
}

/// Whether the cache entry `msh` holds a sound mesh within `limits`; one that does not is
/// evicted (with a warning), to be meshed again.
fn from_cache(msh: &Path, limits: &MeshLimits, reporter: &dyn Reporter) -> bool {
    if !msh.is_file() {
        return false;
    }
    match verify_cached(msh, limits.max_elements) {
        Ok(()) => true,
        Err(why) => {
            reporter.warning(&format!(
                "cached mesh {} {why}: meshing again",
                msh.display()
            ));
            evict(msh);
            false
        }
    }
}

/// Mesh `request` with gmsh `cmd` into the cache entry `msh`: the element estimate (and its
/// refusal) first, in the same gmsh session, then the mesh to a file beside `msh`, its
/// checksum and the move into place.
fn mesh_into_cache(
    cmd: &GmshCommand,
    request: &MeshRequest,
    limits: &MeshLimits,
    cache_dir: &Path,
    reporter: &dyn Reporter,
    msh: &Path,
) -> Result<()> {
    // Unique per call: threads of one process (parallel tests, studies) may mesh at once.
    let tmp = crate::files::temp_beside(msh);
    let meshed = with_gmsh(cmd, request, limits, reporter, &tmp, |steps| {
        let estimate = estimate_with(steps, request, cache_dir)?;
        if estimate > limits.max_elements as f64 {
            return Err(Stop::Error(too_many_elements(request, limits, estimate)));
        }
        steps.limit_memory(MemoryLimit::for_estimate(estimate))?;
        steps.mesh(1.0, &tmp)
    });
    if let Err(e) = meshed {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    // The checksum goes first, so a mesh in the cache always has one (a crash in between
    // leaves a checksum without its mesh, which is harmless).
    let bytes = std::fs::read(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let sum = checksum_path(msh);
    std::fs::write(&sum, sha256_hex(&bytes)).map_err(|e| Error::io(&sum, e))?;
    std::fs::rename(&tmp, msh).map_err(|e| Error::io(msh, e))?;
    Ok(())
}
