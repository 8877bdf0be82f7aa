//! The contact-free sweep: the curve is the linear response z_k(ω) = Z_k(ω)⁻¹ f_k, a graph
//! over ω, so it steps in ω alone.
//!
//! Glossary: Δs the step as a fraction of the span Ω = |ω_end − ω_start|, ω_next = ω +
//! sign(ω_end − ω_start) Δs Ω (clipped to ω_end); the change of a step is
//! ‖a − b‖ / max(‖a‖, ‖b‖) over the free dofs' harmonic amplitudes (re and im parts). A step
//! whose change exceeds `max_change` is halved (down to `min_step`); one below 0.3 ×
//! `max_change` grows the next by 1.5, up to `max_step`.

use std::time::Instant;

use super::stepping::relative_change;
use super::{hz, ContinuationState, Corrector, OnPoint, PointInfo, SweepOutcome, SweepSettings};
use crate::hbm::{prepare, HbSettings, Solution, System, Timings};
use crate::progress::Reporter;
use crate::Result;

/// Without contact the curve is the linear response, a graph over ω: steps in ω shrink where
/// the response changes fast (near a resonance) and grow where it does not.
pub(super) fn linear_sweep(
    system: &mut System,
    hb: &HbSettings,
    s: &SweepSettings,
    reporter: &dyn Reporter,
    on_point: &mut OnPoint,
) -> Result<SweepOutcome> {
    let sweep = LinearSweep {
        hb,
        s,
        reporter,
        span: (s.omega_end - s.omega_start).abs(),
        direction: (s.omega_end - s.omega_start).signum(),
    };
    let direction = sweep.direction;
    let mut outcome = SweepOutcome::default();
    let clock = Instant::now();
    let (start, mut omega, mut ds) = s
        .resume
        .as_ref()
        .map_or((0, s.omega_start, s.step), |r| (r.index, r.omega, r.step));
    let mut current = sweep.solve_at(system, omega, &mut outcome.timings)?;
    let mut info = PointInfo {
        index: start,
        omega,
        corrector: Corrector::Linear,
        factorizations: 1,
        tangent_omega: direction,
        seconds: clock.elapsed().as_secs_f64(),
        state: Some(sweep.state(start, omega, ds)),
        ..info_stub()
    };
    on_point(&info, &current)?;
    let mut index = start + 1;
    while index < s.max_points && (omega - s.omega_end) * direction < 0.0 {
        let clock = Instant::now();
        let tries;
        (omega, current, tries) =
            sweep.next(system, (omega, &current), &mut ds, &mut outcome.timings)?;
        info = PointInfo {
            index,
            omega,
            factorizations: tries,
            step: ds,
            seconds: clock.elapsed().as_secs_f64(),
            state: Some(sweep.state(index, omega, ds)),
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

/// What the contact-free sweep keeps fixed: the settings, the span Ω and the direction
/// sign(ω_end − ω_start).
struct LinearSweep<'a> {
    hb: &'a HbSettings,
    s: &'a SweepSettings,
    reporter: &'a dyn Reporter,
    span: f64,
    direction: f64,
}

impl LinearSweep<'_> {
    /// The linear response at ω (`system.omega` set to it).
    fn solve_at(&self, system: &mut System, omega: f64, timings: &mut Timings) -> Result<Solution> {
        system.omega = omega;
        let (linear, _) = prepare(system, None, self.hb, self.reporter, timings)?;
        Ok(linear.into_solution(system, None, Timings::default()))
    }

    /// The point after (ω, `current`): steps of Δs = `ds` (clipped to the end frequency),
    /// halved while the response changes by more than `max_change` (down to `min_step`), the
    /// next grown by 1.5 after a small change; its ω, response and the solves it took.
    fn next(
        &self,
        system: &mut System,
        (omega, current): (f64, &Solution),
        ds: &mut f64,
        timings: &mut Timings,
    ) -> Result<(f64, Solution, usize)> {
        let (s, direction, span) = (self.s, self.direction, self.span);
        let mut tries = 0;
        loop {
            let w = if ((omega + direction * *ds * span) - s.omega_end) * direction > 0.0 {
                s.omega_end
            } else {
                omega + direction * *ds * span
            };
            tries += 1;
            let candidate = self.solve_at(system, w, timings)?;
            let change = response_change(current, &candidate);
            if change <= s.max_change || *ds * 0.5 < s.min_step {
                if change < 0.3 * s.max_change {
                    *ds = (1.5 * *ds).min(s.max_step);
                }
                return Ok((w, candidate, tries));
            }
            *ds *= 0.5;
        }
    }

    /// What continuing from point `index` at ω with the next step `ds` needs (no contact:
    /// the direction alone).
    fn state(&self, index: usize, omega: f64, ds: f64) -> ContinuationState {
        ContinuationState {
            index,
            omega,
            step: ds,
            tangent: vec![self.direction],
            multipliers: Vec::new(),
            force_scale: 0.0,
            c: 0.0,
            samples: 0,
            largest: 0.0,
            reduced_frame: false,
            enriched_at: Vec::new(),
            harmonic_first: false,
            trail: Vec::new(),
            max_turn: None,
        }
    }
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
        harmonics_estimate: None,
    }
}
