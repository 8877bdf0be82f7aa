//! Frequency-response curves: pseudo-arclength continuation of the contact solution in
//! (λ, ω), which passes the folds contact bends a resonance into (docs/method.md, "Sweeps").
//!
//! Glossary and formulas:
//! - R(λ, ω) = 0 the complementarity residual (23) at ω, J = ∂R/∂λ its Newton matrix;
//! - y = (λ/F, ω/Ω) the scaled unknowns: F a force scale (c × the 2-norm of the first point's
//!   linear-gap coefficients, so ‖λ/F‖ is of order one), Ω the sweep's span |ω_end − ω_start|;
//!   s the arc length in y;
//! - direction τ: at the first point the tangent, [J F, R_ω Ω; (0, ±1)ᵀ] τ = [0; 1]
//!   normalised; after that the secant from the previous point, normalised. The contact law
//!   makes R only piecewise smooth in λ (samples switch between open and closed), so J-based
//!   tangents flip at kinks; the secant follows the curve through them;
//! - predictor y_p = y + Δs τ, then a corrector on R = 0 and τᵀ(y − y_p) = 0 (`corrector`);
//! - folds: sign changes of the secants' ω-components, at the point where ω turns back; a
//!   back-and-forth within `KINK` of the span over a few points is a kink of
//!   the sampled law (one sample switching), not reported.
//!
//! The parts: `start` (the first point, cold or resumed), `frame` (everything at one ω, from
//! factorizations or the reduced model), `stepping` (predictor and step control),
//! `corrector` (fixed-ω and arc-length correctors, R_ω), `grazing` (the corner where a
//! contacting branch ends on the open one), `trail` (a curve running back onto itself) and
//! `linear` (the contact-free sweep). This file holds the public types, `sweep` and the loop
//! over the points (`Continuation::run`).

mod corrector;
mod frame;
mod grazing;
mod law;
mod levels;
mod linear;
mod sliver;
mod start;
mod stepping;
mod trail;

use std::time::Instant;

use super::frames::ReducedModel;
use super::reduced::NewtonSettings;
use super::{ContactSolution, HbSettings, ReducedProblem, Solution, System};
use super::{NewtonOutcome, Timings};
use crate::contact::ContactOperator;
use crate::hbm::adaptive::HarmonicRange;
use crate::linalg::norm2;
use crate::progress::Reporter;
use crate::{Error, Result};
pub use frame::reduced_model_pays;
use frame::Frame;
use trail::{retrace_reason, Trail};

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
    /// Largest turn of the curve in one step [degrees] (`stepping`); `None`: no limit.
    pub max_turn: Option<f64>,
    /// Continue a sweep from its last saved point instead of starting at `omega_start`.
    pub resume: Option<ContinuationState>,
    /// Frequencies over the range at which the reduced model places its shifts
    /// (`frames::SHIFTS_PER_HARMONIC` by default; 0: no model, every frame factored).
    pub model_frequencies: usize,
    /// H chosen per point within this range (`levels`; frictionless contact on the Fourier
    /// basis); `None`: H fixed at the settings' `harmonics`.
    pub harmonics: Option<HarmonicRange>,
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
    /// trail a retrace is checked against (empty without contact). `hbm::continuation` leaves it
    /// empty in each point's state (`PointInfo::scaled` gives the points one by one); the
    /// caller fills it where it saves the state.
    pub trail: Vec<Vec<f64>>,
    /// The largest turn per step the curve is swept with [degrees] (`SweepSettings::max_turn`;
    /// a sweep swept again with a limit resumes with it).
    #[serde(default)]
    pub max_turn: Option<f64>,
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
    /// The first contacting state back in ω from the corner where the open branch ends (the
    /// linear response reaches the obstacle) and a contacting branch leaves it.
    OpenCorner,
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
    /// With H chosen per point: the point's truncation estimate (`levels`).
    pub harmonics_estimate: Option<f64>,
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
    /// With H chosen per point: how many times the curve moved to another H.
    pub level_changes: usize,
    /// Times the curve ran back along a sliver of the sampled law and was led round it
    /// (`sliver`).
    pub slivers: usize,
    /// The level change a segment of such a curve ended on (`levels`).
    level_change: Option<levels::LevelChange>,
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
    let fourier = matches!(system.basis, super::basis::TimeBasis::Fourier);
    match contact {
        // With friction the curve's unknowns are the stacked rows' (`ContactOperator::stacked`).
        Some(op) => match (op.stacked(), s.harmonics) {
            (Some(rows), _) => {
                Continuation::start(system, (op, &rows), hb, s, reporter, None)?.run(on_point)
            }
            (None, Some(range)) if fourier && range.max > range.min => {
                levels::sweep_levels(system, op, hb, s, range, reporter, on_point)
            }
            (None, _) => {
                Continuation::start(system, (op, op), hb, s, reporter, None)?.run(on_point)
            }
        },
        None => linear::linear_sweep(system, hb, s, reporter, on_point),
    }
}

/// The first point of a continuation, its index and the step the next is tried with; or the
/// level change it asks for and its index (`levels`).
type First = std::result::Result<(Point, usize, f64), (levels::LevelChange, usize)>;

/// A converged point: its multipliers, ω, unit tangent and contact gaps.
#[derive(Clone)]
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
    /// The scene's contact operator, and the one the problem is reduced to (with friction its
    /// normal rows followed by its tangential ones; else the same).
    contact: &'a ContactOperator,
    op: &'a ContactOperator,
    /// μ per contact node with friction (`law`).
    friction: Option<Vec<f64>>,
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
    /// H chosen per point (`levels`); `None`: H fixed.
    levels: Option<levels::Levels>,
    /// The first point is a level change's restart (checked for a raise again).
    restarted: bool,
}

impl Continuation<'_> {
    /// Follow the curve point by point from the first, handing each to `on_point`, until it
    /// passes the end frequency, `max_points` are reached or it cannot go on (`stopped`).
    fn run(mut self, on_point: &mut OnPoint) -> Result<SweepOutcome> {
        let mut trail = Trail::default();
        let mut outcome = SweepOutcome::default();
        let (mut point, start, mut ds) = match self.first_point(&mut trail, on_point)? {
            Ok(first) => first,
            Err((change, start)) => {
                outcome.level_change = Some(change);
                return Ok(self.finish(outcome, start));
            }
        };
        let mut index = start + 1;
        let mut recent = sliver::Recent::new(trail.points().len() - 1, &point);
        while index < self.s.max_points {
            if self.beyond_end(&point) {
                break;
            }
            if self.before_start(&point) {
                outcome.stopped = Some(self.left_through_start(&point, index - 1));
                break;
            }
            let (mut next, mut frame, mut info) = match self.next_point(&point, &mut ds, index) {
                Ok(found) => found,
                Err(stopped) => {
                    outcome.stopped = Some(stopped);
                    break;
                }
            };
            let mut y = self.scaled(&next);
            if let Some(j) = trail.retraced(&y, info.step) {
                let Some(around) = self.around_sliver(&mut recent, &mut trail, j, index) else {
                    let key = self.system.basis.refine_key();
                    let samples = self.newton.samples;
                    let why = retrace_reason(&point, (index - 1, j), key, samples);
                    outcome.stopped = Some(why);
                    break;
                };
                (point, next, frame, info, ds) = around;
                y = self.scaled(&next);
                outcome.slivers += 1;
            }
            if let Some(change) = self.level_change((&next, &frame), (index, ds), &trail, true) {
                outcome.level_change = Some(change);
                break;
            }
            info.harmonics_estimate = self.levels.and_then(|l| l.last);
            trail.push(y.clone());
            recent.push(trail.points().len() - 1, &next, info.step);
            if index > 1 && point.tangent_omega() * next.tangent_omega() < 0.0 {
                outcome.folds.push(fold(index - 1, &point));
            }
            let newton = corrector_newton(info.newton_iterations);
            self.largest = self.largest.max(norm2(&next.x));
            info.state = Some(self.state(&next, ds, index, frame.reduced));
            info.scaled = y;
            self.emit(&info, &next.x, frame, newton, on_point)?;
            let status = format!("{:.3} Hz", hz(next.omega));
            self.reporter.progress("sweep", index as u64, None, &status);
            point = next;
            index += 1;
        }
        Ok(self.finish(outcome, index))
    }

    /// The first point (cold, or the resumed one, from `first`) with its direction (the
    /// saved one, or the tangent towards the end frequency), pushed on `trail` after the trail
    /// a resumed state brings, and handed to `on_point`; the point, its index and the step the
    /// next is tried with. With H chosen per point, a cold or restarted first point whose
    /// estimate asks for a higher H is not kept: the level change and its index instead.
    fn first_point(&mut self, trail: &mut Trail, on_point: &mut OnPoint) -> Result<First> {
        let clock = Instant::now();
        let (x, first_newton, frame) = self
            .first
            .take()
            .ok_or_else(|| Error::Model("internal: the sweep's first point was taken".into()))?;
        let (tangent, start, ds) = match &self.s.resume {
            Some(r) => (r.tangent.clone(), r.index, r.step),
            None => {
                let initial = [vec![0.0; x.len()], vec![self.direction]].concat();
                (self.tangent(&frame, &x, &initial)?, 0, self.s.step)
            }
        };
        let point = Point {
            gaps: frame.problem.gap(&x),
            x,
            omega: frame.omega,
            tangent,
        };
        // A resumed point brings the largest ‖λ‖ before it and its trail.
        self.largest = self.largest.max(norm2(&point.x));
        for y in self.s.resume.iter().flat_map(|r| &r.trail) {
            trail.push(y.clone());
        }
        if self.s.resume.is_none() || self.restarted {
            if let Some(change) = self.level_change((&point, &frame), (start, ds), trail, false) {
                return Ok(Err((change, start)));
            }
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
            harmonics_estimate: self.levels.and_then(|l| l.last),
        };
        self.build_model();
        self.emit(&info, &point.x, frame, first_newton, on_point)?;
        Ok(Ok((point, start, ds)))
    }

    /// The outcome of a sweep that ended after `points` points: its folds (kinks of the
    /// sampled law dropped), timings and the reduced model's account.
    fn finish(self, mut outcome: SweepOutcome, points: usize) -> SweepOutcome {
        self.reporter.task_done("sweep");
        outcome.points = points;
        outcome.folds = without_kinks(std::mem::take(&mut outcome.folds), KINK * self.span);
        outcome.timings = self.timings;
        outcome.reduced = ReducedFrames {
            dimension: self.model.as_ref().map_or(0, ReducedModel::dim),
            ..self.reduced
        };
        outcome
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
            max_turn: self.s.max_turn,
        }
    }

    /// Past the end frequency, moving away from it.
    fn beyond_end(&self, p: &Point) -> bool {
        let past = (p.omega - self.s.omega_end) * self.direction >= 0.0;
        past && p.tangent_omega() * self.direction > 0.0
    }

    /// Back before the start frequency, moving away from the range (`leaves_through_start`).
    fn before_start(&self, p: &Point) -> bool {
        let range = (self.s.omega_start, self.s.omega_end);
        leaves_through_start(p.omega, p.tangent_omega(), range)
    }

    /// Why a sweep whose curve left the range through its start (at `p`, point `index`) stops.
    fn left_through_start(&self, p: &Point, index: usize) -> String {
        let (start, end) = (hz(self.s.omega_start), hz(self.s.omega_end));
        format!(
            "at {:.6} Hz (point {index}) the curve ran out of the range back through its start \
             ({start:.4} Hz): the branch the first point lies on turns round before reaching \
             {end:.4} Hz, so the rest of the range was not swept. Start the sweep outside the \
             folded region, or sweep the other way (sweep.from = {end:.4}, sweep.to = \
             {start:.4})",
            hz(p.omega)
        )
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
        let contact = self.point_solution(problem, newton);
        let m = problem.coefficients();
        let mut linear = frame.linear;
        super::timed(&mut self.timings.recover, || linear.recover(self.op, x, m));
        self.system.omega = frame.omega;
        let solution = linear.into_solution(self.system, Some(contact), Timings::default());
        on_point(info, &solution)
    }
}

impl Continuation<'_> {
    /// The contact solution of a point whose Newton account `newton` holds its unknowns
    /// (the knob checks are the first point's); with friction, its tangential result too,
    /// its samples not checked again.
    fn point_solution(&self, problem: &ReducedProblem, newton: NewtonOutcome) -> ContactSolution {
        let (samples, c) = (self.newton.samples, self.newton.c);
        let Some(coefficients) = &self.friction else {
            return ContactSolution::unchecked(problem, samples, c, newton);
        };
        let x = newton.multipliers.clone();
        let part = super::friction::normal_part(problem);
        let normal = NewtonOutcome {
            multipliers: x[..part.linear_gap.len()].to_vec(),
            ..newton
        };
        let normal = ContactSolution::unchecked(&part, samples, c, normal);
        let counts = (f64::NAN, normal.newton.iterations);
        super::with_friction(normal, problem, coefficients.clone(), &x, counts)
    }
}

fn hz(omega: f64) -> f64 {
    omega / (2.0 * std::f64::consts::PI)
}

/// Two turning points closer than this fraction of the span in ω, a few points apart, are a
/// kink of the sampled contact law (a sample switching), not a fold of the curve.
pub const KINK: f64 = 1e-3;

/// A point at frequency `at` whose tangent has ω-component `tangent` lies before the start of
/// the sweep `range` (start, end) and moves away from it: the curve turned round and leaves
/// the range the way it came in, short of the end (any unit of frequency; a sweep stops
/// there, and a resume would leave the same way).
pub fn leaves_through_start(at: f64, tangent: f64, (start, end): (f64, f64)) -> bool {
    let direction = (end - start).signum();
    (at - start) * direction < 0.0 && tangent * direction < 0.0
}

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

/// The Newton account of a point the corrector reached in `iterations` (its multipliers are
/// the point's, given to `emit` apart).
fn corrector_newton(iterations: usize) -> NewtonOutcome {
    NewtonOutcome {
        multipliers: Vec::new(),
        converged: true,
        iterations,
        relative_residual: 0.0,
        log: Vec::new(),
        reason: String::new(),
    }
}

/// The fold at point `at`, where ω turns back (the secants before and after it disagree in
/// the sign of their ω-component).
fn fold(at: usize, a: &Point) -> Fold {
    Fold {
        after: at,
        omega: a.omega,
    }
}
