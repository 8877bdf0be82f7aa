//! Body loads and the rotating frame: gravity (`boundaries.gravity`), the centrifugal force,
//! the spin softening and the Coriolis force of `boundaries.rotation`.

mod common;

/// TEST GOAL: a strip clamped at x = 0 whose free end face just touches a rigid wall at
/// x = L (gap 0), pulled toward the wall by gravity along x, with ν = 0 (a one-dimensional
/// bar): fixed at both ends under a uniform body force, the wall takes half the weight,
/// ρ g L H t / 2, and the clamp the other half. Static contact (H = 0), to 1e-6.
#[test]
fn gravity_along_a_strip_between_clamp_and_wall_puts_half_its_weight_on_the_wall() {
    let s = common::run_summary(
        "strip_wall",
        &[
            "geometry.parameters.gap=0.0",
            "geometry.parameters.lc=0.0025",
            "boundaries.loads=[]",
            "boundaries.gravity=[9.81, 0.0]",
            "material.poisson_ratio=0.0",
            "harmonic_balance.harmonics=0",
            "damping=null",
        ],
        "gravity-strip-wall",
    );
    let (rho, g, l, h, t) = (7800.0, 9.81, 0.2, 0.01, 1.0);
    let half = rho * g * l * h * t / 2.0;
    let force = s.contact.as_ref().unwrap().peak_contact_force;
    println!("wall reaction {force:.8e} N, half the weight {half:.8e} N");
    assert!((force - half).abs() < 1e-6 * half, "{force} vs {half}");
    let effects = serde_json::to_value(&s.effects).unwrap();
    assert_eq!(
        effects["gravity"],
        serde_json::json!([9.81, 0.0]),
        "{effects}"
    );
}

/// The first row of probes.csv: (probe's u_x, u_y) per probe, in column order.
fn static_probes(dir: &std::path::Path) -> Vec<f64> {
    let text = std::fs::read_to_string(dir.join("probes.csv")).unwrap();
    let row = text.lines().nth(1).unwrap();
    row.split(',').skip(1).map(|v| v.parse().unwrap()).collect()
}

/// TEST GOAL: a solid steel disc turning at Ω = 1000 rad/s (plane stress, R = 0.1 m, a quarter
/// with symmetry conditions) under its centrifugal force alone stretches its rim by
/// u(R) = (1 − ν) ρ Ω² R³ / (4E) (Timoshenko & Goodier, rotating discs), and its centre
/// carries σ_r = σ_θ = (3 + ν) ρ Ω² R² / 8, the largest von Mises stress: within 0.5%
/// (measured −0.006% and −0.08% at lc = 4 mm). With spin softening (the centrifugal force
/// following the displacement) the rim moves a little further, by about ρΩ²R²/E (+0.008%).
#[test]
fn a_turning_disc_stretches_and_is_stressed_as_the_closed_form_says() {
    let run = |sets: &[&str], tag: &str| {
        let out = common::temp_out(tag);
        let out_arg = out.display().to_string();
        let mut args = vec!["run", "tests/data/quarter_disc.yaml", "--out", &out_arg];
        for s in sets {
            args.extend(["--set", s]);
        }
        let r = common::hbcontact(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        (
            static_probes(&out),
            common::read_json(&out.join("summary.json")),
        )
    };
    let (rho, omega, r, e, nu): (f64, f64, f64, f64, f64) = (7800.0, 1000.0, 0.1, 210.0e9, 0.3);
    let rim = (1.0 - nu) * rho * omega * omega * r.powi(3) / (4.0 * e);
    let centre = (3.0 + nu) / 8.0 * rho * omega * omega * r * r;
    let (plain, summary) = run(&["boundaries.rotation.spin_softening=false"], "disc-plain");
    let vm = summary["max_von_mises"].as_f64().unwrap();
    println!(
        "rim u_x {:.6e}, u_y {:.6e} vs {rim:.6e}; von Mises {vm:.5e} vs {centre:.5e}",
        plain[0], plain[3]
    );
    for u in [plain[0], plain[3]] {
        assert!((u - rim).abs() < 5e-3 * rim, "{u} vs {rim}");
    }
    assert!((vm - centre).abs() < 5e-3 * centre, "{vm} vs {centre}");
    let (softened, summary) = run(&[], "disc-softened");
    let gain = softened[0] / plain[0] - 1.0;
    println!("spin softening: rim +{:.4}%", 100.0 * gain);
    assert!(
        gain > 0.0 && gain < 10.0 * rho * omega * omega * r * r / e,
        "{gain}"
    );
    let effects = summary["effects"]["rotation"].as_str().unwrap();
    assert!(
        effects.contains("centrifugal force, spin softening"),
        "{effects}"
    );
}

/// TEST GOAL: spin softening lowers every in-plane natural frequency as a mass on a spring
/// along a turning arm, ω² = k/m − Ω²: (K − Ω²M)φ = (ω0² − Ω²)Mφ, so each mode of the
/// quickstart bracket turning at Ω = 2000 rad/s has f² = f0² − (Ω/2π)², to 1e-9 (the mode
/// shapes unchanged).
#[test]
fn spin_softening_lowers_every_squared_natural_frequency_by_the_squared_speed() {
    let modes = |sets: &[&str], tag: &str| -> Vec<f64> {
        let out = common::temp_out(tag);
        let out_arg = out.display().to_string();
        let mut args = vec![
            "modes",
            "pipelines/quickstart.yaml",
            "--count",
            "4",
            "--out",
            &out_arg,
        ];
        for s in sets {
            args.extend(["--set", s]);
        }
        let r = common::hbcontact(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let json = common::read_json(&out.join("modes.json"));
        json["modes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["frequency_hz"].as_f64().unwrap())
            .collect()
    };
    let still = modes(&[], "spin-still");
    let omega: f64 = 2000.0;
    let turning = modes(
        &["boundaries.rotation={speed: 2000.0, centrifugal: false}"],
        "spin-turning",
    );
    let shift = (omega / (2.0 * std::f64::consts::PI)).powi(2);
    for (f0, f) in still.iter().zip(&turning) {
        let expected = (f0 * f0 - shift).sqrt();
        println!("f0 {f0:.6} Hz → {f:.6} Hz (closed form {expected:.6})");
        assert!((f - expected).abs() < 1e-9 * expected, "{f} vs {expected}");
    }
}

/// The cos and sin coefficients of the first harmonic of probes.csv's columns 1 (u_x) and 2
/// (u_y), sampled uniformly over one period.
fn first_harmonic(dir: &std::path::Path) -> [[f64; 2]; 2] {
    let text = std::fs::read_to_string(dir.join("probes.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let n = rows.len() as f64;
    let coefficient = |col: usize, trig: fn(f64) -> f64| {
        let sum: f64 = rows
            .iter()
            .enumerate()
            .map(|(j, r)| r[col] * trig(2.0 * std::f64::consts::PI * j as f64 / n))
            .sum();
        2.0 * sum / n
    };
    [
        [coefficient(1, f64::cos), coefficient(1, f64::sin)],
        [coefficient(2, f64::cos), coefficient(2, f64::sin)],
    ]
}

/// TEST GOAL: a free strip in a frame turning at Ω = ±2 rev/s about its centroid, pushed by
/// F0 cos ωt (5 Hz) through the centroid, moves as a rigid body (its first elastic mode is
/// near 530 Hz): z = x + iy obeys m (z̈ + 2iΩż − Ω²z) = F0 cos ωt, so
/// x = −(F0/2m)(1/(ω+Ω)² + 1/(ω−Ω)²) cos ωt and y = −(F0/2m)(1/(ω+Ω)² − 1/(ω−Ω)²) sin ωt:
/// the Coriolis force turns a push along x into a motion along y whose sign follows the sense
/// of rotation. Measured 1e-6 relative on both (the elastic part, (ω/ω₁)²); held to 1e-4,
/// the other coefficients to 1e-4 of |x|. Without the Coriolis force y is 0 and
/// x = −F0/(m(ω² + Ω²)).
#[test]
fn a_free_strip_in_a_turning_frame_moves_as_the_coriolis_closed_form_says() {
    let (f0, m) = (1e5 * 0.1, 7800.0 * 0.1);
    let w = 2.0 * std::f64::consts::PI * 5.0;
    let speed: f64 = 4.0 * std::f64::consts::PI;
    for (sense, coriolis) in [(1.0, true), (-1.0, true), (1.0, false)] {
        let o = sense * speed;
        let (a, b) = (1.0 / (w + o).powi(2), 1.0 / (w - o).powi(2));
        let expected = match coriolis {
            true => [-f0 / (2.0 * m) * (a + b), -f0 / (2.0 * m) * (a - b)],
            false => [-f0 / (m * (w * w + o * o)), 0.0],
        };
        let sets = [
            format!("boundaries.rotation.speed={o}"),
            format!("boundaries.rotation.coriolis={coriolis}"),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let tag = format!("free-strip-turning-{sense}-{coriolis}");
        let dir = common::run_cli("run", "tests/data/free_strip_turning.yaml", &tag, &sets);
        let [[xc, xs], [yc, ys]] = first_harmonic(&dir);
        println!("Ω = {o:+.4} rad/s, Coriolis {coriolis}: x cos {xc:.9e} ({:.9e}), y sin {ys:.9e} ({:.9e})", expected[0], expected[1]);
        assert!(
            (xc - expected[0]).abs() < 1e-4 * expected[0].abs(),
            "{xc} vs {}",
            expected[0]
        );
        assert!(
            (ys - expected[1]).abs() < 1e-4 * expected[0].abs(),
            "{ys} vs {}",
            expected[1]
        );
        if coriolis {
            assert!((ys - expected[1]).abs() < 1e-4 * expected[1].abs());
        }
        assert!(xs.abs().max(yc.abs()) < 1e-4 * xc.abs(), "{xs} {yc}");
        let summary = common::read_json(&dir.join("summary.json"));
        let effects = summary["effects"]["rotation"].as_str().unwrap().to_string();
        assert_eq!(effects.contains("Coriolis force"), coriolis, "{effects}");
    }
}

/// TEST GOAL: the time marching takes the same Coriolis force as harmonic balance. On the
/// shipped blade passing a 3-lobed casing at 100 rev/s (pipelines/blade_lobed_casing.yaml),
/// the Coriolis force raises the probe's radial harmonics 3 and 6 by 5.5% and 6.0% in
/// harmonic balance and by 5.5% and 6.0% in the marching (measured difference of the two
/// rises 0.06 and 0.02 points; held to 0.5 point), and with it on, harmonic balance (H = 30)
/// and the marching agree as they do without it (x harmonics 3 and 6 +1.0% and +0.4%, both
/// with and without; the mean contact force −0.02%): held to 2% and 0.5%.
#[test]
fn the_coriolis_force_moves_the_lobed_casing_response_alike_in_harmonic_balance_and_marching() {
    let pipeline = "pipelines/blade_lobed_casing.yaml";
    let mut harmonics = Vec::new();
    for coriolis in [false, true] {
        let sets = [
            format!("boundaries.rotation.coriolis={coriolis}"),
            "stability.check=false".to_string(),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let hb_dir = common::run_cli("run", pipeline, &format!("coriolis-{coriolis}-hb"), &sets);
        let tm_dir = common::run_cli(
            "transient",
            pipeline,
            &format!("coriolis-{coriolis}-tm"),
            &sets,
        );
        let (hb, tm) = (
            common::read_json(&hb_dir.join("summary.json")),
            common::read_json(&tm_dir.join("summary.json")),
        );
        let at = |s: &serde_json::Value, k: usize| {
            s["probes"]["probe"]["harmonics_x"][k - 1].as_f64().unwrap()
        };
        for k in [3, 6] {
            let (a, b) = (at(&hb, k), at(&tm, k));
            println!(
                "Coriolis {coriolis}, harmonic {k}: HB {a:.6e}, marching {b:.6e} ({:+.3}%)",
                100.0 * (a / b - 1.0)
            );
            assert!((a / b - 1.0).abs() < 0.02);
        }
        let pointer = "/contact/mean_contact_force";
        let (a, b) = (
            common::json_number(&hb, pointer),
            common::json_number(&tm, pointer),
        );
        assert!((a / b - 1.0).abs() < 0.005, "{a} vs {b}");
        harmonics.push([at(&hb, 3), at(&hb, 6), at(&tm, 3), at(&tm, 6)]);
    }
    for (i, k) in [3, 6].into_iter().enumerate() {
        let rise_hb = harmonics[1][i] / harmonics[0][i] - 1.0;
        let rise_tm = harmonics[1][i + 2] / harmonics[0][i + 2] - 1.0;
        println!(
            "harmonic {k}: the Coriolis force raises it {:+.3}% (HB), {:+.3}% (marching)",
            100.0 * rise_hb,
            100.0 * rise_tm
        );
        assert!(rise_hb > 0.03 && (rise_hb - rise_tm).abs() < 0.005);
    }
}

/// TEST GOAL: where the Coriolis force is not taken yet it is refused or said, never
/// silently dropped: a contact sweep on reduced frames refuses it naming the key (exit 2),
/// and a contact run's stability verdict comes from the marching, with the reason in the
/// warnings.
#[test]
fn the_coriolis_force_is_refused_by_sweeps_and_judged_by_marching() {
    let r = common::hbcontact(&[
        "sweep",
        "pipelines/strip_sweep_light.yaml",
        "--set",
        "boundaries.rotation={speed: 10.0, coriolis: true}",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("boundaries.rotation.coriolis"), "{err}");
    let r = common::hbcontact(&[
        "run",
        "pipelines/blade_lobed_casing.yaml",
        "--out",
        &common::temp_out("coriolis-stability").display().to_string(),
        "--set",
        "boundaries.rotation.coriolis=true",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("Coriolis force yet"), "{err}");
    assert!(err.contains("judged by time marching"), "{err}");
}

/// TEST GOAL: the rotation speed is given once: a fixed `speed` or `turns_per_period` (the
/// speed following the frequency); both, or neither, are refused (exit 2) naming the two keys
/// and the file.
#[test]
fn a_rotation_speed_given_twice_or_not_at_all_is_refused_naming_both_keys() {
    for rotation in [
        "boundaries.rotation={speed: 100.0, turns_per_period: 1.0}",
        "boundaries.rotation={center: [0.0, 0.0]}",
    ] {
        let r = common::hbcontact(&[
            "check",
            "pipelines/blade_lobed_casing.yaml",
            "--set",
            rotation,
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{rotation}: {err}");
        for needle in ["blade_lobed_casing.yaml", "`speed`", "`turns_per_period`"] {
            assert!(err.contains(needle), "{rotation}: {err}");
        }
    }
}
