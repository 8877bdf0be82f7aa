//! Sparse LU factorizations P A Q = L U (faer) whose symbolic analysis is shared by every
//! matrix of the same pattern (all harmonics, all frequencies of a sweep), real or complex
//! (A + i B), and the solves with them.

use faer::c64;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::Mat;

use super::{modal, schur, Csc};
use crate::{Error, Result};

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

    /// Solve for several real right-hand sides of a real factorization (a complex one solves
    /// them as complex columns and keeps the real part).
    pub fn solve_real_many(&self, rhs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let (n, k) = (self.dim(), rhs.len());
        let SparseLu::Real(lu) = self else {
            let complex = complex_columns(rhs);
            return (self.solve_many(&complex).into_iter())
                .map(|col| col.into_iter().map(|z| z.re).collect())
                .collect();
        };
        if k == 0 {
            return Vec::new();
        }
        let b = Mat::<f64>::from_fn(n, k, |i, c| rhs[c][i]);
        let x = lu.solve(&b);
        (0..k).map(|c| x.col(c).iter().copied().collect()).collect()
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

/// A sparse Cholesky factorization A = L Lᵀ of a real symmetric positive definite matrix
/// (faer's supernodal one; its own AMD analysis): about half the LU's work and storage, and
/// no pivoting. A matrix that is not positive definite is an error (the caller uses the LU).
pub struct SparseLlt(faer::sparse::linalg::solvers::Llt<usize, f64>);

impl SparseLlt {
    /// The analysis and factorization of `a` (its lower triangle is read).
    pub fn factor(a: &Csc) -> Result<Self> {
        use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
        let m = a.faer_real()?;
        let symbolic = SymbolicLlt::try_new(m.symbolic(), faer::Side::Lower)
            .map_err(|e| Error::Model(format!("sparse Cholesky analysis failed: {e:?}")))?;
        let llt = Llt::try_new_with_symbolic(symbolic, m.as_ref(), faer::Side::Lower)
            .map_err(|e| Error::Model(format!("sparse Cholesky factorization failed: {e:?}")))?;
        Ok(SparseLlt(llt))
    }

    /// Solve for several real right-hand sides (columns, each of length n).
    pub fn solve_many(&self, rhs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let n = faer::linalg::solvers::ShapeCore::nrows(&self.0);
        if rhs.is_empty() {
            return Vec::new();
        }
        let b = Mat::<f64>::from_fn(n, rhs.len(), |i, c| rhs[c][i]);
        let x = self.0.solve(&b);
        (0..rhs.len())
            .map(|c| x.col(c).iter().copied().collect())
            .collect()
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
}
