//! Reduced frames (docs/method.md, "Reduced frames"): a reduced model of Z_k(ω)⁻¹ that a
//! sweep's frames come from instead of factorizations, checked against the factorizations.

mod common;

use faer::c64;
use hbcontact::hbm::continuation::{sweep, PointInfo, SweepOutcome, SweepSettings};
use hbcontact::hbm::frames::{self, ReducedModel};
use hbcontact::hbm::{solve_from, Solution};
use hbcontact::linalg::Factor;
use hbcontact::pipeline::Purpose;
use hbcontact::Silent;

const TWO_PI: f64 = 2.0 * std::f64::consts::PI;

fn max_norm(v: &[c64]) -> f64 {
    v.iter().map(|z| z.norm()).fold(0.0, f64::max)
}

/// The swept strip's model, its B and the reduced model over 1000–1800 Hz at H = 10.
fn strip_and_model() -> (
    hbcontact::pipeline::Model,
    hbcontact::linalg::Csc,
    ReducedModel,
) {
    let p = common::scene("strip_sweep", &[]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let b = model
        .contact
        .as_ref()
        .expect("contact")
        .operator
        .b_free
        .clone();
    let range = (TWO_PI * 1000.0, TWO_PI * 1800.0);
    let rom = ReducedModel::build(&model.system, &b, range, frames::SHIFTS_PER_HARMONIC, 10)
        .unwrap_or_else(|e| panic!("{e}"));
    (model, b, rom)
}

fn relative(a: &[c64], b: &[c64]) -> f64 {
    let diff: Vec<c64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    max_norm(&diff) / max_norm(a)
}

/// TEST GOAL: on the swept strip (1000–1800 Hz, H = 10), the reduced model built from real
/// shifts gives every harmonic's contact compliance G_k = B Z_k⁻¹ Bᵀ and the loaded
/// harmonic's linear gap B z_1 within 1e-7 (relative, largest entry) of the exact sparse
/// factorization, at frequencies that are none of its shifts: a Galerkin projection that
/// interpolates the resolvent at the shifts (Grimme, Krylov projection methods for model
/// reduction, 1997). Measured: at most 2.1e-8 (G_0), 1.2e-9 elsewhere.
#[test]
fn a_reduced_model_gives_the_compliance_and_linear_gap_of_the_factorizations() {
    let (mut model, b, rom) = strip_and_model();
    let h = 10;
    assert!(
        rom.dim() < model.system.free_count() / 4,
        "r = {}",
        rom.dim()
    );
    let mut worst: f64 = 0.0;
    for hz in [1003.7, 1234.5, 1361.6, 1500.1, 1666.6, 1799.0] {
        model.system.omega = TWO_PI * hz;
        for k in 0..=h {
            let exact = model
                .system
                .factor(k, Some(&b))
                .unwrap_or_else(|e| panic!("{e}"));
            let load = model.system.load(k);
            let reduced = rom
                .factor(&model.system, k, &load)
                .map(Factor::Modal)
                .expect("regular on the space");
            let err = relative(&exact.compliance(&b), &reduced.compliance(&b));
            assert!(err < 1e-7, "G_{k} at {hz} Hz: {err:.2e}");
            worst = worst.max(err);
            if max_norm(&load) > 0.0 {
                let gap = |f: &Factor| b.mul_complex(&f.solve(&load));
                let err = relative(&gap(&exact), &gap(&reduced));
                assert!(err < 1e-7, "B z_{k} at {hz} Hz: {err:.2e}");
            }
        }
    }
    println!("r = {}, worst G error {worst:.2e}", rom.dim());
}

/// TEST GOAL: the sweep's ∂g/∂ω on a reduced frame, computed on the reduced space alone
/// ((a'θ + b') ∘ y with no product with K or M), equals the exact rate
/// −B Z_k⁻¹ (∂Z_k/∂ω u_k) with u_k = Z_k⁻¹(f_k + Bᵀλ_k) from the factorization, to 1e-6, for
/// an arbitrary λ at a frequency between the shifts.
#[test]
fn the_reduced_frames_gap_rate_equals_the_factored_one() {
    let (mut model, b, rom) = strip_and_model();
    model.system.omega = TWO_PI * 1420.3;
    let system = &model.system;
    for k in [1, 2, 7] {
        let lam: Vec<c64> = (0..b.nrows)
            .map(|i| c64::new(1e3 * (1.0 + i as f64), -2e2 * i as f64))
            .collect();
        let exact = system.factor(k, Some(&b)).unwrap_or_else(|e| panic!("{e}"));
        let rhs: Vec<c64> = system
            .load(k)
            .iter()
            .zip(b.mul_transpose_complex(&lam))
            .map(|(f, l)| f + l)
            .collect();
        let u = exact.solve(&rhs);
        let motion = vec![c64::new(0.0, 0.0); system.dofs.prescribed.len()];
        let rate = system.omega_derivative(k, &u, &motion);
        let expected: Vec<c64> = b
            .mul_complex(&exact.solve(&rate))
            .iter()
            .map(|v| -v)
            .collect();
        let reduced = rom
            .factor(system, k, &system.load(k))
            .expect("regular on the space");
        let got = reduced.contact_rate(&lam, system.pencil_rate(k), None);
        let err = relative(&expected, &got);
        assert!(err < 1e-6, "k = {k}: {err:.2e}");
    }
}

/// One sweep of the strip (1000–1800 Hz, H = 10) through the solver with the reduced model's
/// shifts at `frequencies` frequencies (0: every frame factored), and its largest departure
/// from the factorizations: every point re-solved on factored frames at its ω from its own
/// multipliers (`hbm::solve_from`), the largest change of a gap coefficient relative to the
/// largest gap coefficient of the curve.
fn strip_sweep(frequencies: usize) -> (SweepOutcome, f64) {
    let p = common::scene("strip_sweep", &[]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let spec = p.sweep.as_ref().expect("a sweep block");
    let settings = SweepSettings {
        model_frequencies: frequencies,
        ..hbcontact::sweep::settings(spec, None)
    };
    let mut system = model.system.clone();
    let op = &model.contact.as_ref().expect("contact").operator;
    let mut points = Vec::new();
    let mut on_point = |info: &PointInfo, solution: &Solution| {
        points.push((info.omega, solution.contact.clone().expect("contact")));
        Ok(())
    };
    let hb = common::settings(&p);
    let outcome = sweep(
        &mut system,
        Some(op),
        &hb,
        &settings,
        &Silent,
        &mut on_point,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(outcome.stopped.is_none(), "{:?}", outcome.stopped);
    let scale = points
        .iter()
        .flat_map(|(_, c)| c.gaps.iter())
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    let mut worst: f64 = 0.0;
    for (omega, point) in &points {
        system.omega = *omega;
        let exact = solve_from(&system, op, &hb, point, &Silent).unwrap_or_else(|e| panic!("{e}"));
        let gaps = &exact.contact.expect("contact").gaps;
        let d = gaps
            .iter()
            .zip(&point.gaps)
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        worst = worst.max(d / scale);
    }
    (outcome, worst)
}

/// TEST GOAL: a sweep's reduced frames give the points the factorizations give. On the strip
/// sweep (1762 dofs, 9 contact nodes, H = 10, both folds) the default model (shifts at three
/// frequencies) gives most frames and keeps every point within the backward error 1e-10
/// (measured: 242 reduced frames for 150 points, one point re-solved, 8.6e-11). Every point,
/// re-solved on factorizations at its ω from its own multipliers, moves about as much as the
/// factored curve's own points do, which is the corrector's tolerance (measured 3.9e-7 of the
/// largest gap coefficient for both; with flexible GMRES's round-off the default model's
/// curve takes other points, and its worst moves 5.1e-7: which point of a curve sits nearest
/// the tolerance moves with round-off; asserted ≤ 1.5× the factored curve's + 1e-8 and
/// < 8e-7),
/// and the folds lie where the factored curve's do to the corrector's tolerance (a residual
/// perturbation ε moves a fold by O(ε): measured 1.0e-8 relative for the default model and
/// 4.4e-8 for the poor one, whose points come from other frames; asserted < 9e-8). A
/// deliberately poor model (shifts at the start frequency only) fails its check at points far
/// from its shifts, re-solves them on factorizations and learns from them, and gives points as
/// good (measured: 10 re-solved, r grows to 129, 4.0e-7). The check is what makes the model
/// safe: a kept point passed the test a factorization's solve passes.
#[test]
fn reduced_frames_give_the_factored_points_and_a_poor_model_is_caught_and_mended() {
    let (factored, exact_error) = strip_sweep(0);
    assert_eq!(factored.reduced.frames, 0);
    println!(
        "factored: {} points, re-solved {exact_error:.1e}",
        factored.points
    );
    for (name, frequencies) in [("default", frames::SHIFTS_PER_HARMONIC), ("poor", 1)] {
        let (outcome, error) = strip_sweep(frequencies);
        let r = &outcome.reduced;
        let folds = |o: &SweepOutcome| o.folds.iter().map(|f| f.omega / TWO_PI).collect::<Vec<_>>();
        println!(
            "{name}: {} points, r = {}, {} reduced frames, {} replaced, largest kept error {:.1e}, \
             re-solved {error:.1e}; folds {:?} (factored {:?})",
            outcome.points, r.dimension, r.frames, r.replaced, r.largest_error, folds(&outcome), folds(&factored)
        );
        assert!(r.dimension > 0 && r.frames > outcome.points / 2, "{r:?}");
        assert!(r.largest_error <= frames::BACKWARD_TOLERANCE, "{r:?}");
        assert!(
            error < 8e-7 && error <= 1.5 * exact_error + 1e-8,
            "{name}: {error:.2e}"
        );
        assert_eq!(outcome.folds.len(), factored.folds.len());
        for (a, b) in outcome.folds.iter().zip(&factored.folds) {
            assert!((a.omega - b.omega).abs() < 9e-8 * b.omega, "{a:?} {b:?}");
        }
        if name == "poor" {
            assert!(r.replaced > 0, "the poor model passed every check: {r:?}");
        }
    }
}
