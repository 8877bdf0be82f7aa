//! Grazing corners: where a contacting branch ends on the open one (λ = 0) no step of the
//! corrector converges, however small; the curve goes on along the open branch. And the
//! reverse: where the open branch ends (past the frequency at which the linear response
//! reaches the obstacle it penetrates), a contacting branch leaves the corner back in ω
//! (`leave_open`; a sweep down a hardening resonance meets it at the lower fold).
//!
//! Glossary: ‖λ‖ the 2-norm of the multipliers' coefficients, λ_max the largest along the
//! curve so far; a point with ‖λ‖ ≤ `GRAZING` λ_max touches, but barely, and may sit at a
//! grazing corner. The open state is the next point if it solves the complementarity at
//! ω ∓ Δs₀ Ω (ω the corner's, back first; Δs₀ the initial step; ‖λ‖ ≤ tolerance × F after
//! the Newton from λ = 0) and lies within `JUMP` largest steps of the corner in
//! y = (λ/F, ω/Ω); its direction is ±ω alone.
//!
//! Leaving the open branch: a point with ‖λ‖ ≤ `OPEN` F, from which no step converges, is at
//! the open branch's end. The contacting branch's first point is sought at ω_p − 2⁻ᵏ Δs₀ Ω
//! sgn τ_ω, k = 4, 3, … 0 (the nearest first: the branch that leaves the corner, not another
//! contacting branch further back): the Newton from λ_A = −J_A⁻¹ A (c r), the
//! state that closes the samples the linear gap r touches with (within `TOUCHING` of its
//! largest value; A = Q D_A P their activity, J_A = I − A + c A G), kept when it converges to
//! ‖λ‖ above twice the corner's (so not back onto the branch it came along).

use std::time::Instant;

use super::frame::Frame;
use super::stepping::JUMP;
use super::{Continuation, Corrector, Point, PointInfo};
use crate::hbm::{step, ReducedProblem};
use crate::linalg::norm2;
use faer::Mat;

/// A point whose ‖λ‖ is below this fraction of the largest along the curve may be at a
/// grazing corner (on the strip the contact force there is 0.1–0.2% of its largest, in mean).
pub(super) const GRAZING: f64 = 0.05;

impl Continuation<'_> {
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
    pub(super) fn graze(&mut self, p: &Point, index: usize) -> Option<(Point, Frame, PointInfo)> {
        let force = norm2(&p.x);
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
        let o = self.newton_on(&frame.problem, &open);
        if !o.converged || norm2(&o.multipliers) > self.hb.tolerance * self.force {
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
        let reached = (Corrector::Grazing, o.iterations, dist);
        let info = self.corner_info((index, &point), reached, clock);
        Some((point, frame, info))
    }

    /// The account of a point past a corner (`index`, `point`), `reached` by a corrector in
    /// a number of Newton iterations over a distance (scaled), its seconds since `clock`.
    fn corner_info(
        &self,
        (index, point): (usize, &Point),
        (corrector, iterations, step): (Corrector, usize, f64),
        clock: Instant,
    ) -> PointInfo {
        PointInfo {
            index,
            omega: point.omega,
            corrector,
            newton_iterations: iterations,
            factorizations: self.factorizations,
            step,
            tangent_omega: point.tangent_omega(),
            seconds: clock.elapsed().as_secs_f64(),
            state: None,
            scaled: Vec::new(),
            harmonics_estimate: None,
        }
    }
}

/// A point whose ‖λ‖ is below this share of the force scale F is on the open branch, or
/// touches so little that it ends with it (the clamped beam between its stops and the rubbing
/// blade of pipelines/scenes/ reach their corner sweeping down with 2e-7 F and 1e-6 F).
const OPEN: f64 = 1e-3;

/// Samples whose linear gap lies within this share of its largest magnitude below its
/// largest value are the ones an open state at its grazing corner touches with.
const TOUCHING: f64 = 1e-3;

impl Continuation<'_> {
    /// The corner where the open branch ends: arriving along it (λ = 0), past the grazing
    /// frequency the linear response penetrates and no state near the open one solves, so no
    /// step converges; the contacting branch leaves the corner back in ω (sweeping down a
    /// hardening resonance, the lower fold is such a corner). Its first point is sought one
    /// sixteenth of an initial step back, then at twice that, up to one step (the nearest
    /// first, so on the branch that leaves the corner): the Newton from the state
    /// that closes the samples the linear response touches with (`touching_start`), kept
    /// when it converges with contact. `None`: `p` is not on the open branch, or no such
    /// state was found.
    pub(super) fn leave_open(
        &mut self,
        p: &Point,
        index: usize,
    ) -> Option<(Point, Frame, PointInfo)> {
        let touch = norm2(&p.x);
        if touch > OPEN * self.force || self.friction.is_some() {
            return None;
        }
        let clock = Instant::now();
        let back = -p.tangent_omega().signum() * self.s.step * self.span;
        (0..5).rev().find_map(|k| {
            let frame = self.frame(p.omega + back / f64::from(1 << k)).ok()?;
            let start = self.touching_start(&frame.problem)?;
            let o = self.newton_on(&frame.problem, &start);
            let floor = (2.0 * touch).max(self.hb.tolerance * self.force);
            if !o.converged || norm2(&o.multipliers) <= floor {
                return None;
            }
            let point = self.after(p, o.multipliers, &frame).ok()?;
            let (point, frame) = self.verified(p, point, frame).ok()?;
            let moved: Vec<f64> = (self.scaled(&point).iter().zip(self.scaled(p)))
                .map(|(a, b)| a - b)
                .collect();
            let step = norm2(&moved);
            let reached = (Corrector::OpenCorner, o.iterations, step);
            let info = self.corner_info((index, &point), reached, clock);
            Some((point, frame, info))
        })
    }

    /// The multipliers that close the samples where the linear gap r is within `TOUCHING`
    /// of its largest value, the others open: one Newton step from λ = 0 with that active
    /// set, λ = −J_A⁻¹ A (c r), J_A = I − A + c A G (`step::dense_jacobian`). `None` where
    /// the step is not finite.
    fn touching_start(&self, problem: &ReducedProblem) -> Option<Vec<f64>> {
        let sampler = problem.sampler(self.newton.samples);
        let (m, n, nodes, c) = (
            problem.coefficients(),
            sampler.samples(),
            problem.nodes,
            self.newton.c,
        );
        let mut r = vec![0.0; nodes * n];
        for i in 0..nodes {
            sampler.to_samples(
                &problem.linear_gap[i * m..(i + 1) * m],
                &mut r[i * n..(i + 1) * n],
            );
        }
        let top = r.iter().copied().fold(f64::MIN, f64::max);
        let scale = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let slopes: Vec<f64> = (r.iter())
            .map(|&v| {
                if v >= top - TOUCHING * scale {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let blocks = step::activity_blocks(&sampler, nodes, &slopes);
        let jac = step::dense_jacobian(problem, c, &blocks);
        let closed: Vec<f64> = r.iter().zip(&slopes).map(|(v, d)| -c * v * d).collect();
        let mut rhs = Mat::<f64>::zeros(nodes * m, 1);
        let mut coeffs = vec![0.0; m];
        for i in 0..nodes {
            sampler.to_coefficients(&closed[i * n..(i + 1) * n], &mut coeffs);
            (0..m).for_each(|a| rhs[(i * m + a, 0)] = coeffs[a]);
        }
        let x = crate::linalg::dense_solve(jac, rhs);
        let start: Vec<f64> = (0..nodes * m).map(|i| x[(i, 0)]).collect();
        start.iter().all(|v| v.is_finite()).then_some(start)
    }
}
