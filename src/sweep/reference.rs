//! The linear reference a contact sweep draws beside its curve, as frequency-response figures of
//! this field do: the probe's first-harmonic amplitude of the same discrete structure with the
//! contact open, and the gap where the probe sits on the contact.
//!
//! Formulas and glossary:
//! - U(ω) = Z_1(ω)⁻¹ f_1(ω) the free dofs' first-harmonic amplitude without contact, Z_1 = a K + b M
//!   (`System::coefficients`: a = 1 + iωβ, b = −ω² + iωα with Rayleigh damping, plus the
//!   spin shift where the speed follows ω) and f_1 the harmonic-1 load (prescribed motion
//!   included); Fourier harmonic 1 whatever the sweep's basis: the physics, not the
//!   discretization;
//! - the probe's amplitude max(|ū_x|, |ū_y|), ū the mean of U over the probe group's nodes
//!   (`probe_first_harmonic`'s definition);
//! - not a factorization per frequency: K φ_n = λ_n M φ_n, φ_nᵀ M φ_n = 1 diagonalize Z_1, so
//!   U(ω) = Σ_{n∈N} φ_n φ_nᵀ f(ω) / (a λ_n + b) + R(ω), N the modes nearest the band's centre
//!   (shift-invert at ω_c², as many as reach both ends of the band in λ), R the rest (modes
//!   far from the band), smooth over it: R is formed exactly at three anchors (the band's ends
//!   and centre, one factorization each) and interpolated quadratically in ω;
//! - `check_error`: at a fourth frequency, 30% into the band, the reference against the exact
//!   solve, relative.
//!
//! Cost: one real factorization and a few dozen solves (the modes), four complex
//! factorizations of Z_1, then a sum over N per plotted frequency.

use faer::c64;
use schemars::JsonSchema;
use serde::Serialize;

use crate::fem::modes::{modes_near, Mode};
use crate::hbm::basis::TimeBasis;
use crate::hbm::System;
use crate::pipeline::model::Model;
use crate::Result;

/// The fewest and most modes taken near the band (doubled from the first until the band is
/// covered).
const MODES: [usize; 2] = [8, 128];
/// Frequencies evenly spaced over the band, besides the sweep's own and each in-band mode's.
const EVEN: usize = 300;
/// Offsets from an in-band mode in its half-power widths ζ_n ω_n, so that its peak is drawn.
const AROUND_MODE: [f64; 9] = [-3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0];

/// The probe's linear (contact-open) first-harmonic amplitude over the sweep's band.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct LinearReference {
    /// The frequencies [Hz], ascending: the sweep's rows', evenly spaced ones and each in-band
    /// mode's neighbourhood.
    pub frequency_hz: Vec<f64>,
    /// |ū_1| [m] at each frequency (non-finite at an undamped natural frequency: null).
    pub probe_first_harmonic: Vec<Option<f64>>,
    /// The modes summed (the rest interpolated between three exact solves).
    pub modes: usize,
    /// The reference against an exact solve at `check_hz`, relative.
    pub check_error: f64,
    pub check_hz: f64,
}

/// The linear reference for frequencies `rows_hz` and the band [from, to] Hz: `None` without
/// a probe or a harmonic-1 load; an error where Z_1 or the modes cannot be formed (the sweep
/// then warns and draws none).
pub fn linear_reference(
    model: &Model,
    band_hz: [f64; 2],
    rows_hz: &[f64],
) -> Result<Option<LinearReference>> {
    let Some((_, nodes)) = model.probes.first() else {
        return Ok(None);
    };
    let mut system = model.system.clone().with_basis(TimeBasis::Fourier);
    if !system.inputs.contains_key(&1) {
        return Ok(None);
    }
    let two_pi = 2.0 * std::f64::consts::PI;
    let (lo, hi) = (band_hz[0].min(band_hz[1]), band_hz[0].max(band_hz[1]));
    let omega = [lo, 0.5 * (lo + hi), hi].map(|f| two_pi * f);
    let modes = band_modes(&system, [omega[0], omega[2]])?;
    let probe = Probe::new(&system, nodes);
    let mut reference = Reference {
        modal: modes
            .iter()
            .map(|(l, phi)| (*l, probe.of_real(phi), phi))
            .collect(),
        rest: Vec::new(),
        anchors: omega,
    };
    for w in omega {
        let exact = exact(&mut system, &probe, w)?;
        let modal = reference.modal_sum(&mut system, w);
        reference
            .rest
            .push([exact[0] - modal[0], exact[1] - modal[1]]);
    }
    let check = omega[0] + 0.3 * (omega[2] - omega[0]);
    let want = exact(&mut system, &probe, check)?;
    let got = reference.at(&mut system, check);
    let check_error = amplitude(sub(got, want)) / amplitude(want).max(f64::MIN_POSITIVE);
    let frequency_hz = frequencies(&system, &modes, [lo, hi], rows_hz);
    let probe_first_harmonic = frequency_hz
        .iter()
        .map(|f| Some(amplitude(reference.at(&mut system, two_pi * f))).filter(|a| a.is_finite()))
        .collect();
    Ok(Some(LinearReference {
        frequency_hz,
        probe_first_harmonic,
        modes: modes.len(),
        check_error,
        check_hz: check / two_pi,
    }))
}

/// The modes nearest the band's centre in λ = ω², as many as reach both its ends (or all the
/// model has, or `MODES[1]`).
fn band_modes(system: &System, [w0, w1]: [f64; 2]) -> Result<Vec<Mode>> {
    let (l0, l1) = (w0 * w0, w1 * w1);
    let centre = 0.5 * (l0 + l1);
    let pattern = system.lu_pattern().ok();
    let mut count = MODES[0];
    loop {
        let count_now = count.min(system.free_count());
        let modes = modes_near(&system.k_ff, &system.m_ff, count_now, centre, pattern)?;
        let reach = modes
            .iter()
            .map(|(l, _)| (l - centre).abs())
            .fold(0.0, f64::max);
        let covered = reach >= 0.5 * (l1 - l0);
        if covered || modes.len() < count_now || count >= MODES[1] {
            return Ok(modes);
        }
        count *= 2;
    }
}

/// The probe group's mean as a functional of the free and prescribed dofs, per component.
struct Probe {
    /// Per component: (free index, weight) and (prescribed index, weight).
    free: [Vec<(usize, f64)>; 2],
    held: [Vec<(usize, f64)>; 2],
}

impl Probe {
    fn new(system: &System, nodes: &[usize]) -> Self {
        let w = 1.0 / nodes.len().max(1) as f64;
        let (mut free, mut held) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
        for &n in nodes {
            for c in 0..2 {
                let d = 2 * n + c;
                if let Some(i) = system.dofs.free_index(d) {
                    free[c].push((i, w));
                } else if let Some(j) = system.dofs.prescribed_index(d) {
                    held[c].push((j, w));
                }
            }
        }
        Probe { free, held }
    }

    fn of_real(&self, x: &[f64]) -> [f64; 2] {
        [0, 1].map(|c| self.free[c].iter().map(|&(i, w)| w * x[i]).sum())
    }

    fn of(&self, x: &[c64], motion: &[c64]) -> [c64; 2] {
        [0, 1].map(|c| {
            let f: c64 = self.free[c].iter().map(|&(i, w)| x[i] * w).sum();
            let h: c64 = self.held[c].iter().map(|&(j, w)| motion[j] * w).sum();
            f + h
        })
    }
}

/// The probe's exact U(ω): Z_1(ω) factored and solved.
fn exact(system: &mut System, probe: &Probe, omega: f64) -> Result<[c64; 2]> {
    system.omega = omega;
    let lu = system.factor(1, None)?;
    let u = lu.solve(&system.load(1));
    Ok(probe.of(&u, &system.motion(1)))
}

/// The modal sum over N and the rest R at the three anchors.
struct Reference<'a> {
    /// (λ_n, φ_n at the probe, φ_n).
    modal: Vec<(f64, [f64; 2], &'a Vec<f64>)>,
    rest: Vec<[c64; 2]>,
    anchors: [f64; 3],
}

impl Reference<'_> {
    /// Σ_n φ_n(probe) φ_nᵀ f(ω) / (a λ_n + b) (a held probe dof's motion is in R).
    fn modal_sum(&self, system: &mut System, omega: f64) -> [c64; 2] {
        system.omega = omega;
        let f = system.load(1);
        let c = system.coefficients(1, omega);
        let mut sum = [c64::new(0.0, 0.0); 2];
        for (lambda, at, phi) in &self.modal {
            let force: c64 = phi.iter().zip(&f).map(|(p, fi)| fi * *p).sum();
            let q = force / (c.a * *lambda + c.b);
            sum = [sum[0] + q * at[0], sum[1] + q * at[1]];
        }
        sum
    }

    /// The reference at ω: the modal sum and R interpolated (Lagrange, three anchors).
    fn at(&self, system: &mut System, omega: f64) -> [c64; 2] {
        let modal = self.modal_sum(system, omega);
        let w = self.anchors;
        let l = |i: usize| {
            (0..3)
                .filter(|&j| j != i)
                .map(|j| (omega - w[j]) / (w[i] - w[j]))
                .product::<f64>()
        };
        let mut out = modal;
        for (i, r) in self.rest.iter().enumerate() {
            let li = l(i);
            out = [out[0] + r[0] * li, out[1] + r[1] * li];
        }
        out
    }
}

fn sub(a: [c64; 2], b: [c64; 2]) -> [c64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn amplitude(u: [c64; 2]) -> f64 {
    u[0].norm().max(u[1].norm())
}

/// The rows' frequencies, `EVEN` evenly spaced ones and each in-band mode's neighbourhood,
/// ascending, within the band.
fn frequencies(system: &System, modes: &[Mode], [lo, hi]: [f64; 2], rows_hz: &[f64]) -> Vec<f64> {
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut out: Vec<f64> = (0..=EVEN)
        .map(|j| lo + (hi - lo) * j as f64 / EVEN as f64)
        .chain(rows_hz.iter().copied())
        .collect();
    for (lambda, _) in modes {
        let wn = lambda.max(0.0).sqrt();
        let zeta = crate::fem::modes::rayleigh_damping_ratio(system.rayleigh, wn).max(1e-4);
        out.extend(AROUND_MODE.iter().map(|t| wn * (1.0 + zeta * t) / two_pi));
    }
    out.retain(|f| f.is_finite() && *f >= lo && *f <= hi);
    out.sort_by(f64::total_cmp);
    out.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * hi);
    out
}

/// The gap where the probe sits on the contact: every probe node has a row against a rigid,
/// fixed obstacle (no gap harmonics, no target body) whose normal lies along x or y, and
/// their initial gaps agree within 1%: their mean [m]. `None` otherwise.
pub fn probe_gap(model: &Model) -> Option<f64> {
    let (_, nodes) = model.probes.first()?;
    let contact = model.contact.as_ref()?;
    if !contact.operator.gap_harmonics.is_empty() {
        return None;
    }
    let set = &contact.set;
    let mut gaps = Vec::new();
    for n in nodes {
        let row = set.nodes.iter().position(|m| m == n)?;
        let [nx, ny] = set.normals[row];
        let along_axis = nx.abs().max(ny.abs()) > 0.99;
        let rigid = set.targets.get(row).is_none_or(|t| t.is_empty());
        if !(along_axis && rigid) {
            return None;
        }
        gaps.push(set.gaps[row]);
    }
    let mean = gaps.iter().sum::<f64>() / gaps.len().max(1) as f64;
    let spread = gaps.iter().map(|g| (g - mean).abs()).fold(0.0, f64::max);
    (mean > 0.0 && spread <= 0.01 * mean).then_some(mean)
}
