//! The period-doubled problem a sweep switches to after a period doubling, and where on it
//! the new branch leaves the T-periodic one (docs/method.md, "The 2T branch").
//!
//! Formulas and glossary:
//! - the 2T problem: base frequency ω₂ = ω/2, every load, prescribed motion and gap harmonic
//!   k of the T problem moved to harmonic 2k, H₂ = 2H harmonics and N₂ = 2N samples over 2T
//!   (the same instants t_n = nT/N, the same c): its states with only even harmonics are the
//!   T problem's states, coefficient for coefficient (`embed`);
//! - at such a state the contact law's sampled activity D is T-periodic, so the Newton matrix
//!   J = I + Q D P (cG − I) maps odd harmonics to odd harmonics (an antiperiodic sample
//!   sequence times a periodic one is antiperiodic): J = J_even ⊕ J_odd, J_even the T
//!   problem's own;
//! - a period doubling of the T state (a Floquet multiplier through −1) is a zero eigenvalue of
//!   J_odd (Hill's exponent iω/2 is the 2T problem's harmonic 1): the 2T branch leaves the
//!   T branch there along J_odd's null vector φ (a symmetric pitchfork: λ → λ with its odd
//!   harmonics negated is the same orbit shifted by T), `odd_null_vector`, the Floquet vector
//!   of the period doubling in the harmonic-balance unknowns;
//! - the odd share ‖λ_odd‖/‖λ‖ (`odd_share`) is zero on the T branch and grows along the 2T
//!   branch from the period doubling.

use std::collections::BTreeMap;

use faer::{c64, Mat};

use super::fourier::{cos_index, sin_index};
use super::problem::ReducedProblem;
use super::{HbSettings, System};
use crate::contact::ContactOperator;
use crate::linalg::norm2;
use crate::{Error, Result};

/// J_odd is formed on the odd harmonics up to the one that keeps its order at most this
/// (the null vector's weight lies on the lowest odd harmonics).
const ODD_ORDER: usize = 600;

/// The 2T problem of `system` and `op` (`ω₂ = ω/2`, harmonic k → 2k). Refused for what it
/// does not carry over: a spline basis, a frame whose speed follows ω, friction.
pub fn doubled_period(system: &System, op: &ContactOperator) -> Result<(System, ContactOperator)> {
    if !matches!(system.basis, super::basis::TimeBasis::Fourier) {
        return Err(Error::Input(
            "a 2T branch needs harmonic_balance.basis: fourier".into(),
        ));
    }
    if system.spin.is_some() || op.tangential.is_some() {
        return Err(Error::Input(
            "a 2T branch is not followed with boundaries.rotation.turns_per_period or friction"
                .into(),
        ));
    }
    let mut doubled = system.clone();
    doubled.omega = system.omega / 2.0;
    doubled.inputs = (system.inputs.iter())
        .map(|(&k, input)| (2 * k, input.clone()))
        .collect();
    let mut contact = op.clone();
    contact.gap_harmonics = double_keys(&op.gap_harmonics);
    Ok((doubled, contact))
}

fn double_keys<V: Clone>(map: &BTreeMap<usize, V>) -> BTreeMap<usize, V> {
    map.iter().map(|(&k, v)| (2 * k, v.clone())).collect()
}

/// The settings of the 2T problem: 2H harmonics, 2N samples.
pub fn doubled_settings(settings: &HbSettings) -> HbSettings {
    HbSettings {
        harmonics: 2 * settings.harmonics,
        samples: 2 * settings.samples,
        ..settings.clone()
    }
}

/// T coefficients (node-major, 2H + 1 per node) as 2T ones (4H + 1 per node): harmonic k at
/// 2k, the odd harmonics zero.
pub fn embed(x: &[f64], nodes: usize, h: usize) -> Vec<f64> {
    let (m, m2) = (2 * h + 1, 4 * h + 1);
    let mut out = vec![0.0; nodes * m2];
    for i in 0..nodes {
        out[i * m2] = x[i * m];
        for k in 1..=h {
            out[i * m2 + cos_index(2 * k)] = x[i * m + cos_index(k)];
            out[i * m2 + sin_index(2 * k)] = x[i * m + sin_index(k)];
        }
    }
    out
}

/// The odd harmonics of 2T coefficients (node-major, `h2` harmonics per node), the even ones
/// zeroed.
pub fn odd_part(x: &[f64], h2: usize) -> Vec<f64> {
    let m2 = 2 * h2 + 1;
    let odd = |i: usize| super::fourier::harmonic_of(i % m2) % 2 == 1;
    (x.iter().enumerate())
        .map(|(i, &v)| if odd(i) { v } else { 0.0 })
        .collect()
}

/// ‖x_odd‖/‖x‖ of 2T coefficients (`h2` harmonics per node; 0 for x = 0).
pub fn odd_share(x: &[f64], h2: usize) -> f64 {
    let all = norm2(x);
    if all > 0.0 {
        norm2(&odd_part(x, h2)) / all
    } else {
        0.0
    }
}

/// What J_odd says at an embedded T state.
pub struct OddNull {
    /// The unit eigenvector of its eigenvalue of least modulus, as full 2T coefficients.
    pub vector: Vec<f64>,
    /// That eigenvalue's modulus relative to J_odd's largest entry (near zero at a period
    /// doubling).
    pub least: f64,
    /// Its real eigenvalue of least modulus, relative, signed (`None`: none is real).
    pub real: Option<f64>,
    /// The sign of its determinant (the product of its real eigenvalues' signs): it changes
    /// each time a real Floquet multiplier passes −1, so it counts the multipliers below −1
    /// modulo 2, also where the contact set jumps between two states.
    pub det_sign: f64,
}

/// J_odd at the 2T state `x` (an embedded T state) of `problem` with N samples and c, formed
/// on the odd harmonics up to the order `ODD_ORDER`: its near-null vector and eigenvalues.
pub fn odd_null_vector(
    problem: &ReducedProblem,
    x: &[f64],
    samples: usize,
    c: f64,
) -> Result<OddNull> {
    let (nc, h2) = (problem.nodes, problem.harmonics);
    let m2 = 2 * h2 + 1;
    let odd: Vec<usize> = (1..=h2)
        .filter(|k| k % 2 == 1)
        .take((ODD_ORDER / (2 * nc.max(1))).max(1))
        .flat_map(|k| [cos_index(k), sin_index(k)])
        .collect();
    let active = activity(problem, x, samples, c);
    let sampler = problem.sampler(samples);
    let n = nc * odd.len();
    let mut j = Mat::<f64>::zeros(n, n);
    let (mut v, mut gv, mut scratch) = (vec![0.0; nc * m2], vec![0.0; nc * m2], Vec::new());
    let (mut s, mut back) = (vec![0.0; samples], vec![0.0; m2]);
    for col in 0..n {
        let (a, q) = (col / odd.len(), odd[col % odd.len()]);
        v.fill(0.0);
        v[a * m2 + q] = 1.0;
        problem.compliance_product(&v, &mut gv, &mut scratch);
        for b in 0..nc {
            let u: Vec<f64> = (0..m2)
                .map(|r| c * gv[b * m2 + r] - v[b * m2 + r])
                .collect();
            sampler.to_samples(&u, &mut s);
            s.iter_mut()
                .zip(&active[b * samples..(b + 1) * samples])
                .for_each(|(si, &on)| *si = if on { *si } else { 0.0 });
            sampler.to_coefficients(&s, &mut back);
            for (ri, &r) in odd.iter().enumerate() {
                j[(b * odd.len() + ri, col)] = back[r] + v[b * m2 + r];
            }
        }
    }
    let (values, vectors) = crate::linalg::eigen_real(j.as_ref())?;
    let scale = (0..n)
        .flat_map(|i| (0..n).map(move |k| (i, k)))
        .map(|(i, k)| j[(i, k)].abs())
        .fold(0.0, f64::max);
    let least = (0..values.len())
        .min_by(|&a, &b| values[a].norm().total_cmp(&values[b].norm()))
        .ok_or_else(|| Error::Model("internal: no odd harmonics".into()))?;
    let mut phi = vec![0.0; nc * m2];
    for (col, v) in rotate_real(&vectors, least).into_iter().enumerate() {
        let (a, q) = (col / odd.len(), odd[col % odd.len()]);
        phi[a * m2 + q] = v;
    }
    let norm = norm2(&phi);
    phi.iter_mut()
        .for_each(|p| *p /= norm.max(f64::MIN_POSITIVE));
    let scale = scale.max(f64::MIN_POSITIVE);
    let real = (values.iter())
        .filter(|z| z.im == 0.0)
        .min_by(|a, b| a.re.abs().total_cmp(&b.re.abs()))
        .map(|z| z.re / scale);
    let det_sign = (values.iter())
        .filter(|z| z.im == 0.0)
        .map(|z| z.re.signum())
        .product();
    Ok(OddNull {
        vector: phi,
        least: values[least].norm() / scale,
        real,
        det_sign,
    })
}

/// Column `j` of complex eigenvectors as a real vector: rotated by the phase of its largest
/// entry (a real eigenvalue's vector is real up to that phase).
fn rotate_real(vectors: &Mat<c64>, j: usize) -> Vec<f64> {
    let col: Vec<c64> = (0..vectors.nrows()).map(|i| vectors[(i, j)]).collect();
    let largest = col
        .iter()
        .copied()
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .unwrap_or(c64::new(1.0, 0.0));
    let phase = largest.conj() / largest.norm().max(f64::MIN_POSITIVE);
    col.iter().map(|z| (z * phase).re).collect()
}

/// Where the law is active at the state x, node-major over the samples: c g − λ > 0.
fn activity(problem: &ReducedProblem, x: &[f64], samples: usize, c: f64) -> Vec<bool> {
    let (nc, m2) = (problem.nodes, problem.coefficients());
    let g = problem.gap(x);
    let sampler = problem.sampler(samples);
    let mut s = vec![0.0; samples];
    let mut active = Vec::with_capacity(nc * samples);
    for i in 0..nc {
        let w: Vec<f64> = (0..m2).map(|r| c * g[i * m2 + r] - x[i * m2 + r]).collect();
        sampler.to_samples(&w, &mut s);
        active.extend(s.iter().map(|&v| v > 0.0));
    }
    active
}

/// The 2T reduced problem at the system's ω₂ (`prepare`'s factorizations, dropped once its
/// G_k are formed).
pub fn reduced_problem(
    system: &System,
    op: &ContactOperator,
    settings: &HbSettings,
) -> Result<ReducedProblem> {
    let mut timings = super::Timings::default();
    let (_, problem) = super::prepare(system, Some(op), settings, &crate::Silent, &mut timings)?;
    problem.ok_or_else(|| Error::Model("internal: no reduced problem".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a T state embedded in the 2T layout keeps every coefficient at twice its
    /// harmonic and has no odd share; a vector with odd harmonics only has share 1.
    #[test]
    fn an_embedded_state_lies_on_the_even_harmonics_only() {
        let (nodes, h) = (2, 3);
        let x: Vec<f64> = (0..nodes * (2 * h + 1)).map(|i| 1.0 + i as f64).collect();
        let y = embed(&x, nodes, h);
        assert_eq!(y.len(), nodes * (4 * h + 1));
        assert_eq!(odd_share(&y, 2 * h), 0.0);
        for i in 0..nodes {
            for k in 1..=h {
                assert_eq!(y[i * 13 + cos_index(2 * k)], x[i * 7 + cos_index(k)]);
                assert_eq!(y[i * 13 + sin_index(2 * k)], x[i * 7 + sin_index(k)]);
            }
        }
        let mut odd = vec![0.0; 13];
        odd[cos_index(3)] = 2.0;
        assert_eq!(odd_share(&odd, 6), 1.0);
    }
}
