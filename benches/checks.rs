//! What the checks a run makes besides its solve cost (issue #44's budget: at most 25% of the
//! run's wall time, and a sweep with every point checked at most 2× the same sweep
//! unchecked), in one run of this build:
//! - every shipped contact scene of `pipelines/` run as `hbcontact run` runs it (VTU series,
//!   plots), the second of two runs (the mesh cached): the stability verdict's, the resonance
//!   check's and the knob check's seconds, and their shares of the run's wall time, with the
//!   verdict and the leading multiplier;
//! - the coarse strip sweep (`strip_sweep.yaml` at lc = 25 mm, H = 10) with every point
//!   judged by Hill's method against the same sweep with `stability.check: false`.
//!
//! `cargo bench --bench checks [-- runs | sweep]` (default: both). Times come from one run on
//! a shared machine: compare the shares and ratios, not seconds across runs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use hbcontact::config::load_pipeline;
use hbcontact::pipeline::{self, RunOptions, Stage, WriteLevel};
use hbcontact::Silent;

/// The shipped scenes with contact.
const SCENES: [&str; 6] = [
    "strip_wall",
    "reference_strip",
    "blade_casing",
    "blade_elastic_casing",
    "blade_lobed_casing",
    "half_disc",
];

fn options(work: &Path, dir: &str, write: WriteLevel) -> RunOptions {
    RunOptions {
        out: Some(work.join(dir)),
        write,
        ..Default::default()
    }
}

fn runs(root: &Path, work: &Path) {
    println!(
        "{:<22} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>7}",
        "scene", "verdict", "|μ|", "stab s", "reson s", "knob s", "total s", "stab %", "checks %"
    );
    for scene in SCENES {
        let p = match load_pipeline(&root.join(format!("pipelines/{scene}.yaml")), &[]) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("{scene}: {e}");
                continue;
            }
        };
        for round in 0..2 {
            let s = match pipeline::run(&p, &options(work, scene, WriteLevel::Full), &Silent) {
                Ok(r) => r.summary,
                Err(e) => {
                    println!("{scene:<22} failed: {e}");
                    break;
                }
            };
            if round == 0 {
                continue;
            }
            let t = &s.stage_seconds;
            let (stab, res, knob) = (
                t.get(Stage::Stability),
                t.get(Stage::Resonance),
                t.get(Stage::KnobCheck),
            );
            let total = t.total();
            let verdict = s.stability.as_ref();
            println!(
                "{scene:<22} {:>9} {:>8.4} {stab:>8.3} {res:>8.3} {knob:>8.3} {total:>8.3} {:>7.0} {:>7.0}",
                verdict.map_or("-".into(), |v| format!("{:?}", v.verdict).to_lowercase()),
                verdict.and_then(|v| v.multiplier).unwrap_or(f64::NAN),
                100.0 * stab / total,
                100.0 * (stab + res + knob) / total,
            );
        }
    }
}

fn sweep(root: &Path, work: &Path) {
    let scene = root.join("pipelines/strip_sweep.yaml");
    let base = ["geometry.parameters.lc=0.025".to_string()];
    let unchecked = [base[0].clone(), "stability.check=false".to_string()];
    let mut walls = Vec::new();
    for (name, sets) in [("checked", &base[..]), ("unchecked", &unchecked[..])] {
        let p = match load_pipeline(&scene, sets) {
            Ok(p) => p,
            Err(e) => return eprintln!("strip_sweep: {e}"),
        };
        // The first sweep meshes; the second is the one that counts.
        for round in 0..2 {
            let t = Instant::now();
            let s = match hbcontact::sweep::run(&p, &options(work, name, WriteLevel::Full), &Silent)
            {
                Ok(r) => r.summary,
                Err(e) => return eprintln!("{name} sweep: {e}"),
            };
            let wall = t.elapsed().as_secs_f64();
            if round == 1 {
                let judged = s.rows.iter().filter(|r| r.stable.is_some()).count();
                println!(
                    "coarse strip sweep {name}: {} points, {judged} judged, {} bifurcations, wall {wall:.2} s, stability stage {:.2} s",
                    s.points,
                    s.bifurcations.len(),
                    s.stage_seconds.get(Stage::Stability)
                );
                walls.push(wall);
            }
        }
    }
    if let [checked, unchecked] = walls[..] {
        println!(
            "every point checked against unchecked: {:.2}x (goal ≤ 2x)",
            checked / unchecked
        );
    }
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let work = root.join("output/bench-checks");
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let all = args.is_empty();
    if all || args.iter().any(|a| a == "runs") {
        runs(&root, &work);
    }
    if all || args.iter().any(|a| a == "sweep") {
        sweep(&root, &work);
    }
}
