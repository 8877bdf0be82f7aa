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

use faer::{c64, Mat};
use num_complex::Complex64;

use super::fourier::{cos_index, harmonic_of, sin_index, Sampler};
use super::reduced::ReducedProblem;
use super::sampler::ContactSampler;
use crate::linalg::{gmres, DenseLu};

/// GMRES iterations the cost model assumes per Newton step (measured: 10–40 on the strip and
/// the half-disc with the node-block preconditioner).
const ASSUMED_KRYLOV_ITERATIONS: f64 = 40.0;

/// A stalled GMRES falls back to the dense step below this many flops (≈ 1–3 s on 2 cores):
/// the node-block preconditioner ignores the coupling between nodes, which is strong where
/// one face strikes a wall.
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

/// A_i = Q diag(s) P (M × M, row-major) from the slopes `s` at the N samples, Fourier basis
/// (a spline basis forms it in `sampler`).
pub fn activity_block(sampler: &Sampler, slopes: &[f64], out: &mut [f64]) {
    let (h, n) = (sampler.harmonics, sampler.samples);
    let m = 2 * h + 1;
    let mut spectrum: Vec<Complex64> = slopes.iter().map(|&v| Complex64::new(v, 0.0)).collect();
    sampler.forward_in_place(&mut spectrum);
    // Ĉ_j = mean(s cos jθ) and Ŝ_j = mean(s sin jθ) for j = 0..2H (2H < N); Ĉ is even in j,
    // Ŝ odd.
    let scale = 1.0 / n as f64;
    let c_table: Vec<f64> = spectrum[..=2 * h].iter().map(|z| z.re * scale).collect();
    let s_table: Vec<f64> = spectrum[..=2 * h].iter().map(|z| -z.im * scale).collect();
    let c_hat = |j: i64| c_table[j.unsigned_abs() as usize];
    let s_hat = |j: i64| s_table[j.unsigned_abs() as usize] * j.signum() as f64;
    // Basis p_a: index 0 the constant (cos 0θ), 2k−1 cos kθ, 2k sin kθ; harmonics p (rows)
    // and q (columns) fill their cos/sin block, weight 1 for the constant's row, else 2.
    for p in 0..=h {
        let weight = if p == 0 { 1.0 } else { 2.0 };
        for q in 0..=h {
            let (pi, qi) = (p as i64, q as i64);
            let (difference, sum) = (pi - qi, pi + qi);
            let cos_cos = 0.5 * (c_hat(difference) + c_hat(sum));
            let cos_sin = 0.5 * (s_hat(sum) - s_hat(difference));
            out[cos_index(p) * m + cos_index(q)] = weight * cos_cos;
            if q > 0 {
                out[cos_index(p) * m + sin_index(q)] = weight * cos_sin;
            }
            if p > 0 {
                let sin_cos = 0.5 * (s_hat(sum) + s_hat(difference));
                out[sin_index(p) * m + cos_index(q)] = weight * sin_cos;
                if q > 0 {
                    let sin_sin = 0.5 * (c_hat(difference) - c_hat(sum));
                    out[sin_index(p) * m + sin_index(q)] = weight * sin_sin;
                }
            }
        }
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
) -> Result<Vec<f64>, String> {
    let (nc, h, n) = (problem.nodes, problem.harmonics, sampler.samples());
    cache.update(sampler, nc, c, slopes);
    let dense = |blocks: &[f64]| {
        dense_step(problem, c, blocks, residual)
            .ok_or_else(|| "the Newton matrix is singular".to_string())
    };
    match resolve(method, nc, h, n) {
        StepMethod::Krylov => {
            cache.refresh_factors(problem);
            let (blocks, factors) = (&cache.blocks, &cache.factors);
            krylov_step(problem, c, blocks, factors, residual, forcing).or_else(|why| {
                if method == StepMethod::Auto && estimated_flops(nc, h, n).0 <= DENSE_FALLBACK {
                    dense(&cache.blocks)
                } else {
                    Err(why)
                }
            })
        }
        _ => dense(&cache.blocks),
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
    /// The LU of J_ii per node, valid where `factor_ready`; `None` for a singular J_ii,
    /// which preconditions as the identity (GMRES converges, slower).
    factors: Vec<Option<DenseLu>>,
    factor_ready: Vec<bool>,
}

impl NodeBlocks {
    fn update(&mut self, sampler: &ContactSampler, nodes: usize, c: f64, slopes: &[f64]) {
        let (m, n) = (sampler.coefficients(), sampler.samples());
        if self.slopes.len() != slopes.len() || self.blocks.len() != nodes * m * m || self.c != c {
            *self = NodeBlocks {
                c,
                slopes: vec![f64::NAN; slopes.len()], // NaN equals nothing: all recomputed
                blocks: vec![0.0; nodes * m * m],
                factors: (0..nodes).map(|_| None).collect(),
                factor_ready: vec![false; nodes],
            };
        }
        for i in 0..nodes {
            let (new, old) = (
                &slopes[i * n..(i + 1) * n],
                &mut self.slopes[i * n..(i + 1) * n],
            );
            if new != old {
                sampler.activity_block(new, &mut self.blocks[i * m * m..(i + 1) * m * m]);
                old.copy_from_slice(new);
                self.factor_ready[i] = false;
            }
        }
    }

    fn refresh_factors(&mut self, problem: &ReducedProblem) {
        let m = problem.coefficients();
        for (i, ready) in self.factor_ready.iter_mut().enumerate() {
            if !*ready {
                let block =
                    node_block(problem, self.c, i, &self.blocks[i * m * m..(i + 1) * m * m]);
                self.factors[i] = DenseLu::new(&block, m);
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

/// The dense step: J assembled column-block by column-block and factored by faer's LU with
/// partial pivoting. `None` when J is singular (a non-finite solution).
pub fn dense_step(
    problem: &ReducedProblem,
    c: f64,
    blocks: &[f64],
    residual: &[f64],
) -> Option<Vec<f64>> {
    let jac = dense_jacobian(problem, c, blocks);
    let dim = jac.nrows();
    let rhs = Mat::<f64>::from_fn(dim, 1, |r, _| -residual[r]);
    let x = crate::linalg::dense_solve(jac, rhs);
    let out: Vec<f64> = (0..dim).map(|r| x[(r, 0)]).collect();
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// J = I − A + c A G formed densely, column block by column block (dim × dim).
pub fn dense_jacobian(problem: &ReducedProblem, c: f64, blocks: &[f64]) -> Mat<f64> {
    let (nc, m) = (problem.nodes, problem.coefficients());
    let dim = nc * m;
    let mut jac = Mat::<f64>::identity(dim, dim);
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
    jac
}

/// The step without forming J: restarted GMRES on J v = v − A v + c A G v, right-
/// preconditioned by J's node-diagonal blocks J_ii = I − A_i + c A_i G_ii solved by their LUs
/// (`NodeBlocks`, factored once per step at most). Products with A use the activity blocks A_i
/// (an M × M product per node, cheaper than the two FFTs of length N that Q D_i P takes, since
/// M ≈ N/8), products with G go harmonic by harmonic: a GMRES iteration costs an M × M
/// product and two M × M triangular solves per node and one n_c × n_c product per harmonic.
/// Inexact Newton: the linear tolerance is the forcing term, loose because the line search
/// guards the step.
fn krylov_step(
    problem: &ReducedProblem,
    c: f64,
    blocks: &[f64],
    factors: &[Option<DenseLu>],
    residual: &[f64],
    forcing: f64,
) -> Result<Vec<f64>, String> {
    let m = problem.coefficients();
    let (mut gv, mut lam) = (vec![0.0; residual.len()], Vec::new());
    let mut apply_j = |v: &[f64], out: &mut [f64]| {
        problem.compliance_product(v, &mut gv, &mut lam);
        for (g, x) in gv.iter_mut().zip(v) {
            *g = c * *g - x;
        }
        out.copy_from_slice(v);
        block_products(blocks, m, &gv, out);
    };
    let mut work = vec![0.0f32; m];
    let mut precondition = |v: &[f64], out: &mut [f64]| {
        out.copy_from_slice(v);
        for (lu, x) in factors.iter().zip(out.chunks_exact_mut(m)) {
            if let Some(lu) = lu {
                lu.solve_in_place(x, &mut work);
            }
        }
    };
    let rhs: Vec<f64> = residual.iter().map(|v| -v).collect();
    gmres(&mut apply_j, &mut precondition, &rhs, forcing, 60, 20)
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
fn node_block(problem: &ReducedProblem, c: f64, i: usize, a_i: &[f64]) -> Vec<f64> {
    let m = problem.coefficients();
    let mut out: Vec<f64> = a_i.iter().map(|a| -a).collect();
    for d in 0..m {
        out[d * m + d] += 1.0;
    }
    let g: Vec<c64> = (0..=(m - 1) / 2)
        .map(|k| c * problem.compliance[k][i * problem.nodes + i])
        .collect();
    for (row, out) in a_i.chunks_exact(m).zip(out.chunks_exact_mut(m)) {
        out[0] += row[0] * g[0].re;
        let pairs = row[1..].chunks_exact(2).zip(out[1..].chunks_exact_mut(2));
        for ((a, o), gk) in pairs.zip(&g[1..]) {
            // a = (cos, sin) entries of harmonic k in this row of A_i.
            o[0] += a[0] * gk.re - a[1] * gk.im;
            o[1] += a[0] * gk.im + a[1] * gk.re;
        }
    }
    out
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

    /// TEST GOAL: the activity block from the slopes' Fourier sums equals Q diag(s) P formed
    /// densely, for 0/1 and smoothed slopes (the trigonometric product identities, exact on
    /// the samples because 2H < N).
    #[test]
    fn activity_block_from_spectrum_equals_dense_q_s_p() {
        for (h, n) in [(0usize, 1usize), (1, 3), (3, 16), (5, 11), (8, 128)] {
            let sampler = Sampler::new(h, n);
            let m = 2 * h + 1;
            let (p, q) = (sampler.p_matrix(), sampler.q_matrix());
            for smooth in [false, true] {
                let slopes: Vec<f64> = (0..n)
                    .map(|s| {
                        let x = ((s * 37 + 11) % 17) as f64 / 17.0;
                        if smooth {
                            x
                        } else {
                            (x > 0.4) as u8 as f64
                        }
                    })
                    .collect();
                let mut fast = vec![0.0; m * m];
                activity_block(&sampler, &slopes, &mut fast);
                for a in 0..m {
                    for b in 0..m {
                        let dense: f64 = (0..n)
                            .map(|s| q[a * n + s] * slopes[s] * p[s * m + b])
                            .sum();
                        assert!(
                            (dense - fast[a * m + b]).abs() < 1e-12,
                            "H = {h}, N = {n}, ({a}, {b}): {dense} vs {}",
                            fast[a * m + b]
                        );
                    }
                }
            }
        }
    }
}
