//! gmsh as a bounded child process: its own process group, a time limit after which the
//! whole group is killed, a memory limit (setrlimit before exec), a parent-death signal, and
//! a conversation on its stdin and stdout for the session driver.

use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::process::{Command, Stdio};
use std::sync::{mpsc, Mutex};
use std::time::{Duration, Instant};

use crate::progress::Reporter;
use crate::{Error, Result};

use super::*;

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
pub(super) fn describe_status(status: &std::process::ExitStatus) -> String {
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
pub(super) struct SpawnLimits {
    pub(super) memory: MemoryLimit,
    pub(super) most: MemoryLimit,
}

/// Why a conversation with a gmsh session stopped early.
pub(super) enum Stop {
    /// gmsh failed or ended: the message is made from all it printed and its exit status.
    Gmsh,
    /// An error of ours: a refusal, a timeout, an unreadable trial mesh.
    Error(Error),
}

/// The stdin and stdout lines of a running gmsh session (`converse`).
pub(super) struct Conversation<'a> {
    pub(super) stdin: Option<std::process::ChildStdin>,
    pub(super) lines: mpsc::Receiver<String>,
    deadline: Instant,
    pub(super) timeout: Duration,
    pub(super) what: &'a str,
    /// The memory limit in force (the last one the session was told).
    pub(super) memory: MemoryLimit,
}

impl Conversation<'_> {
    /// Send `command` (none: only wait) and wait for the answer `hbcontact:ok`; an answer
    /// `hbcontact:failed`, a line with "Error", or gmsh ending fail it.
    pub(super) fn ask(&mut self, command: &str) -> std::result::Result<(), Stop> {
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
pub(super) fn converse<T>(
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
