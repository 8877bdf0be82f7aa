//! The first point of a continuation: cold (the single-frequency solve, which fixes c and N
//! for the whole curve and the force scale F = c ‖r‖ of the first point's linear gap r), or
//! resumed from a saved state.
//!
//! Resume: a `ContinuationState` saved after any point holds all the continuation carries from
//! one point to the next (index, ω, the next Δs, τ, λ, F, c, N, the largest ‖λ‖, the trail,
//! the Krylov hint, the frequencies the reduced model learned at and the kind of the point's
//! frame), and continues the curve from that point as if it had not stopped: the model is
//! built and taught again, the point's λ is taken as saved on a frame of the same kind (a
//! Newton from it checks it solves there, on its own branch), and the points after it are the
//! uninterrupted sweep's bit for bit.

use super::corrector::MAX_CORRECTOR;
use super::frame::Frame;
use super::{hz, Continuation, ContinuationState, ReducedFrames, SweepSettings};
use crate::contact::ContactOperator;
use crate::hbm::reduced::NewtonSettings;
use crate::hbm::{
    solve_contact_timed, solve_frictional, HbSettings, NewtonOutcome, System, Timings,
};
use crate::progress::Reporter;
use crate::{Error, Result};

/// A start from `SweepSettings::resume` that is a level change of H chosen per point
/// (`levels`), not a saved point: its λ, carried from another H, is solved again at this one.
pub(super) struct Restart;

impl<'a> Continuation<'a> {
    /// The cold first point (the single-frequency solve, knob checks included) fixes c and N
    /// for the whole curve; a resumed one is taken as saved (`resume_at`), a restarted one
    /// solved again (`restart_at`).
    pub(super) fn start(
        system: &'a mut System,
        (contact, op): (&'a ContactOperator, &'a ContactOperator),
        hb: &'a HbSettings,
        s: &'a SweepSettings,
        reporter: &'a dyn Reporter,
        restart: Option<Restart>,
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
            contact,
            op,
            friction: contact.tangential.as_ref().map(|t| t.coefficients.clone()),
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
            levels: None,
            restarted: restart.is_some(),
        };
        match (&s.resume, restart) {
            (None, _) => c.cold_start(omega)?,
            (Some(r), None) => c.resume_at(r)?,
            (Some(r), Some(Restart)) => c.restart_at(r)?,
        }
        Ok(c)
    }

    /// The first point of a new curve: the single-frequency solve at ω on factorizations.
    fn cold_start(&mut self, omega: f64) -> Result<()> {
        let frame = self.exact_frame(omega)?;
        let (system, problem) = (&*self.system, &frame.problem);
        let (hb, reporter, timings) = (self.hb, self.reporter, &mut self.timings);
        let first = match self.friction {
            None => solve_contact_timed(system, self.op, problem, hb, reporter, timings)?,
            Some(_) => solve_frictional(system, self.contact, problem, hb, reporter, timings)?,
        };
        let norm = frame.problem.linear_gap.iter().map(|v| v * v).sum::<f64>();
        (self.newton.samples, self.newton.c) = (first.samples, first.c);
        self.force = (first.c * norm.sqrt()).max(f64::MIN_POSITIVE);
        let mut x = first.multipliers;
        x.extend(first.friction.iter().flat_map(|f| f.tangential.iter()));
        self.first = Some((x, first.newton, frame));
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
        let o = resolve_saved(&frame, r, self.newton_on(&frame.problem, &r.multipliers))?;
        self.factorizations = 1;
        self.first = Some((o.multipliers.clone(), o, frame));
        Ok(())
    }
}

impl Continuation<'_> {
    /// A level change's state `r` (`levels`): its scaling, c, N and the largest ‖λ‖ as
    /// carried, the reduced model built for this H, and its λ solved again at this H on an
    /// exact frame: a Newton from the carried λ, the smoothing continuation where that fails.
    fn restart_at(&mut self, r: &ContinuationState) -> Result<()> {
        (self.newton.samples, self.newton.c) = (r.samples, r.c);
        self.force = r.force_scale;
        self.largest = r.largest;
        self.build_model();
        let frame = self.exact_frame(r.omega)?;
        let mut o = self.newton_on(&frame.problem, &r.multipliers);
        if !o.converged {
            let (problem, hb, c) = (&frame.problem, self.hb, r.c);
            let start = &r.multipliers;
            o = crate::hbm::globalize::smoothed_from(problem, hb, c, start, self.reporter);
        }
        if !o.converged {
            return Err(Error::NotConverged(format!(
                "the point at {:.6} Hz did not solve again at H = {} ({}): fix \
                 harmonic_balance.harmonics to one value, or narrow its range",
                hz(r.omega),
                self.hb.harmonics,
                o.reason
            )));
        }
        self.factorizations = 1;
        self.first = Some((o.multipliers.clone(), o, frame));
        Ok(())
    }
}

/// The saved point checked on its frame by Newton from its own multipliers, which solve it
/// (no iteration, the multipliers unchanged, on the frame they were solved on). One that does
/// not solve again belongs to another scene, or was edited: bad input.
fn resolve_saved(frame: &Frame, r: &ContinuationState, o: NewtonOutcome) -> Result<NewtonOutcome> {
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
