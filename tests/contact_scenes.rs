//! Contact by harmonic balance against what it must equal: Hertz, the linear limits, the
//! time-domain cross-check, convergence in H.

mod common;

use hbcontact::config::Pipeline;
use hbcontact::hbm::{self, fourier};
use hbcontact::pipeline::{Model, Purpose};
use hbcontact::transient::setup::Marching;
use hbcontact::transient::{self, TransientSettings};

/// Mean x displacement (the strip's axial motion) of the probe nodes over one period.
fn probe_series(model: &Model, solution: &hbm::Solution, samples: usize) -> Vec<f64> {
    let nodes = &model.probes[0].1;
    let period = solution.period();
    (0..samples)
        .map(|j| {
            let u = solution.field_at(&model.system.dofs, j as f64 * period / samples as f64, 0);
            nodes.iter().map(|&n| u[2 * n]).sum::<f64>() / nodes.len() as f64
        })
        .collect()
}

/// Mean and first-harmonic magnitude of a periodic sampled signal.
fn mean_and_first(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let (mut c, mut s) = (0.0, 0.0);
    for (j, x) in v.iter().enumerate() {
        let th = 2.0 * std::f64::consts::PI * j as f64 / n;
        c += x * th.cos();
        s += x * th.sin();
    }
    (mean, 2.0 * (c * c + s * s).sqrt() / n)
}

/// The total pressing contact force −Σλ over a period at `samples` instants.
fn total_force_series(solution: &hbm::Solution, samples: usize) -> Vec<f64> {
    let period = solution.period();
    (0..samples)
        .map(|j| {
            let lambda = solution.multipliers_at(j as f64 * period / samples as f64);
            -lambda.expect("contact solution").iter().sum::<f64>()
        })
        .collect()
}

/// The nodal contact pressure −λ_i / tributary_i, interpolated linearly in x to `x0` (exact
/// where a node sits at `x0`).
fn pressure_at(model: &Model, lambda: &[f64], x0: f64) -> f64 {
    let set = &model.contact.as_ref().unwrap().set;
    let mut profile: Vec<(f64, f64)> = set
        .nodes
        .iter()
        .enumerate()
        .map(|(i, &n)| (model.mesh.nodes[n][0], -lambda[i] / set.tributary[i]))
        .collect();
    profile.sort_by(|a, b| a.0.total_cmp(&b.0));
    let j = profile.partition_point(|q| q.0 < x0);
    let (l, r) = (profile[j - 1], profile[j]);
    if (r.0 - x0).abs() < 1e-12 {
        return r.1;
    }
    l.1 + (r.1 - l.1) * (x0 - l.0) / (r.0 - l.0)
}

/// TEST GOAL: 2-D Hertz line contact (Johnson, Contact Mechanics, §4.3): a cylinder of radius
/// R pressed on a rigid plane by a force P per unit length has a contact half-width
/// a = sqrt(4PR/(πE*)) and a centre pressure p0 = 2P/(πa), E* = E/(1−ν²) in plane strain.
///
/// ```text
///        top: u_x = 0, u_y = −δ
///   ┌──────────────────────┐
///    ╲                    ╱     half-disc, R = 1, far size lc = 0.02, refined to
///      ╲______________╱         h = lc_contact near the bottom (a ≈ 0.021 ≈ 10–20 h)
///   ═══════════════════════     rigid plane y = 0 (analytic line obstacle)
///              x = 0: p0 read here
/// ```
/// P is measured (the sum of the contact forces), a and p0 follow from it. Pressure is the
/// nodal force over its tributary length, read at the centre node (x = 0, a point of the
/// geometry), not as the maximum over nodes: the nodal pressures of an unstructured mesh
/// scatter by 0.1–0.3% from node to node, and the maximum picks up that scatter. The far size
/// matters: at the .geo's lc = 0.1 the centre is +0.26% (maximum +0.94%) and at lc = 0.05
/// +0.32%; from lc = 0.03 down the error is node-to-node scatter of either sign
/// (−0.08% at lc = 0.03, +0.04% at 0.02, +0.14% at 0.015, +0.23% at 0.01, h = 1.5e-3).
/// Three contact sizes at lc = 0.02 measured −0.23%, +0.04%, +0.17% (h = 2, 1.5, 1 mm,
/// 4.5 s together); each is held to 0.3%.
#[test]
fn half_disc_matches_hertz_line_contact() {
    assert_hertz(1, &[0.002, 0.0015, 0.001]);
}

/// The Hertz checks of the half-disc in elements of `order` at each contact size.
fn assert_hertz(order: usize, sizes: &[f64]) {
    for &h in sizes {
        let started = std::time::Instant::now();
        let p = common::scene(
            "half_disc",
            &[
                "harmonic_balance.harmonics=0",
                "damping=null",
                "geometry.parameters.lc=0.02",
                &format!("geometry.order={order}"),
                &format!("geometry.parameters.lc_contact={h}"),
                "boundaries.prescribed=[{group: top, component: x, static: 0.0}, {group: top, component: y, static: -1.0e-3}]",
            ],
        );
        let model = common::model(&p, Purpose::HarmonicBalance);
        let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
        let contact = solution.contact.as_ref().unwrap();
        let set = &model.contact.as_ref().unwrap().set;
        let lambda = &contact.multipliers; // M = 1: one coefficient per node
        let load: f64 = -lambda.iter().sum::<f64>();
        let e_star = p.material.youngs_modulus / (1.0 - p.material.poisson_ratio.powi(2));
        let radius = 1.0;
        let a = (4.0 * load * radius / (std::f64::consts::PI * e_star)).sqrt();
        let p0 = 2.0 * load / (std::f64::consts::PI * a);
        let centre = pressure_at(&model, lambda, 0.0);
        let mut half_width: f64 = 0.0;
        for (i, &n) in set.nodes.iter().enumerate() {
            if -lambda[i] > 1e-9 * load {
                half_width = half_width.max(model.mesh.nodes[n][0].abs());
            }
        }
        let closed = lambda.iter().filter(|&&l| -l > 1e-9 * load).count();
        let error = (centre - p0) / p0;
        println!(
            "Hertz, order {order}, lc = 0.02, h = {h}: {} nodes, P = {load:.4e} N/m, a = {a:.5e} m (FE {half_width:.5e}, {closed} closed nodes), p0 = {p0:.5e} Pa (FE centre {centre:.5e}, {:+.3}%), {:.2} s",
            model.mesh.nodes.len(),
            100.0 * error,
            started.elapsed().as_secs_f64()
        );
        assert!(
            closed >= 15,
            "h = {h}: the contact zone must be resolved by ~20 elements, got {closed} nodes"
        );
        assert!(
            error.abs() < 3e-3,
            "h = {h}: centre pressure {centre:e} vs Hertz {p0:e} ({:+.3}%)",
            100.0 * error
        );
        // The last closed node lies within one element of the Hertz edge.
        assert!(
            (half_width - a).abs() <= h,
            "half-width {half_width:e} vs Hertz {a:e} (h = {h})"
        );
        assert!(
            contact.complementarity.violation < 1e-8,
            "static: exact complementarity"
        );
    }
}

/// TEST GOAL: when the obstacle is out of reach, the contact solve returns the linear
/// response (zero multipliers, no Newton step, the same fields to round-off: the two solves
/// may factor Z_k in different elimination orders).
#[test]
fn unreachable_wall_gives_exactly_the_linear_result() {
    let p = common::scene(
        "strip_wall",
        &[
            "geometry.parameters.gap=0.05",
            "contact.search_distance=1.0",
            "harmonic_balance.harmonics=5",
        ],
    );
    let model = common::model(&p, Purpose::HarmonicBalance);
    let with = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
    let without = hbm::solve(
        &model.system,
        None,
        &common::settings(&p),
        &hbcontact::Silent,
    )
    .unwrap();
    let c = with.contact.as_ref().unwrap();
    assert_eq!(c.newton.iterations, 0);
    assert!(c.multipliers.iter().all(|&l| l == 0.0));
    // The contact solve factors Z_k with the contact normals ordered last (the kept LDLᵀ that
    // also gives G_k), the linear one without: the same solution up to round-off.
    for (k, z) in &without.free {
        let scale = z.iter().fold(0.0f64, |m, v| m.max(v.norm()));
        let diff = with.free[k]
            .iter()
            .zip(z)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).norm()));
        eprintln!("harmonic {k}: relative difference {:.1e}", diff / scale);
        assert!(
            diff <= 2e-12 * scale,
            "harmonic {k} differs from the linear solve by {diff:e} of {scale:e}"
        );
    }
}

/// TEST GOAL: a flat face resting on a flat obstacle (g0 = 0) and pressed hard enough to stay
/// closed all period is the linear problem with the face's normal displacement held at zero
/// (frictionless: the tangential motion stays free).
#[test]
fn closed_contact_equals_the_constrained_linear_solve() {
    let common_overrides = [
        "geometry.mesh_size=0.01",
        "geometry.order=1",
        "harmonic_balance.harmonics=3",
        "boundaries.loads=[{group: top, type: traction, static: [0.0, -1.0e6], harmonics: [{k: 1, cos: [0.0, 3.0e5], sin: [0.0, 0.0]}]}]",
    ];
    let mut with_contact = common_overrides.to_vec();
    with_contact.push("contact={boundary: bottom, obstacle: {line: {point: [0.0, -0.01], normal: [0.0, 1.0]}}, mass: lumped}");
    let p = common::scene("cantilever", &with_contact);
    let model = common::model(&p, Purpose::HarmonicBalance);
    assert!(
        model
            .contact
            .as_ref()
            .unwrap()
            .set
            .gaps
            .iter()
            .all(|g| g.abs() < 1e-12),
        "g0 = 0"
    );
    let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
    let c = solution.contact.as_ref().unwrap();
    // Closed all period: every sampled multiplier of a free contact node presses.
    let m = 2 * c.harmonics + 1;
    let sampler = fourier::Sampler::new(c.harmonics, c.samples);
    let mut s = vec![0.0; c.samples];
    for coeffs in c.multipliers.chunks(m) {
        if coeffs.iter().all(|&v| v == 0.0) {
            continue; // the clamped corner: held, carries nothing
        }
        sampler.to_samples(coeffs, &mut s);
        assert!(s.iter().all(|&l| l < 0.0), "contact opened somewhere");
    }

    let mut constrained = common_overrides.to_vec();
    constrained.push("boundaries.prescribed=[{group: bottom, component: y, static: 0.0}]");
    let q = common::scene("cantilever", &constrained);
    // Purpose::Transient: the same HRZ-lumped mass as the contact scene with `mass: lumped`.
    let linear_model = common::model(&q, Purpose::Transient);
    let linear = hbm::solve(
        &linear_model.system,
        None,
        &common::settings(&q),
        &hbcontact::Silent,
    )
    .unwrap();
    let period = 2.0 * std::f64::consts::PI / solution.omega;
    for j in 0..5 {
        let t = j as f64 * period / 5.0;
        let u = solution.field_at(&model.system.dofs, t, 0);
        let v = linear.field_at(&linear_model.system.dofs, t, 0);
        let scale = v.iter().map(|x| x.abs()).fold(0.0, f64::max);
        let err = u
            .iter()
            .zip(&v)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-6 * scale, "t = {t}: {err:e} vs {scale:e}");
    }
}

/// TEST GOAL: on the strip striking a wall, the probe's first-harmonic amplitude converges
/// toward a high-H reference as H grows, and the complementarity violation of the truncated
/// series stays below a stated bound (0.15 of the force and gap scales) and shrinks with H.
#[test]
fn strip_converges_in_h_and_complementarity_violation_shrinks() {
    let run = |h: usize| {
        let p = common::scene("strip_wall", &[&format!("harmonic_balance.harmonics={h}")]);
        let model = common::model(&p, Purpose::HarmonicBalance);
        let s = common::solve(&model, &p).unwrap_or_else(|e| panic!("H = {h}: {e}"));
        let (_, first) = mean_and_first(&probe_series(&model, &s, 1024));
        let c = s.contact.as_ref().unwrap();
        (first, c.complementarity.violation, c.newton.iterations)
    };
    let (reference, _, _) = run(60);
    let mut errors = Vec::new();
    let mut violations = Vec::new();
    for h in [5, 10, 20, 40] {
        let (amp, violation, iterations) = run(h);
        let err = (amp - reference).abs() / reference;
        println!("H = {h:>2}: first-harmonic probe amplitude {amp:.6e}, error vs H = 60 {err:.3e}, complementarity violation {violation:.3e}, {iterations} Newton iterations");
        errors.push(err);
        violations.push(violation);
    }
    for w in errors.windows(2) {
        assert!(w[1] < w[0], "error must fall with H: {errors:?}");
    }
    // Measured 4.1e-4 at H = 40.
    assert!(errors[3] < 7e-4, "{errors:?}");
    assert!(
        violations[3] < violations[1],
        "violation must shrink with H: {violations:?}"
    );
    // Measured at most 9.6e-2 (H = 10).
    assert!(
        violations.iter().all(|&v| v < 0.15),
        "violation bound 0.15: {violations:?}"
    );
}

/// TEST GOAL: the hard case that stalled the plain semi-smooth Newton (no stiffness-
/// proportional damping, so impacts excite undamped mesh modes; H = 40: 774 iterations and
/// exit 4 before) converges by the smoothing continuation in a few dozen iterations (measured
/// 16 since the settled exit, 24 before; held within 2×); and a Newton starved of iterations
/// stops with a diagnosis naming what to change instead of answering.
#[test]
fn undamped_impacts_converge_by_continuation_and_a_starved_newton_is_diagnosed() {
    let overrides = [
        "harmonic_balance.harmonics=40",
        "damping.beta=0.0",
        "geometry.parameters.lc=0.005",
    ];
    let p = common::scene("strip_wall", &overrides);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let s = common::solve(&model, &p).unwrap_or_else(|e| panic!("H = 40 without beta: {e}"));
    let c = s.contact.unwrap();
    println!(
        "undamped, H = 40: {} iterations, violation {:.3e}",
        c.newton.iterations, c.complementarity.violation
    );
    assert!(
        c.newton.converged && c.newton.iterations <= 32,
        "{}",
        c.newton.iterations
    );
    let mut starved = overrides.to_vec();
    starved.push("harmonic_balance.solver.max_iterations=2");
    let p = common::scene("strip_wall", &starved);
    let model = common::model(&p, Purpose::HarmonicBalance);
    match common::solve(&model, &p) {
        Err(hbcontact::Error::NotConverged(msg)) => assert!(
            msg.contains("damping.beta") && msg.contains("harmonic_balance.harmonics"),
            "the diagnosis names the fixes: {msg}"
        ),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("two Newton iterations cannot solve H = 40"),
    }
}

/// TEST GOAL: on the reference strip of the contact-solver benchmarks (5% damping, 9 contact
/// nodes), every H from 5 to 80 converges in a bounded number of Newton iterations (measured
/// 10–11; the plain semi-smooth Newton took 4–117), the answer does not move with N (the
/// adaptive N settles within 1e-3), and its dependence on c falls with H (measured 0.7% at
/// H = 5, 0.042% at H = 80), as the truncation error does.
#[test]
fn reference_strip_converges_at_every_h_and_knob_dependence_falls_with_h() {
    let mut c_changes = Vec::new();
    for h in [5usize, 10, 20, 40, 80] {
        let p = common::scene(
            "reference_strip",
            &[&format!("harmonic_balance.harmonics={h}")],
        );
        let model = common::model(&p, Purpose::HarmonicBalance);
        let s = common::solve(&model, &p).unwrap_or_else(|e| panic!("H = {h}: {e}"));
        let c = s.contact.unwrap();
        let k = &c.knob_check;
        println!(
            "H = {h}: {} iterations (+{} checking), N = {}, N changes {:?}, c change {:?}",
            c.newton.iterations, k.iterations, c.samples, k.samples_changes, k.c_change
        );
        assert!(
            c.newton.iterations <= 22,
            "H = {h}: {} iterations",
            c.newton.iterations
        );
        assert!(
            k.samples_changes.last().is_some_and(|&v| v <= 1e-3),
            "H = {h}: {k:?}"
        );
        c_changes.push(k.c_change.expect("the c/3 check converges"));
    }
    assert!(c_changes[4] < 0.2 * c_changes[0], "{c_changes:?}");
    assert!(c_changes[4] < 1e-3, "{c_changes:?}");
}

/// TEST GOAL: with 0.5% damping (alpha = 86) instead of 5%, the reference strip's contact
/// Newton needs at most 3 times the iterations at every H up to 70 (issue 8's goal; measured
/// at most 2.8×, at H = 70; at H = 60 2.4×, where it took 4.7× while a smoothing level could
/// spend 30 iterations cycling), and its answer's independence of c is verified at every one of them
/// (at H = 40 the re-solve at c/3 cycles between active sets and the one at 3c converges:
/// the run had warned "unverified"; the c/3 re-solve gives up after 8 steps without halving
/// its residual, so the checks take 14 iterations, where its cap made them 26; at H = 60 the change, 3.4%, is above the 1% the run
/// warns at). At H = 80 the direct continuation folds; the solve then continues in the damping
/// together with the smoothing, from 5% at the fundamental down to the scene's 0.56% over six
/// smoothing levels, and converges (34 iterations measured, all attempts counted, 3.1 times
/// the 5%-damped strip's 11: the direct path's fold costs 13 of them; the
/// stepwise damping continuation it replaced took 111, the harmonic ladder at c/10 1215 or
/// the run stopped, by round-off), warns that it reached one of several periodic states that
/// way, and its answer continues the direct solves' family in H: the mean contact force
/// within 0.5% of H = 60's (measured 0.36%; H = 70, 90, 100 lie within 0.4% of it too).
#[test]
fn lightly_damped_reference_strip_needs_at_most_three_times_the_iterations() {
    let solve = |h: usize, alpha: f64| {
        let sets = [
            format!("harmonic_balance.harmonics={h}"),
            format!("damping.alpha={alpha}"),
        ];
        let refs: Vec<&str> = sets.iter().map(String::as_str).collect();
        let p = common::scene("reference_strip", &refs);
        let model = common::model(&p, Purpose::HarmonicBalance);
        common::solve(&model, &p)
    };
    // The 0.5%-damped answer's change at the second c, measured (docs/performance.md's light-damping
    // table), held within a factor 2: H = 40 at 3c, H = 60 above the 1% the run warns at.
    for (h, measured) in [(5usize, 0.0068), (20, 0.0091), (40, 0.0045), (60, 0.0339)] {
        let contact = |alpha: f64| {
            let s = solve(h, alpha).unwrap_or_else(|e| panic!("H = {h}, alpha = {alpha}: {e}"));
            // A direct solve: no detour to warn about.
            let detour = s
                .warnings
                .iter()
                .find(|w| w.contains("did not converge and"));
            assert!(detour.is_none(), "H = {h}: {detour:?}");
            s.contact.unwrap()
        };
        let (heavy, light) = (contact(857.0), contact(86.0));
        let (k, c) = (&light.knob_check, light.c);
        println!(
            "H = {h}: 5% {}, 0.5% {} iterations; c check at {:.2}c: {:?}",
            heavy.newton.iterations,
            light.newton.iterations,
            k.c_alternative / c,
            k.c_change
        );
        assert!(
            light.newton.iterations <= 3 * heavy.newton.iterations,
            "H = {h}: {} against {}",
            light.newton.iterations,
            heavy.newton.iterations
        );
        assert!(
            k.c_change
                .is_some_and(|change| (0.5 * measured..2.0 * measured).contains(&change)),
            "H = {h}: {k:?}"
        );
        if h == 40 {
            // The cycling re-solve at c/3 gives up after 8 steps without halving its
            // residual: 14 iterations measured for the checks, 26 where it ran to its cap.
            assert!(k.iterations <= 18, "H = 40: {k:?}");
        }
    }
    // H = 70: direct, one level narrowed after cycling (25 against 9 measured; 28 where a
    // level may take 8 near-full steps without halving its residual before narrowing).
    let iterations = |alpha: f64| {
        let s = solve(70, alpha).unwrap_or_else(|e| panic!("H = 70, alpha = {alpha}: {e}"));
        s.contact.unwrap().newton.iterations
    };
    let (heavy, light) = (iterations(857.0), iterations(86.0));
    println!("H = 70: 5% {heavy}, 0.5% {light} iterations");
    assert!(light <= 3 * heavy, "H = 70: {light} against {heavy}");
    let at_80 = solve(80, 86.0).unwrap_or_else(|e| panic!("H = 80: {e}"));
    let c = at_80.contact.as_ref().unwrap();
    let path = &c.damping_path;
    println!(
        "H = 80: {} iterations, damping path {path:?}",
        c.newton.iterations
    );
    assert_eq!(c.ladder, [80]);
    // The first level at 5%, one ratio per heavier level, the scene's own at the end.
    assert_eq!(path.len(), 7, "{path:?}");
    assert!((path[0] - 0.05).abs() < 1e-12, "{path:?}");
    // The scene's own ζ = α/(2ω) at the fundamental.
    let zeta = 86.0 / (2.0 * 2.0 * std::f64::consts::PI * 1225.4930618);
    assert!((path[6] / zeta - 1.0).abs() < 1e-9, "{path:?}");
    assert!(path.windows(2).all(|w| w[1] < w[0]), "{path:?}");
    // Measured 34; 40 where a direct level whose steps each raise the residual may go on
    // to the `hover` bound (no `rise` bound), 51 where a first failed direct level is also
    // narrowed when its steps were short, 98 where it may hover for 30 iterations (no
    // `hover` bound): this bound catches all three.
    assert!(c.newton.iterations <= 38, "{}", c.newton.iterations);
    let detour = at_80
        .warnings
        .iter()
        .find(|w| w.contains("several periodic states"));
    assert!(
        detour.is_some_and(|w| w.contains("continuation in the damping")),
        "{:?}",
        at_80.warnings
    );
    let mean_force = |s: &hbm::Solution| -> f64 {
        let f = total_force_series(s, 4096);
        f.iter().sum::<f64>() / f.len() as f64
    };
    let at_60 = solve(60, 86.0).unwrap();
    let (m80, m60) = (mean_force(&at_80), mean_force(&at_60));
    assert!(
        (m80 / m60 - 1.0).abs() < 5e-3,
        "mean force {m80} at H = 80, {m60} at H = 60"
    );
}

/// The mean total pressing force −Σ_i λ̃_i,0 of a contact solution [N].
fn mean_contact_force(c: &hbm::ContactSolution) -> f64 {
    let m = 2 * c.harmonics + 1;
    -c.multipliers.iter().step_by(m).sum::<f64>()
}

/// TEST GOAL: near its resonance the 0.5%-damped reference strip has two periodic states at
/// one H, N and c, so a solve that starts from the open state can reach either, or fold
/// between them (why the light-damping iteration goal of issue 8 is met at 11 of 16 H only,
/// docs/method.md §7). At H = 15 the direct continuation from λ = 0 reaches one (mean
/// contact force 30 061 N measured); the 5%-damped state followed down in the damping by
/// plain Newton runs on the exact law (α = 857, 482, 271, 152, 86, each from the last
/// state: 4, 3, 3 and 3 iterations measured) reaches another (28 580 N, the value the
/// continuation in the damping run first reaches there, and next to the direct solves'
/// 28 284–28 661 N at the other H). Both solve the same discrete complementarity (the same
/// N and c) to the tolerance; they differ by 5.2%. Held within 0.5% each, and apart by more
/// than 3%.
#[test]
fn lightly_damped_strip_has_two_periodic_states_at_one_h() {
    let at = |alpha: f64| {
        let sets = [
            "harmonic_balance.harmonics=15".to_string(),
            format!("damping.alpha={alpha}"),
        ];
        let refs: Vec<&str> = sets.iter().map(String::as_str).collect();
        let p = common::scene("reference_strip", &refs);
        let model = common::model(&p, Purpose::HarmonicBalance);
        (p, model)
    };
    let contact = |(p, model): &(Pipeline, Model)| {
        let s = common::solve(model, p).unwrap_or_else(|e| panic!("{e}"));
        s.contact.expect("contact")
    };
    let direct = contact(&at(86.0));
    let mut state = contact(&at(857.0));
    // The same discrete problem as the direct solve's: its N (c depends on G_0 alone, which
    // mass-proportional damping does not touch).
    assert_eq!(state.c, direct.c);
    state.samples = direct.samples;
    for alpha in [482.0, 271.0, 152.0, 86.0] {
        let (p, model) = at(alpha);
        let op = &model.contact.as_ref().expect("contact").operator;
        let settings = common::settings(&p);
        let s = hbm::solve_from(&model.system, op, &settings, &state, &hbcontact::Silent)
            .unwrap_or_else(|e| panic!("alpha = {alpha}: {e}"));
        state = s.contact.expect("contact");
        println!(
            "alpha = {alpha}: {} iterations, mean force {:.1} N",
            state.newton.iterations,
            mean_contact_force(&state)
        );
    }
    let (a, b) = (mean_contact_force(&direct), mean_contact_force(&state));
    println!(
        "direct {a:.1} N, followed down in the damping {b:.1} N, N = {}",
        state.samples
    );
    assert!((a / 30_061.0 - 1.0).abs() < 5e-3, "direct: {a}");
    assert!((b / 28_580.0 - 1.0).abs() < 5e-3, "followed down: {b}");
    assert!(a / b - 1.0 > 0.03, "{a} against {b}");
}

/// TEST GOAL: where the re-solves at c/3 and 3c both fail from the solution (the 0.5%-damped
/// reference strip at H = 45, reached through the damping continuation), the knob check goes
/// on to the nearer c/2 and reports the answer's change there (measured 2.2%, held within
/// 2×), with the warning that the answer depends on c, instead of calling the independence
/// of c unverified (docs/method.md §7, "Answers that do not depend on solver knobs").
#[test]
fn a_lightly_damped_answer_is_checked_at_c_over_2_where_c_over_3_and_3c_fail() {
    let sets = ["harmonic_balance.harmonics=45", "damping.alpha=86"];
    let p = common::scene("reference_strip", &sets);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let s = common::solve(&model, &p).unwrap_or_else(|e| panic!("H = 45: {e}"));
    let contact = s.contact.as_ref().expect("contact");
    let check = &contact.knob_check;
    println!("H = 45, 0.5%: {check:?}");
    let ratio = check.c_alternative / contact.c;
    assert!((ratio - 0.5).abs() < 1e-12, "second c at {ratio} c");
    let change = check.c_change.expect("the re-solve at c/2 converges");
    assert!((0.011..0.044).contains(&change), "{change}");
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("depends on the complementarity")),
        "{:?}",
        s.warnings
    );
    assert!(!s.warnings.iter().any(|w| w.contains("unverified")));
}

/// TEST GOAL: the damping continuation is not the reference strip's alone: `strip_wall` with
/// light mass and stiffness damping (alpha = 150, beta = 1e-8: ζ = 0.25% at its 5 kHz drive)
/// at H = 40, whose smoothing path folds, is followed down from 5% with the smoothing over six
/// levels (37 Newton iterations measured, all attempts counted, where the stepwise damping
/// continuation it replaced took 76 and the harmonic ladder 624), its answer is checked
/// against the second c like a direct one (0.51% measured), and the run's warning and
/// headline say which way it went.
#[test]
fn lightly_damped_strip_wall_converges_through_the_damping_continuation() {
    let sets = [
        "harmonic_balance.harmonics=40",
        "damping.alpha=150",
        "damping.beta=1.0e-8",
        "stability.check=false",
    ];
    let s = common::run_summary("strip_wall", &sets, "light-strip-wall");
    let c = s.contact.as_ref().and_then(|c| c.solver.as_ref()).unwrap();
    println!(
        "{} iterations, damping path {:?}, c change {:?}",
        c.newton_iterations, c.damping_path, c.knob_check.c_change
    );
    assert_eq!(c.ladder, [40]);
    assert_eq!(c.damping_path.len(), 7, "{:?}", c.damping_path);
    assert!(c.newton_iterations <= 2 * 37, "{}", c.newton_iterations);
    let change = c.knob_check.c_change.expect("the second c converges");
    assert!(change < 2.0 * 0.0051, "{change}");
    let warned = |w: &String| w.contains("continuation in the damping");
    assert!(s.warnings.iter().any(warned), "{:?}", s.warnings);
    // The run's headline says how it got there.
    let detour = s.headline().contact_detour.unwrap_or_default();
    assert!(detour.contains("0.25% in 6 steps"), "{detour}");
}

/// TEST GOAL: the redistributed mass keeps total mass and centre of mass and takes all inertia
/// off the contact nodes of the strip.
#[test]
fn redistributed_mass_keeps_total_mass_and_centre_of_mass() {
    let p = common::scene("strip_wall", &[]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let c = model.contact.as_ref().unwrap();
    let r = c.redistribution.as_ref().expect("redistributed");
    let lumped = hbcontact::fem::assemble_mass(
        &model.mesh,
        &model.material,
        hbcontact::fem::MassKind::Lumped,
    )
    .unwrap()
    .diagonal();
    let moments = |m: &[f64]| {
        let mut t = [0.0; 3];
        for (n, x) in model.mesh.nodes.iter().enumerate() {
            t[0] += m[2 * n];
            t[1] += m[2 * n] * x[0];
            t[2] += m[2 * n] * x[1];
        }
        t
    };
    let (a, b) = (moments(&lumped), moments(&r.mass));
    assert!((a[0] - b[0]).abs() < 1e-12 * a[0]);
    assert!((a[1] / a[0] - b[1] / b[0]).abs() < 1e-12 && (a[2] / a[0] - b[2] / b[0]).abs() < 1e-12);
    for &n in &c.set.nodes {
        assert_eq!(r.mass[2 * n], 0.0);
        assert_eq!(r.mass[2 * n + 1], 0.0);
    }
    assert!(model
        .mesh
        .body_nodes()
        .iter()
        .filter(|n| !c.set.nodes.contains(n))
        .all(|&n| r.mass[2 * n] > 0.0));
    println!(
        "moved {:.3}% of the mass; polar inertia changed by {:.2e}",
        100.0 * r.moved_fraction,
        r.inertia_change
    );
}

/// TEST GOAL: harmonic balance and explicit time marching (same mesh, same redistributed
/// mass, same damping) agree on the strip in the probe's first-harmonic amplitude and in the
/// mean and first harmonic of the total contact force, more closely as H grows.
#[test]
fn strip_agrees_with_time_marching() {
    let coarse = "geometry.parameters.lc=0.0025";
    let p = common::scene("strip_wall", &[coarse]);
    let model = common::model(&p, Purpose::Transient);
    let op = &model.contact.as_ref().unwrap().operator;
    let probe_node = model.probes[0].1[0];
    let diag = model.mass_diagonal.as_ref().unwrap();
    // The probe node's x dof is the first recorded one.
    let marching = Marching::new(&model.system, diag, Some(op), &[probe_node])
        .unwrap_or_else(|e| panic!("{e}"));
    let problem = marching.problem();
    let settings = TransientSettings {
        courant: 0.8,
        periodic_tolerance: 1e-8,
        max_periods: 400,
        samples_per_period: 64,
    };
    let tr = transient::run_to_periodic(&problem, &settings, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(tr.converged, "time marching did not reach a periodic state");
    let (_, amp_tr) = mean_and_first(&tr.probe_history[0]);
    let totals: Vec<f64> = tr.total_contact_history.iter().map(|v| -v).collect();
    let (mean_tr, first_tr) = mean_and_first(&totals);
    println!(
        "transient: {} periods, {} steps/period, {:.2} s; first-harmonic amplitude {amp_tr:.6e}, mean force {mean_tr:.5e}, first harmonic {first_tr:.5e}",
        tr.periods,
        tr.steps_per_period,
        tr.wall_time.as_secs_f64()
    );
    let mut amp_errors = Vec::new();
    for h in [5usize, 10, 20, 40] {
        let q = common::scene(
            "strip_wall",
            &[coarse, &format!("harmonic_balance.harmonics={h}")],
        );
        let s = common::solve(&model, &q).unwrap_or_else(|e| panic!("H = {h}: {e}"));
        let (_, amp) = mean_and_first(&probe_series(&model, &s, 2048));
        let (mean, first) = mean_and_first(&total_force_series(&s, 2048));
        let e_amp = (amp - amp_tr).abs() / amp_tr;
        let e_mean = (mean - mean_tr).abs() / mean_tr;
        let e_first = (first - first_tr).abs() / first_tr;
        println!("H = {h:>2}: amplitude error {e_amp:.3e}, mean force error {e_mean:.3e}, first-harmonic force error {e_first:.3e}");
        amp_errors.push(e_amp);
        if h == 40 {
            // Measured 1.06e-3, 8.3e-4, 3.6e-4.
            assert!(
                e_amp < 1.6e-3,
                "amplitude within 1.6e-3 at H = 40: {e_amp:e}"
            );
            assert!(
                e_mean < 1.3e-3,
                "mean contact force within 1.3e-3 at H = 40: {e_mean:e}"
            );
            assert!(
                e_first < 6e-4,
                "first harmonic of the contact force within 6e-4 at H = 40: {e_first:e}"
            );
        }
    }
    assert!(
        amp_errors[3] < amp_errors[0],
        "agreement must tighten with H: {amp_errors:?}"
    );
}

/// TEST GOAL: a contact scene whose loads excite a harmonic above H is refused with the fix,
/// instead of silently dropping the load: by the pipeline check (a config error), and by the
/// solver when a library caller sets such an H.
#[test]
fn loads_above_h_are_refused() {
    // The pipeline check refuses it (bad input, exit code 2) …
    let path = common::root().join("pipelines/strip_wall.yaml");
    let e = hbcontact::config::load_pipeline(&path, &["harmonic_balance.harmonics=0".into()])
        .expect_err("H = 0 below a k = 1 load must not pass the pipeline check");
    assert!(
        matches!(e, hbcontact::Error::Config { .. })
            && e.to_string().contains("harmonic_balance.harmonics = 0"),
        "{e}"
    );
    // … and the solver, given such settings through the library, still refuses them.
    let mut p = common::scene("strip_wall", &[]);
    p.harmonic_balance.harmonics = 0;
    let model = common::model(&p, Purpose::HarmonicBalance);
    match common::solve(&model, &p) {
        Err(hbcontact::Error::Model(msg)) => assert!(
            msg.contains("harmonic 1") && msg.contains("raise it"),
            "{msg}"
        ),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a load above H must not be dropped"),
    }
}

/// TEST GOAL: hard cases converge: from an initial penetration (a preload, g0 < 0) through
/// contact to grazing (the gap equal to the free amplitude) and beyond, the solver converges
/// at every gap, and the mean contact force falls monotonically to zero. The complementarity
/// violation grows toward grazing (measured 5.9e-2 at g0 = −5e-8 up to 0.179 at 2.5e-7, where
/// the contact lasts a small part of the period) and is held to 0.27.
#[test]
fn penetration_to_grazing_converges_and_the_mean_force_falls_to_zero() {
    let mut previous = f64::INFINITY;
    for gap in [-5e-8, 0.0, 1e-7, 2e-7, 2.4e-7, 2.5e-7, 3e-7] {
        let p = common::scene(
            "strip_wall",
            &[
                "geometry.parameters.lc=0.0025",
                "harmonic_balance.harmonics=10",
                &format!("geometry.parameters.gap={gap:e}"),
            ],
        );
        let model = common::model(&p, Purpose::HarmonicBalance);
        let s = common::solve(&model, &p).unwrap_or_else(|e| panic!("gap {gap:e}: {e}"));
        let (mean, _) = mean_and_first(&total_force_series(&s, 512));
        let c = s.contact.as_ref().unwrap();
        println!(
            "gap {gap:>9.2e}: mean force {mean:.4e}, {} iterations, violation {:.3e}",
            c.newton.iterations, c.complementarity.violation
        );
        assert!(mean.is_finite() && c.complementarity.violation < 0.27);
        assert!(
            mean < previous || (mean == 0.0 && previous == 0.0),
            "mean force must fall with the gap: {mean} after {previous}"
        );
        previous = mean;
    }
    assert_eq!(
        previous, 0.0,
        "beyond the free amplitude the wall is never touched"
    );
}

/// TEST GOAL: Hertz on quadratic elements (`geometry.order: 2`), whose contact law acts on the
/// element corners with mortar-weighted gaps (docs/method.md, "Quadratic elements"): the
/// same checks as on linear elements, centre pressure within 0.3% of p0 at h = 2 and 1.5 mm
/// (measured +0.060% and +0.071%, +0.036% at 1 mm; the corners alone, without the middle
/// nodes in their gaps, read −1.09% at 3 mm, and the mortar gap +0.37% there).
#[test]
fn quadratic_half_disc_matches_hertz_line_contact_with_mortar_weighted_corners() {
    assert_hertz(2, &[0.002, 0.0015]);
}

/// The Newton iterations of a single run of scene `name` at `ratio` times its own first
/// natural frequency (`modes`), without the stability check.
fn iterations_at(name: &str, ratio: f64) -> usize {
    let out = common::temp_out(&format!("iterations-{}-modes", name.replace('/', "-")));
    let pipeline = format!("pipelines/{name}.yaml");
    let out_arg = out.display().to_string();
    let r = common::hbcontact(&["modes", &pipeline, "--count", "1", "--out", &out_arg]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let f1 = common::read_json(&out.join("modes.json"))["modes"][0]["frequency_hz"]
        .as_f64()
        .expect("f1");
    let frequency = format!("harmonic_balance.frequency={}", ratio * f1);
    let s = common::run_summary(
        name,
        &[&frequency, "stability.check=false"],
        &format!("iterations-{}-{ratio}", name.replace('/', "-")),
    );
    s.headline().newton_iterations.expect("a contact solve")
}

/// TEST GOAL: contact on quadratic elements costs the Newton no more than on linear ones
/// (issue #45: at most twice): the cantilever on its stop and the clamped beam between its
/// stops in quadratic elements (`scenes/*_p2`, the law on the corners with mortar-weighted
/// gaps) against their linear meshes, at 0.985, 1 and 1.015 times each mesh's own f1
/// (measured: cantilever 9, 12, 15 iterations against 8, 14, 21; clamped beam 10, 12, 142
/// against 9, 12, 559, both of the last through the harmonic ladder; with the law on every
/// node of the quadratic edges the order-2 cantilever at lc = 3.3 mm took 131 at f1).
#[test]
fn quadratic_beams_on_their_stops_converge_within_twice_the_linear_newton_iterations() {
    for scene in ["cantilever_stop", "clamped_stops"] {
        for ratio in [0.985, 1.0, 1.015] {
            let (linear, quadratic) = (
                iterations_at(&format!("scenes/{scene}"), ratio),
                iterations_at(&format!("scenes/{scene}_p2"), ratio),
            );
            println!(
                "{scene}, {ratio} f1: order 1 {linear}, order 2 {quadratic} Newton iterations"
            );
            assert!(
                quadratic <= 2 * linear,
                "{scene}: {quadratic} against {linear}"
            );
        }
    }
}
