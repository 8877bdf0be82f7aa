//! What `hbcontact transient` says about the late response: the last whole periods the march
//! recorded (`transient::late`) as the probe groups' mean displacements and the total
//! contact force, characterized by `transient::characterize` (periodic, k·T subharmonic,
//! quasi-periodic, irregular), the period-to-period spread of the contact force, and, where
//! the run has a Floquet verdict on the harmonic-balance state it started from, whether the
//! marching shows the motion that verdict predicts.
//!
//! Glossary: f the drive frequency, T = 1/f; L the periods analysed; f₂ the second frequency
//! folded into (0, f/2]; f_p the Floquet prediction, f/2 for a period doubling and
//! |arg μ|/(2π) f for a complex pair; the tolerance of a frequency comparison is two bins of
//! the record's spectrum, 2f/L. A period doubling or a complex pair agrees with a marched
//! k·T subharmonic or quasi-periodic response whose line lies within the tolerance of f_p
//! (a complex pair within it of f/2 and a period doubling are the same prediction to the
//! record's resolution); an irregular response agrees with no prediction, though its
//! strongest line off the harmonics is reported beside f_p.

use schemars::JsonSchema;
use serde::Serialize;

use super::model::Model;
use super::stability::{Stability, Verdict};
use crate::hbm::floquet::Crossing;
use crate::transient::characterize::{self, Characterization, Kind};
use crate::transient::late::LateRecord;
use crate::transient::setup::Marching;

/// The late response's signals: per probe group u_x and u_y (mean over its nodes), then the
/// total contact force (contact scenes), each with its label and unit.
pub struct LateSignals {
    pub labels: Vec<(String, &'static str)>,
    pub values: Vec<Vec<f64>>,
    /// The samples' times [s] from the start of the march.
    pub times: Vec<f64>,
    pub samples_per_period: usize,
    pub periods: usize,
}

impl LateSignals {
    pub fn of(model: &Model, marching: &Marching, late: &LateRecord) -> Self {
        let dofs = &model.system.dofs;
        let probe: Vec<Vec<f64>> = (0..marching.probes.len()).map(|d| late.probe(d)).collect();
        let samples = late.periods.len() * late.samples_per_period;
        let mut labels = Vec::new();
        let mut values = Vec::new();
        for (name, nodes) in &model.probes {
            for (c, axis) in ["x", "y"].iter().enumerate() {
                let mut mean = vec![0.0; samples];
                for &n in nodes {
                    let at = dofs
                        .free_index(2 * n + c)
                        .and_then(|fi| marching.probes.iter().position(|&p| p == fi));
                    if let Some(p) = at {
                        for (m, v) in mean.iter_mut().zip(&probe[p]) {
                            *m += v / nodes.len() as f64;
                        }
                    }
                }
                labels.push((format!("{name} u_{axis}"), "m"));
                values.push(mean);
            }
        }
        if model.contact.is_some() {
            labels.push(("total contact force".into(), "N"));
            values.push(late.force());
        }
        LateSignals {
            labels,
            values,
            times: late.times(),
            samples_per_period: late.samples_per_period,
            periods: late.periods.len(),
        }
    }

    /// The probe groups' signals (those in metres).
    pub fn probes(&self) -> impl Iterator<Item = (&str, &[f64])> {
        self.labels
            .iter()
            .zip(&self.values)
            .filter(|((_, unit), _)| *unit == "m")
            .map(|((label, _), v)| (label.as_str(), v.as_slice()))
    }
}

/// What the late response is (`transient.late_response` in summary.json).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct LateResponse {
    /// `periodic`, `subharmonic` (repeats after `multiple` periods), `quasi_periodic` (a
    /// second, incommensurate frequency) or `irregular` (broadband).
    pub kind: LateKind,
    /// k of a k·T subharmonic.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub multiple: Option<usize>,
    /// f₂, the strongest line off the drive's harmonics folded into (0, f/2] [Hz]
    /// (quasi-periodic and irregular).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub second_frequency_hz: Option<f64>,
    /// Whole periods analysed (the last of the march, at most 64).
    pub periods: usize,
    /// ρ_k, k = 1, 2, …: how far the signals are from repeating after k periods (relative
    /// RMS; below 0.01 they repeat).
    pub fold_residuals: Vec<f64>,
    /// The share of the spectrum's power in its strongest lines (≈ 1: a sum of sinusoids).
    pub line_fraction: f64,
    /// The strongest lines of the probes' and contact force's spectrum, strongest first:
    /// [frequency in multiples of f, power relative to the strongest].
    pub lines: Vec<[f64; 2]>,
    /// Per-period peak total contact force over the periods analysed: min, mean, max [N].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_contact_force: Option<Spread>,
    /// Per-period mean total contact force over the periods analysed: min, mean, max [N].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_contact_force: Option<Spread>,
    /// The Floquet verdict's prediction on the harmonic-balance state the march started from
    /// (`transient.start: harmonic_balance`), against the marching.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prediction: Option<Prediction>,
    /// The late response in a sentence.
    pub description: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LateKind {
    Periodic,
    Subharmonic,
    QuasiPeriodic,
    Irregular,
}

/// Min, mean and max of a per-period quantity.
#[derive(Clone, Copy, Debug, Serialize, JsonSchema)]
pub struct Spread {
    pub min: f64,
    pub mean: f64,
    pub max: f64,
}

impl Spread {
    fn of(values: impl Iterator<Item = f64>) -> Option<Spread> {
        let v: Vec<f64> = values.collect();
        (!v.is_empty()).then(|| Spread {
            min: v.iter().copied().fold(f64::INFINITY, f64::min),
            mean: v.iter().sum::<f64>() / v.len() as f64,
            max: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }
}

/// A Floquet prediction against the marching.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Prediction {
    pub verdict: Verdict,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crossing: Option<Crossing>,
    /// f_p [Hz].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_hz: Option<f64>,
    /// The marched counterpart: f/2·(2j/k) nearest f_p for a k·T subharmonic, f₂ otherwise
    /// [Hz].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub marched_hz: Option<f64>,
    /// 2f/L [Hz].
    pub tolerance_hz: f64,
    pub agree: bool,
    pub reason: String,
}

/// The late response of `signals`; `converged`: the march met its periodicity tolerance;
/// `late` for the contact force's per-period spread; `floquet` the verdict on the
/// harmonic-balance start, if any; f the drive frequency [Hz]; `periods_key` the setting
/// its advice names (what bounds the periods marched).
pub fn characterize(
    signals: &LateSignals,
    late: &LateRecord,
    converged: bool,
    (floquet, f): (Option<&Stability>, f64),
    periods_key: &str,
) -> LateResponse {
    let mut c = characterize::characterize(&signals.values, signals.samples_per_period);
    if converged {
        c.kind = Kind::Periodic;
    }
    let has_force = signals.labels.iter().any(|(_, unit)| *unit == "N");
    let recent = late.periods.iter().skip(late.periods.len() - c.periods);
    let peak = Spread::of(recent.clone().map(|p| p.peak_force)).filter(|_| has_force);
    let mean = Spread::of(recent.map(|p| p.mean_force)).filter(|_| has_force);
    let (kind, multiple) = match c.kind {
        Kind::Periodic => (LateKind::Periodic, None),
        Kind::Subharmonic(k) => (LateKind::Subharmonic, Some(k)),
        Kind::QuasiPeriodic => (LateKind::QuasiPeriodic, None),
        Kind::Irregular => (LateKind::Irregular, None),
    };
    let prediction = floquet.map(|v| compare(v, &c, f));
    let description = if converged {
        let what = "the late response is T-periodic (the march met transient.periodic_tolerance)";
        match &prediction {
            Some(p) => format!("{what}; {}", p.reason),
            None => what.to_string(),
        }
    } else {
        describe(&c, f, prediction.as_ref(), periods_key)
    };
    LateResponse {
        kind,
        multiple,
        second_frequency_hz: c.second_frequency.map(|nu| nu * f),
        periods: c.periods,
        fold_residuals: c.fold_residuals.clone(),
        line_fraction: c.line_fraction,
        lines: c
            .lines
            .iter()
            .take(8)
            .map(|l| [l.frequency, l.relative_power])
            .collect(),
        peak_contact_force: peak,
        mean_contact_force: mean,
        description,
        prediction,
    }
}

/// The late response in words a user can act on.
/// `key` is the setting that bounds the periods marched (`transient.max_periods`, or
/// `stability.max_periods` for the stability check's march).
fn describe(c: &Characterization, f: f64, prediction: Option<&Prediction>, key: &str) -> String {
    let over = format!("over the last {} periods", c.periods);
    let rho = c.fold_residuals.first().copied().unwrap_or(0.0);
    let what = match c.kind {
        _ if c.periods < 2 => format!("not judged: one period marched cannot show whether it repeats (an impact or other single event; raise {key} to judge a steady state)"),
        Kind::Periodic if rho < characterize::REPEATS => {
            format!("T-periodic {over} (repeats within {:.1e} of its RMS)", rho)
        }
        Kind::Periodic => format!(
            "still approaching a T-periodic state {over} (only harmonics of f in its spectrum, but it drifts by {:.1}% of its RMS): raise {key}",
            100.0 * rho
        ),
        Kind::Subharmonic(k) => format!(
            "a {k}T subharmonic {over}: it repeats after {k} periods, not after one (a line at f/{k} = {:.4} Hz)",
            f / k as f64
        ),
        Kind::QuasiPeriodic => format!(
            "quasi-periodic {over}: a second frequency f₂ = {:.4} Hz ({:.4} f) incommensurate with the drive, and its combinations with it; more periods do not make it periodic",
            c.second_frequency.unwrap_or(0.0) * f,
            c.second_frequency.unwrap_or(0.0)
        ),
        Kind::Irregular => format!(
            "irregular {over}: a broadband spectrum ({:.0}% of its power in lines), no repeat within 8 periods: chaotic, or a transient not yet died out (raise {key} to tell)",
            100.0 * c.line_fraction
        ),
    };
    match prediction {
        Some(p) => format!("the late response is {what}; {}", p.reason),
        None => format!("the late response is {what}"),
    }
}

/// The Floquet verdict `v` against the characterization `c` (see the header).
fn compare(v: &Stability, c: &Characterization, f: f64) -> Prediction {
    let tolerance_hz = 2.0 * f / c.periods.max(1) as f64;
    let predicted_hz = v
        .new_frequency_hz
        .filter(|_| v.verdict == Verdict::Unstable);
    let marched_hz = match (c.kind, predicted_hz) {
        (Kind::Subharmonic(k), Some(fp)) => {
            // The subharmonic lines j f/k folded into (0, f/2], nearest f_p.
            (1..k)
                .map(|j| (j as f64 / k as f64).min(1.0 - j as f64 / k as f64) * f)
                .min_by(|a, b| (a - fp).abs().total_cmp(&(b - fp).abs()))
        }
        (Kind::QuasiPeriodic | Kind::Irregular, _) => c.second_frequency.map(|nu| nu * f),
        _ => None,
    };
    let near =
        matches!((predicted_hz, marched_hz), (Some(a), Some(b)) if (a - b).abs() <= tolerance_hz);
    let show = |h: Option<f64>| h.map_or("-".into(), |h| format!("{h:.4} Hz"));
    let (agree, reason) = match (v.verdict, v.crossing) {
        (Verdict::Unstable, Some(Crossing::Fold)) => (
            c.kind == Kind::Periodic,
            "Floquet predicted a fold (a real multiplier through +1): the structure leaves for another T-periodic state".to_string(),
        ),
        (Verdict::Unstable, Some(crossing)) => (
            near && c.kind != Kind::Irregular,
            format!(
                "Floquet predicted {} at {}; the marched spectrum shows {}",
                crossing.describe(),
                show(predicted_hz),
                show(marched_hz)
            ),
        ),
        (Verdict::Stable, _) => (
            c.kind == Kind::Periodic,
            "Floquet predicted a stable T-periodic state".to_string(),
        ),
        _ => (false, "the Floquet verdict was undecided".to_string()),
    };
    let word = match (agree, near && c.kind == Kind::Irregular) {
        (true, _) => "they agree",
        (false, true) => "the line is there, but within a broadband response, not the one new frequency predicted",
        (false, false) => "they disagree",
    };
    Prediction {
        verdict: v.verdict,
        crossing: v.crossing,
        predicted_hz,
        marched_hz,
        tolerance_hz,
        agree,
        reason: format!(
            "{reason}: {word} (within {tolerance_hz:.3} Hz, two bins of the record's spectrum)"
        ),
    }
}

/// The Floquet verdict on `solution`, the harmonic-balance state of `model` (the transient's
/// own, diagonal mass) the march starts from: `None` without contact, with
/// `stability.check: false`, or for a state the check does not judge by multipliers (static,
/// or a contact set constant over the period).
pub fn floquet_of_start(
    p: &crate::config::Pipeline,
    model: &Model,
    solution: &crate::hbm::Solution,
) -> Option<crate::Result<Stability>> {
    let contact = solution.contact.as_ref().filter(|_| p.stability.check)?;
    if contact.harmonics == 0 {
        return None;
    }
    let segments = crate::hbm::floquet::segments(&solution.basis, solution.omega, contact);
    if segments.len() < 2 {
        return None;
    }
    Some(
        super::stability::hill_model(model, &solution.basis).and_then(|hill| {
            super::stability::by_floquet_state(
                model,
                hill.as_ref(),
                solution.omega,
                contact,
                &segments,
            )
        }),
    )
}
