//! The run summary: one typed value per run, returned by `run`/`run_transient` and written as
//! `summary.json` (its JSON Schema is `docs/summary.schema.json`). It says what was simulated,
//! how big it was, how accurate, and what each stage cost. Studies and benchmarks read these
//! fields, never the file.

use std::collections::BTreeMap;
use std::path::PathBuf;

use schemars::JsonSchema;
use serde::Serialize;

use super::model::{Effects, Model};
use super::report::{truncated_law_force, Sampled};
use super::resonance::ResonanceCheck;
use super::times::StageTimes;
use crate::config::Pipeline;
use crate::hbm::knobs::KnobCheck;
use crate::hbm::{Complementarity, IterationLog, Solution};
use crate::transient::TransientResult;

/// The JSON Schema (draft 07) of `summary.json` (`docs/summary.schema.json`).
pub fn summary_schema() -> serde_json::Value {
    let schema = schemars::generate::SchemaSettings::draft07()
        .into_generator()
        .into_root_schema_for::<Summary>();
    serde_json::Value::from(schema)
}

/// Which solver produced the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RunMode {
    HarmonicBalance,
    Transient,
}

/// Everything a run reports.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Summary {
    /// The pipeline's `name`.
    pub name: String,
    pub mode: RunMode,
    /// The pipeline file.
    pub pipeline: PathBuf,
    /// Fundamental frequency f [Hz].
    pub frequency_hz: f64,
    /// Period T = 1/f [s].
    pub period_s: f64,
    pub mesh: MeshInfo,
    /// What the run simulated, and so what it paid for.
    pub effects: EffectsSummary,
    pub sizes: Sizes,
    /// Contact candidates and mass model; null without contact.
    pub contact_setup: Option<ContactSetup>,
    /// Normwise backward error of each harmonic's linear solve (harmonic balance only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub linear_residuals: Option<BTreeMap<usize, f64>>,
    /// The contact result; null without contact.
    pub contact: Option<ContactSummary>,
    /// Per probe group: amplitudes of its mean displacement over one period [m].
    pub probes: BTreeMap<String, ProbeAmplitudes>,
    /// Things the user should know although the run succeeded.
    pub warnings: Vec<String>,
    /// VTU frames written over one period.
    pub frames: usize,
    /// Time-marching details (transient only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub transient: Option<TransientInfo>,
    /// Half peak-to-peak of every recorded probe dof over every step of the last period
    /// (transient only) [m].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub probe_dof_amplitudes: Option<BTreeMap<String, f64>>,
    /// Wall time per stage [s], in run order, with their `total`.
    pub stage_seconds: StageTimes,
    /// The natural frequencies nearest each load-excited harmonic and whether one lies
    /// within a mode's half-power band (harmonic balance only; its cost is the stage time
    /// `resonance`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resonance: Option<ResonanceCheck>,
    /// Whether the harmonic-balance state is one the structure settles into (harmonic
    /// balance; time marching from it, `transient.start: harmonic_balance`, by its Floquet
    /// multipliers; `stability`, its cost is the stage time `stability`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stability: Option<super::stability::Stability>,
    /// The largest cell von Mises stress over the output frames [Pa].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_von_mises: Option<f64>,
}

/// The few numbers a run ends with (`hbcontact run` prints them), taken from its summary.
#[derive(Clone, Debug)]
pub struct Headline {
    /// The first probe group and its amplitudes.
    pub probe: Option<(String, ProbeAmplitudes)>,
    /// Peak and mean total contact force [N] and the peak's change from H/2 to H (relative).
    pub peak_contact_force: Option<f64>,
    pub mean_contact_force: Option<f64>,
    pub peak_change_from_half_h: Option<f64>,
    pub max_von_mises: Option<f64>,
    /// Contact Newton iterations over every attempt.
    pub newton_iterations: Option<usize>,
    /// How the contact solve got there when not directly (`ContactSolve::detour`).
    pub contact_detour: Option<String>,
    /// How H was chosen within a range, in words (`HarmonicsChosen::describe`).
    pub harmonics_chosen: Option<String>,
    /// Wall time of every stage [s].
    pub wall_seconds: f64,
    pub warnings: usize,
    /// The stability verdict in a few words, when the state is not stable.
    pub stability: Option<String>,
    /// Friction's energy per period [J] and stick and slip shares (frictional runs).
    pub friction: Option<(f64, f64, f64)>,
    /// What the late response of a march is (time marching).
    pub late_response: Option<String>,
}

impl Summary {
    /// The run's headline numbers.
    pub fn headline(&self) -> Headline {
        let contact = self.contact.as_ref();
        Headline {
            probe: self
                .probes
                .iter()
                .next()
                .map(|(name, a)| (name.clone(), a.clone())),
            peak_contact_force: contact.map(|c| c.peak_contact_force),
            mean_contact_force: contact.map(|c| c.mean_contact_force),
            peak_change_from_half_h: contact.and_then(|c| c.peak_change_from_half_h),
            max_von_mises: self.max_von_mises,
            newton_iterations: contact
                .and_then(|c| c.solver.as_ref())
                .map(|s| s.newton_iterations),
            contact_detour: contact
                .and_then(|c| c.solver.as_ref())
                .and_then(ContactSolve::detour),
            harmonics_chosen: contact
                .and_then(|c| c.solver.as_ref())
                .and_then(|s| s.harmonics_chosen.as_ref())
                .map(|h| h.describe()),
            wall_seconds: self.stage_seconds.total(),
            warnings: self.warnings.len(),
            stability: self.stability.as_ref().and_then(|s| s.headline()),
            friction: contact
                .and_then(|c| c.friction.as_ref())
                .map(|f| (f.dissipated_energy_per_period, f.stick_share, f.slip_share)),
            late_response: self
                .transient
                .as_ref()
                .map(|t| t.late_response.description.clone()),
        }
    }
}

/// The mesh the run used.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct MeshInfo {
    /// The `.geo` (or `.msh`) file.
    pub geometry: PathBuf,
    /// The gmsh parameters passed with `-setnumber`.
    pub parameters: BTreeMap<String, f64>,
    /// `geometry.mesh_size`, if given [m].
    pub mesh_size: Option<f64>,
    /// Element order (1 or 2).
    pub order: u8,
    /// The mesh file read (in the cache).
    pub msh: PathBuf,
    /// Whether the mesh came from the cache.
    pub cache_hit: bool,
    pub gmsh_version: String,
    pub nodes: usize,
    pub cells: usize,
    /// Shortest element edge [m].
    pub min_edge_length: f64,
}

/// `Effects` plus what the harmonic-balance solve computed.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct EffectsSummary {
    #[serde(flatten)]
    pub effects: Effects,
    /// The time basis of the harmonic-balance solve: `fourier`, or `spline (degree p, S
    /// segments)` (harmonic balance only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_basis: Option<String>,
    /// Harmonics factored and solved; for a spline basis its discrete frequencies j (harmonic
    /// balance only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harmonics_computed: Option<Vec<usize>>,
    /// `real` (undamped) or `complex` factorizations (harmonic balance only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub arithmetic: Option<String>,
}

impl EffectsSummary {
    /// What was simulated, in words, for people (the command line's `simulated:` line):
    /// `harmonic 1 excited; damping Rayleigh: alpha = 2e2 1/s, beta = 1e-7 s; contact
    /// unilateral, …; redistributed mass; time basis fourier, harmonics 0–10 computed,
    /// complex arithmetic`.
    pub fn describe(&self) -> String {
        let e = &self.effects;
        let mut loads = Vec::new();
        if let Some(g) = e.gravity {
            loads.push(format!("gravity [{:e}, {:e}]", g[0], g[1]));
        }
        if let Some(r) = &e.rotation {
            loads.push(format!("rotation {r}"));
        }
        if e.static_load {
            loads.push("static load".to_string());
        }
        loads.extend(harmonics_phrase(&e.excited_harmonics, "excited"));
        if e.prescribed_motion {
            loads.push("prescribed motion".into());
        }
        let mut parts = vec![
            if loads.is_empty() {
                "no load".to_string()
            } else {
                loads.join(", ")
            },
            e.damping
                .as_ref()
                .map_or("no damping".into(), |d| format!("damping {d}")),
            e.contact.as_ref().map_or("no contact".into(), |c| {
                let moving = harmonics_phrase(&e.gap_harmonics, "of the gap");
                format!(
                    "contact {c}{}",
                    moving.map_or(String::new(), |m| format!(", {m}"))
                )
            }),
            format!("{} mass", e.mass.name()),
        ];
        let mut solve = Vec::new();
        if let Some(basis) = &self.time_basis {
            solve.push(format!("time basis {basis}"));
        }
        let computed = self.harmonics_computed.as_deref().unwrap_or_default();
        solve.extend(harmonics_phrase(computed, "computed"));
        if let Some(arithmetic) = &self.arithmetic {
            solve.push(format!("{arithmetic} arithmetic"));
        }
        if !solve.is_empty() {
            parts.push(solve.join(", "));
        }
        parts.join("; ")
    }
}

/// `harmonic 1 <what>` or `harmonics 0–10 <what>`; `None` for no harmonics.
fn harmonics_phrase(ks: &[usize], what: &str) -> Option<String> {
    match ks {
        [] => None,
        [k] => Some(format!("harmonic {k} {what}")),
        ks => Some(format!("harmonics {} {what}", ranges(ks))),
    }
}

/// Ascending integers with runs of three or more written as ranges: `0–10`, `0, 3`,
/// `1, 3–6`.
fn ranges(v: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        if j >= i + 2 {
            out.push(format!("{}–{}", v[i], v[j]));
        } else {
            out.extend(v[i..=j].iter().map(usize::to_string));
        }
        i = j + 1;
    }
    out.join(", ")
}

/// Problem sizes.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Sizes {
    pub nodes: usize,
    pub cells: usize,
    pub dofs: usize,
    pub free_dofs: usize,
    pub prescribed_dofs: usize,
    pub stiffness_nonzeros: usize,
}

/// Which boundary nodes became contact nodes, and the mass model's effect.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ContactSetup {
    /// Nodes of the contact boundary group.
    pub candidates: usize,
    /// Contact nodes kept.
    pub kept: usize,
    pub dropped_off_obstacle: usize,
    pub dropped_beyond_search: usize,
    /// Candidates whose normal motion boundary conditions hold (supports, not contacts).
    pub dropped_held: usize,
    /// Smallest initial gap g0 [m] (negative: initial penetration).
    pub min_initial_gap: f64,
    /// Largest initial gap g0 [m].
    pub max_initial_gap: f64,
    /// Mass moved off the contact nodes over the total (redistributed mass only).
    pub mass_moved_fraction: Option<f64>,
    /// Relative change of the polar moment of inertia (redistributed mass only).
    pub inertia_change: Option<f64>,
}

/// The contact result. Forces are pressing positive, in N for the body's thickness (plane
/// strain: per metre of thickness).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ContactSummary {
    /// Peak over the period of the total pressing contact force of the contact law [N]:
    /// harmonic balance over the output history's samples (`contact.csv`), time marching over
    /// every time step (`contact_steps.csv`).
    pub peak_contact_force: f64,
    /// Mean over the period of the total pressing contact force of the contact law [N]
    /// (samples as for the peak).
    pub mean_contact_force: f64,
    /// Peak of the total −Σλ(t) of the multipliers' truncated Fourier series over the output
    /// history [N] (time marching: of the frames' forces).
    pub peak_contact_force_series: f64,
    /// Mean of the total −Σλ(t) of the multipliers' series over the output history [N]; at a
    /// converged solution sampled at the solver's instants it equals the law's mean.
    pub mean_contact_force_series: f64,
    /// Truncation indicator: the largest tension (negative total −Σλ(t)) of the multipliers'
    /// series over its peak, over the output history (0: never pulls; time marching: 0).
    pub force_series_tension_ratio: f64,
    /// The same per node: the largest nodal tension of the series over its largest nodal
    /// pressing force, over the output history.
    pub force_series_node_tension_ratio: f64,
    /// A contact node is written as closed (`contact_status` 1) when its law force is positive
    /// and its opening is at most this [m]: the largest of 1e-3 × the largest opening, the
    /// largest penetration over the output history and the gaps' round-off (1e-9 × the
    /// largest |n·u| + |g0| of a contact node).
    pub closed_opening_tolerance: f64,
    /// Largest sampled penetration B u − g0 > 0 over the output history [m].
    pub max_sampled_penetration: f64,
    /// Truncation indicator of the peak (harmonic balance only): the peak total law force
    /// over the same samples with the solved multipliers' and gaps' series cut to H/2
    /// harmonics [N]. The solved coefficients re-evaluated, not a solve at H/2.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_contact_force_half_h: Option<f64>,
    /// (peak at H − peak at H/2) / peak at H, both from the cut series: how much the peak
    /// still moves with H (impact peaks converge slowly; the mean and the amplitudes fast).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_change_from_half_h: Option<f64>,
    /// Share of (contact node, history sample) pairs that are closed (`closed_opening_tolerance`):
    /// 0 never touching, 1 every node closed all period.
    pub contact_fraction: f64,
    /// The harmonic-balance contact solve (harmonic balance only).
    #[serde(flatten)]
    pub solver: Option<ContactSolve>,
    /// Coulomb friction's result (`contact.friction`; absent when frictionless).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<FrictionSummary>,
}

/// The tangential result of a frictional run.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct FrictionSummary {
    /// The largest friction coefficient of the contact pairs.
    pub coefficient: f64,
    /// Energy the contact nodes dissipate by friction per period, −Σ_i ∫ λ_t ẇ dt [J, for
    /// the body's thickness; plane strain: per metre].
    pub dissipated_energy_per_period: f64,
    /// The same per second (energy per period × frequency) [W].
    pub dissipated_power: f64,
    /// The contact node that dissipates most, and its energy per period [J].
    pub most_dissipating_node: Option<usize>,
    pub most_dissipated_energy: f64,
    /// Peak over the period of the total tangential force |Σ λ_t| [N].
    pub peak_tangential_force: f64,
    /// Shares of (contact node, solver sample) pairs open, stuck and slipping.
    pub open_share: f64,
    pub stick_share: f64,
    pub slip_share: f64,
    /// The largest change of the multipliers from N to 2N samples, relative to the largest
    /// (harmonic balance; a sweep checks its first point only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples_change: Option<f64>,
    /// Newton iterations of the frictional solve after the frictionless one (harmonic
    /// balance).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub newton_iterations: Option<usize>,
}

impl FrictionSummary {
    /// The summary of a frictional solution at `frequency` [Hz]; `nodes` the contact nodes'
    /// mesh indices.
    pub fn new(
        f: &crate::hbm::FrictionSolution,
        harmonics: usize,
        frequency: f64,
        nodes: &[usize],
    ) -> FrictionSummary {
        let total: f64 = f.dissipation(harmonics).iter().sum();
        let most = f.most_dissipating(harmonics);
        FrictionSummary {
            coefficient: f.coefficients.iter().fold(0.0, |a: f64, &b| a.max(b)),
            dissipated_energy_per_period: total,
            dissipated_power: total * frequency,
            most_dissipating_node: most.and_then(|(i, _)| nodes.get(i).copied()),
            most_dissipated_energy: most.map_or(0.0, |(_, e)| e),
            peak_tangential_force: f.peak_force,
            open_share: f.shares[0],
            stick_share: f.shares[1],
            slip_share: f.shares[2],
            samples_change: Some(f.samples_change).filter(|c| !c.is_nan()),
            newton_iterations: Some(f.iterations),
        }
    }

    /// The summary of the last marched period's friction (time marching: shares over
    /// (row, time step) pairs; no node breakdown).
    pub fn marched(
        m: &crate::transient::MarchedFriction,
        coefficient: f64,
        frequency: f64,
    ) -> FrictionSummary {
        let all = m.counts.iter().sum::<usize>().max(1) as f64;
        let energy = m.energy();
        FrictionSummary {
            coefficient,
            dissipated_energy_per_period: energy,
            dissipated_power: energy * frequency,
            most_dissipating_node: None,
            most_dissipated_energy: 0.0,
            peak_tangential_force: m.peak_force,
            open_share: m.counts[0] as f64 / all,
            stick_share: m.counts[1] as f64 / all,
            slip_share: m.counts[2] as f64 / all,
            samples_change: None,
            newton_iterations: None,
        }
    }
}

/// How the harmonic-balance contact solve went.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ContactSolve {
    /// H of the contact solve.
    pub harmonics: usize,
    /// Time samples N per period.
    pub samples: usize,
    /// The complementarity parameter c used [N/m].
    pub c: f64,
    /// Newton iterations over every attempt.
    pub newton_iterations: usize,
    /// ‖R‖∞ over the force scale at the end.
    pub relative_residual: f64,
    /// The harmonic ladder climbed ([H] when the direct solve converged).
    pub ladder: Vec<usize>,
    /// The damping ratios ζ at the fundamental the solve continued through, from 5% down to
    /// the scene's own (empty when the direct solve converged; docs/method.md,
    /// "Globalization").
    pub damping_path: Vec<f64>,
    pub complementarity: Complementarity,
    /// Largest penetration on the output history [m].
    pub max_penetration_on_history: f64,
    /// One entry per Newton iteration.
    pub newton_log: Vec<IterationLog>,
    /// Whether the answer moved with the samples N (doubled until it settles; `samples` is
    /// the N used) and with c (re-solved at c/3, or at 3c, c/2, 2c in turn where that does not
    /// converge).
    pub knob_check: KnobCheck,
    /// How H was chosen within `harmonic_balance.harmonics: {min, max}` (absent at a fixed
    /// H): the levels solved, each with its truncation estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harmonics_chosen: Option<crate::hbm::adaptive::HarmonicsChosen>,
}

impl ContactSolve {
    /// The detour the solve took where the direct one failed (`hbm::solution::detour`).
    pub fn detour(&self) -> Option<String> {
        crate::hbm::solution::detour(&self.ladder, &self.damping_path)
    }
}

/// Amplitudes of a probe group's mean displacement over one period [m].
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ProbeAmplitudes {
    /// Half the peak-to-peak range of u_x (what a gauge shows).
    pub half_peak_to_peak_x: f64,
    /// Amplitude of u_x's first harmonic (smooth in H: the accuracy studies' measure).
    pub first_harmonic_x: f64,
    pub half_peak_to_peak_y: f64,
    pub first_harmonic_y: f64,
    /// Amplitude of u_x's harmonics 1, 2, … up to the pipeline's H (and below half the
    /// history's samples).
    pub harmonics_x: Vec<f64>,
    pub harmonics_y: Vec<f64>,
}

impl ProbeAmplitudes {
    /// The larger first-harmonic amplitude of the two components.
    pub fn first_harmonic(&self) -> f64 {
        self.first_harmonic_x.max(self.first_harmonic_y)
    }
}

/// Time-marching details.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct TransientInfo {
    /// Time step [s].
    pub dt: f64,
    pub steps_per_period: usize,
    /// Periods marched.
    pub periods: usize,
    /// Whether two successive periods agreed within `transient.periodic_tolerance`.
    pub converged: bool,
    /// Relative change between the last two periods.
    pub periodicity_error: f64,
    /// `rest`, `harmonic_balance`, `previous`, `rigid` or `state` (`transient.start`).
    pub start: String,
    /// The relative perturbation of a harmonic-balance start (0 from rest).
    pub perturbation: f64,
    /// Present when an interruption (Ctrl-C, SIGTERM, SIGHUP) stopped the march: the result
    /// is partial (the command exits with 130). Absent when the march ran its course.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped: Option<MarchStopped>,
    /// What the last whole periods marched (at most 64) show: periodic, a k·T subharmonic,
    /// quasi-periodic or irregular, the contact force's spread over those periods, and the
    /// Floquet prediction against them (`transient.start: harmonic_balance`).
    pub late_response: super::late::LateResponse,
}

/// Why a march ended before it was periodic or had marched `transient.max_periods`.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct MarchStopped {
    /// `interrupted` (the error class of exit code 130, as a sweep's `stopped.class`).
    pub class: String,
    /// Whole periods marched (`periods`): the end state and the periodicity are those of the
    /// last of them.
    pub periods: usize,
    /// Steps marched into the period after them (of `steps_per_period`): the sampled period
    /// (frames, histories, amplitudes) is the last period of time marched, which ends there.
    pub steps_into_period: usize,
    pub reason: String,
}

pub fn sizes(model: &Model) -> Sizes {
    Sizes {
        nodes: model.mesh.nodes.len(),
        cells: model.mesh.cells.len(),
        dofs: model.system.dofs.total(),
        free_dofs: model.system.free_count(),
        prescribed_dofs: model.system.dofs.prescribed.len(),
        stiffness_nonzeros: model.system.k_ff.nnz(),
    }
}

pub fn contact_setup(model: &Model) -> Option<ContactSetup> {
    let c = model.contact.as_ref()?;
    let gaps = &c.set.gaps;
    Some(ContactSetup {
        candidates: c.set.candidates,
        kept: c.set.nodes.len(),
        dropped_off_obstacle: c.set.dropped_off_obstacle,
        dropped_beyond_search: c.set.dropped_beyond_search,
        dropped_held: c.set.dropped_held,
        min_initial_gap: gaps.iter().cloned().fold(f64::INFINITY, f64::min),
        max_initial_gap: gaps.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
        mass_moved_fraction: c.redistribution.as_ref().map(|r| r.moved_fraction),
        inertia_change: c.redistribution.as_ref().map(|r| r.inertia_change),
    })
}

/// Effects with the harmonic-balance solve's harmonics and arithmetic.
pub fn effects(model: &Model, solution: Option<&Solution>) -> EffectsSummary {
    EffectsSummary {
        effects: model.effects.clone(),
        time_basis: solution.map(|s| s.basis.describe()),
        harmonics_computed: solution.map(Solution::harmonics),
        arithmetic: solution.map(|s| {
            if s.complex_arithmetic {
                "complex"
            } else {
                "real"
            }
            .to_string()
        }),
    }
}

/// Peak and mean over samples of the total pressing force −Σλ.
pub fn force_stats(totals: &[f64]) -> (f64, f64) {
    let peak = totals.iter().cloned().fold(0.0, f64::max);
    let mean = totals.iter().sum::<f64>() / totals.len().max(1) as f64;
    (peak, mean)
}

/// The series statistics and the closed tolerance of a contact summary; the law's peak,
/// mean and penetration are zero here, for the caller to fill in.
fn series_stats(sampled: &Sampled) -> ContactSummary {
    let series = sampled.history.total_force_series();
    let (peak, mean) = force_stats(&series);
    let tension = series.iter().fold(0.0f64, |a, &v| a.max(-v));
    let nodal = sampled.history.contact.iter().flat_map(|c| &c.series);
    let (node_tension, node_peak) =
        nodal.fold((0.0f64, 0.0f64), |(t, p), &v| (t.max(-v), p.max(v)));
    ContactSummary {
        peak_contact_force: 0.0,
        mean_contact_force: 0.0,
        peak_contact_force_series: peak,
        mean_contact_force_series: mean,
        force_series_tension_ratio: if peak > 0.0 { tension / peak } else { 0.0 },
        force_series_node_tension_ratio: if node_peak > 0.0 {
            node_tension / node_peak
        } else {
            0.0
        },
        closed_opening_tolerance: sampled.closed_tolerance,
        max_sampled_penetration: 0.0,
        peak_contact_force_half_h: None,
        peak_change_from_half_h: None,
        contact_fraction: contact_fraction(sampled),
        solver: None,
        friction: None,
    }
}

/// Share of (contact node, sample) pairs of the history that are closed.
fn contact_fraction(sampled: &Sampled) -> f64 {
    let tolerance = sampled.closed_tolerance;
    let (mut closed, mut all) = (0usize, 0usize);
    for state in &sampled.history.contact {
        closed += (0..state.gap.len())
            .filter(|&i| state.closed(i, tolerance))
            .count();
        all += state.gap.len();
    }
    if all == 0 {
        0.0
    } else {
        closed as f64 / all as f64
    }
}

/// Largest cell von Mises stress over the output frames [Pa].
fn max_von_mises(model: &Model, sampled: &Sampled) -> f64 {
    sampled
        .frames
        .iter()
        .flat_map(|s| crate::fem::cell_stresses(&model.mesh, &model.material, &s.displacement))
        .map(|t| t.von_mises())
        .fold(0.0, f64::max)
}

/// Half the peak-to-peak range of a series (what a gauge shows as amplitude).
fn half_range(series: &[f64]) -> f64 {
    let max = series.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let min = series.iter().cloned().fold(f64::INFINITY, f64::min);
    0.5 * (max - min)
}

/// Over evenly spaced samples of one period, per probe: half the peak-to-peak range and the
/// first-harmonic amplitude of each component of the probe's mean displacement.
/// The H a contact solution was solved at (chosen within a range, or the pipeline's).
fn solved_harmonics(p: &Pipeline, solution: &Solution) -> usize {
    let contact = solution.contact.as_ref();
    contact.map_or(p.harmonic_balance.harmonics, |c| c.harmonics)
}

pub fn probe_amplitudes(
    model: &Model,
    probe_means: &[[Vec<f64>; 2]],
    harmonics: usize,
) -> BTreeMap<String, ProbeAmplitudes> {
    let samples = probe_means.first().map_or(0, |m| m[0].len());
    let count = samples.max(1) as f64;
    let top = harmonics.min((samples / 2).saturating_sub(1)).max(1);
    let amplitude = |series: &[f64], k: usize| -> f64 {
        let (mut a, mut b) = (0.0, 0.0);
        for (j, s) in series.iter().enumerate() {
            let phase = 2.0 * std::f64::consts::PI * (k * j) as f64 / count;
            a += s * phase.cos();
            b += s * phase.sin();
        }
        2.0 * (a * a + b * b).sqrt() / count
    };
    let measure = |series: &[f64]| -> (f64, Vec<f64>) {
        let spectrum = (1..=top).map(|k| amplitude(series, k)).collect();
        (half_range(series), spectrum)
    };
    model
        .probes
        .iter()
        .zip(probe_means)
        .map(|((name, _), [x, y])| {
            let (px, hx) = measure(x);
            let (py, hy) = measure(y);
            let amplitudes = ProbeAmplitudes {
                half_peak_to_peak_x: px,
                first_harmonic_x: hx[0],
                half_peak_to_peak_y: py,
                first_harmonic_y: hy[0],
                harmonics_x: hx,
                harmonics_y: hy,
            };
            (name.clone(), amplitudes)
        })
        .collect()
}

/// The summary of a harmonic-balance run (stage times are filled in at the end).
pub fn harmonic_balance(
    p: &Pipeline,
    mesh: MeshInfo,
    model: &Model,
    solution: &Solution,
    sampled: &Sampled,
) -> Summary {
    let history = &sampled.history;
    let contact = solution.contact.as_ref().map(|c| {
        let (peak, mean) = force_stats(&history.total_force());
        let (half_h, change) = peak_change_from_half_h(solution, &history.times, c.harmonics);
        ContactSummary {
            peak_contact_force: peak,
            mean_contact_force: mean,
            peak_contact_force_half_h: half_h,
            peak_change_from_half_h: change,
            max_sampled_penetration: c.complementarity.max_penetration,
            solver: Some(ContactSolve {
                harmonics: c.harmonics,
                samples: c.samples,
                c: c.c,
                newton_iterations: c.newton.iterations,
                relative_residual: c.newton.relative_residual,
                ladder: c.ladder.clone(),
                damping_path: c.damping_path.clone(),
                complementarity: c.complementarity.clone(),
                max_penetration_on_history: history.max_penetration(),
                newton_log: c.newton.log.clone(),
                knob_check: c.knob_check.clone(),
                harmonics_chosen: c.harmonics_chosen.clone(),
            }),
            friction: c.friction.as_ref().map(|f| {
                let nodes = model.contact.as_ref().map_or(&[][..], |m| &m.set.nodes[..]);
                FrictionSummary::new(f, c.harmonics, frequency_of(p, solution), nodes)
            }),
            ..series_stats(sampled)
        }
    });
    Summary {
        linear_residuals: Some(solution.residuals.clone()),
        contact,
        probes: probe_amplitudes(model, &history.probe_means, solved_harmonics(p, solution)),
        warnings: solution.warnings.clone(),
        max_von_mises: Some(max_von_mises(model, sampled)),
        ..common(
            p,
            (RunMode::HarmonicBalance, frequency_of(p, solution)),
            mesh,
            model,
            Some(solution),
        )
    }
}

/// The summary of a time-marching run.
pub fn transient(
    p: &Pipeline,
    mesh: MeshInfo,
    model: &Model,
    result: &TransientResult,
    sampled: &Sampled,
    late_response: super::late::LateResponse,
) -> Summary {
    // Peak and mean from every step (`contact_steps.csv`), which the frames undersample.
    let contact = sampled.steps.as_ref().map(|steps| {
        let (peak, mean) = force_stats(&steps.total_force);
        let coefficient =
            (p.contact.iter().flat_map(|c| &c.pairs)).fold(0.0, |a: f64, c| a.max(c.friction));
        let frequency = model.system.omega / (2.0 * std::f64::consts::PI);
        ContactSummary {
            peak_contact_force: peak,
            mean_contact_force: mean,
            max_sampled_penetration: sampled.history.max_penetration(),
            solver: None,
            friction: (result.friction.as_ref())
                .map(|m| FrictionSummary::marched(m, coefficient, frequency)),
            ..series_stats(sampled)
        }
    });
    let mut warnings = Vec::new();
    let stopped = result.interrupted.map(|k| march_interrupted(p, result, k));
    match &stopped {
        Some(s) => warnings.push(format!("a partial result: {}", s.reason)),
        None if !result.converged => warnings.push(format!(
            "not periodic after {} periods (change {:.3e} > {:.1e}): {}",
            result.periods,
            result.periodicity_error,
            p.transient.periodic_tolerance,
            late_response.description
        )),
        None => {}
    }
    let dof_amplitudes = result
        .probe_history
        .iter()
        .enumerate()
        .map(|(j, h)| (format!("probe_dof_{j}"), half_range(h)))
        .collect();
    Summary {
        contact,
        probes: probe_amplitudes(
            model,
            &every_step_probe_means(model, result)
                .unwrap_or_else(|| sampled.history.probe_means.clone()),
            p.harmonic_balance.harmonics,
        ),
        warnings,
        transient: Some(TransientInfo {
            dt: result.dt,
            steps_per_period: result.steps_per_period,
            periods: result.periods,
            converged: result.converged,
            periodicity_error: result.periodicity_error,
            start: p.transient.start.name().into(),
            perturbation: p.transient.perturbation,
            stopped,
            late_response,
        }),
        probe_dof_amplitudes: Some(dof_amplitudes),
        max_von_mises: Some(max_von_mises(model, sampled)),
        ..common(
            p,
            (RunMode::Transient, p.harmonic_balance.frequency),
            mesh,
            model,
            None,
        )
    }
}

/// Each probe group's mean (u_x, u_y) at every step of the marched period, from the march's
/// probe record (whose dofs are the probe nodes' free ones, in order): the frames alone alias
/// the harmonics of an impact above half their count. `None` where a probe dof is held.
fn every_step_probe_means(model: &Model, result: &TransientResult) -> Option<Vec<[Vec<f64>; 2]>> {
    let dofs = &model.system.dofs;
    let mut next = 0;
    let mut means = Vec::new();
    for (_, nodes) in &model.probes {
        let steps = result.probe_history.first()?.len();
        let mut mean = [vec![0.0; steps], vec![0.0; steps]];
        for &n in nodes {
            for (c, series) in mean.iter_mut().enumerate() {
                dofs.free_index(2 * n + c)?;
                let history = result.probe_history.get(next)?;
                next += 1;
                for (m, u) in series.iter_mut().zip(history) {
                    *m += u / nodes.len() as f64;
                }
            }
        }
        means.push(mean);
    }
    (next == result.probe_history.len()).then_some(means)
}

/// `transient.stopped` of a march an interruption stopped `steps` steps into the period after
/// its last whole one.
fn march_interrupted(p: &Pipeline, result: &TransientResult, steps: usize) -> MarchStopped {
    let whole = match result.periods {
        1 => "1 whole period".to_string(),
        n => format!("{n} whole periods"),
    };
    let reason = format!(
        "interrupted during the `march` stage after {whole} and {steps} of the {} steps of \
         the next: the results are the last period of time marched, not a periodic state \
         (change {:.3e} between the last two periods, transient.periodic_tolerance {:.1e}); \
         `transient.start: previous` marches on from its end state",
        result.steps_per_period, result.periodicity_error, p.transient.periodic_tolerance
    );
    MarchStopped {
        class: "interrupted".into(),
        periods: result.periods,
        steps_into_period: steps,
        reason,
    }
}

/// The solution's frequency [Hz]: the pipeline's where ω is 2π times it (so it reads as
/// written), else ω/2π (a sweep's point).
fn frequency_of(p: &Pipeline, solution: &Solution) -> f64 {
    let nominal = p.harmonic_balance.frequency;
    if 2.0 * std::f64::consts::PI * nominal == solution.omega {
        nominal
    } else {
        solution.omega / (2.0 * std::f64::consts::PI)
    }
}

/// The parts every run reports, at `frequency_hz`.
fn common(
    p: &Pipeline,
    (mode, frequency_hz): (RunMode, f64),
    mesh: MeshInfo,
    model: &Model,
    solution: Option<&Solution>,
) -> Summary {
    Summary {
        name: p.name.clone(),
        mode,
        pipeline: p.source.clone(),
        frequency_hz,
        period_s: 1.0 / frequency_hz,
        mesh,
        effects: effects(model, solution),
        sizes: sizes(model),
        contact_setup: contact_setup(model),
        linear_residuals: None,
        contact: None,
        probes: BTreeMap::new(),
        warnings: Vec::new(),
        frames: p.output.frames,
        transient: None,
        probe_dof_amplitudes: None,
        stage_seconds: StageTimes::default(),
        resonance: None,
        stability: None,
        max_von_mises: None,
    }
}

/// The peak total law force with the series cut to H/2, and the peak's relative change from
/// there to H (both peaks from the cut-series evaluation, over the history's times).
fn peak_change_from_half_h(
    solution: &Solution,
    times: &[f64],
    harmonics: usize,
) -> (Option<f64>, Option<f64>) {
    let peak =
        |h: usize| truncated_law_force(solution, times, h).map(|totals| force_stats(&totals).0);
    match (peak(harmonics / 2), peak(harmonics)) {
        (Some(half), Some(full)) if full > 0.0 => (Some(half), Some((full - half) / full)),
        (half, _) => (half, None),
    }
}

#[cfg(test)]
mod tests {
    use super::ranges;

    /// TEST GOAL: lists of harmonics print with runs of three or more as ranges.
    #[test]
    fn harmonic_lists_print_runs_of_three_or_more_as_ranges() {
        assert_eq!(ranges(&[1]), "1");
        assert_eq!(ranges(&[0, 3]), "0, 3");
        assert_eq!(ranges(&[0, 1]), "0, 1");
        assert_eq!(ranges(&(0..=10).collect::<Vec<_>>()), "0–10");
        assert_eq!(ranges(&[1, 3, 4, 5, 6, 9]), "1, 3–6, 9");
        assert_eq!(ranges(&[]), "");
    }

    /// TEST GOAL: the mass model's name in words is the one summary.json writes.
    #[test]
    fn mass_model_names_are_the_summarys() {
        use crate::pipeline::model::MassModel;
        for m in [
            MassModel::Consistent,
            MassModel::Lumped,
            MassModel::Redistributed,
        ] {
            assert_eq!(serde_json::to_value(m).ok(), Some(m.name().into()));
        }
    }
}
