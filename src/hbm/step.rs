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

use faer::linalg::solvers::Solve;
use faer::Mat;
use nalgebra::DMatrix;
use num_complex::Complex64;

use super::fourier::{harmonic_of, Sampler};
use super::reduced::ReducedProblem;
use super::sampler::ContactSampler;
use crate::linalg::gmres;

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

/// Estimated flops of the dense step and of the matrix-free one (per Newton iteration).
pub fn estimated_flops(nodes: usize, harmonics: usize, samples: usize) -> (f64, f64) {
    let (nc, m, n) = (nodes as f64, (2 * harmonics + 1) as f64, samples as f64);
    let dim = nc * m;
    let dense = 2.0 / 3.0 * dim.powi(3) + 4.0 * nc * nc * m * m;
    let fft = 5.0 * n * n.log2().max(1.0);
    let per_iteration = nc * (2.0 * fft + 2.0 * m * m) + 8.0 * nc * nc * (harmonics as f64 + 1.0);
    let setup = nc * (2.0 / 3.0 * m.powi(3) + 2.0 * m.powi(3));
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
    // Ĉ_j = mean(s cos jθ), Ŝ_j = mean(s sin jθ) for j = 0..2H (2H < N).
    let scale = 1.0 / n as f64;
    let c_hat = |j: i64| spectrum[j.unsigned_abs() as usize].re * scale;
    let s_hat = |j: i64| -spectrum[j.unsigned_abs() as usize].im * scale * j.signum() as f64;
    // Basis p_a: index 0 the constant (cos 0θ), 2k−1 cos kθ, 2k sin kθ.
    let kind = |a: usize| -> (i64, bool) { (harmonic_of(a) as i64, a > 0 && a.is_multiple_of(2)) };
    for a in 0..m {
        let (p, a_sin) = kind(a);
        let weight = if a == 0 { 1.0 } else { 2.0 };
        for b in 0..m {
            let (q, b_sin) = kind(b);
            let mean = match (a_sin, b_sin) {
                (false, false) => 0.5 * (c_hat(p - q) + c_hat(p + q)),
                (true, true) => 0.5 * (c_hat(p - q) - c_hat(p + q)),
                (false, true) => 0.5 * (s_hat(p + q) - s_hat(p - q)),
                (true, false) => 0.5 * (s_hat(p + q) + s_hat(p - q)),
            };
            out[a * m + b] = weight * mean;
        }
    }
}

/// The Newton direction d = −J⁻¹ R.
pub fn direction(
    problem: &ReducedProblem,
    sampler: &ContactSampler,
    c: f64,
    slopes: &[f64],
    residual: &[f64],
    method: StepMethod,
) -> Result<Vec<f64>, String> {
    let (nc, h, n) = (problem.nodes, problem.harmonics, sampler.samples());
    let blocks = activity_blocks(sampler, nc, slopes);
    let dense = || {
        dense_step(problem, c, &blocks, residual)
            .ok_or_else(|| "the Newton matrix is singular".to_string())
    };
    match resolve(method, nc, h, n) {
        StepMethod::Krylov => {
            krylov_step(problem, sampler, c, slopes, &blocks, residual).or_else(|why| {
                if method == StepMethod::Auto && estimated_flops(nc, h, n).0 <= DENSE_FALLBACK {
                    dense()
                } else {
                    Err(why)
                }
            })
        }
        _ => dense(),
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
    let x = jac.partial_piv_lu().solve(&rhs);
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

/// The step without forming J: restarted GMRES on J v = v − A v + c A G v (products by FFT
/// and per-harmonic G), right-preconditioned by J's node-diagonal blocks. Inexact Newton: the
/// linear tolerance is loose because the line search guards the step.
fn krylov_step(
    problem: &ReducedProblem,
    sampler: &ContactSampler,
    c: f64,
    slopes: &[f64],
    blocks: &[f64],
    residual: &[f64],
) -> Result<Vec<f64>, String> {
    let (nc, m, ns) = (problem.nodes, problem.coefficients(), sampler.samples());
    let dim = nc * m;
    let apply_a = |w: &[f64], out: &mut [f64]| {
        let mut samples = vec![0.0; ns];
        for i in 0..nc {
            sampler.to_samples(&w[i * m..(i + 1) * m], &mut samples);
            for (v, s) in samples.iter_mut().zip(&slopes[i * ns..(i + 1) * ns]) {
                *v *= s;
            }
            sampler.to_coefficients(&samples, &mut out[i * m..(i + 1) * m]);
        }
    };
    let linear_gap = &problem.linear_gap;
    let apply_j = |v: &[f64]| -> Vec<f64> {
        let mut gv = problem.gap(v);
        for (g, r) in gv.iter_mut().zip(linear_gap) {
            *g -= r;
        }
        let arg: Vec<f64> = gv.iter().zip(v).map(|(g, x)| c * g - x).collect();
        let mut a = vec![0.0; dim];
        apply_a(&arg, &mut a);
        v.iter().zip(&a).map(|(x, y)| x + y).collect()
    };
    let node_blocks: Vec<_> = (0..nc)
        .map(|i| {
            let a_block = DMatrix::from_row_slice(m, m, &blocks[i * m * m..(i + 1) * m * m]);
            let g_block = DMatrix::from_fn(m, m, |a, b| problem.real_entry(i, a, i, b));
            (DMatrix::<f64>::identity(m, m) - &a_block + (&a_block * g_block) * c).lu()
        })
        .collect();
    let precondition = |v: &[f64]| -> Vec<f64> {
        let mut out = v.to_vec();
        for (i, lu) in node_blocks.iter().enumerate() {
            let rhs = DMatrix::from_column_slice(m, 1, &v[i * m..(i + 1) * m]);
            if let Some(x) = lu.solve(&rhs) {
                out[i * m..(i + 1) * m].copy_from_slice(x.as_slice());
            }
        }
        out
    };
    let rhs: Vec<f64> = residual.iter().map(|v| -v).collect();
    gmres(&apply_j, &precondition, &rhs, 1e-6, 60, 20)
}

#[cfg(test)]
mod tests {
    use super::*;

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
