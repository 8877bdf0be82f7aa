//! The steps of one meshing (unroll the geometry, trial meshes, the mesh) either as one
//! native gmsh command per step or as one Python session (`SESSION_DRIVER`) answering them
//! on stdin; the command lines, and the diagnosis of a failed run.

use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::Command;

use crate::progress::Reporter;
use crate::{Error, Result};

use super::*;

/// The gmsh command line meshing `request` in 2-D into `out`, sizes scaled by `scale`
/// (`-clscale`), without the program.
fn mesh_args(request: &MeshRequest, out: &Path, scale: f64) -> Vec<std::ffi::OsString> {
    let mut args: Vec<std::ffi::OsString> = vec![request.geo.clone().into(), "-2".into()];
    args.extend(["-order".into(), request.order.to_string().into()]);
    args.extend(parameter_args(request));
    if let Some(h) = request.mesh_size {
        args.extend(["-clmax".into(), format!("{h:e}").into()]);
    }
    if scale != 1.0 {
        args.extend(["-clscale".into(), format!("{scale:e}").into()]);
    }
    for a in ["-format", "msh41", "-save_all", "0", "-nopopup", "-o"] {
        args.push(a.into());
    }
    args.push(out.into());
    args
}

fn parameter_args(request: &MeshRequest) -> Vec<std::ffi::OsString> {
    let mut args: Vec<std::ffi::OsString> = Vec::new();
    for (k, v) in &request.parameters {
        args.extend(["-setnumber".into(), k.into(), format!("{v:e}").into()]);
    }
    if request.quads {
        args.extend(["-setnumber".into(), "quads".into(), "1".into()]);
    }
    args
}

/// The message of a failed gmsh run: its lines with "Error" (else its last lines) and how it
/// ended, even when it printed nothing (killed by a signal).
fn failure(request: &MeshRequest, o: &GmshOutput, out: &Path) -> Error {
    let text = format!("{}{}", o.stdout, o.stderr);
    let errors: Vec<&str> = text.lines().filter(|l| l.contains("Error")).collect();
    let mut shown = if errors.is_empty() {
        let tail: Vec<&str> = text
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with("hbcontact:"))
            .rev()
            .take(10)
            .collect();
        tail.into_iter().rev().collect::<Vec<_>>().join("\n")
    } else {
        errors.join("\n")
    };
    if out_of_memory(o) {
        // Keep what gmsh said beyond the bare "Error :" of a failed allocation.
        let said: Vec<&str> = shown
            .lines()
            .filter(|l| {
                l.trim_end()
                    .strip_prefix("Error")
                    .is_none_or(|r| r.trim() != ":")
            })
            .collect();
        let said = if said.is_empty() {
            String::new()
        } else {
            format!("\n{}", said.join("\n"))
        };
        return Error::Gmsh(format!(
            "meshing {} failed: {}{said}",
            request.geo.display(),
            memory_exceeded(request, &o.memory)
        ));
    }
    if !o.status.success() {
        if !shown.is_empty() {
            shown.push('\n');
        }
        shown.push_str(&describe_status(&o.status));
    } else if shown.is_empty() {
        shown = format!("gmsh wrote no mesh file {}", out.display());
    }
    Error::Gmsh(format!(
        "meshing {} failed:\n{shown}",
        request.geo.display()
    ))
}

/// Whether a failed gmsh ran out of the memory its limit allows: an allocation failed (C++
/// `std::bad_alloc`, Python's `MemoryError`, "Cannot allocate memory"), the session caught an
/// exception gmsh logged no error for (what `bad_alloc` through gmsh's API looks like:
/// "Error : " and nothing after it), or gmsh died of SIGABRT, SIGSEGV or SIGBUS (an
/// allocation failure it did not catch).
fn out_of_memory(o: &GmshOutput) -> bool {
    let text = format!("{}{}", o.stdout, o.stderr);
    let failed = !o.status.success() || text.contains("Error");
    let allocation = [
        "bad_alloc",
        "MemoryError",
        "Cannot allocate memory",
        "out of memory",
    ]
    .iter()
    .any(|w| text.contains(w));
    let silent_exception = text.lines().any(|l| {
        l.trim_end()
            .strip_prefix("Error")
            .is_some_and(|r| r.trim() == ":")
    });
    let crashed = matches!(
        o.status.signal(),
        Some(libc::SIGABRT | libc::SIGSEGV | libc::SIGBUS)
    );
    failed && (allocation || silent_exception || crashed)
}

/// The message of a gmsh stopped by its memory limit: the limit, what it was derived from,
/// and what to change.
fn memory_exceeded(request: &MeshRequest, memory: &MemoryLimit) -> String {
    let per_element = GMSH_BYTES_PER_ELEMENT >> 10;
    let base = GMSH_BASE_BYTES as f64 / 1e9;
    if memory.from_estimate {
        format!(
            "gmsh exceeded its memory limit of {} derived from the element estimate ({:.2e} elements × {per_element} kB + {base:.2} GB): the mesh needs far more than its estimate, as when size fields refine far below the sizes the .geo names; make the smallest sizes coarser (a larger geometry.mesh_size, or the .geo's size parameters{}) or name them in the .geo, where the estimate sees them",
            memory.shown(),
            memory.elements,
            parameters_named(request)
        )
    } else {
        format!(
            "gmsh exceeded its memory limit of {} while reading the geometry and making the element estimate's trial meshes (derived from an element count as for the mesh: {:.0} elements, ten times a trial mesh, × {per_element} kB + {base:.2} GB): a geometry that costs this much before it is meshed is out of scale, e.g. a length of 1e29 beside sizes of millimetres; check geometry.parameters{} and the .geo's lengths and sizes",
            memory.shown(),
            memory.elements,
            parameters_named(request)
        )
    }
}

/// ` (now a = 1e0, b = 2e0)`, the request's geometry parameters, or nothing.
fn parameters_named(request: &MeshRequest) -> String {
    if request.parameters.is_empty() {
        return String::new();
    }
    let list: Vec<String> = request
        .parameters
        .iter()
        .map(|(k, v)| format!("{} = {v:e}", crate::error::excerpt(k)))
        .collect();
    format!(" (now {})", list.join(", "))
}

/// Run one gmsh command to its end under the memory limit `memory` and check that it wrote
/// `out` without an error.
fn run_checked(
    c: Command,
    cmd: &GmshCommand,
    request: &MeshRequest,
    out: &Path,
    limits: &MeshLimits,
    memory: MemoryLimit,
    reporter: &dyn Reporter,
) -> Result<()> {
    let result = run_gmsh(c, &cmd.describe(), limits.timeout, memory, reporter).and_then(|o| {
        let errors = format!("{}{}", o.stdout, o.stderr).contains("Error");
        if o.status.success() && !errors && out.is_file() {
            Ok(())
        } else {
            Err(failure(request, &o, out))
        }
    });
    if result.is_err() {
        let _ = std::fs::remove_file(out);
    }
    result
}

/// The steps the estimate and the mesh take from gmsh.
pub(super) trait GmshSteps {
    /// Write the unrolled geometry (what gmsh `-0` writes) to `path`.
    fn unroll(&mut self, path: &Path) -> std::result::Result<(), Stop>;
    /// Mesh in 2-D with every size scaled by `scale` into `path`.
    fn mesh(&mut self, scale: f64, path: &Path) -> std::result::Result<(), Stop>;
    /// Run the next steps under the memory limit `memory` (it starts as
    /// `MemoryLimit::READING`).
    fn limit_memory(&mut self, memory: MemoryLimit) -> std::result::Result<(), Stop>;
}

/// A native gmsh: one command per step, each started under the limit in force.
struct Commands<'a> {
    pub(super) cmd: &'a GmshCommand,
    pub(super) request: &'a MeshRequest,
    pub(super) limits: &'a MeshLimits,
    pub(super) memory: MemoryLimit,
    pub(super) reporter: &'a dyn Reporter,
}

impl Commands<'_> {
    /// Run one gmsh step `c` writing `path`, under this run's limits and memory bound.
    pub(super) fn run(&self, c: Command, path: &Path) -> std::result::Result<(), Stop> {
        run_checked(
            c,
            self.cmd,
            self.request,
            path,
            self.limits,
            self.memory,
            self.reporter,
        )
        .map_err(Stop::Error)
    }
}

impl GmshSteps for Commands<'_> {
    fn unroll(&mut self, path: &Path) -> std::result::Result<(), Stop> {
        let mut c = self.cmd.command();
        c.arg(&self.request.geo).arg("-0");
        c.args(parameter_args(self.request));
        c.args(["-nopopup", "-o"]).arg(path);
        self.run(c, path)
    }
    fn mesh(&mut self, scale: f64, path: &Path) -> std::result::Result<(), Stop> {
        let mut c = self.cmd.command();
        c.args(mesh_args(self.request, path, scale));
        self.run(c, path)
    }
    fn limit_memory(&mut self, memory: MemoryLimit) -> std::result::Result<(), Stop> {
        self.memory = memory;
        Ok(())
    }
}

/// The pip wheel's gmsh: one session answering each step.
struct Session<'c, 'a>(&'c mut Conversation<'a>);

impl GmshSteps for Session<'_, '_> {
    fn unroll(&mut self, path: &Path) -> std::result::Result<(), Stop> {
        self.0.ask(&format!("unroll {}", path.display()))
    }
    fn mesh(&mut self, scale: f64, path: &Path) -> std::result::Result<(), Stop> {
        self.0.ask(&format!("mesh {scale:e} {}", path.display()))
    }
    fn limit_memory(&mut self, memory: MemoryLimit) -> std::result::Result<(), Stop> {
        self.0.ask(&format!("limit {}", memory.bytes()))?;
        self.0.memory = memory;
        Ok(())
    }
}

/// The Python program of a gmsh session, run by the venv's python with the gmsh command line
/// of the mesh (`mesh_args`): it drops `-2` and `-o OUT`, initializes gmsh's API with the
/// other options (exactly as the gmsh command line sets them), opens the geometry, and
/// answers `hbcontact:ok` (or prints the error and `hbcontact:failed`) to each line on stdin:
/// `unroll PATH` (gmsh `-0`), `mesh SCALE PATH` (`-2 -clscale SCALE -o PATH`), `limit BYTES`
/// (its address space from then on, within the hard limit it started with). End of input
/// ends it. Its meshes are byte for byte the command line's.
const SESSION_DRIVER: &str = r#"
import resource
import sys
import gmsh
args = sys.argv[1:]
geo = args.pop(0)
if "-o" in args:
    i = args.index("-o")
    del args[i:i + 2]
args = [a for a in args if a != "-2"]
def answer(word):
    sys.stdout.write("hbcontact:" + word + "\n")
    sys.stdout.flush()
gmsh.initialize(["gmsh"] + args)
try:
    gmsh.open(geo)
    answer("ok")
    for line in sys.stdin:
        word, _, rest = line.rstrip("\n").partition(" ")
        if word == "unroll":
            gmsh.write(rest)
        elif word == "mesh":
            scale, _, path = rest.partition(" ")
            gmsh.option.setNumber("Mesh.MeshSizeFactor", float(scale))
            gmsh.model.mesh.clear()
            gmsh.model.mesh.generate(2)
            gmsh.write(path)
        elif word == "limit":
            hard = resource.getrlimit(resource.RLIMIT_AS)[1]
            soft = int(rest)
            if hard != resource.RLIM_INFINITY:
                soft = min(soft, hard)
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        else:
            break
        answer("ok")
except Exception as e:
    sys.stdout.write("Error : %s\n" % e)
    answer("failed")
    sys.exit(1)
gmsh.finalize()
"#;

/// The session command for `cmd` (None: not the pip wheel's Python script).
fn session_command(cmd: &GmshCommand, request: &MeshRequest, out: &Path) -> Option<Command> {
    let python = cmd
        .program
        .file_name()?
        .to_string_lossy()
        .starts_with("python");
    if !python || cmd.prefix_args.len() != 1 {
        return None;
    }
    let mut c = Command::new(&cmd.program);
    c.arg("-c")
        .arg(SESSION_DRIVER)
        .args(mesh_args(request, out, 1.0));
    Some(c)
}

/// Run `steps` against gmsh for `request`: in one session when gmsh is the pip wheel, else one
/// command per step. `out` is the mesh the steps aim at (on the session's command line).
pub(super) fn with_gmsh<T>(
    cmd: &GmshCommand,
    request: &MeshRequest,
    limits: &MeshLimits,
    reporter: &dyn Reporter,
    out: &Path,
    steps: impl FnOnce(&mut dyn GmshSteps) -> std::result::Result<T, Stop>,
) -> Result<T> {
    let Some(c) = session_command(cmd, request, out) else {
        let mut commands = Commands {
            cmd,
            request,
            limits,
            memory: MemoryLimit::READING,
            reporter,
        };
        return steps(&mut commands).map_err(|stop| match stop {
            Stop::Error(e) => e,
            Stop::Gmsh => Error::Gmsh(format!("meshing {} failed", request.geo.display())),
        });
    };
    let what = cmd.describe();
    // The session starts under the reading limit; the most it may raise it to is the limit
    // of the largest mesh `max_elements` allows.
    let spawn = SpawnLimits {
        memory: MemoryLimit::READING,
        most: MemoryLimit::for_estimate(limits.max_elements as f64),
    };
    let (output, talked) = converse(
        c,
        &what,
        limits.timeout,
        spawn,
        reporter,
        true,
        |conversation| {
            conversation.ask("")?;
            steps(&mut Session(conversation))
        },
    )?;
    match talked {
        Ok(t) if output.status.success() => Ok(t),
        Ok(_) | Err(Stop::Gmsh) => Err(failure(request, &output, out)),
        Err(Stop::Error(e)) => Err(e),
    }
}
