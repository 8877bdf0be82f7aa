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
//!   n = i·r + g; P the samples of Re Σ_j z_j E_j(t) and Q = L_K⁻¹ Pᵀ W with W the weights
//!   of T⁻¹∫, both factored through the circulant diagonalization: P = (local B-spline
//!   values, p + 1 per sample) ∘ (inverse real DFT over the S coefficients), and
//!   Q = (DFT, divided per frequency by S² â_j) ∘ Pᵀ W; Q P = I on the kept frequencies,
//!   since the quadrature of φᵀφ is exact.

use num_complex::Complex64;

use super::basis::{cardinal, SplineSampler, TimeBasis};
use super::fourier::{self, cos_index, phasor, sin_index, Sampler};

/// Samples per segment a spline contact solve uses unless `harmonic_balance.samples` says
/// otherwise.
pub const SPLINE_SAMPLES_PER_SEGMENT: usize = 8;

/// The work space of `ContactSampler`'s maps (the FFT's for Fourier, the spline
/// coefficients' vectors for splines), kept by a caller in a loop (the contact Newton's
/// residual and activity blocks) so that they allocate nothing.
#[derive(Default)]
pub struct SamplerWork {
    pub(super) fft: fourier::FftWork,
    pub(super) a: Vec<f64>,
    pub(super) b: Vec<f64>,
    pub(super) c: Vec<f64>,
    pub(super) d: Vec<f64>,
}

/// P and Q of the contact terms for one basis, H and N.
pub enum ContactSampler {
    Fourier(Sampler),
    Spline(SplineMaps),
}

/// P and Q of a spline basis in factored form (see the header): the real DFT over the
/// segments, and the B-spline values at the Gauss points.
pub struct SplineMaps {
    pub harmonics: usize,
    pub samples: usize,
    segments: usize,
    degree: usize,
    /// B(u_g + r) at point g of a segment, row g, r = 0..=p.
    values: Vec<f64>,
    /// w_g, the Gauss weights on [0, 1].
    weights: Vec<f64>,
    /// κ_j = w_j/(S² â_j) (w_j = 1 at j = 0 and at the Nyquist frequency, else 2).
    kappa: Vec<f64>,
    /// cos(θ_j n), sin(θ_j n), row j = 0..=H, n = 0..S−1.
    cos: Vec<f64>,
    sin: Vec<f64>,
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
        self.to_samples_with(coeffs, out, &mut SamplerWork::default());
    }

    /// `to_samples` in the work space `work`.
    pub fn to_samples_with(&self, coeffs: &[f64], out: &mut [f64], work: &mut SamplerWork) {
        match self {
            ContactSampler::Fourier(s) => s.to_samples_with(coeffs, out, &mut work.fft),
            ContactSampler::Spline(s) => s.to_samples(coeffs, out, &mut work.a),
        }
    }

    /// Q: the coefficients (length M) of the projection of `samples` (length N).
    pub fn to_coefficients(&self, samples: &[f64], out: &mut [f64]) {
        self.to_coefficients_with(samples, out, &mut SamplerWork::default());
    }

    /// `to_coefficients` in the work space `work`.
    pub fn to_coefficients_with(&self, samples: &[f64], out: &mut [f64], work: &mut SamplerWork) {
        match self {
            ContactSampler::Fourier(s) => s.to_coefficients_with(samples, out, &mut work.fft),
            ContactSampler::Spline(s) => s.to_coefficients(samples, out, &mut work.a),
        }
    }

    /// A = Q diag(s) P (M × M, row-major) from the slopes `s` at the N samples.
    pub fn activity_block(&self, slopes: &[f64], out: &mut [f64]) {
        self.activity_block_with(slopes, out, &mut SamplerWork::default());
    }

    /// `activity_block` in the work space `work`.
    pub fn activity_block_with(&self, slopes: &[f64], out: &mut [f64], work: &mut SamplerWork) {
        match self {
            ContactSampler::Fourier(s) => activity_block_with(s, slopes, out, work),
            ContactSampler::Spline(s) => s.activity_block(slopes, out, work),
        }
    }

    /// Dense P (N × M, row-major).
    pub fn p_matrix(&self) -> Vec<f64> {
        match self {
            ContactSampler::Fourier(s) => s.p_matrix(),
            ContactSampler::Spline(s) => s.p_matrix(),
        }
    }

    /// Dense Q (M × N, row-major).
    pub fn q_matrix(&self) -> Vec<f64> {
        match self {
            ContactSampler::Fourier(s) => s.q_matrix(),
            ContactSampler::Spline(s) => s.q_matrix(),
        }
    }
}

impl SplineMaps {
    /// The maps on frequencies 0..=`harmonics` (≤ S/2) at the sampler's Gauss points.
    pub fn new(sampler: &SplineSampler, harmonics: usize) -> Self {
        let basis = &sampler.basis;
        let (s, p) = (basis.segments, basis.degree);
        let harmonics = harmonics.min(s / 2);
        let weights = sampler.weights();
        let values = sampler
            .points()
            .iter()
            .flat_map(|&u| (0..=p).map(move |r| cardinal(p, 0, u + r as f64)))
            .collect();
        let two_pi = 2.0 * std::f64::consts::PI;
        let kappa = (0..=harmonics)
            .map(|j| {
                let (a, _, _) = basis.eigenvalues(j, two_pi);
                let weight = if j == 0 || 2 * j == s { 1.0 } else { 2.0 };
                weight / (s as f64 * s as f64 * a)
            })
            .collect();
        let angle = |j: usize, n: usize| two_pi * ((j * n) % s) as f64 / s as f64;
        let table = |f: fn(f64) -> f64| -> Vec<f64> {
            (0..=harmonics)
                .flat_map(|j| (0..s).map(move |n| f(angle(j, n))))
                .collect()
        };
        SplineMaps {
            harmonics,
            samples: sampler.samples(),
            segments: s,
            degree: p,
            values,
            weights,
            kappa,
            cos: table(f64::cos),
            sin: table(f64::sin),
        }
    }

    fn coefficients(&self) -> usize {
        2 * self.harmonics + 1
    }

    fn per_segment(&self) -> usize {
        self.weights.len()
    }

    /// The spline coefficients ũ_n = Σ_j a_j cos θ_j n + b_j sin θ_j n of phasors `coeffs`,
    /// into `u`.
    fn synthesize(&self, coeffs: &[f64], u: &mut Vec<f64>) {
        let s = self.segments;
        u.clear();
        u.resize(s, coeffs[0]);
        for j in 1..=self.harmonics {
            let (a, b) = (coeffs[cos_index(j)], coeffs[sin_index(j)]);
            let (c, sn) = (&self.cos[j * s..(j + 1) * s], &self.sin[j * s..(j + 1) * s]);
            for (n, un) in u.iter_mut().enumerate() {
                *un += a * c[n] + b * sn[n];
            }
        }
    }

    /// P: y_{i,g} = Σ_r B(u_g + r) ũ_{i−r} (`u` work space).
    fn to_samples(&self, coeffs: &[f64], out: &mut [f64], u: &mut Vec<f64>) {
        let (s, p, per) = (self.segments, self.degree, self.per_segment());
        self.synthesize(coeffs, u);
        for i in 0..s {
            for g in 0..per {
                let row = &self.values[g * (p + 1)..(g + 1) * (p + 1)];
                out[i * per + g] = (0..=p).map(|r| row[r] * u[(i + s - r % s) % s]).sum();
            }
        }
    }

    /// Q: v = Pᵀ W y on the spline coefficients, then a_j = κ_j Σ_n v_n cos θ_j n and
    /// b_j = κ_j Σ_n v_n sin θ_j n (L_K⁻¹ per frequency).
    fn to_coefficients(&self, samples: &[f64], out: &mut [f64], v: &mut Vec<f64>) {
        let (s, p, per) = (self.segments, self.degree, self.per_segment());
        v.clear();
        v.resize(s, 0.0);
        for i in 0..s {
            for g in 0..per {
                let wy = self.weights[g] * samples[i * per + g];
                let row = &self.values[g * (p + 1)..(g + 1) * (p + 1)];
                for (r, b) in row.iter().enumerate() {
                    v[(i + s - r % s) % s] += b * wy;
                }
            }
        }
        self.project(v, out);
    }

    /// The phasors of L_K⁻¹-weighted coefficient-space values `v` (the DFT half of Q).
    fn project(&self, v: &[f64], out: &mut [f64]) {
        let s = self.segments;
        for j in 0..=self.harmonics {
            let (c, sn) = (&self.cos[j * s..(j + 1) * s], &self.sin[j * s..(j + 1) * s]);
            let a: f64 = v.iter().zip(c).map(|(x, y)| x * y).sum();
            out[cos_index(j)] = self.kappa[j] * a;
            if j > 0 {
                let b: f64 = v.iter().zip(sn).map(|(x, y)| x * y).sum();
                out[sin_index(j)] = self.kappa[j] * b;
            }
        }
    }

    /// A = Q diag(s) P: the banded S × S matrix Pᵀ W diag(s) P on the spline coefficients
    /// (bandwidth p; only samples with a nonzero slope contribute), then the DFT on both
    /// sides: S·(2p+1)·M + S·M² per node instead of N·M².
    fn activity_block(&self, slopes: &[f64], out: &mut [f64], work: &mut SamplerWork) {
        let (s, p, per, m) = (
            self.segments,
            self.degree,
            self.per_segment(),
            self.coefficients(),
        );
        let width = 2 * p + 1;
        // band[n * width + (d + p)] = entry (n, n + d).
        let SamplerWork {
            a: band,
            b: column,
            c: banded,
            d: projected,
            ..
        } = work;
        band.clear();
        band.resize(s * width, 0.0);
        for (k, &slope) in slopes.iter().enumerate().filter(|(_, &v)| v != 0.0) {
            let (i, g) = (k / per, k % per);
            let row = &self.values[g * (p + 1)..(g + 1) * (p + 1)];
            let ws = self.weights[g] * slope;
            for r1 in 0..=p {
                let n = (i + s - r1 % s) % s;
                for r2 in 0..=p {
                    band[n * width + (r1 + p - r2)] += row[r1] * ws * row[r2];
                }
            }
        }
        // Column b of P on the coefficients is cos θ_j n or sin θ_j n; T = band · that.
        column.resize(s, 0.0);
        banded.resize(s, 0.0);
        projected.resize(m, 0.0);
        for b in 0..m {
            let j = fourier::harmonic_of(b);
            let table = if b > 0 && b % 2 == 0 {
                &self.sin
            } else {
                &self.cos
            };
            column.copy_from_slice(&table[j * s..(j + 1) * s]);
            for (n, t) in banded.iter_mut().enumerate() {
                *t = (0..width)
                    .map(|q| band[n * width + q] * column[(n + s * (p + 1) + q - p) % s])
                    .sum();
            }
            self.project(banded, projected);
            for (a, &v) in projected.iter().enumerate() {
                out[a * m + b] = v;
            }
        }
    }

    /// Dense P (N × M): P applied to the unit coefficient vectors.
    fn p_matrix(&self) -> Vec<f64> {
        let (m, n) = (self.coefficients(), self.samples);
        dense(n, m, |e, col| self.to_samples(e, col, &mut Vec::new()))
    }

    /// Dense Q (M × N): Q applied to the unit sample vectors.
    fn q_matrix(&self) -> Vec<f64> {
        let (m, n) = (self.coefficients(), self.samples);
        dense(m, n, |e, col| self.to_coefficients(e, col, &mut Vec::new()))
    }
}

/// A_i = Q diag(s) P (M × M, row-major) from the slopes `s` at the N samples, Fourier basis
/// (a spline basis forms it in `SplineMaps`). A_i is a Toeplitz-plus-Hankel matrix in the
/// harmonics, so it follows from one FFT of the slopes and M² lookups (`step`'s header).
pub fn activity_block(sampler: &Sampler, slopes: &[f64], out: &mut [f64]) {
    activity_block_with(sampler, slopes, out, &mut SamplerWork::default());
}

/// `activity_block` in the work space `work`.
pub fn activity_block_with(
    sampler: &Sampler,
    slopes: &[f64],
    out: &mut [f64],
    work: &mut SamplerWork,
) {
    let (h, n) = (sampler.harmonics, sampler.samples);
    let m = 2 * h + 1;
    let SamplerWork {
        fft,
        a: c_table,
        b: s_table,
        ..
    } = work;
    let spectrum = &mut fft.spectrum;
    spectrum.clear();
    spectrum.extend(slopes.iter().map(|&v| Complex64::new(v, 0.0)));
    sampler.forward_with(spectrum, &mut fft.scratch);
    // Ĉ_j = mean(s cos jθ) and Ŝ_j = mean(s sin jθ) for j = 0..2H (2H < N); Ĉ is even in j,
    // Ŝ odd.
    let scale = 1.0 / n as f64;
    c_table.clear();
    c_table.extend(spectrum[..=2 * h].iter().map(|z| z.re * scale));
    s_table.clear();
    s_table.extend(spectrum[..=2 * h].iter().map(|z| -z.im * scale));
    let c_hat = |j: i64| c_table[j.unsigned_abs() as usize];
    let s_hat = |j: i64| s_table[j.unsigned_abs() as usize] * j.signum() as f64;
    // Basis p_a: index 0 the constant (cos 0θ), 2k−1 cos kθ, 2k sin kθ; harmonics p (rows)
    // and q (columns) fill their cos/sin block, weight 1 for the constant's row, else 2.
    for p in 0..=h {
        let weight = if p == 0 { 1.0 } else { 2.0 };
        for q in 0..=h {
            let (pi, qi) = (p as i64, q as i64);
            let (difference, sum) = (pi - qi, pi + qi);
            let cos_cos = 0.5 * (c_hat(difference) + c_hat(sum));
            let cos_sin = 0.5 * (s_hat(sum) - s_hat(difference));
            out[cos_index(p) * m + cos_index(q)] = weight * cos_cos;
            if q > 0 {
                out[cos_index(p) * m + sin_index(q)] = weight * cos_sin;
            }
            if p > 0 {
                let sin_cos = 0.5 * (s_hat(sum) + s_hat(difference));
                out[sin_index(p) * m + cos_index(q)] = weight * sin_cos;
                if q > 0 {
                    let sin_sin = 0.5 * (c_hat(difference) - c_hat(sum));
                    out[sin_index(p) * m + sin_index(q)] = weight * sin_sin;
                }
            }
        }
    }
}

/// The value at t of the function with coefficients `coeffs` (M = 2H + 1, phasors of the
/// basis' frequencies 0..H) for period 2π/ω: Fourier's series, or Re Σ_j z_j E_j(t).
pub fn evaluate(basis: &TimeBasis, coeffs: &[f64], omega: f64, t: f64) -> f64 {
    match basis {
        TimeBasis::Fourier => fourier::value(coeffs, omega, t),
        TimeBasis::Spline(s) => {
            let count = coeffs.len().div_ceil(2);
            let rotors = s.rotors(count, omega, t, 0);
            (0..count).map(|k| (phasor(coeffs, k) * rotors[k]).re).sum()
        }
    }
}

/// The row-major `rows` × `cols` matrix of the linear map `apply` (input of length `cols`,
/// output of length `rows`): its columns are `apply` of the unit vectors.
fn dense(rows: usize, cols: usize, apply: impl Fn(&[f64], &mut [f64])) -> Vec<f64> {
    let (mut a, mut e, mut col) = (vec![0.0; rows * cols], vec![0.0; cols], vec![0.0; rows]);
    for j in 0..cols {
        e.iter_mut().for_each(|v| *v = 0.0);
        e[j] = 1.0;
        apply(&e, &mut col);
        for (i, v) in col.iter().enumerate() {
            a[i * cols + j] = *v;
        }
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: the activity block from the slopes' Fourier sums equals Q diag(s) P formed
    /// densely, for 0/1 and smoothed slopes (the trigonometric product identities, exact on
    /// the samples because 2H < N).
    #[test]
    fn activity_block_from_spectrum_equals_dense_q_s_p() {
        for (h, n) in [(0usize, 1usize), (1, 3), (3, 16), (5, 11), (8, 128)] {
            let sampler = Sampler::new(h, n);
            let m = 2 * h + 1;
            let (p, q) = (sampler.p_matrix(), sampler.q_matrix());
            for smooth in [false, true] {
                let slopes: Vec<f64> = (0..n)
                    .map(|s| {
                        let x = ((s * 37 + 11) % 17) as f64 / 17.0;
                        if smooth {
                            x
                        } else {
                            (x > 0.4) as u8 as f64
                        }
                    })
                    .collect();
                let mut fast = vec![0.0; m * m];
                activity_block(&sampler, &slopes, &mut fast);
                for a in 0..m {
                    for b in 0..m {
                        let dense: f64 = (0..n)
                            .map(|s| q[a * n + s] * slopes[s] * p[s * m + b])
                            .sum();
                        assert!(
                            (dense - fast[a * m + b]).abs() < 1e-12,
                            "H = {h}, N = {n}, ({a}, {b}): {dense} vs {}",
                            fast[a * m + b]
                        );
                    }
                }
            }
        }
    }
}
