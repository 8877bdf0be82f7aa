//! Reduced frames (docs/method.md, "Reduced frames"): a reduced model of Z_k(ω)⁻¹ that a
//! sweep's frames come from instead of factorizations, checked against the factorizations.

mod common;

use faer::c64;
use hbcontact::hbm::frames::ReducedModel;
use hbcontact::linalg::Factor;
use hbcontact::pipeline::Purpose;

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
    let rom = ReducedModel::build(&model.system, &b, (TWO_PI * 1000.0, TWO_PI * 1800.0), 10)
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
