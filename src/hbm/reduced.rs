//! The contact problem reduced to the contact nodes' multipliers, solved by a semi-smooth
//! Newton method on the complementarity residual (23) of docs/method.md:
//!
//! R(λ) = λ + Q φ_μ(P(c(Gλ + r) − λ)),   J = I + Q D P (cG − I),   D = diag(φ_μ'),
//!
//! with φ_0(w) = max(0, w) the contact law and, for μ > 0, its smoothing
//! φ_μ(w) = (w + √(w² + 4μ²))/2 (Chen–Harker–Kanzow–Smale), whose root λ_μ tends to the
//! contact solution as μ → 0 (the continuation in μ lives in `globalize`). μ is a force.
//!
//! Unknowns are node-major: x[i·M + m] is coefficient m (`fourier` layout) of node i's λ.

use std::fmt::Write as _;

use faer::c64;

use crate::linalg::norm2;
use crate::progress::Reporter;

use super::problem::ReducedProblem;
use super::sampler::{ContactSampler, SamplerWork};
use super::step::{self, StepMethod};

#[derive(Clone, Debug)]
pub struct NewtonSettings {
    pub samples: usize,
    pub c: f64,
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Dense LU or matrix-free GMRES for the Newton step (`Auto`: by estimated flops).
    pub method: StepMethod,
    /// The smoothing μ of the projection (a force; 0 = the exact contact law).
    pub smoothing: f64,
    /// Newton steps taken even when the start is within the tolerance (1 polishes a
    /// continuation's end point onto the exact law's active set).
    pub min_iterations: usize,
    /// Give up after this many steps of length ≥ 1/2 without halving the residual (0: never):
    /// a run cycling between active sets, which a smoothing level narrows its step for. A
    /// run creeping by short steps through many active-set changes is not stopped by it.
    pub stagnation: usize,
    /// Give up after this many steps of any length without halving the residual (0: never):
    /// a run hovering at one residual by short steps, where a fallback is at hand.
    pub hover: usize,
    /// Give up once this many steps have each ended above the starting residual (0: never):
    /// a run with no solution near its start, where a fallback is at hand.
    pub rise: usize,
    /// The preconditioner the matrix-free steps start with, shared by the settings' clones.
    pub krylov_hint: step::KrylovHint,
}

/// The plain run: a step method by estimated flops, the exact contact law, no forced steps,
/// no give-up rule but the line search's and the iteration budget, a fresh Krylov hint. N,
/// c, the tolerance and the iteration budget are zero: every run sets them.
impl Default for NewtonSettings {
    fn default() -> Self {
        NewtonSettings {
            samples: 0,
            c: 0.0,
            tolerance: 0.0,
            max_iterations: 0,
            method: StepMethod::Auto,
            smoothing: 0.0,
            min_iterations: 0,
            stagnation: 0,
            hover: 0,
            rise: 0,
            krylov_hint: Default::default(),
        }
    }
}

/// The force c · max_n r_n(t_n) the linear solution's sampled penetration implies: the scale
/// of the multipliers before any is known (zero when nothing penetrates).
pub fn linear_force(problem: &ReducedProblem, samples: usize, c: f64) -> f64 {
    linear_force_of_rows(problem, problem.nodes, samples, c)
}

/// `linear_force` over the first `rows` rows only (a frictional problem's normal rows).
pub fn linear_force_of_rows(problem: &ReducedProblem, rows: usize, samples: usize, c: f64) -> f64 {
    c * sampled_linear_gap(problem, rows, samples).0.max(0.0)
}

/// The linear solution's sampled gap r_n(t_n): its largest value (the deepest penetration
/// where positive) and its largest magnitude, over the first `rows` rows and every sample.
fn sampled_linear_gap(problem: &ReducedProblem, rows: usize, samples: usize) -> (f64, f64) {
    let sampler = problem.sampler(samples);
    let m = problem.coefficients();
    let mut buffer = vec![0.0; samples];
    let (mut penetration, mut largest): (f64, f64) = (0.0, 0.0);
    for i in 0..rows {
        sampler.to_samples(&problem.linear_gap[i * m..(i + 1) * m], &mut buffer);
        for &v in &buffer {
            penetration = penetration.max(v);
            largest = largest.max(v.abs());
        }
    }
    (penetration, largest)
}

/// The share of c · max |r| (the force that closes the linear solution's largest gap)
/// below which a start's multipliers are noise where nothing penetrates (the answer is
/// λ = 0): such a start is λ = 0. Measured against their own peak, multipliers of 1e-200
/// would read 100% wrong, and on the strip sweep's reduced frame 200 iterations never moved
/// them.
const NOISE: f64 = 1e-9;

/// Residual norms the non-monotone line search looks back over.
const NONMONOTONE_WINDOW: usize = 8;
/// Steps taken without sufficient decrease before the Newton gives up.
const MAX_FORCED_STEPS: usize = 10;
/// Iteration records a Newton run reserves room for at its start (its `max_iterations` if
/// fewer), so that the log grows without allocating in the loop for the runs that matter.
const LOG_RESERVE: usize = 1000;

/// One Newton iteration's record (the log the user sees with `--verbose`).
#[derive(Clone, Debug, serde::Serialize, schemars::JsonSchema)]
pub struct IterationLog {
    pub residual: f64,
    pub active_samples: usize,
    pub step: f64,
}

#[derive(Clone, Debug)]
pub struct NewtonOutcome {
    pub multipliers: Vec<f64>,
    pub converged: bool,
    pub iterations: usize,
    /// ‖R‖∞ / force scale at the end.
    pub relative_residual: f64,
    pub log: Vec<IterationLog>,
    /// Why it stopped when not converged.
    pub reason: String,
}

/// The complementarity residual (23) at one λ, with what the Jacobian and the scale need.
#[derive(Clone, Default)]
pub(super) struct Evaluation {
    pub(super) x: Vec<f64>,
    pub(super) residual: Vec<f64>,
    /// Peak |λ| over the samples.
    peak: f64,
    /// Per node and sample: the slope φ_μ'(c g − λ) ∈ [0, 1] (1 where contact is active).
    pub(super) slopes: Vec<f64>,
}

impl Evaluation {
    /// Samples where the contact law is (mostly) active.
    fn active_samples(&self) -> usize {
        self.slopes.iter().filter(|&&s| s > 0.5).count()
    }
}

/// R(λ) = λ + Q max(0, P(c(Gλ + r) − λ)) and its pieces.
pub(super) struct Residual<'a> {
    problem: &'a ReducedProblem,
    pub(super) sampler: ContactSampler,
    c: f64,
    smoothing: f64,
    /// The force the linear solution's sampled penetration implies (c · max r): with the
    /// multipliers' own peak, the scale tolerances are relative to, so units do not matter.
    linear_force: f64,
    /// c · max_n |r_n(t_n)|, the gap's own force: the scale where nothing penetrates and
    /// λ = 0, and NOISE times it the size below which such a start is λ = 0.
    gap_force: f64,
    /// The Newton matrix's node blocks, kept between steps (`step::NodeBlocks`).
    node_blocks: std::cell::RefCell<step::NodeBlocks>,
    /// What an evaluation writes besides its result, kept between evaluations.
    scratch: std::cell::RefCell<EvaluationScratch>,
}

/// The work vectors of one residual evaluation: the gap G λ + r (node-major), one node's
/// law argument, its samples and λ's, its projected coefficients, and the phasors of the
/// product with G.
#[derive(Default)]
struct EvaluationScratch {
    gap: Vec<f64>,
    argument: Vec<f64>,
    samples: Vec<f64>,
    multipliers: Vec<f64>,
    coefficients: Vec<f64>,
    phasors: Vec<c64>,
    sampling: SamplerWork,
}

impl<'a> Residual<'a> {
    pub(super) fn new(problem: &'a ReducedProblem, settings: &NewtonSettings) -> Self {
        // One pass over the sampled linear gap for both scales.
        let (penetration, largest) = sampled_linear_gap(problem, problem.nodes, settings.samples);
        Residual {
            problem,
            sampler: problem.sampler(settings.samples),
            c: settings.c,
            smoothing: settings.smoothing,
            linear_force: settings.c * penetration.max(0.0),
            gap_force: settings.c * largest,
            node_blocks: Default::default(),
            scratch: Default::default(),
        }
    }

    /// φ_μ(w) and φ_μ'(w).
    fn law(&self, w: f64) -> (f64, f64) {
        if self.smoothing == 0.0 {
            (w.max(0.0), if w > 0.0 { 1.0 } else { 0.0 })
        } else {
            let root = (w * w + 4.0 * self.smoothing * self.smoothing).sqrt();
            (0.5 * (w + root), 0.5 * (1.0 + w / root))
        }
    }

    pub(super) fn evaluate(&self, x: Vec<f64>) -> Evaluation {
        let mut e = Evaluation {
            x,
            ..Evaluation::default()
        };
        self.evaluate_in_place(&mut e);
        e
    }

    /// R and the slopes at `e.x`, into `e`: nothing is allocated once `e` and this residual
    /// have held an evaluation of the same problem.
    pub(super) fn evaluate_in_place(&self, e: &mut Evaluation) {
        let (nc, m, ns) = (
            self.problem.nodes,
            self.problem.coefficients(),
            self.sampler.samples(),
        );
        let mut scratch = self.scratch.borrow_mut();
        let EvaluationScratch {
            gap,
            argument,
            samples: w,
            multipliers: lam,
            coefficients: coeffs,
            phasors,
            sampling,
        } = &mut *scratch;
        let x = &e.x;
        self.problem.gap_into(x, gap, phasors);
        argument.resize(m, 0.0);
        w.resize(ns, 0.0);
        lam.resize(ns, 0.0);
        coeffs.resize(m, 0.0);
        e.residual.clear();
        e.residual.extend_from_slice(x);
        e.slopes.clear();
        let mut peak: f64 = 0.0;
        for i in 0..nc {
            for (a, arg) in argument.iter_mut().enumerate() {
                *arg = self.c * gap[i * m + a] - x[i * m + a];
            }
            self.sampler.to_samples_with(argument, w, sampling);
            self.sampler
                .to_samples_with(&x[i * m..(i + 1) * m], lam, sampling);
            peak = lam.iter().fold(peak, |a, &v| a.max(v.abs()));
            for v in w.iter_mut() {
                let (value, slope) = self.law(*v);
                e.slopes.push(slope);
                *v = value;
            }
            self.sampler.to_coefficients_with(w, coeffs, sampling);
            for (r, q) in e.residual[i * m..(i + 1) * m].iter_mut().zip(coeffs.iter()) {
                *r += q;
            }
        }
        e.peak = peak;
    }

    /// `start`, or λ = 0 where nothing penetrates and `start` is below NOISE × `gap_force`.
    fn denoised(&self, start: &[f64]) -> Vec<f64> {
        let peak = start.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
        if self.linear_force == 0.0 && peak <= NOISE * self.gap_force {
            vec![0.0; start.len()]
        } else {
            start.to_vec()
        }
    }

    /// ‖R‖∞ over the force scale: the linear penetration's force or the multipliers' peak;
    /// where both are zero (nothing penetrates and λ = 0, as in a heavier-damped level of the
    /// damping continuation, whose smoothed law leaves a tiny R), c max_n |r_n(t_n)|.
    pub(super) fn relative(&self, e: &Evaluation) -> f64 {
        let scale = match self.linear_force.max(e.peak) {
            s if s > 0.0 => s,
            _ => self.gap_force.max(f64::MIN_POSITIVE),
        };
        e.residual.iter().fold(0.0f64, |a, &b| a.max(b.abs())) / scale
    }

    /// The Newton direction into `d`: dense LU or matrix-free GMRES (`step`), the latter to
    /// the forcing term of `step::forcing` at the current relative residual.
    fn direction(
        &self,
        e: &Evaluation,
        settings: &NewtonSettings,
        d: &mut Vec<f64>,
    ) -> Result<(), String> {
        step::direction_into(
            self.problem,
            &self.sampler,
            self.c,
            &e.slopes,
            &e.residual,
            (
                settings.method,
                step::forcing(self.relative(e), settings.tolerance),
            ),
            &mut self.node_blocks.borrow_mut(),
            &settings.krylov_hint,
            d,
        )
    }
}

/// Non-monotone Armijo backtracking (Grippo, Lampariello, Lucidi 1986) against `reference`,
/// the worst of the last few ‖R‖₂: semi-smooth Newton steps cross kinks of max(0, ·) and a
/// strictly monotone search stalls on them. On success `trial` holds the accepted point and
/// the step length is returned; otherwise `best` holds the best trial and its length is the
/// error. `trial` and `best` are work space the caller keeps (nothing is allocated once they
/// held an evaluation).
fn line_search(
    residual: &Residual,
    current: &Evaluation,
    step: &[f64],
    reference: f64,
    (trial, best): (&mut Evaluation, &mut Evaluation),
) -> Result<f64, f64> {
    let mut alpha = 1.0;
    let mut best_trial: Option<(f64, f64)> = None;
    while alpha >= 1.0 / 1024.0 {
        trial.x.clear();
        trial
            .x
            .extend(current.x.iter().zip(step).map(|(x, d)| x + alpha * d));
        residual.evaluate_in_place(trial);
        let norm = norm2(&trial.residual);
        if norm <= (1.0 - 1e-4 * alpha) * reference {
            return Ok(alpha);
        }
        if best_trial.is_none_or(|b| norm < b.0) {
            best_trial = Some((norm, alpha));
            std::mem::swap(trial, best);
        }
        alpha *= 0.5;
    }
    Err(best_trial.map_or(0.0, |b| b.1))
}

/// Semi-smooth Newton on R(λ) = 0 from `start`, globalized by the non-monotone line search
/// with a bounded number of forced steps; progress goes to `reporter` every iteration.
pub fn newton(
    problem: &ReducedProblem,
    settings: &NewtonSettings,
    start: &[f64],
    reporter: &dyn Reporter,
) -> NewtonOutcome {
    newton_until(problem, settings, start, reporter, None)
}

/// `newton`, stopping before an iteration that would start at or after `deadline` (the
/// outcome's reason then names the iteration reached).
pub fn newton_until(
    problem: &ReducedProblem,
    settings: &NewtonSettings,
    start: &[f64],
    reporter: &dyn Reporter,
    deadline: Option<std::time::Instant>,
) -> NewtonOutcome {
    let residual = Residual::new(problem, settings);
    let mut current = residual.evaluate(residual.denoised(start));
    // Everything the iterations write, sized here: the loop allocates nothing of its own.
    let (mut trial, mut best) = (current.clone(), current.clone());
    let mut step = Vec::with_capacity(current.x.len());
    let mut status = String::with_capacity(64);
    let mut log = Vec::with_capacity(settings.max_iterations.min(LOG_RESERVE) + 1);
    log.push(IterationLog {
        residual: residual.relative(&current),
        active_samples: current.active_samples(),
        step: 0.0,
    });
    let mut iterations = 0;
    let mut memory = SearchMemory::default();
    let mut watch = Watch::new(residual.relative(&current));
    let reason = loop {
        let rel = residual.relative(&current);
        let within = rel <= settings.tolerance;
        if within && iterations >= settings.min_iterations {
            break None;
        }
        let h = problem.harmonics;
        if let Some(why) = watch.reason(settings, (iterations, rel, h), &log, deadline) {
            break Some(why);
        }
        iterations += 1;
        status.clear();
        let _ = write!(status, "H = {h}, residual {rel:.2e}");
        reporter.progress("contact Newton", iterations as u64, None, &status);
        if let Err(why) = residual.direction(&current, settings, &mut step) {
            break Some(why);
        }
        let buffers = (&mut trial, &mut best);
        let alpha = memory.step(&residual, iterations, &mut current, &step, buffers);
        let stalled = alpha.is_none();
        let alpha = alpha.unwrap_or(0.0);
        watch.stepped(alpha);
        log.push(IterationLog {
            residual: residual.relative(&current),
            active_samples: current.active_samples(),
            step: alpha,
        });
        if stalled {
            // A polishing step that could not improve keeps the converged point.
            let why = "the line search found no decrease of ‖R‖ (stalled)";
            break (!within).then(|| why.to_string());
        }
    };
    reporter.task_done("contact Newton");
    NewtonOutcome {
        relative_residual: residual.relative(&current),
        multipliers: current.x,
        converged: reason.is_none(),
        iterations,
        log,
        reason: reason.unwrap_or_default(),
    }
}

/// The non-monotone line search's memory over a Newton run: the last `NONMONOTONE_WINDOW`
/// residual norms ‖R‖ (newest at `iterations % window`) and the forced steps taken.
#[derive(Default)]
struct SearchMemory {
    history: [f64; NONMONOTONE_WINDOW],
    stalls: usize,
}

impl SearchMemory {
    /// Iteration `iterations`' step from `current` along `step`: the line search against the
    /// worst of the last min(iterations, window) norms, or, when it finds no decrease, its
    /// best trial anyway (up to `MAX_FORCED_STEPS` times, to leave a kink). `current` becomes
    /// the point taken; the step length, `None` when the search stalled (`current` unchanged).
    fn step(
        &mut self,
        residual: &Residual,
        iterations: usize,
        current: &mut Evaluation,
        step: &[f64],
        (trial, best): (&mut Evaluation, &mut Evaluation),
    ) -> Option<f64> {
        self.history[iterations % NONMONOTONE_WINDOW] = norm2(&current.residual);
        // The unused slots are 0.
        let reference = self.history.iter().fold(0.0f64, |a, &b| a.max(b));
        match line_search(
            residual,
            current,
            step,
            reference,
            (&mut *trial, &mut *best),
        ) {
            Ok(alpha) => {
                std::mem::swap(current, trial);
                Some(alpha)
            }
            Err(alpha) if self.stalls < MAX_FORCED_STEPS => {
                self.stalls += 1;
                std::mem::swap(current, best);
                Some(alpha)
            }
            Err(_) => None,
        }
    }
}

/// What a Newton run watches to give up before its next iteration (the rules of
/// `NewtonSettings`: stagnation, rise, hover, and its budgets): the residual the last
/// halving reached, and the near-full steps and all steps taken since.
struct Watch {
    mark: f64,
    full_steps: usize,
    since: usize,
}

impl Watch {
    fn new(start: f64) -> Watch {
        Watch {
            mark: start,
            full_steps: 0,
            since: 0,
        }
    }

    /// A step of length `alpha` was taken.
    fn stepped(&mut self, alpha: f64) {
        self.full_steps += usize::from(alpha >= 0.5);
        self.since += 1;
    }

    /// Why the run stops after `iterations` at relative residual `rel` (harmonic count `h`),
    /// or `None` to go on.
    fn reason(
        &mut self,
        settings: &NewtonSettings,
        (iterations, rel, h): (usize, f64, usize),
        log: &[IterationLog],
        deadline: Option<std::time::Instant>,
    ) -> Option<String> {
        if rel <= 0.5 * self.mark {
            *self = Watch::new(rel);
        }
        let (full_steps, since) = (self.full_steps, self.since);
        if settings.stagnation > 0 && full_steps >= settings.stagnation {
            return Some(format!(
                "{full_steps} near-full Newton steps did not halve the residual (cycling between \
                 active sets)"
            ));
        }
        if settings.rise > 0 && iterations >= settings.rise && rose(log) {
            return Some(format!(
                "{iterations} Newton steps each ended above the starting residual (no solution \
                 near the start)"
            ));
        }
        if settings.hover > 0 && since >= settings.hover {
            return Some(format!(
                "{since} Newton steps did not halve the residual (hovering between active sets)"
            ));
        }
        if !rel.is_finite() {
            return Some("the residual became non-finite".to_string());
        }
        if iterations >= settings.max_iterations {
            let max = settings.max_iterations;
            return Some(format!("reached max_iterations = {max}"));
        }
        if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            return Some(format!(
                "the time budget ran out after iteration {iterations} of this Newton run (H = \
                 {h}, residual {rel:.2e})"
            ));
        }
        None
    }
}

/// Whether a Newton run took steps and each ended above its starting residual.
pub fn rose(log: &[IterationLog]) -> bool {
    log.len() > 1 && log[1..].iter().all(|l| l.residual > log[0].residual)
}

/// Pad node-major coefficients from `from_h` harmonics to `to_h` (zeros for the new ones).
pub fn pad(x: &[f64], nodes: usize, from_h: usize, to_h: usize) -> Vec<f64> {
    let (mf, mt) = (2 * from_h + 1, 2 * to_h + 1);
    let mut out = vec![0.0; nodes * mt];
    for i in 0..nodes {
        let keep = mf.min(mt);
        out[i * mt..i * mt + keep].copy_from_slice(&x[i * mf..i * mf + keep]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hbm::basis::TimeBasis;

    /// One massless contact node on a spring k against a stop at distance g0, pushed by a
    /// static plus harmonic force: the exact solution is piecewise (clipped) and the
    /// Fourier–Galerkin one must reproduce its mean force for a static push.
    #[test]
    fn static_spring_against_stop() {
        // u = f/k; gap = u − g0; closed when f/k > g0, then λ = −(f − k g0).
        let (k, f, g0) = (2.0, 3.0, 1.0);
        let problem = ReducedProblem {
            nodes: 1,
            harmonics: 0,
            compliance: vec![vec![c64::new(1.0 / k, 0.0)]],
            linear_gap: vec![f / k - g0],
            basis: TimeBasis::Fourier,
        };
        let settings = NewtonSettings {
            samples: 1,
            c: k,
            tolerance: 1e-12,
            max_iterations: 20,
            ..Default::default()
        };
        let out = newton(&problem, &settings, &[0.0], &crate::Silent);
        assert!(out.converged, "{}", out.reason);
        assert!((out.multipliers[0] + (f - k * g0)).abs() < 1e-12);
    }

    /// `nodes` contact nodes, each on a spring k (coupled to the others by 0.1 k), statically
    /// held g0/2 off the stop at H harmonics, and Newton settings for them (N = 16, c = k).
    fn held_off(nodes: usize, (k, g0, h): (f64, f64, usize)) -> (ReducedProblem, NewtonSettings) {
        let m = 2 * h + 1;
        let problem = ReducedProblem::from_compliance(nodes, h, |_, i, j| {
            c64::new(if i == j { 1.0 / k } else { 0.1 / k }, 0.0)
        });
        let problem = ReducedProblem {
            linear_gap: (0..nodes * m)
                .map(|r| if r % m == 0 { -g0 / 2.0 } else { 0.0 })
                .collect(),
            ..problem
        };
        let settings = NewtonSettings {
            samples: 16,
            c: k,
            tolerance: 1e-10,
            max_iterations: 50,
            ..Default::default()
        };
        (problem, settings)
    }

    /// TEST GOAL: where nothing penetrates (the answer is λ = 0), Newton from multipliers of
    /// 1e-200 (a resumed sweep state tampered in its last digits) reads them as zero at once;
    /// with their own peak as the residual's scale they read 100% wrong (on the strip sweep's
    /// reduced frame 200 iterations then never moved them: the case ef33f7e6 of
    /// tests/fuzz.proptest-regressions).
    #[test]
    fn denormal_scale_multipliers_where_nothing_penetrates_are_zero() {
        let (k, g0, h) = (2.0, 1.0, 3usize);
        let m = 2 * h + 1;
        let (problem, settings) = held_off(2, (k, g0, h));
        for start in [0.0, 1e-200, -1e-300] {
            let x: Vec<f64> = (0..2 * m).map(|r| start * (1.0 + r as f64)).collect();
            let out = newton(&problem, &settings, &x, &crate::Silent);
            assert!(out.converged, "from {start:e}: {}", out.reason);
            assert_eq!(out.iterations, 0, "from {start:e}");
        }
    }

    /// TEST GOAL: where nothing penetrates, the smoothed law (μ > 0) leaves a residual at
    /// λ = 0, and its relative size is of order one: it is measured against c max |r|, not the
    /// zero penetration force (a heavier-damped level of the damping continuation, the strip
    /// of pipelines/scenes/ at H = 40 and 1350 Hz, read it as infinite and failed at once).
    /// Newton converges there to a λ of the smoothing's order.
    #[test]
    fn a_smoothed_start_where_nothing_penetrates_has_a_residual_of_order_one_and_converges() {
        let (k, g0, h) = (2.0, 1.0, 3usize);
        let m = 2 * h + 1;
        let (problem, settings) = held_off(1, (k, g0, h));
        let settings = NewtonSettings {
            smoothing: 1.0,
            ..settings
        };
        let residual = Residual::new(&problem, &settings);
        let at_zero = residual.evaluate(vec![0.0; m]);
        let relative = residual.relative(&at_zero);
        // φ_μ(−1) = (√5 − 1)/2 against c max |r| = 1; against the zero penetration force
        // (floored at the smallest normal number) it read 3e307, and above a force of 4, inf.
        assert!(
            (relative - 0.5 * (5f64.sqrt() - 1.0)).abs() < 1e-12,
            "{relative}"
        );
        let out = newton(&problem, &settings, &vec![0.0; m], &crate::Silent);
        assert!(out.converged, "{}", out.reason);
        let peak = out.multipliers.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(peak < settings.smoothing, "{peak}");
    }

    /// A massless node on a spring driven by f(t) = F cos ωt against a stop at g0 > 0: the
    /// exact λ(t) = −max(0, F cos ωt − k g0), whose Fourier coefficients are known in closed
    /// form; the harmonic-balance multipliers converge to them as H grows.
    #[test]
    fn clipped_cosine_converges_with_h() {
        let (k, big_f, g0) = (1.0f64, 2.0f64, 1.0f64);
        // cos θ > k g0 / F = 1/2 for |θ| < θ0 = π/3.
        let theta0 = (k * g0 / big_f).acos();
        let pi = std::f64::consts::PI;
        let exact = |n: usize| -> f64 {
            // coefficient of cos nθ of −max(0, F cos θ − k g0).
            let integrand = |th: f64| -(big_f * th.cos() - k * g0) * (n as f64 * th).cos();
            // Simpson on [−θ0, θ0].
            let steps = 2000;
            let h = 2.0 * theta0 / steps as f64;
            let mut s = integrand(-theta0) + integrand(theta0);
            for q in 1..steps {
                let w = if q % 2 == 1 { 4.0 } else { 2.0 };
                s += w * integrand(-theta0 + q as f64 * h);
            }
            let integral = s * h / 3.0;
            if n == 0 {
                integral / (2.0 * pi)
            } else {
                integral / pi
            }
        };
        let mut errors = Vec::new();
        for h in [3usize, 6, 12, 24] {
            let m = 2 * h + 1;
            let mut r = vec![0.0; m];
            r[0] = -g0;
            r[1] = big_f / k;
            let problem = ReducedProblem {
                nodes: 1,
                harmonics: h,
                compliance: vec![vec![c64::new(1.0 / k, 0.0)]; h + 1],
                linear_gap: r,
                basis: TimeBasis::Fourier,
            };
            let settings = NewtonSettings {
                samples: 16 * h,
                c: k,
                tolerance: 1e-12,
                max_iterations: 50,
                ..Default::default()
            };
            let out = newton(&problem, &settings, &vec![0.0; m], &crate::Silent);
            assert!(out.converged, "H = {h}: {}", out.reason);
            let err = (out.multipliers[0] - exact(0)).abs() + (out.multipliers[1] - exact(1)).abs();
            errors.push(err);
        }
        for w in errors.windows(2) {
            assert!(w[1] < w[0], "errors must shrink with H: {errors:?}");
        }
        assert!(errors[3] < 2e-3, "{errors:?}");
    }

    /// Two coupled massless nodes against stops, harmonic forcing: the matrix-free Krylov
    /// Newton reaches the same solution as the dense one.
    #[test]
    fn krylov_path_matches_dense() {
        let h = 8;
        let m = 2 * h + 1;
        let g = vec![
            c64::new(1.0, 0.0),
            c64::new(0.3, 0.0),
            c64::new(0.3, 0.0),
            c64::new(0.8, 0.0),
        ];
        let mut r = vec![0.0; 2 * m];
        r[0] = -0.5;
        r[1] = 1.2;
        r[m] = -0.2;
        r[m + 2] = 0.7;
        let problem = ReducedProblem {
            nodes: 2,
            harmonics: h,
            compliance: vec![g; h + 1],
            linear_gap: r,
            basis: TimeBasis::Fourier,
        };
        let mut settings = NewtonSettings {
            samples: 16 * h,
            c: 1.0,
            tolerance: 1e-10,
            max_iterations: 60,
            ..Default::default()
        };
        settings.method = StepMethod::Dense;
        let dense = newton(&problem, &settings, &vec![0.0; 2 * m], &crate::Silent);
        settings.method = StepMethod::Krylov;
        let krylov = newton(&problem, &settings, &vec![0.0; 2 * m], &crate::Silent);
        assert!(
            dense.converged && krylov.converged,
            "{} / {}",
            dense.reason,
            krylov.reason
        );
        let diff = dense
            .multipliers
            .iter()
            .zip(&krylov.multipliers)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-8, "{diff:e}");
        assert!(
            dense.multipliers.iter().any(|&v| v.abs() > 0.1),
            "contact must be active"
        );
    }
}

#[cfg(test)]
mod jacobian_tests {
    use super::*;
    use crate::hbm::basis::TimeBasis;

    /// TEST GOAL: G x by faer's product per harmonic (sequential for small G, on both cores
    /// from 2¹⁶ entries) equals Σ_b G_real[a, b] x_b formed from the real-form entries that
    /// the dense Jacobian uses, to round-off, for a non-symmetric G (so a transposed or
    /// conjugated product would fail).
    #[test]
    fn compliance_product_equals_the_real_form_entries_sequential_and_parallel() {
        for (nc, h) in [(3usize, 4usize), (260, 1)] {
            let m = 2 * h + 1;
            let entry = |k: usize, i: usize, j: usize| {
                c64::new(
                    ((i * 7 + j * 3 + k) % 11) as f64 - 5.0,
                    ((i * 5 + j * 13 + 2 * k) % 7) as f64 - 3.0,
                )
            };
            let problem = ReducedProblem::from_compliance(nc, h, entry);
            let x: Vec<f64> = (0..nc * m)
                .map(|r| ((r * 37 % 19) as f64) / 19.0 - 0.4)
                .collect();
            let mut out = vec![0.0; nc * m];
            problem.compliance_product(&x, &mut out, &mut Vec::new());
            let mut worst: f64 = 0.0;
            for i in 0..nc {
                for a in 0..m {
                    let dense: f64 = (0..nc)
                        .flat_map(|j| (0..m).map(move |b| (j, b)))
                        .map(|(j, b)| problem.real_entry(i, a, j, b) * x[j * m + b])
                        .sum();
                    worst = worst.max((dense - out[i * m + a]).abs() / (1.0 + dense.abs()));
                }
            }
            assert!(worst < 1e-12, "n_c = {nc}: {worst:.2e}");
        }
    }

    /// A Fourier problem of `nc` nodes at H = `h` drawn from `rnd` (values in [−½, ½)):
    /// symmetric G_k with diagonal real parts shifted by 2, and a linear gap.
    fn random_problem(nc: usize, h: usize, rnd: &mut dyn FnMut() -> f64) -> ReducedProblem {
        let m = 2 * h + 1;
        let compliance: Vec<Vec<c64>> = (0..=h)
            .map(|_| {
                let mut g = vec![c64::new(0.0, 0.0); nc * nc];
                for i in 0..nc {
                    for j in 0..=i {
                        let v = c64::new(rnd() + if i == j { 2.0 } else { 0.0 }, 0.3 * rnd());
                        g[i * nc + j] = v;
                        g[j * nc + i] = v;
                    }
                }
                g
            })
            .collect();
        ReducedProblem {
            nodes: nc,
            harmonics: h,
            compliance,
            linear_gap: (0..nc * m).map(|_| rnd()).collect(),
            basis: TimeBasis::Fourier,
        }
    }

    /// The generalized Jacobian equals the finite-difference derivative of R away from kinks.
    #[test]
    fn jacobian_matches_finite_differences() {
        let (nc, h) = (3usize, 4usize);
        let m = 2 * h + 1;
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as f64 / (1u64 << 31) as f64) - 0.5
        };
        let problem = random_problem(nc, h, &mut rnd);
        let sampler = ContactSampler::new(&TimeBasis::Fourier, h, 64);
        let x: Vec<f64> = (0..nc * m).map(|_| rnd()).collect();
        let c = 0.7;
        let residual = |x: &[f64]| -> (Vec<f64>, Vec<bool>) {
            let g = problem.gap(x);
            let mut r = x.to_vec();
            let mut active = Vec::new();
            let mut w = vec![0.0; 64];
            let mut co = vec![0.0; m];
            for i in 0..nc {
                let arg: Vec<f64> = (0..m).map(|a| c * g[i * m + a] - x[i * m + a]).collect();
                sampler.to_samples(&arg, &mut w);
                for v in w.iter_mut() {
                    active.push(*v > 0.0);
                    *v = v.max(0.0);
                }
                sampler.to_coefficients(&w, &mut co);
                for a in 0..m {
                    r[i * m + a] += co[a];
                }
            }
            (r, active)
        };
        let (r0, active) = residual(&x);
        // J d = −r0 solved densely; check J against finite differences via J·e_k.
        let eps = 1e-7;
        for k in [0usize, 3, 7, 13, 20] {
            let mut xp = x.clone();
            xp[k] += eps;
            let (rp, ap) = residual(&xp);
            assert_eq!(ap, active, "perturbation crossed a kink");
            let mut e = vec![0.0; nc * m];
            e[k] = 1.0;
            // The dense step returns J⁻¹(−r): J⁻¹ of the finite-difference column,
            // J⁻¹ (R(x+εe_k) − R(x))/ε, must be e_k.
            let fd: Vec<f64> = rp.iter().zip(&r0).map(|(a, b)| -(a - b) / eps).collect();
            let slopes: Vec<f64> = active.iter().map(|&a| a as u8 as f64).collect();
            let back = step::direction(
                &problem,
                &sampler,
                c,
                &slopes,
                &fd,
                StepMethod::Dense,
                1e-6,
                &mut Default::default(),
                &Default::default(),
            )
            .expect("regular");
            for (a, b) in back.iter().zip(&e) {
                assert!((a - b).abs() < 1e-5, "column {k}: {back:?}");
            }
        }
    }
}
