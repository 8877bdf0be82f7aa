//! The resonance check of every `run`: the natural frequencies nearest each load-excited
//! harmonic kω, with the damping ratio the scene's Rayleigh damping gives there, and a warning
//! when kω lies within a mode's half-power band.
//!
//! Glossary and formulas (Chopra, Dynamics of Structures, §3.2 and §11.4):
//! - ω_n a natural angular frequency of K φ = ω² M φ with the scene's supports and the contact
//!   open (the model's free-dof K and M, the matrices the harmonic balance factors);
//! - ζ_n = α/(2ω_n) + βω_n/2 the modal damping ratio of D = αM + βK;
//! - r = kω/ω_n the frequency ratio, detuning r − 1;
//! - the half-power band of mode n is |ω_n − kω| ≤ ζ_n ω_n, where a single mode's response is
//!   within 1/√2 of its peak; the check uses max(ζ_n, `BAND_FLOOR`) so that a lightly damped or
//!   undamped mode warns within 1% (where its amplitude is set by the damping or the distance
//!   to resonance alone);
//! - A = 1/√((1 − r²)² + (2ζ_n r)²) the single-mode magnification over the static response.
//!
//! Cost: one shift-invert block Lanczos per load-excited harmonic, shifted to (kω)² so it
//! converges first to the modes nearest kω: one real factorization of K − (kω)²M (reusing the
//! symbolic analysis the harmonic balance made of K's pattern) and a few dozen solves. Where
//! the run computes the open structure's lowest modes anyway (a contact run's Hill check,
//! `RunModes`) and they reach above kω, the nearest are read from those instead: every mode
//! below the last one computed is among them, so a mode missing from them lies farther from
//! kω than the last one. Contact scenes compute every harmonic up to H, but only the load-excited ones
//! are checked: the others are driven by the contact forces, whose contact-closed dynamics
//! differ from these contact-open modes, and finding every mode below Hω would cost more than
//! the solve (docs/method.md §11).

use schemars::JsonSchema;
use serde::Serialize;

use super::model::Model;
use crate::fem::modes::{modes_near, rayleigh_damping_ratio, Mode};
use crate::Result;

/// The smallest half-width of the band checked, relative to ω_n.
pub const BAND_FLOOR: f64 = 0.01;

/// Modes found and reported nearest each checked harmonic.
const NEAREST: usize = 2;

/// The resonance check of a run (`summary.resonance`).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ResonanceCheck {
    /// Which harmonics were checked, and why those.
    pub scope: String,
    /// The smallest half-width of the band checked, relative to ω_n (undamped: 1%).
    pub band_floor: f64,
    /// One entry per checked harmonic.
    pub harmonics: Vec<HarmonicResonance>,
}

/// The natural frequencies nearest one harmonic.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct HarmonicResonance {
    /// The harmonic index k.
    pub k: usize,
    /// kf [Hz].
    pub frequency_hz: f64,
    /// The nearest natural frequencies (at most two), nearest first.
    pub nearest_modes: Vec<NearMode>,
}

/// One natural frequency near a harmonic.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct NearMode {
    /// f_n [Hz].
    pub frequency_hz: f64,
    /// ζ_n of the scene's Rayleigh damping (0 without).
    pub damping_ratio: f64,
    /// kf/f_n − 1: positive when the harmonic lies above the mode.
    pub detuning: f64,
    /// The band's half-width checked, max(ζ_n, band_floor).
    pub band: f64,
    /// |detuning| ≤ band: the harmonic is within the mode's half-power band.
    pub within_band: bool,
    /// 1/√((1 − r²)² + (2ζ_n r)²): a single mode's amplification over its static response.
    pub magnification: f64,
}

/// The check on the model's load-excited harmonics, and its warnings; `lowest`, where given,
/// the open structure's lowest modes, complete below their last.
pub fn check(model: &Model, lowest: Option<&[Mode]>) -> Result<(ResonanceCheck, Vec<String>)> {
    let system = &model.system;
    let ks = &model.effects.excited_harmonics;
    let mut harmonics = Vec::with_capacity(ks.len());
    for &k in ks {
        let kw = k as f64 * system.omega;
        harmonics.push(HarmonicResonance {
            k,
            frequency_hz: kw / (2.0 * std::f64::consts::PI),
            nearest_modes: nearest_modes(model, kw, lowest)?,
        });
    }
    let warnings = harmonics.iter().filter_map(|h| warning(model, h)).collect();
    let scope = if model.contact.is_some() {
        "load-excited harmonics (contact scene: the other harmonics up to H are driven by the contact forces, not checked)"
    } else {
        "load-excited harmonics (the only ones a linear scene computes)"
    };
    let check = ResonanceCheck {
        scope: scope.into(),
        band_floor: BAND_FLOOR,
        harmonics,
    };
    Ok((check, warnings))
}

/// The `count` modes of `lowest` nearest (kω)², where they are surely the nearest: no mode
/// missing from `lowest` (all lie above its last) can be nearer.
fn nearest_of(lowest: &[Mode], kw: f64, count: usize) -> Option<Vec<Mode>> {
    let last = lowest.last()?.0;
    let target = kw * kw;
    let mut near: Vec<&Mode> = lowest.iter().collect();
    near.sort_by(|a, b| (a.0 - target).abs().total_cmp(&(b.0 - target).abs()));
    near.truncate(count);
    let farthest = near.last().map_or(f64::INFINITY, |m| (m.0 - target).abs());
    (near.len() == count && farthest <= last - target).then(|| near.into_iter().cloned().collect())
}

/// The natural frequencies nearest kω (from `lowest` where they reach, else by shift-invert
/// at (kω)²), nearest first.
fn nearest_modes(model: &Model, kw: f64, lowest: Option<&[Mode]>) -> Result<Vec<NearMode>> {
    let system = &model.system;
    let count = NEAREST.min(system.free_count());
    let known = lowest.and_then(|l| nearest_of(l, kw, count));
    // An exact hit makes K − (kω)²M singular: shift a hair away and try again.
    let modes = known.or_else(|| {
        modes_near(
            &system.k_ff,
            &system.m_ff,
            count,
            kw * kw,
            system.lu_pattern().ok(),
        )
        .ok()
        .filter(|m| m.iter().all(|(w2, _)| w2.is_finite()))
    });
    let modes = match modes {
        Some(m) => m,
        None => modes_near(
            &system.k_ff,
            &system.m_ff,
            count,
            kw * kw * (1.0 - 1e-6),
            None,
        )?,
    };
    let mut near: Vec<NearMode> = modes
        .iter()
        .map(|(w2, _)| w2.max(0.0).sqrt())
        .filter(|&wn| wn > 0.0)
        .map(|wn| near_mode(system.rayleigh, wn, kw))
        .collect();
    near.sort_by(|a, b| a.detuning.abs().total_cmp(&b.detuning.abs()));
    Ok(near)
}

fn near_mode(rayleigh: Option<(f64, f64)>, wn: f64, kw: f64) -> NearMode {
    let zeta = rayleigh_damping_ratio(rayleigh, wn);
    let r = kw / wn;
    let band = zeta.max(BAND_FLOOR);
    NearMode {
        frequency_hz: wn / (2.0 * std::f64::consts::PI),
        damping_ratio: zeta,
        detuning: r - 1.0,
        band,
        within_band: (r - 1.0).abs() <= band,
        magnification: 1.0 / ((1.0 - r * r).powi(2) + (2.0 * zeta * r).powi(2)).sqrt(),
    }
}

/// The warning for a harmonic within a mode's band (the nearest such mode).
fn warning(model: &Model, h: &HarmonicResonance) -> Option<String> {
    let m = h.nearest_modes.iter().find(|m| m.within_band)?;
    let set_by = if m.damping_ratio > 0.0 {
        "the damping"
    } else {
        "the distance to resonance alone (no damping)"
    };
    let contact = if model.contact.is_some() {
        " (contact open)"
    } else {
        ""
    };
    Some(format!(
        "harmonic {} ({:.4} Hz) lies within the half-power band of the natural frequency \
         {:.4} Hz{contact} (detuning {:+.2}%, band ±{:.2}%, modal damping ζ = {:.3}%): one mode \
         there amplifies its static response {:.0}×, and the amplitude is set by {set_by}. \
         Check that this is intended, or move harmonic_balance.frequency out of the band \
         (see `hbcontact modes`)",
        h.k,
        h.frequency_hz,
        m.frequency_hz,
        100.0 * m.detuning,
        100.0 * m.band,
        100.0 * m.damping_ratio,
        m.magnification,
    ))
}
