//! The correctors of the continuation: from the predictor y_p back onto the curve R = 0.
//!
//! Glossary and formulas (y, F, Ω, τ as in the module `continuation`):
//! - R(λ, ω) = 0 the complementarity residual (23) at ω, J = ∂R/∂λ its Newton matrix;
//! - R_ω = ∂R/∂ω = Q D P (c ∂g/∂ω) at fixed λ, exact from the kept factorizations:
//!   ∂g_k/∂ω = B ∂z_k/∂ω,  ∂z_k/∂ω = −Z_k⁻¹ (∂Z_k/∂ω z_k + ∂Z_k,fp/∂ω u_p,k),
//!   ∂Z_k/∂ω = −2k²ω M + ik(αM + βK) (two solves per harmonic: the recovery and this);
//! - predictor y_p = y + Δs τ; corrector on R = 0 and τᵀ(y − y_p) = 0. Where the curve is a
//!   graph over ω (|τ_ω| ≥ `GRAPH_SLOPE`) the corrector keeps ω = ω_p and iterates on λ alone
//!   (one set of factorizations per point); near a fold ω is an unknown: a chord corrector on
//!   the problem frozen at ω_p, g ≈ G(ω_p)λ + r(ω_p) + (ω − ω_p) ∂g/∂ω, then one set of
//!   factorizations at its ω* and a fixed-ω Newton (two sets per point); where that fails, Z_k
//!   is refactored numerically (the symbolic analysis is shared) at every corrector iterate;
//! - the bordered system [J F, R_ω Ω; τᵀ] d = [R; τᵀ(y − y_p)] gives each (λ, ω) update.

use faer::{c64, Mat};

use super::{hz, Continuation, Corrector, Frame};
use crate::contact::ContactOperator;
use crate::hbm::fourier::{node_phasors, set_phasor};
use crate::hbm::{contact_part, globalize, HbSettings, LinearResponse, System};
use crate::linalg::norm2;
use crate::{Error, Result};

/// |τ_ω| above which the corrector keeps ω fixed (the curve is a graph over ω there).
const GRAPH_SLOPE: f64 = 0.05;

/// The fixed-ω Newton that puts the chord corrector's point on the curve may move λ by at most
/// this many arc-length steps (scaled); more means it found another state.
const CHORD_POLISH: f64 = 0.1;

/// Corrector iterations before a step is rejected.
pub(super) const MAX_CORRECTOR: usize = 12;

impl Continuation<'_> {
    /// The corrector from the predictor (x_p, ω_p): at fixed ω where the curve is a graph over
    /// ω or the step is `landing` on the end frequency (and converges there), else along the
    /// arc-length condition; at a `corner` (a step of a few smallest steps, away from a grazing
    /// corner) the one that failed hands over to the other.
    pub(super) fn correct(
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
            let o = self.newton_on(&frame.problem, x_p);
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
            let mut o = self.newton_on(&frame.problem, x_p);
            // Where the exact law's Newton cycles (where contact starts on a lightly damped
            // resonance, from the open state): the smoothing continuation, on the same
            // factorizations. It costs tens of Newton iterations, so steps longer than the
            // initial one are halved first, which is cheaper wherever it works.
            if !o.converged && ds < self.s.step && self.friction.is_none() {
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
            let (residual, relative) = self.residual_on(&model, &x);
            if relative <= self.newton.tolerance && iterations > 0 {
                break;
            }
            if iterations == MAX_CORRECTOR {
                return Err("the chord corrector did not converge".into());
            }
            iterations += 1;
            let (jac, r_omega) = self.linearize_on(&model, &x, &dg);
            (x, omega) =
                self.bordered_update(&jac, &r_omega, t, &residual, (x, omega), (x_p, omega_p))?;
        }
        let frame = self.frame(omega).map_err(|e| e.to_string())?;
        let o = self.newton_on(&frame.problem, &x);
        if !o.converged {
            return Err(format!("chord corrector, polish at ω*: {}", o.reason));
        }
        let moved = norm2(
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
            let (residual, relative) = self.residual_on(&frame.problem, &x);
            if relative <= self.newton.tolerance && iteration > 0 {
                return Ok((x, frame, iteration));
            }
            let dg = gap_rate(self.system, self.op, &frame.linear, &x, self.hb.harmonics);
            let (jac, r_omega) = self.linearize_on(&frame.problem, &x, &dg);
            (x, omega) =
                self.bordered_update(&jac, &r_omega, t, &residual, (x, omega), (x_p, omega_p))?;
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
    pub(super) fn tangent(&self, frame: &Frame, x: &[f64], previous: &[f64]) -> Result<Vec<f64>> {
        let dg = gap_rate(self.system, self.op, &frame.linear, x, self.hb.harmonics);
        let (jac, r_omega) = self.linearize_on(&frame.problem, x, &dg);
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
        let norm = norm2(&t);
        let sign = if t.iter().zip(previous).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        Ok(t.iter().map(|v| sign * v / norm).collect())
    }
}

/// The dofs summed over the harmonics below which `gap_rate` solves them in turn: the
/// preloaded rod of pipelines/scenes/ (11 harmonics of 200 dofs) spends 0.9 s more of a
/// 6.2 s sweep in threads than in turn, the coarse strip at H = 40 (41 of 410) 1.4 s less
/// of 8.4 s in its correctors.
const PARALLEL_RATE_DOFS: usize = 8192;

/// ∂g/∂ω at fixed λ (node-major coefficients), by two solves per harmonic (the second only
/// to the contact rows where the factor's plan gives them), the harmonics in parallel where
/// their solves are large enough (`PARALLEL_RATE_DOFS`); on a reduced frame, whose solves
/// are small dense ones, in turn.
fn gap_rate(
    system: &System,
    op: &ContactOperator,
    linear: &LinearResponse,
    x: &[f64],
    harmonics: usize,
) -> Vec<f64> {
    use rayon::prelude::*;
    let (nc, m) = (op.nodes(), 2 * harmonics + 1);
    let rate_of = |(&k, lu): (&usize, &crate::linalg::Factor)| {
        let lam = node_phasors(x, m, k);
        if let crate::linalg::Factor::Modal(f) = lu {
            // On the reduced space: no product with K or M.
            let load_rate = system.input_rate(k, &linear.motion[&k]);
            return (
                k,
                f.contact_rate(&lam, system.pencil_rate(k), load_rate.as_deref()),
            );
        }
        let mut z = linear.free[&k].clone();
        if let Some((_, dz)) = contact_part(op, lu, &lam) {
            z.iter_mut().zip(dz).for_each(|(a, b)| *a += b);
        }
        let rate = system.omega_derivative(k, &z, &linear.motion[&k]);
        let bdz = lu.contact_rows_of_solve(&op.b_free, &rate);
        (k, bdz.into_iter().map(|v| -v).collect::<Vec<c64>>())
    };
    let reduced = (linear.factors.values()).any(|f| matches!(f, crate::linalg::Factor::Modal(_)));
    let dofs: usize = linear.factors.values().map(|f| f.dim()).sum();
    let rates: Vec<(usize, Vec<c64>)> = if reduced || dofs < PARALLEL_RATE_DOFS {
        linear.factors.iter().map(rate_of).collect()
    } else {
        linear.factors.par_iter().map(rate_of).collect()
    };
    let mut dg = vec![0.0; nc * m];
    for (k, bdz) in rates {
        for (i, v) in bdz.into_iter().enumerate() {
            set_phasor(&mut dg[i * m..(i + 1) * m], k, v);
        }
    }
    dg
}
