//! The dense front kernels of the Schur-complement LDLᵀ: gather and scatter, extend-add of a
//! child's contribution block, the elimination of a pivot (column scaled by 1/d, the trailing
//! rank-1 update y −= s x), and the blocked trailing update of a panel.

use faer::c64;
use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::{Accum, MatMut, MatRef, Par};

use super::*;

/// Column k of a panel of m rows stored as a trapezoid: its rows k..m (the diagonal first).
#[inline(always)]
pub(super) fn trapezoid_column(panel: &[c64], m: usize, k: usize) -> &[c64] {
    let at = trapezoid(k, m);
    &panel[at..at + m - k]
}

/// local[i * r + c] = x[rows[i] * r + c].
#[inline(always)]
pub(super) fn gather(local: &mut Vec<c64>, x: &[c64], rows: &[usize], r: usize) {
    local.clear();
    for &row in rows {
        local.extend_from_slice(&x[row * r..(row + 1) * r]);
    }
}

/// x[rows[i] * r + c] = local[i * r + c].
#[inline(always)]
pub(super) fn scatter(local: &[c64], x: &mut [c64], rows: &[usize], r: usize) {
    for (i, &row) in rows.iter().enumerate() {
        x[row * r..(row + 1) * r].copy_from_slice(&local[i * r..(i + 1) * r]);
    }
}

/// Add the lower triangle of a contribution block (column-major, rows `rows`) into `front`
/// (column-major m × m, lower triangle) at the positions `local[row]`. Fronts list their
/// rows in elimination order, so those positions rise with the CB's rows and entry (a, b),
/// a ≥ b, lands in the lower triangle at column `local[rows[b]]`; `at` is scratch for them.
#[inline(always)]
pub(super) fn extend_add(
    front: &mut [c64],
    m: usize,
    cb: &[c64],
    rows: &[usize],
    local: &[usize],
    at: &mut Vec<usize>,
) {
    let mc = rows.len();
    at.clear();
    at.extend(rows.iter().map(|&r| local[r]));
    debug_assert!(at.windows(2).all(|w| w[0] < w[1]));
    for b in 0..mc {
        let column = &mut front[at[b] * m..(at[b] + 1) * m];
        for (&la, &v) in at[b..].iter().zip(&cb[b * mc + b..(b + 1) * mc]) {
            column[la] += v;
        }
    }
}

/// Blocked partial LDLᵀ (no pivoting) of the front's first p columns, `PANEL` columns at a
/// time: each panel is factored column by column (updating only its own columns), then the
/// trailing lower triangle gets F22 −= L21 D L21ᵀ by one matrix product. Afterwards the
/// first p columns hold L (unit diagonal implied, D on it) and the trailing (m − p)² lower
/// triangle is the Schur complement. `Err(k)` when pivot k vanishes.
#[inline(always)]
pub(super) fn eliminate<S: pulp::Simd>(
    simd: S,
    front: &mut [c64],
    m: usize,
    p: usize,
    tolerance: f64,
    work: &mut Vec<c64>,
) -> Result<(), usize> {
    let mut start = 0;
    while start < p {
        let end = (start + PANEL).min(p);
        for k in start..end {
            let d = front[k * m + k];
            // Sizes as max(|re|, |im|), within √2 of the modulus and without its hypot (a
            // quarter of the elimination's time with it).
            let size = |z: &c64| z.re.abs().max(z.im.abs());
            let scale = largest(simd, &front[k * m + k..(k + 1) * m]);
            let finite = d.re.is_finite() && d.im.is_finite();
            if !(size(&d) > 1e-300_f64.max(tolerance * scale)) || !finite {
                return Err(k);
            }
            let inv = d.inv();
            let (head, tail) = front.split_at_mut((k + 1) * m);
            let colk = &head[k * m..];
            for j in k + 1..end {
                let s = colk[j] * inv;
                let colj = &mut tail[(j - k - 1) * m..(j - k) * m];
                subtract_product(&mut colj[j..], &colk[j..], s);
            }
            scale_exactly(&mut front[k * m + k + 1..(k + 1) * m], inv);
        }
        trailing_update(front, m, start, end, work);
        start = end;
    }
    Ok(())
}

/// y −= x s (complex), in the machine's widest registers.
#[inline(always)]
pub(super) fn subtract_multiple<S: pulp::Simd>(simd: S, y: &mut [c64], x: &[c64], s: c64) {
    let minus = simd.splat_c64s(-s);
    let x = &x[..y.len()];
    let (y_head, y_tail) = S::as_mut_simd_c64s(y);
    let (x_head, x_tail) = S::as_simd_c64s(x);
    for (yv, xv) in y_head.iter_mut().zip(x_head) {
        *yv = simd.mul_add_c64s(*xv, minus, *yv);
    }
    for (yv, xv) in y_tail.iter_mut().zip(x_tail) {
        *yv -= xv * s;
    }
}

/// y −= x s (complex), rounded exactly as the plain loop `y[i] -= x[i] * s` (each product
/// and sum rounded once, no fused multiply-add), written two complex numbers at a time so
/// that the compiler puts them in one vector register. The elimination keeps the plain
/// loop's rounding: a sweep through a tangle of the sampled law turns on its last digits
/// (docs/method.md §4).
#[inline(always)]
fn subtract_product(y: &mut [c64], x: &[c64], s: c64) {
    let x = &x[..y.len()];
    let (yf, xf): (&mut [f64], &[f64]) = (
        pulp::bytemuck::cast_slice_mut(y),
        pulp::bytemuck::cast_slice(x),
    );
    let mut ys = yf.chunks_exact_mut(4);
    let mut xs = xf.chunks_exact(4);
    for (y, x) in (&mut ys).zip(&mut xs) {
        let (a0, b0, a1, b1) = (x[0], x[1], x[2], x[3]);
        y[0] -= a0 * s.re - b0 * s.im;
        y[1] -= a0 * s.im + b0 * s.re;
        y[2] -= a1 * s.re - b1 * s.im;
        y[3] -= a1 * s.im + b1 * s.re;
    }
    for (y, x) in ys
        .into_remainder()
        .chunks_exact_mut(2)
        .zip(xs.remainder().chunks_exact(2))
    {
        y[0] -= x[0] * s.re - x[1] * s.im;
        y[1] -= x[0] * s.im + x[1] * s.re;
    }
}

/// x *= s (complex), rounded exactly as the plain loop, two at a time (as `subtract_product`).
#[inline(always)]
fn scale_exactly(x: &mut [c64], s: c64) {
    let xf: &mut [f64] = pulp::bytemuck::cast_slice_mut(x);
    let mut pairs = xf.chunks_exact_mut(4);
    for x in &mut pairs {
        let (a0, b0, a1, b1) = (x[0], x[1], x[2], x[3]);
        x[0] = a0 * s.re - b0 * s.im;
        x[1] = a0 * s.im + b0 * s.re;
        x[2] = a1 * s.re - b1 * s.im;
        x[3] = a1 * s.im + b1 * s.re;
    }
    for x in pairs.into_remainder().chunks_exact_mut(2) {
        let (a, b) = (x[0], x[1]);
        x[0] = a * s.re - b * s.im;
        x[1] = a * s.im + b * s.re;
    }
}

/// The largest max(|re|, |im|) of x (0 for none), in the machine's widest registers.
#[inline(always)]
fn largest<S: pulp::Simd>(simd: S, x: &[c64]) -> f64 {
    let parts: &[f64] = pulp::bytemuck::cast_slice(x);
    let (head, tail) = S::as_simd_f64s(parts);
    let mut big = simd.splat_f64s(0.0);
    for v in head {
        big = simd.max_f64s(big, simd.abs_f64s(*v));
    }
    tail.iter()
        .fold(simd.reduce_max_f64s(big), |a, v| a.max(v.abs()))
}

/// Σ x_i y_i (complex, unconjugated), in the machine's widest registers with two
/// accumulators (a serial sum waits on each addition).
#[inline(always)]
pub(super) fn dot<S: pulp::Simd>(simd: S, x: &[c64], y: &[c64]) -> c64 {
    let y = &y[..x.len()];
    let (x_head, x_tail) = S::as_simd_c64s(x);
    let (y_head, y_tail) = S::as_simd_c64s(y);
    let zero = simd.splat_c64s(c64::new(0.0, 0.0));
    let (mut even, mut odd) = (zero, zero);
    let mut pairs_x = x_head.chunks_exact(2);
    let mut pairs_y = y_head.chunks_exact(2);
    for (a, b) in (&mut pairs_x).zip(&mut pairs_y) {
        even = simd.mul_add_c64s(a[0], b[0], even);
        odd = simd.mul_add_c64s(a[1], b[1], odd);
    }
    for (a, b) in pairs_x.remainder().iter().zip(pairs_y.remainder()) {
        even = simd.mul_add_c64s(*a, *b, even);
    }
    let mut sum = simd.reduce_sum_c64s(simd.add_c64s(even, odd));
    for (a, b) in x_tail.iter().zip(y_tail) {
        sum += a * b;
    }
    sum
}

/// F[end.., end..] −= L D Lᵀ (lower triangle) for the panel of columns start..end.
fn trailing_update(front: &mut [c64], m: usize, start: usize, end: usize, work: &mut Vec<c64>) {
    let (rest, width) = (m - end, end - start);
    if rest == 0 {
        return;
    }
    work.clear();
    work.resize(rest * width, c64::new(0.0, 0.0));
    for c in 0..width {
        let k = start + c;
        let d = front[k * m + k];
        for i in 0..rest {
            work[c * rest + i] = front[k * m + end + i] * d;
        }
    }
    let (left, right) = front.split_at_mut(end * m);
    let l21 = MatRef::from_column_major_slice_with_stride(&left[start * m + end..], rest, width, m);
    let w = MatRef::from_column_major_slice(&work[..], rest, width);
    let f22 = MatMut::from_column_major_slice_with_stride_mut(&mut right[end..], rest, rest, m);
    let par = if rest * rest * width > 1 << 21 {
        faer::get_global_parallelism()
    } else {
        Par::Seq
    };
    matmul(
        f22,
        BlockStructure::TriangularLower,
        Accum::Add,
        l21,
        BlockStructure::Rectangular,
        w.transpose(),
        BlockStructure::Rectangular,
        c64::new(-1.0, 0.0),
        par,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(n: usize, phase: f64) -> Vec<c64> {
        (0..n)
            .map(|i| c64::new((i as f64 + phase).sin(), (0.7 * i as f64 - phase).cos()))
            .collect()
    }

    fn check<S: pulp::Simd>(simd: S) {
        let s = c64::new(0.3, -1.2);
        for n in 0..19 {
            let (x, y) = (sample(n, 0.1), sample(n, 2.3));
            let reference: c64 = x.iter().zip(&y).map(|(a, b)| a * b).sum();
            let scale = 1.0 + n as f64;
            assert!(
                (dot(simd, &x, &y) - reference).norm() < 1e-14 * scale,
                "dot at n = {n}"
            );
            let mut z = y.clone();
            subtract_multiple(simd, &mut z, &x, s);
            for i in 0..n {
                assert!(
                    (z[i] - (y[i] - x[i] * s)).norm() < 1e-15 * scale,
                    "axpy at n = {n}"
                );
            }
        }
    }

    /// TEST GOAL: the elimination's column kernels round exactly as the plain loops they
    /// replace (`y[i] -= x[i] * s`, `x[i] *= s`: equal bit for bit, no fused multiply-add,
    /// at every length from 0 to 18), and `largest` is the plain maximum of max(|re|, |im|),
    /// on the scalar instruction set and on AVX2. A sweep through a tangle of the sampled law
    /// turns on the factorization's last digits (docs/method.md §4), so they must not move.
    #[test]
    fn elimination_kernels_round_exactly_as_the_plain_loops() {
        let plain_max = |x: &[c64]| {
            x.iter()
                .fold(0.0f64, |a, z| a.max(z.re.abs().max(z.im.abs())))
        };
        for (n, t) in (0..19).flat_map(|n| (0..40).map(move |t| (n, t as f64))) {
            let s = c64::new(0.3 + 0.37 * t, -1.2 + 0.11 * t * t);
            let (x, y) = (sample(n, 0.1 + t), sample(n, 2.3 - t));
            let (mut z, mut w) = (y.clone(), x.clone());
            subtract_product(&mut z, &x, s);
            scale_exactly(&mut w, s);
            for i in 0..n {
                let (zi, wi) = (y[i] - x[i] * s, x[i] * s);
                let bits = |a: c64| (a.re.to_bits(), a.im.to_bits());
                assert_eq!(bits(z[i]), bits(zi), "y -= x s at n = {n}, i = {i}");
                assert_eq!(bits(w[i]), bits(wi), "x *= s at n = {n}, i = {i}");
            }
            assert_eq!(largest(pulp::Scalar::new(), &x), plain_max(&x), "n = {n}");
            #[cfg(target_arch = "x86_64")]
            if let Some(v3) = pulp::x86::V3::try_new() {
                assert_eq!(largest(v3, &x), plain_max(&x), "AVX2, n = {n}");
            }
        }
    }

    /// TEST GOAL: the vector kernels of a solve's passes (the unconjugated complex dot
    /// product and y −= x s) equal the plain loops to round-off at every length
    /// from 0 to 18 (whole registers, pairs of them and the scalar tail), on the scalar
    /// instruction set and on AVX2 where the machine has it.
    #[test]
    fn vector_kernels_equal_the_plain_loops_at_every_length() {
        check(pulp::Scalar::new());
        #[cfg(target_arch = "x86_64")]
        if let Some(v3) = pulp::x86::V3::try_new() {
            check(v3);
        }
    }
}
