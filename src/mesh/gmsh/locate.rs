//! Finding gmsh (an explicit path, the project's .venv, PATH) and its version, remembered per
//! command in the cache folder so a run does not start gmsh only to ask it.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Duration;

use crate::{Error, Result, Silent};

use super::*;

/// How to start gmsh: the pip wheel's `gmsh` is a Python script, started with its venv's python.
#[derive(Clone, Debug)]
pub struct GmshCommand {
    pub program: PathBuf,
    pub prefix_args: Vec<PathBuf>,
}

impl GmshCommand {
    pub(super) fn command(&self) -> Command {
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

static VERSIONS: Mutex<Vec<(String, String)>> = Mutex::new(Vec::new());

/// The file in a mesh cache that remembers `gmsh --version` across processes.
const VERSIONS_FILE: &str = "gmsh-versions.txt";

/// The largest `VERSIONS_FILE` read back [bytes]: a line per gmsh installation, each a few
/// hundred bytes.
const VERSIONS_FILE_BYTES: u64 = 64 << 10;

/// The contents of `path` when it holds at most `max` bytes (None: missing, unreadable or
/// larger): files of the cache are read back without trusting their size.
pub(super) fn read_at_most(path: &Path, max: u64) -> Option<Vec<u8>> {
    let file = std::fs::File::open(path).ok()?;
    let mut bytes = Vec::new();
    file.take(max + 1).read_to_end(&mut bytes).ok()?;
    (bytes.len() as u64 <= max).then_some(bytes)
}

/// `gmsh --version`, remembered per command: in this process (asked once even when threads
/// mesh at once: the lock is held while gmsh answers) and, with a `cache_dir`, on disk for the
/// next processes (`remembered_version`).
pub fn gmsh_version(cmd: &GmshCommand, cache_dir: Option<&Path>) -> Result<String> {
    let key = cmd.describe();
    let mut cache = VERSIONS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((_, v)) = cache.iter().find(|(k, _)| *k == key) {
        return Ok(v.clone());
    }
    let version = match cache_dir {
        Some(dir) => remembered_version(cmd, dir, || ask_version(cmd))?,
        None => ask_version(cmd)?,
    };
    cache.push((key, version.clone()));
    Ok(version)
}

/// The version `ask` gives, remembered in `dir`'s `VERSIONS_FILE` under the paths, sizes and
/// modification times of the command's files (`command_stamp`). Starting the
/// pip wheel's Python only to ask costs 0.1–0.15 s, most of a small scene's run; an upgrade
/// of gmsh rewrites those files, and a changed file asks again. A file that cannot be read or
/// written only means asking.
fn remembered_version(
    cmd: &GmshCommand,
    dir: &Path,
    ask: impl FnOnce() -> Result<String>,
) -> Result<String> {
    let Some((paths, states)) = command_stamp(cmd) else {
        return ask();
    };
    let path = dir.join(VERSIONS_FILE);
    // Read back like user input: a file beyond `VERSIONS_FILE_BYTES` or not text is
    // forgotten (and written anew below).
    let known = read_at_most(&path, VERSIONS_FILE_BYTES)
        .and_then(|b| String::from_utf8(b).ok())
        .unwrap_or_default();
    let mut lines: Vec<&str> = known.lines().collect();
    let stamp = format!("{paths}\t{states}\t");
    if let Some(v) = lines.iter().find_map(|l| l.strip_prefix(&stamp)) {
        return Ok(v.to_string());
    }
    let version = ask()?;
    let entry = format!("{stamp}{version}");
    // This installation's earlier state (before an upgrade) is not kept.
    lines.retain(|l| l.split('\t').next() != Some(paths.as_str()));
    lines.push(&entry);
    // A memo that cannot be written just means asking again next time.
    let text = lines.join("\n") + "\n";
    let _ = std::fs::create_dir_all(dir)
        .and_then(|()| crate::files::write_atomic(&path, text.as_bytes()));
    Ok(version)
}

/// The command's files (the program, the script it runs and, for a script in a venv's `bin`,
/// the venv's `gmsh.py` module, the wheel's API, which holds the version): their paths, and
/// their sizes and modification times (ns); `None` when one cannot be read (then the version
/// is not remembered).
fn command_stamp(cmd: &GmshCommand) -> Option<(String, String)> {
    let modules = cmd.prefix_args.iter().flat_map(|script| {
        let lib = script
            .parent()
            .and_then(Path::parent)
            .map(|venv| venv.join("lib"));
        let pythons = lib
            .and_then(|l| std::fs::read_dir(l).ok())
            .into_iter()
            .flatten();
        pythons
            .filter_map(|e| e.ok())
            .map(|e| e.path().join("site-packages").join("gmsh.py"))
            .filter(|m| m.is_file())
    });
    let files: Vec<PathBuf> = std::iter::once(cmd.program.clone())
        .chain(cmd.prefix_args.iter().cloned())
        .chain(modules)
        .collect();
    let (mut paths, mut states) = (String::new(), String::new());
    for file in &files {
        let path = std::fs::canonicalize(file).ok()?;
        let meta = std::fs::metadata(&path).ok()?;
        let since = meta
            .modified()
            .ok()?
            .duration_since(std::time::UNIX_EPOCH)
            .ok()?;
        paths.push_str(&format!("{}|", path.display()));
        states.push_str(&format!("{}|{}|", meta.len(), since.as_nanos()));
    }
    // A tab or newline in a path would break the file's lines: do not remember that one.
    (!paths.contains(['\t', '\n'])).then_some((paths, states))
}

/// Run `gmsh --version`.
fn ask_version(cmd: &GmshCommand) -> Result<String> {
    let key = cmd.describe();
    let mut c = cmd.command();
    c.arg("--version");
    let out = run_gmsh(
        c,
        &key,
        Duration::from_secs(60),
        MemoryLimit::READING,
        &Silent,
    )?;
    let text = format!("{}{}", out.stdout, out.stderr);
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
    Ok(version)
}
