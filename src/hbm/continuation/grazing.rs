//! Grazing corners: where a contacting branch ends on the open one (λ = 0) no step of the
//! corrector converges, however small; the curve goes on along the open branch.
//!
//! Glossary: ‖λ‖ the 2-norm of the multipliers' coefficients, λ_max the largest along the
//! curve so far; a point with ‖λ‖ ≤ `GRAZING` λ_max touches, but barely, and may sit at a
//! grazing corner. The open state is the next point if it solves the complementarity at
//! ω ∓ Δs₀ Ω (ω the corner's, back first; Δs₀ the initial step; ‖λ‖ ≤ tolerance × F after
//! the Newton from λ = 0) and lies within `JUMP` largest steps of the corner in
//! y = (λ/F, ω/Ω); its direction is ±ω alone.

use std::time::Instant;

use super::frame::Frame;
use super::stepping::JUMP;
use super::{Continuation, Corrector, Point, PointInfo};
use crate::linalg::norm2;

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
            harmonics_estimate: None,
        };
        Some((point, frame, info))
    }
}
