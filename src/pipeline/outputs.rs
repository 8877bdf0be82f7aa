//! What a study tabulates for each point, read from the run's typed `Summary` right after the
//! run (never from summary.json). Each output has a column name, a unit for the axes, and a
//! value (NaN when the run does not have it, e.g. a contact force without contact).
//!
//! Probe outputs are of the study's probe group's mean displacement: `probe_first_harmonic`
//! is the larger first-harmonic amplitude of u_x and u_y, `probe_harmonic_K` the same for
//! harmonic K, `probe_peak_to_peak` the larger peak-to-peak range of the two.
//!
//! Three outputs do not come from the summary but from the point's run (execute.rs):
//! `natural_frequency_K` (the K-th lowest natural frequency f_K = ω_K/2π of the model `run`
//! solves, its supports held and the contact open, as `hbcontact modes` computes it),
//! `peak_memory` (the run's peak resident memory) and, for accuracy rungs, the harmonic
//! amplitudes kept for the displacement L2 error.

use super::stability::Verdict;
use super::Stage;
use super::Summary;

/// One tabulated quantity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    ProbeFirstHarmonic,
    ProbeFirstHarmonicX,
    ProbeFirstHarmonicY,
    /// The amplitude of harmonic K (≥ 1) of the probe (the larger of x and y).
    ProbeHarmonic(usize),
    ProbePeakToPeak,
    ProbePeakToPeakX,
    ProbePeakToPeakY,
    PeakContactForce,
    MeanContactForce,
    ContactFraction,
    MaxVonMises,
    NewtonIterations,
    /// H of the contact solve (chosen within `harmonic_balance.harmonics: {min, max}`, or the
    /// pipeline's).
    Harmonics,
    FreeDofs,
    /// Wall time of the point's run without meshing (which the cache makes free) [s].
    WallTime,
    /// Wall time without meshing and writing (accuracy rungs write harmonic amplitudes that
    /// other points do not) [s].
    SolveTime,
    /// The K-th lowest natural frequency (K ≥ 1) [Hz], computed after the run.
    NaturalFrequency(usize),
    /// Peak resident memory of the run [MB] (points run one at a time only).
    PeakMemory,
    /// The stability verdict (`stability.method`): 1 stable, 0 unstable, empty when undecided.
    /// Only a study that asks for it (or for `Multiplier`) pays for the check.
    Stable,
    /// The check's largest Floquet multiplier modulus |μ| (marching: its estimate μ̂; as
    /// sweep.csv's column).
    Multiplier,
    /// Friction: the energy dissipated per period [J], the peak total tangential force [N]
    /// and the share of (node, sample) pairs slipping (NaN when frictionless).
    DissipatedEnergy,
    PeakTangentialForce,
    SlipShare,
}

/// The fixed names, in documentation order (`probe_harmonic_K` and `natural_frequency_K`
/// come on top).
const NAMED: [(Output, &str, &str); 21] = [
    (Output::ProbeFirstHarmonic, "probe_first_harmonic", "m"),
    (Output::ProbeFirstHarmonicX, "probe_first_harmonic_x", "m"),
    (Output::ProbeFirstHarmonicY, "probe_first_harmonic_y", "m"),
    (Output::ProbePeakToPeak, "probe_peak_to_peak", "m"),
    (Output::ProbePeakToPeakX, "probe_peak_to_peak_x", "m"),
    (Output::ProbePeakToPeakY, "probe_peak_to_peak_y", "m"),
    (Output::PeakContactForce, "peak_contact_force", "N"),
    (Output::MeanContactForce, "mean_contact_force", "N"),
    (Output::ContactFraction, "contact_fraction", "-"),
    (Output::MaxVonMises, "max_von_mises", "Pa"),
    (Output::NewtonIterations, "newton_iterations", "-"),
    (Output::Harmonics, "harmonics", "-"),
    (Output::FreeDofs, "free_dofs", "-"),
    (Output::WallTime, "wall_time", "s"),
    (Output::SolveTime, "solve_time", "s"),
    (Output::PeakMemory, "peak_memory", "MB"),
    (Output::Stable, "stable", "-"),
    (Output::Multiplier, "multiplier", "-"),
    (Output::DissipatedEnergy, "dissipated_energy", "J"),
    (Output::PeakTangentialForce, "peak_tangential_force", "N"),
    (Output::SlipShare, "slip_share", "-"),
];

/// A point's response: the probe's amplitude and range, the contact forces and fraction (what
/// every sweep row tabulates, and the first of a study's default outputs).
pub const RESPONSE: [Output; 5] = [
    Output::ProbeFirstHarmonic,
    Output::ProbePeakToPeak,
    Output::PeakContactForce,
    Output::MeanContactForce,
    Output::ContactFraction,
];

impl Output {
    /// The default outputs of a study: the response, the largest stress and the cost.
    pub fn defaults() -> Vec<Output> {
        let cost = [
            Output::MaxVonMises,
            Output::NewtonIterations,
            Output::WallTime,
        ];
        RESPONSE.into_iter().chain(cost).collect()
    }

    /// Every name a study accepts (for messages and docs).
    pub fn all_names() -> Vec<String> {
        let mut names: Vec<String> = NAMED.iter().map(|(_, n, _)| n.to_string()).collect();
        names.push("probe_harmonic_K".into());
        names.push("natural_frequency_K".into());
        names
    }

    /// The named outputs every summary answers (NaN where the scene lacks one), without the
    /// stability check's, which only a checked run has.
    pub fn from_summary() -> Vec<Output> {
        let checked = |o: &Output| matches!(o, Output::Stable | Output::Multiplier);
        (NAMED.iter().map(|(o, _, _)| *o))
            .filter(|o| !o.from_run() && !checked(o))
            .collect()
    }

    /// Whether the value comes from the point's run rather than its summary.
    pub fn from_run(&self) -> bool {
        matches!(self, Output::NaturalFrequency(_) | Output::PeakMemory)
    }

    pub fn parse(name: &str) -> std::result::Result<Output, String> {
        if let Some((o, _, _)) = NAMED.iter().find(|(_, n, _)| *n == name) {
            return Ok(*o);
        }
        if let Some(k) = name.strip_prefix("probe_harmonic_") {
            return match k.parse::<usize>() {
                Ok(k) if k >= 1 => Ok(Output::ProbeHarmonic(k)),
                _ => Err("the harmonic K of probe_harmonic_K is a whole number ≥ 1".into()),
            };
        }
        if let Some(k) = name.strip_prefix("natural_frequency_") {
            return match k.parse::<usize>() {
                Ok(k) if (1..=crate::pipeline::modes::MAX_MODES).contains(&k) => {
                    Ok(Output::NaturalFrequency(k))
                }
                _ => Err(format!(
                    "the mode K of natural_frequency_K is a whole number from 1 to {}",
                    crate::pipeline::modes::MAX_MODES
                )),
            };
        }
        let names = Output::all_names();
        let hint = names
            .iter()
            .max_by(|a, b| strsim::jaro_winkler(a, name).total_cmp(&strsim::jaro_winkler(b, name)))
            .map(|n| format!("did you mean `{n}`? "))
            .unwrap_or_default();
        Err(format!("unknown output; {hint}known: {}", names.join(", ")))
    }

    /// The column name.
    pub fn name(&self) -> String {
        match self {
            Output::ProbeHarmonic(k) => format!("probe_harmonic_{k}"),
            Output::NaturalFrequency(k) => format!("natural_frequency_{k}"),
            o => NAMED
                .iter()
                .find(|(n, _, _)| n == o)
                .map_or_else(String::new, |(_, name, _)| name.to_string()),
        }
    }

    pub fn unit(&self) -> &'static str {
        match self {
            Output::ProbeHarmonic(_) => "m",
            Output::NaturalFrequency(_) => "Hz",
            o => NAMED
                .iter()
                .find(|(n, _, _)| n == o)
                .map_or("-", |(_, _, u)| u),
        }
    }

    /// `name [unit]` for an axis.
    pub fn axis_label(&self) -> String {
        format!("{} [{}]", self.name(), self.unit())
    }

    /// The value for a finished run; `probe` is the probe group (None: the first). NaN for
    /// the outputs `from_run`.
    pub fn value(&self, s: &Summary, probe: Option<&str>) -> f64 {
        let p = match probe {
            Some(name) => s.probes.get(name),
            None => s.probes.values().next(),
        };
        let probe =
            |f: &dyn Fn(&crate::pipeline::summary::ProbeAmplitudes) -> f64| p.map_or(f64::NAN, f);
        let contact = s.contact.as_ref();
        let friction = |f: &dyn Fn(&crate::pipeline::summary::FrictionSummary) -> f64| {
            contact
                .and_then(|c| c.friction.as_ref())
                .map_or(f64::NAN, f)
        };
        match self {
            Output::ProbeFirstHarmonic => probe(&|a| a.first_harmonic()),
            Output::ProbeFirstHarmonicX => probe(&|a| a.first_harmonic_x),
            Output::ProbeFirstHarmonicY => probe(&|a| a.first_harmonic_y),
            Output::ProbeHarmonic(k) => probe(&|a| {
                let at = |v: &[f64]| v.get(k - 1).copied().unwrap_or(f64::NAN);
                at(&a.harmonics_x).max(at(&a.harmonics_y))
            }),
            Output::ProbePeakToPeak => {
                probe(&|a| 2.0 * a.half_peak_to_peak_x.max(a.half_peak_to_peak_y))
            }
            Output::ProbePeakToPeakX => probe(&|a| 2.0 * a.half_peak_to_peak_x),
            Output::ProbePeakToPeakY => probe(&|a| 2.0 * a.half_peak_to_peak_y),
            Output::PeakContactForce => contact.map_or(f64::NAN, |c| c.peak_contact_force),
            Output::MeanContactForce => contact.map_or(f64::NAN, |c| c.mean_contact_force),
            Output::ContactFraction => contact.map_or(f64::NAN, |c| c.contact_fraction),
            Output::MaxVonMises => s.max_von_mises.unwrap_or(f64::NAN),
            Output::NewtonIterations => contact
                .and_then(|c| c.solver.as_ref())
                .map_or(f64::NAN, |c| c.newton_iterations as f64),
            Output::Harmonics => contact
                .and_then(|c| c.solver.as_ref())
                .map_or(f64::NAN, |c| c.harmonics as f64),
            Output::FreeDofs => s.sizes.free_dofs as f64,
            Output::DissipatedEnergy => friction(&|f| f.dissipated_energy_per_period),
            Output::PeakTangentialForce => friction(&|f| f.peak_tangential_force),
            Output::SlipShare => friction(&|f| f.slip_share),
            Output::WallTime => {
                let st = &s.stage_seconds;
                st.total() - st.get(Stage::Mesh)
            }
            Output::SolveTime => {
                let st = &s.stage_seconds;
                st.total() - st.get(Stage::Mesh) - st.get(Stage::Write)
            }
            Output::Stable => match s.stability.as_ref().map(|st| st.verdict) {
                Some(Verdict::Stable) => 1.0,
                Some(Verdict::Unstable) => 0.0,
                _ => f64::NAN,
            },
            Output::Multiplier => s
                .stability
                .as_ref()
                .and_then(|st| st.multiplier)
                .unwrap_or(f64::NAN),
            Output::NaturalFrequency(_) | Output::PeakMemory => f64::NAN,
        }
    }

    /// Whether asking for this output makes each point run the stability check.
    pub fn needs_stability(&self) -> bool {
        matches!(self, Output::Stable | Output::Multiplier)
    }
}
