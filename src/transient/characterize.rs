//! What a late response is when it is not T-periodic: periodic, a k·T subharmonic (k ≤ 8),
//! quasi-periodic (a second, incommensurate frequency) or irregular (broadband), from signals
//! sampled R times a period over L whole periods (`late::LateRecord`; docs/method.md, "The
//! late response").
//!
//! Formulas and glossary:
//! - y_s(t_i), i = 0 … LR − 1: signal s (a probe's displacement, the total contact force)
//!   minus its mean and divided by its RMS, so every signal weighs alike;
//! - the fold of period kT: ȳ_s,k(φ) = (1/J) Σ_j y_s(φ + jkT) over the J = ⌊L/k⌋ last
//!   whole repeats, φ one of the kR phases; its residual
//!   ρ_k = (Σ_s Σ_i (y_s − ȳ_s,k)² / Σ_s Σ_i y_s²)^½ over those JkR samples: 0 when every
//!   signal repeats after kT, ≈ 1 when it has nothing periodic in kT;
//! - periodic when ρ_1 < `REPEATS`; a k·T subharmonic for the least k = 2 … 8 with
//!   ρ_k < `REPEATS` (and J ≥ 2);
//! - otherwise the spectrum decides: X_s(b) = Σ_i w_i y_s(t_i) e^{−2πi b i/(LR)}, Hann weights
//!   w_i = sin²(πi/(LR)), bin b at ν = b/L multiples of the drive frequency f; the power
//!   P(b) = Σ_s |X_s(b)|²; a line is a local maximum of P, its frequency refined by the
//!   parabola through ln P at b − 1, b, b + 1 (Hann: a bias below 1% of a bin);
//! - the line fraction η = the power within ±2 bins (the Hann main lobe) of the `LINES`
//!   strongest lines over the total (bins 1 … LR/2): ≈ 1 for a sum of sinusoids, small for
//!   noise;
//! - quasi-periodic when η ≥ `LINE_SHARE` and the strongest line off the drive's harmonics
//!   (more than `OFF_HARMONIC` bins from every m f) is at ν′: its second frequency
//!   f₂ = |ν′ − round(ν′)| f ∈ (0, f/2] (the combinations m f ± f₂ fold to it); irregular
//!   otherwise, or periodic (still drifting: ρ_1 ≥ `REPEATS`) when every line is a harmonic.
//!
//! A Neimark–Sacker bifurcation predicts f₂ = |arg μ|/(2π) f, a period doubling f/2: both
//! compare with `second_frequency`, or with f/2 for a 2T subharmonic.

use std::f64::consts::PI;

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;

/// ρ_k below this repeats (1% of the signals' RMS).
pub const REPEATS: f64 = 0.01;
/// The largest subharmonic order looked for.
pub const MAX_MULTIPLE: usize = 8;
/// Lines counted in the line fraction.
pub const LINES: usize = 24;
/// η at or above this is a line spectrum.
pub const LINE_SHARE: f64 = 0.9;
/// A line farther than this many bins from every harmonic is off the harmonics.
pub const OFF_HARMONIC: f64 = 1.5;

/// What the late response is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Periodic,
    /// Repeats after k periods, not after one.
    Subharmonic(usize),
    QuasiPeriodic,
    Irregular,
}

/// A line of the spectrum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// ν, in multiples of the drive frequency.
    pub frequency: f64,
    /// Its power over the strongest line's.
    pub relative_power: f64,
}

/// The verdict on a late response.
#[derive(Clone, Debug)]
pub struct Characterization {
    pub kind: Kind,
    /// L, the whole periods analysed.
    pub periods: usize,
    /// ρ_k for k = 1, 2, … (those with J ≥ 2).
    pub fold_residuals: Vec<f64>,
    /// f₂/f (quasi-periodic and irregular: the strongest line off the harmonics, folded).
    pub second_frequency: Option<f64>,
    /// η.
    pub line_fraction: f64,
    /// The strongest lines, strongest first (at most `LINES`).
    pub lines: Vec<Line>,
}

/// The amplitude spectrum of one signal: A(b) = 2|X(b)|/Σw (a sinusoid's amplitude at its
/// bin), ν = b/L, b = 0 … LR/2 (the mean removed: A(0) = 0).
pub fn amplitude_spectrum(values: &[f64], periods: usize) -> Vec<(f64, f64)> {
    let spectrum = hann_dft(&centred(values));
    let gain: f64 = hann(values.len())
        .iter()
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    spectrum
        .iter()
        .enumerate()
        .map(|(b, x)| (b as f64 / periods.max(1) as f64, 2.0 * x.norm() / gain))
        .collect()
}

/// Characterize `signals`, each R samples a period over L whole periods (`samples_per_period`
/// = R; lengths a multiple of R, the shortest decides L).
pub fn characterize(signals: &[Vec<f64>], samples_per_period: usize) -> Characterization {
    let r = samples_per_period.max(1);
    let periods = signals.iter().map(|s| s.len() / r).min().unwrap_or(0);
    let ys: Vec<Vec<f64>> = signals
        .iter()
        .map(|s| normalized(&s[s.len() - periods * r..]))
        .filter(|y| !y.is_empty())
        .collect();
    let fold_residuals: Vec<f64> = (1..=MAX_MULTIPLE)
        .take_while(|k| periods / k >= 2)
        .map(|k| fold_residual(&ys, k * r))
        .collect();
    let repeats = |k: usize| fold_residuals.get(k - 1).is_some_and(|&rho| rho < REPEATS);
    let (lines, line_fraction) = lines(&ys, periods);
    let off = off_harmonic(&lines, periods);
    let kind = if ys.is_empty() || repeats(1) {
        Kind::Periodic
    } else if let Some(k) = (2..=fold_residuals.len()).find(|&k| repeats(k)) {
        Kind::Subharmonic(k)
    } else if off.is_none() && !lines.is_empty() {
        Kind::Periodic
    } else if line_fraction >= LINE_SHARE {
        Kind::QuasiPeriodic
    } else {
        Kind::Irregular
    };
    let second_frequency = match kind {
        Kind::QuasiPeriodic | Kind::Irregular => off.map(|nu| (nu - nu.round()).abs()),
        _ => None,
    };
    Characterization {
        kind,
        periods,
        fold_residuals,
        second_frequency,
        line_fraction,
        lines,
    }
}

/// The signal minus its mean over its RMS; empty when it does not vary (relative to its
/// size).
fn normalized(values: &[f64]) -> Vec<f64> {
    let y = centred(values);
    let rms = (y.iter().map(|v| v * v).sum::<f64>() / y.len().max(1) as f64).sqrt();
    let size = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if !(rms > 1e-12 * size && rms > 0.0 && rms.is_finite()) {
        return Vec::new();
    }
    y.iter().map(|v| v / rms).collect()
}

fn centred(values: &[f64]) -> Vec<f64> {
    let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
    values.iter().map(|v| v - mean).collect()
}

/// ρ for a fold of `len` samples over the last whole repeats.
fn fold_residual(ys: &[Vec<f64>], len: usize) -> f64 {
    let (mut off, mut size) = (0.0, 0.0);
    for y in ys {
        let repeats = y.len() / len;
        let tail = &y[y.len() - repeats * len..];
        for phase in 0..len {
            let mean = (0..repeats).map(|j| tail[phase + j * len]).sum::<f64>() / repeats as f64;
            for j in 0..repeats {
                let v = tail[phase + j * len];
                off += (v - mean).powi(2);
                size += v * v;
            }
        }
    }
    (off / size.max(f64::MIN_POSITIVE)).sqrt()
}

fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (PI * i as f64 / n as f64).sin().powi(2))
        .collect()
}

/// X(b), b = 0 … n/2, of the Hann-weighted samples.
fn hann_dft(y: &[f64]) -> Vec<Complex<f64>> {
    let n = y.len();
    let mut buffer: Vec<Complex<f64>> = y
        .iter()
        .zip(hann(n))
        .map(|(v, w)| Complex::new(v * w, 0.0))
        .collect();
    if n > 0 {
        FftPlanner::new().plan_fft_forward(n).process(&mut buffer);
    }
    buffer.truncate(n / 2 + 1);
    buffer
}

/// The spectrum's lines (strongest first, at most `LINES`) and the line fraction η.
fn lines(ys: &[Vec<f64>], periods: usize) -> (Vec<Line>, f64) {
    let mut power: Vec<f64> = Vec::new();
    for y in ys {
        let x = hann_dft(y);
        power.resize(x.len(), 0.0);
        for (p, v) in power.iter_mut().zip(&x) {
            *p += v.norm_sqr();
        }
    }
    let total: f64 = power.iter().skip(1).sum();
    if power.len() < 4 || total <= 0.0 {
        return (Vec::new(), 1.0);
    }
    let mut peaks: Vec<usize> = (1..power.len() - 1)
        .filter(|&b| power[b] > power[b - 1] && power[b] >= power[b + 1] && power[b] > 0.0)
        .collect();
    peaks.sort_by(|&a, &b| power[b].total_cmp(&power[a]));
    peaks.truncate(LINES);
    let mut covered = vec![false; power.len()];
    for &b in &peaks {
        let end = (b + 2).min(power.len() - 1);
        covered[b.saturating_sub(2)..=end].fill(true);
    }
    let in_lines: f64 = (1..power.len())
        .filter(|&b| covered[b])
        .map(|b| power[b])
        .sum();
    let strongest = peaks.first().map_or(1.0, |&b| power[b]);
    let l = periods.max(1) as f64;
    let lines = peaks
        .iter()
        .map(|&b| Line {
            frequency: (b as f64 + vertex(&power, b)) / l,
            relative_power: power[b] / strongest,
        })
        .collect();
    (lines, in_lines / total)
}

/// The offset in bins of the parabola's vertex through ln P at b − 1, b, b + 1.
fn vertex(power: &[f64], b: usize) -> f64 {
    let ln = |i: usize| power[i].max(f64::MIN_POSITIVE).ln();
    let (a, m, c) = (ln(b - 1), ln(b), ln(b + 1));
    let d = a - 2.0 * m + c;
    if d.abs() < f64::MIN_POSITIVE {
        0.0
    } else {
        (0.5 * (a - c) / d).clamp(-0.5, 0.5)
    }
}

/// The strongest line more than `OFF_HARMONIC` bins from every harmonic m f, ν.
fn off_harmonic(lines: &[Line], periods: usize) -> Option<f64> {
    let bin = 1.0 / periods.max(1) as f64;
    lines
        .iter()
        .find(|l| (l.frequency - l.frequency.round()).abs() > OFF_HARMONIC * bin)
        .map(|l| l.frequency)
}

#[cfg(test)]
mod tests {
    use super::*;

    const R: usize = 128;
    const L: usize = 64;

    /// y(t) sampled R times a period T = 1 over L periods.
    fn signal(f: impl Fn(f64) -> f64) -> Vec<f64> {
        (0..R * L).map(|i| f(i as f64 / R as f64)).collect()
    }

    fn tau(nu: f64, t: f64) -> f64 {
        (2.0 * PI * nu * t).sin()
    }

    /// TEST GOAL: a T-periodic signal with impact-like harmonics is periodic (ρ_1 at round-off).
    #[test]
    fn a_periodic_response_is_classified_as_periodic() {
        let y = signal(|t| tau(1.0, t) + 0.3 * tau(3.0, t + 0.1) + (tau(1.0, t)).max(0.0).powi(3));
        let c = characterize(&[y], R);
        assert_eq!(c.kind, Kind::Periodic);
        assert!(c.fold_residuals[0] < 1e-12, "{:?}", c.fold_residuals);
    }

    /// TEST GOAL: a response that repeats after two periods is a 2T subharmonic, its
    /// strongest off-harmonic content the line at f/2.
    #[test]
    fn a_subharmonic_response_is_classified_as_two_period() {
        let y = signal(|t| tau(1.0, t) + 0.2 * tau(0.5, t) + 0.05 * tau(1.5, t));
        let force = signal(|t| (tau(1.0, t) + 0.5 * tau(0.5, t)).max(0.0));
        let c = characterize(&[y, force], R);
        assert_eq!(c.kind, Kind::Subharmonic(2));
        assert!(c.fold_residuals[0] > 0.1, "{:?}", c.fold_residuals);
        let half = off_harmonic(&c.lines, c.periods).unwrap();
        assert!((half - 0.5).abs() < 0.01 / L as f64, "{half}");
    }

    /// TEST GOAL: a response repeating after three periods is 3T, not 2T or 6T.
    #[test]
    fn a_response_repeating_after_three_periods_is_classified_as_three_period() {
        let y = signal(|t| tau(1.0, t) + 0.1 * tau(1.0 / 3.0, t) + 0.1 * tau(2.0 / 3.0, t));
        assert_eq!(characterize(&[y], R).kind, Kind::Subharmonic(3));
    }

    /// TEST GOAL: a sum of the drive, an incommensurate frequency ν₂ = 1/π and their
    /// combinations is quasi-periodic, and the second frequency found is ν₂ to a tenth of a
    /// bin (1/L); one near the half (ν₂ = 0.493, a Neimark–Sacker pair near −1) is not taken
    /// for a period doubling.
    #[test]
    fn a_quasi_periodic_response_is_classified_with_its_second_frequency() {
        for nu2 in [1.0 / PI, 0.493] {
            let y = signal(|t| {
                tau(1.0, t)
                    + 0.3 * tau(nu2, t + 0.2)
                    + 0.1 * tau(1.0 + nu2, t)
                    + 0.05 * tau(2.0 - nu2, t)
            });
            let c = characterize(&[y], R);
            assert_eq!(c.kind, Kind::QuasiPeriodic, "ν₂ = {nu2}: {c:?}");
            let found = c.second_frequency.unwrap();
            assert!(
                (found - nu2).abs() < 0.1 / L as f64,
                "ν₂ = {nu2}: found {found}"
            );
        }
    }

    /// TEST GOAL: noise (a deterministic pseudo-random sequence) is irregular.
    #[test]
    fn broadband_noise_is_classified_as_irregular() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let y: Vec<f64> = (0..R * L)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let c = characterize(&[y], R);
        assert_eq!(c.kind, Kind::Irregular, "{c:?}");
        assert!(c.line_fraction < 0.5);
    }

    /// TEST GOAL: a sinusoid's amplitude spectrum peaks at its frequency with its amplitude.
    #[test]
    fn the_amplitude_spectrum_gives_a_sinusoids_amplitude_at_its_bin() {
        let y = signal(|t| 2.5 * tau(3.0, t) + 0.7);
        let a = amplitude_spectrum(&y, L);
        let (nu, amp) = a[3 * L];
        assert_eq!(nu, 3.0);
        assert!((amp - 2.5).abs() < 1e-9, "{amp}");
        assert!(a[0].1 < 1e-9);
    }
}
