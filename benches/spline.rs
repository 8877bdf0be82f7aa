//! Fourier against periodic cubic splines on the reference strip's impacts, in one run: each
//! basis' errors against time marching (same mesh, same redistributed mass; the marching
//! peak over every time step) in the probe's first-harmonic amplitude, the mean and the peak
//! contact force, the largest tension of the force series over its peak (the Gibbs dip before
//! an impact), the unknowns per contact node and the wall time with its phases.
//!
//! `cargo bench --bench spline`. The asserted numbers are tests/spline_contact.rs's.

use std::path::PathBuf;

use hbcontact::config::load_pipeline;
use hbcontact::pipeline::{self, RunOptions, Stage, Summary};
use hbcontact::Silent;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = root.join("pipelines/reference_strip.yaml");
    let work = root.join("output/bench-spline");
    let off = "stability.check=false".to_string();
    let options = |tag: &str| RunOptions {
        out: Some(work.join(tag)),
        write: hbcontact::pipeline::WriteLevel::Summary,
        ..Default::default()
    };
    let run = |tag: &str, set: &str| -> Option<Summary> {
        let p = load_pipeline(&scene, &[off.clone(), set.to_string()]).ok()?;
        match pipeline::run(&p, &options(tag), &Silent) {
            Ok(r) => Some(r.summary),
            Err(e) => {
                eprintln!("{tag}: {e}");
                None
            }
        }
    };
    // Warm the mesh cache so no row pays for gmsh.
    let _ = run("warm", "harmonic_balance.harmonics=1");
    let Ok(p) = load_pipeline(&scene, std::slice::from_ref(&off)) else {
        eprintln!("cannot read {}", scene.display());
        return;
    };
    let marching = match pipeline::run_transient(&p, &options("transient"), &Silent) {
        Ok(r) => r.summary,
        Err(e) => {
            eprintln!("transient: {e}");
            return;
        }
    };
    let amplitude = |s: &Summary| {
        s.probes
            .get("probe")
            .map_or(f64::NAN, |p| p.first_harmonic_x)
    };
    let Some(reference) = marching.contact.as_ref() else {
        eprintln!("the marching run has no contact summary");
        return;
    };
    println!(
        "time marching: {:.2} s; amplitude {:.5e} m, mean force {:.5e} N, peak force {:.5e} N\n",
        marching.stage_seconds.total(),
        amplitude(&marching),
        reference.mean_contact_force,
        reference.peak_contact_force
    );
    println!(
        "| basis | unknowns per contact node | wall time [s] | factor / Newton / write [s] | amplitude error | mean force error | peak force error | largest tension / peak |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let rows = [
        ("Fourier H = 40", "harmonic_balance.harmonics=40", 81),
        ("Fourier H = 80", "harmonic_balance.harmonics=80", 161),
        (
            "spline p = 3, S = 80",
            "harmonic_balance.basis.spline.segments=80",
            80,
        ),
        (
            "spline p = 3, S = 160",
            "harmonic_balance.basis.spline.segments=160",
            160,
        ),
    ];
    for (name, set, unknowns) in rows {
        let Some(s) = run(&format!("u{unknowns}"), set) else {
            continue;
        };
        let Some(c) = s.contact.as_ref() else {
            continue;
        };
        let t = &s.stage_seconds;
        let error = |v: f64, r: f64| format!("{:+.2}%", 100.0 * (v / r - 1.0));
        println!(
            "| {name} | {unknowns} | {:.2} | {:.2} / {:.2} / {:.2} | {} | {} | {} | {:.4} |",
            t.total(),
            t.get(Stage::Factor),
            t.get(Stage::Newton),
            t.get(Stage::Write),
            error(amplitude(&s), amplitude(&marching)),
            error(c.mean_contact_force, reference.mean_contact_force),
            error(c.peak_contact_force, reference.peak_contact_force),
            c.force_series_tension_ratio
        );
    }
}
