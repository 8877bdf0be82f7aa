//! Body loads: gravity (`boundaries.gravity`), the static body force ρg on every cell.

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
