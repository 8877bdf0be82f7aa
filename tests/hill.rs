//! Floquet multipliers by Hill's method on the harmonic-balance model itself (`hbm::hill`,
//! the `stability.method: floquet` verdict of Fourier states), held against closed forms, an
//! independent time integration, its own dense eigenvalues, and the folds of a sweep.

mod common;

use faer::c64;
use hbcontact::fem::modes::lowest_modes;
use hbcontact::hbm::floquet::Crossing;
use hbcontact::hbm::hill::{Eigen, HillModel, SampledLaw};
use hbcontact::pipeline::stability::Verdict;
use hbcontact::pipeline::Purpose;
use nalgebra::DMatrix;

/// The multiplier of largest modulus of a 2 × 2 monodromy.
fn leading(phi: [[f64; 2]; 2]) -> c64 {
    let (tr, det) = (
        phi[0][0] + phi[1][1],
        phi[0][0] * phi[1][1] - phi[0][1] * phi[1][0],
    );
    let disc = c64::new(tr * tr - 4.0 * det, 0.0).sqrt();
    let (a, b) = (
        (c64::new(tr, 0.0) + disc) * 0.5,
        (c64::new(tr, 0.0) - disc) * 0.5,
    );
    if a.norm() >= b.norm() {
        a
    } else {
        b
    }
}

/// The bilinear oscillator as a harmonic-balance state: one mode (θ = 1, gap E = 2, α =
/// 0.02) and a static rest G = 4/k_c, so that a closed node adds k_c = 8 to the stiffness; the
/// node closed where cos ωt > cos(0.3π) (g = cos ωt − cos 0.3π, λ = 0). Returns the compliance
/// G_k = E²/(θ − k²ω² + ikωα) + G, the law's coefficients and ω.
fn bilinear_state(h: usize) -> (Vec<Vec<c64>>, Vec<f64>, Vec<f64>, f64) {
    let (theta, e, alpha, rest) = (1.0, 2.0, 0.02, 4.0 / 8.0);
    let omega = 2.0 / 0.7;
    let compliance = (0..=h)
        .map(|k| {
            let kw = k as f64 * omega;
            vec![c64::new(e * e, 0.0) / c64::new(theta - kw * kw, kw * alpha) + rest]
        })
        .collect();
    let mut gaps = vec![0.0; 2 * h + 1];
    gaps[0] = -(0.3 * std::f64::consts::PI).cos();
    gaps[1] = 1.0;
    (compliance, vec![0.0; 2 * h + 1], gaps, omega)
}

/// TEST GOAL: on the bilinear oscillator (k = 1 open, 9 closed for 30% of the period T =
/// 0.7π, α = 0.02: inside its principal parametric resonance), Hill's method on the
/// harmonic-balance model at H = 40 (N = 16H samples) finds the leading multiplier of a fine
/// Runge–Kutta integration of the piecewise-linear equation (closed over the same samples'
/// share of the period) within 1%, real below −1, a period doubling; and it converges: at
/// H = 20 it is farther off than at H = 40.
#[test]
fn hill_multipliers_of_the_bilinear_oscillator_match_an_independent_integration() {
    let model = HillModel::from_parts(vec![1.0], DMatrix::from_element(1, 1, 2.0), (0.02, 0.0));
    let mut errors = Vec::new();
    for h in [20, 40] {
        let (compliance, lambda, gaps, omega) = bilinear_state(h);
        let samples = 16 * h;
        let law = SampledLaw {
            harmonics: h,
            samples,
            c: 1.0,
            multipliers: &lambda,
            gaps: &gaps,
        };
        let m = model
            .multipliers_of(&compliance, &law, omega, Eigen::Dense)
            .unwrap();
        // The samples closed: t_n = nT/N with cos(2πn/N) > cos(0.3π), each holding T/N.
        let closed = (0..samples)
            .filter(|&n| {
                (2.0 * std::f64::consts::PI * n as f64 / samples as f64).cos()
                    > (0.3 * std::f64::consts::PI).cos()
            })
            .count();
        let period = 2.0 * std::f64::consts::PI / omega;
        let share = closed as f64 / samples as f64;
        let reference = leading(common::rk4_monodromy(
            0.02,
            &[(9.0, share * period), (1.0, (1.0 - share) * period)],
            20_000,
        ));
        let mu = m.leading();
        let error = (mu - reference).norm() / reference.norm();
        println!("H = {h}: Hill {mu:?}, integration {reference:?}, error {error:.2e}");
        assert!(
            reference.re < -1.0 && reference.im.abs() < 1e-9,
            "{reference:?}"
        );
        errors.push(error);
        if h == 40 {
            assert!(error < 0.01, "H = 40: {error}");
            assert_eq!(m.crossing(), Crossing::PeriodDoubling);
        }
    }
    assert!(errors[1] < errors[0], "no convergence in H: {errors:?}");
}

/// TEST GOAL: with the wall out of reach no node closes and Hill's multipliers are those of
/// the damped modes kept, e^{(−c/2 ± i√(ω² − c²/4))T} with c = α + βω², for the lowest modes
/// computed independently by `lowest_modes`, to 1e-6, by dense eigenvalues and by shift-invert
/// Arnoldi alike (the largest modulus the same to 1e-6); the leading multiplier's Floquet
/// vector is the least damped mode's shape (MAC 1 to 1e-9), constant over the period.
#[test]
fn hill_multipliers_out_of_reach_are_the_damped_modes() {
    let sets = [
        "geometry.parameters.gap=0.05",
        "contact.search_distance=1.0",
        "harmonic_balance.harmonics=5",
    ];
    let p = common::scene("strip_wall", &sets);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
    let contact = solution.contact.as_ref().unwrap();
    let b = &model.contact.as_ref().unwrap().operator.b_free;
    let hill = HillModel::new(&model.system, b, 8).unwrap();
    let compliance = contact.compliance.as_ref().expect("the solve keeps G_k");
    let law = SampledLaw::of(contact);
    let dense = hill
        .multipliers_of(compliance, &law, solution.omega, Eigen::Dense)
        .unwrap();
    let arnoldi = hill
        .multipliers_of(compliance, &law, solution.omega, Eigen::Arnoldi)
        .unwrap();
    let (alpha, beta) = model.system.rayleigh.unwrap();
    let period = solution.period();
    for (w2, _) in lowest_modes(&model.system.k_ff, &model.system.m_ff, 4, 0.0).unwrap() {
        let c = alpha + beta * w2;
        let expected = c64::new(
            (-0.5 * c * period).exp() * ((w2 - 0.25 * c * c).sqrt() * period).cos(),
            (-0.5 * c * period).exp() * ((w2 - 0.25 * c * c).sqrt() * period).sin(),
        );
        let nearest = dense
            .values
            .iter()
            .map(|mu| (mu - expected).norm())
            .fold(f64::INFINITY, f64::min);
        println!(
            "ω² = {w2:e}: the nearest multiplier {:.1e} away (relative)",
            nearest / expected.norm()
        );
        assert!(
            nearest < 1e-6 * expected.norm(),
            "ω² = {w2:e}: {expected:?} not among {:?}",
            dense.values
        );
    }
    let (a, d) = (arnoldi.leading().norm(), dense.leading().norm());
    assert!((a - d).abs() < 1e-6 * d, "Arnoldi {a} against dense {d}");
    // The leading multiplier is the least damped mode's (c = α + βω² grows with ω): its Floquet
    // vector is that mode's shape, constant over the period.
    let first = &lowest_modes(&model.system.k_ff, &model.system.m_ff, 1, 0.0).unwrap()[0].1;
    for (how, m) in [("dense", &dense), ("Arnoldi", &arnoldi)] {
        let v = m.leading_vector.as_ref().expect("a Floquet vector");
        let coefficients = v.coefficients();
        let p0 = &coefficients[0];
        let dot: c64 = p0.iter().zip(first).map(|(p, f)| p * *f).sum();
        let norms = p0.iter().map(|p| p.norm_sqr()).sum::<f64>() * dot_real(first, first);
        let mac = dot.norm_sqr() / norms;
        let rest = (coefficients[1..].iter().flatten())
            .map(|p| p.norm())
            .fold(0.0, f64::max);
        println!("{how}: MAC with mode 1 {mac:.12}, other coefficients up to {rest:.1e}");
        assert!(1.0 - mac < 1e-9, "{how}: MAC {mac}");
        assert!(rest < 1e-6, "{how}: {rest}");
    }
}

fn dot_real(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// TEST GOAL: near a period doubling two copies of one exponent are equally centred
/// (s and s − iω, |κ| ≈ ½), and the copies kept must not depend on how the eigenvalues are
/// found: on the coarse strip at 1030 Hz, H = 10 (Hill order 546), the dense eigenvalues and
/// shift-invert Arnoldi give the same leading multiplier, and it is the near-period-doubling
/// one (argument near 180°), which the H = 20 and H = 40 states also lead with. Taking the
/// 2r most centred copies instead dropped it (|μ| 0.71 at 0° against 0.95 at 178°).
#[test]
fn hill_dense_and_arnoldi_keep_the_same_copies_near_a_period_doubling() {
    let p = common::scene(
        "strip_sweep",
        &[
            "geometry.parameters.lc=0.025",
            "harmonic_balance.frequency=1030",
        ],
    );
    let model = common::model(&p, Purpose::HarmonicBalance);
    let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
    let contact = solution.contact.as_ref().unwrap();
    let b = &model.contact.as_ref().unwrap().operator.b_free;
    let full = HillModel::new(&model.system, b, hbcontact::hbm::hill::MODES).unwrap();
    let hill = full.truncated(
        full.modes_for(solution.omega, contact.harmonics),
        solution.omega,
    );
    let compliance = contact.compliance.as_ref().expect("the solve keeps G_k");
    let law = SampledLaw::of(contact);
    let [dense, arnoldi] = [Eigen::Dense, Eigen::Arnoldi].map(|eigen| {
        hill.multipliers_of(compliance, &law, solution.omega, eigen)
            .unwrap()
            .leading()
    });
    // The same multiplier or its conjugate (either member of the pair may lead).
    assert!(
        (dense - arnoldi)
            .norm()
            .min((dense - arnoldi.conj()).norm())
            < 1e-6 * dense.norm(),
        "dense {dense} against Arnoldi {arnoldi}"
    );
    let degrees = dense.im.atan2(dense.re).abs().to_degrees();
    assert!(
        degrees > 170.0 && dense.norm() > 0.9,
        "the leading multiplier {dense} (|μ| {}, {degrees:.1}°) is not the near-period-doubling one",
        dense.norm()
    );
}

/// TEST GOAL: along the strip's stiffened resonance (5% damping, H = 10, coarse mesh) Hill's
/// verdict changes at the folds the sweep locates, because its multiplier +1 is exactly a
/// singular Jacobian of the harmonic-balance solve: the points approaching the upper fold are
/// stable, every point of the branch between the upper and the lower fold is unstable (a
/// multiplier above 1), and the points past the lower fold are stable again. The row on each
/// side of a fold is left out: the fold lies within that step, on either side of the row.
#[test]
fn hill_verdict_changes_at_the_folds_of_the_strip_sweep() {
    use hbcontact::pipeline::RunOptions;
    use hbcontact::sweep;
    let p = common::scene("strip_sweep", &["geometry.parameters.lc=0.025"]);
    let out = common::temp_out("hill-sweep");
    let options = RunOptions {
        out: Some(out),
        ..Default::default()
    };
    let s = sweep::run(&p, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"))
        .summary;
    let upper = s
        .folds
        .iter()
        .find(|f| f.frequency_hz > 1650.0)
        .expect("the upper fold");
    let lower = s
        .folds
        .iter()
        .find(|f| f.after > upper.after)
        .expect("the lower fold");
    let row = |i: usize| &s.rows[i];
    for i in upper.after - 4..upper.after {
        assert_eq!(
            row(i).stable,
            Some(true),
            "before the upper fold: {:?}",
            row(i)
        );
    }
    for i in upper.after + 2..lower.after {
        let r = row(i);
        assert_eq!(r.stable, Some(false), "between the folds: {r:?}");
        assert!(r.multiplier.is_some_and(|mu| mu > 1.0), "{r:?}");
    }
    for i in lower.after + 2..(lower.after + 5).min(s.rows.len()) {
        assert_eq!(
            row(i).stable,
            Some(true),
            "past the lower fold: {:?}",
            row(i)
        );
    }
}

/// The text boxes of an SVG's labels drawn from their left end (`text-anchor="start"`, the
/// mark labels): (left, top, right, bottom), 0.6 em per character.
fn start_anchored_labels(svg: &str) -> Vec<(String, [f64; 4])> {
    let mut out = Vec::new();
    for piece in svg.split("<text ").skip(1) {
        let (attrs, rest) = piece.split_once('>').unwrap_or((piece, ""));
        if !attrs.contains("text-anchor=\"start\"") {
            continue;
        }
        let attr = |name: &str| -> f64 {
            let key = format!("{name}=\"");
            attrs
                .split(&key)
                .nth(1)
                .and_then(|v| v.split('"').next())
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN)
        };
        let text = rest
            .split("</text>")
            .next()
            .unwrap_or("")
            .trim()
            .to_string();
        let (x, y, size) = (attr("x"), attr("y"), attr("font-size"));
        let width = 0.6 * size * text.chars().count() as f64;
        out.push((text, [x, y, x + width, y + size]));
    }
    out
}

/// TEST GOAL: along the coarse strip sweep (H = 10, every point judged by Hill's method) the
/// verdict changes only at a located fold or at a bifurcation listed in sweep.json, each
/// located between its two rows and classified by its leading multiplier: a real multiplier
/// through +1 only where the curve turns (the folds, and kinks of the sampled law), period
/// doublings at arg μ = 180°, Neimark–Sacker pairs off the real axis with their second
/// frequency |arg μ|/(2π)·f. sweep.csv carries each row's argument and crossing, and the
/// plot's labels do not overlap.
#[test]
fn strip_sweep_verdict_changes_only_at_located_folds_and_classified_bifurcations() {
    let p = common::scene("strip_sweep", &["geometry.parameters.lc=0.025"]);
    let out = common::temp_out("hill-bifurcations");
    let options = hbcontact::pipeline::RunOptions {
        out: Some(out.clone()),
        ..Default::default()
    };
    let s = hbcontact::sweep::run(&p, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"))
        .summary;
    let json = common::read_json(&out.join("sweep.json"));
    let listed = json["bifurcations"].as_array().expect("bifurcations").len();
    assert_eq!(listed, s.bifurcations.len());
    assert!(
        !s.bifurcations.is_empty(),
        "the strip's upper branch has some"
    );
    let decided: Vec<_> = s.rows.iter().filter(|r| r.stable.is_some()).collect();
    assert!(
        decided.len() * 10 >= s.rows.len() * 9,
        "nearly every row judged"
    );
    let mut away_from_folds = 0;
    for w in decided.windows(2).filter(|w| w[0].stable != w[1].stable) {
        let (a, b) = (w[0].index, w[1].index);
        let at_fold = s.folds.iter().any(|f| a <= f.after && f.after <= b);
        let listed = s.bifurcations.iter().any(|x| x.between == [a, b]);
        assert!(
            at_fold ^ listed,
            "rows {a}–{b}: fold {at_fold}, listed {listed}"
        );
        away_from_folds += usize::from(!at_fold);
    }
    assert_eq!(away_from_folds, s.bifurcations.len());
    for x in &s.bifurcations {
        let row = |i: usize| s.rows.iter().find(|r| r.index == i).expect("row");
        let (fa, fb) = (
            row(x.between[0]).frequency_hz,
            row(x.between[1]).frequency_hz,
        );
        assert!(
            x.frequency_hz >= fa.min(fb) && x.frequency_hz <= fa.max(fb),
            "{x:?}"
        );
        assert!(x.multiplier > 1.0, "{x:?}");
        use hbcontact::sweep::bifurcations::BifurcationKind as K;
        match x.kind {
            K::PeriodDoubling => assert!((x.argument_deg - 180.0).abs() < 0.1, "{x:?}"),
            K::NeimarkSacker => {
                assert!(x.argument_deg > 0.05 && x.argument_deg < 179.95, "{x:?}");
                let second = x.argument_deg / 360.0 * x.frequency_hz;
                let given = x.new_frequency_hz.expect("its frequency");
                assert!((given - second).abs() < 1e-9 * second, "{x:?}");
            }
            K::BranchPoint => panic!("a real +1 crossing where the curve does not turn: {x:?}"),
            K::Kink | K::Grazing | K::Unclassified => {}
        }
    }
    let csv = std::fs::read_to_string(out.join("sweep.csv")).expect("sweep.csv");
    let header = csv.lines().next().unwrap_or("");
    assert!(
        header.contains(",stable,multiplier,argument_deg,crossing,"),
        "{header}"
    );
    let svg = std::fs::read_to_string(out.join("sweep.svg")).expect("sweep.svg");
    let labels = start_anchored_labels(&svg);
    assert!(labels
        .iter()
        .any(|(t, _)| t.starts_with("NS ") || t.starts_with("PD ")));
    for (i, (t, a)) in labels.iter().enumerate() {
        for (u, b) in &labels[i + 1..] {
            let overlap = a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
            assert!(!overlap, "'{t}' {a:?} overlaps '{u}' {b:?}");
        }
    }
}

/// TEST GOAL: a run's Hill model keeps the modes below 10ω and the next one above, each the
/// mode `lowest_modes` finds (ω² to 1e-8, the next one above to 1e-6), none missing below
/// the last; the resonance check reads from them the same natural frequencies nearest ω that
/// its own shift-invert finds (to 5e-7, that search's own accuracy), and the same Hill
/// verdict follows from them as from the 24 lowest modes.
#[test]
fn a_runs_hill_modes_are_every_mode_below_their_last_and_serve_the_resonance_check() {
    let p = common::scene("strip_wall", &[]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let omega = model.system.omega;
    let band = HillModel::band_modes(&model.system, omega).unwrap();
    let all = lowest_modes(&model.system.k_ff, &model.system.m_ff, band.len() + 4, 0.0).unwrap();
    let bound = (hbcontact::hbm::hill::BAND * omega).powi(2);
    let below = all.iter().filter(|(w2, _)| *w2 <= bound).count();
    println!(
        "{} modes returned, {below} below 10ω, the last at {:.1} Hz",
        band.len(),
        band.last().unwrap().0.sqrt() / (2.0 * std::f64::consts::PI)
    );
    assert_eq!(band.len(), below.max(hbcontact::hbm::hill::MIN_MODES) + 1);
    // Every mode kept to 1e-8; the last, which only bounds them, to modes_near's 1e-6.
    for (i, ((w2, _), (reference, _))) in band.iter().zip(&all).enumerate() {
        let tolerance = if i + 1 == band.len() { 1e-6 } else { 1e-8 };
        assert!(
            (w2 - reference).abs() < tolerance * reference,
            "mode {i}: {w2} against {reference}"
        );
    }
    let (own, _) = hbcontact::pipeline::resonance::check(&model, None).unwrap();
    let (shared, _) = hbcontact::pipeline::resonance::check(&model, Some(&band)).unwrap();
    for (a, b) in own.harmonics.iter().zip(&shared.harmonics) {
        assert_eq!(a.nearest_modes.len(), b.nearest_modes.len());
        for (x, y) in a.nearest_modes.iter().zip(&b.nearest_modes) {
            let (x, y) = (x.frequency_hz, y.frequency_hz);
            assert!(
                (x - y).abs() < 5e-7 * x,
                "harmonic {}: {x} Hz against {y} Hz",
                a.k
            );
        }
    }
    // The verdict on the band's modes is the verdict on the 24 lowest.
    let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
    let contact = solution.contact.as_ref().unwrap();
    let b = &model.contact.as_ref().unwrap().operator.b_free;
    let verdict = |hill: &HillModel| {
        hbcontact::pipeline::stability::by_hill(hill, contact, solution.omega).unwrap()
    };
    let on_band = verdict(&HillModel::with_modes(&model.system, b, &band).unwrap());
    let on_24 = verdict(&HillModel::new(&model.system, b, hbcontact::hbm::hill::MODES).unwrap());
    let (x, y) = (on_band.multiplier.unwrap(), on_24.multiplier.unwrap());
    println!("|μ| {x:.10} on the band's modes, {y:.10} on the 24 lowest");
    assert!((x - y).abs() < 1e-8, "{x} against {y}");
    assert_eq!(on_band.verdict, on_24.verdict);
    // A harmonic above the last mode is not read from them.
    let last = band.last().unwrap().0.sqrt();
    let mut above = model;
    above.system.omega = 1.1 * last;
    let (far, _) = hbcontact::pipeline::resonance::check(&above, Some(&band)).unwrap();
    let (far_own, _) = hbcontact::pipeline::resonance::check(&above, None).unwrap();
    let hz = |c: &hbcontact::pipeline::resonance::ResonanceCheck| -> Vec<f64> {
        (c.harmonics.iter().flat_map(|h| &h.nearest_modes))
            .map(|m| m.frequency_hz)
            .collect()
    };
    assert_eq!(hz(&far), hz(&far_own));
    assert!(hz(&far)
        .iter()
        .any(|&f| 2.0 * std::f64::consts::PI * f > last));
}

/// TEST GOAL: where the dynamic modes lie far above the drive, the real shift's Arnoldi finds
/// only copies off centre, and the strips of the modes' own frequencies (complex shifts
/// 0.2ω + imω) find the centred exponents: the leading multiplier is the dense eigenvalues'
/// on the blade against its casing at H = 20 (first mode 1.23ω), the elastic casing (drive
/// 700 Hz) and the lobed casing (drive 100 Hz, modes 8.6ω and above), to 1e-9. Before
/// 2026-11-29 these took the Hill matrix's every eigenvalue (orders 410 and 488 on the
/// casings, 0.10–0.13 s a run).
#[test]
fn the_modes_strips_find_the_dense_leading_multiplier_where_the_modes_lie_far_above_the_drive() {
    for (scene, set) in [
        ("blade_casing", &["harmonic_balance.harmonics=20"][..]),
        ("blade_elastic_casing", &[][..]),
        ("blade_lobed_casing", &[][..]),
    ] {
        let p = common::scene(scene, set);
        let model = common::model(&p, Purpose::HarmonicBalance);
        let solution = common::solve(&model, &p).unwrap_or_else(|e| panic!("{e}"));
        let contact = solution.contact.as_ref().unwrap();
        let b = &model.contact.as_ref().unwrap().operator.b_free;
        let band = HillModel::band_modes(&model.system, solution.omega).unwrap();
        let full = HillModel::with_modes(&model.system, b, &band).unwrap();
        let hill = full.truncated(
            full.modes_for(solution.omega, contact.harmonics),
            solution.omega,
        );
        let compliance = contact.compliance.as_ref().expect("the solve keeps G_k");
        let law = SampledLaw::of(contact);
        let clock = std::time::Instant::now();
        let auto = hill.multipliers_of(compliance, &law, solution.omega, Eigen::Auto);
        let auto_seconds = clock.elapsed().as_secs_f64();
        let auto = auto.unwrap().leading();
        let arnoldi = hill.multipliers_of(compliance, &law, solution.omega, Eigen::Arnoldi);
        let clock = std::time::Instant::now();
        let dense = hill.multipliers_of(compliance, &law, solution.omega, Eigen::Dense);
        let dense_seconds = clock.elapsed().as_secs_f64();
        let dense = dense.unwrap().leading();
        println!(
            "{scene}: r = {}, H = {}: |μ| {:.12} (strips, {auto_seconds:.4} s) against {:.12} (dense, {dense_seconds:.4} s)",
            hill.dim(),
            contact.harmonics,
            auto.norm(),
            dense.norm()
        );
        assert!(
            arnoldi.is_err(),
            "{scene}: the real shift found a centred copy"
        );
        assert!(
            (auto - dense).norm().min((auto - dense.conj()).norm()) < 1e-9 * dense.norm().max(1e-3),
            "{scene}: strips {auto} against dense {dense}"
        );
    }
}

/// TEST GOAL: a contact state that H resolves has one Hill verdict whatever H it is solved
/// at: the shipped impact scenes (the strip against its wall, 5% and 0.5% damped, the strip
/// on two other meshes, and the blade rubbing its casing) at H = 10, 20, 30 and 40 are all
/// stable, their leading |μ| within 0.05 of each other. (Along the upper branch of the strip
/// sweep the H = 10 and H = 40 states themselves differ, their peak contact forces by 2–56%,
/// and so may their verdicts: docs/method.md §15.)
#[test]
fn a_resolved_contact_state_gets_the_same_hill_verdict_at_every_h() {
    let cases = [
        ("strip_wall", None),
        ("strip_wall", Some("geometry.parameters.lc=0.025")),
        ("strip_wall", Some("geometry.parameters.lc=0.00625")),
        ("reference_strip", None),
        ("blade_casing", None),
    ];
    for (i, (scene, mesh)) in cases.into_iter().enumerate() {
        let mut moduli = Vec::new();
        for h in [10, 20, 30, 40] {
            let set = format!("harmonic_balance.harmonics={h}");
            let sets: Vec<&str> = [Some(set.as_str()), mesh].into_iter().flatten().collect();
            let s = common::run_summary(scene, &sets, &format!("hill-every-h-{i}-{h}"));
            let st = s.stability.expect("a verdict");
            println!(
                "{scene} {mesh:?} H = {h}: {:?} |μ| = {:?}",
                st.verdict, st.multiplier
            );
            assert_eq!(
                st.verdict,
                Verdict::Stable,
                "{scene} {mesh:?} H = {h}: {}",
                st.reason
            );
            moduli.push(st.multiplier.expect("a Floquet multiplier"));
        }
        let lo = moduli.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = moduli.iter().copied().fold(0.0, f64::max);
        assert!(hi - lo < 0.05, "{scene} {mesh:?}: |μ| {moduli:?}");
    }
}
