//! What `hbcontact transient` says about a late response that is not T-periodic
//! (`pipeline::late`, `transient::characterize`; docs/method.md, "The late response"), on a
//! scene past a period doubling.

mod common;

use hbcontact::config::load_pipeline;
use hbcontact::pipeline::late::LateKind;
use hbcontact::pipeline::stability::Verdict;
use hbcontact::pipeline::{self, RunOptions};

/// TEST GOAL: the impact cantilever (tests/data/impact_cantilever.yaml, drive f = 1400 Hz,
/// a rigid stop at the tip) marched 200 periods from its harmonic-balance state, perturbed
/// by 1%. Hill's method on that state (the marching's own discrete model) says unstable,
/// by a period doubling (its leading multiplier real and below −1, a motion within two bins
/// of the record's spectrum of f/2); the marching, which knows
/// nothing of Hill, leaves the state, and the strongest line of its late spectrum (last 64
/// periods) is f/2 to a tenth of a bin, the marched counterpart of the predicted frequency
/// within two bins of it. The late response is not called periodic, the contact force's
/// per-period peaks spread (min < mean < max), and the spectrum and late-history plots are
/// drawn.
#[test]
fn a_period_doubling_predicted_by_hill_shows_as_the_half_frequency_line_of_the_marched_spectrum() {
    let path = common::root().join("tests/data/impact_cantilever.yaml");
    let p = load_pipeline(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
    let f = p.harmonic_balance.frequency;
    let out = common::temp_out("late-impact-cantilever");
    let options = RunOptions {
        out: Some(out.clone()),
        ..Default::default()
    };
    let run =
        pipeline::run_transient(&p, &options, &hbcontact::Silent).unwrap_or_else(|e| panic!("{e}"));
    let s = run.summary;
    let v = s
        .stability
        .expect("a Floquet verdict on the harmonic-balance start");
    println!("{}", v.reason);
    assert_eq!(v.verdict, Verdict::Unstable, "{}", v.reason);
    let argument = v.argument.expect("an argument").to_degrees();
    assert!(argument > 175.0, "arg μ = {argument}°");
    assert_eq!(
        v.crossing,
        Some(hbcontact::hbm::floquet::Crossing::PeriodDoubling),
        "{}",
        v.reason
    );
    let late = s.transient.expect("transient details").late_response;
    println!("{}", late.description);
    let bins = late.periods as f64;
    assert_eq!(late.periods, 64);
    assert_ne!(late.kind, LateKind::Periodic, "{}", late.description);
    let strongest = late.lines[0][0];
    assert!(
        (strongest - 0.5).abs() < 0.1 / bins,
        "the strongest line is at {strongest} f, not f/2"
    );
    let prediction = late.prediction.expect("a prediction to compare");
    let predicted = prediction.predicted_hz.expect("a predicted frequency");
    let marched = prediction.marched_hz.expect("a marched frequency");
    assert!(
        (predicted - f / 2.0).abs() < 2.0 * f / bins,
        "Hill's motion {predicted} Hz against f/2"
    );
    assert!(
        (marched - predicted).abs() <= prediction.tolerance_hz,
        "{marched} Hz against {predicted} Hz"
    );
    let peaks = late.peak_contact_force.expect("a contact force spread");
    assert!(
        peaks.min < peaks.mean && peaks.mean < peaks.max,
        "{peaks:?}"
    );
    for plot in ["spectrum", "late_response", "late_contact_force"] {
        let svg = out.join("plots").join(format!("{plot}.svg"));
        assert!(svg.exists(), "{} missing", svg.display());
    }
}

/// TEST GOAL: a `run` whose state Hill's method finds unstable writes the leading Floquet
/// vector as a series (summary's `stability.floquet_vector_file`: floquet.pvd, 32 frames over
/// two drive periods, point field `floquet_vector`, largest |u| 1, read by meshio); at the
/// impact cantilever's period doubling the motion it shows repeats after 2T and reverses after
/// T (u(t + T) = −u(t): half the drive frequency); a stable run (the README's strip against
/// its wall) writes none.
#[test]
fn an_unstable_run_writes_its_floquet_vector_as_a_series_at_half_the_drive_frequency() {
    let out = common::run_cli(
        "run",
        "tests/data/impact_cantilever.yaml",
        "late-floquet-vector",
        &[],
    );
    let summary = common::read_json(&out.join("summary.json"));
    assert_eq!(summary["stability"]["crossing"], "period_doubling");
    assert_eq!(summary["stability"]["floquet_vector_file"], "floquet.pvd");
    let script = r#"
import sys, xml.etree.ElementTree as ET, numpy as np, meshio
out = sys.argv[1]
sets = ET.parse(out + "/floquet.pvd").getroot().iter("DataSet")
frames = [(float(d.get("timestep")), d.get("file")) for d in sets]
u = [meshio.read(out + "/" + f).point_data["floquet_vector"][:, :2] for _, f in frames]
n = len(u)
largest = max(np.abs(np.hypot(x[:, 0], x[:, 1])).max() for x in u)
reverse = max(np.abs(u[j + n // 2] + u[j]).max() for j in range(n // 2))
print(n, frames[-1][0] * 1400.0 * n / (n - 1), largest, reverse)
"#;
    let r = std::process::Command::new(common::venv_python())
        .args(["-c", script, &out.display().to_string()])
        .output()
        .expect("python runs");
    let text = String::from_utf8_lossy(&r.stdout);
    println!("{text}{}", String::from_utf8_lossy(&r.stderr));
    let v: Vec<f64> = text
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert_eq!(v.len(), 4, "{text}");
    assert_eq!(v[0], 32.0);
    assert!(
        (v[1] - 2.0).abs() < 1e-9,
        "the frames span {} periods",
        v[1]
    );
    assert!((v[2] - 1.0).abs() < 1e-6, "largest |u| {}", v[2]);
    assert!(v[3] < 1e-9, "u(t + T) + u(t) up to {}", v[3]);
    let stable = common::run_cli(
        "run",
        "pipelines/strip_wall.yaml",
        "late-floquet-stable",
        &["geometry.parameters.lc=0.0025"],
    );
    let summary = common::read_json(&stable.join("summary.json"));
    println!("{}", summary["stability"]["reason"]);
    assert_eq!(summary["stability"]["verdict"], "stable");
    assert!(summary["stability"].get("floquet_vector_file").is_none());
    assert!(!stable.join("floquet.pvd").exists());
}

/// TEST GOAL: with `stability.method: both` the audit's march is characterized as a
/// `transient`'s late response is, and compared with the Floquet prediction: on the impact
/// cantilever, whose Hill verdict is a period doubling (700 Hz), the summary's
/// `stability.marched_response` says what the march from the perturbed state did and finds the
/// predicted half-frequency line in its spectrum within two bins, naming the audit's own
/// periods key (`stability.max_periods`), not the transient's.
#[test]
fn the_marching_audit_says_what_its_march_did_against_the_floquet_prediction() {
    let out = common::run_cli(
        "run",
        "tests/data/impact_cantilever.yaml",
        "late-audit",
        &["stability.method=both"],
    );
    let summary = common::read_json(&out.join("summary.json"));
    let v = &summary["stability"];
    assert_eq!(v["crossing"], "period_doubling");
    let said = v["marched_response"]
        .as_str()
        .expect("the march characterized");
    println!("{said}");
    assert!(
        said.contains("Floquet predicted") && said.contains("700.0000 Hz"),
        "{said}"
    );
    let shows = said
        .split("the marched spectrum shows ")
        .nth(1)
        .expect("a marched line");
    let hz: f64 = shows
        .split(' ')
        .next()
        .and_then(|w| w.parse().ok())
        .expect("its frequency");
    let bins = said
        .split("within ")
        .last()
        .and_then(|w| w.split(' ').next());
    let tolerance: f64 = bins.and_then(|w| w.parse().ok()).expect("the tolerance");
    assert!(
        (hz - 700.0).abs() <= tolerance,
        "{hz} Hz against 700 Hz ± {tolerance}"
    );
    assert!(!said.contains("transient.max_periods"), "{said}");
}

/// TEST GOAL: a march that gains energy the scene does not supply says so instead of
/// reporting a runaway as an answer: the friction block without friction and without damping,
/// its top held down and shaken along the floor at 100 Hz, marched 32 periods at
/// transient.courant 0.8 sees its peak contact force grow about ×1.19 a period (to about 180×
/// its smallest, measured) and warns, naming transient.courant and a smaller value; at 0.4
/// the same march stays bounded (peak within 3 kN) and does not warn.
#[test]
fn a_march_that_gains_energy_warns_and_names_the_step_to_lower() {
    let scene = "pipelines/scenes/friction_block.yaml";
    let sets = |c: &'static str| {
        [
            "contact.friction.coefficient=0.0",
            "transient.max_periods=32",
            c,
            "output.plots=false",
        ]
    };
    let long = common::run_cli(
        "transient",
        scene,
        "late-runaway",
        &sets("transient.courant=0.8"),
    );
    let summary = common::read_json(&long.join("summary.json"));
    let warned = |s: &serde_json::Value| {
        (s["warnings"].as_array().unwrap().iter())
            .filter_map(|w| w.as_str())
            .find(|w| w.contains("gains energy"))
            .map(str::to_string)
    };
    let warning = warned(&summary).expect("a runaway warning");
    println!("{warning}");
    assert!(
        warning.contains("transient.courant (now 0.8; e.g. to 0.4)"),
        "{warning}"
    );
    let short = common::run_cli(
        "transient",
        scene,
        "late-bounded",
        &sets("transient.courant=0.4"),
    );
    let summary = common::read_json(&short.join("summary.json"));
    assert!(warned(&summary).is_none(), "{:?}", warned(&summary));
    let peak = common::json_number(&summary, "/contact/peak_contact_force");
    assert!(peak < 3.0e3, "{peak} N");
}

/// TEST GOAL: where the 0.5%-damped strip (pipelines/scenes/strip_light.yaml) starts to
/// touch its wall on the way up, Hill's method on the H = 10 curve says stability is lost by
/// a complex pair of multipliers (a second motion at arg μ/360° × f); a march from rest at
/// 1340 Hz, which knows nothing of harmonic balance, is not T-periodic but quasi-periodic, its
/// second frequency within 5% of the one Hill predicts at the loss. The tangle of folds the
/// H = 40 curve makes over 1345–1358 Hz lies in this stretch of unstable states
/// (docs/verification.md, User scenes).
#[test]
fn the_light_strip_loses_stability_where_it_touches_and_a_march_there_moves_at_hills_second_frequency(
) {
    let path = common::root().join("pipelines/scenes/strip_light.yaml");
    let swept = load_pipeline(&path, &["harmonic_balance.harmonics=10".into()])
        .unwrap_or_else(|e| panic!("{e}"));
    let options = RunOptions {
        out: Some(common::temp_out("late-strip-light-sweep")),
        ..Default::default()
    };
    let s = hbcontact::sweep::run(&swept, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"))
        .summary;
    let loss = (s.bifurcations.iter())
        .find(|b| b.loses)
        .expect("a loss of stability");
    println!("{loss:?}");
    assert!((loss.frequency_hz - 1336.0).abs() < 2.0, "{loss:?}");
    assert!(
        loss.argument_deg > 5.0 && loss.argument_deg < 175.0,
        "a complex pair: {loss:?}"
    );
    let predicted = loss.argument_deg / 360.0 * loss.frequency_hz;
    let marched = load_pipeline(&path, &["harmonic_balance.frequency=1340".into()])
        .unwrap_or_else(|e| panic!("{e}"));
    let late = common::marched_late_response(&marched, "late-strip-light-march");
    assert_eq!(late.kind, LateKind::QuasiPeriodic, "{}", late.description);
    let f2 = late.second_frequency_hz.expect("a second frequency");
    assert!(
        (f2 - predicted).abs() < 0.05 * predicted,
        "marched {f2} Hz against Hill's {predicted} Hz"
    );
}
