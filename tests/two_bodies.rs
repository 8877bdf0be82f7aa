//! Contact between two meshed elastic bodies (`contact.obstacle: {body: GROUP}`, node to
//! segment): against its rigid-wall twin by symmetry, against Hertz's two-cylinder closed form,
//! and against the product's own time marching of the same two-body model.

mod common;

use hbcontact::config::{load_pipeline, Pipeline};
use hbcontact::pipeline::{self, Purpose};
use serde_json::Value;

use common::json_number as number;

fn data(name: &str, overrides: &[&str]) -> Pipeline {
    let path = common::root()
        .join("tests/data")
        .join(format!("{name}.yaml"));
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    load_pipeline(&path, &overrides).unwrap_or_else(|e| panic!("{e}"))
}

/// `hbcontact COMMAND tests/data/NAME.yaml --out output/test-runs/TAG` with `--set`s; the
/// summary it wrote.
fn summary_of(command: &str, name: &str, tag: &str, sets: &[&str]) -> Value {
    let pipeline = format!("tests/data/{name}.yaml");
    let out = common::run_cli(command, &pipeline, tag, sets);
    common::read_json(&out.join("summary.json"))
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// TEST GOAL: two identical strips, each clamped at its outer end and driven toward the other
/// by mirrored harmonic tractions on its free face, 2·gap apart, have the steady state of one
/// strip against a rigid wall at the mirror plane (gap): by symmetry each face stops at the
/// plane. geometries/two_strips.geo meshes both strips structured, so B's nodes mirror A's, and
/// second = 0 replaces B by the wall. Probe amplitudes, contact peak and mean force and the
/// Newton count agree to the solver's tolerance (1e-8); B's probe moves as A's mirror image.
#[test]
fn two_identical_strips_driven_toward_each_other_equal_one_strip_against_a_wall_at_half_the_gap() {
    let two = summary_of("run", "two_strips", "two-bodies-symmetric", &[]);
    let one = summary_of("run", "two_strips_wall", "two-bodies-wall", &[]);
    for pointer in [
        "/probes/probe/first_harmonic_x",
        "/probes/probe/half_peak_to_peak_x",
        "/probes/probe/first_harmonic_y",
        "/contact/peak_contact_force",
        "/contact/mean_contact_force",
    ] {
        let (a, b) = (number(&two, pointer), number(&one, pointer));
        println!("{pointer}: two bodies {a:.10e}, wall {b:.10e}");
        assert!(relative(a, b) < 1e-7, "{pointer}: {a:e} vs {b:e}");
    }
    let (a, b) = (
        number(&two, "/probes/probe/first_harmonic_x"),
        number(&two, "/probes/probe_b/first_harmonic_x"),
    );
    assert!(relative(b, a) < 1e-7, "mirror probe {b:e} vs {a:e}");
    assert_eq!(two["contact_setup"]["kept"], one["contact_setup"]["kept"]);
}

/// The total pressing force P (per unit thickness) and the pressure at x = 0 of a static
/// two-body solution: the slave side's −λ_i over tributary lengths, interpolated in x.
fn force_and_centre_pressure(model: &pipeline::Model, lambda: &[f64]) -> (f64, f64, f64) {
    let set = &model.contact.as_ref().unwrap().set;
    let t = model.material.thickness;
    let load = -lambda.iter().sum::<f64>() / t;
    let mut profile: Vec<(f64, f64)> = set
        .nodes
        .iter()
        .enumerate()
        .map(|(i, &n)| (model.mesh.nodes[n][0], -lambda[i] / (set.tributary[i] * t)))
        .collect();
    profile.sort_by(|a, b| a.0.total_cmp(&b.0));
    let j = profile.iter().position(|p| p.0 >= 0.0).unwrap();
    let (l, r) = (profile[j - 1], profile[j]);
    let centre = if r.0 == 0.0 {
        r.1
    } else {
        l.1 + (r.1 - l.1) * (0.0 - l.0) / (r.0 - l.0)
    };
    // Hertz's p(x)² = p0² (1 − x²/a²) is linear in x²: fit it (least squares) over the
    // closed nodes of the inner 80% of the zone, a = sqrt(−intercept/slope).
    let last = profile
        .iter()
        .filter(|p| p.1 > 1e-9 * centre)
        .fold(0.0f64, |m, p| m.max(p.0.abs()));
    let inner: Vec<(f64, f64)> = profile
        .iter()
        .filter(|p| p.0.abs() < 0.8 * last)
        .map(|p| (p.0 * p.0, p.1 * p.1))
        .collect();
    let n = inner.len() as f64;
    let (sx, sy) = inner.iter().fold((0.0, 0.0), |s, p| (s.0 + p.0, s.1 + p.1));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) = inner.iter().fold((0.0, 0.0), |s, p| {
        (s.0 + (p.0 - mx) * (p.1 - my), s.1 + (p.0 - mx).powi(2))
    });
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    (load, centre, (-intercept / slope).sqrt())
}

/// TEST GOAL: 2-D Hertz contact of two elastic cylinders (Johnson, Contact Mechanics, §4.3):
/// radii R1 = 1 and R2 = 2 of the same steel, plane strain, pressed together by a force P per
/// unit length, touch over a half-width a = sqrt(4PR/(πE*)) with a centre pressure
/// p0 = 2P/(πa), where 1/R = 1/R1 + 1/R2 and 1/E* = 2(1 − ν²)/E. The upper half-disc's flat
/// top is pushed down 1 mm, the lower one's flat base held; neither mesh's contact nodes face
/// the other's (unstructured, node to segment). P is measured (−Σλ), a and p0 follow; the FE
/// half-width is the fit of p² = p0²(1 − x²/a²) over the zone's inner 80%. Three contact sizes
/// measured p0 +0.17%, −0.03%, +0.16% and a −0.06%, +0.29%, +0.11% (h = 2, 1.5, 1 mm); each is
/// held to 0.5%. The target side takes the whole reaction (Bᵀλ).
#[test]
fn two_elastic_cylinders_match_hertz_with_the_effective_radius_and_modulus() {
    for h in [0.002, 0.0015, 0.001] {
        let p = data(
            "two_discs",
            &[&format!("geometry.parameters.lc_contact={h}")],
        );
        let model = common::model(&p, Purpose::HarmonicBalance);
        let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
        let contact = solution.contact.as_ref().unwrap();
        let lambda = &contact.multipliers;
        let (load, centre, half_width) = force_and_centre_pressure(&model, lambda);
        let (r1, r2) = (1.0, 2.0);
        let radius = r1 * r2 / (r1 + r2);
        let nu = p.material.poisson_ratio;
        let e_star = p.material.youngs_modulus / (2.0 * (1.0 - nu * nu));
        let a = (4.0 * load * radius / (std::f64::consts::PI * e_star)).sqrt();
        let p0 = 2.0 * load / (std::f64::consts::PI * a);
        let error = (centre - p0) / p0;
        let set = &model.contact.as_ref().unwrap().set;
        println!(
            "two cylinders, h = {h}: {} contact nodes, {} target nodes, P = {load:.5e} N/m, a = {a:.5e} m (FE fit {half_width:.5e}, {:+.3}%), p0 = {p0:.5e} Pa (FE centre {centre:.5e}, {:+.3}%)",
            set.nodes.len(),
            set.target_nodes.len(),
            100.0 * (half_width - a) / a,
            100.0 * error
        );
        assert!(
            error.abs() < 5e-3,
            "h = {h}: centre pressure {:+.3}%",
            100.0 * error
        );
        let width_error = (half_width - a) / a;
        assert!(
            width_error.abs() < 5e-3,
            "h = {h}: half-width {half_width:e} vs Hertz {a:e} ({:+.3}%)",
            100.0 * width_error
        );
        // Bᵀλ: the force on the target side is the opposite of the slave side's.
        let weights: f64 = set
            .targets
            .iter()
            .zip(lambda)
            .map(|(t, l)| l * t.iter().map(|&(_, w)| w).sum::<f64>())
            .sum();
        assert!(relative(weights, lambda.iter().sum()) < 1e-12);
    }
}

/// TEST GOAL: a strip driven against a shorter, flexible second strip (B: half A's length, a
/// finer mesh whose face nodes do not face A's) agrees with the product's own explicit time
/// marching of the same two-body model, both sides' contact nodes massless: A's probe's first
/// harmonic and the mean contact force within 1% at H = 20 (measured 0.29% and 0.26%).
#[test]
fn a_strip_against_a_shorter_flexible_strip_agrees_with_its_time_marching() {
    let sets = [
        "geometry.parameters.LB=0.1",
        "geometry.parameters.lcB=0.0017",
        "boundaries.loads=[{group: tip, type: traction, harmonics: [{k: 1, cos: [3.0e5, 0.0], sin: [0.0, 0.0]}]}]",
    ];
    let hb = summary_of("run", "two_strips", "two-bodies-hb", &sets);
    let tm = summary_of("transient", "two_strips", "two-bodies-tm", &sets);
    let pointers = [
        "/probes/probe/first_harmonic_x",
        "/contact/mean_contact_force",
    ];
    common::assert_agrees_with_marching(&hb, &tm, &pointers, 1e-2);
    assert!(number(&tm, "/probes/probe_b/first_harmonic_x") > 0.0);
}

/// TEST GOAL: with two bodies, the mass redistribution takes the inertia off both sides'
/// contact nodes and keeps each body's own mass and centre of mass (mass does not move from
/// one body to the other).
#[test]
fn each_body_keeps_its_mass_and_centre_and_both_contact_sides_are_massless() {
    let p = data(
        "two_strips",
        &[
            "geometry.parameters.LB=0.1",
            "geometry.parameters.lcB=0.0017",
        ],
    );
    let model = common::model(&p, Purpose::HarmonicBalance);
    let c = model.contact.as_ref().unwrap();
    let mass = model.mass_diagonal.as_ref().unwrap();
    for &n in c.set.nodes.iter().chain(&c.set.target_nodes) {
        assert_eq!(mass[2 * n], 0.0, "contact node {n} carries mass");
    }
    assert!(!c.set.target_nodes.is_empty());
    let lumped = hbcontact::fem::assemble_mass(
        &model.mesh,
        &model.material,
        hbcontact::fem::MassKind::Lumped,
    )
    .unwrap()
    .diagonal();
    for group in ["body", "body_b"] {
        let cells = &model.mesh.cell_groups[group];
        let mut nodes: Vec<usize> = cells
            .iter()
            .flat_map(|&c| model.mesh.cells[c].nodes.clone())
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        let moments = |m: &[f64]| {
            nodes.iter().fold([0.0; 3], |s, &n| {
                let x = model.mesh.nodes[n];
                [
                    s[0] + m[2 * n],
                    s[1] + m[2 * n] * x[0],
                    s[2] + m[2 * n] * x[1],
                ]
            })
        };
        let (after, before) = (moments(mass), moments(&lumped));
        for k in 0..3 {
            assert!(
                (after[k] - before[k]).abs() <= 1e-12 * before[k].abs().max(before[0]),
                "{group}: moment {k} {} vs {}",
                after[k],
                before[k]
            );
        }
    }
}

/// TEST GOAL: a two-body run writes the contact fields on both sides (an independent reader,
/// meshio): pressure ≥ 0 and status consistent on each side, no obstacle.vtu (the target is
/// in the mesh), and `check` names the target and how many of its nodes take the reaction.
#[test]
fn both_sides_carry_the_contact_fields_and_check_names_the_target() {
    let out = common::run_cli(
        "run",
        "tests/data/two_strips.yaml",
        "two-bodies-fields",
        &[],
    );
    assert!(!out.join("obstacle.vtu").exists());
    let s = common::read_json(&out.join("summary.json"));
    let tolerance = number(&s, "/contact/closed_opening_tolerance");
    let check = std::process::Command::new(common::venv_python())
        .arg(common::root().join("tests/scripts/meshio_check.py"))
        .arg(&out)
        .args(["--contact", &format!("{tolerance:e}")])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&check.stdout);
    assert!(
        check.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&check.stderr)
    );
    // Closed node-frames on both faces: twice those of one face (5 nodes each, mirrored).
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix("meshio_check: contact "))
        .unwrap();
    let closed: usize = line.split_whitespace().next().unwrap().parse().unwrap();
    let total: usize = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert_eq!(total, 10 * 16, "{line}");
    assert!(closed > 0 && closed.is_multiple_of(2), "{line}");
    let r = common::hbcontact(&["check", "tests/data/two_strips.yaml"]);
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(
        text.contains("against `tip_b` of another body: 5 of its nodes take the reaction"),
        "{text}"
    );
    assert!(text.contains("smallest initial gap 2.000e-7 m"), "{text}");
}

/// The folds' frequencies and the rows (frequency, probe amplitude, peak and mean contact
/// force) of a sweep's output folder.
fn sweep_of(dir: &std::path::Path) -> (Vec<f64>, Vec<[f64; 4]>) {
    let json = common::read_json(&dir.join("sweep.json"));
    let folds = json["folds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["frequency_hz"].as_f64().unwrap())
        .collect();
    let text = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let cols = [
        col("frequency_hz"),
        col("probe_first_harmonic"),
        col("peak_contact_force"),
        col("mean_contact_force"),
    ];
    let rows = lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            cols.map(|c| v[c].parse().unwrap())
        })
        .collect();
    (folds, rows)
}

/// TEST GOAL: a frequency sweep works on two bodies: the two mirrored strips swept
/// 3–6 kHz through their contact-stiffened resonance trace the curve of one strip against the
/// wall at the mirror plane. The same points and folds (each fold frequency within 1e-6:
/// measured 4e-8), and every row within 1e-4 (measured 3e-5: the two continuations are the
/// same curve, their correctors scaled differently).
#[test]
fn a_sweep_of_two_mirrored_strips_is_the_sweep_of_one_strip_against_the_wall() {
    let sets = [
        "geometry.parameters.lc=0.005",
        "sweep={from: 3000.0, to: 6000.0}",
        "stability.check=false",
    ];
    let run = |name: &str, tag: &str| {
        let pipeline = format!("tests/data/{name}.yaml");
        sweep_of(&common::run_cli("sweep", &pipeline, tag, &sets))
    };
    let (two_folds, two_rows) = run("two_strips", "two-bodies-sweep");
    let (one_folds, one_rows) = run("two_strips_wall", "two-bodies-sweep-wall");
    println!("folds: two bodies {two_folds:?}, wall {one_folds:?}");
    assert!(!two_folds.is_empty());
    assert_eq!(two_folds.len(), one_folds.len());
    for (a, b) in two_folds.iter().zip(&one_folds) {
        assert!(relative(*a, *b) < 1e-6, "fold {a} vs {b}");
    }
    assert_eq!(two_rows.len(), one_rows.len());
    for (a, b) in two_rows.iter().zip(&one_rows) {
        for k in 0..4 {
            assert!(relative(a[k], b[k]) < 1e-4, "{a:?} vs {b:?}");
        }
    }
}
