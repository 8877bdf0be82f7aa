//! What the command line says when an interruption (Ctrl-C, SIGTERM, SIGHUP) ends the process
//! at once: the stage that was running, as the reporter last heard of it (`Tracking`), whether
//! gmsh was stopped, and what is kept (`Keeps`, set by each subcommand once it knows its output
//! folder). A sweep and the march of `transient` stop cleanly instead and write what they
//! found (`hbcontact::sweep::request_stop`, `hbcontact::transient::request_stop`).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use hbcontact::Reporter;

/// What an interrupted subcommand leaves behind.
#[derive(Clone, Debug)]
pub enum Keeps {
    /// Nothing written (`check`, `schema`, `compare` before it writes).
    Nothing,
    /// An output folder written whole or not at all: `<folder>.partial-<pid>` is staged and
    /// renamed onto the folder at the end (`hbcontact::output::staging`).
    Folder(PathBuf),
    /// A study's folder: each finished point's records are kept under `points/`.
    Study(PathBuf),
}

/// The stage and the tasks under way, as the reporter last heard of them.
#[derive(Default)]
struct Heard {
    /// The last stage announced, and whether it ended.
    stage: Option<(String, bool)>,
    /// Tasks under way: name, done, total.
    tasks: Vec<(String, u64, Option<u64>)>,
    keeps: Option<Keeps>,
}

static HEARD: Mutex<Heard> = Mutex::new(Heard {
    stage: None,
    tasks: Vec::new(),
    keeps: None,
});

/// What the running subcommand keeps when it is interrupted.
pub fn keeps(k: Keeps) {
    if let Ok(mut h) = HEARD.lock() {
        h.keeps = Some(k);
    }
}

/// A reporter that notes the stage and the tasks under way for `message`, then passes every
/// call on.
pub struct Tracking(pub Box<dyn Reporter>);

impl Reporter for Tracking {
    fn stage(&self, name: &str) {
        if let Ok(mut h) = HEARD.lock() {
            h.stage = Some((name.to_string(), false));
        }
        self.0.stage(name);
    }

    fn stage_done(&self, name: &str, seconds: f64) {
        if let Ok(mut h) = HEARD.lock() {
            h.stage = Some((name.to_string(), true));
        }
        self.0.stage_done(name, seconds);
    }

    fn progress(&self, task: &str, done: u64, total: Option<u64>, status: &str) {
        if let Ok(mut h) = HEARD.lock() {
            match h.tasks.iter_mut().find(|t| t.0 == task) {
                Some(t) => (t.1, t.2) = (done, total),
                None => h.tasks.push((task.to_string(), done, total)),
            }
        }
        self.0.progress(task, done, total, status);
    }

    fn task_done(&self, task: &str) {
        if let Ok(mut h) = HEARD.lock() {
            h.tasks.retain(|t| t.0 != task);
        }
        self.0.task_done(task);
    }

    fn warning(&self, message: &str) {
        self.0.warning(message);
    }
}

/// The staged folder this process writes for `folder` (`staging::StagedDir`).
fn partial_of(folder: &Path) -> Option<PathBuf> {
    let name = folder.file_name()?.to_string_lossy().into_owned();
    let partial = folder.with_file_name(format!("{name}.partial-{}", std::process::id()));
    partial.exists().then_some(partial)
}

/// The message of an interruption that ends the process now: e.g. "interrupted during the
/// `write` stage: nothing written; output/strip is as it was, and the unfinished
/// output/strip.partial-123 is removed by the next run into it".
pub fn message(gmsh_stopped: bool) -> String {
    let heard = HEARD.lock().map(|h| Heard {
        stage: h.stage.clone(),
        tasks: h.tasks.clone(),
        keeps: h.keeps.clone(),
    });
    let heard = heard.unwrap_or_default();
    let mut text = match &heard.stage {
        Some((name, false)) => format!("interrupted during the `{name}` stage"),
        Some((name, true)) => format!("interrupted after the `{name}` stage"),
        None => "interrupted before the first stage".to_string(),
    };
    if !heard.tasks.is_empty() {
        let tasks: Vec<String> = heard
            .tasks
            .iter()
            .map(|(name, done, total)| match total {
                Some(n) => format!("{name} {done}/{n}"),
                None => format!("{name} {done}"),
            })
            .collect();
        text.push_str(&format!(" ({})", tasks.join(", ")));
    }
    if gmsh_stopped {
        text.push_str("; gmsh stopped");
    }
    let kept = match heard.keeps.unwrap_or(Keeps::Nothing) {
        Keeps::Nothing => "nothing written".to_string(),
        Keeps::Folder(dir) => {
            let mut kept = format!(
                "nothing written: {} is as it was before this run",
                dir.display()
            );
            if let Some(partial) = partial_of(&dir) {
                kept.push_str(&format!(
                    ", and the unfinished {} is removed by the next run into it",
                    partial.display()
                ));
            }
            kept
        }
        Keeps::Study(dir) => format!(
            "the points finished so far are kept in {}/points; run the study again to finish \
             it (finished points are not run again)",
            dir.display()
        ),
    };
    format!("{text}: {kept}")
}
