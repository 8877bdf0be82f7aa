//! Linear harmonic balance against what it must equal.
//!
//! TEST GOAL: the per-harmonic solve reproduces (a) a direct solve of the complex frequency-
//! domain system assembled separately in real block form, and (b) the time-domain equation
//! M ü + D u̇ + K u = f(t) at arbitrary instants, including sine loads and prescribed harmonic
//! motion; and the run computes only the harmonics the scene excites.

mod common;

use std::collections::BTreeMap;

use faer::c64;
use hbcontact::fem;
use hbcontact::hbm::basis::{SplineBasis, TimeBasis};
use hbcontact::hbm::{self, HarmonicInput, HbSettings, System};
use hbcontact::linalg::{solve_real, Csc, Triplets};
use hbcontact::pipeline::Purpose;

fn settings(h: usize) -> HbSettings {
    HbSettings {
        harmonics: h,
        samples: 64,
        c_scale: 1.0,
        tolerance: 1e-10,
        max_seconds: 3600.0,
        max_iterations: 50,
    }
}

/// [[A, −B], [B, A]] [x; y] = [f_r; f_i] for (A + iB)(x + iy) = f_r + i f_i.
fn direct_complex_solve(
    a: &Triplets,
    b: &Triplets,
    free: &[usize],
    free_of: &[Option<usize>],
    f: &[c64],
) -> Vec<c64> {
    let n = free.len();
    let mut entries = Vec::new();
    for (t, sign_off) in [(a, 0.0), (b, 1.0)] {
        for &(i, j, v) in &t.entries {
            let (Some(r), Some(c)) = (free_of[i], free_of[j]) else {
                continue;
            };
            if sign_off == 0.0 {
                entries.push((r, c, v));
                entries.push((n + r, n + c, v));
            } else {
                entries.push((r, n + c, -v));
                entries.push((n + r, c, v));
            }
        }
    }
    let big = Csc::from_entries(2 * n, 2 * n, &entries);
    let rhs: Vec<f64> = f
        .iter()
        .map(|z| z.re)
        .chain(f.iter().map(|z| z.im))
        .collect();
    let x = solve_real(&big, &rhs).expect("direct solve");
    (0..n).map(|i| c64::new(x[i], x[n + i])).collect()
}

#[test]
fn harmonic_balance_equals_a_direct_complex_solve_and_the_time_domain_equation() {
    let p = common::scene(
        "cantilever",
        &["damping.beta=1.0e-4", "harmonic_balance.frequency=12.0"],
    );
    let model = common::model(&p, Purpose::HarmonicBalance);
    let mesh = &model.mesh;
    let k = fem::assemble_stiffness(mesh, &model.material).unwrap();
    let m = fem::assemble_mass(mesh, &model.material, fem::MassKind::Consistent).unwrap();
    let (alpha, beta) = model.system.rayleigh.expect("damped scene");
    let omega = model.system.omega;

    // A cos and a sin load on the tip, at harmonic 1; a static load.
    let tip = fem::edge_traction_load(mesh, &mesh.edge_groups["tip"], [0.0, 1.0e4], 1.0);
    let side = fem::edge_traction_load(mesh, &mesh.edge_groups["tip"], [2.0e3, 0.0], 1.0);
    let dofs = model.system.dofs.clone();
    let f1: Vec<c64> = dofs
        .free
        .iter()
        .map(|&d| c64::new(tip[d], -side[d]))
        .collect();
    let np = dofs.prescribed.len();
    let inputs = BTreeMap::from([(
        1,
        HarmonicInput {
            force: f1.clone(),
            motion: vec![c64::new(0.0, 0.0); np],
        },
    )]);
    let system = System::new(
        dofs.clone(),
        &k,
        &m,
        Some((alpha, beta)),
        omega,
        inputs,
        None,
    )
    .unwrap();
    let solution = hbm::solve(&system, None, &settings(1), &hbcontact::Silent).unwrap();
    assert_eq!(
        solution.harmonics(),
        vec![1],
        "only the excited harmonic is computed"
    );
    assert!(solution.complex_arithmetic);

    // (a) Direct: A = K − ω²M, B = ω(αM + βK).
    let mut a = Triplets::new(k.n);
    let mut b = Triplets::new(k.n);
    for &(i, j, v) in &k.entries {
        a.push(i, j, v);
        b.push(i, j, omega * beta * v);
    }
    for &(i, j, v) in &m.entries {
        a.push(i, j, -omega * omega * v);
        b.push(i, j, omega * alpha * v);
    }
    let direct = direct_complex_solve(&a, &b, &dofs.free, dofs.free_map(), &f1);
    let hb = &solution.free[&1];
    let scale = direct.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let err = hb
        .iter()
        .zip(&direct)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    // Both are direct sparse LU solves of the same matrix in different forms (complex vs real
    // 2n × 2n): they agree to the round-off that the slender beam's condition number allows.
    assert!(
        scale > 0.0 && err / scale < 1e-7,
        "HB vs direct complex solve: {err:e} of {scale:e}"
    );

    // (b) The time-domain equation at a few instants: M ü + D u̇ + K u = f(t) on free dofs,
    // with f(t) = tip cos ωt + side sin ωt.
    for t in [0.0, 0.013, 0.031] {
        let u = solution.field_at(&dofs, t, 0);
        let v = solution.field_at(&dofs, t, 1);
        let acc = solution.field_at(&dofs, t, 2);
        let ku = k.mul_vec(&u);
        let kv = k.mul_vec(&v);
        let mv = m.mul_vec(&v);
        let ma = m.mul_vec(&acc);
        let (c, s) = ((omega * t).cos(), (omega * t).sin());
        let mut worst: f64 = 0.0;
        let mut fmax: f64 = 0.0;
        for &d in &dofs.free {
            let f = tip[d] * c + side[d] * s;
            let r = ma[d] + alpha * mv[d] + beta * kv[d] + ku[d] - f;
            worst = worst.max(r.abs());
            fmax = fmax.max(tip[d].abs());
        }
        assert!(
            worst < 1e-7 * fmax,
            "time-domain residual {worst:e} at t = {t}"
        );
    }
}

#[test]
fn prescribed_harmonic_motion_satisfies_the_global_equation() {
    // Base excitation: the clamp moves vertically, no load at all.
    let p = common::scene(
        "cantilever",
        &[
            "boundaries.loads=[]",
            "boundaries.prescribed=[{group: clamp, component: x, static: 0.0}, {group: clamp, component: y, harmonics: [{k: 2, cos: 0.0, sin: 1.0e-3}]}]",
            "boundaries.fixed=[]",
        ],
    );
    let model = common::model(&p, Purpose::HarmonicBalance);
    let solution = hbm::solve(&model.system, None, &settings(2), &hbcontact::Silent).unwrap();
    assert_eq!(
        solution.harmonics(),
        vec![2],
        "no static solve without static load; only k = 2"
    );
    assert!(model.effects.prescribed_motion);
    let k = fem::assemble_stiffness(&model.mesh, &model.material).unwrap();
    let m = fem::assemble_mass(&model.mesh, &model.material, fem::MassKind::Consistent).unwrap();
    let (alpha, beta) = model.system.rayleigh.unwrap_or((0.0, 0.0));
    let dofs = &model.system.dofs;
    let t = 0.0123;
    let u = solution.field_at(dofs, t, 0);
    let v = solution.field_at(dofs, t, 1);
    let acc = solution.field_at(dofs, t, 2);
    let (ku, kv, mv, ma) = (k.mul_vec(&u), k.mul_vec(&v), m.mul_vec(&v), m.mul_vec(&acc));
    let scale = ku.iter().map(|x| x.abs()).fold(0.0, f64::max);
    for &d in &dofs.free {
        let r = ma[d] + alpha * mv[d] + beta * kv[d] + ku[d];
        assert!(
            r.abs() < 1e-8 * scale,
            "free-row residual {r:e} (scale {scale:e})"
        );
    }
    // The clamp follows the prescribed motion: u_y = 1e-3 sin(2ωt).
    let w = 2.0 * model.system.omega;
    let clamp = &model.mesh.node_groups["clamp"];
    for &n in clamp {
        assert!((u[2 * n + 1] - 1e-3 * (w * t).sin()).abs() < 1e-15);
        assert_eq!(u[2 * n], 0.0);
    }
}

/// TEST GOAL: an undamped scene is solved in real arithmetic with an in-phase response, and a
/// body without supports (K singular at k = 0) is diagnosed instead of returning NaN. (Resonance
/// at k > 0: `undamped_scene_driven_at_a_natural_frequency_is_refused_with_the_fix`.)
#[test]
fn undamped_scenes_factor_real_matrices_and_a_free_body_is_diagnosed() {
    let p = common::scene("cantilever", &["damping=null", "boundaries.loads=[{group: tip, type: traction, harmonics: [{k: 1, cos: [0.0, 1.0e3], sin: [0.0, 0.0]}]}]"]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    assert!(model.system.rayleigh.is_none());
    assert!(model.effects.damping.is_none());
    assert!(!model.effects.static_load);
    let solution = hbm::solve(&model.system, None, &settings(1), &hbcontact::Silent).unwrap();
    assert!(
        !solution.complex_arithmetic,
        "no damping: real factorizations"
    );
    assert_eq!(solution.harmonics(), vec![1]);
    let z = &solution.free[&1];
    assert!(
        z.iter().all(|v| v.im == 0.0),
        "undamped response is in phase with the load"
    );

    // A structure without supports: K singular, diagnosed instead of NaN.
    let p = common::scene(
        "cantilever",
        &[
            "boundaries.fixed=[]",
            "boundaries.loads=[{group: tip, type: traction, static: [0.0, 1.0e3]}]",
        ],
    );
    let model = common::model(&p, Purpose::HarmonicBalance);
    match hbm::solve(&model.system, None, &settings(0), &hbcontact::Silent) {
        Err(hbcontact::Error::Model(msg)) => assert!(
            msg.contains("rigid body") && msg.contains("boundaries.fixed"),
            "{msg}"
        ),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a free-floating body must not solve"),
    }
}

/// TEST GOAL: resonance at k > 0 (Géradin & Rixen, Mechanical Vibrations, §2.2: the undamped
/// dynamic stiffness K − ω²M is singular at a natural frequency): an undamped cantilever driven
/// exactly at its first bending frequency (computed by `fem::modes` on the scene's own reduced
/// K and M) is refused with Error::Model naming harmonic 1, the frequency setting and the
/// remedy (add damping), instead of returning a huge or NaN answer. Measured: refused from
/// exactly f1 out to 1e-8 relative; 1e-6 off it solves (tip amplitude 21 m under a 1 kPa load),
/// as 1e-4 off, the case held here (its warning is the run's resonance check: modes.rs).
///
/// ```text
///   ▐████████████████████████████████▌ ↕ tip load cos(ω t), ω = ω₁ (no damping)
///   clamp                            tip
/// ```
#[test]
fn undamped_scene_driven_at_a_natural_frequency_is_refused_with_the_fix() {
    let load = "boundaries.loads=[{group: tip, type: traction, harmonics: [{k: 1, cos: [0.0, 1.0e3], sin: [0.0, 0.0]}]}]";
    let p = common::scene("cantilever", &["damping=null", load]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let modes = fem::modes::lowest_modes(&model.system.k_ff, &model.system.m_ff, 2, 0.0).unwrap();
    let f1 = modes[0].0.sqrt() / (2.0 * std::f64::consts::PI);
    println!("first natural frequency {f1:.10} Hz");
    let at = |frequency: f64| {
        let frequency = format!("harmonic_balance.frequency={frequency:e}");
        let q = common::scene("cantilever", &["damping=null", load, &frequency]);
        let model = common::model(&q, Purpose::HarmonicBalance);
        common::solve(&model, &q)
    };
    match at(f1) {
        Err(hbcontact::Error::Model(msg)) => {
            println!("at f1: {msg}");
            assert!(
                msg.contains("harmonic 1")
                    && msg.contains("harmonic_balance.frequency")
                    && msg.contains("add `damping`"),
                "{msg}"
            );
        }
        Err(e) => panic!("wrong error: {e:?}"),
        Ok(s) => panic!(
            "solved at resonance: max |z| {:e}, warnings {:?}",
            s.free[&1].iter().map(|z| z.norm()).fold(0.0, f64::max),
            s.warnings
        ),
    }
    // Near (not at) resonance the answer exists. The warning that its amplitude is set by
    // the distance to resonance alone is the run's resonance check (pipeline::resonance),
    // tested in modes.rs::resonance_warning_fires_within_half_a_percent_of_f1_and_not_at_half_of_it.
    let s = at(f1 * (1.0 + 1e-4)).unwrap_or_else(|e| panic!("1e-4 off f1: {e}"));
    let tip = s.free[&1].iter().map(|z| z.norm()).fold(0.0, f64::max);
    println!("1e-4 off f1: largest |z| {tip:e} m");
    assert!(tip.is_finite() && tip > 0.0);
}

/// max over `times` and all dofs of |u_a(t) − u_b(t)| relative to the largest dynamic
/// excursion |u_b(t) − u_b(0)| of the reference.
fn relative_time_error(
    model: &hbcontact::pipeline::Model,
    a: &hbm::Solution,
    b: &hbm::Solution,
    times: &[f64],
) -> f64 {
    let dofs = &model.system.dofs;
    let start = b.field_at(dofs, 0.0, 0);
    let (mut err, mut scale) = (0.0f64, 0.0f64);
    for &t in times {
        let (ua, ub) = (a.field_at(dofs, t, 0), b.field_at(dofs, t, 0));
        for d in 0..ua.len() {
            err = err.max((ua[d] - ub[d]).abs());
            scale = scale.max((ub[d] - start[d]).abs());
        }
    }
    err / scale
}

/// The errors of the spline solutions of degree p over the segment ladder against the Fourier
/// solution (exact in time for a linear scene whose loads hold harmonics ≤ H), and the local
/// order of the last two.
fn spline_ladder(
    model: &hbcontact::pipeline::Model,
    h: usize,
    degree: usize,
    ladder: &[usize],
) -> (Vec<f64>, f64) {
    let exact = hbm::solve(&model.system, None, &settings(h), &hbcontact::Silent).unwrap();
    let period = exact.period();
    // 101 instants, not aligned with any knot of the ladder.
    let times: Vec<f64> = (0..101)
        .map(|i| period * (i as f64 + 0.37) / 101.0)
        .collect();
    let errors: Vec<f64> = ladder
        .iter()
        .map(|&s| {
            let basis = TimeBasis::Spline(SplineBasis::new(degree, s));
            let system = model.system.clone().with_basis(basis);
            let spline = hbm::solve(&system, None, &settings(h), &hbcontact::Silent).unwrap();
            assert_eq!(
                spline.harmonics(),
                exact.harmonics(),
                "the same frequencies solved"
            );
            relative_time_error(model, &spline, &exact, &times)
        })
        .collect();
    let n = ladder.len();
    let order =
        (errors[n - 2] / errors[n - 1]).ln() / (ladder[n - 1] as f64 / ladder[n - 2] as f64).ln();
    (errors, order)
}

/// TEST GOAL: the linear forced response with a periodic spline basis of degree p converges
/// to the exact periodic solution at order p + 1 in the maximum displacement error over the
/// period (the L² projection error of the splines, O(h^{p+1}); the symbol errors are
/// O(h^{2p}), smaller for p ≥ 2: docs/method.md §16), measured over S = 8…64 on the damped
/// cantilever under a static plus harmonic-1 tip load, and under a harmonic-2 base motion (the
/// prescribed dofs follow the projected motion).
#[test]
fn spline_linear_response_converges_to_the_exact_solution_at_order_p_plus_one() {
    let ladder = [8usize, 16, 32, 64];
    let loaded = common::scene("cantilever", &[]);
    let loaded = common::model(&loaded, Purpose::HarmonicBalance);
    let shaken = common::scene(
        "cantilever",
        &[
            "boundaries.loads=[]",
            "boundaries.prescribed=[{group: clamp, component: x, static: 0.0}, {group: clamp, component: y, harmonics: [{k: 2, cos: 1.0e-3, sin: 5.0e-4}]}]",
            "boundaries.fixed=[]",
            "harmonic_balance.harmonics=2",
        ],
    );
    let shaken = common::model(&shaken, Purpose::HarmonicBalance);
    for (name, model, h) in [("tip load", &loaded, 1usize), ("base motion", &shaken, 2)] {
        for degree in [2usize, 3] {
            let (errors, order) = spline_ladder(model, h, degree, &ladder);
            println!(
                "{name}, p = {degree}: errors {errors:?} over S = {ladder:?}, order {order:.2}"
            );
            let want = degree as f64 + 1.0;
            assert!(
                (order - want).abs() < 0.3,
                "{name}, p = {degree}: order {order:.2}, expected {want} ({errors:?})"
            );
            assert!(
                errors.windows(2).all(|w| w[1] < w[0]),
                "monotone: {errors:?}"
            );
        }
    }
}

/// TEST GOAL: with the Fourier basis the general per-frequency code builds exactly today's
/// Z_k = K − k²ω²M + ikω(αM + βK): its pencil Z_k = a K + b M has a = 1 + ikωβ and
/// b = −k²ω² + ikωα bit for bit, and its product with a vector equals the classic one to
/// round-off, so the Fourier path reproduces the earlier results.
#[test]
fn fourier_basis_builds_the_classic_dynamic_stiffness_bit_for_bit() {
    let p = common::scene("cantilever", &["damping.beta=1.0e-4"]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let system = &model.system;
    assert!(matches!(system.basis, TimeBasis::Fourier));
    let (alpha, beta) = system.rayleigh.unwrap();
    let n = system.free_count();
    let x: Vec<c64> = (0..n)
        .map(|i| c64::new((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos()))
        .collect();
    for k in 0..4usize {
        let kw = k as f64 * system.omega;
        let (a, b) = if k > 0 { (alpha, beta) } else { (0.0, 0.0) };
        assert_eq!(
            system.pencil(k),
            (c64::new(1.0, kw * b), c64::new(-(kw * kw), kw * a)),
            "k = {k}"
        );
        let (kx, mx) = (system.k_ff.mul_complex(&x), system.m_ff.mul_complex(&x));
        let classic: Vec<c64> = kx
            .iter()
            .zip(&mx)
            .map(|(&kv, &mv)| kv - mv * (kw * kw) + c64::new(0.0, kw) * (kv * b + mv * a))
            .collect();
        let scale = classic.iter().fold(0.0f64, |m, z| m.max(z.norm()));
        let err = system
            .apply(k, &x)
            .iter()
            .zip(&classic)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).norm()));
        assert!(err <= 1e-14 * scale, "k = {k}: {err:e} of {scale:e}");
    }
}

/// TEST GOAL: a spline basis runs a linear scene end to end (outputs written, the tip
/// amplitude within 1e-4 of Fourier's at 32 cubic segments), and a contact sweep with an even
/// number of segments (an undamped Nyquist frequency: docs/method.md §16) is refused with exit
/// code 2 and the odd S to use instead of running anyway.
#[test]
fn spline_basis_runs_linear_pipelines_and_refuses_even_segments_in_contact_sweeps() {
    let spline = "harmonic_balance.basis={spline: {degree: 3, segments: 32}}";
    let amplitude = |tag: &str, sets: &[&str]| -> f64 {
        let out = common::temp_out(tag);
        let mut args = vec![
            "run",
            "pipelines/cantilever.yaml",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ];
        for s in sets {
            args.extend(["--set", s]);
        }
        let run = common::hbcontact(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let summary = common::read_json(&out.join("summary.json"));
        summary["probes"]["tip_point"]["first_harmonic_y"]
            .as_f64()
            .expect("tip amplitude")
    };
    let (fourier, splines) = (
        amplitude("basis-fourier", &[]),
        amplitude("basis-spline", &[spline]),
    );
    assert!(
        (splines / fourier - 1.0).abs() < 1e-4,
        "spline {splines:e} vs Fourier {fourier:e}"
    );
    let refused = common::hbcontact(&[
        "sweep",
        "pipelines/strip_sweep.yaml",
        "--quiet",
        "--set",
        spline,
    ]);
    assert_eq!(refused.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("harmonic_balance.basis.spline.segments")
            && stderr.contains("sweep")
            && stderr.contains("odd")
            && stderr.contains("segments = 33"),
        "{stderr}"
    );
}
