//! Restarted flexible GMRES for A x = b with a right preconditioner M that may change from
//! step to step: the Arnoldi relation A Z_m = V_{m+1} H̄_m with z_j = M_j v_j, the least
//! squares min ‖β e₁ − H̄ y‖ by Givens rotations, and x = x₀ + Z_m y.

use super::dot;

/// The work arrays of restarted flexible GMRES (`GmresWork::cycles`) for one restart length:
/// the Krylov basis V and the preconditioned vectors Z (row-major, one vector per row), the
/// Hessenberg matrix (row i, column j at i · restart + j), the rotations and the residual
/// vector. Kept by the caller, so a solve's restart cycles, and a Newton run's steps,
/// allocate nothing once the first has sized them.
pub struct GmresWork {
    restart: usize,
    w: Vec<f64>,
    v: Vec<f64>,
    z: Vec<f64>,
    h: Vec<f64>,
    cs: Vec<f64>,
    sn: Vec<f64>,
    g: Vec<f64>,
}

impl GmresWork {
    /// Work arrays for restart cycles of `restart` iterations (sized at the first solve).
    pub fn new(restart: usize) -> Self {
        let restart = restart.max(1);
        GmresWork {
            restart,
            w: Vec::new(),
            v: Vec::new(),
            z: Vec::new(),
            h: vec![0.0; (restart + 1) * restart],
            cs: vec![0.0; restart],
            sn: vec![0.0; restart],
            g: vec![0.0; restart + 1],
        }
    }

    /// Restarted flexible GMRES (Saad, Iterative Methods for Sparse Linear Systems, Alg.
    /// 9.6: right-preconditioned GMRES that keeps the preconditioned vectors z_j = M⁻¹ v_j
    /// and forms x = x₀ + Z y from them), with modified Gram–Schmidt and Givens rotations,
    /// for A x = b with `apply(v, out)` (out = A v) and `precondition(v, out)` (out ≈ M⁻¹ v,
    /// which need not be exactly linear: a preconditioner in lower precision is fine). Both
    /// write into `out`, and the bases live in `self`, so an iteration allocates nothing.
    /// Up to `cycles` restarts from `x` (updated in place): `Ok` when the relative residual
    /// reaches `tolerance` by the rotations' estimate (the true residual of A x in exact
    /// arithmetic), else the relative residual the last cycle ended at, for
    /// `loose_or_stalled`. Successive calls with different preconditioners continue one
    /// solve (each restart is a flexible GMRES of its own from the current x).
    pub fn cycles(
        &mut self,
        apply: &mut dyn FnMut(&[f64], &mut [f64]),
        precondition: &mut dyn FnMut(&[f64], &mut [f64]),
        b: &[f64],
        x: &mut [f64],
        tolerance: f64,
        cycles: usize,
    ) -> std::result::Result<(), f64> {
        let (n, restart) = (b.len(), self.restart);
        let norm = |v: &[f64]| dot(v, v).sqrt();
        let b_norm = norm(b);
        if b_norm == 0.0 {
            x.fill(0.0);
            return Ok(());
        }
        self.w.resize(n, 0.0);
        self.z.resize(restart * n, 0.0);
        self.v.clear();
        self.v.reserve((restart + 1) * n);
        let GmresWork {
            w,
            v,
            z,
            h,
            cs,
            sn,
            g,
            ..
        } = self;
        let mut last = f64::INFINITY;
        for _ in 0..cycles {
            initial_residual(apply, b, x, w);
            let beta = norm(w);
            last = beta / b_norm;
            if last <= tolerance {
                return Ok(());
            }
            v.clear();
            v.extend(w.iter().map(|a| a / beta));
            h.fill(0.0);
            g.fill(0.0);
            g[0] = beta;
            let (mut used, mut converged) = (0, false);
            for j in 0..restart {
                let zj = &mut z[j * n..(j + 1) * n];
                precondition(&v[j * n..(j + 1) * n], zj);
                apply(zj, w);
                let wn = orthogonalize(w, v, h, restart, j);
                if !rotate(h, cs, sn, g, restart, j) {
                    break;
                }
                used = j + 1;
                last = g[j + 1].abs() / b_norm;
                if last <= tolerance || wn == 0.0 {
                    converged = true;
                    break;
                }
                v.extend(w.iter().map(|a| a / wn));
            }
            update_solution(h, g, z, x, restart, used);
            if converged {
                return Ok(());
            }
        }
        Err(last)
    }
}

/// w = b − A x, or b itself from x = 0 (no product).
fn initial_residual(
    apply: &mut dyn FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &[f64],
    w: &mut [f64],
) {
    if x.iter().all(|&xi| xi == 0.0) {
        w.copy_from_slice(b);
    } else {
        apply(x, w);
        w.iter_mut().zip(b).for_each(|(wi, bi)| *wi = bi - *wi);
    }
}

/// Modified Gram–Schmidt of w = A z_j against the basis v_0..v_j: column j of H̄ (h_ij =
/// w·v_i, then h_{j+1,j} = ‖w‖), w left orthogonal to the basis; returns ‖w‖.
fn orthogonalize(w: &mut [f64], v: &[f64], h: &mut [f64], restart: usize, j: usize) -> f64 {
    let n = w.len(); // one vector of the basis
    for (i, vi) in v.chunks_exact(n).enumerate() {
        let hij = dot(w, vi);
        h[i * restart + j] = hij;
        for (wk, vk) in w.iter_mut().zip(vi) {
            *wk -= hij * vk;
        }
    }
    let wn = dot(w, w).sqrt();
    h[(j + 1) * restart + j] = wn;
    wn
}

/// Column j of H̄ through the earlier Givens rotations, then the rotation (c_j, s_j) that
/// zeroes h_{j+1,j}, applied to it and to g (g_{j+1} = −s_j g_j, g_j ← c_j g_j). `false`
/// (nothing changed but the earlier rotations) when the column is zero: the Krylov space is
/// exhausted.
fn rotate(
    h: &mut [f64],
    cs: &mut [f64],
    sn: &mut [f64],
    g: &mut [f64],
    restart: usize,
    j: usize,
) -> bool {
    for i in 0..j {
        let (a, b) = (h[i * restart + j], h[(i + 1) * restart + j]);
        h[i * restart + j] = cs[i] * a + sn[i] * b;
        h[(i + 1) * restart + j] = -sn[i] * a + cs[i] * b;
    }
    let (a, b) = (h[j * restart + j], h[(j + 1) * restart + j]);
    let d = (a * a + b * b).sqrt();
    if d == 0.0 {
        return false;
    }
    cs[j] = a / d;
    sn[j] = b / d;
    h[j * restart + j] = d;
    h[(j + 1) * restart + j] = 0.0;
    g[j + 1] = -sn[j] * g[j];
    g[j] *= cs[j];
    true
}

/// Back substitution of the rotated H y = g for y over the first `used` columns (y in g's
/// first entries), then x += Z y.
fn update_solution(
    h: &[f64],
    g: &mut [f64],
    z: &[f64],
    x: &mut [f64],
    restart: usize,
    used: usize,
) {
    let n = z.len() / restart; // z holds `restart` vectors
    for i in (0..used).rev() {
        let s: f64 = ((i + 1)..used).map(|k| h[i * restart + k] * g[k]).sum();
        g[i] = (g[i] - s) / h[i * restart + i];
    }
    for (yk, zk) in g[..used].iter().zip(z.chunks_exact(n)) {
        for (xi, zi) in x.iter_mut().zip(zk) {
            *xi += yk * zi;
        }
    }
}

/// How a Newton step's Krylov solve that stalled begins its reason (the diagnosis of a
/// failed contact solve looks for it).
pub const KRYLOV_STALL: &str = "the Krylov solve of the Newton step stalled";

/// A solve that ran out of cycles at the estimated relative residual `last`: `Ok` (x serves)
/// when its true relative residual is 1e-2 or better (still a descent direction for a
/// guarded step, like a line search's), else why it stalled. `w` is work space.
pub fn loose_or_stalled(
    apply: &mut dyn FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &[f64],
    last: f64,
    w: &mut Vec<f64>,
) -> std::result::Result<(), String> {
    w.resize(b.len(), 0.0);
    apply(x, w);
    w.iter_mut().zip(b).for_each(|(wi, bi)| *wi = bi - *wi);
    let rel = dot(w, w).sqrt() / dot(b, b).sqrt();
    if rel <= 1e-2 {
        Ok(())
    } else {
        Err(format!(
            "{KRYLOV_STALL} at relative residual {rel:.2e} (GMRES estimate {last:.2e})"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: flexible GMRES solves a nonsymmetric system to its tolerance in the true
    /// residual with a preconditioner that is not exactly linear (the diagonal's inverse
    /// applied in single precision), over restarts, continues one solve across calls (a
    /// short first one, then another preconditioner), reports a stall with its residual, and
    /// gives the same x to the bit from work arrays that served another solve before (the
    /// Newton steps share one `GmresWork`).
    #[test]
    fn flexible_gmres_meets_its_tolerance_with_a_single_precision_preconditioner() {
        let n = 60;
        let entry = |i: usize, j: usize| {
            if i == j {
                4.0 + (i % 7) as f64
            } else {
                (((3 * i + 5 * j) % 11) as f64 - 5.0) / (n as f64)
            }
        };
        let mut apply = |v: &[f64], out: &mut [f64]| {
            for (i, o) in out.iter_mut().enumerate() {
                *o = (0..n).map(|j| entry(i, j) * v[j]).sum();
            }
        };
        let mut precondition = |v: &[f64], out: &mut [f64]| {
            for (i, (o, x)) in out.iter_mut().zip(v).enumerate() {
                *o = f64::from((*x / entry(i, i)) as f32);
            }
        };
        let b: Vec<f64> = (0..n).map(|i| ((i * 13) % 5) as f64 - 2.0).collect();
        let mut x = vec![0.0; n];
        let mut work = GmresWork::new(8);
        work.cycles(&mut apply, &mut precondition, &b, &mut x, 1e-10, 20)
            .expect("converges");
        let mut ax = vec![0.0; n];
        apply(&x, &mut ax);
        let r = ax
            .iter()
            .zip(&b)
            .map(|(p, q)| (p - q).powi(2))
            .sum::<f64>()
            .sqrt();
        let b_norm = dot(&b, &b).sqrt();
        assert!(r <= 2e-10 * b_norm, "{}", r / b_norm);
        let mut short = vec![0.0; n];
        let last = GmresWork::new(1)
            .cycles(&mut apply, &mut precondition, &b, &mut short, 1e-14, 1)
            .expect_err("one iteration cannot reach 1e-14");
        let stalled = loose_or_stalled(&mut apply, &b, &short, last, &mut Vec::new());
        assert!(stalled.is_err_and(|why| why.contains("stalled at relative residual")));
        // One solve in two calls: a short first call, then more cycles from where it ended
        // (as the Newton step continues with the other preconditioner).
        let mut x = vec![0.0; n];
        let first = GmresWork::new(2).cycles(&mut apply, &mut precondition, &b, &mut x, 1e-10, 1);
        assert!(
            first.is_err_and(|last| last > 1e-10 && last < 1.0),
            "{first:?}"
        );
        let mut identity = |v: &[f64], out: &mut [f64]| out.copy_from_slice(v);
        let mut continued = x.clone();
        GmresWork::new(8)
            .cycles(&mut apply, &mut identity, &b, &mut x, 1e-10, 20)
            .expect("converges");
        // The work arrays of the first solve, sized and filled, serve this one alike.
        work.cycles(&mut apply, &mut identity, &b, &mut continued, 1e-10, 20)
            .expect("converges");
        assert!(x
            .iter()
            .zip(&continued)
            .all(|(p, q)| p.to_bits() == q.to_bits()));
        apply(&x, &mut ax);
        let r: f64 = ax
            .iter()
            .zip(&b)
            .map(|(p, q)| (p - q).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(r <= 2e-10 * b_norm, "{}", r / b_norm);
    }
}
