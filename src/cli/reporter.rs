//! The command line's `Reporter`. Each stage is one line, `[mesh] 0.378 s`, when it ends. Long
//! tasks (the sweep's frequency, a study's points, the contact Newton, the marching periods
//! and the step within one) show as progress bars (indicatif) when stderr is a terminal;
//! otherwise as plain lines, at most one per second in all, each naming every task under way
//! (`sweep 41: 1402.964 Hz; factor 3/11: harmonic 2`); a task that a line showed and that
//! ends in a state no line showed says that last state once (`points 9/9: …`), before its
//! stage's time, unless it ran inside another (a sweep's hundreds of factorizations print
//! nothing of their own). A stage that shows progress is announced (`[stability]`) before its
//! first line. A stage run again that shows no progress of its own (the quick checks between
//! mesh, assembly and solve) prints no second line: `[check]` appears once a run, and
//! summary.json's `stage_seconds` holds the sum of its parts.

use std::collections::{HashMap, HashSet};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use hbcontact::Reporter;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The shortest time between two progress lines (without a terminal).
const LINE_INTERVAL: Duration = Duration::from_secs(1);

pub struct Cli {
    bars: Option<MultiProgress>,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    /// Terminal: a bar per task under way, and a spinner for the running stage.
    bars: HashMap<String, ProgressBar>,
    stage_bar: Option<ProgressBar>,
    /// Lines: the tasks under way in the order they started, each with its latest state and
    /// whether a line showed it.
    tasks: Vec<Task>,
    /// The stage started and not yet named on a line.
    unannounced: Option<String>,
    /// When the last progress line was printed.
    last_line: Option<Instant>,
    /// The stages whose line was printed.
    printed: HashSet<String>,
    /// The running stage reported progress.
    progressed: bool,
}

struct Task {
    name: String,
    text: String,
    /// A line showed `text`.
    shown: bool,
    /// A line showed this task at all (a task too short for one stays silent to its end).
    seen: bool,
}

impl State {
    /// Print the tasks under way on one line (announcing the stage first).
    fn print_tasks(&mut self) {
        if let Some(stage) = self.unannounced.take() {
            eprintln!("[{stage}]");
        }
        let line: Vec<&str> = self.tasks.iter().map(|t| t.text.as_str()).collect();
        eprintln!("  {}", line.join("; "));
        for t in &mut self.tasks {
            t.shown = true;
            t.seen = true;
        }
        self.last_line = Some(Instant::now());
    }
}

impl Cli {
    pub fn new() -> Self {
        let bars = std::io::stderr()
            .is_terminal()
            .then(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()));
        Cli {
            bars,
            state: Mutex::new(State::default()),
        }
    }

    fn line(&self, text: &str) {
        match &self.bars {
            Some(mp) => {
                if mp.println(text).is_err() {
                    eprintln!("{text}");
                }
            }
            None => eprintln!("{text}"),
        }
    }

    fn bar(mp: &MultiProgress, task: &str, total: Option<u64>) -> ProgressBar {
        let bar = match total {
            Some(n) => ProgressBar::new(n).with_style(
                ProgressStyle::with_template(
                    "  {prefix:>15} [{bar:30}] {pos}/{len} {elapsed} {msg}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
            ),
            None => ProgressBar::new_spinner().with_style(
                ProgressStyle::with_template("  {prefix:>15} {spinner} {pos} {elapsed} {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            ),
        };
        let bar = mp.add(bar.with_prefix(task.to_string()));
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    }

    fn stage_spinner(mp: &MultiProgress, name: &str) -> ProgressBar {
        let bar = ProgressBar::new_spinner().with_style(
            ProgressStyle::with_template("[{prefix}] {spinner} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        let bar = mp.insert(0, bar.with_prefix(name.to_string()));
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    }
}

impl Reporter for Cli {
    fn stage(&self, name: &str) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        state.progressed = false;
        match &self.bars {
            Some(mp) => {
                if let Some(old) = state.stage_bar.take() {
                    old.finish_and_clear();
                }
                state.stage_bar = Some(Self::stage_spinner(mp, name));
            }
            None => state.unannounced = Some(name.to_string()),
        }
    }

    fn stage_done(&self, name: &str, seconds: f64) {
        if let Ok(mut state) = self.state.lock() {
            if let Some(bar) = state.stage_bar.take() {
                bar.finish_and_clear();
            }
            state.unannounced = None;
            // A task's last state that no line showed goes before the stage's time.
            if state.tasks.iter().any(|t| t.seen && !t.shown) {
                state.print_tasks();
            }
            let again = !state.printed.insert(name.to_string());
            if again && !state.progressed {
                return;
            }
        }
        self.line(&format!("[{name}] {seconds:.3} s"));
    }

    fn progress(&self, task: &str, done: u64, total: Option<u64>, status: &str) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        state.progressed = true;
        match &self.bars {
            Some(mp) => {
                let bar = state
                    .bars
                    .entry(task.to_string())
                    .or_insert_with(|| Self::bar(mp, task, total));
                bar.set_position(done);
                bar.set_message(status.to_string());
            }
            None => {
                let of = total.map(|n| format!("/{n}")).unwrap_or_default();
                let text = match status {
                    "" => format!("{task} {done}{of}"),
                    _ => format!("{task} {done}{of}: {status}"),
                };
                match state.tasks.iter_mut().find(|t| t.name == task) {
                    Some(t) => {
                        t.shown &= t.text == text;
                        t.text = text;
                    }
                    None => state.tasks.push(Task {
                        name: task.to_string(),
                        text,
                        shown: false,
                        seen: false,
                    }),
                }
                let due = state.last_line.is_none_or(|t| t.elapsed() >= LINE_INTERVAL);
                if due {
                    state.print_tasks();
                }
            }
        }
    }

    fn task_done(&self, task: &str) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        if let Some(bar) = state.bars.remove(task) {
            bar.finish_and_clear();
        }
        let Some(i) = state.tasks.iter().position(|t| t.name == task) else {
            return;
        };
        let ended = state.tasks.remove(i);
        if ended.seen && !ended.shown && state.tasks.is_empty() {
            state.tasks.push(ended);
            state.print_tasks();
            state.tasks.clear();
        }
    }

    fn warning(&self, message: &str) {
        self.line(&format!("warning: {message}"));
    }
}
