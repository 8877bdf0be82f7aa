//! Frames: everything the continuation needs at one ω, the linear response z_lin,k, the
//! reduced problem (G_k = B Z_k⁻¹ Bᵀ and the linear gap r) and, for the recovery and R_ω, the
//! solves with Z_k(ω).
//!
//! Glossary: an exact frame factors Z_k(ω) = K − k²ω²M + ikωD per harmonic; a reduced frame
//! takes the solves from the reduced model of Z_k(ω)⁻¹ over the sweep's range
//! (`hbm::frames::ReducedModel`), which pays where its start block times the shifts stays
//! below half the free dofs (`reduced_model_pays`). A point solved on a reduced frame is kept
//! when its recovered field's backward error is at most `frames::BACKWARD_TOLERANCE`; else it
//! is solved again on an exact frame, and the model learns that frame's solves.

use std::time::Instant;

use super::{Continuation, Point};
use crate::hbm::frames::{self, ReducedModel};
use crate::hbm::{prepare_with, LinearResponse, ReducedProblem, Source, System};
use crate::{Error, Result};

/// Everything at one ω: the factorizations (or a reduced model's solves), the linear response
/// and the reduced problem.
pub(super) struct Frame {
    pub(super) omega: f64,
    pub(super) linear: LinearResponse,
    pub(super) problem: ReducedProblem,
    /// From the reduced model (its points are checked before they are kept).
    pub(super) reduced: bool,
}

impl Continuation<'_> {
    /// Teach the reduced model the solves of the exact frame `exact` (`frames::enrich_from`),
    /// noting its ω for a resume; a model that cannot learn them is dropped.
    pub(super) fn enrich(&mut self, exact: &Frame) {
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
    pub(super) fn frame(&mut self, omega: f64) -> Result<Frame> {
        self.frame_from(omega, self.model.is_some())
    }

    /// The frame at ω from one set of factorizations.
    pub(super) fn exact_frame(&mut self, omega: f64) -> Result<Frame> {
        self.frame_from(omega, false)
    }

    pub(super) fn frame_from(&mut self, omega: f64, reduced: bool) -> Result<Frame> {
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
    pub(super) fn build_model(&mut self) {
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
    pub(super) fn verified(
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
        let o = self.newton_on(&exact.problem, &next.x);
        if !o.converged {
            return Err(format!("the exact frame of a reduced point: {}", o.reason));
        }
        let point = self.after(p, o.multipliers, &exact)?;
        Ok((point, exact))
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
