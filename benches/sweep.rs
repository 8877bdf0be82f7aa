//! The cost of a frequency-response curve, in one run: the shipped fold scene
//! (`pipelines/strip_sweep.yaml`, H = 10) swept by continuation, each point's cost against a
//! cold single-frequency `run` at the same H (the target: ≤ 0.5×), the solver phases'
//! shares, and points per minute. Both sides without the stability check (what it adds to a
//! sweep: `cargo bench --bench checks -- sweep`). Last, the same sweep with every frame factored
//! (`sweep.reduced_frames: false`), per point against the reduced frames'.
//!
//! `cargo bench --bench sweep [-- --harmonics 10]`.

use std::path::PathBuf;
use std::time::Instant;

use hbcontact::pipeline::load_pipeline;
use hbcontact::pipeline::{self, RunOptions, Stage};
use hbcontact::Silent;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let args: Vec<String> = std::env::args().collect();
    let h = args
        .iter()
        .position(|a| a == "--harmonics")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(10);
    let scene = root.join("pipelines/strip_sweep.yaml");
    let work = root.join("output/bench-sweep");
    let set = vec![format!("harmonic_balance.harmonics={h}")];
    let p = match load_pipeline(&scene, &set) {
        Ok(p) => p,
        Err(e) => return eprintln!("{e}"),
    };
    let options = |dir: &str, summary_only: bool| RunOptions {
        out: Some(work.join(dir)),
        write: if summary_only {
            hbcontact::pipeline::WriteLevel::Summary
        } else {
            hbcontact::pipeline::WriteLevel::Full
        },
        ..Default::default()
    };
    // A cold run at mid-span (warms the mesh cache too), then the one that counts.
    let mut cold = f64::NAN;
    for _ in 0..2 {
        let mut q = p.clone();
        q.harmonic_balance.frequency = 1500.0;
        q.stability.check = false;
        match pipeline::run(&q, &options("cold", true), &Silent) {
            Ok(r) => {
                cold = r.summary.stage_seconds.total() - r.summary.stage_seconds.get(Stage::Mesh)
            }
            Err(e) => return eprintln!("cold run: {e}"),
        }
    }
    let mut unchecked = p.clone();
    unchecked.stability.check = false;
    let t = Instant::now();
    let s = match hbcontact::sweep::run(&unchecked, &options("sweep", false), &Silent) {
        Ok(r) => r.summary,
        Err(e) => return eprintln!("sweep: {e}"),
    };
    let wall = t.elapsed().as_secs_f64();
    let sweep = s.stage_seconds.get(Stage::Sweep);
    let per_point = sweep / s.points as f64;
    let t = &s.solver_seconds;
    let share = |v: f64| 100.0 * v / sweep;
    let outputs =
        sweep - (t.factor + t.linear_solve + t.reduce + t.newton + t.knob_check + t.recover);
    let sets: usize = s.rows.iter().map(|r| r.factorizations).sum();
    println!(
        "frequency sweep of {} ({} to {} Hz, H = {h}); {} points, {} folds, wall {wall:.1} s",
        s.name,
        s.from_hz,
        s.to_hz,
        s.points,
        s.folds.len()
    );
    println!(
        "per point {per_point:.3} s against a cold run (without meshing) {cold:.3} s: {:.2}x (target ≤ 0.5x)",
        per_point / cold
    );

    println!(
        "sets of factorizations: {sets} ({:.1} per point); points per minute {:.0}",
        sets as f64 / s.points as f64,
        60.0 / per_point
    );
    let mut q = p.clone();
    q.stability.check = false;
    if let Some(spec) = q.sweep.as_mut() {
        spec.reduced_frames = false;
    }
    let factored = match hbcontact::sweep::run(&q, &options("factored", false), &Silent) {
        Ok(r) => r.summary,
        Err(e) => return eprintln!("factored sweep: {e}"),
    };
    let factored_point = factored.stage_seconds.get(Stage::Sweep) / factored.points as f64;
    let r = &s.reduced_frames;
    println!(
        "reduced model: r = {}, {} frames, {} points re-solved on factorizations; every frame factored instead (`sweep.reduced_frames: false`): {factored_point:.3} s per point, {:.2}x a cold run, {:.2}x the reduced frames' point",
        r.dimension,
        r.frames,
        r.replaced,
        factored_point / cold,
        factored_point / per_point
    );
    println!(
        "shares of the sweep: factor {:.0}%, linear solve {:.0}%, reduce {:.0}%, correctors {:.0}%, recover {:.0}%, outputs per point {:.0}%",
        share(t.factor),
        share(t.linear_solve),
        share(t.reduce),
        share(t.newton),
        share(t.recover),
        share(outputs)
    );
}
