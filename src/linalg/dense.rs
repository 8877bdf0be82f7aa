//! Dense linear algebra: Σ a_i b_i, ‖x‖₂, LU with partial pivoting P A = L U (in place,
//! reusing its work space), A⁻¹ and A⁻¹ B, and the eigenvalues of a real square matrix; on
//! the calling thread below `DENSE_PARALLEL_ORDER`, on faer's pool above.

use faer::c64;
use faer::{Mat, Par};

use crate::{Error, Result};

/// ‖x‖₂, summed in order (the same value wherever it is asked).
pub fn norm2(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Σ a_i b_i (real or complex) with eight running sums, so the compiler can keep them in
/// SIMD registers (a single running sum is a chain of dependent adds that it may not reorder).
pub fn dot<T>(a: &[T], b: &[T]) -> T
where
    T: Copy + Default + std::ops::Mul<Output = T> + std::ops::AddAssign + std::iter::Sum,
{
    let mut sums = [T::default(); 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: T = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| *x * *y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            sums[l] += x[l] * y[l];
        }
    }
    let mut total = tail;
    for s in sums {
        total += s;
    }
    total
}

/// Dense matrices below this order are factored on the calling thread. faer's global pool
/// spreads even an 81 × 81 LU over its threads, and waking them costs more than the work:
/// the 9 × 9 Schur complement inverted in each of the strip's LDLᵀ factorizations took
/// about a sixth of their time that way.
const DENSE_PARALLEL_ORDER: usize = 256;

/// faer's parallelism for dense work of order n: its global pool from `DENSE_PARALLEL_ORDER`
/// on, else the calling thread.
fn dense_parallelism(n: usize) -> Par {
    if n >= DENSE_PARALLEL_ORDER {
        faer::get_global_parallelism()
    } else {
        Par::Seq
    }
}

/// The workspace of faer's eigendecomposition of order n with right eigenvectors only.
fn right_eigenvectors_scratch<T: faer::traits::ComplexField>(
    n: usize,
    par: Par,
) -> faer::dyn_stack::MemBuffer {
    use faer::linalg::evd::{self, ComputeEigenvectors};
    let (no, yes) = (ComputeEigenvectors::No, ComputeEigenvectors::Yes);
    faer::dyn_stack::MemBuffer::new(evd::evd_scratch::<T>(n, no, yes, par, Default::default()))
}

/// The eigenvalues and right eigenvectors (columns, complex) of a real square `a`, on the
/// calling thread below `DENSE_PARALLEL_ORDER` (faer's `eigen()` uses its global pool
/// whatever the order, which made a 132 × 132 Hessenberg matrix 2.7× slower on 2 cores).
pub fn eigen_real(a: faer::MatRef<'_, f64>) -> Result<(Vec<c64>, Mat<c64>)> {
    use faer::dyn_stack::MemStack;
    use faer::linalg::evd;
    let n = a.nrows();
    let par = dense_parallelism(n);
    let (mut u, mut re, mut im) = (
        Mat::<f64>::zeros(n, n),
        faer::diag::Diag::<f64>::zeros(n),
        faer::diag::Diag::<f64>::zeros(n),
    );
    let mut scratch = right_eigenvectors_scratch::<f64>(n, par);
    evd::evd_real(
        a,
        re.as_mut(),
        im.as_mut(),
        None,
        Some(u.as_mut()),
        par,
        MemStack::new(&mut scratch),
        Default::default(),
    )
    .map_err(|e| Error::Model(format!("dense eigenvalues failed ({e:?})")))?;
    // A complex pair is stored as (re, im) columns j, j + 1: the vectors u_j ± i u_{j+1}.
    let (re, im) = (re.column_vector(), im.column_vector());
    let mut values = vec![c64::new(0.0, 0.0); n];
    let mut vectors = Mat::<c64>::zeros(n, n);
    let mut j = 0;
    while j < n {
        if im[j] == 0.0 || j + 1 == n {
            values[j] = c64::new(re[j], 0.0);
            for i in 0..n {
                vectors[(i, j)] = c64::new(u[(i, j)], 0.0);
            }
            j += 1;
        } else {
            values[j] = c64::new(re[j], im[j]);
            values[j + 1] = c64::new(re[j], -im[j]);
            for i in 0..n {
                vectors[(i, j)] = c64::new(u[(i, j)], u[(i, j + 1)]);
                vectors[(i, j + 1)] = c64::new(u[(i, j)], -u[(i, j + 1)]);
            }
            j += 2;
        }
    }
    Ok((values, vectors))
}

/// The eigenvalues and right eigenvectors (columns) of a complex square `a`, on the calling
/// thread below `DENSE_PARALLEL_ORDER` (as `eigen_real`).
pub fn eigen_complex(a: faer::MatRef<'_, c64>) -> Result<(Vec<c64>, Mat<c64>)> {
    use faer::dyn_stack::MemStack;
    use faer::linalg::evd;
    let n = a.nrows();
    let par = dense_parallelism(n);
    let (mut u, mut s) = (Mat::<c64>::zeros(n, n), faer::diag::Diag::<c64>::zeros(n));
    let mut scratch = right_eigenvectors_scratch::<c64>(n, par);
    evd::evd_cplx(
        a,
        s.as_mut(),
        None,
        Some(u.as_mut()),
        par,
        MemStack::new(&mut scratch),
        Default::default(),
    )
    .map_err(|e| Error::Model(format!("dense eigenvalues failed ({e:?})")))?;
    let values = s.column_vector().iter().copied().collect();
    Ok((values, u))
}

/// The partially pivoted LU of a square `a` in place (L unit lower below the diagonal, U on
/// and above it), with its row permutation (forward, backward).
fn dense_lu_in_place<T: faer::traits::ComplexField>(
    a: faer::MatMut<'_, T>,
    par: Par,
) -> (Vec<usize>, Vec<usize>) {
    let n = a.nrows();
    let mut work = LuWork::default();
    work.size::<T>(n, par);
    dense_lu_with(a, par, &mut work);
    (work.forward, work.backward)
}

/// The row permutation and faer's scratch of in-place dense LUs of one order (and of
/// one-column solves with them), kept so that refactoring allocates nothing.
pub struct LuWork {
    /// What the scratch was sized for: the order, faer's thread count and the scalar's size.
    sized: (usize, usize, usize),
    /// (P b)_i = b[forward[i]].
    pub forward: Vec<usize>,
    pub backward: Vec<usize>,
    stack: faer::dyn_stack::MemBuffer,
}

impl Default for LuWork {
    fn default() -> Self {
        LuWork {
            sized: (0, 0, 0),
            forward: Vec::new(),
            backward: Vec::new(),
            stack: faer::dyn_stack::MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
        }
    }
}

impl LuWork {
    /// Make room for LUs of order n (and one-column solves) of scalar T at parallelism
    /// `par`; nothing is allocated when those are the last call's.
    pub fn size<T: faer::traits::ComplexField>(&mut self, n: usize, par: Par) {
        use faer::linalg::lu::partial_pivoting::{factor, solve};
        let sized = (n, par.degree(), std::mem::size_of::<T>());
        if self.sized == sized {
            return;
        }
        let need = factor::lu_in_place_scratch::<usize, T>(n, n, par, Default::default())
            .or(solve::solve_in_place_scratch::<usize, T>(n, 1, par));
        *self = LuWork {
            sized,
            forward: vec![0; n],
            backward: vec![0; n],
            stack: faer::dyn_stack::MemBuffer::new(need),
        };
    }

    /// faer's scratch, as sized by `size`.
    pub fn stack(&mut self) -> &mut faer::dyn_stack::MemStack {
        faer::dyn_stack::MemStack::new(&mut self.stack)
    }
}

/// `dense_lu_in_place` into the permutation and scratch of `work` (sized for a's order by
/// `LuWork::size`).
pub fn dense_lu_with<T: faer::traits::ComplexField>(
    a: faer::MatMut<'_, T>,
    par: Par,
    work: &mut LuWork,
) {
    use faer::dyn_stack::MemStack;
    use faer::linalg::lu::partial_pivoting::factor;
    let LuWork {
        forward,
        backward,
        stack,
        ..
    } = work;
    factor::lu_in_place(
        a,
        forward,
        backward,
        par,
        MemStack::new(stack),
        Default::default(),
    );
}

/// b ← a⁻¹ b by the partially pivoted LU of the square `a`, factored in place, with the
/// permutation and scratch of `work`: nothing is allocated once `work` held this order
/// (`dense_solve` for a kept matrix). A singular `a` gives non-finite entries.
pub fn dense_solve_with(mut a: faer::MatMut<'_, f64>, b: &mut [f64], work: &mut LuWork) {
    use faer::dyn_stack::MemStack;
    use faer::linalg::lu::partial_pivoting::solve;
    let n = a.nrows();
    let par = dense_parallelism(n);
    work.size::<f64>(n, par);
    dense_lu_with(a.as_mut(), par, work);
    let LuWork {
        forward,
        backward,
        stack,
        ..
    } = work;
    let perm = faer::perm::PermRef::new_checked(forward, backward, n);
    solve::solve_in_place(
        a.as_ref(),
        a.as_ref(),
        perm,
        faer::MatMut::from_column_major_slice_mut(b, n, 1),
        par,
        MemStack::new(stack),
    );
}

/// A⁻¹ of a square dense matrix by partially pivoted LU (`dense_parallelism`); a singular A
/// gives non-finite entries, for the caller to check.
pub fn dense_inverse<T: faer::traits::ComplexField>(mut a: Mat<T>) -> Mat<T> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::lu::partial_pivoting::inverse;
    let n = a.nrows();
    let par = dense_parallelism(n);
    let (forward, backward) = dense_lu_in_place(a.as_mut(), par);
    let perm = faer::perm::PermRef::new_checked(&forward, &backward, n);
    let mut out = Mat::zeros(n, n);
    let scratch = inverse::inverse_scratch::<usize, T>(n, par);
    inverse::inverse(
        out.as_mut(),
        a.as_ref(),
        a.as_ref(),
        perm,
        par,
        MemStack::new(&mut MemBuffer::new(scratch)),
    );
    out
}

/// A⁻¹ B for a square dense A by partially pivoted LU (`dense_parallelism`); a singular A
/// gives non-finite entries, for the caller to check.
pub fn dense_solve(mut a: Mat<f64>, mut b: Mat<f64>) -> Mat<f64> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::lu::partial_pivoting::solve;
    let n = a.nrows();
    let par = dense_parallelism(n);
    let (forward, backward) = dense_lu_in_place(a.as_mut(), par);
    let perm = faer::perm::PermRef::new_checked(&forward, &backward, n);
    let scratch = solve::solve_in_place_scratch::<usize, f64>(n, b.ncols(), par);
    solve::solve_in_place(
        a.as_ref(),
        a.as_ref(),
        perm,
        b.as_mut(),
        par,
        MemStack::new(&mut MemBuffer::new(scratch)),
    );
    b
}

/// The partially pivoted LU (P A = L U) of a small dense n × n matrix in single precision,
/// as a preconditioner: factored by faer on the calling thread at every order (on faer's pool
/// the contact Newton's many node blocks were slower with two threads than with one; see
/// `DENSE_PARALLEL_ORDER`) and solved in f32, twice the vector lanes and half the memory of
/// f64. A solve is accurate to about
/// 10⁻⁷ times the block's condition number, which is what a preconditioner of flexible
/// GMRES needs (`GmresWork::cycles`: the products with the matrix itself stay in f64). Kept as factors,
/// not inverted: the LU costs ⅔ n³, an inverse 2 n³, and a solve with the factors costs the
/// 2 n² of a product with the inverse.
#[derive(Default)]
pub struct DenseLu {
    /// L (unit lower, below the diagonal) and U, column-major n × n.
    cols: Vec<f32>,
    /// (P b)_i = b[forward[i]].
    forward: Vec<usize>,
}

/// Columns of L or U a triangular solve takes at once: after the small triangle, one pass
/// over the rest of the solution subtracts all of them (one load and store of it per
/// `SOLVE_COLUMNS` multiply-adds, where a column at a time took one per multiply-add).
const SOLVE_COLUMNS: usize = 8;

/// What refactoring `DenseLu`s of one order reuses: the single-precision matrix factored in
/// place and the permutation and scratch of the LU.
pub struct DenseLuWork {
    matrix: Mat<f32>,
    lu: LuWork,
}

impl Default for DenseLuWork {
    fn default() -> Self {
        DenseLuWork {
            matrix: Mat::zeros(0, 0),
            lu: LuWork::default(),
        }
    }
}

impl DenseLu {
    /// The LU of the row-major n × n `a`; `None` when a pivot vanishes or is not finite.
    pub fn new(a: &[f64], n: usize) -> Option<DenseLu> {
        let mut lu = DenseLu::default();
        lu.refactor(a, n, &mut DenseLuWork::default()).then_some(lu)
    }

    /// Replace this LU by that of the row-major n × n `a` (to single precision), allocating
    /// nothing once this LU and `work` have held one of order n; `false` when a pivot
    /// vanishes or is not finite (the LU is then not to be used).
    pub fn refactor(&mut self, a: &[f64], n: usize, work: &mut DenseLuWork) -> bool {
        if work.matrix.nrows() != n || work.matrix.ncols() != n {
            work.matrix = Mat::zeros(n, n);
        }
        for j in 0..n {
            for (i, v) in work.matrix.col_mut(j).iter_mut().enumerate() {
                *v = a[i * n + j] as f32;
            }
        }
        work.lu.size::<f32>(n, Par::Seq);
        dense_lu_with(work.matrix.as_mut(), Par::Seq, &mut work.lu);
        self.cols.clear();
        self.cols
            .extend(work.matrix.col_iter().flat_map(|c| c.iter().copied()));
        self.forward.clear();
        self.forward.extend_from_slice(&work.lu.forward);
        let cols = &self.cols;
        (0..n).all(|i| cols[i * n + i] != 0.0) && cols.iter().all(|v| v.is_finite())
    }

    /// x ← A⁻¹ x (to single precision): x ← P x, then L and U `SOLVE_COLUMNS` columns at a
    /// time (the small triangle, then one vectorized update of the rest; 2n² flops in all,
    /// the cost of a product with the inverse), compiled for the widest instruction set the
    /// machine has (the contact Newton's preconditioner is these solves). `work` is n long.
    pub fn solve_in_place(&self, x: &mut [f64], work: &mut [f32]) {
        pulp::Arch::new().dispatch(LuSolve { lu: self, x, work });
    }
}

/// `DenseLu::solve_in_place` as a `pulp::WithSimd` operation.
struct LuSolve<'a> {
    lu: &'a DenseLu,
    x: &'a mut [f64],
    work: &'a mut [f32],
}

impl pulp::WithSimd for LuSolve<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        let LuSolve { lu, x, work } = self;
        let n = lu.forward.len();
        let col = |j: usize| &lu.cols[j * n..(j + 1) * n];
        let y = &mut work[..n];
        for (w, &f) in y.iter_mut().zip(&lu.forward) {
            *w = x[f] as f32;
        }
        // L y = P x: columns s..e solve their unit triangle, then update the rows below.
        for s in (0..n).step_by(SOLVE_COLUMNS) {
            let e = (s + SOLVE_COLUMNS).min(n);
            for c in s..e {
                let (yc, l) = (y[c], col(c));
                for r in c + 1..e {
                    y[r] -= l[r] * yc;
                }
            }
            let columns = std::array::from_fn(|k| &col((s + k).min(e - 1))[e..]);
            let coefficients = std::array::from_fn(|k| if s + k < e { y[s + k] } else { 0.0 });
            subtract_columns(simd, columns, coefficients, &mut y[e..]);
        }
        // U x = y: columns s..e (the last first) solve their triangle, then update above.
        let mut e = n;
        while e > 0 {
            let s = e.saturating_sub(SOLVE_COLUMNS);
            for c in (s..e).rev() {
                let u = col(c);
                y[c] /= u[c];
                let yc = y[c];
                for r in s..c {
                    y[r] -= u[r] * yc;
                }
            }
            let columns = std::array::from_fn(|k| &col(s + k.min(e - s - 1))[..s]);
            let coefficients = std::array::from_fn(|k| if s + k < e { y[s + k] } else { 0.0 });
            subtract_columns(simd, columns, coefficients, &mut y[..s]);
            e = s;
        }
        for (xi, yi) in x.iter_mut().zip(y.iter()) {
            *xi = f64::from(*yi);
        }
    }
}

/// y −= Σ_k a_k c_k for `SOLVE_COLUMNS` columns c_k as long as y, in one pass over y.
#[inline(always)]
fn subtract_columns<S: pulp::Simd>(
    simd: S,
    columns: [&[f32]; SOLVE_COLUMNS],
    a: [f32; SOLVE_COLUMNS],
    y: &mut [f32],
) {
    let heads = columns.map(|c| S::as_simd_f32s(c));
    let minus = a.map(|a| simd.splat_f32s(-a));
    let (y_head, y_tail) = S::as_mut_simd_f32s(y);
    for (i, yv) in y_head.iter_mut().enumerate() {
        let mut acc = *yv;
        for ((h, _), m) in heads.iter().zip(&minus) {
            acc = simd.mul_add_f32s(h[i], *m, acc);
        }
        *yv = acc;
    }
    for (i, yv) in y_tail.iter_mut().enumerate() {
        for ((_, t), ak) in heads.iter().zip(&a) {
            *yv -= t[i] * ak;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: the LU solves A x = b with the backward error of single precision
    /// (‖b − A y‖∞ ≤ n·u ‖A‖∞ ‖y‖∞, u the unit round-off of f32) where pivoting is needed
    /// (the first pivot is zero), at every size 1–20 (the solves take `SOLVE_COLUMNS` = 8
    /// columns at once: every remainder, sizes below one block and two blocks), and refuses
    /// a singular matrix.
    #[test]
    fn dense_lu_solves_with_row_exchanges_at_every_block_remainder_and_refuses_a_singular_matrix() {
        for n in 1..=20usize {
            // A zero in the corner and a weak diagonal: pivoting is needed.
            let mut a: Vec<f64> = (0..n * n)
                .map(|r| {
                    let (i, j) = (r / n, r % n);
                    ((7 * i + 3 * j + i * j) % 11) as f64 / 5.0 - 1.0
                        + 1.5 * f64::from(u8::from(i == j))
                })
                .collect();
            if n > 1 {
                a[0] = 0.0;
            }
            let x: Vec<f64> = (0..n).map(|i| (i as f64 - 2.5) / 3.0).collect();
            let b: Vec<f64> = (0..n).map(|i| dot(&a[i * n..(i + 1) * n], &x)).collect();
            let lu = DenseLu::new(&a, n).expect("regular");
            let (mut y, mut work) = (b.clone(), vec![0.0; n]);
            lu.solve_in_place(&mut y, &mut work);
            // Backward error ‖b − A y‖∞ / (‖A‖∞ ‖y‖∞), of the order n·u for LU in f32.
            let norm_a = (0..n)
                .map(|i| a[i * n..(i + 1) * n].iter().map(|v| v.abs()).sum::<f64>())
                .fold(0.0, f64::max);
            let norm_y = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let backward = (0..n)
                .map(|i| (b[i] - dot(&a[i * n..(i + 1) * n], &y)).abs())
                .fold(0.0, f64::max)
                / (norm_a * norm_y);
            let u = f64::from(f32::EPSILON) / 2.0;
            assert!(backward < n as f64 * u, "n = {n}: {backward:.2e}");
        }
        let singular = vec![1.0, 2.0, 2.0, 4.0];
        assert!(DenseLu::new(&singular, 2).is_none());
    }

    /// TEST GOAL: the dense inverse and solve (faer's in-place LU, on the calling thread
    /// below `DENSE_PARALLEL_ORDER` and on its pool above) give A A⁻¹ = I and A x = b to
    /// round-off, with pivoting needed (a zero first pivot), for complex and real matrices
    /// on both sides of the threshold.
    #[test]
    fn dense_inverse_and_solve_are_exact_to_round_off_on_both_sides_of_the_parallel_order() {
        for n in [1usize, 9, 40, DENSE_PARALLEL_ORDER + 3] {
            let entry = |i: usize, j: usize| {
                let v = ((7 * i + 3 * j + i * j) % 11) as f64 / 5.0 - 1.0;
                if i == 0 && j == 0 && n > 1 {
                    0.0
                } else {
                    v + 4.0 * f64::from(u8::from(i == j))
                }
            };
            let a = Mat::<c64>::from_fn(n, n, |i, j| c64::new(entry(i, j), entry(j, i) / 3.0));
            let inv = dense_inverse(a.clone());
            let product = &a * &inv;
            let off = (0..n)
                .flat_map(|i| (0..n).map(move |j| (i, j)))
                .map(|(i, j)| (product[(i, j)] - c64::new(f64::from(u8::from(i == j)), 0.0)).norm())
                .fold(0.0, f64::max);
            assert!(off < 1e-12, "n = {n}: |A A⁻¹ − I| = {off:.2e}");
            let real = Mat::<f64>::from_fn(n, n, entry);
            let x = Mat::<f64>::from_fn(n, 2, |i, c| (i + c) as f64 / 7.0 - 0.5);
            let b = &real * &x;
            let y = dense_solve(real, b);
            let error = (0..n)
                .flat_map(|i| (0..2).map(move |c| (i, c)))
                .map(|(i, c)| (y[(i, c)] - x[(i, c)]).abs())
                .fold(0.0, f64::max);
            assert!(error < 1e-12, "n = {n}: |x − A⁻¹ b| = {error:.2e}");
        }
        let singular = Mat::<c64>::from_fn(2, 2, |i, j| c64::new(((i + 1) * (j + 1)) as f64, 0.0));
        let inv = dense_inverse(singular);
        let finite = (0..2)
            .all(|i| (0..2).all(|j| inv[(i, j)].re.is_finite() && inv[(i, j)].im.is_finite()));
        assert!(!finite, "a singular matrix's inverse is not finite");
    }
}
