//! The Fourier convention of the whole crate, in one place, and the truncated series' samples:
//! the P (coefficients → samples) and Q (samples → coefficients) maps of the alternating
//! frequency–time scheme (docs/method.md, (21)–(23)).
//!
//! - Real coefficients are stored `[a0, a1, b1, a2, b2, …, aH, bH]` (M = 2H + 1 of them) for
//!   x(t) = a0 + Σ_k a_k cos(kωt) + b_k sin(kωt): `cos_index(k)` and `sin_index(k)`.
//! - The complex amplitude of harmonic k is z_k = a_k − i b_k, so x(t) = Re Σ_k z_k e^{ikωt}
//!   (z_0 = a_0): `phasor`, `set_phasor`, `from_cos_sin`, `cos_sin`.
//! - A derivative of order d at time t is Re(z_k (ikω)^d e^{ikωt}): `rotor`.
//! - Samples sit at t_n = nT/N, n = 0..N−1; with N > 2H, Q P = I exactly (discrete
//!   orthogonality), which the Newton relies on.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use num_complex::Complex64;

use faer::c64;
use rustfft::{Fft, FftPlanner};

/// Position of harmonic k's cos coefficient (k = 0: the mean).
pub fn cos_index(k: usize) -> usize {
    if k == 0 {
        0
    } else {
        2 * k - 1
    }
}

/// Position of harmonic k's sin coefficient (k ≥ 1).
pub fn sin_index(k: usize) -> usize {
    2 * k
}

/// The harmonic a coefficient position belongs to.
pub fn harmonic_of(index: usize) -> usize {
    index.div_ceil(2)
}

/// z = a − i b for a cos + b sin.
pub fn from_cos_sin(a: f64, b: f64) -> c64 {
    c64::new(a, -b)
}

/// (a, b) of a cos + b sin from z = a − i b.
pub fn cos_sin(z: c64) -> (f64, f64) {
    (z.re, -z.im)
}

/// The complex amplitude z_k of harmonic k from the real coefficients (z_0 = a_0).
pub fn phasor(coeffs: &[f64], k: usize) -> c64 {
    if k == 0 {
        c64::new(coeffs[0], 0.0)
    } else {
        from_cos_sin(coeffs[cos_index(k)], coeffs[sin_index(k)])
    }
}

/// Harmonic k's phasor of every node's coefficients (`coeffs` node-major, `m` per node).
pub fn node_phasors(coeffs: &[f64], m: usize, k: usize) -> Vec<c64> {
    coeffs.chunks_exact(m).map(|c| phasor(c, k)).collect()
}

/// Store z_k as real coefficients (k = 0 keeps the real part only).
pub fn set_phasor(coeffs: &mut [f64], k: usize, z: c64) {
    if k == 0 {
        coeffs[0] = z.re;
    } else {
        let (a, b) = cos_sin(z);
        coeffs[cos_index(k)] = a;
        coeffs[sin_index(k)] = b;
    }
}

/// (ikω)^d e^{ikωt}: the d-th time derivative at t of harmonic k is Re(z_k · rotor).
pub fn rotor(k: usize, omega: f64, t: f64, derivative: u32) -> c64 {
    let kw = k as f64 * omega;
    c64::from_polar(1.0, kw * t) * c64::new(0.0, kw).powu(derivative)
}

/// The work space of `Sampler`'s maps: one spectrum of N and the FFT's scratch, kept by a
/// caller in a loop so that P and Q allocate nothing (`rustfft`'s `process` allocates its
/// scratch on every call).
#[derive(Default)]
pub struct FftWork {
    pub(crate) spectrum: Vec<Complex64>,
    pub(crate) scratch: Vec<Complex64>,
}

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
        let (forward, inverse) = plans(samples);
        Sampler {
            harmonics,
            samples,
            forward,
            inverse,
        }
    }

    /// The forward DFT X_j = Σ_n x_n e^{−2πijn/N} in place (length N), with the FFT's
    /// scratch in `scratch`.
    pub fn forward_with(&self, buffer: &mut [Complex64], scratch: &mut Vec<Complex64>) {
        in_place(&*self.forward, buffer, scratch);
    }

    /// Number of coefficients, M = 2H + 1.
    pub fn coefficients(&self) -> usize {
        2 * self.harmonics + 1
    }

    /// P: the samples of the series with coefficients `coeffs` (length M) into `out` (length N).
    pub fn to_samples(&self, coeffs: &[f64], out: &mut [f64]) {
        self.to_samples_with(coeffs, out, &mut FftWork::default());
    }

    /// `to_samples` in the work space `work`.
    pub fn to_samples_with(&self, coeffs: &[f64], out: &mut [f64], work: &mut FftWork) {
        let n = self.samples;
        let FftWork { spectrum, scratch } = work;
        spectrum.clear();
        spectrum.resize(n, Complex64::new(0.0, 0.0));
        spectrum[0] = Complex64::new(coeffs[0], 0.0);
        for k in 1..=self.harmonics {
            let half = phasor(coeffs, k) * 0.5;
            spectrum[k] += half;
            spectrum[n - k] += half.conj();
        }
        in_place(&*self.inverse, spectrum, scratch);
        for (o, s) in out.iter_mut().zip(spectrum.iter()) {
            *o = s.re;
        }
    }

    /// Q: the discrete Fourier projection of `samples` (length N) onto M coefficients.
    pub fn to_coefficients(&self, samples: &[f64], out: &mut [f64]) {
        self.to_coefficients_with(samples, out, &mut FftWork::default());
    }

    /// `to_coefficients` in the work space `work`.
    pub fn to_coefficients_with(&self, samples: &[f64], out: &mut [f64], work: &mut FftWork) {
        let n = self.samples;
        let FftWork { spectrum, scratch } = work;
        spectrum.clear();
        spectrum.extend(samples.iter().map(|&x| Complex64::new(x, 0.0)));
        self.forward_with(spectrum, scratch);
        let scale = 1.0 / n as f64;
        out[0] = spectrum[0].re * scale;
        for (k, &z) in spectrum.iter().enumerate().take(self.harmonics + 1).skip(1) {
            set_phasor(out, k, z * (2.0 * scale));
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
                p[s * m + cos_index(k)] = cos;
                p[s * m + sin_index(k)] = sin;
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

/// The forward and inverse FFT plans of length N, planned once per process: a Newton run
/// makes a sampler per N, and rustfft's planning (twiddles, the algorithm's choice) cost 3%
/// of the reference strip's Newton at H = 40 when each planned its own.
/// `fft` of `buffer` in place, its scratch in `scratch` (sized here: `Fft::process`
/// allocates it on every call).
fn in_place(fft: &dyn Fft<f64>, buffer: &mut [Complex64], scratch: &mut Vec<Complex64>) {
    scratch.resize(fft.get_inplace_scratch_len(), Complex64::new(0.0, 0.0));
    fft.process_with_scratch(buffer, scratch);
}

fn plans(samples: usize) -> (Arc<dyn Fft<f64>>, Arc<dyn Fft<f64>>) {
    type Plans = HashMap<usize, (Arc<dyn Fft<f64>>, Arc<dyn Fft<f64>>)>;
    static PLANS: OnceLock<Mutex<(FftPlanner<f64>, Plans)>> = OnceLock::new();
    let cache = PLANS.get_or_init(|| Mutex::new((FftPlanner::new(), HashMap::new())));
    let mut guard = cache.lock().unwrap_or_else(|e| e.into_inner());
    let (planner, plans) = &mut *guard;
    plans
        .entry(samples)
        .or_insert_with(|| {
            (
                planner.plan_fft_forward(samples),
                planner.plan_fft_inverse(samples),
            )
        })
        .clone()
}

/// The value alone at t, Σ_k Re(z_k e^{ikωt}), with e^{ikωt} by repeated multiplication by
/// e^{iωt}: one sine and cosine per call instead of `evaluate`'s three rotors per harmonic
/// (the summary's and the output's contact histories evaluate every node's multipliers at
/// every sample). The recurrence's round-off grows like k ε, 1e-14 at k = 40.
pub fn value(coeffs: &[f64], omega: f64, t: f64) -> f64 {
    let harmonics = (coeffs.len() - 1) / 2;
    let step = c64::from_polar(1.0, omega * t);
    let (mut rot, mut out) = (c64::new(1.0, 0.0), 0.0);
    for k in 0..=harmonics {
        out += (phasor(coeffs, k) * rot).re;
        rot *= step;
    }
    out
}

/// Evaluate the series (and its first two time derivatives) at time `t`.
pub fn evaluate(coeffs: &[f64], omega: f64, t: f64) -> [f64; 3] {
    let harmonics = (coeffs.len() - 1) / 2;
    let mut out = [0.0; 3];
    for k in 0..=harmonics {
        let z = phasor(coeffs, k);
        for (d, o) in out.iter_mut().enumerate() {
            *o += (z * rotor(k, omega, t, d as u32)).re;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: the value by the rotation recurrence equals `evaluate`'s (one rotor per
    /// harmonic) to round-off at H = 40 over a period (where the histories evaluate it).
    #[test]
    fn value_by_recurrence_equals_the_rotor_sum() {
        let h = 40;
        let coeffs: Vec<f64> = (0..2 * h + 1)
            .map(|m| ((m * 37 + 5) % 11) as f64 / 11.0 - 0.4)
            .collect();
        let scale: f64 = coeffs.iter().map(|c| c.abs()).sum();
        let period = 2.0 * std::f64::consts::PI / 7700.0;
        for j in 0..97 {
            let t = j as f64 * period / 97.0;
            let (fast, slow) = (value(&coeffs, 7700.0, t), evaluate(&coeffs, 7700.0, t)[0]);
            assert!(
                (fast - slow).abs() < 1e-13 * scale,
                "t = {t}: {fast} vs {slow}"
            );
        }
    }

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
