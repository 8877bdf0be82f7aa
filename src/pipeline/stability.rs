//! Is a harmonic-balance state one the structure settles into? The verdict by time marching
//! (docs/method.md, "Stability"): march the scene's own discrete model (diagonal mass, the
//! transient's explicit scheme) from its harmonic-balance state, perturbed, and watch the
//! period-to-period change.
//!
//! Formulas and glossary:
//! - x_k = (u, T u̇) at t = kT, the state at the start of period k (x_0 the harmonic-balance
//!   state scaled by 1 + ε);
//! - d_k = ‖x_k − x_{k−1}‖/‖x_k‖ the period-to-period change. Near a periodic orbit
//!   x_{k+1} − x* ≈ Φ (x_k − x*), Φ the monodromy matrix, so d_k ~ |μ_max|^k: d_k decays when
//!   every Floquet multiplier μ lies inside the unit circle and grows when one lies outside;
//! - μ̂ = exp(slope of ln d_k) over the last half of the periods, the estimate of |μ_max|
//!   (with mass-proportional damping alone and no contact, every μ = e^{−αT/2});
//! - e = ‖u − u_hb‖/‖u_hb‖ in L²(0, T) over `SAMPLES` instants of the last period: how far
//!   the state the marching ends in lies from the harmonic-balance state, in displacement
//!   (phase-independent, unlike x_k at one instant; the velocities are left out because a
//!   truncated Fourier series misses most of the waves impacts send: on the strip at H = 10,
//!   x_1 is 40% off in T u̇ but 2% in u on a stable state).
//!
//! Verdicts:
//! - unstable: d grows (μ̂ > 1 + `MARGIN` and d_end > `GROWTH` · min d), or the march settles
//!   (d < `SETTLED`, or decays with μ̂ < 1 − `MARGIN`) on a state e ≥ `SAME_STATE` away (the
//!   structure went to another branch), or the displacements moved away from the start by
//!   more than `LEFT` times its amplitude, (‖u_0‖² + ‖u̇_0/ω‖²)^½;
//! - stable: it settles on a state e < `SAME_STATE` away;
//! - undecided: neither within the periods allowed (a multiplier near 1: a fold, or light
//!   damping); more periods decide it.
//!
//! `SAME_STATE` bounds what the harmonic-balance truncation may differ from the marched orbit:
//! a scene whose H leaves more than that cannot be judged, and says so by an unstable verdict
//! whose e is in the reason (raise H and compare).
//!
//! A damped linear scene needs no marching: every free vibration decays (all multipliers are
//! e^{−ζωT} < 1); an undamped one keeps them (|μ| = 1, stable but not asymptotically).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use schemars::JsonSchema;
use serde::Serialize;

use crate::config::{Pipeline, StabilityMethod, StabilitySpec};
use crate::contact::ContactOperator;
use crate::fem::modes::Mode;
use crate::fem::DofMap;
use crate::hbm::floquet::{self, Crossing, FloquetModel, Segment};
use crate::hbm::hill::HillModel;
use crate::hbm::{self, ContactSolution};
use crate::pipeline::model::time_basis;
use crate::pipeline::{hb_settings, Model, Purpose};
use crate::progress::Reporter;
use crate::transient::setup::Marching;
use crate::transient::{self, InitialState, TransientSettings};
use crate::{Error, Result};

/// Period-to-period change below which the march is periodic.
const SETTLED: f64 = 1e-9;
/// An end state this close to the harmonic-balance state (e) is that state.
const SAME_STATE: f64 = 0.1;
/// Displacements this far from the start (relative to its amplitude) have left it.
const LEFT: f64 = 1.0;
/// Instants of the last period the end state is compared at.
const SAMPLES: usize = 16;
/// μ̂ within 1 ± this decides nothing.
const MARGIN: f64 = 0.01;
/// Growth of d from its minimum that counts as growing.
const GROWTH: f64 = 10.0;
/// Decay of d from its maximum that ends a march early as stable.
const DECAY: f64 = 1e3;
/// Periods before an early end.
const MIN_PERIODS: usize = 24;

/// What the check says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Stable,
    Unstable,
    Undecided,
    /// `stability.check: false`.
    NotChecked,
}

/// How the verdict was reached.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// A linear scene: from its damping, no marching.
    Linear,
    /// The Floquet multipliers of the harmonic-balance state (`hbm::floquet`).
    Floquet,
    /// Time marching from the perturbed harmonic-balance state.
    Marching,
    None,
}

/// A stability verdict (in the run summary, and per sweep point).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Stability {
    pub verdict: Verdict,
    pub method: Method,
    /// The largest Floquet multiplier's modulus |μ| (Floquet), or μ̂, its estimate from the
    /// period-to-period change (marching).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub multiplier: Option<f64>,
    /// Floquet: the largest multiplier's argument [rad], in [0, π].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub argument: Option<f64>,
    /// Floquet: how the largest multiplier crosses (unstable) or would cross (stable) the
    /// unit circle.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crossing: Option<Crossing>,
    /// Floquet: the frequency of the motion the leading multiplier brings [Hz]: half the
    /// drive's at a period doubling, |arg μ|/(2π)·f for a complex pair.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub new_frequency_hz: Option<f64>,
    /// Floquet: the reduced model's dimension r (the modes kept dynamic) and the segments of
    /// constant contact over the period.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reduced_dimension: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<usize>,
    /// `method: both`: what the time-marching audit said, where it disagrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub audit: Option<String>,
    /// Marching (and the audit of `method: both`): what the march from the perturbed state did
    /// over the periods it ran, characterized as `transient` characterizes a late response
    /// (`pipeline::late`), and, after a Floquet verdict, whether it shows the motion predicted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub marched_response: Option<String>,
    /// Periods marched.
    pub periods: usize,
    /// The last period-to-period change d.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub change: Option<f64>,
    /// e, the distance of the state the marching ends in from the harmonic-balance state
    /// (relative, displacements in L² over the last period).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub departure: Option<f64>,
    /// The verdict in a sentence.
    pub reason: String,
    /// Floquet, unstable: the series of the leading multiplier's Floquet vector the run
    /// wrote (`floquet.pvd`: Re(e^{i Im(s) t} p(t)) over two periods, `pipeline::floquet_vector`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floquet_vector_file: Option<String>,
    /// Hill's method: that vector (not serialized; a sweep's points drop it).
    #[serde(skip)]
    #[schemars(skip)]
    pub floquet_vector: Option<hbm::hill::FloquetVector>,
}

impl Stability {
    pub fn not_checked() -> Stability {
        Stability {
            verdict: Verdict::NotChecked,
            reason: "not checked (stability.check: false)".into(),
            ..Stability::blank(Method::None)
        }
    }

    /// Undecided, because time marching could not take the scene.
    pub fn cannot_march(why: &Error) -> Stability {
        Stability {
            reason: format!("time marching could not check it: {why}"),
            ..Stability::undecided()
        }
    }

    /// Undecided, because the Floquet multipliers could not be computed.
    pub fn no_multipliers(why: &Error) -> Stability {
        Stability {
            reason: format!("no Floquet multipliers: {why}"),
            ..Stability::blank(Method::Floquet)
        }
    }

    fn undecided() -> Stability {
        Stability::blank(Method::Marching)
    }

    /// Undecided by `method`, every measure empty.
    fn blank(method: Method) -> Stability {
        Stability {
            verdict: Verdict::Undecided,
            method,
            multiplier: None,
            argument: None,
            crossing: None,
            new_frequency_hz: None,
            reduced_dimension: None,
            segments: None,
            audit: None,
            marched_response: None,
            periods: 0,
            change: None,
            departure: None,
            reason: String::new(),
            floquet_vector_file: None,
            floquet_vector: None,
        }
    }

    /// A contact set that does not change over the period: the perturbation sees a linear
    /// time-invariant structure (the closed nodes held), judged by its damping like a linear
    /// scene.
    pub fn constant_contact(model: &Model) -> Stability {
        let linear = linear(model);
        Stability {
            reason: format!(
                "the contact set does not change over the period, so the perturbation sees a linear structure (closed nodes held): {}",
                linear.reason
            ),
            ..linear
        }
    }

    /// A frictional state: undecided, its multipliers not formed.
    pub fn frictional() -> Stability {
        Stability {
            reason: "not judged: the Floquet multipliers of a frictional state (whose \
                     linearization changes between stick and slip) are not formed; \
                     `stability.method: march` judges it by time marching"
                .into(),
            ..Stability::blank(Method::None)
        }
    }

    /// A static state (H = 0): no motion to judge.
    pub fn static_state() -> Stability {
        Stability {
            verdict: Verdict::NotChecked,
            reason: "a static state (H = 0): no periodic motion to judge".into(),
            ..Stability::blank(Method::None)
        }
    }

    /// `Some(true/false)` for a decided verdict.
    pub fn stable(&self) -> Option<bool> {
        match self.verdict {
            Verdict::Stable => Some(true),
            Verdict::Unstable => Some(false),
            _ => None,
        }
    }

    /// The verdict in a few words for the run's headline when the state is not stable: the
    /// verdict and, from Floquet multipliers, how stability is lost and the motion it brings.
    pub fn headline(&self) -> Option<String> {
        let verdict = match self.verdict {
            Verdict::Unstable => "unstable",
            Verdict::Undecided => "undecided",
            _ => return None,
        };
        let how = match (self.crossing, self.multiplier) {
            (Some(c), Some(m)) => {
                let motion = self
                    .new_frequency_hz
                    .map_or(String::new(), |h| format!(", a motion at {h:.4} Hz"));
                format!(" (|μ| = {m:.4}: {}{motion})", c.describe())
            }
            _ => String::new(),
        };
        let vector = (self.floquet_vector_file.as_ref())
            .map_or(String::new(), |f| format!("; the growing motion in {f}"));
        Some(format!(
            "the harmonic-balance state is {verdict}{how}{vector}"
        ))
    }

    /// The run's warning when the state is not one the structure settles into, or when the
    /// time-marching audit disagrees with the Floquet verdict.
    pub fn warning(&self) -> Option<String> {
        if let Some(audit) = &self.audit {
            return Some(format!(
                "the Floquet verdict ({:?}: {}) and the time-marching audit disagree: {audit}. Marching uses another discretization (diagonal mass, explicit steps); where the harmonic balance is coarse (raise the harmonics) the two orbits differ",
                self.verdict, self.reason
            ));
        }
        match self.verdict {
            Verdict::Unstable => Some(format!(
                "the harmonic-balance state is unstable: {}. The structure does not settle into it; a frequency sweep (`hbcontact sweep`) shows the stable branches, and `hbcontact transient` what it does instead",
                self.reason
            )),
            Verdict::Undecided if self.method == Method::None => Some(format!(
                "the stability of the harmonic-balance state is undecided: {}",
                self.reason
            )),
            Verdict::Undecided => Some(format!(
                "the stability of the harmonic-balance state is undecided: {}; raise stability.max_periods",
                self.reason
            )),
            _ => None,
        }
    }
}

/// A contact state that needs no multipliers gets its verdict here: a static state (H = 0)
/// is not judged, and one whose contact set does not change over the period is judged by its
/// damping (`Stability::constant_contact`). Otherwise the closed sets over the period
/// (`floquet::segments`), for the Floquet or marching verdict.
pub fn shortcut(
    model: &Model,
    basis: &hbm::basis::TimeBasis,
    omega: f64,
    contact: &ContactSolution,
) -> std::result::Result<Stability, Vec<Segment>> {
    if contact.harmonics == 0 {
        return Ok(Stability::static_state());
    }
    if contact.friction.is_some() {
        return Ok(Stability::frictional());
    }
    let segments = floquet::segments(basis, omega, contact);
    if segments.len() == 1 {
        return Ok(Stability::constant_contact(model));
    }
    Err(segments)
}

/// The verdict of a linear scene, from its damping.
pub fn linear(model: &Model) -> Stability {
    let damped = model
        .system
        .rayleigh
        .is_some_and(|(a, b)| a > 0.0 || b > 0.0);
    Stability {
        verdict: Verdict::Stable,
        reason: if damped {
            "a damped linear scene: every free vibration decays".into()
        } else {
            "an undamped linear scene: free vibrations neither grow nor decay (stable, not asymptotically)".into()
        },
        ..Stability::blank(Method::Linear)
    }
}

/// The verdict from the Floquet multipliers of a contact state of `model` (the model the
/// harmonic balance solved: its mass) at ω, whose law's closed sets are `segments`
/// (`floquet::segments`).
pub fn by_floquet(model: &Model, segments: &[Segment], omega: f64) -> Result<Stability> {
    let Some(cm) = &model.contact else {
        return Ok(linear(model));
    };
    let nodes = floquet::closed_nodes(segments);
    let reduced = FloquetModel::new(&model.system, &cm.operator.b_free, &nodes)?;
    floquet_verdict(&reduced, segments, omega)
}

/// The open structure's modes a contact run's Hill check keeps (`HillModel::band_modes` at
/// the run's ω), computed at most once: the resonance check reads the modes nearest its
/// harmonics from them where they reach (`resonance::check`), and the Hill model is built on
/// them. Empty where the run makes no Hill check: no contact, a static state, friction, a
/// spline basis, the Coriolis force, marching alone, or no check.
pub struct RunModes {
    omega: Option<f64>,
    modes: std::sync::OnceLock<std::result::Result<Vec<Mode>, String>>,
}

impl RunModes {
    /// The modes `model`'s run under `p` would compute for its Hill check.
    pub fn of(p: &Pipeline, model: &Model) -> RunModes {
        let hill = hill_judges(p, model)
            && p.harmonic_balance.harmonics > 0
            && floquet::refuse_gyroscopic(&model.system).is_ok();
        RunModes {
            omega: hill.then_some(model.system.omega),
            modes: std::sync::OnceLock::new(),
        }
    }

    /// The modes, computed on first use (`None`: the run makes no Hill check).
    pub fn get(&self, model: &Model) -> Option<Result<&[Mode]>> {
        let omega = self.omega?;
        let found = self
            .modes
            .get_or_init(|| HillModel::band_modes(&model.system, omega).map_err(|e| e.to_string()));
        Some(found.as_deref().map_err(|e| Error::Model(e.clone())))
    }
}

/// Whether `model`'s states under `p` are judged by Hill's method: frictionless contact on a
/// Fourier basis, checked by `floquet` or `both` (runs and sweeps alike).
pub fn hill_judges(p: &Pipeline, model: &Model) -> bool {
    let frictionless = (model.contact.as_ref()).is_some_and(|c| c.operator.tangential.is_none());
    frictionless
        && p.stability.check
        && p.stability.method != StabilityMethod::March
        && matches!(
            time_basis(p, Purpose::HarmonicBalance),
            hbm::basis::TimeBasis::Fourier
        )
}

/// The Hill model of a contact scene on a Fourier basis (`None`: splines, judged by the
/// monodromy of `hbm::floquet`; or no contact).
pub fn hill_model(model: &Model, basis: &hbm::basis::TimeBasis) -> Result<Option<HillModel>> {
    match (&model.contact, basis) {
        (Some(cm), hbm::basis::TimeBasis::Fourier) => Ok(Some(HillModel::new(
            &model.system,
            &cm.operator.b_free,
            hbm::hill::MODES,
        )?)),
        _ => Ok(None),
    }
}

/// The Floquet verdict on `contact`, a state of `model` at ω whose closed sets are
/// `segments`: Hill's method on its own harmonic-balance model where `hill` is given and the
/// state carries its compliance, the monodromy of the reduced model otherwise.
pub fn by_floquet_state(
    model: &Model,
    hill: Option<&HillModel>,
    omega: f64,
    contact: &ContactSolution,
    segments: &[Segment],
) -> Result<Stability> {
    match hill {
        Some(hill) if contact.compliance.is_some() => by_hill(hill, contact, omega),
        _ => by_floquet(model, segments, omega),
    }
}

/// The verdict from the multipliers of the state whose closed sets are `segments`, at ω.
pub fn floquet_verdict(
    reduced: &FloquetModel,
    segments: &[Segment],
    omega: f64,
) -> Result<Stability> {
    let m = reduced.multipliers(segments)?;
    Ok(verdict_of(&m, reduced.dim(), omega))
}

/// The verdict by Hill's method (`hbm::hill`) on `contact`, a Fourier state at ω solved with
/// the compliance it carries.
pub fn by_hill(hill: &HillModel, contact: &ContactSolution, omega: f64) -> Result<Stability> {
    let compliance = contact.compliance.as_ref().ok_or_else(|| {
        crate::Error::Model("internal: the state carries no compliance for Hill's method".into())
    })?;
    let r = hill.modes_for(omega, contact.harmonics);
    let m = hill
        .truncated(r, omega)
        .multipliers(compliance, contact, omega)?;
    let mut verdict = verdict_of(&m, r, omega);
    verdict.reason = format!(
        "{}; Hill's method on the harmonic-balance model itself (H = {}, N = {}, {r} modes dynamic): the verdict of the state at this H",
        verdict.reason, contact.harmonics, contact.samples
    );
    Ok(verdict)
}

/// The verdict from the multipliers `m` of a model with `dim` modes kept dynamic, at ω.
pub fn verdict_of(m: &floquet::Multipliers, dim: usize, omega: f64) -> Stability {
    let mu = m.leading();
    let (modulus, argument) = (mu.norm(), mu.im.atan2(mu.re).abs());
    let crossing = m.crossing();
    let f = omega / (2.0 * std::f64::consts::PI);
    let new_frequency_hz = match crossing {
        Crossing::Fold => None,
        Crossing::PeriodDoubling => Some(0.5 * f),
        Crossing::NeimarkSacker => Some(argument / (2.0 * std::f64::consts::PI) * f),
    };
    let motion = new_frequency_hz.map_or(String::new(), |h| format!(", a motion at {h:.4} Hz"));
    let (verdict, reason) = if modulus > 1.0 + floquet::MARGIN {
        let reason = format!(
            "the largest Floquet multiplier |μ| = {modulus:.4} (arg {:.1}°) lies outside the unit circle: stability is lost by {}{motion}",
            argument.to_degrees(),
            crossing.describe()
        );
        (Verdict::Unstable, reason)
    } else if modulus < 1.0 - floquet::MARGIN {
        let reason = format!(
            "every Floquet multiplier lies inside the unit circle (largest |μ| = {modulus:.4}, arg {:.1}°)",
            argument.to_degrees()
        );
        (Verdict::Stable, reason)
    } else {
        let reason = format!(
            "the largest Floquet multiplier lies on the unit circle (|μ| = {modulus:.7}): undamped, or at a bifurcation ({})",
            crossing.describe()
        );
        (Verdict::Undecided, reason)
    };
    Stability {
        verdict,
        multiplier: Some(modulus),
        argument: Some(argument),
        crossing: Some(crossing),
        new_frequency_hz,
        reduced_dimension: Some(dim),
        segments: Some(m.segments),
        reason,
        floquet_vector: m.leading_vector.clone(),
        ..Stability::blank(Method::Floquet)
    }
}

/// `method: both`: Floquet's verdict with what the march did, and the marched verdict where
/// they disagree.
pub fn audited(floquet: Stability, marched: Stability) -> Stability {
    let agree = floquet.verdict == marched.verdict || marched.verdict == Verdict::Undecided;
    let audit = (!agree).then(|| {
        format!(
            "time marching says {:?}: {}",
            marched.verdict, marched.reason
        )
    });
    Stability {
        audit,
        marched_response: marched.marched_response,
        ..floquet
    }
}

/// March the transient model `marching_model` at ω from its harmonic-balance state (solved
/// from `start`, a contact solution of a nearby model, or cold when `None`), perturbed.
pub fn by_marching(
    p: &Pipeline,
    spec: &StabilitySpec,
    marching_model: &Model,
    omega: f64,
    start: Option<&ContactSolution>,
    floquet: Option<&Stability>,
    reporter: &dyn Reporter,
) -> Result<Stability> {
    let Some(diag) = &marching_model.mass_diagonal else {
        return Err(Error::Model(
            "internal: marching needs a diagonal mass".into(),
        ));
    };
    let system = marching_model.system.at_frequency(omega);
    let contact = marching_model.contact.as_ref().map(|c| &c.operator);
    // A frictional state is solved anew on the marching model (a re-solve from a nearby
    // state is the frictionless law's).
    let start = start.filter(|s| s.friction.is_none());
    let solution = match harmonic_balance_state(p, &system, contact, start, reporter) {
        Ok(s) => s,
        Err(Error::NotConverged(why)) => return Ok(undecided_without_state(&why)),
        Err(e) => return Err(e),
    };
    let probes: Vec<usize> = (marching_model.probes.iter())
        .flat_map(|(_, n)| n.iter().copied())
        .collect();
    let marching = Marching::new(&system, diag, contact, &probes)?;
    let model = (marching_model, &marching);
    march_from(p, spec, model, &solution, floquet, reporter)
}

/// The harmonic-balance state at `system`'s ω on the pipeline's time basis (a spline
/// start's unknowns are its discrete frequencies; the march itself takes the Fourier loads
/// of `system`): from `start` where given, else cold.
fn harmonic_balance_state(
    p: &Pipeline,
    system: &hbm::System,
    contact: Option<&ContactOperator>,
    start: Option<&ContactSolution>,
    reporter: &dyn Reporter,
) -> Result<hbm::Solution> {
    let hb = hb_settings(p);
    let hb_system = system
        .clone()
        .with_basis(time_basis(p, Purpose::HarmonicBalance));
    match (contact, start) {
        (Some(op), Some(s)) => hbm::solve_from(&hb_system, op, &hb, s, reporter),
        _ => hbm::solve(&hb_system, contact, &hb, reporter),
    }
}

/// March `model` from `solution`'s state, perturbed by `stability.perturbation`, until the
/// verdict is clear, `stability.max_periods` or `stability.max_seconds`; the verdict, with
/// what the march did (compared with the `floquet` verdict's prediction where given).
fn march_from(
    p: &Pipeline,
    spec: &StabilitySpec,
    (model, marching): (&Model, &Marching),
    solution: &hbm::Solution,
    floquet: Option<&Stability>,
    reporter: &dyn Reporter,
) -> Result<Stability> {
    let dofs = &model.system.dofs;
    let clock = Instant::now();
    let out_of_time = AtomicBool::new(false);
    let stop = |changes: &[f64], departures: &[f64]| {
        let late = clock.elapsed().as_secs_f64() > spec.max_seconds;
        out_of_time.store(late, Ordering::Relaxed);
        late || decided(changes, departures)
    };
    let mut problem = marching.problem();
    problem.initial = Some(marching_start(solution, dofs, spec.perturbation));
    problem.decided = Some(&stop);
    let settings = TransientSettings {
        courant: p.transient.courant,
        periodic_tolerance: SETTLED,
        max_periods: spec.max_periods,
        samples_per_period: SAMPLES,
    };
    let result = transient::run_to_periodic(&problem, &settings, reporter)?;
    reporter.task_done("periods");
    let distance = end_distance(solution, dofs, &result.times, &result.displacement);
    let refine = crate::pipeline::model::time_basis(p, Purpose::HarmonicBalance).refine_key();
    let signals = super::late::LateSignals::of(model, marching, &result.late);
    let f = solution.omega / (2.0 * std::f64::consts::PI);
    let key = "stability.max_periods";
    let late =
        super::late::characterize(&signals, &result.late, result.converged, (floquet, f), key);
    let verdict = Stability {
        marched_response: Some(late.description),
        ..judge(&result.changes, &result.departures, distance, refine)
    };
    if verdict.verdict == Verdict::Undecided && out_of_time.load(Ordering::Relaxed) {
        return Ok(Stability {
            reason: format!(
                "{}; the march reached stability.max_seconds = {} s (the explicit time step follows the smallest element): raise it",
                verdict.reason, spec.max_seconds
            ),
            ..verdict
        });
    }
    Ok(verdict)
}

/// The state time marching starts from: the harmonic-balance `solution`'s u and u̇ at t = 0
/// on the free dofs, scaled by 1 + `perturbation`.
pub fn marching_start(solution: &hbm::Solution, dofs: &DofMap, perturbation: f64) -> InitialState {
    let free = |derivative: u32| -> Vec<f64> {
        let all = solution.field_at(dofs, 0.0, derivative);
        dofs.free.iter().map(|&d| all[d]).collect()
    };
    let start = InitialState {
        displacement: free(0),
        velocity: free(1),
    };
    start.scaled(1.0 + perturbation)
}

/// e: the L²(0, T) distance of the last period's displacements from the harmonic-balance
/// state's, relative to the latter (free dofs, at the recorded instants).
fn end_distance(
    solution: &hbm::Solution,
    dofs: &DofMap,
    times: &[f64],
    marched: &[Vec<f64>],
) -> f64 {
    let (mut diff, mut size) = (0.0, 0.0);
    for (&t, u) in times.iter().zip(marched) {
        let hb = solution.field_at(dofs, t, 0);
        for (&d, &um) in dofs.free.iter().zip(u) {
            diff += (um - hb[d]).powi(2);
            size += hb[d].powi(2);
        }
    }
    (diff / size.max(f64::MIN_POSITIVE)).sqrt()
}

fn undecided_without_state(why: &str) -> Stability {
    Stability {
        reason: format!("the marching model (diagonal mass) has no state here to start from ({why}); this happens within a step of a fold"),
        ..Stability::undecided()
    }
}

/// Whether the history already decides: the state left, or the change grew `GROWTH`-fold
/// at a multiplier above 1, or fell by `DECAY` at one below 1 (after `MIN_PERIODS`).
fn decided(changes: &[f64], departures: &[f64]) -> bool {
    if departures.last().is_some_and(|&e| e > LEFT) {
        return true;
    }
    if changes.len() < MIN_PERIODS {
        return false;
    }
    let Some(mu) = multiplier(changes) else {
        return false;
    };
    let d = changes.last().copied().unwrap_or(f64::NAN);
    let d_min = changes.iter().copied().fold(f64::INFINITY, f64::min);
    let d_max = changes.iter().copied().fold(0.0, f64::max);
    (mu > 1.0 + MARGIN && d > GROWTH * d_min) || (mu < 1.0 - MARGIN && d * DECAY < d_max)
}

/// The verdict from the period-to-period changes d_k, the departures from the start and the
/// end state's distance e from the harmonic-balance state (see the header).
/// `refine` is the key that refines the harmonic-balance state in time.
pub fn judge(changes: &[f64], departures: &[f64], e: f64, refine: &str) -> Stability {
    let periods = changes.len();
    let d = changes.last().copied().unwrap_or(f64::NAN);
    let left = departures.last().is_some_and(|&x| x > LEFT);
    let mu = multiplier(changes);
    let d_min = changes.iter().copied().fold(f64::INFINITY, f64::min);
    let growing = mu.is_some_and(|m| m > 1.0 + MARGIN) && d > GROWTH * d_min;
    let settled = d < SETTLED || mu.is_some_and(|m| m < 1.0 - MARGIN);
    let per_period = |m: Option<f64>| m.map_or("unknown".to_string(), |m| format!("{m:.3}"));
    let (verdict, reason) = if growing {
        let reason = format!(
            "time marching from it drifts away: the period-to-period change grows by {} per period (the largest Floquet multiplier's modulus)",
            per_period(mu)
        );
        (Verdict::Unstable, reason)
    } else if left {
        let reason = format!("time marching from it left it within {periods} periods");
        (Verdict::Unstable, reason)
    } else if settled && e >= SAME_STATE {
        let reason = format!(
            "time marching from it settles on another state, {:.0}% away in displacement (if the harmonic balance is too coarse to be within {:.0}% of the marched orbit, raise {refine} and compare)",
            100.0 * e,
            100.0 * SAME_STATE
        );
        (Verdict::Unstable, reason)
    } else if settled {
        let reason = format!(
            "time marching from it stays, {:.1}% from it in displacement, the change decaying by {} per period",
            100.0 * e,
            per_period(mu)
        );
        (Verdict::Stable, reason)
    } else {
        let reason = format!(
            "after {periods} periods of time marching the change neither decays nor grows (multiplier {})",
            per_period(mu)
        );
        (Verdict::Undecided, reason)
    };
    Stability {
        verdict,
        multiplier: mu,
        periods,
        change: Some(d),
        departure: Some(e),
        reason,
        ..Stability::blank(Method::Marching)
    }
}

/// μ̂: exp of the least-squares slope of ln d_k over the last half of the periods (at least 4).
fn multiplier(changes: &[f64]) -> Option<f64> {
    let tail: Vec<(f64, f64)> = changes
        .iter()
        .enumerate()
        .skip(changes.len() / 2)
        .filter(|(_, d)| **d > 0.0 && d.is_finite())
        .map(|(k, d)| (k as f64, d.ln()))
        .collect();
    if tail.len() < 4 {
        return None;
    }
    let n = tail.len() as f64;
    let (mk, ml) = (
        tail.iter().map(|t| t.0).sum::<f64>() / n,
        tail.iter().map(|t| t.1).sum::<f64>() / n,
    );
    let sxy: f64 = tail.iter().map(|(k, l)| (k - mk) * (l - ml)).sum();
    let sxx: f64 = tail.iter().map(|(k, _)| (k - mk).powi(2)).sum();
    Some((sxy / sxx).exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a march that settles (changes decaying by 0.5 per period) on a state 20%
    /// from the harmonic-balance one is judged unstable, and the reason names the key that
    /// refines the harmonic-balance state in time, as given.
    #[test]
    fn settling_elsewhere_is_unstable_and_names_the_refining_key() {
        let changes: Vec<f64> = (0..30).map(|k| 0.5f64.powi(k)).collect();
        let departures = vec![0.0; 30];
        let key = "harmonic_balance.basis.spline.segments";
        let s = judge(&changes, &departures, 0.2, key);
        assert_eq!(s.verdict, Verdict::Unstable);
        assert!(s.reason.contains(key), "{}", s.reason);
        assert!((s.multiplier.unwrap() - 0.5).abs() < 1e-9);
    }
}
