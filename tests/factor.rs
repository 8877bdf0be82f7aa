//! The kept complex symmetric LDLᵀ (`linalg::Factor::Ldlt`, `src/linalg/schur/`) against
//! faer's pivoting sparse LU on shipped scenes: its solves, its contact compliance G_k, and
//! the fallback to the LU when a pivot fails.

mod common;

use faer::c64;
use hbcontact::hbm::system::{FactorOptions, FactorPath};
use hbcontact::hbm::System;
use hbcontact::linalg::{Csc, Factor};
use hbcontact::pipeline::Purpose;

fn on(path: FactorPath) -> FactorOptions {
    FactorOptions {
        path,
        ..Default::default()
    }
}

fn factor(system: &System, k: usize, b: Option<&Csc>, options: FactorOptions) -> Factor {
    system
        .factor_with(k, b, &options)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// max |a − b| / max |b|.
fn relative_difference(a: &[c64], b: &[c64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, z| m.max(z.norm()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).norm()))
        / scale
}

/// The load of harmonic k, or a fixed vector where the scene does not load it.
fn right_hand_side(system: &System, k: usize) -> Vec<c64> {
    let load = system.load(k);
    if load.iter().any(|z| z.norm() > 0.0) {
        return load;
    }
    (0..system.free_count())
        .map(|i| c64::new(((i * 7) % 11) as f64 - 5.0, ((i * 3) % 5) as f64))
        .collect()
}

/// The strip against the wall and the half-disc on its flat: their model and contact B.
fn scenes() -> Vec<(String, hbcontact::pipeline::Model)> {
    ["reference_strip", "half_disc"]
        .iter()
        .map(|name| {
            let p = common::scene(name, &[]);
            (
                name.to_string(),
                common::model(&p, Purpose::HarmonicBalance),
            )
        })
        .collect()
}

/// TEST GOAL: Z_k x by `System::apply` (one pass over the pattern K and M share, reading
/// row j as column j of the symmetric matrices) equals the column-by-column product with the
/// assembled Z_k = re + i·im of `System::dynamic_stiffness`, to round-off, on the strip and
/// the half-disc, statically and at two harmonics.
#[test]
fn the_one_pass_dynamic_stiffness_product_equals_the_assembled_matrixs() {
    for (name, model) in scenes() {
        let system = &model.system;
        let x: Vec<c64> = (0..system.free_count())
            .map(|i| c64::new(((i * 7) % 11) as f64 - 5.0, ((i * 3) % 5) as f64))
            .collect();
        for k in [0usize, 1, 3] {
            let (re, im) = system.dynamic_stiffness(k);
            let mut reference = vec![c64::new(0.0, 0.0); re.nrows];
            for (j, xj) in x.iter().enumerate() {
                for p in re.col_ptr[j]..re.col_ptr[j + 1] {
                    let z = c64::new(re.values[p], im.as_ref().map_or(0.0, |v| v[p]));
                    reference[re.row_idx[p]] += z * xj;
                }
            }
            let diff = relative_difference(&system.apply(k, &x), &reference);
            assert!(diff < 1e-13, "{name}, k = {k}: {diff:e}");
        }
    }
}

/// TEST GOAL: the LDLᵀ solve of Z_k x = f equals the pivoting LU's to round-off, with the
/// contact normals kept last and without contact (plain LDLᵀ), on the strip and the
/// half-disc, statically (real) and at two harmonics (complex, indefinite above the first
/// natural frequency). Reference: faer's sparse LU with partial pivoting.
#[test]
fn ldlt_solves_equal_the_lu_solves_to_round_off() {
    for (name, model) in scenes() {
        let b = contact_rows(&model);
        for k in [0usize, 1, 3] {
            let rhs = right_hand_side(&model.system, k);
            let lu = factor(&model.system, k, Some(b), on(FactorPath::Lu));
            let reference = lu.solve(&rhs);
            for kept in [Some(b), None] {
                let ldlt = factor(&model.system, k, kept, on(FactorPath::Ldlt));
                assert!(
                    ldlt.is_ldlt(),
                    "{name}, k = {k}: the LDLᵀ fell back to the LU"
                );
                let x = ldlt.solve(&rhs);
                let diff = relative_difference(&x, &reference);
                let backward =
                    hbcontact::hbm::system::relative_residual(&model.system, k, &x, &rhs);
                eprintln!(
                    "{name}, k = {k}, contact rows kept: {}: |Δx|/|x| = {diff:.1e}, backward error {backward:.1e}",
                    kept.is_some()
                );
                assert!(
                    backward < 1e-14,
                    "{name}, k = {k}: backward error {backward:e}"
                );
                assert!(diff < 1e-10, "{name}, k = {k}: |Δx|/|x| = {diff:e}");
            }
        }
    }
}

/// TEST GOAL: G_k = S⁻¹ from the kept LDLᵀ equals B Z_k⁻¹ Bᵀ by blocked solves with the
/// pivoting LU to 1e-10 of its largest entry, on the strip and the half-disc, k = 0…3.
#[test]
fn compliance_from_the_factor_equals_b_z_inverse_bt_by_lu() {
    for (name, model) in scenes() {
        let b = contact_rows(&model);
        for k in 0..=3 {
            let ldlt = factor(&model.system, k, Some(b), on(FactorPath::Ldlt));
            assert!(
                ldlt.is_ldlt(),
                "{name}, k = {k}: the LDLᵀ fell back to the LU"
            );
            let lu = factor(&model.system, k, Some(b), on(FactorPath::Lu));
            let diff = relative_difference(&ldlt.compliance(b), &lu.compliance(b));
            eprintln!("{name}, k = {k}: |ΔG|/|G| = {diff:.1e}");
            assert!(diff < 1e-10, "{name}, k = {k}: |ΔG|/|G| = {diff:e}");
        }
    }
}

/// TEST GOAL: when a pivot of the LDLᵀ fails (forced here by a pivot threshold of 1: no
/// pivot exceeds its whole column), the factorization falls back to the pivoting LU and gives
/// exactly the LU's solve and G; never a silently wrong answer.
#[test]
fn a_failed_pivot_falls_back_to_the_lu_with_the_same_answer() {
    let p = common::scene("reference_strip", &[]);
    let model = common::model(&p, Purpose::HarmonicBalance);
    let b = &model
        .contact
        .as_ref()
        .expect("a contact scene")
        .operator
        .b_free;
    let failing = FactorOptions {
        path: FactorPath::Ldlt,
        pivot_tolerance: 1.0,
    };
    for kept in [Some(b), None] {
        let k = 1;
        let fallback = factor(&model.system, k, kept, failing);
        assert!(
            !fallback.is_ldlt(),
            "a pivot threshold of 1 must fail the LDLᵀ"
        );
        let lu = factor(&model.system, k, kept, on(FactorPath::Lu));
        let rhs = right_hand_side(&model.system, k);
        assert_eq!(fallback.solve(&rhs), lu.solve(&rhs));
        assert_eq!(fallback.compliance(b), lu.compliance(b));
    }
}

/// B on the free dofs of a contact scene.
fn contact_rows(model: &hbcontact::pipeline::Model) -> &hbcontact::linalg::Csc {
    &model
        .contact
        .as_ref()
        .expect("a contact scene")
        .operator
        .b_free
}
