//! The Newton step of the reduced contact problem: solve J d = −R with
//!
//! J = I − A + c A G,   A = blockdiag_i(A_i),   A_i = Q D_i P,
//!
//! where D_i = diag(φ'(w_i,n)) holds the slope of the (possibly smoothed) projection at node
//! i's samples (0/1 for the plain max(0, ·)), G is the compliance in real form (block-diagonal
//! in the harmonics, or a spline basis' discrete frequencies) and P, Q the sampling and
//! projection maps of `sampler` (Fourier's FFT maps, or a spline basis' quadrature maps). Glossary: nc
//! contact nodes, M = 2H + 1 coefficients per node, N samples, dim = nc·M unknowns.
//!
//! Two facts make the step cheap:
//! - A_i is a Toeplitz-plus-Hankel matrix in the harmonics: entry (a, b) is w_a times the mean
//!   of s(t)·p_a(t)·p_b(t), and products of cos/sin of harmonics p and q are cos/sin of p ± q,
//!   so A_i follows from the discrete Fourier sums Ĉ_j, Ŝ_j (j = 0..2H) of the slopes s_n:
//!   one FFT and M² lookups per node instead of M²·N products.
//! - J is dense only across the contact nodes of one harmonic: the dense LU costs ⅔ dim³,
//!   a matrix-free GMRES iteration O(nc·N log N + nc²·H). The step picks by estimated flops.
//!
//! GMRES is preconditioned by J's node blocks J_ii = I − A_i + c A_i G_ii (exact for
//! uncoupled nodes) or by its harmonic blocks P_k = I − diag(a) + c diag(a) G_k, a_i node
//! i's mean slope (exact for nodes closed or open all period, however G couples them),
//! whichever served the last step (`krylov_step`).

use faer::{c64, Mat};

use super::fourier::{harmonic_of, phasor, set_phasor};
use super::problem::ReducedProblem;
use super::sampler::{ContactSampler, SamplerWork};
use crate::linalg::{loose_or_stalled, DenseLu, DenseLuWork, GmresWork, LuWork};

/// GMRES iterations the cost model assumes per Newton step (measured: 10–40 on the strip and
/// the half-disc with the node-block preconditioner).
const ASSUMED_KRYLOV_ITERATIONS: f64 = 40.0;

/// A GMRES that stalls with both preconditioners falls back to the dense step below this
/// many flops (≈ 1–3 s on 2 cores): the node blocks ignore the coupling between nodes, the
/// harmonic blocks the coupling between harmonics of nodes that open and close.
const DENSE_FALLBACK: f64 = 5e10;

/// How a Newton step is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepMethod {
    /// Pick by the flop estimate below.
    Auto,
    Dense,
    Krylov,
}

/// Estimated flops of the dense step and of the matrix-free one (per Newton iteration). Both
/// form the activity blocks (an FFT and M² lookups per node); the dense step then assembles
/// and factors J, the matrix-free one factors the node blocks (⅔M³ each) and runs GMRES,
/// whose iteration costs an M × M product and two triangular solves per node, the products
/// with G and the Gram–Schmidt of about half the iterations' vectors.
pub fn estimated_flops(nodes: usize, harmonics: usize, samples: usize) -> (f64, f64) {
    let (nc, m, n) = (nodes as f64, (2 * harmonics + 1) as f64, samples as f64);
    let dim = nc * m;
    let blocks = nc * (5.0 * n * n.log2().max(1.0) + m * m);
    let dense = blocks + 2.0 / 3.0 * dim.powi(3) + 4.0 * nc * nc * m * m;
    let per_iteration = nc * 4.0 * m * m
        + 8.0 * nc * nc * (harmonics as f64 + 1.0)
        + 2.0 * dim * ASSUMED_KRYLOV_ITERATIONS / 2.0;
    let setup = blocks + nc * (2.0 / 3.0 * m.powi(3) + 4.0 * m * m);
    (dense, setup + ASSUMED_KRYLOV_ITERATIONS * per_iteration)
}

/// The step method a problem of this size uses under `Auto`.
pub fn resolve(method: StepMethod, nodes: usize, harmonics: usize, samples: usize) -> StepMethod {
    match method {
        StepMethod::Auto => {
            let (dense, krylov) = estimated_flops(nodes, harmonics, samples);
            if dense <= krylov {
                StepMethod::Dense
            } else {
                StepMethod::Krylov
            }
        }
        other => other,
    }
}

/// The relative accuracy a matrix-free step needs (the forcing term η of inexact Newton,
/// Eisenstat and Walker 1996): ‖J d + R‖ ≤ η ‖R‖ with η = min(10⁻⁴, max(r, 0.1 τ / r)) at
/// relative residual r and tolerance τ. η = O(r) keeps Newton's local quadratic rate, and
/// nothing is solved much beyond what the tolerance asks of the next iterate (r η ≈ 0.1 τ).
/// The cap: looser steps change the semi-smooth path on hard cases. At 10⁻² the 0.5%-damped
/// reference strip at H = 60 went down the harmonic ladder to another state (845
/// iterations); at 10⁻³ the undamped `strip_wall` at H = 40 (lc 0.005) stalled, or with the
/// preconditioner's round-off changed took 43 iterations to another state, where 10⁻⁴ … 10⁻⁶
/// give the state of the 10⁻⁶ solver in 18–26 (tests/contact_scenes.rs
/// `undamped_impacts_converge_by_continuation_and_a_starved_newton_is_diagnosed` and
/// `lightly_damped_reference_strip_needs_at_most_three_times_the_iterations`).
pub fn forcing(relative_residual: f64, tolerance: f64) -> f64 {
    let r = relative_residual.max(f64::MIN_POSITIVE);
    r.max(0.1 * tolerance / r).min(1e-4)
}

/// The Newton direction d = −J⁻¹ R (matrix-free to relative accuracy `forcing`), with the
/// node blocks of `cache` brought up to date for these slopes.
#[allow(clippy::too_many_arguments)]
pub fn direction(
    problem: &ReducedProblem,
    sampler: &ContactSampler,
    c: f64,
    slopes: &[f64],
    residual: &[f64],
    method: StepMethod,
    forcing: f64,
    cache: &mut NodeBlocks,
    hint: &KrylovHint,
) -> Result<Vec<f64>, String> {
    let mut d = Vec::new();
    let how = (method, forcing);
    direction_into(
        problem, sampler, c, slopes, residual, how, cache, hint, &mut d,
    )?;
    Ok(d)
}

/// `direction` into `d`, which with `cache` is all it writes: a Newton run that keeps both
/// allocates nothing in its steps after the first (issue #8, "no allocation in the loop").
#[allow(clippy::too_many_arguments)]
pub fn direction_into(
    problem: &ReducedProblem,
    sampler: &ContactSampler,
    c: f64,
    slopes: &[f64],
    residual: &[f64],
    (method, forcing): (StepMethod, f64),
    cache: &mut NodeBlocks,
    hint: &KrylovHint,
    d: &mut Vec<f64>,
) -> Result<(), String> {
    let (nc, h, n) = (problem.nodes, problem.harmonics, sampler.samples());
    cache.update(sampler, nc, c, slopes);
    let dense = |cache: &mut NodeBlocks, d: &mut Vec<f64>| {
        if dense_step_into(problem, c, cache, residual, d) {
            Ok(())
        } else {
            Err("the Newton matrix is singular".to_string())
        }
    };
    match resolve(method, nc, h, n) {
        StepMethod::Krylov => {
            let mut rhs = std::mem::take(&mut cache.scratch.rhs);
            rhs.clear();
            rhs.extend(residual.iter().map(|v| -v));
            let step = krylov_step(problem, c, slopes, &rhs, forcing, cache, hint, d);
            cache.scratch.rhs = rhs;
            step.or_else(|why| {
                if method == StepMethod::Auto && estimated_flops(nc, h, n).0 <= DENSE_FALLBACK {
                    dense(cache, d)
                } else {
                    Err(why)
                }
            })
        }
        _ => dense(cache, d),
    }
}

/// The parts of J that belong to one node and depend only on its slopes (and c): A_i and,
/// once a matrix-free step asks for it, the LU of I − A_i + c A_i G_ii. A Newton run keeps
/// them and recomputes a node's only when its slopes change, so once the active set settles
/// the last steps reuse every block (the same numbers: nothing is approximated).
#[derive(Default)]
pub struct NodeBlocks {
    c: f64,
    slopes: Vec<f64>,
    blocks: Vec<f64>,
    /// The LU of J_ii per node, valid where `factor_ready` and `regular` (a singular J_ii
    /// preconditions as the identity: GMRES converges, slower).
    factors: Vec<DenseLu>,
    regular: Vec<bool>,
    factor_ready: Vec<bool>,
    /// J_ii being factored, and what refactoring the node LUs reuses.
    node_block: Vec<f64>,
    node_work: DenseLuWork,
    /// The dense step's J and its LU's work (`dense_step_into`).
    dense: Option<(Mat<f64>, LuWork)>,
    /// The activity blocks' work space.
    sampling: SamplerWork,
    /// The Krylov steps' work arrays, sized at the first step and kept for the run.
    scratch: KrylovScratch,
}

/// What the matrix-free steps of a Newton run write into: the GMRES bases, the products'
/// buffers and the preconditioners' work vectors. One per run (in `NodeBlocks`), so the
/// steps and their restart cycles allocate nothing after the first.
struct KrylovScratch {
    gmres: GmresWork,
    products: ProductBuffers,
    /// The node blocks' single-precision solve vector (M).
    single: Vec<f32>,
    /// The harmonic blocks' phasors (n_c).
    phasors: Vec<c64>,
    /// The step's right-hand side −R, and the stalled solve's residual check.
    rhs: Vec<f64>,
    check: Vec<f64>,
    /// The harmonic blocks, refactored in place at the steps that use them.
    harmonic: HarmonicBlocks,
}

impl Default for KrylovScratch {
    fn default() -> Self {
        KrylovScratch {
            gmres: GmresWork::new(KRYLOV_RESTART),
            products: ProductBuffers::default(),
            single: Vec::new(),
            phasors: Vec::new(),
            rhs: Vec::new(),
            check: Vec::new(),
            harmonic: HarmonicBlocks::default(),
        }
    }
}

/// The buffers of one product with J: G v (node-major) and the phasors of one harmonic.
#[derive(Default)]
struct ProductBuffers {
    gv: Vec<f64>,
    phasors: Vec<c64>,
}

impl NodeBlocks {
    fn update(&mut self, sampler: &ContactSampler, nodes: usize, c: f64, slopes: &[f64]) {
        let (m, n) = (sampler.coefficients(), sampler.samples());
        if self.slopes.len() != slopes.len() || self.blocks.len() != nodes * m * m || self.c != c {
            *self = NodeBlocks {
                c,
                slopes: vec![f64::NAN; slopes.len()], // NaN equals nothing: all recomputed
                blocks: vec![0.0; nodes * m * m],
                factors: (0..nodes).map(|_| DenseLu::default()).collect(),
                regular: vec![false; nodes],
                factor_ready: vec![false; nodes],
                node_block: vec![0.0; m * m],
                node_work: std::mem::take(&mut self.node_work),
                dense: self.dense.take(),
                sampling: std::mem::take(&mut self.sampling),
                scratch: std::mem::take(&mut self.scratch),
            };
        }
        for i in 0..nodes {
            let (new, old) = (
                &slopes[i * n..(i + 1) * n],
                &mut self.slopes[i * n..(i + 1) * n],
            );
            if new != old {
                let block = &mut self.blocks[i * m * m..(i + 1) * m * m];
                sampler.activity_block_with(new, block, &mut self.sampling);
                old.copy_from_slice(new);
                self.factor_ready[i] = false;
            }
        }
    }

    fn refresh_factors(&mut self, problem: &ReducedProblem) {
        let m = problem.coefficients();
        for (i, ready) in self.factor_ready.iter_mut().enumerate() {
            if !*ready {
                let a_i = &self.blocks[i * m * m..(i + 1) * m * m];
                node_block(problem, self.c, i, a_i, &mut self.node_block);
                self.regular[i] =
                    self.factors[i].refactor(&self.node_block, m, &mut self.node_work);
                *ready = true;
            }
        }
    }
}

/// A_i for every node, concatenated (nc · M²).
pub fn activity_blocks(sampler: &ContactSampler, nodes: usize, slopes: &[f64]) -> Vec<f64> {
    let (m, n) = (sampler.coefficients(), sampler.samples());
    let mut blocks = vec![0.0; nodes * m * m];
    for i in 0..nodes {
        sampler.activity_block(
            &slopes[i * n..(i + 1) * n],
            &mut blocks[i * m * m..(i + 1) * m * m],
        );
    }
    blocks
}

/// The dense step into `d`: J assembled column-block by column-block (`dense_jacobian`)
/// from the node blocks of `cache` into its kept matrix, and solved by faer's LU with
/// partial pivoting; `false` when J is singular (a non-finite solution).
fn dense_step_into(
    problem: &ReducedProblem,
    c: f64,
    cache: &mut NodeBlocks,
    residual: &[f64],
    d: &mut Vec<f64>,
) -> bool {
    let dim = residual.len();
    let (jac, work) = cache
        .dense
        .get_or_insert_with(|| (Mat::zeros(dim, dim), LuWork::default()));
    if jac.nrows() != dim {
        *jac = Mat::zeros(dim, dim);
    }
    dense_jacobian_into(problem, c, &cache.blocks, jac);
    d.clear();
    d.extend(residual.iter().map(|v| -v));
    crate::linalg::dense_solve_with(jac.as_mut(), d, work);
    d.iter().all(|v| v.is_finite())
}

/// J = I − A + c A G formed densely, column block by column block (dim × dim).
pub fn dense_jacobian(problem: &ReducedProblem, c: f64, blocks: &[f64]) -> Mat<f64> {
    let dim = problem.nodes * problem.coefficients();
    let mut jac = Mat::<f64>::zeros(dim, dim);
    dense_jacobian_into(problem, c, blocks, &mut jac);
    jac
}

/// `dense_jacobian` into the dim × dim `jac`.
fn dense_jacobian_into(problem: &ReducedProblem, c: f64, blocks: &[f64], jac: &mut Mat<f64>) {
    let (nc, m) = (problem.nodes, problem.coefficients());
    jac.fill(0.0);
    jac.diagonal_mut().fill(1.0);
    for i in 0..nc {
        let a_i = &blocks[i * m * m..(i + 1) * m * m];
        for a in 0..m {
            let row = i * m + a;
            for bb in 0..m {
                let aval = a_i[a * m + bb];
                if aval == 0.0 {
                    continue;
                }
                jac[(row, i * m + bb)] -= aval;
                // c A_i G: G couples coefficient bb of node i with the coefficients of the
                // same harmonic of every node j.
                let k = harmonic_of(bb);
                let cols: &[usize] = if k == 0 { &[0] } else { &[2 * k - 1, 2 * k] };
                for j in 0..nc {
                    for &b in cols {
                        jac[(row, j * m + b)] += c * aval * problem.real_entry(i, bb, j, b);
                    }
                }
            }
        }
    }
}

/// The step without forming J: restarted flexible GMRES on J v = v − A v + c A G v, to the
/// forcing term, right-preconditioned by one of two approximations of J:
/// - the node blocks J_ii = I − A_i + c A_i G_ii solved by their LUs (`NodeBlocks`, factored
///   once per step at most): exact where the nodes do not couple, and what the reference
///   strip's impacts want;
/// - the harmonic blocks (`HarmonicBlocks`): exact where every node is closed or open all
///   period, what a contact patch pressed onto a wall wants (the half-disc at H = 40, where
///   the node blocks take hundreds of iterations per step or stall).
///
/// The solve starts with the one that served the last step (`KrylovHint`, the node blocks
/// at first) and runs restart cycle by restart cycle; a cycle that stalls (`STAGNATION`)
/// hands the solve, from where it is, to the other preconditioner, and whichever meets the
/// forcing term serves the next step first.
///
/// Products with A use the activity blocks A_i (an M × M product per node, cheaper than the
/// two FFTs of length N that Q D_i P takes, since M ≈ N/8), products with G go harmonic by
/// harmonic. Inexact Newton: the linear tolerance is the forcing term, loose because the
/// line search guards the step.
#[allow(clippy::too_many_arguments)]
fn krylov_step(
    problem: &ReducedProblem,
    c: f64,
    slopes: &[f64],
    rhs: &[f64],
    forcing: f64,
    cache: &mut NodeBlocks,
    hint: &KrylovHint,
    x: &mut Vec<f64>,
) -> Result<(), String> {
    x.clear();
    x.resize(rhs.len(), 0.0);
    let mut by_harmonics = hint.harmonic_first();
    let mut harmonic_ready = false;
    let system = KrylovSystem {
        problem,
        c,
        rhs,
        forcing,
    };
    // Each preconditioner's last cycle's gain (residual after / before), once it ran one.
    let (mut gains, mut last) = ([None::<f64>; 2], 1.0);
    for _ in 0..KRYLOV_CYCLES {
        let cycle = if by_harmonics {
            if !harmonic_ready {
                cache.scratch.harmonic.refactor(problem, c, slopes);
                harmonic_ready = true;
            }
            harmonic_cycle(&system, cache, x)
        } else {
            cache.refresh_factors(problem);
            node_cycle(&system, cache, x)
        };
        let after = match cycle {
            Ok(()) => {
                hint.set_harmonic_first(by_harmonics);
                return Ok(());
            }
            Err(after) => after,
        };
        let gain = after / last;
        (gains[usize::from(by_harmonics)], last) = (Some(gain), after);
        let other = gains[usize::from(!by_harmonics)];
        if gain > STAGNATION && other.is_none_or(|o| o < gain) {
            by_harmonics = !by_harmonics;
        }
    }
    let (blocks, scratch) = (&cache.blocks, &mut cache.scratch);
    let mut apply_j = jacobian_product(problem, c, blocks, &mut scratch.products);
    loose_or_stalled(&mut apply_j, rhs, x, last, &mut scratch.check)
}

/// The linear system of one Newton step, J d = `rhs` to the relative residual `forcing`.
struct KrylovSystem<'a> {
    problem: &'a ReducedProblem,
    c: f64,
    rhs: &'a [f64],
    forcing: f64,
}

/// GMRES iterations per restart cycle.
const KRYLOV_RESTART: usize = 60;
/// Restart cycles of length `KRYLOV_RESTART` that a Newton step's GMRES may take in all.
const KRYLOV_CYCLES: usize = 20;
/// A restart cycle that leaves more than this share of the residual it started from has
/// stalled: the next cycle goes to the other preconditioner, unless that one's last cycle
/// gained less. On the half-disc at H = 40 the node blocks' cycles after the first keep
/// 0.4–0.96 of the residual, where the harmonic blocks meet the forcing term in one; on the
/// reference strip the node blocks' cycles that do not converge gain more than the harmonic
/// blocks' (measured on the 0.5%-damped strip at H = 80, where a switch after two cycles
/// made the harmonic blocks run out of cycles at 10⁻³–10⁻² on nine steps).
const STAGNATION: f64 = 0.5;

/// Which preconditioner the Krylov steps of a chain of Newton runs start with
/// (`krylov_step`): the node blocks until the harmonic blocks served a step they missed,
/// and back. Clones share it, so the runs of one solve (a continuation's levels, its damping
/// levels and ladder rungs) each start with the one that served the last, and pay for the
/// other's missed cycles once, not once per run.
#[derive(Clone, Debug, Default)]
pub struct KrylovHint(std::sync::Arc<std::sync::atomic::AtomicBool>);

impl KrylovHint {
    /// The next Krylov steps start with the harmonic blocks (else the node blocks).
    pub fn harmonic_first(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Start the next Krylov steps with the harmonic blocks (`true`) or the node blocks.
    pub fn set_harmonic_first(&self, yes: bool) {
        self.0.store(yes, std::sync::atomic::Ordering::Relaxed);
    }

    /// A hint of its own that starts where this one is: for runs side by side (the knob
    /// checks), which must not steer each other (their paths would depend on timing).
    pub fn detached(&self) -> KrylovHint {
        let start = std::sync::atomic::AtomicBool::new(self.harmonic_first());
        KrylovHint(std::sync::Arc::new(start))
    }
}

/// One GMRES restart cycle from `x` preconditioned by the node blocks (their LUs current).
fn node_cycle(system: &KrylovSystem, cache: &mut NodeBlocks, x: &mut [f64]) -> Result<(), f64> {
    let m = system.problem.coefficients();
    let NodeBlocks {
        blocks,
        factors,
        regular,
        scratch,
        ..
    } = cache;
    let KrylovScratch {
        gmres,
        products,
        single,
        ..
    } = scratch;
    single.resize(m, 0.0);
    let mut precondition = |v: &[f64], out: &mut [f64]| {
        out.copy_from_slice(v);
        for ((lu, &regular), x) in factors
            .iter()
            .zip(regular.iter())
            .zip(out.chunks_exact_mut(m))
        {
            if regular {
                lu.solve_in_place(x, single);
            }
        }
    };
    one_cycle(system, blocks, &mut precondition, x, gmres, products)
}

/// One GMRES restart cycle from `x` preconditioned by the harmonic blocks of `cache`
/// (current).
fn harmonic_cycle(system: &KrylovSystem, cache: &mut NodeBlocks, x: &mut [f64]) -> Result<(), f64> {
    let m = system.problem.coefficients();
    let NodeBlocks {
        blocks, scratch, ..
    } = cache;
    let KrylovScratch {
        gmres,
        products,
        phasors,
        harmonic,
        ..
    } = scratch;
    let mut precondition = |v: &[f64], out: &mut [f64]| {
        out.copy_from_slice(v);
        harmonic.solve_in_place(m, out, phasors);
    };
    one_cycle(system, blocks, &mut precondition, x, gmres, products)
}

/// One GMRES restart cycle on `system` from `x`, with `precondition`.
fn one_cycle(
    system: &KrylovSystem,
    blocks: &[f64],
    precondition: &mut dyn FnMut(&[f64], &mut [f64]),
    x: &mut [f64],
    gmres: &mut GmresWork,
    products: &mut ProductBuffers,
) -> Result<(), f64> {
    let mut apply_j = jacobian_product(system.problem, system.c, blocks, products);
    gmres.cycles(&mut apply_j, precondition, system.rhs, x, system.forcing, 1)
}

/// v ↦ J v = v − A v + c A G v: G harmonic by harmonic, A through the activity blocks,
/// written through `buffers`.
fn jacobian_product<'a>(
    problem: &'a ReducedProblem,
    c: f64,
    blocks: &'a [f64],
    buffers: &'a mut ProductBuffers,
) -> impl FnMut(&[f64], &mut [f64]) + 'a {
    let m = problem.coefficients();
    let ProductBuffers { gv, phasors } = buffers;
    gv.resize(problem.nodes * m, 0.0);
    move |v: &[f64], out: &mut [f64]| {
        problem.compliance_product(v, gv, phasors);
        for (g, x) in gv.iter_mut().zip(v) {
            *g = c * *g - x;
        }
        out.copy_from_slice(v);
        block_products(blocks, m, gv, out);
    }
}

/// J with every node's activity A_i replaced by its mean slope a_i (the time average of its
/// slopes): P = I − ā + c ā G, ā = diag(a) ⊗ I_M, which is block-diagonal in the harmonics,
/// P_k = I − diag(a) + c diag(a) G_k on harmonic k's phasors, one complex n_c × n_c LU each.
/// P = J exactly where every node is closed all period or open all period (A_i = I or 0): a
/// contact patch pressed onto a wall, whose nodes G couples strongly and the node blocks
/// ignore; only the nodes at the patch's edge, which open and close, make P approximate.
#[derive(Default)]
pub struct HarmonicBlocks {
    /// P_k's LU in place (L unit lower below the diagonal, U on and above), per harmonic,
    /// and its row permutation (forward, backward).
    lus: Vec<Mat<c64>>,
    perms: Vec<(Vec<usize>, Vec<usize>)>,
    /// The nodes' mean slopes, and the LU's and the solves' work space (faer's
    /// `Solve::solve_in_place` allocates its own on every call: H + 1 times per GMRES
    /// iteration).
    mean: Vec<f64>,
    work: LuWork,
}

impl HarmonicBlocks {
    /// The LUs of P_k at the nodes' slopes `slopes` (node-major, N per node).
    pub fn new(problem: &ReducedProblem, c: f64, slopes: &[f64]) -> Self {
        let mut blocks = HarmonicBlocks::default();
        blocks.refactor(problem, c, slopes);
        blocks
    }

    /// `new` in place: nothing is allocated once these blocks held the same problem's.
    pub fn refactor(&mut self, problem: &ReducedProblem, c: f64, slopes: &[f64]) {
        let nc = problem.nodes;
        let samples = slopes.len() / nc.max(1);
        self.mean.clear();
        self.mean.extend(
            slopes
                .chunks_exact(samples.max(1))
                .map(|s| s.iter().sum::<f64>() / samples as f64),
        );
        let harmonics = problem.compliance.len();
        if self.lus.len() != harmonics || self.lus.first().is_some_and(|l| l.nrows() != nc) {
            self.lus = (0..harmonics).map(|_| Mat::zeros(nc, nc)).collect();
            self.perms = (0..harmonics).map(|_| (vec![0; nc], vec![0; nc])).collect();
        }
        // The parallelism faer's `PartialPivLu` factors with, which these replace.
        let par = faer::get_global_parallelism();
        self.work.size::<c64>(nc, par);
        for ((gk, lu), (forward, backward)) in problem
            .compliance
            .iter()
            .zip(&mut self.lus)
            .zip(&mut self.perms)
        {
            for j in 0..nc {
                for (i, p) in lu.col_mut(j).iter_mut().enumerate() {
                    let own = if i == j { 1.0 - self.mean[i] } else { 0.0 };
                    *p = c64::new(own, 0.0) + gk[i * nc + j] * (c * self.mean[i]);
                }
            }
            crate::linalg::dense_lu_with(lu.as_mut(), par, &mut self.work);
            forward.copy_from_slice(&self.work.forward);
            backward.copy_from_slice(&self.work.backward);
        }
    }

    /// x ← P⁻¹ x harmonic by harmonic (`x` node-major, `m` coefficients per node); a harmonic
    /// whose solve is not finite (a singular P_k) is left as it is, the identity there.
    pub fn solve_in_place(&mut self, m: usize, x: &mut [f64], phasors: &mut Vec<c64>) {
        use faer::linalg::lu::partial_pivoting::solve::solve_in_place;
        let nc = x.len() / m;
        phasors.resize(nc, c64::new(0.0, 0.0));
        let stack = self.work.stack();
        for (k, (lu, (forward, backward))) in self.lus.iter().zip(&self.perms).enumerate() {
            for (z, xi) in phasors.iter_mut().zip(x.chunks_exact(m)) {
                *z = phasor(xi, k);
            }
            let rhs = faer::MatMut::from_column_major_slice_mut(phasors, nc, 1);
            let perm = faer::perm::PermRef::new_checked(forward, backward, nc);
            solve_in_place(
                lu.as_ref(),
                lu.as_ref(),
                perm,
                rhs,
                faer::Par::Seq,
                &mut *stack,
            );
            if phasors.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
                for (z, xi) in phasors.iter().zip(x.chunks_exact_mut(m)) {
                    set_phasor(xi, k, *z);
                }
            }
        }
    }
}

/// out_i += B_i x_i for the row-major M × M blocks B_i of every node, by faer's
/// matrix–vector product on the calling thread.
fn block_products(blocks: &[f64], m: usize, x: &[f64], out: &mut [f64]) {
    use faer::linalg::matmul::matmul;
    use faer::{Accum, MatMut, MatRef, Par};
    for ((b, xi), oi) in blocks
        .chunks_exact(m * m)
        .zip(x.chunks_exact(m))
        .zip(out.chunks_exact_mut(m))
    {
        matmul(
            MatMut::from_column_major_slice_mut(oi, m, 1),
            Accum::Add,
            MatRef::from_row_major_slice(b, m, m),
            MatRef::from_column_major_slice(xi, m, 1),
            1.0,
            Par::Seq,
        );
    }
}

/// J_ii = I − A_i + c A_i G_ii (row-major). G_ii couples only the cosine and sine of one
/// harmonic, as the real 2 × 2 block [[Re g, Im g], [−Im g, Re g]] of g = G_k[i, i] (1 × 1
/// for the constant), so A_i G_ii costs 4 M² instead of M³.
fn node_block(problem: &ReducedProblem, c: f64, i: usize, a_i: &[f64], out: &mut [f64]) {
    let m = problem.coefficients();
    for (o, a) in out.iter_mut().zip(a_i) {
        *o = -a;
    }
    for d in 0..m {
        out[d * m + d] += 1.0;
    }
    let g = |k: usize| c * problem.compliance[k][i * problem.nodes + i];
    for (row, out) in a_i.chunks_exact(m).zip(out.chunks_exact_mut(m)) {
        out[0] += row[0] * g(0).re;
        let pairs = row[1..].chunks_exact(2).zip(out[1..].chunks_exact_mut(2));
        for (k, (a, o)) in pairs.enumerate() {
            let gk = g(k + 1);
            // a = (cos, sin) entries of harmonic k in this row of A_i.
            o[0] += a[0] * gk.re - a[1] * gk.im;
            o[1] += a[0] * gk.im + a[1] * gk.re;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: the cost model picks the matrix-free step where it was measured to be as
    /// fast or faster (reference strip, 9 nodes, H = 5…40 at N = 16H: docs/method.md §7) and
    /// the dense LU for a single node with few harmonics, where the node block is all of J.
    #[test]
    fn the_step_method_follows_the_measured_costs() {
        for h in [5usize, 10, 20, 40] {
            let n = (16 * h).max(64);
            assert_eq!(
                resolve(StepMethod::Auto, 9, h, n),
                StepMethod::Krylov,
                "H = {h}"
            );
        }
        assert_eq!(resolve(StepMethod::Auto, 1, 3, 64), StepMethod::Dense);
        assert_eq!(resolve(StepMethod::Dense, 9, 40, 640), StepMethod::Dense);
    }

    /// TEST GOAL: the forcing term is 1e-4 far from the solution, O(r) near it, and never asks
    /// for much more than the tolerance needs of the next iterate.
    #[test]
    fn forcing_is_capped_proportional_and_floored_by_the_tolerance() {
        assert_eq!(forcing(0.4, 1e-8), 1e-4);
        assert_eq!(forcing(5e-5, 1e-8), 5e-5);
        // 0.1 τ / r: solving to 1e-4 from r = 1e-5 already leaves 1e-9 = 0.1 τ.
        assert!((forcing(1e-5, 1e-8) - 1e-4).abs() < 1e-18);
        assert_eq!(forcing(1e-7, 1e-8), 1e-4);
    }

    /// A coupled problem: `nodes` nodes whose compliance G_k couples them all (a contact
    /// patch's), complex symmetric per harmonic, diagonally heavier.
    fn patch(nodes: usize, harmonics: usize) -> ReducedProblem {
        ReducedProblem::from_compliance(nodes, harmonics, |k, i, j| {
            let d = (i as f64 - j as f64).abs();
            let re = 1.0 / (1.0 + d) / (1.0 + k as f64);
            c64::new(re, 0.05 * k as f64 * re)
        })
    }

    /// TEST GOAL: the harmonic blocks invert J exactly when every node is closed all period
    /// or open all period (A_i = I or 0: J = I − ā + c ā G is then block-diagonal in the
    /// harmonics), however strongly G couples the nodes; with one node opening and closing
    /// within the period they are only an approximation (the node's A_i ≠ a_i I).
    #[test]
    fn harmonic_blocks_invert_the_jacobian_of_a_patch_closed_or_open_all_period() {
        let (nc, h, n, c) = (6, 4, 32, 3.0);
        let problem = patch(nc, h);
        let sampler = problem.sampler(n);
        let m = problem.coefficients();
        let v: Vec<f64> = (0..nc * m)
            .map(|r| ((r * 7 + 3) % 11) as f64 - 5.0)
            .collect();
        let error = |slopes: &[f64]| {
            let blocks = activity_blocks(&sampler, nc, slopes);
            let mut jv = vec![0.0; nc * m];
            jacobian_product(&problem, c, &blocks, &mut ProductBuffers::default())(&v, &mut jv);
            HarmonicBlocks::new(&problem, c, slopes).solve_in_place(m, &mut jv, &mut Vec::new());
            let d: f64 = jv.iter().zip(&v).map(|(a, b)| (a - b).powi(2)).sum();
            (d / v.iter().map(|a| a * a).sum::<f64>()).sqrt()
        };
        // Nodes 0–2 closed all period, 3–5 open.
        let pure: Vec<f64> = (0..nc * n)
            .map(|r| f64::from(u8::from(r / n < 3)))
            .collect();
        let exact = error(&pure);
        assert!(exact < 1e-12, "{exact:e}");
        // Node 2 closed for the first half of the period only.
        let mut mixed = pure.clone();
        mixed[2 * n + n / 2..3 * n].fill(0.0);
        let approximate = error(&mixed);
        assert!(approximate > 1e-3, "{approximate:e}");
    }

    /// TEST GOAL: a detached hint starts where its source is and then goes its own way (the
    /// knob checks' side-by-side re-solves do not steer each other), while clones share one.
    #[test]
    fn a_detached_hint_starts_from_its_source_and_clones_share() {
        let hint = KrylovHint::default();
        hint.set_harmonic_first(true);
        let (copy, shared) = (hint.detached(), hint.clone());
        assert!(copy.harmonic_first());
        copy.set_harmonic_first(false);
        assert!(hint.harmonic_first());
        shared.set_harmonic_first(false);
        assert!(!hint.harmonic_first());
    }

    /// TEST GOAL: the Krylov step meets the forcing term on a coupled patch with nodes that
    /// open and close, from either preconditioner first, and the hint then names one that
    /// met it; J d = −R holds to the forcing term.
    #[test]
    fn the_krylov_step_meets_the_forcing_term_from_either_preconditioner() {
        let (nc, h, n, c) = (8, 5, 48, 2.0);
        let problem = patch(nc, h);
        let sampler = problem.sampler(n);
        let m = problem.coefficients();
        let slopes: Vec<f64> = (0..nc * n)
            .map(|r| f64::from(u8::from((r % n) < n * (r / n + 1) / (nc + 1))))
            .collect();
        let rhs: Vec<f64> = (0..nc * m)
            .map(|r| ((r * 5 + 1) % 13) as f64 - 6.0)
            .collect();
        for harmonic_first in [false, true] {
            let hint = KrylovHint::default();
            hint.set_harmonic_first(harmonic_first);
            let mut cache = NodeBlocks::default();
            cache.update(&sampler, nc, c, &slopes);
            let forcing = 1e-8;
            let mut d = Vec::new();
            krylov_step(
                &problem, c, &slopes, &rhs, forcing, &mut cache, &hint, &mut d,
            )
            .expect("converges");
            let mut jd = vec![0.0; nc * m];
            jacobian_product(&problem, c, &cache.blocks, &mut ProductBuffers::default())(
                &d, &mut jd,
            );
            let r: f64 = jd
                .iter()
                .zip(&rhs)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            let b: f64 = crate::linalg::norm2(&rhs);
            assert!(
                r <= 2.0 * forcing * b,
                "first {harmonic_first}: {:e}",
                r / b
            );
        }
    }
}
