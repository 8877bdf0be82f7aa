//! The predictor and the step control of the continuation.
//!
//! Glossary (y, F, Ω, τ as in the module `continuation`): Δs the arc-length step in the
//! scaled unknowns y, y_p = y + Δs τ the predictor, g̃ the contact gaps' coefficients.
//!
//! Step control: a corrector that fails, needs more than `MAX_CORRECTOR` iterations, lands
//! farther than `JUMP` Δs from the predictor (a jump to another branch), turns the curve by
//! more than `max_turn` from the last direction (when the sweep sets one: a kink of the
//! sampled law crossed onto another sheet of its solutions; not within `CORNER_STEPS`
//! smallest steps, where a kink turns the curve for real) or changes the contact gaps by more
//! than `max_change` (relative: ‖Δg̃‖/max(‖g̃_a‖, ‖g̃_b‖, `GAP_FLOOR`·‖g̃_lin‖), g̃_lin the
//! first point's contact-free gap, so a contact closed all period, whose gaps are round-off,
//! is not measured against its round-off) rejects the step and halves Δs; an easy step
//! (≤ 3 iterations) grows it by 1.5, up to the maximum.

use std::time::Instant;

use super::frame::Frame;
use super::grazing::GRAZING;
use super::{hz, Continuation, Corrector, Point, PointInfo};
use crate::linalg::{dot, norm2};

/// A corrector that lands farther than this many steps from its predictor jumped to another
/// branch (a kink of the sampled law bends the curve by less).
pub(super) const JUMP: f64 = 3.0;

/// A corrector landing farther than `JUMP` steps is still accepted, as a corner of the curve
/// where a branch leaves at an angle (contact starting on a steep resonance), when halving the
/// step shrank its distance below `CORNER_SHRINK` of the last and it is within `CORNER` steps.
const CORNER_SHRINK: f64 = 0.6;
const CORNER: f64 = 30.0;

/// Steps up to this many smallest steps that one corrector fails (at a corner of the curve,
/// not a grazing one) try the other: the fixed-ω smoothed corrector after the arc-length one,
/// and back.
const CORNER_STEPS: f64 = 4.0;

/// The gap change of a step is measured against at least this share of the contact-free
/// gap ‖g̃_lin‖ = F/c of the first point (the scaling).
const GAP_FLOOR: f64 = 1e-3;

impl Continuation<'_> {
    /// The point after `p`: steps from `ds`, halved on every failure down to the smallest
    /// step, grown after an easy one; `Err` says why the curve cannot go on.
    pub(super) fn next_point(
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
                        harmonics_estimate: None,
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
                    let corner = self.graze(p, index);
                    if let Some(found) = corner.or_else(|| self.leave_open(p, index)) {
                        // Past the corner the curve is a new smooth branch.
                        *ds = self.s.step;
                        return Ok(found);
                    }
                    return Err(format!(
                        "at {:.6} Hz the continuation found no next point down to the \
                         smallest step {:.1e} ({why}); sweep again with a smaller \
                         sweep.max_change (now {}: the steps before may have left the curve \
                         at a fold), lower sweep.min_step, raise {} or add damping",
                        hz(p.omega),
                        self.s.min_step,
                        self.s.max_change,
                        self.system.basis.refine_key()
                    ));
                }
            }
        }
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
        let corner = ds <= CORNER_STEPS * self.s.min_step && norm2(&p.x) > GRAZING * self.largest;
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
        self.turn_within_limit(p, &point, ds)?;
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
    pub(super) fn after(
        &self,
        p: &Point,
        x: Vec<f64>,
        frame: &Frame,
    ) -> std::result::Result<Point, String> {
        let mut secant: Vec<f64> = (0..x.len())
            .map(|i| (x[i] - p.x[i]) / self.force)
            .chain([(frame.omega - p.omega) / self.span])
            .collect();
        let length = norm2(&secant);
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

    /// `Err` where the step to `next` turned the curve by more than `max_turn` from `p`'s
    /// direction, unless the step is one of the `CORNER_STEPS` smallest.
    fn turn_within_limit(
        &self,
        p: &Point,
        next: &Point,
        ds: f64,
    ) -> std::result::Result<(), String> {
        let Some(limit) = self.s.max_turn else {
            return Ok(());
        };
        let cos = dot(&next.tangent, &p.tangent);
        if cos >= limit.to_radians().cos() || ds <= CORNER_STEPS * self.s.min_step {
            return Ok(());
        }
        let degrees = cos.clamp(-1.0, 1.0).acos().to_degrees();
        Err(format!(
            "the curve turned by {degrees:.0}° in one step (sweep.max_turn {limit}°)"
        ))
    }

    /// Seconds spent in `prepare` so far (factorizations, linear solves, reductions).
    fn prepare_seconds(&self) -> f64 {
        self.timings.factor + self.timings.linear_solve + self.timings.reduce
    }
}

/// ‖b − a‖ / max(‖a‖, ‖b‖, floor).
pub(super) fn relative_change(a: &[f64], b: &[f64], floor: f64) -> f64 {
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
