//! Sparse matrices: triplets (duplicates add up) and compressed sparse columns A (rows
//! sorted and distinct per column), restricted to the free dofs, merged onto a common
//! pattern, and the products y = A x of the solvers.

use faer::c64;
use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};

use crate::{Error, Result};

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
    /// [self; below]: the rows of `below` appended after this matrix's (same columns).
    pub fn stacked(&self, below: &Csc) -> Csc {
        debug_assert_eq!(self.ncols, below.ncols);
        let mut out = Csc {
            nrows: self.nrows + below.nrows,
            ncols: self.ncols,
            col_ptr: vec![0],
            row_idx: Vec::with_capacity(self.row_idx.len() + below.row_idx.len()),
            values: Vec::with_capacity(self.values.len() + below.values.len()),
        };
        for j in 0..self.ncols {
            let (a, b) = (
                self.col_ptr[j]..self.col_ptr[j + 1],
                below.col_ptr[j]..below.col_ptr[j + 1],
            );
            out.row_idx.extend_from_slice(&self.row_idx[a.clone()]);
            out.values.extend_from_slice(&self.values[a]);
            out.row_idx
                .extend(below.row_idx[b.clone()].iter().map(|r| r + self.nrows));
            out.values.extend_from_slice(&below.values[b]);
            out.col_ptr.push(out.row_idx.len());
        }
        out
    }

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

    /// self + s·other (same shape), on the union of their patterns.
    pub fn plus_scaled(&self, other: &Csc, s: f64) -> Csc {
        let mut entries = Vec::with_capacity(self.nnz() + other.nnz());
        for (m, scale) in [(self, 1.0), (other, s)] {
            for j in 0..m.ncols {
                for p in m.col_ptr[j]..m.col_ptr[j + 1] {
                    entries.push((m.row_idx[p], j, scale * m.values[p]));
                }
            }
        }
        Csc::from_entries(self.nrows, self.ncols, &entries)
    }

    /// y = A x.
    pub fn mul_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.nrows];
        for (j, &xj) in x.iter().enumerate().take(self.ncols) {
            if xj != 0.0 {
                let span = self.col_ptr[j]..self.col_ptr[j + 1];
                let (rows, values) = (&self.row_idx[span.clone()], &self.values[span]);
                for (&i, &v) in rows.iter().zip(values) {
                    y[i] += v * xj;
                }
            }
        }
        y
    }

    /// y = Aᵀ x.
    pub fn mul_transpose_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.ncols];
        for (j, yj) in y.iter_mut().enumerate() {
            let span = self.col_ptr[j]..self.col_ptr[j + 1];
            let (rows, values) = (&self.row_idx[span.clone()], &self.values[span]);
            *yj = rows.iter().zip(values).map(|(&i, &v)| v * x[i]).sum();
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

    pub(super) fn faer_real(&self) -> Result<SparseColMat<usize, f64>> {
        self.faer_with(self.values.clone())
    }

    pub(super) fn faer_complex(&self, imag: Option<&[f64]>) -> Result<SparseColMat<usize, c64>> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::solve_real;

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
