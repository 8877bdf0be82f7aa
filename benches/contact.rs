//! Harmonic balance against time marching on the strip-against-wall scene, in one run:
//! the probe amplitude of each method against a high-H harmonic-balance reference, their wall
//! times, the ratio at equal accuracy, and each stage's share of the harmonic-balance time.
//! The harmonic-balance runs skip the stability check (`stability.check=false`): it marches
//! the state for periods on its own, and is a verdict, not part of the solve compared here.
//!
//! `cargo bench --bench contact [-- --mesh-size 0.0025]`.

use std::path::PathBuf;
use std::time::Instant;

use hbcontact::config::load_pipeline;
use hbcontact::pipeline::{self, RunOptions, Stage, Summary};
use hbcontact::Silent;

/// The probe's axial first-harmonic amplitude (smooth in H, unlike the peak).
fn probe_amplitude(s: &Summary) -> f64 {
    s.probes
        .get("probe")
        .map_or(f64::NAN, |p| p.first_harmonic_x)
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = root.join("pipelines/strip_wall.yaml");
    let work = root.join("output/bench-contact");
    let run_hb = |h: usize| -> Option<(f64, Summary)> {
        let set = [
            format!("harmonic_balance.harmonics={h}"),
            "stability.check=false".to_string(),
        ];
        let p = load_pipeline(&scene, &set).ok()?;
        let options = RunOptions {
            out: Some(work.join(format!("hb-h{h}"))),
            ..Default::default()
        };
        let t = Instant::now();
        match pipeline::run(&p, &options, &Silent) {
            Ok(r) => Some((t.elapsed().as_secs_f64(), r.summary)),
            Err(e) => {
                eprintln!("H = {h}: {e}");
                None
            }
        }
    };
    // Warm the mesh cache so no row pays for gmsh.
    let _ = run_hb(1);
    let Some((t_ref, reference)) = run_hb(60) else {
        eprintln!("the H = 60 reference did not run");
        return;
    };
    let a_ref = probe_amplitude(&reference);
    println!("reference: harmonic balance at H = 60, probe first-harmonic amplitude {a_ref:.6e} m, {t_ref:.2} s");

    let p = match load_pipeline(&scene, &[]) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            return;
        }
    };
    let options = RunOptions {
        out: Some(work.join("transient")),
        ..Default::default()
    };
    let t = Instant::now();
    let transient = match pipeline::run_transient(&p, &options, &Silent) {
        Ok(r) => r.summary,
        Err(e) => {
            eprintln!("transient: {e}");
            return;
        }
    };
    let t_transient = t.elapsed().as_secs_f64();
    let a_tr = probe_amplitude(&transient);
    let e_tr = (a_tr - a_ref).abs() / a_ref;
    let (periods, dt) = transient
        .transient
        .as_ref()
        .map_or((0, f64::NAN), |t| (t.periods, t.dt));
    println!(
        "transient: {periods} periods, dt = {dt:.3e} s, probe amplitude {a_tr:.6e} m, error {e_tr:.2e}, {t_transient:.2} s"
    );

    println!(
        "\n{:>4} {:>10} {:>10} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>14}",
        "H",
        "amplitude",
        "error",
        "wall s",
        "factor%",
        "reduce%",
        "newton%",
        "recover%",
        "write%",
        "iters",
        "transient/HB"
    );
    let mut matched = None;
    for h in [5usize, 10, 20, 40] {
        let Some((secs, s)) = run_hb(h) else { continue };
        let a = probe_amplitude(&s);
        let err = (a - a_ref).abs() / a_ref;
        let st = &s.stage_seconds;
        let share = |k: Stage| 100.0 * st.get(k) / st.total();
        let iterations = s
            .contact
            .as_ref()
            .and_then(|c| c.solver.as_ref())
            .map_or(0, |c| c.newton_iterations);
        println!(
            "{h:>4} {a:>10.4e} {err:>10.2e} {secs:>9.3} {:>9.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8} {:>14.1}",
            share(Stage::Factor),
            share(Stage::Reduce),
            share(Stage::Newton),
            share(Stage::Recover),
            share(Stage::Write),
            iterations,
            t_transient / secs
        );
        if matched.is_none() && err <= e_tr {
            matched = Some((h, secs));
        }
    }
    match matched {
        Some((h, secs)) => println!(
            "\nat the transient's accuracy ({e_tr:.2e}): harmonic balance needs H = {h}, {secs:.3} s against {t_transient:.2} s: {:.1}× faster",
            t_transient / secs
        ),
        None => println!("\nno H tried reached the transient's accuracy ({e_tr:.2e})"),
    }
}
