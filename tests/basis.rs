//! The time bases of harmonic balance and their operators (src/hbm/basis.rs).
//!
//! TEST GOAL: the periodic B-spline Gram matrices L_K, L_D, L_M (the note's (10)–(12)) equal
//! brute-force quadrature of the basis functions, are circulant with the DFT eigenvalues the
//! solver uses, and their symbols s_j, q_j converge to ijω, −(jω)² at the rate 2p; the same
//! eigen-check on the Fourier basis gives ikω and −(kω)² exactly; the load factor is the L²
//! projection; the sample maps P, Q are inverse (Q P = I) and agree with their DFT forms.
//! Reference: spline dispersion O((ωh)^{2p}) of Galerkin B-splines (Cottrell, Reali, Bazilevs,
//! Hughes, CMAME 195, 2006, §4: k-refinement).

use std::f64::consts::PI;

use faer::c64;
use hbcontact::hbm::basis::{gauss_legendre, SplineBasis, SplineSampler, TimeBasis};

/// Brute-force T⁻¹∫ f(t) dt over one period: 12 Gauss points in each of `cells` cells.
fn mean_over_period(period: f64, cells: usize, f: impl Fn(f64) -> f64) -> f64 {
    let rule = gauss_legendre(12);
    let mut sum = 0.0;
    for c in 0..cells {
        for &(u, w) in &rule {
            sum += w * f(period * (c as f64 + u) / cells as f64);
        }
    }
    sum / cells as f64
}

/// y = A x for a dense row-major n × n matrix.
fn apply(a: &[f64], x: &[f64]) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|r| (0..n).map(|c| a[r * n + c] * x[c]).sum())
        .collect()
}

/// Solve the dense system A x = b by Gaussian elimination with partial pivoting.
fn solve(a: &[f64], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let (mut a, mut b) = (a.to_vec(), b.to_vec());
    for col in 0..n {
        let piv = (col..n)
            .max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))
            .unwrap();
        for c in 0..n {
            a.swap(col * n + c, piv * n + c);
        }
        b.swap(col, piv);
        for r in col + 1..n {
            let f = a[r * n + col] / a[col * n + col];
            for c in col..n {
                a[r * n + c] -= f * a[col * n + c];
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| a[r * n + c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r * n + r];
    }
    x
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a, &x| a.max(x.abs()))
}

/// TEST GOAL: the circulant Gram matrices equal brute-force quadrature of φ_m φ_n, φ_m φ̇_n
/// and −φ̇_m φ̇_n with φ evaluated independently (`SplineBasis::value`), and L_M also equals
/// T⁻¹∫φᵀφ̈ (the note's (12), integration by parts over a period).
#[test]
fn spline_gram_matrices_equal_brute_force_quadrature() {
    let omega = 3.0;
    let period = 2.0 * PI / omega;
    for (p, s) in [(2usize, 7usize), (3, 8), (3, 5), (4, 12), (5, 16)] {
        let basis = SplineBasis::new(p, s);
        let [lk, ld, lm] = basis.gram_matrices(period);
        for m in 0..s {
            for n in 0..s {
                let phi = |k: usize, d: u32, t: f64| basis.value(k, omega, t, d);
                let mk = mean_over_period(period, s, |t| phi(m, 0, t) * phi(n, 0, t));
                let md = mean_over_period(period, s, |t| phi(m, 0, t) * phi(n, 1, t));
                let mm = -mean_over_period(period, s, |t| phi(m, 1, t) * phi(n, 1, t));
                let green = mean_over_period(period, s, |t| phi(m, 0, t) * phi(n, 2, t));
                let e = s * m + n;
                assert!((lk[e] - mk).abs() < 1e-13, "p={p} S={s} L_K[{m},{n}]");
                assert!(
                    (ld[e] - md).abs() < 1e-12 * omega,
                    "p={p} S={s} L_D[{m},{n}]"
                );
                assert!((lm[e] - mm).abs() < 1e-11 * omega * omega, "L_M[{m},{n}]");
                assert!(
                    (lm[e] - green).abs() < 1e-11 * omega * omega,
                    "(12) [{m},{n}]"
                );
            }
            // Partition of unity: each row of L_K sums to 1/S, of L_D and L_M to 0.
            let row = |a: &[f64]| (0..s).map(|n| a[m * s + n]).sum::<f64>();
            assert!((row(&lk) - 1.0 / s as f64).abs() < 1e-14);
            assert!(row(&ld).abs() < 1e-12 && row(&lm).abs() < 1e-10);
        }
    }
}

/// The coefficients Re(z e^{iθ_j n}) of frequency j on S coefficients.
fn discrete_harmonic(z: c64, j: usize, s: usize) -> Vec<f64> {
    (0..s)
        .map(|n| (z * c64::from_polar(1.0, 2.0 * PI * (j * n) as f64 / s as f64)).re)
        .collect()
}

/// TEST GOAL: the discrete harmonics are eigenvectors of L_K⁻¹L_D and L_K⁻¹L_M with the
/// eigenvalues s_j = iσ_j, q_j the solver uses (`TimeBasis::symbols`): L_K⁻¹L_D maps
/// Re(z e^{iθn}) to Re(iσ z e^{iθn}), for every j including 0 and Nyquist.
#[test]
fn spline_gram_ratios_are_diagonal_in_dft_coordinates_with_the_solver_symbols() {
    let omega = 2.5;
    let period = 2.0 * PI / omega;
    for (p, s) in [(2usize, 10usize), (3, 16), (3, 9), (4, 12)] {
        let basis = SplineBasis::new(p, s);
        let [lk, ld, lm] = basis.gram_matrices(period);
        let spline = TimeBasis::Spline(basis.clone());
        for j in 0..=s / 2 {
            let z = c64::new(0.7, -0.4);
            let v = discrete_harmonic(z, j, s);
            let sym = spline.symbols(j, omega);
            let ds = solve(&lk, &apply(&ld, &v));
            let qs = solve(&lk, &apply(&lm, &v));
            let want_d = discrete_harmonic(z * c64::new(0.0, sym.damping), j, s);
            let want_q = discrete_harmonic(z * sym.mass, j, s);
            let diff = |a: &[f64], b: &[f64]| {
                max_abs(&a.iter().zip(b).map(|(x, y)| x - y).collect::<Vec<_>>())
            };
            let scale = (j as f64 + 1.0) * omega;
            assert!(
                diff(&ds, &want_d) < 1e-11 * scale,
                "p={p} S={s} j={j} (s_j)"
            );
            assert!(
                diff(&qs, &want_q) < 1e-10 * scale * scale,
                "p={p} S={s} j={j} (q_j)"
            );
        }
    }
}

/// TEST GOAL: with the Fourier basis [1, cos kωt, sin kωt, …] the same eigen-check gives
/// exactly s_k = ikω and q_k = −(kω)² (the Gram matrices are diagonal on the complex
/// harmonics), which is what `TimeBasis::Fourier` returns: the general formulation contains
/// today's Fourier path.
#[test]
fn fourier_gram_ratios_are_exactly_ik_omega_and_minus_k_omega_squared() {
    let (h, omega) = (4usize, 1.7);
    let period = 2.0 * PI / omega;
    let m = 2 * h + 1;
    // φ_a and its derivatives in `fourier`'s order [1, cos ωt, sin ωt, …].
    let phi = |a: usize, d: u32, t: f64| -> f64 {
        let k = hbcontact::hbm::fourier::harmonic_of(a);
        let z = if a == 0 || a % 2 == 1 {
            c64::new(1.0, 0.0)
        } else {
            c64::new(0.0, -1.0)
        };
        (z * hbcontact::hbm::fourier::rotor(k, omega, t, d)).re
    };
    // Trapezoid rule on 4M points: exact for these trigonometric products.
    let n = 4 * m;
    let mean = |f: &dyn Fn(f64) -> f64| -> f64 {
        (0..n).map(|i| f(period * i as f64 / n as f64)).sum::<f64>() / n as f64
    };
    let gram = |da: u32, db: u32, sign: f64| -> Vec<f64> {
        let mut g = vec![0.0; m * m];
        for a in 0..m {
            for b in 0..m {
                g[a * m + b] = sign * mean(&|t| phi(a, da, t) * phi(b, db, t));
            }
        }
        g
    };
    let (lk, ld, lm) = (gram(0, 0, 1.0), gram(0, 1, 1.0), gram(1, 1, -1.0));
    for k in 0..=h {
        let z = c64::new(-0.3, 1.1);
        let mut v = vec![0.0; m];
        hbcontact::hbm::fourier::set_phasor(&mut v, k, z);
        let sym = TimeBasis::Fourier.symbols(k, omega);
        assert_eq!(sym.damping, k as f64 * omega);
        assert_eq!(sym.mass, -(k as f64 * omega).powi(2));
        let ds = solve(&lk, &apply(&ld, &v));
        let qs = solve(&lk, &apply(&lm, &v));
        let (mut want_d, mut want_q) = (vec![0.0; m], vec![0.0; m]);
        hbcontact::hbm::fourier::set_phasor(&mut want_d, k, z * c64::new(0.0, sym.damping));
        hbcontact::hbm::fourier::set_phasor(&mut want_q, k, z * sym.mass);
        for i in 0..m {
            assert!(
                (ds[i] - want_d[i]).abs() < 1e-12 * omega * (k as f64 + 1.0),
                "k={k}"
            );
            assert!((qs[i] - want_q[i]).abs() < 1e-11 * omega * omega * (k * k + 1) as f64);
        }
    }
}

/// The local order log(e_a/e_b)/log(S_b/S_a) of the last two errors of the ladder above
/// round-off (1e-12).
fn asymptotic_order(segments: &[usize], errors: &[f64]) -> f64 {
    let n = errors.iter().take_while(|&&e| e > 1e-12).count();
    assert!(n >= 2, "too few errors above round-off: {errors:?}");
    let (a, b) = (n - 2, n - 1);
    (errors[a] / errors[b]).ln() / (segments[b] as f64 / segments[a] as f64).ln()
}

/// TEST GOAL: s_j → ijω and q_j → −(jω)² as S grows: the relative error of q_j falls as
/// S^{−2p} (the spline dispersion order of the second derivative), that of σ_j as S^{−(2p+2)}
/// (the first-derivative symbol superconverges), measured on j = 1, 2 (p = 2, 3) and 2, 4
/// (p = 4) over S = 8…128, from the last two errors above round-off.
#[test]
fn spline_symbols_converge_to_the_exact_derivatives_at_order_two_p() {
    let omega = 2.0 * PI * 5.0;
    let ladder = [8usize, 16, 32, 64, 128];
    // p = 4 reaches round-off by S = 32 at j = 1: its ladder starts at a larger θ = 2πj/S.
    for (p, js) in [(2usize, [1usize, 2]), (3, [1, 2]), (4, [2, 4])] {
        for j in js {
            let (mut ed, mut em) = (Vec::new(), Vec::new());
            for &s in &ladder {
                let sym = TimeBasis::Spline(SplineBasis::new(p, s)).symbols(j, omega);
                let jw = j as f64 * omega;
                ed.push((sym.damping / jw - 1.0).abs());
                em.push((sym.mass / -(jw * jw) - 1.0).abs());
            }
            let (od, om) = (
                asymptotic_order(&ladder, &ed),
                asymptotic_order(&ladder, &em),
            );
            println!(
                "p = {p}, j = {j}: σ errors {ed:?} order {od:.2}; q errors {em:?} order {om:.2}"
            );
            let want = 2.0 * p as f64;
            assert!(
                (od - want - 2.0).abs() < 0.4,
                "p = {p}, j = {j}: σ order {od}"
            );
            assert!((om - want).abs() < 0.4, "p = {p}, j = {j}: q order {om}");
        }
    }
}

/// TEST GOAL: γ_k E_k(t) is the L² projection of e^{ikωt} onto the splines (the residual is
/// orthogonal to every φ_m), so a harmonic load enters frequency k as γ_k F; and the rotor is
/// Σ_n φ_n(t) e^{iθn} with derivatives matching central differences.
#[test]
fn spline_load_factor_is_the_l2_projection_and_the_rotor_sums_the_basis() {
    let omega = 2.0;
    let period = 2.0 * PI / omega;
    for (p, s, k) in [(2usize, 9usize, 1usize), (3, 16, 3), (5, 12, 2)] {
        let basis = SplineBasis::new(p, s);
        let spline = TimeBasis::Spline(basis.clone());
        let gamma = spline.load_factor(k).expect("splines scale loads");
        for m in 0..s {
            let residual = |t: f64| {
                c64::from_polar(1.0, k as f64 * omega * t) - gamma * spline.rotor(k, omega, t, 0)
            };
            let re = mean_over_period(period, s, |t| basis.value(m, omega, t, 0) * residual(t).re);
            let im = mean_over_period(period, s, |t| basis.value(m, omega, t, 0) * residual(t).im);
            assert!(re.abs() < 1e-14 && im.abs() < 1e-14, "p={p} S={s} m={m}");
        }
        for &t in &[0.0, 0.13 * period, 0.5 * period, 0.871 * period] {
            let theta = 2.0 * PI * k as f64 / s as f64;
            for d in 0..=2u32 {
                let direct: c64 = (0..s)
                    .map(|n| c64::from_polar(basis.value(n, omega, t, d), theta * n as f64))
                    .sum();
                let rotor = spline.rotor(k, omega, t, d);
                assert!((direct - rotor).norm() < 1e-12 * omega.powi(d as i32) * s.pow(d) as f64);
            }
            let dt = 1e-6 * period;
            let fd = (spline.rotor(k, omega, t + dt, 0) - spline.rotor(k, omega, t - dt, 0))
                / (2.0 * dt);
            let exact = spline.rotor(k, omega, t, 1);
            // Central differences across a knot of a quadratic (E'' jumps) err by O(dt·S/T).
            assert!(
                (fd - exact).norm() < 1e-4 * exact.norm().max(1.0),
                "p={p} t={t}"
            );
        }
        // Harmonic content: T⁻¹∫E_k e^{−ikωt} dt.
        let product =
            |t: f64| spline.rotor(k, omega, t, 0) * c64::from_polar(1.0, -(k as f64) * omega * t);
        let numeric = c64::new(
            mean_over_period(period, 4 * s, |t| product(t).re),
            mean_over_period(period, 4 * s, |t| product(t).im),
        );
        assert!(
            (numeric - spline.harmonic_content(k)).norm() < 1e-12,
            "p={p} S={s}"
        );
    }
}

/// TEST GOAL: the spline sample maps at Gauss points invert each other (Q P = I, exact
/// quadrature of φᵀφ), and their DFT forms (`to_samples`, `to_phasors`) equal the dense P, Q
/// applied to the coefficients Re Σ_j z_j e^{iθ_j n}.
#[test]
fn spline_sample_maps_invert_and_match_their_dft_forms() {
    for (p, s, per) in [(2usize, 8usize, 3usize), (3, 10, 4), (3, 7, 6)] {
        let sampler = SplineSampler::new(&SplineBasis::new(p, s), per);
        let n = sampler.samples();
        let (pm, qm) = (sampler.p_matrix(), sampler.q_matrix());
        for a in 0..s {
            for b in 0..s {
                let qp: f64 = (0..n).map(|k| qm[a * n + k] * pm[k * s + b]).sum();
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((qp - want).abs() < 1e-12, "p={p} S={s} QP[{a},{b}] = {qp}");
            }
        }
        let phasors: Vec<c64> = (0..=s / 2)
            .map(|j| {
                let nyquist = 2 * j == s || j == 0;
                c64::new(0.3 + j as f64, if nyquist { 0.0 } else { 0.5 - j as f64 })
            })
            .collect();
        let coeffs: Vec<f64> = (0..s)
            .map(|m| {
                phasors
                    .iter()
                    .enumerate()
                    .map(|(j, z)| {
                        (z * c64::from_polar(1.0, 2.0 * PI * (j * m) as f64 / s as f64)).re
                    })
                    .sum()
            })
            .collect();
        let dense: Vec<f64> = (0..n)
            .map(|k| (0..s).map(|m| pm[k * s + m] * coeffs[m]).sum())
            .collect();
        let mut fast = vec![0.0; n];
        sampler.to_samples(&phasors, &mut fast);
        for k in 0..n {
            assert!((dense[k] - fast[k]).abs() < 1e-12, "p={p} S={s} sample {k}");
        }
        let mut back = vec![c64::new(0.0, 0.0); phasors.len()];
        sampler.to_phasors(&fast, &mut back);
        for (j, (a, b)) in back.iter().zip(&phasors).enumerate() {
            assert!((a - b).norm() < 1e-12, "p={p} S={s} j={j}: {a} vs {b}");
        }
    }
}
