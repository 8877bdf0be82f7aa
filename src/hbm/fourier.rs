//! Truncated Fourier series of a T-periodic scalar and its samples: the P (coefficients →
//! samples) and Q (samples → coefficients) maps of the alternating frequency–time scheme.
//!
//! Coefficients are stored `[a0, a1, b1, a2, b2, …, aH, bH]` for
//! x(t) = a0 + Σ_k a_k cos(kωt) + b_k sin(kωt), sampled at t_n = nT/N, n = 0..N−1.
//! With N > 2H, Q P = I exactly (discrete orthogonality), which the Newton relies on.

use std::sync::Arc;

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

/// FFT plans and dense P, Q for one (H, N).
pub struct Sampler {
    pub harmonics: usize,
    pub samples: usize,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl Sampler {
    /// Requires `samples > 2 * harmonics` (checked by the config; asserted here as an
    /// internal invariant).
    pub fn new(harmonics: usize, samples: usize) -> Self {
        debug_assert!(samples > 2 * harmonics);
        let mut planner = FftPlanner::new();
        Sampler {
            harmonics,
            samples,
            forward: planner.plan_fft_forward(samples),
            inverse: planner.plan_fft_inverse(samples),
        }
    }

    /// Number of coefficients, M = 2H + 1.
    pub fn coefficients(&self) -> usize {
        2 * self.harmonics + 1
    }

    /// P: the samples of the series with coefficients `coeffs` (length M) into `out` (length N).
    pub fn to_samples(&self, coeffs: &[f64], out: &mut [f64]) {
        let n = self.samples;
        let mut spectrum = vec![Complex64::new(0.0, 0.0); n];
        spectrum[0] = Complex64::new(coeffs[0], 0.0);
        for k in 1..=self.harmonics {
            let half = Complex64::new(coeffs[2 * k - 1], -coeffs[2 * k]) * 0.5;
            spectrum[k] += half;
            spectrum[n - k] += half.conj();
        }
        self.inverse.process(&mut spectrum);
        for (o, s) in out.iter_mut().zip(&spectrum) {
            *o = s.re;
        }
    }

    /// Q: the discrete Fourier projection of `samples` (length N) onto M coefficients.
    pub fn to_coefficients(&self, samples: &[f64], out: &mut [f64]) {
        let n = self.samples;
        let mut spectrum: Vec<Complex64> =
            samples.iter().map(|&x| Complex64::new(x, 0.0)).collect();
        self.forward.process(&mut spectrum);
        let scale = 1.0 / n as f64;
        out[0] = spectrum[0].re * scale;
        for k in 1..=self.harmonics {
            out[2 * k - 1] = 2.0 * spectrum[k].re * scale;
            out[2 * k] = -2.0 * spectrum[k].im * scale;
        }
    }

    /// Dense P (N × M, row-major).
    pub fn p_matrix(&self) -> Vec<f64> {
        let (n, m) = (self.samples, self.coefficients());
        let mut p = vec![0.0; n * m];
        for s in 0..n {
            let phase = 2.0 * std::f64::consts::PI * s as f64 / n as f64;
            p[s * m] = 1.0;
            for k in 1..=self.harmonics {
                let (sin, cos) = (k as f64 * phase).sin_cos();
                p[s * m + 2 * k - 1] = cos;
                p[s * m + 2 * k] = sin;
            }
        }
        p
    }

    /// Dense Q (M × N, row-major).
    pub fn q_matrix(&self) -> Vec<f64> {
        let (n, m) = (self.samples, self.coefficients());
        let p = self.p_matrix();
        let mut q = vec![0.0; m * n];
        for s in 0..n {
            for c in 0..m {
                let w = if c == 0 { 1.0 } else { 2.0 };
                q[c * n + s] = w * p[s * m + c] / n as f64;
            }
        }
        q
    }
}

/// Evaluate the series (and its first two time derivatives) at time `t`.
pub fn evaluate(coeffs: &[f64], omega: f64, t: f64) -> [f64; 3] {
    let mut out = [coeffs[0], 0.0, 0.0];
    let harmonics = (coeffs.len() - 1) / 2;
    for k in 1..=harmonics {
        let w = k as f64 * omega;
        let (s, c) = (w * t).sin_cos();
        let (a, b) = (coeffs[2 * k - 1], coeffs[2 * k]);
        out[0] += a * c + b * s;
        out[1] += w * (-a * s + b * c);
        out[2] += -w * w * (a * c + b * s);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_maps_match_the_dense_ones_and_invert() {
        let s = Sampler::new(3, 16);
        let coeffs = [0.5, 1.0, -2.0, 0.25, 0.0, -0.75, 0.3];
        let mut samples = vec![0.0; 16];
        s.to_samples(&coeffs, &mut samples);
        let p = s.p_matrix();
        for n in 0..16 {
            let dense: f64 = (0..7).map(|m| p[n * 7 + m] * coeffs[m]).sum();
            assert!((dense - samples[n]).abs() < 1e-12);
            let t = n as f64 / 16.0;
            let direct = evaluate(&coeffs, 2.0 * std::f64::consts::PI, t)[0];
            assert!((direct - samples[n]).abs() < 1e-12);
        }
        let mut back = vec![0.0; 7];
        s.to_coefficients(&samples, &mut back);
        let q = s.q_matrix();
        for m in 0..7 {
            assert!((back[m] - coeffs[m]).abs() < 1e-12);
            let dense: f64 = (0..16).map(|n| q[m * 16 + n] * samples[n]).sum();
            assert!((dense - coeffs[m]).abs() < 1e-12);
        }
    }
}
