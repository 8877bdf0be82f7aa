//! A 32-point geometry study on the strip (32 gaps, so 32 meshes), run one point after
//! another (1 thread; faer keeps its default, every core) and two points at a time (2 threads;
//! faer sequential per point), each from an empty output directory. Prints the meshing and
//! points phases and their speed-ups, measured in this one run, and then the same study again
//! with the meshes cached (points only).
//!
//! `cargo bench --bench study` (part of `make bench`). Times come from one run on a shared
//! machine: compare the ratios, not absolute seconds across runs.
//!
//! `cargo bench --bench study -- accuracy` instead runs the shipped accuracy study
//! (studies/strip_accuracy.yaml, rungs one at a time) from an empty directory and prints its
//! table: the wall times and peak memories of the accuracy table of docs/verification.md.

use std::path::PathBuf;
use std::time::Instant;

use hbcontact::study::{self, StudyOptions};
use hbcontact::Silent;

const POINTS: usize = 32;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    if std::env::args().any(|a| a == "accuracy") {
        accuracy(&root);
        return;
    }
    let work = root.join("output/bench-study");
    let _ = std::fs::remove_dir_all(&work);
    if let Err(e) = std::fs::create_dir_all(&work) {
        eprintln!("{}: {e}", work.display());
        return;
    }
    let gaps: Vec<String> = (0..POINTS)
        .map(|i| format!("{:e}", 0.5e-7 + 0.05e-7 * i as f64))
        .collect();
    let text = format!(
        "name: bench\npipeline: {}\nset: {{geometry.parameters.lc: 0.0025, harmonic_balance.harmonics: 10}}\nparameters:\n  - {{key: geometry.parameters.gap, values: [{}], unit: m}}\n",
        root.join("pipelines/strip_wall.yaml").display(),
        gaps.join(", ")
    );
    let file = work.join("bench.yaml");
    if let Err(e) = std::fs::write(&file, text) {
        eprintln!("{}: {e}", file.display());
        return;
    }
    let spec = match study::load_study(&file, &[]) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            return;
        }
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("{POINTS}-point geometry study (strip_wall, {POINTS} gaps, H = 10) on {cores} cores");
    println!("{:<34} {:>9} {:>9} {:>9}", "", "meshing", "points", "total");
    let mut rows = Vec::new();
    for (label, threads, dir) in [
        ("1 thread, faer on every core", 1, "serial"),
        ("2 threads, faer sequential", 2, "parallel"),
        ("2 threads, meshes cached", 2, "parallel-again"),
    ] {
        let out = work.join(if dir == "parallel-again" {
            "parallel"
        } else {
            dir
        });
        if dir == "parallel-again" {
            // Keep the meshes, forget the points: only the points run again.
            let _ = std::fs::remove_dir_all(out.join("points"));
            let _ = copy_cache(&work.join("serial"), &out);
        }
        let options = StudyOptions {
            out: Some(out),
            threads: Some(threads),
            shard: None,
            trust_geometry: false,
        };
        let start = Instant::now();
        let report = match study::run(&spec, &options, &Silent) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("{label}: {e}");
                return;
            }
        };
        let total = start.elapsed().as_secs_f64();
        let Some(e) = report.execution else { return };
        println!(
            "{label:<34} {:>8.2}s {:>8.2}s {:>8.2}s   ({} ok, {} geometries)",
            e.meshing_seconds, e.points_seconds, total, report.ok, e.geometries
        );
        rows.push((e.meshing_seconds, e.points_seconds, total));
    }
    let (s, p) = (rows[0], rows[1]);
    println!(
        "speed-up of 2 threads over 1: meshing {:.2}x, points {:.2}x, whole study {:.2}x (target ≥ 1.8x)",
        s.0 / p.0,
        s.1 / p.1,
        s.2 / p.2
    );
    println!(
        "meshing share of the serial study: {:.0} % ({:.3} s per geometry)",
        100.0 * s.0 / s.2,
        s.0 / POINTS as f64
    );
}

/// Copy the serial run's mesh cache into `out` (so the last row measures points alone).
fn copy_cache(from: &std::path::Path, out: &std::path::Path) -> std::io::Result<()> {
    let (src, dst) = (
        from.join("points/.mesh-cache"),
        out.join("points/.mesh-cache"),
    );
    std::fs::create_dir_all(&dst)?;
    for entry in std::fs::read_dir(src)? {
        let entry = entry?;
        std::fs::copy(entry.path(), dst.join(entry.file_name()))?;
    }
    Ok(())
}

/// The shipped accuracy study, from scratch, with its table and the machine's load.
fn accuracy(root: &std::path::Path) {
    let out = root.join("output/bench-accuracy");
    let _ = std::fs::remove_dir_all(&out);
    let spec = match study::load_study(&root.join("studies/strip_accuracy.yaml"), &[]) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            return;
        }
    };
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let options = StudyOptions {
        out: Some(out),
        threads: None,
        shard: None,
        trust_geometry: false,
    };
    match study::run(&spec, &options, &Silent) {
        Ok(report) => {
            if let Some(a) = report.accuracy {
                println!(
                    "studies/strip_accuracy.yaml; load average before: {}",
                    load.trim()
                );
                println!("errors against {}", a.reference_name());
                println!("{}", a.markdown());
            }
        }
        Err(e) => eprintln!("{e}"),
    }
}
