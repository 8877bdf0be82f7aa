//! The user scenes of `pipelines/scenes/` (issue #45), each swept once as shipped (stability
//! check included): per scene its H, the points, folds, Newton iterations of the correctors
//! (summed over the rows), sets of factorizations, the points re-solved on factored frames
//! after the reduced model's check failed, the wall time of the sweep (of both sweeps where
//! the default steps stopped and the curve was swept again with a turn limit), and where and
//! why it stopped if it did, or where the default steps stopped before it was swept again.
//! A curve stopped among unstable states is swept from the other end (`sweep::other_end`):
//! its points and folds follow the first curve's after a `+`, its time is in the wall time,
//! and the row says what it reached and what neither curve traced.
//! A failing scene is a row, not the end of the bench.
//!
//! `cargo bench --bench scenes [-- NAME ...]` (default: every scene).

use std::path::PathBuf;
use std::time::Instant;

use hbcontact::config::load_pipeline;
use hbcontact::pipeline::RunOptions;
use hbcontact::Silent;

const SCENES: [&str; 10] = [
    "cantilever_stop",
    "cantilever_stop_p2",
    "clamped_stops",
    "clamped_stops_p2",
    "blade_mode1",
    "blade_mode2",
    "vibro_impact_bar",
    "vibro_impact_bar_p2",
    "preloaded_rod",
    "strip_light",
];

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let asked: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    println!(
        "{:<20} {:>3} {:>11} {:>8} {:>6} {:>7} {:>6} {:>9} {:>8}  stopped",
        "scene", "H", "range [Hz]", "points", "folds", "newton", "factor", "re-solves", "time [s]"
    );
    for name in SCENES {
        if !asked.is_empty() && !asked.iter().any(|a| a == name) {
            continue;
        }
        let path = root.join("pipelines/scenes").join(format!("{name}.yaml"));
        let p = match load_pipeline(&path, &[]) {
            Ok(p) => p,
            Err(e) => {
                println!("{name:<20} {e}");
                continue;
            }
        };
        let options = RunOptions {
            out: Some(root.join("output/bench-scenes").join(name)),
            ..Default::default()
        };
        let t = Instant::now();
        let s = match hbcontact::sweep::run(&p, &options, &Silent) {
            Ok(r) => r.summary,
            Err(e) => {
                println!("{name:<20} {e}");
                continue;
            }
        };
        let wall = t.elapsed().as_secs_f64();
        let newton: usize = s.rows.iter().map(|r| r.newton_iterations).sum();
        let factor: usize = s.rows.iter().map(|r| r.factorizations).sum();
        let again = s.swept_again.as_ref().filter(|a| a.kept).map(|a| {
            format!(
                " (swept again with max_turn {}°; the default steps stopped at {:.2} Hz after {} points)",
                a.max_turn, a.first_stop_hz, a.first_points
            )
        });
        let other = s.from_the_end.as_ref();
        let from_end = other.map_or(String::new(), |o| {
            let ended = o
                .stopped
                .as_ref()
                .map_or(format!("reached {:.2} Hz", o.to_hz), |x| {
                    format!("stopped at {:.2} Hz ({})", x.frequency_hz, x.class)
                });
            let untraced = o.untraced_hz.map_or(String::new(), |[lo, hi]| {
                format!(", untraced {lo:.2}-{hi:.2} Hz")
            });
            format!("; from the other end: {ended}{untraced}")
        });
        let plus = |n: Option<usize>| n.map_or(String::new(), |n| format!("+{n}"));
        let (points, folds) = (
            format!("{}{}", s.points, plus(other.map(|o| o.points))),
            format!("{}{}", s.folds.len(), plus(other.map(|o| o.folds.len()))),
        );
        let newton = newton + other.map_or(0, |o| o.rows.iter().map(|r| r.newton_iterations).sum());
        let factor = factor + other.map_or(0, |o| o.rows.iter().map(|r| r.factorizations).sum());
        let stopped = s.stopped.as_ref().map_or(
            format!("reached the end{}", again.unwrap_or_default()),
            |x| {
                format!(
                    "at {:.2} Hz ({}): {}{from_end}",
                    x.frequency_hz,
                    x.class,
                    short(&x.reason)
                )
            },
        );
        println!(
            "{name:<20} {:>3} {:>11} {points:>8} {folds:>6} {newton:>7} {factor:>6} {:>9} {wall:>8.1}  {stopped}",
            s.harmonics,
            format!("{:.0}-{:.0}", s.from_hz, s.to_hz),
            s.reduced_frames.replaced,
        );
    }
}

/// The reason without the pipeline path and the resume hint.
fn short(reason: &str) -> String {
    let body = reason.split_once("): ").map_or(reason, |(_, b)| b);
    body.split("; `hbcontact sweep")
        .next()
        .unwrap_or(body)
        .to_string()
}
