//! The contact terms' time samples for either basis: P (coefficients → the gap or force at
//! the N time samples) and Q (samples → coefficients, the projection of the note's (22)–(23)
//! with its quadrature in time), and the Newton's activity blocks A = Q diag(s) P.
//!
//! Glossary: the contact unknowns of one node are real coefficients in `fourier`'s layout
//! `[a_0, a_1, b_1, …, a_H, b_H]` (M = 2H + 1), read as phasors z_k = a_k − i b_k of the
//! basis' frequencies k = 0..H:
//! - Fourier: k the harmonic, x(t) = Re Σ_k z_k e^{ikωt}; samples t_n = nT/N; P, Q by FFT
//!   (`fourier::Sampler`, today's path unchanged);
//! - splines (p the degree, S segments, h = T/S): k the discrete frequency j of the spline
//!   coefficients (ũ_n = Re Σ_j z_j e^{2πijn/S}, `basis`), H ≤ ⌊S/2⌋ (at the Nyquist frequency
//!   j = S/2 only a_j acts; b_j is a dummy that P ignores and Q sets to zero);
//!   r = N/S ≥ p + 1 Gauss–Legendre points per segment (default 8), t_{i,g} = (i + u_g)h,
//!   n = i·r + g; P[n, j] the samples of the rotor E_j and Q = L_K⁻¹ Pᵀ W with W the weights
//!   of T⁻¹∫, both formed from the per-frequency symbols P̂_j,g of `basis::SplineSampler`
//!   (the circulant diagonalization): Q P = I on the kept frequencies, since the quadrature
//!   of φᵀφ is exact.

use faer::c64;

use super::basis::{SplineSampler, TimeBasis};
use super::fourier::{self, cos_index, phasor, sin_index, Sampler};
use super::step;

/// Samples per segment a spline contact solve uses unless `harmonic_balance.samples` says
/// otherwise.
pub const SPLINE_SAMPLES_PER_SEGMENT: usize = 8;

/// P and Q of the contact terms for one basis, H and N.
pub enum ContactSampler {
    Fourier(Sampler),
    Spline(SplineMaps),
}

/// The dense real-layout P (N × M) and Q (M × N) of a spline basis, row-major.
pub struct SplineMaps {
    pub harmonics: usize,
    pub samples: usize,
    p: Vec<f64>,
    q: Vec<f64>,
}

impl ContactSampler {
    /// The sampler of `basis` for frequencies 0..=`harmonics` and N = `samples` (splines:
    /// a multiple of S with at least p + 1 per segment, which the caller checks).
    pub fn new(basis: &TimeBasis, harmonics: usize, samples: usize) -> Self {
        match basis {
            TimeBasis::Fourier => ContactSampler::Fourier(Sampler::new(harmonics, samples)),
            TimeBasis::Spline(s) => {
                let per_segment = (samples / s.segments).max(1);
                let maps = SplineMaps::new(&SplineSampler::new(s, per_segment), harmonics);
                ContactSampler::Spline(maps)
            }
        }
    }

    pub fn harmonics(&self) -> usize {
        match self {
            ContactSampler::Fourier(s) => s.harmonics,
            ContactSampler::Spline(s) => s.harmonics,
        }
    }

    pub fn samples(&self) -> usize {
        match self {
            ContactSampler::Fourier(s) => s.samples,
            ContactSampler::Spline(s) => s.samples,
        }
    }

    /// M = 2H + 1.
    pub fn coefficients(&self) -> usize {
        2 * self.harmonics() + 1
    }

    /// P: the samples of the function with coefficients `coeffs` (length M) into `out` (N).
    pub fn to_samples(&self, coeffs: &[f64], out: &mut [f64]) {
        match self {
            ContactSampler::Fourier(s) => s.to_samples(coeffs, out),
            ContactSampler::Spline(s) => dense_apply(&s.p, s.coefficients(), coeffs, out),
        }
    }

    /// Q: the coefficients (length M) of the projection of `samples` (length N).
    pub fn to_coefficients(&self, samples: &[f64], out: &mut [f64]) {
        match self {
            ContactSampler::Fourier(s) => s.to_coefficients(samples, out),
            ContactSampler::Spline(s) => dense_apply(&s.q, s.samples, samples, out),
        }
    }

    /// A = Q diag(s) P (M × M, row-major) from the slopes `s` at the N samples.
    pub fn activity_block(&self, slopes: &[f64], out: &mut [f64]) {
        match self {
            ContactSampler::Fourier(s) => step::activity_block(s, slopes, out),
            ContactSampler::Spline(s) => s.activity_block(slopes, out),
        }
    }

    /// Dense P (N × M, row-major).
    pub fn p_matrix(&self) -> Vec<f64> {
        match self {
            ContactSampler::Fourier(s) => s.p_matrix(),
            ContactSampler::Spline(s) => s.p.clone(),
        }
    }

    /// Dense Q (M × N, row-major).
    pub fn q_matrix(&self) -> Vec<f64> {
        match self {
            ContactSampler::Fourier(s) => s.q_matrix(),
            ContactSampler::Spline(s) => s.q.clone(),
        }
    }
}

/// out = A x for a dense row-major A with `cols` columns.
fn dense_apply(a: &[f64], cols: usize, x: &[f64], out: &mut [f64]) {
    for (o, row) in out.iter_mut().zip(a.chunks_exact(cols)) {
        *o = row.iter().zip(x).map(|(a, b)| a * b).sum();
    }
}

impl SplineMaps {
    /// P and Q on frequencies 0..=`harmonics` (≤ S/2) from the per-frequency symbols:
    /// P[(i,g), cos j] = Re(P̂_j,g e^{iθ_j i}), P[(i,g), sin j] = Im(P̂_j,g e^{iθ_j i}), and
    /// with κ_j = w_j/(S² â_j) (w_j = 1 at j = 0 and Nyquist, else 2) and
    /// y = κ_j conj(P̂_j,g) w_g e^{−iθ_j i}: Q[cos j, (i,g)] = Re y, Q[sin j, (i,g)] = −Im y.
    pub fn new(sampler: &SplineSampler, harmonics: usize) -> Self {
        let basis = &sampler.basis;
        let s = basis.segments;
        let harmonics = harmonics.min(s / 2);
        let (m, n) = (2 * harmonics + 1, sampler.samples());
        let per = n / s;
        let weights = sampler.weights();
        let (mut p, mut q) = (vec![0.0; n * m], vec![0.0; m * n]);
        for j in 0..=harmonics {
            let theta = 2.0 * std::f64::consts::PI * j as f64 / s as f64;
            let symbol = sampler.sample_symbol(j);
            let (a, _, _) = basis.eigenvalues(j, 2.0 * std::f64::consts::PI);
            let weight = if j == 0 || 2 * j == s { 1.0 } else { 2.0 };
            let kappa = weight / (s as f64 * s as f64 * a);
            for i in 0..s {
                let turn = c64::from_polar(1.0, theta * i as f64);
                for (g, ps) in symbol.iter().enumerate() {
                    let row = i * per + g;
                    let v = ps * turn;
                    let y = ps.conj() * turn.conj() * (kappa * weights[g]);
                    p[row * m + cos_index(j)] = v.re;
                    q[cos_index(j) * n + row] = y.re;
                    if j > 0 {
                        let nyquist = 2 * j == s;
                        p[row * m + sin_index(j)] = if nyquist { 0.0 } else { v.im };
                        q[sin_index(j) * n + row] = if nyquist { 0.0 } else { -y.im };
                    }
                }
            }
        }
        SplineMaps {
            harmonics,
            samples: n,
            p,
            q,
        }
    }

    fn coefficients(&self) -> usize {
        2 * self.harmonics + 1
    }

    /// A = Q diag(s) P, skipping the samples where the slope is zero (the exact law's open
    /// samples): M² per active sample.
    fn activity_block(&self, slopes: &[f64], out: &mut [f64]) {
        let (m, n) = (self.coefficients(), self.samples);
        out.iter_mut().for_each(|v| *v = 0.0);
        for (k, &slope) in slopes.iter().enumerate().filter(|(_, &s)| s != 0.0) {
            let p_row = &self.p[k * m..(k + 1) * m];
            for a in 0..m {
                let qa = self.q[a * n + k] * slope;
                if qa == 0.0 {
                    continue;
                }
                for (o, pv) in out[a * m..(a + 1) * m].iter_mut().zip(p_row) {
                    *o += qa * pv;
                }
            }
        }
    }
}

/// The value at t of the function with coefficients `coeffs` (M = 2H + 1, phasors of the
/// basis' frequencies 0..H) for period 2π/ω: Fourier's series, or Re Σ_j z_j E_j(t).
pub fn evaluate(basis: &TimeBasis, coeffs: &[f64], omega: f64, t: f64) -> f64 {
    match basis {
        TimeBasis::Fourier => fourier::evaluate(coeffs, omega, t)[0],
        TimeBasis::Spline(_) => (0..coeffs.len().div_ceil(2))
            .map(|k| (phasor(coeffs, k) * basis.rotor(k, omega, t, 0)).re)
            .sum(),
    }
}
