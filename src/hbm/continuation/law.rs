//! The contact law a continuation follows: Signorini's alone (`reduced`), or with Coulomb
//! friction on the stacked rows (`friction`, docs/method.md §17). Each gives the Newton at one
//! ω, the residual, and the linearization of the bordered corrector.
//!
//! Glossary: x the unknowns (λ, or λ_n and λ_t stacked), R(x, ω) the residual, J = ∂R/∂x;
//! R_ω = ∂R/∂ω at fixed x, from dg = ∂g/∂ω (`corrector::gap_rate`): the Signorini law's
//! R_ω = A c dg (A the activity blocks), the frictional one's c F dg (`friction::linearization`).
//! The frictional residual is measured against the peak normal force, at least the normal
//! rows' linear force c · max r_n (`reduced::linear_force`, the frictionless measure's).

use faer::Mat;

use super::Continuation;
use crate::hbm::reduced::{self, Residual};
use crate::hbm::{friction, step, NewtonOutcome, ReducedProblem};

impl Continuation<'_> {
    /// The frictional law at the curve's c, `None` for the frictionless one.
    fn coulomb(&self) -> Option<friction::Law<'_>> {
        self.friction.as_ref().map(|coefficients| friction::Law {
            coefficients,
            c: self.newton.c,
            tangential_scale: 1.0,
        })
    }

    /// The force the frictional residual is measured against, at least: the normal rows'
    /// linear force (the first half of the stacked rows).
    fn force_floor(&self, problem: &ReducedProblem) -> f64 {
        let (rows, n) = (problem.nodes / 2, &self.newton);
        reduced::linear_force_of_rows(problem, rows, n.samples, n.c)
    }

    /// Newton at the frame's ω from `x`.
    pub(super) fn newton_on(&self, problem: &ReducedProblem, x: &[f64]) -> NewtonOutcome {
        match self.coulomb() {
            None => reduced::newton(problem, &self.newton, x, self.reporter),
            Some(law) => {
                let n = &self.newton;
                let knobs = (n.tolerance, n.max_iterations, self.force_floor(problem));
                friction::newton(problem, &law, n.samples, knobs, x.to_vec(), None)
            }
        }
    }

    /// R at x and its relative size (what the Newton stops on).
    pub(super) fn residual_on(&self, problem: &ReducedProblem, x: &[f64]) -> (Vec<f64>, f64) {
        match self.coulomb() {
            None => {
                let residual = Residual::new(problem, &self.newton);
                let e = residual.evaluate(x.to_vec());
                let relative = residual.relative(&e);
                (e.residual, relative)
            }
            Some(law) => {
                let floor = self.force_floor(problem);
                friction::residual(problem, &law, self.newton.samples, x, floor)
            }
        }
    }

    /// J and R_ω at x, from the gaps' rate `dg`.
    pub(super) fn linearize_on(
        &self,
        problem: &ReducedProblem,
        x: &[f64],
        dg: &[f64],
    ) -> (Mat<f64>, Vec<f64>) {
        if let Some(law) = self.coulomb() {
            return friction::linearization(problem, &law, self.newton.samples, x, dg);
        }
        let residual = Residual::new(problem, &self.newton);
        let e = residual.evaluate(x.to_vec());
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
}
