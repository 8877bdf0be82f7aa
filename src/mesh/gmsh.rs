//! Running gmsh on a parametrised .geo, with a cache keyed by contents, parameters and version.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use sha2::{Digest, Sha256};

use crate::{Error, Result};

/// What to mesh.
#[derive(Clone, Debug)]
pub struct MeshRequest {
    pub geo: PathBuf,
    pub parameters: BTreeMap<String, f64>,
    pub mesh_size: Option<f64>,
    pub order: u8,
    pub quads: bool,
    pub gmsh: Option<PathBuf>,
}

/// The mesh file made (or found in the cache).
#[derive(Clone, Debug)]
pub struct MeshedGeometry {
    pub msh: PathBuf,
    pub cache_hit: bool,
    pub gmsh_version: String,
}

/// How to start gmsh: the pip wheel's `gmsh` is a Python script, started with its venv's python.
#[derive(Clone, Debug)]
pub struct GmshCommand {
    pub program: PathBuf,
    pub prefix_args: Vec<PathBuf>,
}

impl GmshCommand {
    fn command(&self) -> Command {
        let mut c = Command::new(&self.program);
        c.args(&self.prefix_args);
        c
    }

    pub fn describe(&self) -> String {
        let mut s = self.program.display().to_string();
        for a in &self.prefix_args {
            s.push(' ');
            s.push_str(&a.display().to_string());
        }
        s
    }
}

fn venv_command(venv_bin: &Path) -> Option<GmshCommand> {
    let script = venv_bin.join("gmsh");
    if !script.is_file() {
        return None;
    }
    let python = venv_bin.join("python");
    Some(if python.is_file() {
        GmshCommand {
            program: python,
            prefix_args: vec![script],
        }
    } else {
        GmshCommand {
            program: script,
            prefix_args: vec![],
        }
    })
}

/// Find gmsh: the explicit path, then `.venv/bin/gmsh` in the current directory or above the
/// geometry, then `gmsh` on PATH.
pub fn find_gmsh(explicit: Option<&Path>, near: Option<&Path>) -> Result<GmshCommand> {
    let mut tried = Vec::new();
    if let Some(p) = explicit {
        if p.is_file() {
            // A venv script next to its python is started with that python.
            if let Some(dir) = p.parent() {
                if dir.join("python").is_file() && p.file_name().is_some_and(|n| n == "gmsh") {
                    if let Some(c) = venv_command(dir) {
                        return Ok(c);
                    }
                }
            }
            return Ok(GmshCommand {
                program: p.to_path_buf(),
                prefix_args: vec![],
            });
        }
        return Err(Error::Gmsh(format!(
            "geometry.gmsh = {} does not exist: fix the path, or remove the key to use .venv/bin/gmsh (made by `make venv`) or gmsh on PATH",
            p.display()
        )));
    }
    let mut starts: Vec<PathBuf> = Vec::new();
    if let Ok(cwd) = std::env::current_dir() {
        starts.push(cwd);
    }
    if let Some(n) = near.and_then(|p| p.canonicalize().ok()) {
        starts.push(n);
    }
    for start in starts {
        for dir in start.ancestors() {
            let bin = dir.join(".venv").join("bin");
            tried.push(bin.join("gmsh").display().to_string());
            if let Some(c) = venv_command(&bin) {
                return Ok(c);
            }
        }
    }
    if let Some(path) = std::env::var_os("PATH") {
        for dir in std::env::split_paths(&path) {
            let candidate = dir.join("gmsh");
            if candidate.is_file() {
                return Ok(GmshCommand {
                    program: candidate,
                    prefix_args: vec![],
                });
            }
        }
    }
    tried.truncate(4);
    Err(Error::Gmsh(format!(
        "gmsh not found (looked in {} and on PATH): run `make venv` to install the pinned gmsh into .venv, or set geometry.gmsh to a gmsh executable",
        tried.join(", ")
    )))
}

static TEMP_COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

static VERSIONS: Mutex<Vec<(String, String)>> = Mutex::new(Vec::new());

/// `gmsh --version`, remembered per command.
pub fn gmsh_version(cmd: &GmshCommand) -> Result<String> {
    let key = cmd.describe();
    if let Ok(cache) = VERSIONS.lock() {
        if let Some((_, v)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(v.clone());
        }
    }
    let out = cmd
        .command()
        .arg("--version")
        .output()
        .map_err(|e| Error::Gmsh(format!("cannot start {key}: {e}")))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let version = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .unwrap_or("")
        .to_string();
    if !out.status.success() || version.is_empty() {
        return Err(Error::Gmsh(format!(
            "{key} --version failed: {}",
            text.trim()
        )));
    }
    if let Ok(mut cache) = VERSIONS.lock() {
        cache.push((key, version.clone()));
    }
    Ok(version)
}

fn cache_key(request: &MeshRequest, contents: &[u8], version: &str) -> String {
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

/// Mesh `request.geo` with gmsh (or take it as is when it is already a `.msh`).
pub fn mesh_geometry(request: &MeshRequest, cache_dir: &Path) -> Result<MeshedGeometry> {
    let geo = &request.geo;
    if geo.extension().is_some_and(|e| e == "msh") {
        if !geo.is_file() {
            return Err(Error::Gmsh(format!(
                "mesh file {} does not exist",
                geo.display()
            )));
        }
        return Ok(MeshedGeometry {
            msh: geo.clone(),
            cache_hit: true,
            gmsh_version: String::new(),
        });
    }
    let contents = std::fs::read(geo)
        .map_err(|e| Error::Gmsh(format!("cannot read geometry {}: {e}", geo.display())))?;
    let cmd = find_gmsh(request.gmsh.as_deref(), geo.parent())?;
    let version = gmsh_version(&cmd)?;
    let stem = geo
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "mesh".into());
    let msh = cache_dir.join(format!(
        "{stem}-{}.msh",
        cache_key(request, &contents, &version)
    ));
    if msh.is_file() {
        return Ok(MeshedGeometry {
            msh,
            cache_hit: true,
            gmsh_version: version,
        });
    }
    std::fs::create_dir_all(cache_dir).map_err(|e| Error::io(cache_dir, e))?;
    // Unique per call: threads of one process (parallel tests, studies) may mesh at once.
    let unique = TEMP_COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = cache_dir.join(format!("{stem}.tmp-{}-{unique}.msh", std::process::id()));
    let mut c = cmd.command();
    c.arg(geo)
        .arg("-2")
        .arg("-order")
        .arg(request.order.to_string());
    for (k, v) in &request.parameters {
        c.arg("-setnumber").arg(k).arg(format!("{v:e}"));
    }
    if request.quads {
        c.arg("-setnumber").arg("quads").arg("1");
    }
    if let Some(h) = request.mesh_size {
        c.arg("-clmax").arg(format!("{h:e}"));
    }
    c.args(["-format", "msh41", "-save_all", "0", "-nopopup", "-o"])
        .arg(&tmp);
    let out = c
        .output()
        .map_err(|e| Error::Gmsh(format!("cannot start {}: {e}", cmd.describe())))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let errors: Vec<&str> = text.lines().filter(|l| l.contains("Error")).collect();
    if !out.status.success() || !errors.is_empty() || !tmp.is_file() {
        let _ = std::fs::remove_file(&tmp);
        let shown = if errors.is_empty() {
            text.lines()
                .rev()
                .take(10)
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .collect::<Vec<_>>()
                .join("\n")
        } else {
            errors.join("\n")
        };
        return Err(Error::Gmsh(format!(
            "meshing {} failed:\n{shown}",
            geo.display()
        )));
    }
    std::fs::rename(&tmp, &msh).map_err(|e| Error::io(&msh, e))?;
    Ok(MeshedGeometry {
        msh,
        cache_hit: false,
        gmsh_version: version,
    })
}
