//! The command line's `Reporter`: progress bars (indicatif) for long tasks when stderr is a
//! terminal, plain lines (at most one per task and second) when it is not.

use std::collections::HashMap;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use hbcontact::Reporter;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

pub struct Cli {
    bars: Option<MultiProgress>,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    bars: HashMap<String, ProgressBar>,
    last_line: HashMap<String, Instant>,
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
}

impl Reporter for Cli {
    fn stage(&self, name: &str) {
        self.line(&format!("[{name}]"));
    }

    fn stage_done(&self, name: &str, seconds: f64) {
        self.line(&format!("[{name}] {seconds:.3} s"));
    }

    fn progress(&self, task: &str, done: u64, total: Option<u64>, status: &str) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
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
                let now = Instant::now();
                let due = state
                    .last_line
                    .get(task)
                    .is_none_or(|t| now.duration_since(*t) >= Duration::from_secs(1));
                if due {
                    state.last_line.insert(task.to_string(), now);
                    let of = total.map(|n| format!("/{n}")).unwrap_or_default();
                    eprintln!("  {task} {done}{of}: {status}");
                }
            }
        }
    }

    fn task_done(&self, task: &str) {
        if let Ok(mut state) = self.state.lock() {
            if let Some(bar) = state.bars.remove(task) {
                bar.finish_and_clear();
            }
            state.last_line.remove(task);
        }
    }

    fn warning(&self, message: &str) {
        self.line(&format!("warning: {message}"));
    }
}
