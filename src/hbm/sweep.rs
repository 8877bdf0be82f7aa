//! Frequency-response curves: pseudo-arclength continuation of the contact solution in
//! (λ, ω), which passes the folds contact bends a resonance into (docs/method.md, "Sweeps").
//!
//! Glossary and formulas:
//! - R(λ, ω) = 0 the complementarity residual (23) at ω, J = ∂R/∂λ its Newton matrix;
//! - R_ω = ∂R/∂ω = Q D P (c ∂g/∂ω) at fixed λ, exact from the kept factorizations:
//!   ∂g_k/∂ω = B ∂z_k/∂ω,  ∂z_k/∂ω = −Z_k⁻¹ (∂Z_k/∂ω z_k + ∂Z_k,fp/∂ω u_p,k),
//!   ∂Z_k/∂ω = −2k²ω M + ik(αM + βK) (two solves per harmonic: the recovery and this);
//! - y = (λ/F, ω/Ω) the scaled unknowns: F a force scale (c × the 2-norm of the first point's
//!   linear-gap coefficients, so ‖λ/F‖ is of order one), Ω the sweep's span |ω_end − ω_start|;
//!   s the arc length in y;
//! - direction τ: at the first point the tangent, [J F, R_ω Ω; (0, ±1)ᵀ] τ = [0; 1]
//!   normalised; after that the secant from the previous point, normalised. The contact law
//!   makes R only piecewise smooth in λ (samples switch between open and closed), so J-based
//!   tangents flip at kinks; the secant follows the curve through them;
//! - predictor y_p = y + Δs τ; corrector on R = 0 and τᵀ(y − y_p) = 0. Where the curve is a
//!   graph over ω (|τ_ω| ≥ `GRAPH_SLOPE`) the corrector keeps ω = ω_p and iterates on λ alone
//!   (one set of factorizations per point); near a fold ω is an unknown: a chord corrector on
//!   the problem frozen at ω_p, g ≈ G(ω_p)λ + r(ω_p) + (ω − ω_p) ∂g/∂ω, then one set of
//!   factorizations at its ω* and a fixed-ω Newton (two sets per point); where that fails, Z_k
//!   is refactored numerically (the symbolic analysis is shared) at every corrector iterate;
//! - folds: sign changes of the secants' ω-components, at the point where ω turns back; a
//!   back-and-forth within `KINK` of the span over a few points is a kink of
//!   the sampled law (one sample switching), not reported.
//!
//! Step control: a corrector that fails, needs more than `MAX_CORRECTOR` iterations, lands
//! farther than Δs from the predictor (a jump to another branch) or changes the contact gaps
//! by more than `max_change` (relative: ‖Δg̃‖/max(‖g̃_a‖, ‖g̃_b‖, `GAP_FLOOR`·‖g̃_lin‖), g̃_lin
//! the first point's contact-free gap, so a contact closed all period, whose gaps are
//! round-off, is not measured against its round-off) rejects the step and halves Δs; an easy
//! step (≤ 3 iterations) grows it by 1.5, up to the maximum.
//!
//! Resume: a `ContinuationState` saved after any point holds all the continuation carries from
//! one point to the next (index, ω, the next Δs, τ, λ, F, c, N, the largest ‖λ‖, the trail,
//! the Krylov hint, the frequencies the reduced model learned at and the kind of the point's
//! frame), and continues the curve from that point as if it had not stopped: the model is
//! built and taught again, the point's λ is taken as saved on a frame of the same kind (a
//! Newton from it checks it solves there, on its own branch), and the points after it are the
//! uninterrupted sweep's bit for bit.

use std::time::Instant;

use faer::Mat;

use super::fourier::{node_phasors, set_phasor};
use super::frames::{self, ReducedModel};
use super::reduced::{NewtonSettings, Residual};
use super::step;
use super::{globalize, prepare, prepare_with, Source};
use super::{ContactSolution, HbSettings, LinearResponse, ReducedProblem, Solution, System};
use super::{NewtonOutcome, Timings};
use crate::contact::ContactOperator;
use crate::progress::Reporter;
use crate::{Error, Result};

/// |τ_ω| above which the corrector keeps ω fixed (the curve is a graph over ω there).
const GRAPH_SLOPE: f64 = 0.05;
/// A corrector that lands farther than this many steps from its predictor jumped to another
/// branch (a kink of the sampled law bends the curve by less).
const JUMP: f64 = 3.0;
/// A corrector landing farther than `JUMP` steps is still accepted, as a corner of the curve
/// where a branch leaves at an angle (contact starting on a steep resonance), when halving the
/// step shrank its distance below `CORNER_SHRINK` of the last and it is within `CORNER` steps.
const CORNER_SHRINK: f64 = 0.6;
const CORNER: f64 = 30.0;
/// The last segments of the trail a new point is not compared with (a kink's back-and-forth).
const RECENT: usize = 4;
/// A point closer than this many steps to an earlier segment of the curve retraces it.
const RETRACE: f64 = 0.05;
/// The fixed-ω Newton that puts the chord corrector's point on the curve may move λ by at most
/// this many arc-length steps (scaled); more means it found another state.
const CHORD_POLISH: f64 = 0.1;
/// Corrector iterations before a step is rejected.
const MAX_CORRECTOR: usize = 12;
/// A point whose ‖λ‖ is below this fraction of the largest along the curve may be at a
/// grazing corner (on the strip the contact force there is 0.1–0.2% of its largest, in mean).
const GRAZING: f64 = 0.05;

/// What to sweep and how finely (the solver's view; the pipeline validates it).
#[derive(Clone, Debug)]
pub struct SweepSettings {
    /// Start and end of the sweep [rad/s] (either order).
    pub omega_start: f64,
    pub omega_end: f64,
    /// Initial, smallest and largest arc-length step, as fractions of the scaled curve
    /// (ω span = 1).
    pub step: f64,
    pub min_step: f64,
    pub max_step: f64,
    /// At most this many points.
    pub max_points: usize,
    /// Largest relative change of the contact gaps' (or, without contact, the response's)
    /// coefficients from one point to the next.
    pub max_change: f64,
    /// Continue a sweep from its last saved point instead of starting at `omega_start`.
    pub resume: Option<ContinuationState>,
    /// Frequencies over the range at which the reduced model places its shifts
    /// (`frames::SHIFTS_PER_HARMONIC` by default; 0: no model, every frame factored).
    pub model_frequencies: usize,
}

/// Where a continuation stands after a point: with the same settings, continuing from it
/// gives the points the uninterrupted sweep would have given, bit for bit (the point's
/// multipliers are taken as saved, on a frame of the kind they were solved on, so on their
/// own branch; everything else a point hands the next is here too).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct ContinuationState {
    /// The point's index on the curve.
    pub index: usize,
    /// The point's ω [rad/s].
    pub omega: f64,
    /// The arc-length step the next point is tried with.
    pub step: f64,
    /// The unit direction (secant) at the point in the scaled unknowns (λ/F, ω/Ω); its last
    /// entry τ_ω (negative on a branch running back). Without contact: [±1].
    pub tangent: Vec<f64>,
    /// The contact multipliers' coefficients (empty without contact).
    pub multipliers: Vec<f64>,
    /// The force scale F, and the c and N the curve's first point fixed (0 without contact).
    pub force_scale: f64,
    pub c: f64,
    pub samples: usize,
    /// The largest ‖λ‖ along the curve up to this point (grazing is judged against it; 0
    /// without contact).
    pub largest: f64,
    /// The point was solved on a frame of the reduced model (`sweep.reduced_frames`), not on
    /// factorizations: the resumed point is taken on the same kind of frame.
    pub reduced_frame: bool,
    /// The ω [rad/s] of the exact frames the reduced model learned from so far
    /// (`frames::ReducedModel::enrich_from`), in order: a resume builds the model again and
    /// has it learn the same.
    pub enriched_at: Vec<f64>,
    /// The Krylov steps of the next Newton start with the harmonic blocks (`step::KrylovHint`).
    pub harmonic_first: bool,
    /// The points before this one in the scaled unknowns (λ/F, ω/Ω), in curve order: the
    /// trail a retrace is checked against (empty without contact). `hbm::sweep` leaves it
    /// empty in each point's state (`PointInfo::scaled` gives the points one by one); the
    /// caller fills it where it saves the state.
    pub trail: Vec<Vec<f64>>,
}

/// How one point's corrector ran.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Corrector {
    /// The first point: the single-frequency solve with its globalization.
    Cold,
    /// Newton in λ at the predicted ω.
    FixedFrequency,
    /// Bordered Newton in (λ, ω) on the arc-length constraint.
    Arclength,
    /// No contact: the linear response at ω.
    Linear,
    /// The open state (λ = 0) one step back in ω from a grazing corner, where a contacting
    /// branch ends on the open one and the curve turns back.
    Grazing,
}

/// One accepted point of the curve (the solution itself goes to the caller's callback).
#[derive(Clone, Debug)]
pub struct PointInfo {
    pub index: usize,
    pub omega: f64,
    pub corrector: Corrector,
    /// Newton iterations of the corrector (0 for a linear point).
    pub newton_iterations: usize,
    /// Sets of factorizations this point cost (its rejected attempts included).
    pub factorizations: usize,
    /// The arc-length step that reached it.
    pub step: f64,
    /// τ_ω, the ω-component of the unit tangent (negative on a branch that runs back).
    pub tangent_omega: f64,
    /// Wall time of this point, rejected attempts included [s].
    pub seconds: f64,
    /// What continuing the sweep from this point needs.
    pub state: Option<ContinuationState>,
    /// The point in the scaled unknowns (λ/F, ω/Ω) as the continuation's trail holds it
    /// (empty without contact): `ContinuationState::trail` is these, point by point.
    pub scaled: Vec<f64>,
}

/// A turning point of the curve.
#[derive(Clone, Debug, serde::Serialize, schemars::JsonSchema)]
pub struct Fold {
    /// The point where ω turns back (within one step of the fold).
    pub after: usize,
    /// That point's ω [rad/s].
    pub omega: f64,
}

/// How a sweep ended.
#[derive(Clone, Debug, Default)]
pub struct SweepOutcome {
    pub points: usize,
    pub folds: Vec<Fold>,
    /// Why the sweep stopped before the end (`None`: it reached the end frequency).
    pub stopped: Option<String>,
    pub timings: Timings,
    /// What the reduced model did (all zero when the sweep factored every frame).
    pub reduced: ReducedFrames,
}

/// The reduced model's account of a sweep.
#[derive(Clone, Debug, Default, serde::Serialize, schemars::JsonSchema)]
pub struct ReducedFrames {
    /// Its dimension r at the end (0: no model, every frame factored).
    pub dimension: usize,
    /// Frames it gave.
    pub frames: usize,
    /// Points whose check failed, solved again on exact frames (and learned from).
    pub replaced: usize,
    /// The largest backward error of a kept point from a reduced frame.
    pub largest_error: f64,
}

/// The receiver of each accepted point and its recovered solution.
pub type OnPoint<'a> = dyn FnMut(&PointInfo, &Solution) -> Result<()> + 'a;

/// Sweep ω from `omega_start` to `omega_end`, calling `on_point` for every accepted point.
/// `system.omega` is changed along the way. Errors only when the first point cannot be
/// solved or the callback fails; a sweep that cannot go on stops with `stopped` set.
pub fn sweep(
    system: &mut System,
    contact: Option<&ContactOperator>,
    hb: &HbSettings,
    s: &SweepSettings,
    reporter: &dyn Reporter,
    on_point: &mut OnPoint,
) -> Result<SweepOutcome> {
    // A spline basis with contact sweeps on odd S only: an even S has a Nyquist frequency
    // without damping (σ_{S/2} = 0), and a sweep passes the frequencies where S/2·ω meets one
    // of the mesh's many high modes, where the branch climbs without bound (docs/method.md
    // §16). The pipeline refuses it too.
    if let super::basis::TimeBasis::Spline(b) = &system.basis {
        if contact.is_some() && b.segments.is_multiple_of(2) {
            return Err(Error::Input(format!(
                "harmonic_balance.basis: a sweep with contact needs an odd number of spline segments (the {} basis has an undamped Nyquist frequency); use {} segments",
                system.basis.describe(),
                b.segments + 1
            )));
        }
    }
    let hb = &super::contact_settings(system, contact.is_some(), hb)?;
    match contact {
        Some(op) => Continuation::start(system, op, hb, s, reporter)?.run(on_point),
        None => linear_sweep(system, hb, s, reporter, on_point),
    }
}

/// Everything at one ω: the factorizations (or a reduced model's solves), the linear response
/// and the reduced problem.
struct Frame {
    omega: f64,
    linear: LinearResponse,
    problem: ReducedProblem,
    /// From the reduced model (its points are checked before they are kept).
    reduced: bool,
}

/// A converged point: its multipliers, ω, unit tangent and contact gaps.
struct Point {
    x: Vec<f64>,
    omega: f64,
    tangent: Vec<f64>,
    gaps: Vec<f64>,
}

impl Point {
    fn tangent_omega(&self) -> f64 {
        self.tangent[self.x.len()]
    }
}

struct Continuation<'a> {
    system: &'a mut System,
    op: &'a ContactOperator,
    hb: &'a HbSettings,
    s: &'a SweepSettings,
    reporter: &'a dyn Reporter,
    newton: NewtonSettings,
    /// F and Ω of the scaling.
    force: f64,
    span: f64,
    direction: f64,
    timings: Timings,
    factorizations: usize,
    /// The largest ‖λ‖ along the curve so far (where grazing is judged against).
    largest: f64,
    /// How far the last rejected corrector of this point landed from its predictor, when it
    /// was rejected as a jump.
    jumped: Option<f64>,
    /// The first point (cold, or the resumed point re-solved), its Newton and its frame
    /// (taken by `run`).
    first: Option<(Vec<f64>, NewtonOutcome, Frame)>,
    /// The reduced model of Z_k(ω)⁻¹ frames come from, when the scene has one.
    model: Option<ReducedModel>,
    /// `build_model` ran (after the first point; before it, for a resumed one).
    model_built: bool,
    /// The ω of the exact frames the model learned from (`ContinuationState::enriched_at`).
    enriched_at: Vec<f64>,
    reduced: ReducedFrames,
}

impl<'a> Continuation<'a> {
    /// The cold first point (the single-frequency solve, knob checks included) fixes c and N
    /// for the whole curve; a resumed one is taken as saved (`resume_at`).
    fn start(
        system: &'a mut System,
        op: &'a ContactOperator,
        hb: &'a HbSettings,
        s: &'a SweepSettings,
        reporter: &'a dyn Reporter,
    ) -> Result<Self> {
        let omega = s.resume.as_ref().map_or(s.omega_start, |r| r.omega);
        system.omega = omega;
        let newton = NewtonSettings {
            tolerance: hb.tolerance,
            max_iterations: MAX_CORRECTOR,
            ..Default::default()
        };
        let mut c = Continuation {
            system,
            op,
            hb,
            s,
            reporter,
            newton,
            force: 0.0,
            span: (s.omega_end - s.omega_start).abs(),
            direction: (s.omega_end - s.omega_start).signum(),
            timings: Timings::default(),
            factorizations: 0,
            largest: 0.0,
            jumped: None,
            first: None,
            model: None,
            model_built: false,
            enriched_at: Vec::new(),
            reduced: ReducedFrames::default(),
        };
        match &s.resume {
            None => c.cold_start(omega)?,
            Some(r) => c.resume_at(r)?,
        }
        Ok(c)
    }

    /// The first point of a new curve: the single-frequency solve at ω on factorizations.
    fn cold_start(&mut self, omega: f64) -> Result<()> {
        let frame = self.exact_frame(omega)?;
        let first = super::solve_contact_timed(
            self.system,
            self.op,
            &frame.problem,
            self.hb,
            self.reporter,
            &mut self.timings,
        )?;
        let norm = frame.problem.linear_gap.iter().map(|v| v * v).sum::<f64>();
        (self.newton.samples, self.newton.c) = (first.samples, first.c);
        self.force = (first.c * norm.sqrt()).max(f64::MIN_POSITIVE);
        self.first = Some((first.multipliers, first.newton, frame));
        Ok(())
    }

    /// The saved point `r`, where the uninterrupted continuation stood after it: its scaling,
    /// c, N and Krylov hint, the largest ‖λ‖ so far, the reduced model built and taught at the
    /// saved frequencies as it was then, and the point's frame of the same kind (reduced or
    /// factored) as the one it was solved on. Its multipliers solve that frame as they are
    /// (checked by a Newton from them, which then takes no step), so the continuation goes on
    /// from the very state it stopped in.
    fn resume_at(&mut self, r: &ContinuationState) -> Result<()> {
        (self.newton.samples, self.newton.c) = (r.samples, r.c);
        self.newton.krylov_hint.set_harmonic_first(r.harmonic_first);
        self.force = r.force_scale;
        self.largest = r.largest;
        self.build_model();
        if self.model.is_none() && !r.enriched_at.is_empty() {
            return Err(Error::Input(format!(
                "the saved point (sweep.json's `resume.enriched_at`) at {:.6} Hz names \
                 frequencies a reduced model learned at, and this scene's sweep builds none: \
                 sweep again without --resume",
                hz(r.omega)
            )));
        }
        for &omega in &r.enriched_at {
            let exact = self.exact_frame(omega)?;
            self.enrich(&exact);
        }
        if r.reduced_frame && self.model.is_none() {
            return Err(Error::Input(format!(
                "the saved point (sweep.json's `resume`) at {:.6} Hz was solved on a frame of \
                 the reduced model, which this scene does not build (`sweep.reduced_frames`, \
                 the mesh or the contact set changed): sweep again without --resume",
                hz(r.omega)
            )));
        }
        let frame = self.frame_from(r.omega, r.reduced_frame)?;
        let o = resolve_saved(&frame, &self.newton, r, self.reporter)?;
        self.factorizations = 1;
        self.first = Some((o.multipliers.clone(), o, frame));
        Ok(())
    }

    /// Teach the reduced model the solves of the exact frame `exact` (`frames::enrich_from`),
    /// noting its ω for a resume; a model that cannot learn them is dropped.
    fn enrich(&mut self, exact: &Frame) {
        let Some(model) = self.model.as_mut() else {
            return;
        };
        let clock = Instant::now();
        self.enriched_at.push(exact.omega);
        let enriched = model.enrich_from(self.system, &self.op.b_free, &exact.linear.factors);
        if enriched.is_err() {
            self.model = None;
        }
        self.timings.reduce += clock.elapsed().as_secs_f64();
    }

    /// The frame at ω: from the reduced model when there is one, else one set of
    /// factorizations and the reduction.
    fn frame(&mut self, omega: f64) -> Result<Frame> {
        self.frame_from(omega, self.model.is_some())
    }

    /// The frame at ω from one set of factorizations.
    fn exact_frame(&mut self, omega: f64) -> Result<Frame> {
        self.frame_from(omega, false)
    }

    fn frame_from(&mut self, omega: f64, reduced: bool) -> Result<Frame> {
        self.system.omega = omega;
        if reduced {
            self.reduced.frames += 1;
        } else {
            self.factorizations += 1;
        }
        let (linear, problem) = prepare_with(
            self.system,
            Some(self.op),
            self.hb,
            self.reporter,
            &mut self.timings,
            match self.model.as_ref().filter(|_| reduced) {
                Some(model) => Source::Reduced(model),
                None => Source::Factors,
            },
        )?;
        let problem = problem.ok_or_else(|| Error::Model("internal: no reduced problem".into()))?;
        Ok(Frame {
            omega,
            linear,
            problem,
            reduced,
        })
    }

    /// The reduced model for the sweep's range, where it pays: its start block times the
    /// shifts well below the number of free dofs (few contact nodes). Built after the first
    /// point, so a model that cannot be built only costs the sweep its speed.
    fn build_model(&mut self) {
        if std::mem::replace(&mut self.model_built, true) {
            return;
        }
        let frequencies = self.s.model_frequencies;
        if !reduced_model_pays(self.system, self.op.nodes(), self.hb.harmonics, frequencies) {
            return;
        }
        let clock = Instant::now();
        let range = (self.s.omega_start, self.s.omega_end);
        let (b, h) = (&self.op.b_free, self.hb.harmonics);
        self.model = ReducedModel::build(self.system, b, range, frequencies, h).ok();
        self.timings.reduce += clock.elapsed().as_secs_f64();
    }

    /// `next` on `frame` as kept: a reduced frame's point whose recovered field misses the
    /// harmonic-balance equations by more than `frames::BACKWARD_TOLERANCE` (backward error)
    /// is solved again on an exact frame at its ω, from its own multipliers, and the model
    /// learns that frame's solves.
    fn verified(
        &mut self,
        p: &Point,
        next: Point,
        frame: Frame,
    ) -> std::result::Result<(Point, Frame), String> {
        if !frame.reduced {
            return Ok((next, frame));
        }
        let m = frame.problem.coefficients();
        let clock = Instant::now();
        let error = frames::point_backward_error(self.system, self.op, &frame.linear, &next.x, m);
        self.timings.reduce += clock.elapsed().as_secs_f64();
        if error <= frames::BACKWARD_TOLERANCE {
            self.reduced.largest_error = self.reduced.largest_error.max(error);
            return Ok((next, frame));
        }
        self.reduced.replaced += 1;
        let exact = self.exact_frame(frame.omega).map_err(|e| e.to_string())?;
        self.enrich(&exact);
        let o = super::reduced::newton(&exact.problem, &self.newton, &next.x, self.reporter);
        if !o.converged {
            return Err(format!("the exact frame of a reduced point: {}", o.reason));
        }
        let point = self.after(p, o.multipliers, &exact)?;
        Ok((point, exact))
    }

    fn run(mut self, on_point: &mut OnPoint) -> Result<SweepOutcome> {
        let clock = Instant::now();
        let (x, first_newton, frame) = self
            .first
            .take()
            .ok_or_else(|| Error::Model("internal: the sweep's first point was taken".into()))?;
        let (tangent, start, mut ds) = match &self.s.resume {
            Some(r) => (r.tangent.clone(), r.index, r.step),
            None => {
                let initial = [vec![0.0; x.len()], vec![self.direction]].concat();
                (self.tangent(&frame, &x, &initial)?, 0, self.s.step)
            }
        };
        let mut point = Point {
            gaps: frame.problem.gap(&x),
            x,
            omega: frame.omega,
            tangent,
        };
        let mut outcome = SweepOutcome::default();
        // A resumed point brings the largest ‖λ‖ before it and its trail.
        self.largest = self.largest.max(norm(&point.x));
        let mut trail = Trail::default();
        for y in self.s.resume.iter().flat_map(|r| &r.trail) {
            trail.push(y.clone());
        }
        let y = self.scaled(&point);
        trail.push(y.clone());
        let info = PointInfo {
            index: start,
            omega: frame.omega,
            corrector: Corrector::Cold,
            newton_iterations: first_newton.iterations,
            factorizations: self.factorizations,
            step: 0.0,
            tangent_omega: point.tangent_omega(),
            seconds: clock.elapsed().as_secs_f64(),
            state: Some(self.state(&point, ds, start, frame.reduced)),
            scaled: y,
        };
        self.build_model();
        self.emit(&info, &point.x, frame, first_newton, on_point)?;
        let mut index = start + 1;
        while index < self.s.max_points {
            if self.beyond_end(&point) {
                break;
            }
            let (next, frame, mut info) = match self.next_point(&point, &mut ds, index) {
                Ok(found) => found,
                Err(stopped) => {
                    outcome.stopped = Some(stopped);
                    break;
                }
            };
            let y = self.scaled(&next);
            if let Some(j) = trail.retraced(&y, info.step) {
                let key = self.system.basis.refine_key();
                outcome.stopped = Some(retrace_reason(&point, index - 1, j, key));
                break;
            }
            trail.push(y.clone());
            if index > 1 && point.tangent_omega() * next.tangent_omega() < 0.0 {
                outcome.folds.push(fold(index - 1, &point));
            }
            let newton = NewtonOutcome {
                multipliers: Vec::new(),
                converged: true,
                iterations: info.newton_iterations,
                relative_residual: 0.0,
                log: Vec::new(),
                reason: String::new(),
            };
            self.largest = self.largest.max(norm(&next.x));
            info.state = Some(self.state(&next, ds, index, frame.reduced));
            info.scaled = y;
            self.emit(&info, &next.x, frame, newton, on_point)?;
            let status = format!("{:.3} Hz", hz(next.omega));
            self.reporter.progress("sweep", index as u64, None, &status);
            point = next;
            index += 1;
        }
        self.reporter.task_done("sweep");
        outcome.points = index;
        outcome.folds = without_kinks(std::mem::take(&mut outcome.folds), KINK * self.span);
        outcome.timings = self.timings;
        outcome.reduced = ReducedFrames {
            dimension: self.model.as_ref().map_or(0, ReducedModel::dim),
            ..self.reduced
        };
        Ok(outcome)
    }

    /// The point after `p`: steps from `ds`, halved on every failure down to the smallest
    /// step, grown after an easy one; `Err` says why the curve cannot go on.
    fn next_point(
        &mut self,
        p: &Point,
        ds: &mut f64,
        index: usize,
    ) -> std::result::Result<(Point, Frame, PointInfo), String> {
        let clock = Instant::now();
        self.factorizations = 0;
        self.jumped = None;
        loop {
            match self.step(p, *ds) {
                Ok((next, frame, corrector, iterations)) => {
                    let info = PointInfo {
                        index,
                        omega: next.omega,
                        corrector,
                        newton_iterations: iterations,
                        factorizations: self.factorizations,
                        step: *ds,
                        tangent_omega: next.tangent_omega(),
                        seconds: clock.elapsed().as_secs_f64(),
                        state: None,
                        scaled: Vec::new(),
                    };
                    if iterations <= 3 {
                        *ds = (1.5 * *ds).min(self.s.max_step);
                    }
                    return Ok((next, frame, info));
                }
                Err(why) if *ds * 0.5 >= self.s.min_step => {
                    let status = format!("from {:.3} Hz, Δs/2: {why}", hz(p.omega));
                    self.reporter.progress("sweep", index as u64, None, &status);
                    *ds *= 0.5;
                }
                Err(why) => {
                    if let Some(found) = self.graze(p, index) {
                        // Past the corner the curve is a new smooth branch.
                        *ds = self.s.step;
                        return Ok(found);
                    }
                    return Err(format!(
                        "at {:.6} Hz the continuation found no next point down to the \
                         smallest step {:.1e} ({why}); lower sweep.min_step, raise {} or add \
                         damping",
                        hz(p.omega),
                        self.s.min_step,
                        self.system.basis.refine_key()
                    ));
                }
            }
        }
    }

    /// y = (λ/F, ω/Ω), the point in the scaled unknowns the arc length is measured in.
    fn scaled(&self, p: &Point) -> Vec<f64> {
        let x = p.x.iter().map(|v| v / self.force);
        x.chain([p.omega / self.span]).collect()
    }

    /// What continuing from `p` (point `index`, next step `ds`, solved on a `reduced` frame or
    /// not) needs, but its trail (`ContinuationState::trail`).
    fn state(&self, p: &Point, ds: f64, index: usize, reduced: bool) -> ContinuationState {
        ContinuationState {
            index,
            omega: p.omega,
            step: ds,
            tangent: p.tangent.clone(),
            multipliers: p.x.clone(),
            force_scale: self.force,
            c: self.newton.c,
            samples: self.newton.samples,
            largest: self.largest,
            reduced_frame: reduced,
            enriched_at: self.enriched_at.clone(),
            harmonic_first: self.newton.krylov_hint.harmonic_first(),
            trail: Vec::new(),
        }
    }

    /// Past the end frequency, moving away from it.
    fn beyond_end(&self, p: &Point) -> bool {
        let past = (p.omega - self.s.omega_end) * self.direction >= 0.0;
        let before = (p.omega - self.s.omega_start) * self.direction < 0.0;
        let onward = p.tangent_omega() * self.direction;
        (past && onward > 0.0) || (before && onward < 0.0)
    }

    /// Predictor and corrector from `p` with arc-length step `ds`.
    fn step(
        &mut self,
        p: &Point,
        ds: f64,
    ) -> std::result::Result<(Point, Frame, Corrector, usize), String> {
        let n = p.x.len();
        let t = &p.tangent;
        let mut omega_p = p.omega + ds * t[n] * self.span;
        // Land on the end frequency rather than past it.
        let end = self.s.omega_end;
        let landing =
            (omega_p - end) * self.direction > 0.0 && (p.omega - end) * self.direction < 0.0;
        if landing {
            omega_p = end;
        }
        let x_p: Vec<f64> = (0..n).map(|i| p.x[i] + ds * t[i] * self.force).collect();
        let clock = Instant::now();
        let prepared = self.prepare_seconds();
        // Near a grazing corner `graze` steps to the open branch instead.
        let corner = ds <= CORNER_STEPS * self.s.min_step && norm(&p.x) > GRAZING * self.largest;
        let corrected = self.correct(&x_p, omega_p, t, ds, (landing, corner));
        // The corrector's own time (Newton, bordered solves, ∂g/∂ω) without its factorizations.
        self.timings.newton += clock.elapsed().as_secs_f64() - (self.prepare_seconds() - prepared);
        let (x, frame, corrector, iterations) = corrected?;
        // Distance from the predictor in the scaled metric.
        let dist = ((0..n)
            .map(|i| ((x[i] - x_p[i]) / self.force).powi(2))
            .sum::<f64>()
            + ((frame.omega - omega_p) / self.span).powi(2))
        .sqrt();
        // A corner of the curve (a branch leaving at an angle) keeps dist/ds as ds shrinks;
        // another branch keeps dist.
        let corner = self
            .jumped
            .is_some_and(|d| dist < CORNER_SHRINK * d && dist < CORNER * ds);
        if dist > JUMP * ds && !corner {
            self.jumped = Some(dist);
            return Err(format!(
                "the corrector moved {dist:.2e} from the predictor, more than {JUMP} steps of {ds:.2e}"
            ));
        }
        let point = self.after(p, x, &frame)?;
        let (point, frame) = self.verified(p, point, frame)?;
        let floor = GAP_FLOOR * self.force / self.newton.c;
        let change = relative_change(&p.gaps, &point.gaps, floor);
        if change > self.s.max_change && ds > self.s.min_step {
            return Err(format!("the contact gaps changed by {change:.2e}"));
        }
        Ok((point, frame, corrector, iterations))
    }

    /// The point with multipliers `x` on `frame`, reached from `p`: its direction is the
    /// secant from `p`.
    fn after(&self, p: &Point, x: Vec<f64>, frame: &Frame) -> std::result::Result<Point, String> {
        let mut secant: Vec<f64> = (0..x.len())
            .map(|i| (x[i] - p.x[i]) / self.force)
            .chain([(frame.omega - p.omega) / self.span])
            .collect();
        let length = secant.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(length > 0.0) {
            return Err("the corrector returned to the same point".into());
        }
        secant.iter_mut().for_each(|v| *v /= length);
        Ok(Point {
            gaps: frame.problem.gap(&x),
            x,
            omega: frame.omega,
            tangent: secant,
        })
    }

    /// The corner where a contacting branch ends on the open one (grazing): past it along
    /// the secant no solution exists, so no step, however small, converges. The curve goes on
    /// along the open (linear) branch, on the side of the grazing frequency where the open
    /// state is feasible (the linear response does not reach the obstacle): back in ω when
    /// the contacting branch came from that side (a fold: both branches exist there), onward
    /// when it came from the side where the linear response penetrates (a corner without a
    /// fold). So the open state (λ = 0) is tried one initial step back from `p`, then one step
    /// onward; it is the next point if `p` touches, but barely (‖λ‖ below `GRAZING` of the
    /// largest along the curve; zero when `p` landed on the corner itself), the open state
    /// solves the complementarity there and lies within `JUMP` largest steps of `p`. `None`:
    /// `p` is not at a grazing corner.
    fn graze(&mut self, p: &Point, index: usize) -> Option<(Point, Frame, PointInfo)> {
        let force = norm(&p.x);
        if force > GRAZING * self.largest || self.largest == 0.0 {
            return None;
        }
        let onward = p.tangent_omega().signum() * self.s.step * self.span;
        let (scale, span) = (self.force, self.span);
        let dist = |shift: f64| (force / scale).hypot(shift / span);
        [-onward, onward]
            .into_iter()
            .filter(|&shift| dist(shift) <= JUMP * self.s.max_step)
            .find_map(|shift| self.open_point(p, shift, dist(shift), index))
    }

    /// The open state at ω_p + `shift`, if it solves the complementarity there: the next
    /// point after the grazing corner `p`, moving along ω alone.
    fn open_point(
        &mut self,
        p: &Point,
        shift: f64,
        dist: f64,
        index: usize,
    ) -> Option<(Point, Frame, PointInfo)> {
        let clock = Instant::now();
        let frame = self.frame(p.omega + shift).ok()?;
        let open = vec![0.0; p.x.len()];
        let o = super::reduced::newton(&frame.problem, &self.newton, &open, self.reporter);
        if !o.converged || norm(&o.multipliers) > self.hb.tolerance * self.force {
            return None;
        }
        // Along the open branch λ stays 0: the direction is ω alone.
        let mut tangent = vec![0.0; p.x.len()];
        tangent.push(shift.signum());
        let point = Point {
            gaps: frame.problem.gap(&o.multipliers),
            x: o.multipliers,
            omega: frame.omega,
            tangent: tangent.clone(),
        };
        let (mut point, frame) = self.verified(p, point, frame).ok()?;
        point.tangent = tangent;
        let info = PointInfo {
            index,
            omega: point.omega,
            corrector: Corrector::Grazing,
            newton_iterations: o.iterations,
            factorizations: self.factorizations,
            step: dist,
            tangent_omega: point.tangent_omega(),
            seconds: clock.elapsed().as_secs_f64(),
            state: None,
            scaled: Vec::new(),
        };
        Some((point, frame, info))
    }

    /// Seconds spent in `prepare` so far (factorizations, linear solves, reductions).
    fn prepare_seconds(&self) -> f64 {
        self.timings.factor + self.timings.linear_solve + self.timings.reduce
    }

    /// The corrector from the predictor (x_p, ω_p): at fixed ω where the curve is a graph over
    /// ω or the step is `landing` on the end frequency (and converges there), else along the
    /// arc-length condition; at a `corner` (a step of a few smallest steps, away from a grazing
    /// corner) the one that failed hands over to the other.
    fn correct(
        &mut self,
        x_p: &[f64],
        omega_p: f64,
        t: &[f64],
        ds: f64,
        (landing, corner): (bool, bool),
    ) -> std::result::Result<(Vec<f64>, Frame, Corrector, usize), String> {
        // The last point lands on the end frequency itself where the curve crosses it.
        if landing && t[x_p.len()].abs() < GRAPH_SLOPE {
            let frame = self.frame(omega_p).map_err(|e| e.to_string())?;
            let o = super::reduced::newton(&frame.problem, &self.newton, x_p, self.reporter);
            if o.converged {
                return Ok((
                    o.multipliers,
                    frame,
                    Corrector::FixedFrequency,
                    o.iterations,
                ));
            }
        }
        if t[x_p.len()].abs() >= GRAPH_SLOPE {
            let frame = self.frame(omega_p).map_err(|e| e.to_string())?;
            let mut o = super::reduced::newton(&frame.problem, &self.newton, x_p, self.reporter);
            // Where the exact law's Newton cycles (where contact starts on a lightly damped
            // resonance, from the open state): the smoothing continuation, on the same
            // factorizations. It costs tens of Newton iterations, so steps longer than the
            // initial one are halved first, which is cheaper wherever it works.
            if !o.converged && ds < self.s.step {
                let hb = HbSettings {
                    samples: self.newton.samples,
                    ..self.hb.clone()
                };
                let c = self.newton.c;
                o = globalize::smoothed_from(&frame.problem, &hb, c, x_p, self.reporter);
            }
            if !o.converged && corner {
                // A corner: the arc-length corrector, which may pass where ω cannot be held.
                let reason = format!("fixed-ω corrector: {}", o.reason);
                let (x, frame, it) = self
                    .arclength(x_p, omega_p, t, ds)
                    .map_err(|e| format!("{reason}; then {e}"))?;
                return Ok((x, frame, Corrector::Arclength, it));
            }
            if !o.converged {
                return Err(format!("fixed-ω corrector: {}", o.reason));
            }
            let iterations = o.iterations;
            Ok((o.multipliers, frame, Corrector::FixedFrequency, iterations))
        } else {
            match self.arclength(x_p, omega_p, t, ds) {
                Ok((x, frame, it)) => Ok((x, frame, Corrector::Arclength, it)),
                // Where the curve has a corner steps do not shrink past, the fixed-ω smoothed
                // corrector from the predictor.
                Err(e) if corner => {
                    let frame = self.frame(omega_p).map_err(|e| e.to_string())?;
                    let hb = HbSettings {
                        samples: self.newton.samples,
                        ..self.hb.clone()
                    };
                    let c = self.newton.c;
                    let o = globalize::smoothed_from(&frame.problem, &hb, c, x_p, self.reporter);
                    if !o.converged {
                        return Err(e);
                    }
                    Ok((
                        o.multipliers,
                        frame,
                        Corrector::FixedFrequency,
                        o.iterations,
                    ))
                }
                Err(e) => Err(e),
            }
        }
    }

    /// The arc-length corrector: the chord corrector first (two sets of factorizations), the
    /// exact one (a set per iterate) where it fails.
    fn arclength(
        &mut self,
        x_p: &[f64],
        omega_p: f64,
        t: &[f64],
        ds: f64,
    ) -> std::result::Result<(Vec<f64>, Frame, usize), String> {
        match self.chord_arclength(x_p, omega_p, t, ds) {
            Ok(found) => Ok(found),
            Err(_) => self.exact_arclength(x_p, omega_p, t),
        }
    }

    /// Bordered Newton in (λ, ω) on a model of the problem frozen at the predictor ω_p:
    /// g(λ, ω) ≈ G(ω_p) λ + r(ω_p) + (ω − ω_p) ∂g/∂ω(λ, ω_p), ∂g/∂ω by two solves per harmonic
    /// with the kept factorizations (no refactoring while it iterates). Its solution (λ*, ω*)
    /// is off the curve by O((ω* − ω_p)²), small where this corrector runs (near folds, where
    /// the curve moves little in ω); one set of factorizations at ω* and a fixed-ω Newton from
    /// λ* put it on the curve. A Newton that moves λ by more than `CHORD_POLISH` of the step
    /// `ds` found another state (near a grazing corner the open one lies close by), not the
    /// model's: the exact corrector decides then.
    fn chord_arclength(
        &mut self,
        x_p: &[f64],
        omega_p: f64,
        t: &[f64],
        ds: f64,
    ) -> std::result::Result<(Vec<f64>, Frame, usize), String> {
        let base = self.frame(omega_p).map_err(|e| e.to_string())?;
        let mut model = base.problem.clone();
        let (mut x, mut omega) = (x_p.to_vec(), omega_p);
        let mut iterations = 0;
        loop {
            let dg = gap_rate(self.system, self.op, &base.linear, &x, self.hb.harmonics);
            let shift = omega - omega_p;
            for ((m, r), d) in model
                .linear_gap
                .iter_mut()
                .zip(&base.problem.linear_gap)
                .zip(&dg)
            {
                *m = r + shift * d;
            }
            let residual = Residual::new(&model, &self.newton);
            let e = residual.evaluate(x.clone());
            if residual.relative(&e) <= self.newton.tolerance && iterations > 0 {
                break;
            }
            if iterations == MAX_CORRECTOR {
                return Err("the chord corrector did not converge".into());
            }
            iterations += 1;
            let (jac, r_omega) = self.linearization(&model, &residual, &e, &dg);
            (x, omega) =
                self.bordered_update(&jac, &r_omega, t, &e.residual, (x, omega), (x_p, omega_p))?;
        }
        let frame = self.frame(omega).map_err(|e| e.to_string())?;
        let o = super::reduced::newton(&frame.problem, &self.newton, &x, self.reporter);
        if !o.converged {
            return Err(format!("chord corrector, polish at ω*: {}", o.reason));
        }
        let moved = norm(
            &o.multipliers
                .iter()
                .zip(&x)
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>(),
        );
        if moved > CHORD_POLISH * ds * self.force {
            return Err(format!(
                "chord corrector: the polish moved {:.2e} steps",
                moved / (ds * self.force)
            ));
        }
        Ok((o.multipliers, frame, iterations + o.iterations))
    }

    /// Bordered Newton in (λ, ω) from the predictor, Z_k refactored at every iterate.
    fn exact_arclength(
        &mut self,
        x_p: &[f64],
        omega_p: f64,
        t: &[f64],
    ) -> std::result::Result<(Vec<f64>, Frame, usize), String> {
        let (mut x, mut omega) = (x_p.to_vec(), omega_p);
        for iteration in 0..=MAX_CORRECTOR {
            let frame = self.frame(omega).map_err(|e| e.to_string())?;
            let residual = Residual::new(&frame.problem, &self.newton);
            let e = residual.evaluate(x.clone());
            if residual.relative(&e) <= self.newton.tolerance && iteration > 0 {
                return Ok((x, frame, iteration));
            }
            let dg = gap_rate(self.system, self.op, &frame.linear, &e.x, self.hb.harmonics);
            let (jac, r_omega) = self.linearization(&frame.problem, &residual, &e, &dg);
            (x, omega) =
                self.bordered_update(&jac, &r_omega, t, &e.residual, (x, omega), (x_p, omega_p))?;
        }
        Err(format!(
            "the arc-length corrector did not converge in {MAX_CORRECTOR} iterations"
        ))
    }

    /// One bordered Newton step on R = 0 and τᵀ(y − y_p) = 0 from (x, ω).
    fn bordered_update(
        &self,
        jac: &Mat<f64>,
        r_omega: &[f64],
        t: &[f64],
        residual: &[f64],
        (mut x, mut omega): (Vec<f64>, f64),
        (x_p, omega_p): (&[f64], f64),
    ) -> std::result::Result<(Vec<f64>, f64), String> {
        let n = x.len();
        let constraint: f64 = (0..n)
            .map(|i| t[i] * (x[i] - x_p[i]) / self.force)
            .sum::<f64>()
            + t[n] * (omega - omega_p) / self.span;
        let rhs: Vec<f64> = residual.iter().copied().chain([constraint]).collect();
        let d = self
            .bordered_solve(jac, r_omega, t, &rhs)
            .ok_or("the bordered corrector matrix is singular")?;
        for i in 0..n {
            x[i] -= d[i] * self.force;
        }
        omega -= d[n] * self.span;
        if !(omega > 0.0) {
            return Err("the corrector left ω > 0".into());
        }
        Ok((x, omega))
    }

    /// J and R_ω = A c ∂g/∂ω at the evaluation `e` of `problem` (A the activity blocks).
    fn linearization(
        &self,
        problem: &ReducedProblem,
        residual: &Residual,
        e: &super::reduced::Evaluation,
        dg: &[f64],
    ) -> (Mat<f64>, Vec<f64>) {
        let m = problem.coefficients();
        let blocks = step::activity_blocks(&residual.sampler, problem.nodes, &e.slopes);
        let jac = step::dense_jacobian(problem, self.newton.c, &blocks);
        let mut r_omega = vec![0.0; dg.len()];
        for i in 0..problem.nodes {
            let a_i = &blocks[i * m * m..(i + 1) * m * m];
            for a in 0..m {
                r_omega[i * m + a] = (0..m)
                    .map(|b| a_i[a * m + b] * self.newton.c * dg[i * m + b])
                    .sum();
            }
        }
        (jac, r_omega)
    }

    /// Solve [J F, R_ω Ω; τᵀ] d = rhs in the scaled unknowns.
    fn bordered_solve(
        &self,
        jac: &Mat<f64>,
        r_omega: &[f64],
        t: &[f64],
        rhs: &[f64],
    ) -> Option<Vec<f64>> {
        let n = r_omega.len();
        let a = Mat::<f64>::from_fn(n + 1, n + 1, |i, j| match (i < n, j < n) {
            (true, true) => jac[(i, j)] * self.force,
            (true, false) => r_omega[i] * self.span,
            (false, _) => t[j],
        });
        let b = Mat::<f64>::from_fn(n + 1, 1, |i, _| rhs[i]);
        let d = crate::linalg::dense_solve(a, b);
        let out: Vec<f64> = (0..=n).map(|i| d[(i, 0)]).collect();
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// The unit tangent at the first point, oriented along `previous`.
    fn tangent(&self, frame: &Frame, x: &[f64], previous: &[f64]) -> Result<Vec<f64>> {
        let residual = Residual::new(&frame.problem, &self.newton);
        let e = residual.evaluate(x.to_vec());
        let dg = gap_rate(self.system, self.op, &frame.linear, x, self.hb.harmonics);
        let (jac, r_omega) = self.linearization(&frame.problem, &residual, &e, &dg);
        let n = x.len();
        let rhs: Vec<f64> = (0..n).map(|_| 0.0).chain([1.0]).collect();
        let t = self
            .bordered_solve(&jac, &r_omega, previous, &rhs)
            .ok_or_else(|| {
                Error::NotConverged(format!(
                    "at {:.6} Hz the continuation's tangent is undefined (a singular bordered \
                     matrix: a branch point); start the sweep slightly off this frequency",
                    hz(frame.omega)
                ))
            })?;
        let norm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
        let sign = if t.iter().zip(previous).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        Ok(t.iter().map(|v| sign * v / norm).collect())
    }

    /// Recover the point's whole field and hand it to the callback.
    fn emit(
        &mut self,
        info: &PointInfo,
        x: &[f64],
        frame: Frame,
        newton: NewtonOutcome,
        on_point: &mut OnPoint,
    ) -> Result<()> {
        let problem = &frame.problem;
        let newton = NewtonOutcome {
            multipliers: x.to_vec(),
            ..newton
        };
        let contact =
            ContactSolution::unchecked(problem, self.newton.samples, self.newton.c, newton);
        let m = problem.coefficients();
        let mut linear = frame.linear;
        super::timed(&mut self.timings.recover, || linear.recover(self.op, x, m));
        self.system.omega = frame.omega;
        let solution = linear.into_solution(self.system, Some(contact), Timings::default());
        on_point(info, &solution)
    }
}

/// Whether a sweep of `system` with `nodes` contact nodes at H = `harmonics` builds a reduced
/// model of its frames with shifts at `frequencies` frequencies (0: none asked): where its
/// start block times the shifts stays below half the free dofs.
pub fn reduced_model_pays(
    system: &System,
    nodes: usize,
    harmonics: usize,
    frequencies: usize,
) -> bool {
    let n = system.free_count();
    let columns = nodes + 2 * system.inputs.len().max(1);
    let shifts = 1 + frequencies * harmonics;
    frequencies > 0 && columns * shifts <= n / 2
}

/// The saved point checked on its frame by Newton from its own multipliers, which solve it
/// (no iteration, the multipliers unchanged, on the frame they were solved on). One that does
/// not solve again belongs to another scene, or was edited: bad input.
fn resolve_saved(
    frame: &Frame,
    newton: &NewtonSettings,
    r: &ContinuationState,
    reporter: &dyn Reporter,
) -> Result<NewtonOutcome> {
    let o = super::reduced::newton(&frame.problem, newton, &r.multipliers, reporter);
    if !o.converged || o.multipliers.len() != r.multipliers.len() {
        return Err(Error::Input(format!(
            "the saved point (sweep.json's `resume`) at {:.6} Hz does not solve again ({}): resume needs the scene the \
             sweep was started with; sweep again without --resume",
            hz(frame.omega),
            o.reason
        )));
    }
    Ok(o)
}

fn info_stub() -> PointInfo {
    PointInfo {
        index: 0,
        omega: 0.0,
        corrector: Corrector::Cold,
        newton_iterations: 0,
        factorizations: 0,
        step: 0.0,
        tangent_omega: 0.0,
        seconds: 0.0,
        state: None,
        scaled: Vec::new(),
    }
}

fn hz(omega: f64) -> f64 {
    omega / (2.0 * std::f64::consts::PI)
}

/// Two turning points closer than this fraction of the span in ω, a few points apart, are a
/// kink of the sampled contact law (a sample switching), not a fold of the curve.
pub const KINK: f64 = 1e-3;

/// Drop pairs of consecutive folds within `width` in ω and 3 points of each other.
pub fn without_kinks(folds: Vec<Fold>, width: f64) -> Vec<Fold> {
    let mut out: Vec<Fold> = Vec::new();
    for f in folds {
        match out.last() {
            Some(l) if f.after - l.after <= 3 && (f.omega - l.omega).abs() < width => {
                out.pop();
            }
            _ => out.push(f),
        }
    }
    out
}

/// The fold at point `at`, where ω turns back (the secants before and after it disagree in
/// the sign of their ω-component).
fn fold(at: usize, a: &Point) -> Fold {
    Fold {
        after: at,
        omega: a.omega,
    }
}

/// The points of the curve so far, in the scaled unknowns, to notice a continuation that runs
/// back along its own path (turned round at a kink of the sampled law) or circles.
#[derive(Default)]
struct Trail {
    points: Vec<Vec<f64>>,
}

impl Trail {
    fn push(&mut self, y: Vec<f64>) {
        self.points.push(y);
    }

    /// The index of an earlier segment (all but the last `RECENT`) that `y`, reached by a
    /// step `ds`, lies on within `RETRACE` × ds.
    fn retraced(&self, y: &[f64], ds: f64) -> Option<usize> {
        let older = self.points.len().checked_sub(RECENT)?;
        (1..older)
            .find(|&j| segment_distance(&self.points[j - 1], &self.points[j], y) < RETRACE * ds)
    }
}

/// Distance of `q` from the segment a–b.
fn segment_distance(a: &[f64], b: &[f64], q: &[f64]) -> f64 {
    let ab: f64 = a.iter().zip(b).map(|(a, b)| (b - a).powi(2)).sum();
    let along: f64 = a
        .iter()
        .zip(b)
        .zip(q)
        .map(|((a, b), q)| (q - a) * (b - a))
        .sum();
    let t = if ab > 0.0 {
        (along / ab).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d2: f64 = a
        .iter()
        .zip(b)
        .zip(q)
        .map(|((a, b), q)| (q - a - t * (b - a)).powi(2))
        .sum();
    d2.sqrt()
}

/// Why a sweep that runs back along its own path stops.
fn retrace_reason(p: &Point, index: usize, j: usize, refine_key: &str) -> String {
    format!(
        "at {:.6} Hz (point {index}) the continuation ran back onto the curve it had traced \
         (between points {} and {j}), so it would retrace the curve instead of following it: \
         a sharp kink of the sampled contact law turned it round, or the curve closes on \
         itself. Raise {refine_key} or the damping, lower sweep.max_step, or sweep a \
         narrower range",
        hz(p.omega),
        j - 1
    )
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Steps up to this many smallest steps that one corrector fails (at a corner of the curve,
/// not a grazing one) try the other: the fixed-ω smoothed corrector after the arc-length one,
/// and back.
const CORNER_STEPS: f64 = 4.0;

/// The gap change of a step is measured against at least this share of the contact-free
/// gap ‖g̃_lin‖ = F/c of the first point (the scaling).
const GAP_FLOOR: f64 = 1e-3;

/// ‖b − a‖ / max(‖a‖, ‖b‖, floor).
fn relative_change(a: &[f64], b: &[f64], floor: f64) -> f64 {
    let diff = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
    let norm = a
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .max(b.iter().map(|x| x * x).sum())
        .max(floor * floor);
    if norm > 0.0 {
        (diff / norm).sqrt()
    } else {
        0.0
    }
}

/// ∂g/∂ω at fixed λ (node-major coefficients), by two solves per harmonic.
fn gap_rate(
    system: &System,
    op: &ContactOperator,
    linear: &LinearResponse,
    x: &[f64],
    harmonics: usize,
) -> Vec<f64> {
    let (nc, m) = (op.nodes(), 2 * harmonics + 1);
    let mut dg = vec![0.0; nc * m];
    for (&k, lu) in &linear.factors {
        let lam = node_phasors(x, m, k);
        if let crate::linalg::Factor::Modal(f) = lu {
            // On the reduced space: no product with K or M.
            let load_rate = system.motion_rate(k, &linear.motion[&k]);
            let bdz = f.contact_rate(&lam, system.pencil_rate(k), load_rate.as_deref());
            for (i, v) in bdz.into_iter().enumerate() {
                set_phasor(&mut dg[i * m..(i + 1) * m], k, v);
            }
            continue;
        }
        let mut z = linear.free[&k].clone();
        if let Some((_, dz)) = super::contact_part(op, lu, &lam) {
            for (a, b) in z.iter_mut().zip(dz) {
                *a += b;
            }
        }
        let rate = system.omega_derivative(k, &z, &linear.motion[&k]);
        let dz = lu.solve(&rate);
        let bdz = op.b_free.mul_complex(&dz);
        for (i, v) in bdz.into_iter().enumerate() {
            set_phasor(&mut dg[i * m..(i + 1) * m], k, -v);
        }
    }
    dg
}

/// Without contact the curve is the linear response, a graph over ω: steps in ω shrink where
/// the response changes fast (near a resonance) and grow where it does not.
fn linear_sweep(
    system: &mut System,
    hb: &HbSettings,
    s: &SweepSettings,
    reporter: &dyn Reporter,
    on_point: &mut OnPoint,
) -> Result<SweepOutcome> {
    let span = (s.omega_end - s.omega_start).abs();
    let direction = (s.omega_end - s.omega_start).signum();
    let mut outcome = SweepOutcome::default();
    let solve_at = |system: &mut System, omega: f64, timings: &mut Timings| {
        system.omega = omega;
        let (linear, _) = prepare(system, None, hb, reporter, timings)?;
        Ok::<_, Error>(linear.into_solution(system, None, Timings::default()))
    };
    let clock = Instant::now();
    let (start, mut omega, mut ds) = s
        .resume
        .as_ref()
        .map_or((0, s.omega_start, s.step), |r| (r.index, r.omega, r.step));
    let state = |index: usize, omega: f64, ds: f64| ContinuationState {
        index,
        omega,
        step: ds,
        tangent: vec![direction],
        multipliers: Vec::new(),
        force_scale: 0.0,
        c: 0.0,
        samples: 0,
        largest: 0.0,
        reduced_frame: false,
        enriched_at: Vec::new(),
        harmonic_first: false,
        trail: Vec::new(),
    };
    let mut current = solve_at(system, omega, &mut outcome.timings)?;
    let mut info = PointInfo {
        index: start,
        omega,
        corrector: Corrector::Linear,
        factorizations: 1,
        tangent_omega: direction,
        seconds: clock.elapsed().as_secs_f64(),
        state: Some(state(start, omega, ds)),
        ..info_stub()
    };
    on_point(&info, &current)?;
    let mut index = start + 1;
    while index < s.max_points && (omega - s.omega_end) * direction < 0.0 {
        let clock = Instant::now();
        let mut tries = 0;
        let next = loop {
            let w = if ((omega + direction * ds * span) - s.omega_end) * direction > 0.0 {
                s.omega_end
            } else {
                omega + direction * ds * span
            };
            tries += 1;
            let candidate = solve_at(system, w, &mut outcome.timings)?;
            let change = response_change(&current, &candidate);
            if change <= s.max_change || ds * 0.5 < s.min_step {
                if change < 0.3 * s.max_change {
                    ds = (1.5 * ds).min(s.max_step);
                }
                break (w, candidate);
            }
            ds *= 0.5;
        };
        (omega, current) = next;
        info = PointInfo {
            index,
            omega,
            factorizations: tries,
            step: ds,
            seconds: clock.elapsed().as_secs_f64(),
            state: Some(state(index, omega, ds)),
            ..info
        };
        on_point(&info, &current)?;
        reporter.progress("sweep", index as u64, None, &format!("{:.3} Hz", hz(omega)));
        index += 1;
    }
    reporter.task_done("sweep");
    outcome.points = index;
    Ok(outcome)
}

/// Relative change of the free dofs' harmonic amplitudes between two linear solutions.
fn response_change(a: &Solution, b: &Solution) -> f64 {
    let flat = |s: &Solution| -> Vec<f64> {
        s.free
            .values()
            .flat_map(|z| z.iter().flat_map(|v| [v.re, v.im]))
            .collect()
    };
    relative_change(&flat(a), &flat(b), 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trail out along the first axis to x = 6, in unit steps.
    fn trail_out() -> Trail {
        let mut trail = Trail::default();
        for i in 0..=6 {
            trail.push(vec![i as f64, 0.0]);
        }
        trail
    }

    /// TEST GOAL: a point landing on an earlier segment of the curve (a continuation walking
    /// back along it) is found, with that segment's index; a point off the curve, or on one of
    /// the last `RECENT` segments (a kink's back-and-forth), is not.
    #[test]
    fn trail_finds_a_point_back_on_an_earlier_segment_only() {
        let trail = trail_out();
        assert_eq!(trail.retraced(&[1.5, 0.01], 1.0), Some(2));
        assert_eq!(trail.retraced(&[1.5, 0.2], 1.0), None, "off the curve");
        assert_eq!(trail.retraced(&[5.5, 0.0], 1.0), None, "a recent segment");
        assert_eq!(Trail::default().retraced(&[0.0, 0.0], 1.0), None);
    }

    /// TEST GOAL: the distance from a segment is the perpendicular one inside it and the
    /// distance to the nearer end outside.
    #[test]
    fn segment_distance_is_perpendicular_inside_and_to_the_end_outside() {
        let (a, b) = ([0.0, 0.0], [2.0, 0.0]);
        assert!((segment_distance(&a, &b, &[1.0, 0.5]) - 0.5).abs() < 1e-15);
        assert!((segment_distance(&a, &b, &[3.0, 0.0]) - 1.0).abs() < 1e-15);
        assert!((segment_distance(&a, &b, &[-3.0, 4.0]) - 5.0).abs() < 1e-15);
    }
}
