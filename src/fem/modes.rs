//! Natural frequencies and mode shapes: K φ = ω² M φ on already-reduced (free-dof) matrices, by
//! shift-invert block Lanczos with full reorthogonalization and Rayleigh–Ritz (Golub & Van
//! Loan, Matrix Computations, §10.3; Ericsson & Ruhe's spectral transformation), and the modal
//! quantities an engineer reads next to them.
//!
//! Glossary:
//! - σ the shift (an ω²): the iteration converges first to the eigenvalues nearest σ;
//! - Q the M-orthonormal basis of the block Krylov space of (K − σM)⁻¹M, grown `BLOCK`
//!   vectors at a time; the Ritz pairs are those of QᵀKQ;
//! - r_d the influence vector of direction d (1 on every free dof of component d, 0 elsewhere);
//! - Γ_d = φᵀ M r_d / φᵀ M φ the participation factor, m_eff,d = (φᵀ M r_d)² / φᵀ M φ the
//!   effective modal mass; summed over all modes it is r_dᵀ M r_d, the mass the supports let
//!   move in d (Chopra, Dynamics of Structures, §13.2);
//! - ζ_n = α/(2ω_n) + β ω_n/2 the modal damping ratio of Rayleigh damping D = αM + βK.
//!
//! Used by `hbcontact modes`, by the resonance check of every run, by Hill's stability check
//! (`modes_below`, the modes it keeps dynamic) and by the tests against beam theory.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::linalg::{dot, Csc, LuPattern, SparseLlt, SparseLu};
use crate::{Error, Result};

/// An eigenpair (ω², φ) with φ M-normalized (φᵀ M φ = 1).
pub type Mode = (f64, Vec<f64>);

/// The `count` eigenpairs whose ω² lie nearest `shift` (on either side; 0 gives the lowest),
/// ascending in ω².
pub fn lowest_modes(k: &Csc, m: &Csc, count: usize, shift: f64) -> Result<Vec<Mode>> {
    let mut modes = block_krylov((k, m), Wanted::Nearest(count), shift, TOLERANCE, None)?;
    modes.truncate(count);
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes)
}

/// A quick look near `shift`: the `count` eigenpairs nearest it, their ω² settled to 1e-6
/// (frequencies to 5e-7), ascending in ω². For deciding
/// how near a frequency sits to a mode, at the cost of one factorization and a few dozen
/// solves; `pattern`, when given, is a symbolic analysis of K's pattern to reuse.
pub fn modes_near(
    k: &Csc,
    m: &Csc,
    count: usize,
    shift: f64,
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let mut modes = block_krylov((k, m), Wanted::Nearest(count), shift, QUICK, pattern)?;
    modes.truncate(count);
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes)
}

/// The ω² of `modes_near` settle to this (frequencies to 5e-7).
const QUICK: f64 = 1e-6;

/// The lowest modes up to ω² = `bound`, at least `least` and at most `most` of them, and the
/// next one above them, ascending in ω²: every mode below the last one returned is among
/// them (what a Hill model, and a resonance check below its last mode, need). All but the
/// last settle as `lowest_modes`'s (a multiplier e^{iω_n T} of a mode at 10ω moves by
/// 63·δω_n/ω_n, so its ω² must settle far below 1e-6); the last, which only bounds them,
/// as `modes_near`'s. `pattern` as for `modes_near`.
pub fn modes_below(
    (k, m): (&Csc, &Csc),
    bound: f64,
    (least, most): (usize, usize),
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let wanted = Wanted::Below { bound, least, most };
    let mut modes = block_krylov((k, m), wanted, 0.0, TOLERANCE, pattern)?;
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes)
}

/// K − σM on the common pattern of K and M (K's own when M shares it, as `System`'s do).
fn shifted(k: &Csc, m: &Csc, shift: f64) -> Result<Csc> {
    if k.col_ptr == m.col_ptr && k.row_idx == m.row_idx {
        let mut a = k.clone();
        a.values
            .iter_mut()
            .zip(&m.values)
            .for_each(|(v, w)| *v -= shift * w);
        return Ok(a);
    }
    let mut common = Csc::on_common_pattern(&[k, m]).into_iter();
    let (Some(mut a), Some(mm)) = (common.next(), common.next()) else {
        return Err(Error::Model("internal: modes pattern".into()));
    };
    for (v, w) in a.values.iter_mut().zip(&mm.values) {
        *v -= shift * w;
    }
    Ok(a)
}

/// Deterministic pseudo-random start vectors (`seed` shifts the sequence).
fn start_vectors(n: usize, p: usize, seed: usize) -> Vec<Vec<f64>> {
    (seed..seed + p)
        .map(|j| {
            (0..n)
                .map(|i| {
                    (((i * 7919 + j * 104_729) % 1000) as f64 / 1000.0) - 0.5
                        + if i % p.max(1) == j % p.max(1) {
                            1.0
                        } else {
                            0.0
                        }
                })
                .collect()
        })
        .collect()
}

/// Relative change of the Ritz values below which they count as converged (frequencies to
/// 5e-9: far below any discretization error).
const TOLERANCE: f64 = 1e-8;

/// Vectors per block of the Krylov space: a mode of multiplicity up to `BLOCK` is found with
/// all its copies (a single-vector Lanczos sees one direction of each eigenspace).
const BLOCK: usize = 6;

/// Which Ritz values must settle before the Krylov space stops growing.
#[derive(Clone, Copy, Debug)]
enum Wanted {
    /// The `count` nearest σ.
    Nearest(usize),
    /// Those at or below `bound` (an ω², σ = 0), at least `least` and at most `most`, and the
    /// one next above them: once it has settled too, no mode below it is missing.
    Below {
        bound: f64,
        least: usize,
        most: usize,
    },
}

impl Wanted {
    /// How many of the Ritz values `values` (nearest σ first) must settle.
    fn count(self, values: &[f64]) -> usize {
        match self {
            Wanted::Nearest(count) => count,
            Wanted::Below { bound, least, most } => {
                let below = values.iter().filter(|&&v| v <= bound).count();
                below.max(least).min(most.max(least)) + 1
            }
        }
    }

    /// Whether the Ritz values have settled: the newest (nearest σ first) against those one
    /// block before, whose own changes were `changes`. Each value settles to `tolerance`,
    /// except the sentinel of `Below` (the one above the wanted, which only shows that none
    /// is missing) to `QUICK`: its change d is below that bound, or the change d²/d′ the next
    /// block would make (d′ the change before; Krylov convergence is at least geometric) is
    /// below a tenth of it while d fell fourfold. Returns the changes for the next check.
    fn settled(
        self,
        values: &[f64],
        previous: &[f64],
        changes: &[f64],
        tolerance: f64,
    ) -> (bool, Vec<f64>) {
        if values.len() != previous.len() {
            return (false, Vec::new());
        }
        let sentinel = matches!(self, Wanted::Below { .. }).then(|| values.len().saturating_sub(1));
        let now: Vec<f64> = (values.iter().zip(previous))
            .map(|(a, b)| ((a - b) / a).abs())
            .collect();
        let settled = now.iter().enumerate().all(|(i, &d)| {
            let bound = if Some(i) == sentinel {
                QUICK.max(tolerance)
            } else {
                tolerance
            };
            let predicted = changes
                .get(i)
                .is_some_and(|&before| d < 0.25 * before && d * d / before < 0.1 * bound);
            d < bound || predicted
        });
        (settled, now)
    }

    /// The most values that may be asked to settle.
    fn most(self) -> usize {
        match self {
            Wanted::Nearest(count) => count,
            Wanted::Below { most, .. } => most + 1,
        }
    }

    /// The fewest values that may be asked to settle.
    fn least(self) -> usize {
        match self {
            Wanted::Nearest(count) => count,
            Wanted::Below { least, .. } => least + 1,
        }
    }
}

/// The factorization of K − σM the Lanczos iteration solves with: Cholesky at σ ≤ 0, where
/// K − σM is positive definite on a supported structure (half the LU's work, no pivoting),
/// else (or where Cholesky meets a pivot that is not positive: rigid-body modes) the LU.
enum RealFactor {
    Llt(SparseLlt),
    Lu(Box<SparseLu>),
}

impl RealFactor {
    fn of(a: &Csc, shift: f64, pattern: Option<&LuPattern>) -> Result<RealFactor> {
        if let Some(llt) = (shift <= 0.0).then(|| SparseLlt::factor(a).ok()).flatten() {
            return Ok(RealFactor::Llt(llt));
        }
        Ok(RealFactor::Lu(Box::new(match pattern {
            Some(pattern) => SparseLu::factor_real(pattern, a)?,
            None => SparseLu::factor_real(&LuPattern::analyse(a)?, a)?,
        })))
    }

    fn solve_many(&self, rhs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        match self {
            RealFactor::Llt(llt) => llt.solve_many(rhs),
            RealFactor::Lu(lu) => lu.solve_real_many(rhs),
        }
    }
}

/// Block Lanczos with full reorthogonalization: an M-orthonormal basis Q of the block Krylov
/// space of (K − σM)⁻¹ M grows by `BLOCK` vectors at a time; Rayleigh–Ritz on span(Q) gives
/// the Ritz values, checked after each block, until the `wanted` ones settle to
/// `tolerance` (or the space stops growing: then it holds every mode M can excite, and
/// its Ritz pairs are exact). Returns the settled Ritz pairs ordered by distance to σ
/// (nearest first). The Krylov space converges where subspace iteration stalls on the ratio
/// of the wanted to the first unwanted eigenvalue: a few dozen solves instead of hundreds.
fn block_krylov(
    (k, m): (&Csc, &Csc),
    wanted: Wanted,
    shift: f64,
    tolerance: f64,
    pattern: Option<&LuPattern>,
) -> Result<Vec<Mode>> {
    let n = k.nrows;
    let a = shifted(k, m, shift)?;
    let factor = RealFactor::of(&a, shift, pattern)?;
    let limit = (6 * wanted.most() + 60).min(n);
    let mut space = MSpace::default();
    let start = start_vectors(n, BLOCK.min(n), 0);
    let mut block = factor.solve_many(&start.iter().map(|x| m.mul_vec(x)).collect::<Vec<_>>());
    let (mut previous, mut changes) = (Vec::new(), Vec::new());
    loop {
        let added = space.extend(k, m, block);
        if added.is_empty() || space.len() >= limit {
            break;
        }
        if space.len() >= wanted.least().min(n) + BLOCK {
            let values = space.values_nearest(shift, wanted);
            let settled;
            (settled, changes) = wanted.settled(&values, &previous, &changes, tolerance);
            if settled {
                break;
            }
            previous = values;
        }
        block = factor.solve_many(&space.m_columns(added));
    }
    let count = wanted.count(&space.values_nearest(shift, Wanted::Nearest(n)));
    space.ritz_pairs(shift, count.min(n))
}

/// Sequential below this many mul-adds (a pool's start costs more than the product saves).
const PARALLEL_FLOPS: usize = 1 << 22;

/// The parallelism of a dense product of `flops` mul-adds.
fn parallelism(flops: usize) -> faer::Par {
    if flops < PARALLEL_FLOPS {
        faer::Par::Seq
    } else {
        faer::get_global_parallelism()
    }
}

/// y ← y + a x.
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

/// An M-orthonormal basis Q with M Q and the projection QᵀKQ kept beside it, grown a block
/// at a time (Rayleigh–Ritz without recomputing what earlier blocks gave). Q and MQ are held
/// column-major in one slice each, so projections against them are matrix products.
#[derive(Default)]
struct MSpace {
    /// The length of a column.
    n: usize,
    q: Vec<f64>,
    mq: Vec<f64>,
    /// QᵀKQ, row i the products of q_i with K q_0 … K q_i.
    kr: Vec<Vec<f64>>,
}

impl MSpace {
    fn len(&self) -> usize {
        self.kr.len()
    }

    fn column(&self, j: usize) -> &[f64] {
        &self.q[j * self.n..(j + 1) * self.n]
    }

    /// Q (or MQ) as a matrix.
    fn basis<'a>(&self, values: &'a [f64]) -> faer::MatRef<'a, f64> {
        faer::MatRef::from_column_major_slice(&values[..self.len() * self.n], self.n, self.len())
    }

    /// y ← y − Q (MQ)ᵀ y and my ← my − MQ (MQ)ᵀ y over all of Q: one classical
    /// Gram–Schmidt pass as matrix products, M y kept without another product with M.
    fn project_out(&self, y: &mut faer::Mat<f64>, my: &mut faer::Mat<f64>) {
        use faer::linalg::matmul::matmul;
        use faer::Accum;
        if self.len() == 0 {
            return;
        }
        let par = parallelism(self.n * self.len() * y.ncols());
        let (q, mq) = (self.basis(&self.q), self.basis(&self.mq));
        let mut c = faer::Mat::<f64>::zeros(q.ncols(), y.ncols());
        matmul(&mut c, Accum::Replace, mq.transpose(), y.as_ref(), 1.0, par);
        matmul(y.as_mut(), Accum::Add, q, c.as_ref(), -1.0, par);
        matmul(my.as_mut(), Accum::Add, mq, c.as_ref(), -1.0, par);
    }

    /// Orthonormalize `y` against Q and itself (Gram–Schmidt twice in the M inner product:
    /// against Q as a block, within `y` a column at a time) and append what is left; a column
    /// (numerically) in the span already is dropped. Returns where the appended columns lie. M y is
    /// formed once and updated along (every update is linear), and QᵀKQ grows by the block
    /// Qᵀ(K Q_new) in one product.
    fn extend(&mut self, k: &Csc, m: &Csc, y: Vec<Vec<f64>>) -> std::ops::Range<usize> {
        let first = self.len();
        if self.n == 0 {
            self.n = y.first().map_or(0, Vec::len);
        }
        let n = self.n;
        let mut block = faer::Mat::<f64>::from_fn(n, y.len(), |i, c| y[c][i]);
        let my: Vec<Vec<f64>> = y.iter().map(|c| m.mul_vec(c)).collect();
        let mut mblock = faer::Mat::<f64>::from_fn(n, y.len(), |i, c| my[c][i]);
        let before: Vec<f64> = (0..y.len())
            .map(|c| dot(&y[c], &my[c]).max(0.0).sqrt())
            .collect();
        for _ in 0..2 {
            self.project_out(&mut block, &mut mblock);
        }
        for (c, before) in before.into_iter().enumerate() {
            let mut col: Vec<f64> = block.col(c).iter().copied().collect();
            let mut mcol: Vec<f64> = mblock.col(c).iter().copied().collect();
            for _ in 0..2 {
                for j in first..self.len() {
                    let coefficient = dot(&self.mq[j * n..(j + 1) * n], &col);
                    axpy(-coefficient, &self.q[j * n..(j + 1) * n], &mut col);
                    axpy(-coefficient, &self.mq[j * n..(j + 1) * n], &mut mcol);
                }
            }
            let norm = dot(&col, &mcol).max(0.0).sqrt();
            if norm > 1e-10 * before && norm > 0.0 {
                self.q.extend(col.iter().map(|v| v / norm));
                self.mq.extend(mcol.iter().map(|v| v / norm));
                self.kr.push(Vec::new());
            }
        }
        self.project_k(k, first);
        first..self.len()
    }

    /// The columns `range` of M Q.
    fn m_columns(&self, range: std::ops::Range<usize>) -> Vec<Vec<f64>> {
        (range.map(|j| self.mq[j * self.n..(j + 1) * self.n].to_vec())).collect()
    }

    /// The rows of QᵀKQ of Q's columns `first..`: K Q_new, then Qᵀ (K Q_new) as one product.
    fn project_k(&mut self, k: &Csc, first: usize) {
        use faer::linalg::matmul::matmul;
        let (n, p) = (self.n, self.len());
        if p == first {
            return;
        }
        let kq: Vec<Vec<f64>> = (first..p).map(|j| k.mul_vec(self.column(j))).collect();
        let kq = faer::Mat::<f64>::from_fn(n, p - first, |i, c| kq[c][i]);
        let mut rows = faer::Mat::<f64>::zeros(p, p - first);
        let par = parallelism(n * p * (p - first));
        let q = self.basis(&self.q);
        matmul(
            &mut rows,
            faer::Accum::Replace,
            q.transpose(),
            kq.as_ref(),
            1.0,
            par,
        );
        for j in first..p {
            self.kr[j] = (0..=j).map(|i| rows[(i, j - first)]).collect();
        }
    }

    /// The symmetric eigen-decomposition of QᵀKQ (the Ritz problem: Q is M-orthonormal).
    fn projected(&self) -> SymmetricEigen<f64, nalgebra::Dyn> {
        SymmetricEigen::new(self.projection())
    }

    /// QᵀKQ, symmetric.
    fn projection(&self) -> DMatrix<f64> {
        let p = self.len();
        DMatrix::from_fn(p, p, |i, j| self.kr[i.max(j)][i.min(j)])
    }

    /// The `wanted` Ritz values, nearest σ first.
    fn values_nearest(&self, shift: f64, wanted: Wanted) -> Vec<f64> {
        let eigenvalues = self.projection().symmetric_eigenvalues();
        let mut values: Vec<f64> = eigenvalues.iter().copied().collect();
        values.sort_by(|a, b| (a - shift).abs().total_cmp(&(b - shift).abs()));
        values.truncate(wanted.count(&values));
        values
    }

    /// The `count` Ritz pairs nearest σ, nearest first, the vectors M-orthonormal.
    fn ritz_pairs(&self, shift: f64, count: usize) -> Result<Vec<Mode>> {
        let n = self.n;
        if self.len() == 0 {
            return Err(Error::Model(
                "mode extraction: the mass matrix is zero on every trial vector (massless dofs?)"
                    .into(),
            ));
        }
        let eig = self.projected();
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by(|&a, &b| {
            (eig.eigenvalues[a] - shift)
                .abs()
                .total_cmp(&(eig.eigenvalues[b] - shift).abs())
        });
        order.truncate(count);
        let mut pairs: Vec<Mode> = (order.into_iter())
            .map(|c| {
                let mut v = vec![0.0; n];
                for r in 0..self.len() {
                    let (w, qr) = (eig.eigenvectors[(r, c)], self.column(r));
                    v.iter_mut().zip(qr).for_each(|(vi, qi)| *vi += w * qi);
                }
                (eig.eigenvalues[c], v)
            })
            .collect();
        pairs.sort_by(|a, b| (a.0 - shift).abs().total_cmp(&(b.0 - shift).abs()));
        Ok(pairs)
    }
}

/// The modal damping ratio ζ = α/(2ω) + βω/2 of Rayleigh damping at angular frequency ω
/// (0 without damping).
pub fn rayleigh_damping_ratio(rayleigh: Option<(f64, f64)>, omega: f64) -> f64 {
    match rayleigh {
        Some((alpha, beta)) if omega > 0.0 => alpha / (2.0 * omega) + beta * omega / 2.0,
        _ => 0.0,
    }
}

/// The effective modal mass (φᵀ M r)² / φᵀ M φ of mode φ in direction `component` (0 x, 1 y),
/// with `component_of[i]` the component of free dof i.
pub fn effective_mass(m: &Csc, phi: &[f64], component_of: &[usize], component: usize) -> f64 {
    let r: Vec<f64> = component_of
        .iter()
        .map(|&c| if c == component { 1.0 } else { 0.0 })
        .collect();
    let mphi = m.mul_vec(phi);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let modal_mass = dot(phi, &mphi);
    if modal_mass > 0.0 {
        dot(&mphi, &r).powi(2) / modal_mass
    } else {
        0.0
    }
}

/// r_dᵀ M r_d: the mass the supports let move in direction `component` (what the effective
/// masses of all modes sum to).
pub fn free_mass(m: &Csc, component_of: &[usize], component: usize) -> f64 {
    let r: Vec<f64> = component_of
        .iter()
        .map(|&c| if c == component { 1.0 } else { 0.0 })
        .collect();
    m.mul_vec(&r).iter().zip(&r).map(|(a, b)| a * b).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: K − σM is factored by Cholesky where it is positive definite and by LU
    /// where it is not (an indefinite matrix, or σ > 0), and both solve it.
    #[test]
    fn cholesky_serves_a_positive_definite_matrix_and_lu_the_others() {
        let spd = Csc::from_entries(2, 2, &[(0, 0, 4.0), (0, 1, 1.0), (1, 0, 1.0), (1, 1, 3.0)]);
        let indefinite =
            Csc::from_entries(2, 2, &[(0, 0, 1.0), (0, 1, 2.0), (1, 0, 2.0), (1, 1, 1.0)]);
        let cases = [
            (&spd, 0.0, true),
            (&indefinite, 0.0, false),
            (&spd, 1.0, false),
        ];
        for (a, shift, cholesky) in cases {
            let factor = RealFactor::of(a, shift, None).unwrap();
            assert_eq!(matches!(factor, RealFactor::Llt(_)), cholesky);
            let x = &factor.solve_many(&[vec![1.0, 2.0]])[0];
            let ax = a.mul_vec(x);
            assert!(
                (ax[0] - 1.0).abs() < 1e-14 && (ax[1] - 2.0).abs() < 1e-14,
                "{ax:?}"
            );
        }
    }
}
