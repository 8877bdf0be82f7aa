//! Output folders the tool owns, written whole or not at all.
//!
//! A run writes into `<name>.partial-<pid>` and renames it onto `<name>` only when everything
//! is written, so a failed run never leaves a series that looks complete (and keeps the
//! previous complete one); a sweep swept again stages its second curve beside the first, in
//! `<name>.partial-<pid>.again`, and commits one of the two. Every folder it writes carries a
//! marker, `MARKER`, naming the tool, its version, the command, the folder's name, the
//! writing process and the entries it wrote.
//!
//! The rule (nothing the tool did not make is deleted or overwritten):
//! - an existing output folder is replaced only when it is empty, or holds a marker and no
//!   entry beyond those the marker lists (other hbcontact outputs nested in it, such as a
//!   sweep's `sweep/` in its run's folder, each with a marker of its own, are carried over
//!   into the new folder); otherwise the run refuses before it starts, naming the folder and
//!   what it holds, or with `Replace::MoveAside` (`--force`) renames it aside to
//!   `<name>.moved-<unix seconds>` when the results are written;
//! - a stale `<name>.partial-<pid>` (or `….again`) beside the target is removed only when
//!   `<name>` is this run's target, the pid is dead and the folder's marker names that target
//!   and that pid.
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::progress::Reporter;
use crate::{Error, Result};

/// The marker file hbcontact writes into every output folder it makes.
pub const MARKER: &str = ".hbcontact-output.json";

/// The largest marker read back [bytes]: a marker is a few hundred bytes; anything larger is
/// not one of ours.
const MARKER_BYTES: u64 = 1 << 20;

/// Who may replace an existing output folder.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Replace {
    /// Only a folder hbcontact wrote and nobody added to (its marker), an empty one, or none.
    #[default]
    IfOurs,
    /// As `IfOurs`, but a folder that is not ours is moved aside, never deleted (`--force`).
    MoveAside,
    /// The caller owns the folder (a study's point folder, inside the study's own tree).
    Owned,
}

/// What a marker says.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Marker {
    tool: String,
    version: String,
    command: String,
    /// The folder's name when written (`<name>` also for its `.partial-<pid>`).
    target: String,
    pid: u32,
    /// The entries the tool wrote (empty while staged).
    entries: Vec<String>,
}

fn read_marker(dir: &Path) -> Option<Marker> {
    use std::io::Read as _;
    let file = std::fs::File::open(dir.join(MARKER)).ok()?;
    let mut text = String::new();
    file.take(MARKER_BYTES).read_to_string(&mut text).ok()?;
    let marker: Marker = serde_json::from_str(&text).ok()?;
    (marker.tool == "hbcontact").then_some(marker)
}

fn write_marker(dir: &Path, command: &str, target: &str, entries: Vec<String>) -> Result<()> {
    let marker = Marker {
        tool: "hbcontact".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        command: command.into(),
        target: target.into(),
        pid: std::process::id(),
        entries,
    };
    let path = dir.join(MARKER);
    let text = serde_json::to_string_pretty(&marker).map_err(|e| Error::Model(e.to_string()))?;
    crate::files::write_atomic(&path, text.as_bytes()).map_err(|e| Error::io(&path, e))
}

/// What an existing path at an output folder's place is.
#[derive(Debug)]
enum Held {
    Absent,
    Empty,
    /// Ours: replaceable; the nested hbcontact outputs to carry over.
    Ours {
        nested: Vec<String>,
    },
    /// Not ours: what it holds that the tool did not write (a few names).
    Foreign(String),
}

fn names(dir: &Path) -> std::io::Result<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(dir)?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    Ok(names)
}

fn held(dir: &Path) -> Result<Held> {
    let meta = match std::fs::symlink_metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Held::Absent),
        Err(e) => return Err(Error::io(dir, e)),
        Ok(m) => m,
    };
    if !meta.is_dir() {
        return Ok(Held::Foreign("a file, not a folder".into()));
    }
    let entries = names(dir).map_err(|e| Error::io(dir, e))?;
    if entries.is_empty() {
        return Ok(Held::Empty);
    }
    // Without a marker, a folder is ours only when all it holds are outputs of ours (a
    // sweep's `sweep/` and the mesh cache in a run's folder not written yet).
    let listed_by_marker = read_marker(dir).map(|m| m.entries).unwrap_or_default();
    let mut nested = Vec::new();
    let mut foreign = Vec::new();
    for name in entries.into_iter().filter(|n| n != MARKER) {
        if listed_by_marker.contains(&name) {
            continue;
        }
        let path = dir.join(&name);
        let is_dir = std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_dir());
        if is_dir && read_marker(&path).is_some() {
            nested.push(name);
        } else {
            foreign.push(name);
        }
    }
    if foreign.is_empty() {
        Ok(Held::Ours { nested })
    } else {
        Ok(Held::Foreign(format!(
            "{}, which hbcontact did not write there (no marker {MARKER} lists it)",
            listed(&foreign)
        )))
    }
}

/// "a.txt, b/ and 3 more".
fn listed(names: &[String]) -> String {
    let shown: Vec<&str> = names.iter().take(3).map(String::as_str).collect();
    match names.len() {
        n if n > 3 => format!("{} and {} more", shown.join(", "), n - 3),
        _ => shown.join(", "),
    }
}

fn refusal(dir: &Path, what: &str) -> Error {
    Error::Input(format!(
        "the output folder {} exists and holds {what}; hbcontact never deletes what it did not \
         write. Choose another folder (--out DIR or output.directory), empty it yourself, or \
         pass --force to have it moved aside to {}.moved-<time> when the results are written",
        dir.display(),
        dir.display()
    ))
}

/// Before a run starts: may it write `final_dir`? Refuses a folder that is not ours (exit 2)
/// unless `replace` says otherwise, then removes this target's stale partial folders.
pub fn claim(final_dir: &Path, replace: Replace, reporter: &dyn Reporter) -> Result<()> {
    if replace != Replace::Owned {
        if let Held::Foreign(what) = held(final_dir)? {
            if replace == Replace::IfOurs {
                return Err(refusal(final_dir, &what));
            }
            reporter.warning(&format!(
                "{} holds {what}: --force moves it aside to {}.moved-<time> when the results are written",
                final_dir.display(),
                final_dir.display()
            ));
        }
    }
    remove_stale_partials(final_dir, reporter);
    Ok(())
}

/// A folder's own name (the marker's `target`).
fn folder_name(dir: &Path) -> Option<String> {
    dir.file_name().map(|n| n.to_string_lossy().into_owned())
}

fn parent_of(final_dir: &Path) -> PathBuf {
    match final_dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Remove the `<name>.partial-<pid>` folders that runs which no longer exist left beside
/// `final_dir` (a run killed outright cannot clean up after itself), telling the reporter
/// about each. Only this target's (`<name>` is `final_dir`'s name), only when `/proc` says the
/// pid is gone, and only when the folder's marker names this target and that pid: anything
/// else that looks like one is left alone. Returns what went.
pub fn remove_stale_partials(final_dir: &Path, reporter: &dyn Reporter) -> Vec<PathBuf> {
    let proc_fs = Path::new("/proc");
    let Some(target) = folder_name(final_dir) else {
        return Vec::new();
    };
    if !proc_fs.join("self").exists() {
        return Vec::new();
    }
    let Ok(entries) = names(&parent_of(final_dir)) else {
        return Vec::new();
    };
    let prefix = format!("{target}.partial-");
    let mut removed = Vec::new();
    for name in entries {
        let Some(pid) = name
            .strip_prefix(&prefix)
            .and_then(|p| p.strip_suffix(".again").unwrap_or(p).parse::<u32>().ok())
        else {
            continue;
        };
        let path = parent_of(final_dir).join(&name);
        let ours = read_marker(&path).is_some_and(|m| m.target == target && m.pid == pid);
        if !ours || pid == std::process::id() || proc_fs.join(pid.to_string()).exists() {
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

/// `<dir>.moved-<unix seconds>`, or with `-<k>` when that exists.
fn aside(dir: &Path) -> PathBuf {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let base = format!("{}.moved-{secs}", dir.display());
    let mut path = PathBuf::from(&base);
    let mut k = 1;
    while std::fs::symlink_metadata(&path).is_ok() {
        path = PathBuf::from(format!("{base}-{k}"));
        k += 1;
    }
    path
}

/// A directory written under a temporary name and renamed onto its final name by `commit`.
pub struct StagedDir {
    pub final_dir: PathBuf,
    pub temp_dir: PathBuf,
    command: String,
    replace: Replace,
    committed: bool,
    /// Where `commit` moved a folder that was not ours (`Replace::MoveAside`).
    pub moved_aside: Option<PathBuf>,
}

impl StagedDir {
    /// Stage `final_dir` for `command` (the marker's word: `run`, `sweep`, …).
    pub fn create(final_dir: &Path, command: &str, replace: Replace) -> Result<Self> {
        Self::create_as(final_dir, command, replace, "")
    }

    /// A second staging of the same folder beside this one (`<name>.partial-<pid>.again`):
    /// whichever of the two is committed replaces the folder, the other is removed when
    /// dropped.
    pub fn again(&self) -> Result<Self> {
        Self::create_as(&self.final_dir, &self.command, self.replace, ".again")
    }

    fn create_as(final_dir: &Path, command: &str, replace: Replace, suffix: &str) -> Result<Self> {
        let name = folder_name(final_dir).ok_or_else(|| {
            Error::Input(format!(
                "output directory {} has no name",
                final_dir.display()
            ))
        })?;
        let parent = parent_of(final_dir);
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let temp_dir = parent.join(format!("{name}.partial-{}{suffix}", std::process::id()));
        if std::fs::symlink_metadata(&temp_dir).is_ok() {
            match read_marker(&temp_dir) {
                Some(m) if m.pid == std::process::id() => {
                    std::fs::remove_dir_all(&temp_dir).map_err(|e| Error::io(&temp_dir, e))?
                }
                _ => return Err(refusal(&temp_dir, "files of another origin")),
            }
        }
        std::fs::create_dir(&temp_dir).map_err(|e| Error::io(&temp_dir, e))?;
        let staged = StagedDir {
            final_dir: final_dir.to_path_buf(),
            temp_dir,
            command: command.into(),
            replace,
            committed: false,
            moved_aside: None,
        };
        write_marker(&staged.temp_dir, command, &name, Vec::new())?;
        Ok(staged)
    }

    pub fn path(&self) -> &Path {
        &self.temp_dir
    }

    /// Replace the previous output by the staged one, by the rule in the module's header:
    /// ours is replaced (nested outputs carried over), anything else refused or moved aside.
    pub fn commit(mut self) -> Result<PathBuf> {
        let target = folder_name(&self.final_dir).unwrap_or_default();
        let written: Vec<String> = names(&self.temp_dir)
            .map_err(|e| Error::io(&self.temp_dir, e))?
            .into_iter()
            .filter(|n| n != MARKER)
            .collect();
        write_marker(&self.temp_dir, &self.command, &target, written.clone())?;
        let held = match self.replace {
            Replace::Owned if self.final_dir.is_dir() => Held::Ours { nested: Vec::new() },
            _ => held(&self.final_dir)?,
        };
        match held {
            Held::Absent => {}
            Held::Empty => {
                std::fs::remove_dir(&self.final_dir).map_err(|e| Error::io(&self.final_dir, e))?
            }
            Held::Ours { nested } => self.replace_ours(&nested, &written)?,
            Held::Foreign(what) => match self.replace {
                Replace::MoveAside => {
                    let to = aside(&self.final_dir);
                    std::fs::rename(&self.final_dir, &to).map_err(|e| Error::io(&to, e))?;
                    self.moved_aside = Some(to);
                }
                _ => return Err(refusal(&self.final_dir, &what)),
            },
        }
        std::fs::rename(&self.temp_dir, &self.final_dir)
            .map_err(|e| Error::io(&self.final_dir, e))?;
        self.committed = true;
        Ok(self.final_dir.clone())
    }

    /// Carry the nested outputs of the previous folder into the staged one, then remove the
    /// previous folder (all of it the tool's own).
    fn replace_ours(&self, nested: &[String], written: &[String]) -> Result<()> {
        for name in nested {
            if written.contains(name) {
                return Err(Error::Input(format!(
                    "{} holds the hbcontact output {name}/ of another command, and this {} \
                     writes an entry of that name: move it, or write elsewhere (--out DIR)",
                    self.final_dir.display(),
                    self.command
                )));
            }
        }
        for name in nested {
            let (from, to) = (self.final_dir.join(name), self.temp_dir.join(name));
            std::fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
        std::fs::remove_dir_all(&self.final_dir).map_err(|e| Error::io(&self.final_dir, e))
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp_dir);
        }
    }
}

/// A folder that accumulates (a study's results, `compare` beside a run's output), so it is
/// not replaced as a whole. Before `command` writes the entries `claimed` into `out`, `out`
/// must be absent, hold the marker, or hold none of `claimed` (a user's own files beside
/// them are never touched); the marker then lists `claimed` among the tool's entries, so
/// that a later run replacing the folder counts them as its own.
pub fn claim_entries(out: &Path, command: &str, claimed: &[&str]) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let target = folder_name(out).unwrap_or_default();
    let (command, mut entries) = match read_marker(out) {
        Some(m) => (m.command, m.entries),
        None => {
            let taken: Vec<String> = claimed
                .iter()
                .filter(|n| std::fs::symlink_metadata(out.join(n)).is_ok())
                .map(|n| n.to_string())
                .collect();
            if !taken.is_empty() {
                let what = format!("{} and no hbcontact marker", listed(&taken));
                return Err(refusal(out, &what));
            }
            (command.to_string(), Vec::new())
        }
    };
    let before = entries.len();
    for name in claimed {
        if !entries.iter().any(|e| e == name) {
            entries.push(name.to_string());
        }
    }
    if entries.len() > before || before == 0 {
        write_marker(out, &command, &target, entries)?;
    }
    Ok(())
}

/// Mark `dir`, a folder the tool made and keeps (the mesh cache), unless it is marked: a
/// run's folder that holds it counts it as the tool's own.
pub fn mark_kept(dir: &Path, command: &str) -> Result<()> {
    if dir.is_dir() && read_marker(dir).is_none() {
        let target = folder_name(dir).unwrap_or_default();
        write_marker(dir, command, &target, Vec::new())?;
    }
    Ok(())
}

/// Write a marker into `dir`, which the caller made under a temporary name for `target` (a
/// study's `.results.partial-<pid>` for `.results`).
pub fn mark(dir: &Path, command: &str, target: &str) -> Result<()> {
    write_marker(dir, command, target, Vec::new())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "hbcontact-staging-{tag}-{}",
            crate::files::unique_tag()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn staged_run(out: &Path, replace: Replace, file: &str) -> Result<StagedDir> {
        let s = StagedDir::create(out, "run", replace)?;
        std::fs::write(s.path().join(file), b"result").unwrap();
        Ok(s)
    }

    /// TEST GOAL: a folder of the user's (a file and a subfolder, no marker) survives a
    /// staged run pointed at it: `claim` refuses it naming `--force`, `commit` refuses it
    /// too (the folder filled during the run), and with `MoveAside` it is renamed aside whole,
    /// never deleted.
    #[test]
    fn a_users_folder_is_refused_or_moved_aside_never_deleted() {
        let root = scratch("user");
        let out = root.join("userdata");
        std::fs::create_dir_all(out.join("chapter")).unwrap();
        std::fs::write(out.join("thesis.txt"), b"thesis").unwrap();
        let e = claim(&out, Replace::IfOurs, &crate::Silent).unwrap_err();
        assert!(e.to_string().contains("--force") && e.to_string().contains("thesis.txt"));
        assert_eq!(e.exit_code(), 2);
        let e = staged_run(&out, Replace::IfOurs, "summary.json")
            .unwrap()
            .commit()
            .unwrap_err();
        assert!(e.to_string().contains("never deletes"), "{e}");
        assert_eq!(std::fs::read(out.join("thesis.txt")).unwrap(), b"thesis");
        claim(&out, Replace::MoveAside, &crate::Silent).unwrap();
        let staged = staged_run(&out, Replace::MoveAside, "summary.json").unwrap();
        let dir = staged.commit().unwrap();
        assert!(dir.join("summary.json").exists());
        let moved = std::fs::read_dir(&root)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .find(|p| p.to_string_lossy().contains("userdata.moved-"))
            .expect("the user's folder moved aside");
        assert_eq!(std::fs::read(moved.join("thesis.txt")).unwrap(), b"thesis");
        assert!(moved.join("chapter").is_dir());
        // Our own output is replaced by the next run, without --force.
        staged_run(&out, Replace::IfOurs, "next.json")
            .unwrap()
            .commit()
            .unwrap();
        assert!(out.join("next.json").exists() && !out.join("summary.json").exists());
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// TEST GOAL: an output of ours is replaced; a file the user added to it makes the next
    /// run refuse; another command's output nested in it (a sweep's `sweep/`) is carried
    /// into the new folder, not deleted.
    #[test]
    fn our_output_is_replaced_keeping_nested_outputs_and_refusing_added_files() {
        let root = scratch("ours");
        let out = root.join("strip");
        staged_run(&out, Replace::IfOurs, "a.vtu")
            .unwrap()
            .commit()
            .unwrap();
        let sweep = StagedDir::create(&out.join("sweep"), "sweep", Replace::IfOurs).unwrap();
        std::fs::write(sweep.path().join("sweep.csv"), b"rows").unwrap();
        sweep.commit().unwrap();
        staged_run(&out, Replace::IfOurs, "b.vtu")
            .unwrap()
            .commit()
            .unwrap();
        assert!(out.join("b.vtu").exists() && !out.join("a.vtu").exists());
        assert_eq!(std::fs::read(out.join("sweep/sweep.csv")).unwrap(), b"rows");
        std::fs::write(out.join("notes.md"), b"mine").unwrap();
        assert!(claim(&out, Replace::IfOurs, &crate::Silent).is_err());
        assert!(staged_run(&out, Replace::IfOurs, "c.vtu")
            .unwrap()
            .commit()
            .is_err());
        assert_eq!(std::fs::read(out.join("notes.md")).unwrap(), b"mine");
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// TEST GOAL: stale-partial clean-up removes only this target's partial folders (the
    /// first staging and a sweep's second) of a dead pid holding our marker: a look-alike
    /// without the marker, another target's partial and a partial whose marker names another
    /// pid all survive.
    #[test]
    fn only_this_targets_marked_partials_of_dead_runs_are_removed() {
        let root = scratch("partials");
        let out = root.join("a");
        let dead = 4_194_400; // above Linux's largest pid_max (2^22): never a live process
        let ours = root.join(format!("a.partial-{dead}"));
        std::fs::create_dir_all(&ours).unwrap();
        std::fs::write(
            ours.join(MARKER),
            format!(r#"{{"tool":"hbcontact","version":"0","command":"run","target":"a","pid":{dead},"entries":[]}}"#),
        )
        .unwrap();
        let lookalike = root.join(format!("notes.partial-{dead}"));
        let unmarked = root.join(format!("a.partial-{}", dead + 1));
        let other = root.join(format!("b.partial-{dead}"));
        let wrong_pid = root.join(format!("a.partial-{}", dead + 2));
        for d in [&lookalike, &unmarked, &other, &wrong_pid] {
            std::fs::create_dir_all(d).unwrap();
            std::fs::write(d.join("keep.txt"), b"keep").unwrap();
        }
        std::fs::copy(ours.join(MARKER), other.join(MARKER)).unwrap();
        std::fs::copy(ours.join(MARKER), wrong_pid.join(MARKER)).unwrap();
        // A sweep's second staging (`StagedDir::again`) of the same dead run goes too.
        let again = root.join(format!("a.partial-{dead}.again"));
        std::fs::create_dir_all(&again).unwrap();
        std::fs::copy(ours.join(MARKER), again.join(MARKER)).unwrap();
        let mut removed = remove_stale_partials(&out, &crate::Silent);
        removed.sort();
        assert_eq!(removed, vec![ours.clone(), again.clone()]);
        for d in [&lookalike, &unmarked, &other, &wrong_pid] {
            assert!(d.join("keep.txt").exists(), "{}", d.display());
        }
        std::fs::remove_dir_all(&root).unwrap();
    }
}
