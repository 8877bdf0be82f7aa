//! Allocation counts of the contact Newton's run and of its matrix-free step (issue #8: "no
//! allocation in the loop"). This test binary counts the heap allocations of its own thread through a
//! counting global allocator, which needs `unsafe impl GlobalAlloc`: the only way to observe
//! allocations, and it forwards every call to the system allocator unchanged.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use faer::c64;
use hbcontact::hbm::problem::ReducedProblem;
use hbcontact::hbm::step::{self, KrylovHint, NodeBlocks, StepMethod};

thread_local! {
    /// Allocations (and reallocations) made by this thread so far.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

struct Counting;

fn count() {
    // `try_with`: a thread being torn down has no counter left, and needs none.
    let _ = ALLOCATIONS.try_with(|a| a.set(a.get() + 1));
}

// SAFETY: every method forwards to `System` with the caller's arguments, which meet
// `GlobalAlloc`'s contract because the caller's do; the counter is a plain thread-local
// `Cell<usize>` with a const initializer, which allocates nothing and never dangles.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

/// A patch of `nodes` contact nodes whose compliance couples every pair strongly, slowly
/// weaker with distance and harmonic (the shape of a pressed Hertz patch's G_k), which the
/// node blocks ignore: their GMRES needs several restart cycles.
fn patch(nodes: usize, harmonics: usize) -> ReducedProblem {
    ReducedProblem::from_compliance(nodes, harmonics, |k, i, j| {
        let d = (i as f64 - j as f64).abs();
        let re = 1.0 / (1.0 + 0.1 * d) / (1.0 + k as f64);
        c64::new(re, 0.05 * k as f64 * re)
    })
}

/// ‖J d + R‖ / ‖R‖ with J formed densely (`step::dense_jacobian`).
fn relative_residual(
    problem: &ReducedProblem,
    c: f64,
    blocks: &[f64],
    d: &[f64],
    r: &[f64],
) -> f64 {
    let j = step::dense_jacobian(problem, c, blocks);
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let jd_r: Vec<f64> = (0..r.len())
        .map(|row| (0..d.len()).map(|col| j[(row, col)] * d[col]).sum::<f64>() + r[row])
        .collect();
    norm(&jd_r) / norm(r)
}

/// TEST GOAL: a Newton step's matrix-free solve allocates the same number of buffers
/// whether its GMRES takes a few iterations or hundreds over several restart cycles, with
/// either preconditioner (at 1e-13 the node blocks took 4 restart cycles of 60, the
/// harmonic blocks first 13, handing over between the two): the Krylov bases, the products' and the preconditioners' buffers
/// live in the Newton run's `NodeBlocks`, sized by its first step (issue #8: "no allocation
/// in the loop"; docs/method.md §7, "The linear step"). Before, every restart cycle
/// allocated its bases (≈ 121 vectors of n_c M: 10 MB per cycle on the half-disc at H = 80).
#[test]
fn a_krylov_steps_allocations_do_not_grow_with_its_iterations() {
    let (nc, h, n, c) = (12, 30, 256, 4.0);
    let problem = patch(nc, h);
    let sampler = problem.sampler(n);
    let m = problem.coefficients();
    // Nodes closed over a share of the period growing along the patch: the node blocks
    // miss the coupling, the harmonic blocks the opening and closing.
    let slopes: Vec<f64> = (0..nc * n)
        .map(|r| f64::from(u8::from((r % n) < n * (r / n + 1) / (nc + 2))))
        .collect();
    let residual: Vec<f64> = (0..nc * m)
        .map(|r| ((r * 5 + 1) % 13) as f64 - 6.0)
        .collect();
    let blocks = step::activity_blocks(&sampler, nc, &slopes);
    for harmonic_first in [false, true] {
        let hint = KrylovHint::default();
        let mut cache = NodeBlocks::default();
        let step = |forcing: f64, cache: &mut NodeBlocks| {
            hint.set_harmonic_first(harmonic_first);
            let before = allocations();
            let d = step::direction(
                &problem,
                &sampler,
                c,
                &slopes,
                &residual,
                StepMethod::Krylov,
                forcing,
                cache,
                &hint,
            )
            .expect("the step converges");
            (allocations() - before, d)
        };
        // The run's first step sizes the buffers and factors the node blocks.
        step(1e-2, &mut cache);
        let (loose, d_loose) = step(1e-1, &mut cache);
        let (tight, d_tight) = step(1e-13, &mut cache);
        let (r_loose, r_tight) = (
            relative_residual(&problem, c, &blocks, &d_loose, &residual),
            relative_residual(&problem, c, &blocks, &d_tight, &residual),
        );
        println!(
            "harmonic blocks first {harmonic_first}: {loose} and {tight} allocations at \
             residuals {r_loose:.1e} and {r_tight:.1e}"
        );
        // The two solves did different amounts of GMRES work...
        assert!(r_loose > 1e-6 && r_tight < 1e-11, "{r_loose:e} {r_tight:e}");
        // ...with the same allocations: the returned step's, none per iteration or cycle
        // (the harmonic blocks are refactored in place).
        assert_eq!(loose, tight, "harmonic blocks first {harmonic_first}");
        assert!(tight <= 1, "{tight}");
    }
}

/// A patch pressed `depth` into its obstacle over part of the period: a mean penetration
/// with a first harmonic, so that each node is closed over part of it.
fn pressed(nodes: usize, harmonics: usize, depth: f64) -> ReducedProblem {
    let mut problem = patch(nodes, harmonics);
    let m = problem.coefficients();
    for i in 0..nodes {
        problem.linear_gap[i * m] = depth * (0.2 + 0.05 * i as f64);
        problem.linear_gap[i * m + 1] = depth;
    }
    problem
}

/// TEST GOAL: a whole Newton run allocates nothing per iteration (issue #8: "no allocation
/// in the loop"): a run of 12 iterations allocates exactly as many buffers as one of 4, on
/// the smoothed and the exact law, with the dense and the matrix-free step. The evaluations
/// of the residual (and the line search's trials), the step, the dense Jacobian and its LU,
/// the node blocks' LUs, the harmonic blocks and the iteration log are all sized by the
/// run's start or its first step and reused. Before, every iteration allocated the gap, the
/// residual, the slopes and one vector per contact node in each evaluation, the step, the
/// LU of each node block whose slopes changed, and the dense path's J.
#[test]
fn a_newton_runs_allocations_do_not_grow_with_its_iterations() {
    use hbcontact::hbm::reduced::{self, NewtonSettings};
    let (nc, h) = (6, 8);
    let problem = pressed(nc, h, 1.0);
    let start = vec![0.0; nc * problem.coefficients()];
    for method in [StepMethod::Dense, StepMethod::Krylov] {
        for smoothing in [0.0, 0.05] {
            let run = |iterations: usize| {
                let settings = NewtonSettings {
                    samples: 64,
                    c: 1.0,
                    // Unreachable: every run takes its max_iterations (forced steps
                    // included), unless its line search stalls for good.
                    tolerance: 0.0,
                    max_iterations: iterations,
                    method,
                    smoothing,
                    ..Default::default()
                };
                let before = allocations();
                let o = reduced::newton(&problem, &settings, &start, &hbcontact::Silent);
                (allocations() - before, o)
            };
            // A first run pays the process's one-time set-ups (FFT plans, the SIMD
            // dispatch), which the runs compared do not.
            run(2);
            let ((short, a), (long, b)) = (run(4), run(12));
            println!(
                "{method:?}, mu = {smoothing}: {short} allocations in {} iterations, {long} in {} \
                 (residuals {:.1e}, {:.1e})",
                a.iterations, b.iterations, a.relative_residual, b.relative_residual
            );
            assert_eq!((a.iterations, b.iterations), (4, 12), "{}", b.reason);
            assert!(b.relative_residual < 1e-8, "{}", b.relative_residual);
            assert_eq!(short, long, "{method:?}, mu = {smoothing}");
        }
    }
}
