//! A gap that changes periodically in time (the note's g̃0 of (18)): a rigid obstacle that
//! translates (`contact.motion`) and an out-of-round casing turning past a blade
//! (`contact.obstacle.circle.lobes`), against closed forms, symmetry, and the product's own
//! time marching of the same scene.

mod common;

use std::path::Path;

use serde_json::Value;

use common::{json_number as number, run_cli as run};

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The columns `time` and `total_force` of a CSV.
fn total_force(path: &Path) -> Vec<(f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "total_force").unwrap();
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[0], v[col])
        })
        .collect()
}

/// The mean contact force of every point of a study's study.csv, each point asserted ok.
fn mean_forces_of_study(out: &Path) -> Vec<f64> {
    let text = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (mean, status) = (col("mean_contact_force"), col("status"));
    lines
        .map(|l| {
            let r: Vec<&str> = l.split(',').collect();
            assert_eq!(r[status], "ok", "{r:?}");
            r[mean].parse().unwrap()
        })
        .collect()
}

/// |c_k| of a series over one period, sampled uniformly.
fn spectrum(values: &[f64], top: usize) -> Vec<f64> {
    let n = values.len() as f64;
    (0..=top)
        .map(|k| {
            let (mut a, mut b) = (0.0, 0.0);
            for (j, v) in values.iter().enumerate() {
                let th = 2.0 * std::f64::consts::PI * (k * j) as f64 / n;
                a += v * th.cos();
                b += v * th.sin();
            }
            (a * a + b * b).sqrt() / n
        })
        .collect()
}

const QUASI_STATIC: [&str; 4] = [
    "boundaries.loads=[]",
    "stability.check=false",
    "geometry.parameters.lc=0.0025",
    "damping=null",
];

/// TEST GOAL: a rigid wall moved slowly into the clamped strip (strip_wall at 50 Hz, its first
/// axial mode near 6.5 kHz, no damping) presses it as its static stiffness says. A static
/// run with the wall offset by `contact.motion.static` (2·gap into the face) measures the
/// force F1 of a penetration of one gap; driven by d(t) = D cos ωt, D = 2·gap, the force is
/// then F1·max(0, D cos ωt − gap)/gap: peak F1 at t = 0, mean F1 (D sin θ0 − gap·θ0)/(π gap),
/// θ0 = acos(gap/D). Measured: peak −0.07% (inertia), mean −0.005% (lc = 2.5 mm; −0.11% and
/// −0.005% at 1.25 mm with damping); held to 0.5% and 0.2%.
#[test]
fn a_wall_pushed_slowly_into_the_strip_presses_it_as_its_static_stiffness_says() {
    let gap: f64 = 1.0e-7;
    let pipeline = "pipelines/strip_wall.yaml";
    let mut statics = QUASI_STATIC.to_vec();
    statics.extend([
        "harmonic_balance.harmonics=0",
        "contact.motion={static: [-2.0e-7, 0.0]}",
    ]);
    let out = run("run", pipeline, "moving-wall-static", &statics);
    let f1 = number(
        &common::read_json(&out.join("summary.json")),
        "/contact/peak_contact_force",
    );
    let mut driven = QUASI_STATIC.to_vec();
    driven.extend([
        "harmonic_balance.frequency=50",
        "harmonic_balance.harmonics=40",
        "contact.motion={harmonics: [{k: 1, cos: [-2.0e-7, 0.0]}]}",
    ]);
    let out = run("run", pipeline, "moving-wall-driven", &driven);
    let s = common::read_json(&out.join("summary.json"));
    let d = 2.0 * gap;
    let theta = (gap / d).acos();
    let mean = f1 * (d * theta.sin() - gap * theta) / (std::f64::consts::PI * gap);
    let (peak_hb, mean_hb) = (
        number(&s, "/contact/peak_contact_force"),
        number(&s, "/contact/mean_contact_force"),
    );
    println!("static F1 {f1:.6e}; peak {peak_hb:.6e} ({:+.3}%), mean {mean_hb:.6e} vs {mean:.6e} ({:+.3}%)",
        100.0 * (peak_hb - f1) / f1, 100.0 * (mean_hb - mean) / mean);
    assert!(relative(peak_hb, f1) < 5e-3);
    assert!(relative(mean_hb, mean) < 2e-3);
    // The force peaks when the wall is deepest, at t = 0.
    let history = total_force(&out.join("contact.csv"));
    let period = 1.0 / 50.0;
    let (t_peak, _) = history
        .iter()
        .copied()
        .fold((0.0, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
    let phase = (t_peak / period).min(1.0 - t_peak / period);
    assert!(phase < 0.02, "peak at t = {t_peak:e}");
    assert!(
        s["effects"]["gap_harmonics"] == serde_json::json!([1]),
        "{}",
        s["effects"]
    );
}

/// TEST GOAL: a wall moving on an ellipse (x and y harmonics out of phase) at 3 kHz against
/// the strip's tip, harmonic balance at H = 40 against the product's own explicit time
/// marching of the same scene from rest (its own gap g0(t) at every step): the probe's first
/// harmonic and the mean contact force within 1% (measured −0.05% and −0.09% at lc = 2.5 mm,
/// −0.34% and +0.01% at 1.25 mm).
#[test]
fn a_moving_wall_agrees_with_the_time_marching_of_the_same_scene() {
    let sets = [
        "boundaries.loads=[]",
        "stability.check=false",
        "geometry.parameters.lc=0.0025",
        "damping={alpha: 1.0e4, beta: 1.0e-7}",
        "harmonic_balance.frequency=3000",
        "harmonic_balance.harmonics=40",
        "contact.motion={harmonics: [{k: 1, cos: [-2.0e-7, 0.0], sin: [0.0, 1.0e-7]}]}",
    ];
    let pipeline = "pipelines/strip_wall.yaml";
    let hb = common::read_json(&run("run", pipeline, "moving-wall-hb", &sets).join("summary.json"));
    let tm = common::read_json(
        &run("transient", pipeline, "moving-wall-tm", &sets).join("summary.json"),
    );
    let pointers = [
        "/probes/probe/first_harmonic_x",
        "/contact/mean_contact_force",
    ];
    common::assert_agrees_with_marching(&hb, &tm, &pointers, 1e-2);
}

/// TEST GOAL: the blade of blade_casing.yaml, unloaded, turning once per period (100 Hz)
/// inside a casing with 3 lobes of 150 µm (its clearance is 100 µm): the lobes strike the tip
/// three times per turn, so the contact force and the blade's response hold harmonics 3, 6,
/// 9, … only — to round-off in harmonic balance (whose Newton is free to use them all), and
/// to 0.1% of the harmonic-3 line in the marching's every-step force — and harmonic balance
/// (H = 30) agrees with the marching: the probe's harmonics 3 and 6 within 1% (measured
/// −0.35% and +0.22%), the mean contact force within 1%.
#[test]
fn a_blade_passing_a_three_lobed_casing_is_struck_at_multiples_of_three_and_agrees_with_marching() {
    let sets = [
        "boundaries.loads=[]",
        "stability.check=false",
        "damping={alpha: 1000, beta: 1.0e-7}",
        "harmonic_balance.frequency=100",
        "harmonic_balance.harmonics=30",
        "contact.obstacle={circle: {center: [0.0, 0.0], radius: 0.2001, body_inside: true, lobes: {count: 3, amplitude: 1.5e-4}}}",
    ];
    let pipeline = "pipelines/blade_casing.yaml";
    let hb_dir = run("run", pipeline, "lobed-casing-hb", &sets);
    let tm_dir = run("transient", pipeline, "lobed-casing-tm", &sets);
    let (hb, tm) = (
        common::read_json(&hb_dir.join("summary.json")),
        common::read_json(&tm_dir.join("summary.json")),
    );
    let hb_force: Vec<f64> = total_force(&hb_dir.join("contact.csv"))
        .iter()
        .map(|p| p.1)
        .collect();
    let tm_force: Vec<f64> = total_force(&tm_dir.join("contact_steps.csv"))
        .iter()
        .map(|p| p.1)
        .collect();
    for (what, force, tolerance) in [
        ("harmonic balance", hb_force, 1e-9),
        ("marching", tm_force, 1e-3),
    ] {
        let c = spectrum(&force, 12);
        let off = (1..=12)
            .filter(|k| k % 3 != 0)
            .map(|k| c[k])
            .fold(0.0, f64::max);
        println!(
            "{what}: contact force |c_3| {:.4e}, largest |c_k| off the multiples of 3 {off:.3e}",
            c[3]
        );
        assert!(c[3] > 0.1 * c[0] && off < tolerance * c[3], "{what}: {c:?}");
    }
    for k in [3usize, 6] {
        let at = |s: &Value| s["probes"]["probe"]["harmonics_x"][k - 1].as_f64().unwrap();
        let (a, b) = (at(&hb), at(&tm));
        println!(
            "probe harmonic {k}: harmonic balance {a:.6e}, marching {b:.6e} ({:+.3}%)",
            100.0 * (a - b) / b
        );
        assert!(relative(a, b) < 1e-2);
    }
    let pointer = "/contact/mean_contact_force";
    assert!(relative(number(&hb, pointer), number(&tm, pointer)) < 1e-2);
    let effects = &hb["effects"];
    assert_eq!(effects["gap_harmonics"], serde_json::json!([3]));
}

/// TEST GOAL: a gap harmonic above H or beyond what a spline basis carries, and
/// `contact.motion` on an elastic body, are refused naming the key and the fix.
#[test]
fn gap_harmonics_beyond_h_and_motion_of_a_body_are_refused_naming_the_key() {
    let lobes = "contact.obstacle={circle: {center: [0.0, 0.0], radius: 0.2001, body_inside: true, lobes: {count: 12, amplitude: 1.0e-5}}}";
    let r = common::hbcontact(&["check", "pipelines/blade_casing.yaml", "--set", lobes]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("harmonic_balance.harmonics = 10 is below harmonic k = 12 of contact.obstacle.circle.lobes"),
        "{err}"
    );
    let r = common::hbcontact(&[
        "check",
        "pipelines/strip_wall.yaml",
        "--set",
        "harmonic_balance.basis={spline: {degree: 3, segments: 33}}",
        "--set",
        "contact.motion={harmonics: [{k: 20, cos: [1.0e-8, 0.0]}]}",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cannot carry harmonic k = 20 of the obstacle's gap"),
        "{err}"
    );
    let r = common::hbcontact(&[
        "check",
        "tests/data/two_strips.yaml",
        "--set",
        "contact.motion={harmonics: [{k: 1, cos: [1.0e-7, 0.0]}]}",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("contact.motion: a `body` obstacle"), "{err}");
}

/// TEST GOAL: a study runs over an obstacle's lobe amplitude (tests/data/lobe_amplitude.yaml,
/// the turning blade of blade_lobed_casing.yaml at 110, 120, 130 µm): every point succeeds,
/// the mean contact force grows with the amplitude (measured 831, 942, 1053 N), and the
/// shipped amplitude's point equals a plain run of the shipped scene to 1e-9.
#[test]
fn a_study_over_the_lobe_amplitude_presses_harder_with_deeper_lobes() {
    let out = common::temp_out("lobe-amplitude-study");
    let out_arg = out.display().to_string();
    let r = common::hbcontact(&["study", "tests/data/lobe_amplitude.yaml", "--out", &out_arg]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let forces = mean_forces_of_study(&out);
    assert_eq!(forces.len(), 3);
    println!("mean contact force over the lobe amplitude: {forces:?}");
    assert!(forces[0] < forces[1] && forces[1] < forces[2], "{forces:?}");
    let shipped = run(
        "run",
        "pipelines/blade_lobed_casing.yaml",
        "lobe-shipped",
        &[],
    );
    let s = common::read_json(&shipped.join("summary.json"));
    let plain = number(&s, "/contact/mean_contact_force");
    assert!(
        relative(forces[1], plain) < 1e-9,
        "{} vs {plain}",
        forces[1]
    );
}

/// TEST GOAL: a study runs over the rotation speed of the turning blade (tests/data/
/// rotation_speed.yaml: 90, 100, 110 rev/s, `turns_per_period: 1` moving the speed with the frequency,
/// and with it the centrifugal force, the spin softening and the lobes' harmonic): every point
/// succeeds, the mean contact force grows with the speed as the centrifugal force throws the
/// tip outward (measured 907, 942, 982 N), and the 100 rev/s point equals a plain run of the
/// shipped scene to 1e-9.
#[test]
fn a_study_over_the_rotation_speed_presses_the_tip_harder_as_it_turns_faster() {
    let out = common::temp_out("rotation-speed-study");
    let out_arg = out.display().to_string();
    let r = common::hbcontact(&["study", "tests/data/rotation_speed.yaml", "--out", &out_arg]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let forces = mean_forces_of_study(&out);
    println!("mean contact force over the rotation speed: {forces:?}");
    assert_eq!(forces.len(), 3);
    assert!(forces[0] < forces[1] && forces[1] < forces[2], "{forces:?}");
    let shipped = run(
        "run",
        "pipelines/blade_lobed_casing.yaml",
        "speed-shipped",
        &[],
    );
    let plain = number(
        &common::read_json(&shipped.join("summary.json")),
        "/contact/mean_contact_force",
    );
    assert!(
        relative(forces[1], plain) < 1e-9,
        "{} vs {plain}",
        forces[1]
    );
}
