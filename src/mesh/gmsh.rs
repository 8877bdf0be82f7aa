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
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{mpsc, Mutex};
use std::time::{Duration, Instant};

use sha2::{Digest, Sha256};

use crate::progress::Reporter;
use crate::{Error, Result, Silent};

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

static VERSIONS: Mutex<Vec<(String, String)>> = Mutex::new(Vec::new());

/// The file in a mesh cache that remembers `gmsh --version` across processes.
const VERSIONS_FILE: &str = "gmsh-versions.txt";

/// The largest `VERSIONS_FILE` read back [bytes]: a line per gmsh installation, each a few
/// hundred bytes.
const VERSIONS_FILE_BYTES: u64 = 64 << 10;

/// The contents of `path` when it holds at most `max` bytes (None: missing, unreadable or
/// larger): files of the cache are read back without trusting their size.
fn read_at_most(path: &Path, max: u64) -> Option<Vec<u8>> {
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

/// Process groups of the gmsh runs under way (their leaders' pids), for `kill_running`.
static RUNNING: Mutex<Vec<i32>> = Mutex::new(Vec::new());

/// Kill every gmsh run under way (its whole process group); true when there was one. For a
/// SIGINT/SIGTERM handler of the program: gmsh runs in its own process group, so a
/// terminal's Ctrl-C does not reach it.
pub fn kill_running() -> bool {
    let Ok(running) = RUNNING.lock() else {
        return false;
    };
    for &pgid in running.iter() {
        kill_group(pgid);
    }
    !running.is_empty()
}

fn kill_group(pgid: i32) {
    if pgid > 0 {
        // SAFETY: kill(2) has no memory-safety preconditions; a negative pid names the group.
        unsafe {
            libc::kill(-pgid, libc::SIGKILL);
        }
    }
}

/// Unregisters a running gmsh and kills its group unless it ended by itself (also on unwinding).
struct RunningGuard {
    pgid: i32,
    ended: bool,
}

impl Drop for RunningGuard {
    fn drop(&mut self) {
        if !self.ended {
            kill_group(self.pgid);
        }
        if let Ok(mut running) = RUNNING.lock() {
            running.retain(|&p| p != self.pgid);
        }
    }
}

/// What one gmsh run printed, and how it ended.
pub struct GmshOutput {
    pub status: std::process::ExitStatus,
    pub stdout: String,
    pub stderr: String,
    /// The memory limit gmsh ran under at its end.
    pub memory: MemoryLimit,
}

/// How a gmsh exit status reads: "exited with code 1", or killed by a signal with the likely
/// cause (an out-of-memory kill leaves gmsh no chance to print anything).
fn describe_status(status: &std::process::ExitStatus) -> String {
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("gmsh exited with code {c}"),
        (None, Some(sig)) if sig == libc::SIGKILL => format!(
            "gmsh was killed by signal {sig} (SIGKILL), most likely by the out-of-memory killer: lower the element count (a larger geometry.mesh_size or larger size parameters of the .geo)"
        ),
        (None, Some(sig)) => format!("gmsh was killed by signal {sig}"),
        (None, None) => "gmsh ended without an exit code".into(),
    }
}

/// Run gmsh to its end, bounded: in its own process group (so that killing the group takes
/// any child it starts along), killed with its group after `timeout`, its memory limited to
/// `memory`, and dying with this process; each stdout line goes to the reporter as progress of
/// the task "gmsh".
pub fn run_gmsh(
    c: Command,
    what: &str,
    timeout: Duration,
    memory: MemoryLimit,
    reporter: &dyn Reporter,
) -> Result<GmshOutput> {
    let limits = SpawnLimits {
        memory,
        most: memory,
    };
    converse(c, what, timeout, limits, reporter, false, |_| Ok(())).map(|(output, _)| output)
}

/// The memory limits a gmsh process starts with: `memory` (the soft limit, in force) and
/// `most` (the hard limit, up to which a session raises its own soft limit for the mesh).
#[derive(Clone, Copy, Debug)]
struct SpawnLimits {
    memory: MemoryLimit,
    most: MemoryLimit,
}

/// Why a conversation with a gmsh session stopped early.
enum Stop {
    /// gmsh failed or ended: the message is made from all it printed and its exit status.
    Gmsh,
    /// An error of ours: a refusal, a timeout, an unreadable trial mesh.
    Error(Error),
}

/// The stdin and stdout lines of a running gmsh session (`converse`).
struct Conversation<'a> {
    stdin: Option<std::process::ChildStdin>,
    lines: mpsc::Receiver<String>,
    deadline: Instant,
    timeout: Duration,
    what: &'a str,
    /// The memory limit in force (the last one the session was told).
    memory: MemoryLimit,
}

impl Conversation<'_> {
    /// Send `command` (none: only wait) and wait for the answer `hbcontact:ok`; an answer
    /// `hbcontact:failed`, a line with "Error", or gmsh ending fail it.
    fn ask(&mut self, command: &str) -> std::result::Result<(), Stop> {
        if !command.is_empty() {
            let stdin = self.stdin.as_mut().ok_or(Stop::Gmsh)?;
            writeln!(stdin, "{command}")
                .and_then(|_| stdin.flush())
                .map_err(|_| Stop::Gmsh)?;
        }
        let mut error = false;
        loop {
            let left = self.deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) if line.starts_with("hbcontact:") => {
                    return match (line.trim_end() == "hbcontact:ok", error) {
                        (true, false) => Ok(()),
                        _ => Err(Stop::Gmsh),
                    }
                }
                Ok(line) => error |= line.contains("Error"),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    return Err(Stop::Error(timed_out(self.what, self.timeout)))
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => return Err(Stop::Gmsh),
            }
        }
    }
}

fn timed_out(what: &str, timeout: Duration) -> Error {
    Error::Gmsh(format!(
        "{what} did not finish within geometry.gmsh_timeout = {} s and was killed (with its process group); the mesh is probably too fine: a larger geometry.mesh_size or larger size parameters, or raise geometry.gmsh_timeout",
        timeout.as_secs_f64()
    ))
}

/// Start gmsh bounded (own process group, parent-death signal, `timeout` for the whole run,
/// stdout lines reported as progress of the task "gmsh"), let `talk` converse with it over
/// stdin and stdout when `interactive` (else stdin is empty), then wait for its end. Its group
/// is killed when `talk` stops with an error of ours or the time is up.
fn converse<T>(
    c: Command,
    what: &str,
    timeout: Duration,
    limits: SpawnLimits,
    reporter: &dyn Reporter,
    interactive: bool,
    talk: impl FnOnce(&mut Conversation) -> std::result::Result<T, Stop>,
) -> Result<(GmshOutput, std::result::Result<T, Stop>)> {
    let (mut child, mut guard) = spawn_bounded(c, what, interactive, limits)?;
    let pgid = guard.pgid;
    let (stdin, stdout, stderr) = (child.stdin.take(), child.stdout.take(), child.stderr.take());
    let start = Instant::now();
    let (status, talked, out_text, err_text, memory) = std::thread::scope(|scope| {
        let (sender, lines) = mpsc::channel();
        let out_reader = scope.spawn(move || read_stdout(stdout, reporter, sender));
        let err_reader = scope.spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut err) = stderr {
                let _ = err.read_to_end(&mut bytes);
            }
            String::from_utf8_lossy(&bytes).into_owned()
        });
        let mut conversation = Conversation {
            stdin,
            lines,
            deadline: start + timeout,
            timeout,
            what,
            memory: limits.memory,
        };
        let talked = talk(&mut conversation);
        let memory = conversation.memory;
        // Closing stdin ends a session; gmsh failing on its own ends by itself.
        drop(conversation);
        if let Err(Stop::Error(_)) = talked {
            kill_group(pgid);
        }
        let status = wait_bounded(&mut child, pgid, start + timeout, what, timeout);
        if status.is_err() {
            // Readers end when every writer of the pipes is gone: kill the whole group.
            kill_group(pgid);
        }
        let out_text = out_reader.join().unwrap_or_default();
        let err_text = err_reader.join().unwrap_or_default();
        (status, talked, out_text, err_text, memory)
    });
    reporter.task_done("gmsh");
    let status = status?;
    guard.ended = true;
    drop(guard);
    let output = GmshOutput {
        status,
        stdout: out_text,
        stderr: err_text,
        memory,
    };
    Ok((output, talked))
}

/// Start gmsh in its own process group, dying with this process (a parent-death signal), its
/// address space limited (`limits`: soft and hard RLIMIT_AS), its stdout and stderr piped (and
/// stdin when `interactive`), registered for `kill_running`.
fn spawn_bounded(
    mut c: Command,
    what: &str,
    interactive: bool,
    limits: SpawnLimits,
) -> Result<(std::process::Child, RunningGuard)> {
    let soft = limits.memory.bytes();
    let address_space = libc::rlimit {
        rlim_cur: soft as libc::rlim_t,
        rlim_max: limits.most.bytes().max(soft) as libc::rlim_t,
    };
    // SAFETY: getpid has no preconditions.
    let me = unsafe { libc::getpid() };
    c.process_group(0)
        .stdin(if interactive {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // The wheel's libgmsh links libgomp, whose thread pool spins on every core at start-up:
    // 0.22 s of CPU for 0.08 s of wall per gmsh process, against 0.07 s with one thread
    // (measured). gmsh meshes with one thread unless General.NumThreads asks for more, which
    // sets its own count over this; a user's own OMP_NUM_THREADS is kept.
    if std::env::var_os("OMP_NUM_THREADS").is_none() {
        c.env("OMP_NUM_THREADS", "1");
    }
    // SAFETY: the closure runs in the forked child before exec and calls only the
    // async-signal-safe system calls prctl, setrlimit and getppid, allocating nothing (the
    // rlimit is built before the fork). PR_SET_PDEATHSIG is the only way to make gmsh die
    // when hbcontact is killed by a signal it cannot catch (SIGKILL, the OOM killer), where
    // no handler of ours can run; RLIMIT_AS makes an allocation beyond the limit fail in
    // gmsh instead of taking the machine's memory.
    unsafe {
        c.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // Within the hard limit hbcontact itself runs under (raising it would fail).
            let mut limit = address_space;
            let mut current = libc::rlimit {
                rlim_cur: 0,
                rlim_max: 0,
            };
            if libc::getrlimit(libc::RLIMIT_AS, &mut current) == 0
                && current.rlim_max != libc::RLIM_INFINITY
            {
                limit.rlim_max = limit.rlim_max.min(current.rlim_max);
                limit.rlim_cur = limit.rlim_cur.min(current.rlim_max);
            }
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The parent may have died before prctl took effect.
            if libc::getppid() != me {
                return Err(std::io::Error::from_raw_os_error(libc::ESRCH));
            }
            Ok(())
        });
    }
    let child = c
        .spawn()
        .map_err(|e| Error::Gmsh(format!("cannot start {what}: {e}")))?;
    let pgid = child.id() as i32;
    if let Ok(mut running) = RUNNING.lock() {
        running.push(pgid);
    }
    Ok((child, RunningGuard { pgid, ended: false }))
}

/// gmsh's stdout: each of gmsh's lines reported as progress (the conversation's own answers,
/// `hbcontact:…`, are not), and every line passed on to the conversation.
fn read_stdout(
    stdout: Option<std::process::ChildStdout>,
    reporter: &dyn Reporter,
    sender: mpsc::Sender<String>,
) -> String {
    let mut text = String::new();
    if let Some(out) = stdout {
        for (i, line) in BufReader::new(out)
            .lines()
            .map_while(|l| l.ok())
            .enumerate()
        {
            if !line.starts_with("hbcontact:") {
                let status: String = line.trim().chars().take(100).collect();
                reporter.progress("gmsh", i as u64 + 1, None, &status);
            }
            text.push_str(&line);
            text.push('\n');
            let _ = sender.send(line);
        }
    }
    text
}

/// Wait for gmsh's end until `deadline`, then kill its group.
fn wait_bounded(
    child: &mut std::process::Child,
    pgid: i32,
    deadline: Instant,
    what: &str,
    timeout: Duration,
) -> Result<std::process::ExitStatus> {
    loop {
        match child.try_wait() {
            Ok(Some(status)) => return Ok(status),
            Ok(None) => {}
            Err(e) => return Err(Error::Gmsh(format!("waiting for {what}: {e}"))),
        }
        if Instant::now() > deadline {
            kill_group(pgid);
            let _ = child.wait();
            return Err(timed_out(what, timeout));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

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
trait GmshSteps {
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
    cmd: &'a GmshCommand,
    request: &'a MeshRequest,
    limits: &'a MeshLimits,
    memory: MemoryLimit,
    reporter: &'a dyn Reporter,
}

impl Commands<'_> {
    /// Run one gmsh step `c` writing `path`, under this run's limits and memory bound.
    fn run(&self, c: Command, path: &Path) -> std::result::Result<(), Stop> {
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
fn with_gmsh<T>(
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

/// The elements a trial mesh aims at: enough that gmsh's per-curve minimum node counts are
/// negligible, few enough that it takes a fraction of a second.
const TRIAL_ELEMENTS: f64 = 4000.0;

/// Elements of an equilateral-triangle mesh of size h per unit area: 4/(√3 h²).
const TRIANGLES_PER_AREA: f64 = 2.31;

/// What the geometry looks like before meshing (from gmsh `-0`): the bounding box of its points
/// and the smallest size it asks for anywhere (point sizes, field sizes, `-clmax`).
#[derive(Clone, Copy, Debug)]
struct Extent {
    area: f64,
    diagonal: f64,
    smallest_size: Option<f64>,
}

/// Read the points and sizes of an unrolled `.geo` (what gmsh `-0` writes: numbers and
/// `cl__N` variables).
fn parse_unrolled(text: &str) -> Option<Extent> {
    let mut vars: BTreeMap<String, f64> = BTreeMap::new();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut smallest = f64::INFINITY;
    let value = |vars: &BTreeMap<String, f64>, t: &str| -> Option<f64> {
        let t = t.trim();
        t.parse::<f64>().ok().or_else(|| vars.get(t).copied())
    };
    for line in text.lines() {
        let line = line.trim().trim_end_matches(';');
        let Some((lhs, rhs)) = line.split_once('=') else {
            continue;
        };
        let (lhs, rhs) = (lhs.trim(), rhs.trim());
        if lhs.starts_with("Point(") {
            let inner = rhs.trim_start_matches('{').trim_end_matches('}');
            let parts: Vec<&str> = inner.split(',').collect();
            let (Some(x), Some(y)) = (
                parts.first().and_then(|t| value(&vars, t)),
                parts.get(1).and_then(|t| value(&vars, t)),
            ) else {
                continue;
            };
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
            if let Some(lc) = parts.get(3).and_then(|t| value(&vars, t)) {
                if lc > 0.0 && lc < 1e20 {
                    smallest = smallest.min(lc);
                }
            }
        } else if let Some(field) = lhs.strip_prefix("Field[") {
            let attribute = field.split_once("].").map(|(_, a)| a).unwrap_or("");
            let is_size = attribute.starts_with("Size")
                || attribute.starts_with("Lc")
                || attribute == "VIn"
                || attribute == "VOut";
            if let (true, Some(v)) = (is_size, value(&vars, rhs)) {
                if v > 0.0 && v < 1e20 {
                    smallest = smallest.min(v);
                }
            }
        } else if !lhs.contains(['(', '[', '.', ' ']) {
            if let Ok(v) = rhs.parse::<f64>() {
                vars.insert(lhs.to_string(), v);
            }
        }
    }
    if !(lo[0].is_finite() && hi[0].is_finite()) {
        return None;
    }
    let (dx, dy) = (hi[0] - lo[0], hi[1] - lo[1]);
    let diagonal = (dx * dx + dy * dy).sqrt();
    let area = if dx > 0.0 && dy > 0.0 {
        dx * dy
    } else {
        diagonal * diagonal
    };
    Some(Extent {
        area,
        diagonal,
        smallest_size: smallest.is_finite().then_some(smallest),
    })
}

/// An estimate of the 2-D elements gmsh would make for `request`, without making them.
///
/// 1. gmsh `-0` (parse only) gives the points and every size the geometry asks for; with the
///    smallest size h (also `-clmax`) over the points' bounding box A, `2.31·A/h²` bounds the
///    count from above (fields may refine below h only where they name a smaller size, which is
///    counted). When that is below 4000 it is the estimate.
/// 2. Otherwise gmsh meshes with every size scaled by s (`-clscale`, applied after `-clmax`
///    and fields), s chosen for about 4000 elements by the bound; with n elements the estimate is
///    n·s² (2-D: the count scales with 1/size²). When n is small (gmsh's minimum nodes per curve
///    dominate), s is lowered (at most 10× per step) and gmsh meshes again, at most 4 times.
pub fn estimate_elements(
    cmd: &GmshCommand,
    request: &MeshRequest,
    scratch: &Path,
    limits: &MeshLimits,
    reporter: &dyn Reporter,
) -> Result<f64> {
    let out = scratch.join(format!("estimate-{}.msh", crate::files::unique_tag()));
    with_gmsh(cmd, request, limits, reporter, &out, |steps| {
        estimate_with(steps, request, scratch)
    })
}

/// The estimate (`estimate_elements`) through `steps`.
fn estimate_with(
    steps: &mut dyn GmshSteps,
    request: &MeshRequest,
    scratch: &Path,
) -> std::result::Result<f64, Stop> {
    let base = format!("estimate-{}", crate::files::unique_tag());
    let unrolled = scratch.join(format!("{base}.geo_unrolled"));
    steps.unroll(&unrolled)?;
    let text = std::fs::read_to_string(&unrolled).unwrap_or_default();
    let _ = std::fs::remove_file(&unrolled);
    let extent = parse_unrolled(&text);
    let mut scale = match extent {
        Some(e) => {
            let h = [e.smallest_size, request.mesh_size, Some(e.diagonal)]
                .into_iter()
                .flatten()
                .filter(|h| *h > 0.0)
                .fold(f64::INFINITY, f64::min);
            let bound = TRIANGLES_PER_AREA * e.area / (h * h);
            if bound <= TRIAL_ELEMENTS {
                return Ok(bound);
            }
            (bound / TRIAL_ELEMENTS).sqrt()
        }
        // No points read (an OpenCASCADE geometry, say): start coarse and refine.
        None => 1e6,
    };
    let trial = scratch.join(format!("{base}.msh"));
    let mut estimate = 0.0;
    for _ in 0..4 {
        let meshed = steps.mesh(scale, &trial);
        let cells = meshed.map(|()| super::msh::read_msh(&trial).map(|m| m.cells.len()));
        let _ = std::fs::remove_file(&trial);
        let n = cells?.map_err(Stop::Error)? as f64;
        estimate = n * scale * scale;
        if n >= TRIAL_ELEMENTS / 8.0 || scale <= 1.0 {
            break;
        }
        scale = (scale * (n.max(1.0) / TRIAL_ELEMENTS).sqrt())
            .max(scale / 10.0)
            .max(1.0);
    }
    Ok(estimate)
}

/// The SHA-256 of a cached mesh is kept beside it, in `<mesh>.msh.sha256`.
fn checksum_path(msh: &Path) -> PathBuf {
    let mut name = msh.as_os_str().to_owned();
    name.push(".sha256");
    PathBuf::from(name)
}

fn sha256_hex(bytes: &[u8]) -> String {
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
fn verify_cached(msh: &Path, max_elements: u64) -> std::result::Result<(), String> {
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
fn lock_entry(msh: &Path) -> Result<std::fs::File> {
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
    let version = gmsh_version(&cmd, Some(cache_dir))?;
    let stem = geo
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "mesh".into());
    let msh = cache_dir.join(format!(
        "{stem}-{}.msh",
        cache_key(request, &contents, &version)
    ));
    // One mesher per cache entry at a time, across threads and processes (a study's points,
    // Slurm shards on a shared file system): the others wait here, then find it cached.
    std::fs::create_dir_all(cache_dir).map_err(|e| Error::io(cache_dir, e))?;
    let _lock = lock_entry(&msh)?;
    if msh.is_file() {
        match verify_cached(&msh, limits.max_elements) {
            Ok(()) => {
                return Ok(MeshedGeometry {
                    msh,
                    cache_hit: true,
                    gmsh_version: version,
                })
            }
            Err(why) => {
                reporter.warning(&format!(
                    "cached mesh {} {why}: meshing again",
                    msh.display()
                ));
                evict(&msh);
            }
        }
    }
    // Unique per call: threads of one process (parallel tests, studies) may mesh at once.
    let tmp = crate::files::temp_beside(&msh);
    // The estimate, and its refusal, come before the mesh, in the same gmsh session.
    let meshed = with_gmsh(&cmd, request, limits, reporter, &tmp, |steps| {
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
    let sum = checksum_path(&msh);
    std::fs::write(&sum, sha256_hex(&bytes)).map_err(|e| Error::io(&sum, e))?;
    std::fs::rename(&tmp, &msh).map_err(|e| Error::io(&msh, e))?;
    Ok(MeshedGeometry {
        msh,
        cache_hit: false,
        gmsh_version: version,
    })
}
