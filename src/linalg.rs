//! Sparse linear algebra over faer: matrices built from triplets, restricted to the free dofs,
//! and LU factorizations whose symbolic analysis is shared by every matrix of the same pattern
//! (all harmonics, all frequencies of a sweep).

use faer::c64;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};
use faer::{Mat, Par};

use crate::{Error, Result};

pub mod modal;
pub mod schur;

/// A square sparse matrix as (row, column, value) triplets; duplicates add up.
#[derive(Clone, Debug, Default)]
pub struct Triplets {
    pub n: usize,
    pub entries: Vec<(usize, usize, f64)>,
}

impl Triplets {
    pub fn new(n: usize) -> Self {
        Triplets {
            n,
            entries: Vec::new(),
        }
    }

    pub fn push(&mut self, row: usize, col: usize, value: f64) {
        self.entries.push((row, col, value));
    }

    /// y = A x over all dofs.
    pub fn mul_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        for &(i, j, v) in &self.entries {
            y[i] += v * x[j];
        }
        y
    }

    /// The diagonal (duplicates summed).
    pub fn diagonal(&self) -> Vec<f64> {
        let mut d = vec![0.0; self.n];
        for &(i, j, v) in &self.entries {
            if i == j {
                d[i] += v;
            }
        }
        d
    }

    /// The block A[rows, cols] with rows and columns renumbered by the maps
    /// (`None` = not in the block).
    pub fn block(
        &self,
        row_map: &[Option<usize>],
        col_map: &[Option<usize>],
        nrows: usize,
        ncols: usize,
    ) -> Csc {
        if nrows == 0 || ncols == 0 {
            return Csc::from_entries(nrows, ncols, &[]);
        }
        let mut entries = Vec::with_capacity(self.entries.len());
        for &(i, j, v) in &self.entries {
            if let (Some(r), Some(c)) = (row_map[i], col_map[j]) {
                entries.push((r, c, v));
            }
        }
        Csc::from_entries(nrows, ncols, &entries)
    }
}

/// A compressed-sparse-column real matrix (duplicates summed, explicit zeros kept so that
/// matrices combined from the same blocks share one pattern).
#[derive(Clone, Debug, PartialEq)]
pub struct Csc {
    pub nrows: usize,
    pub ncols: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    pub values: Vec<f64>,
}

impl Csc {
    /// Duplicates are summed in the order given. Linear in the entries: a counting sort by
    /// column, duplicates merged through a row-to-slot map, then each column's distinct rows
    /// (a dozen or two from an assembly) sorted (a global sort of the element triplets took
    /// about a third of the strip's assembly).
    pub fn from_entries(nrows: usize, ncols: usize, entries: &[(usize, usize, f64)]) -> Self {
        let mut start = vec![0usize; ncols + 1];
        for &(_, j, _) in entries {
            start[j + 1] += 1;
        }
        for j in 0..ncols {
            start[j + 1] += start[j];
        }
        let mut next = start.clone();
        let mut bucket = vec![(0usize, 0.0f64); entries.len()];
        for &(i, j, v) in entries {
            bucket[next[j]] = (i, v);
            next[j] += 1;
        }
        let mut col_ptr = Vec::with_capacity(ncols + 1);
        col_ptr.push(0);
        let mut row_idx: Vec<usize> = Vec::with_capacity(entries.len());
        let mut values: Vec<f64> = Vec::with_capacity(entries.len());
        // slot[i]: where row i sits in the current column (valid when seen[i] == j + 1).
        let (mut slot, mut seen) = (vec![0usize; nrows], vec![0usize; nrows]);
        let mut column: Vec<(usize, f64)> = Vec::new();
        for j in 0..ncols {
            column.clear();
            for &(i, v) in &bucket[start[j]..start[j + 1]] {
                if seen[i] == j + 1 {
                    column[slot[i]].1 += v;
                } else {
                    (seen[i], slot[i]) = (j + 1, column.len());
                    column.push((i, v));
                }
            }
            column.sort_unstable_by_key(|&(i, _)| i);
            row_idx.extend(column.iter().map(|&(i, _)| i));
            values.extend(column.iter().map(|&(_, v)| v));
            col_ptr.push(row_idx.len());
        }
        Csc {
            nrows,
            ncols,
            col_ptr,
            row_idx,
            values,
        }
    }

    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// y = A x.
    pub fn mul_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.nrows];
        for (j, &xj) in x.iter().enumerate().take(self.ncols) {
            if xj != 0.0 {
                for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                    y[self.row_idx[p]] += self.values[p] * xj;
                }
            }
        }
        y
    }

    /// y = Aᵀ x.
    pub fn mul_transpose_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.ncols];
        for (j, yj) in y.iter_mut().enumerate() {
            let mut s = 0.0;
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                s += self.values[p] * x[self.row_idx[p]];
            }
            *yj = s;
        }
        y
    }

    /// y = A z for a complex z (A real: its real and imaginary parts separately).
    pub fn mul_complex(&self, z: &[c64]) -> Vec<c64> {
        let (re, im): (Vec<f64>, Vec<f64>) = z.iter().map(|v| (v.re, v.im)).unzip();
        let (yr, yi) = (self.mul_vec(&re), self.mul_vec(&im));
        yr.into_iter()
            .zip(yi)
            .map(|(a, b)| c64::new(a, b))
            .collect()
    }

    /// y = Aᵀ z for a complex z.
    pub fn mul_transpose_complex(&self, z: &[c64]) -> Vec<c64> {
        let (re, im): (Vec<f64>, Vec<f64>) = z.iter().map(|v| (v.re, v.im)).unzip();
        let (yr, yi) = (self.mul_transpose_vec(&re), self.mul_transpose_vec(&im));
        yr.into_iter()
            .zip(yi)
            .map(|(a, b)| c64::new(a, b))
            .collect()
    }

    /// The union pattern of several same-shape matrices, each scattered into it (so a linear
    /// combination of them is a plain combination of value arrays). Their columns are sorted
    /// and distinct, as `from_entries` leaves them.
    pub fn on_common_pattern(mats: &[&Csc]) -> Vec<Csc> {
        let (nrows, ncols) = (mats[0].nrows, mats[0].ncols);
        // Usually the first pattern holds the others (a lumped mass on the stiffness'
        // diagonal): then it is the common one, and only the others are scattered into it.
        if let Some(on_first) = mats.iter().map(|m| m.scattered_into(mats[0])).collect() {
            return on_first;
        }
        let mut entries = Vec::new();
        for m in mats {
            for j in 0..ncols {
                for p in m.col_ptr[j]..m.col_ptr[j + 1] {
                    entries.push((m.row_idx[p], j, 0.0));
                }
            }
        }
        let pattern = Csc::from_entries(nrows, ncols, &entries);
        // The union holds every entry, so each scatter succeeds.
        mats.iter()
            .filter_map(|m| m.scattered_into(&pattern))
            .collect()
    }

    /// This matrix on `pattern` (explicit zeros where it has no entry); `None` when an entry
    /// of it is not in `pattern` (or the shapes differ).
    fn scattered_into(&self, pattern: &Csc) -> Option<Csc> {
        if std::ptr::eq(self, pattern) {
            return Some(self.clone());
        }
        if (self.nrows, self.ncols) != (pattern.nrows, pattern.ncols) {
            return None;
        }
        let mut out = Csc {
            values: vec![0.0; pattern.values.len()],
            ..pattern.clone()
        };
        for j in 0..self.ncols {
            let rows = &pattern.row_idx[pattern.col_ptr[j]..pattern.col_ptr[j + 1]];
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let q = rows.binary_search(&self.row_idx[p]).ok()?;
                out.values[pattern.col_ptr[j] + q] += self.values[p];
            }
        }
        Some(out)
    }

    fn faer_real(&self) -> Result<SparseColMat<usize, f64>> {
        self.faer_with(self.values.clone())
    }

    fn faer_complex(&self, imag: Option<&[f64]>) -> Result<SparseColMat<usize, c64>> {
        let values = (self.values.iter().enumerate())
            .map(|(p, &v)| c64::new(v, imag.map_or(0.0, |im| im[p])))
            .collect();
        self.faer_with(values)
    }

    /// faer's matrix of this pattern with `values` on it: the arrays as they are where the
    /// columns are sorted without duplicates (as `from_entries` leaves them), else through
    /// faer's triplet sort.
    fn faer_with<T: faer::traits::ComplexField + Copy>(
        &self,
        values: Vec<T>,
    ) -> Result<SparseColMat<usize, T>> {
        let canonical = self.col_ptr.len() == self.ncols + 1
            && self.col_ptr.windows(2).all(|w| w[0] <= w[1])
            && self.col_ptr.last() == Some(&self.row_idx.len())
            && values.len() == self.row_idx.len()
            && (0..self.ncols).all(|j| {
                let rows = &self.row_idx[self.col_ptr[j]..self.col_ptr[j + 1]];
                rows.windows(2).all(|w| w[0] < w[1]) && rows.last().is_none_or(|&r| r < self.nrows)
            });
        if canonical {
            let symbolic = SymbolicSparseColMat::new_checked(
                self.nrows,
                self.ncols,
                self.col_ptr.clone(),
                None,
                self.row_idx.clone(),
            );
            return Ok(SparseColMat::new(symbolic, values));
        }
        let trip: Vec<Triplet<usize, usize, T>> = (0..self.ncols)
            .flat_map(|j| (self.col_ptr[j]..self.col_ptr[j + 1]).map(move |p| (j, p)))
            .map(|(j, p)| Triplet::new(self.row_idx[p], j, values[p]))
            .collect();
        SparseColMat::try_new_from_triplets(self.nrows, self.ncols, &trip)
            .map_err(|e| Error::Model(format!("building a sparse matrix failed: {e:?}")))
    }

    /// The rows as dense vectors (a few contact rows, never a whole matrix).
    pub fn dense_rows(&self) -> Vec<Vec<f64>> {
        let mut rows = vec![vec![0.0; self.ncols]; self.nrows];
        for (i, p, v) in self.triplet_iter() {
            rows[i][p] = v;
        }
        rows
    }

    pub(crate) fn triplet_iter(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        (0..self.ncols).flat_map(move |j| {
            (self.col_ptr[j]..self.col_ptr[j + 1])
                .map(move |p| (self.row_idx[p], j, self.values[p]))
        })
    }
}

/// The symbolic LU analysis of one sparsity pattern, shared by all numeric factorizations.
#[derive(Clone)]
pub struct LuPattern {
    symbolic: SymbolicLu<usize>,
}

impl LuPattern {
    pub fn analyse(pattern: &Csc) -> Result<Self> {
        let m = pattern.faer_real()?;
        let symbolic = SymbolicLu::try_new(m.symbolic())
            .map_err(|e| Error::Model(format!("sparse LU analysis failed: {e:?}")))?;
        Ok(LuPattern { symbolic })
    }
}

/// Right-hand sides per blocked solve of `SparseLu::compliance`: wide enough for faer's
/// supernodal kernels, small enough that the n × block solution stays in cache-sized pieces.
const COMPLIANCE_BLOCK: usize = 64;

/// A numeric sparse LU factorization, real or complex.
pub enum SparseLu {
    Real(Lu<usize, f64>),
    Complex(Lu<usize, c64>),
}

impl SparseLu {
    /// Factor a real matrix with the pattern's symbolic analysis.
    pub fn factor_real(pattern: &LuPattern, a: &Csc) -> Result<Self> {
        let m = a.faer_real()?;
        let lu = Lu::try_new_with_symbolic(pattern.symbolic.clone(), m.as_ref())
            .map_err(|e| Error::Model(format!("sparse LU factorization failed: {e:?}")))?;
        Ok(SparseLu::Real(lu))
    }

    /// Factor the complex matrix `re + i·im`, where `im` holds values on `re`'s pattern.
    pub fn factor_complex(pattern: &LuPattern, re: &Csc, im: &[f64]) -> Result<Self> {
        let m = re.faer_complex(Some(im))?;
        let lu = Lu::try_new_with_symbolic(pattern.symbolic.clone(), m.as_ref())
            .map_err(|e| Error::Model(format!("sparse LU factorization failed: {e:?}")))?;
        Ok(SparseLu::Complex(lu))
    }

    pub fn dim(&self) -> usize {
        match self {
            SparseLu::Real(lu) => faer::linalg::solvers::ShapeCore::nrows(lu),
            SparseLu::Complex(lu) => faer::linalg::solvers::ShapeCore::nrows(lu),
        }
    }

    /// Solve for several real right-hand sides (columns of `rhs`, each of length n); returns
    /// the solutions as complex columns (the imaginary part is zero for a real factorization).
    pub fn solve_many(&self, rhs: &[Vec<c64>]) -> Vec<Vec<c64>> {
        let n = self.dim();
        let k = rhs.len();
        if k == 0 {
            return Vec::new();
        }
        match self {
            SparseLu::Real(lu) => {
                // Real and imaginary parts as separate real columns.
                let mut b = Mat::<f64>::zeros(n, 2 * k);
                for (c, col) in rhs.iter().enumerate() {
                    for i in 0..n {
                        b[(i, 2 * c)] = col[i].re;
                        b[(i, 2 * c + 1)] = col[i].im;
                    }
                }
                let x = lu.solve(&b);
                (0..k)
                    .map(|c| {
                        (0..n)
                            .map(|i| c64::new(x[(i, 2 * c)], x[(i, 2 * c + 1)]))
                            .collect()
                    })
                    .collect()
            }
            SparseLu::Complex(lu) => {
                let mut b = Mat::<c64>::zeros(n, k);
                for (c, col) in rhs.iter().enumerate() {
                    for i in 0..n {
                        b[(i, c)] = col[i];
                    }
                }
                let x = lu.solve(&b);
                (0..k)
                    .map(|c| (0..n).map(|i| x[(i, c)]).collect())
                    .collect()
            }
        }
    }

    /// The compliance B A⁻¹ Bᵀ (row-major nrows(B)²) for a sparse B: blocked solves with the
    /// rows of B as right-hand sides (real ones for a real factorization), `COMPLIANCE_BLOCK`
    /// at a time so the n × n_c solution is never held, each block multiplied by B at once.
    pub fn compliance(&self, b: &Csc) -> Vec<c64> {
        let nc = b.nrows;
        let mut out = vec![c64::new(0.0, 0.0); nc * nc];
        // Row i of B as (column, value) pairs: B_i x = Σ v x_p.
        let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nc];
        for (i, p, v) in b.triplet_iter() {
            rows[i].push((p, v));
        }
        let mut start = 0;
        while start < nc {
            let width = COMPLIANCE_BLOCK.min(nc - start);
            let columns = start..start + width;
            // out[i, j] = B_i x_j for the block's columns j.
            let mut product = |x: &dyn Fn(usize, usize) -> c64| {
                for (i, row) in rows.iter().enumerate() {
                    for (c, j) in columns.clone().enumerate() {
                        out[i * nc + j] = row.iter().map(|&(p, v)| x(p, c) * v).sum();
                    }
                }
            };
            match self {
                SparseLu::Real(lu) => {
                    let mut rhs = Mat::<f64>::zeros(self.dim(), width);
                    for (c, j) in columns.clone().enumerate() {
                        for &(p, v) in &rows[j] {
                            rhs[(p, c)] = v;
                        }
                    }
                    let x = lu.solve(&rhs);
                    product(&|p, c| c64::new(x[(p, c)], 0.0));
                }
                SparseLu::Complex(lu) => {
                    let mut rhs = Mat::<c64>::zeros(self.dim(), width);
                    for (c, j) in columns.clone().enumerate() {
                        for &(p, v) in &rows[j] {
                            rhs[(p, c)] = c64::new(v, 0.0);
                        }
                    }
                    let x = lu.solve(&rhs);
                    product(&|p, c| x[(p, c)]);
                }
            }
            start += width;
        }
        out
    }

    pub fn solve(&self, rhs: &[c64]) -> Vec<c64> {
        self.solve_many(&[rhs.to_vec()]).pop().unwrap_or_default()
    }
}

/// One factorization of Z_k, by whichever path its estimated cost chose (`System::factor`):
/// faer's pivoting sparse LU, or the kept complex symmetric LDLᵀ of `schur`, which also
/// carries G = B Z_k⁻¹ Bᵀ from the same elimination; or no factorization at all, the
/// Galerkin solve of a reduced model (`modal`), whose solves the caller checks.
pub enum Factor {
    Lu(Box<SparseLu>),
    Ldlt(schur::LdltFactor),
    Modal(modal::ModalFactor),
}

impl Factor {
    pub fn dim(&self) -> usize {
        match self {
            Factor::Lu(lu) => lu.dim(),
            Factor::Ldlt(f) => f.dim(),
            Factor::Modal(f) => f.dim(),
        }
    }

    pub fn is_ldlt(&self) -> bool {
        matches!(self, Factor::Ldlt(_))
    }

    pub fn solve(&self, rhs: &[c64]) -> Vec<c64> {
        match self {
            Factor::Lu(lu) => lu.solve(rhs),
            Factor::Ldlt(f) => f.solve(rhs),
            Factor::Modal(f) => f.solve(rhs),
        }
    }

    /// The solution the factorization's own check computed, when `rhs` is its right-hand
    /// side (the load: saves the linear solve one pass over the factor).
    pub fn solution_of(&self, rhs: &[c64]) -> Option<Vec<c64>> {
        match self {
            Factor::Ldlt(f) => f
                .checked
                .as_ref()
                .filter(|(b, _)| b == rhs)
                .map(|(_, x)| x.clone()),
            Factor::Lu(_) | Factor::Modal(_) => None,
        }
    }

    pub fn solve_many(&self, rhs: &[Vec<c64>]) -> Vec<Vec<c64>> {
        match self {
            Factor::Lu(lu) => lu.solve_many(rhs),
            Factor::Ldlt(f) => f.solve_many(rhs),
            Factor::Modal(f) => f.solve_many(rhs),
        }
    }

    /// B Z⁻¹ b: the LDLᵀ's forward half when its plan was built for this B, else a solve.
    pub fn contact_rows_of_solve(&self, b: &Csc, rhs: &[c64]) -> Vec<c64> {
        match self {
            Factor::Ldlt(f) if f.plan().built_for(b) => f.contact_rows_of_solve(rhs),
            _ => b.mul_complex(&self.solve(rhs)),
        }
    }

    /// G = B Z⁻¹ Bᵀ (row-major n_c²): the LDLᵀ's own when its plan was built for this B,
    /// else blocked solves.
    pub fn compliance(&self, b: &Csc) -> Vec<c64> {
        match self {
            Factor::Lu(lu) => lu.compliance(b),
            Factor::Ldlt(f) if f.plan().built_for(b) => f.compliance().to_vec(),
            Factor::Modal(f) if f.built_for(b) => f.compliance(),
            Factor::Ldlt(_) | Factor::Modal(_) => {
                let nc = b.nrows;
                let x = self.solve_many(&complex_columns(&b.dense_rows()));
                let mut out = vec![c64::new(0.0, 0.0); nc * nc];
                for (j, xj) in x.iter().enumerate() {
                    let bx = b.mul_complex(xj);
                    for (i, v) in bx.into_iter().enumerate() {
                        out[i * nc + j] = v;
                    }
                }
                out
            }
        }
    }
}

/// Real columns as complex ones (the right-hand sides a complex factor solves).
pub fn complex_columns(columns: &[Vec<f64>]) -> Vec<Vec<c64>> {
    columns
        .iter()
        .map(|c| c.iter().map(|&v| c64::new(v, 0.0)).collect())
        .collect()
}

/// Solve a real sparse system A x = b once (tests and small static problems).
pub fn solve_real(a: &Csc, b: &[f64]) -> Result<Vec<f64>> {
    let pattern = LuPattern::analyse(a)?;
    let lu = SparseLu::factor_real(&pattern, a)?;
    let rhs: Vec<c64> = b.iter().map(|&v| c64::new(v, 0.0)).collect();
    Ok(lu.solve(&rhs).into_iter().map(|z| z.re).collect())
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

/// The eigenvalues and right eigenvectors (columns, complex) of a real square `a`, on the
/// calling thread below `DENSE_PARALLEL_ORDER` (faer's `eigen()` uses its global pool
/// whatever the order, which made a 132 × 132 Hessenberg matrix 2.7× slower on 2 cores).
pub fn eigen_real(a: faer::MatRef<'_, f64>) -> Result<(Vec<c64>, Mat<c64>)> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::evd::{self, ComputeEigenvectors};
    let n = a.nrows();
    let par = dense_parallelism(n);
    let (mut u, mut re, mut im) = (
        Mat::<f64>::zeros(n, n),
        faer::diag::Diag::<f64>::zeros(n),
        faer::diag::Diag::<f64>::zeros(n),
    );
    let scratch = evd::evd_scratch::<f64>(
        n,
        ComputeEigenvectors::No,
        ComputeEigenvectors::Yes,
        par,
        Default::default(),
    );
    evd::evd_real(
        a,
        re.as_mut(),
        im.as_mut(),
        None,
        Some(u.as_mut()),
        par,
        MemStack::new(&mut MemBuffer::new(scratch)),
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
            // w = b − A x (b itself from x = 0).
            if x.iter().all(|&xi| xi == 0.0) {
                w.copy_from_slice(b);
            } else {
                apply(x, w);
                w.iter_mut().zip(b).for_each(|(wi, bi)| *wi = bi - *wi);
            }
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
                for (i, vi) in v.chunks_exact(n).enumerate() {
                    let hij = dot(w, vi);
                    h[i * restart + j] = hij;
                    for (wk, vk) in w.iter_mut().zip(vi) {
                        *wk -= hij * vk;
                    }
                }
                let wn = norm(w);
                h[(j + 1) * restart + j] = wn;
                for i in 0..j {
                    let (a, b) = (h[i * restart + j], h[(i + 1) * restart + j]);
                    h[i * restart + j] = cs[i] * a + sn[i] * b;
                    h[(i + 1) * restart + j] = -sn[i] * a + cs[i] * b;
                }
                let (a, b) = (h[j * restart + j], h[(j + 1) * restart + j]);
                let d = (a * a + b * b).sqrt();
                if d == 0.0 {
                    break;
                }
                cs[j] = a / d;
                sn[j] = b / d;
                h[j * restart + j] = d;
                h[(j + 1) * restart + j] = 0.0;
                g[j + 1] = -sn[j] * g[j];
                g[j] *= cs[j];
                used = j + 1;
                last = g[j + 1].abs() / b_norm;
                if last <= tolerance || wn == 0.0 {
                    converged = true;
                    break;
                }
                v.extend(w.iter().map(|a| a / wn));
            }
            // Back substitution for y (in g's first entries), then x += Z y.
            for i in (0..used).rev() {
                let s: f64 = ((i + 1)..used).map(|k| h[i * restart + k] * g[k]).sum();
                g[i] = (g[i] - s) / h[i * restart + i];
            }
            for (yk, zk) in g[..used].iter().zip(z.chunks_exact(n)) {
                for (xi, zi) in x.iter_mut().zip(zk) {
                    *xi += yk * zi;
                }
            }
            if converged {
                return Ok(());
            }
        }
        Err(last)
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

    #[test]
    fn lu_solves_a_small_real_and_complex_system() {
        // [[4, 1], [1, 3]] x = [1, 2]  →  x = [1/11, 7/11]
        let a = Csc::from_entries(2, 2, &[(0, 0, 4.0), (0, 1, 1.0), (1, 0, 1.0), (1, 1, 3.0)]);
        let x = solve_real(&a, &[1.0, 2.0]).unwrap();
        assert!((x[0] - 1.0 / 11.0).abs() < 1e-14 && (x[1] - 7.0 / 11.0).abs() < 1e-14);
        // (A + i I) z = [1, 0]: check the residual.
        let pattern = LuPattern::analyse(&a).unwrap();
        let im = vec![1.0, 0.0, 0.0, 1.0]; // values in column-major pattern order: (0,0),(1,0),(0,1),(1,1)
        let lu = SparseLu::factor_complex(&pattern, &a, &im).unwrap();
        let z = lu.solve(&[c64::new(1.0, 0.0), c64::new(0.0, 0.0)]);
        let r0 = c64::new(4.0, 1.0) * z[0] + z[1] - c64::new(1.0, 0.0);
        let r1 = z[0] + c64::new(3.0, 1.0) * z[1];
        assert!(r0.norm() < 1e-14 && r1.norm() < 1e-14);
    }

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

    #[test]
    fn duplicates_add_and_common_pattern_keeps_values() {
        let a = Csc::from_entries(2, 2, &[(0, 0, 1.0), (0, 0, 2.0), (1, 1, 5.0)]);
        assert_eq!(a.nnz(), 2);
        assert_eq!(a.mul_vec(&[1.0, 1.0]), vec![3.0, 5.0]);
        let b = Csc::from_entries(2, 2, &[(1, 0, 7.0)]);
        let common = Csc::on_common_pattern(&[&a, &b]);
        assert_eq!(common[0].nnz(), 3);
        assert_eq!(common[0].mul_vec(&[1.0, 1.0]), vec![3.0, 5.0]);
        assert_eq!(common[1].mul_vec(&[1.0, 0.0]), vec![0.0, 7.0]);
    }

    /// TEST GOAL: where the first pattern holds the others (a lumped mass on the stiffness'
    /// diagonal), the common pattern is the first's, and each matrix keeps its values on it,
    /// as the general merge gives them.
    #[test]
    fn a_pattern_within_the_first_is_scattered_into_it() {
        let k = Csc::from_entries(
            3,
            3,
            &[
                (0, 0, 2.0),
                (1, 0, -1.0),
                (0, 1, -1.0),
                (1, 1, 2.0),
                (2, 2, 1.0),
            ],
        );
        let m = Csc::from_entries(3, 3, &[(0, 0, 0.5), (2, 2, 0.25)]);
        let common = Csc::on_common_pattern(&[&k, &m]);
        assert_eq!(common[0], k);
        assert_eq!(
            (&common[1].col_ptr, &common[1].row_idx),
            (&k.col_ptr, &k.row_idx)
        );
        assert_eq!(common[1].values, vec![0.5, 0.0, 0.0, 0.0, 0.25]);
        // The other way round m does not hold k: the merged pattern is k's all the same.
        let swapped = Csc::on_common_pattern(&[&m, &k]);
        assert_eq!((&swapped[1], &swapped[0]), (&common[0], &common[1]));
    }

    /// TEST GOAL: `from_entries` leaves each column's rows sorted and distinct, whatever the
    /// order the entries come in, so faer takes the arrays as they are; a hand-made CSC with
    /// its rows out of order goes through faer's own sort and factors to the same solution.
    #[test]
    fn csc_columns_come_out_sorted_and_both_faer_paths_agree() {
        let entries = [
            (2, 0, 1.0),
            (0, 0, 4.0),
            (1, 1, 4.0),
            (2, 0, 0.5),
            (0, 2, 1.5),
            (2, 2, 4.0),
            (0, 0, 1.0),
        ];
        let a = Csc::from_entries(3, 3, &entries);
        assert_eq!(a.col_ptr, vec![0, 2, 3, 5]);
        assert_eq!(a.row_idx, vec![0, 2, 1, 0, 2]);
        assert_eq!(a.values, vec![5.0, 1.5, 4.0, 1.5, 4.0]);
        let shuffled = Csc {
            row_idx: vec![2, 0, 1, 2, 0],
            values: vec![1.5, 5.0, 4.0, 4.0, 1.5],
            ..a.clone()
        };
        let b = [1.0, 2.0, 3.0];
        let (x, y) = (
            solve_real(&a, &b).unwrap(),
            solve_real(&shuffled, &b).unwrap(),
        );
        assert!(
            x.iter().zip(&y).all(|(p, q)| (p - q).abs() < 1e-15),
            "{x:?} {y:?}"
        );
        let ax = a.mul_vec(&x);
        assert!(
            ax.iter().zip(&b).all(|(p, q)| (p - q).abs() < 1e-14),
            "{ax:?}"
        );
    }
}
