//! The numeric LDLᵀ of one complex symmetric A on a `SchurPlan`: the fronts eliminated
//! supernode by supernode (L, D kept, CBs extend-added into the parents), S⁻¹ = G, and the
//! solves x = T Ã⁻¹ Tᵀ b (forward with L, D⁻¹ and S⁻¹, backward with Lᵀ).

use std::sync::Arc;

use faer::c64;
use faer::{Mat, MatRef};

use super::*;

/// `SchurPlan::eliminate_all` as a `pulp::WithSimd` operation, so that `Arch::dispatch`
/// compiles it (and the front kernels it inlines) for the widest instruction set the machine
/// has, with a baseline fallback.
pub(super) struct Elimination<'a> {
    pub(super) plan: &'a SchurPlan,
    pub(super) schur: &'a mut [c64],
    pub(super) nk: usize,
    pub(super) tolerance: f64,
    pub(super) scratch: &'a mut Scratch,
}

impl pulp::WithSimd for Elimination<'_> {
    type Output = Result<Panels, String>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) -> Self::Output {
        let Elimination {
            plan,
            schur,
            nk,
            tolerance,
            scratch,
        } = self;
        plan.eliminate_all(simd, schur, nk, tolerance, scratch)
    }
}

/// One elimination's scratch: Ã's values, the local row numbers, the front, the trailing
/// update's product, the contribution blocks waiting for their parent, spent ones to reuse,
/// and S. Kept by the plan between eliminations: fresh zeroed buffers per supernode and per
/// harmonic cost more in page faults than the elimination itself (38% of the strip's
/// factorizations at H = 20 for the fronts alone).
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) values: Vec<c64>,
    pub(super) local: Vec<usize>,
    pub(super) front: Vec<c64>,
    pub(super) work: Vec<c64>,
    pub(super) blocks: Vec<Option<Vec<c64>>>,
    pub(super) spare: Vec<Vec<c64>>,
    pub(super) schur: Vec<c64>,
    pub(super) at: Vec<usize>,
}

/// Buffers handed back for reuse: the eliminations' scratch (one per elimination running at
/// a time) and the panels of dropped factors (a sweep refactors every harmonic at each ω;
/// fresh memory costs a page fault per 4 KiB, two thirds of the time of the strip's
/// elimination that fills it). It remembers whether a `take` found it empty, so that memory
/// touched ahead stops once the eliminations outrun it. A clone is an empty pool.
pub(super) struct Pool<T> {
    items: std::sync::Mutex<Vec<T>>,
    pub(super) ran_dry: std::sync::atomic::AtomicBool,
}

impl<T: Default> Pool<T> {
    pub(super) fn take(&self) -> T {
        let mut items = self.items.lock().unwrap_or_else(|e| e.into_inner());
        items.pop().unwrap_or_else(|| {
            self.ran_dry
                .store(true, std::sync::atomic::Ordering::Relaxed);
            T::default()
        })
    }

    pub(super) fn give_back(&self, item: T) {
        self.items
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(item);
    }

    pub(super) fn clear(&self) {
        self.items.lock().unwrap_or_else(|e| e.into_inner()).clear();
    }

    pub(super) fn ran_dry(&self) -> bool {
        self.ran_dry.load(std::sync::atomic::Ordering::Relaxed)
    }

    pub(super) fn refill_from_now(&self) {
        self.ran_dry
            .store(false, std::sync::atomic::Ordering::Relaxed);
    }
}

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Pool {
            items: std::sync::Mutex::new(Vec::new()),
            ran_dry: std::sync::atomic::AtomicBool::new(false),
        }
    }
}

impl<T> Clone for Pool<T> {
    fn clone(&self) -> Self {
        Pool::default()
    }
}

impl<T> std::fmt::Debug for Pool<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Pool")
    }
}

/// `v` as an m × m column-major matrix whose lower triangle is zero (its upper triangle is
/// never read), reusing its memory.
#[inline(always)]
pub(super) fn lower_zeros(v: &mut Vec<c64>, m: usize) -> &mut [c64] {
    let zero = c64::new(0.0, 0.0);
    if v.len() < m * m {
        v.resize(m * m, zero);
    }
    let front = &mut v[..m * m];
    for j in 0..m {
        front[j * m + j..(j + 1) * m].fill(zero);
    }
    front
}

/// `v` as `len` zeros, reusing its memory.
#[inline(always)]
pub(super) fn refill(v: &mut Vec<c64>, len: usize) -> &mut [c64] {
    v.clear();
    v.resize(len, c64::new(0.0, 0.0));
    v
}

/// The kept LDLᵀ of one A: solves with A and, with contact, G = B A⁻¹ Bᵀ.
pub struct LdltFactor {
    pub(super) plan: Arc<SchurPlan>,
    pub(super) panels: Panels,
    pub(super) s_inverse: Mat<c64>,
    pub(super) compliance: Vec<c64>,
    /// A right-hand side and its solution, kept by the caller's check (`System::factor`).
    pub checked: Option<(Vec<c64>, Vec<c64>)>,
}

impl Drop for LdltFactor {
    fn drop(&mut self) {
        self.plan
            .spare_panels
            .give_back(std::mem::take(&mut self.panels));
    }
}

impl LdltFactor {
    pub fn dim(&self) -> usize {
        self.plan.dim()
    }

    /// G = B A⁻¹ Bᵀ (row-major n_c × n_c) for the B of the plan (empty without contact).
    pub fn compliance(&self) -> &[c64] {
        &self.compliance
    }

    /// The plan this factor was computed with.
    pub fn plan(&self) -> &SchurPlan {
        &self.plan
    }

    /// Supernode s's panel (its pivot columns from the diagonal down, `trapezoid_column`).
    pub(super) fn panel(&self, s: usize) -> &[c64] {
        &self.panels[self.plan.panel_start[s]..self.plan.panel_start[s + 1]]
    }

    /// x = A⁻¹ b = T Ã⁻¹ Tᵀ b.
    pub fn solve(&self, b: &[c64]) -> Vec<c64> {
        self.solve_many(&[b.to_vec()]).pop().unwrap_or_default()
    }

    /// Several solves in one pass over the factor: each supernode's rows of all right-hand
    /// sides are gathered into a dense block, updated, and scattered back.
    pub fn solve_many(&self, rhs: &[Vec<c64>]) -> Vec<Vec<c64>> {
        let plan = &*self.plan;
        let r = rhs.len();
        let mut x = self.transformed(rhs);
        pulp::Arch::new().dispatch(Sweeps {
            factor: self,
            x: &mut x,
            r,
            backward: true,
        });
        (0..r)
            .map(|c| {
                plan.expansion
                    .iter()
                    .map(|e| e.iter().map(|&(q, w)| x[q * r + c] * w).sum())
                    .collect()
            })
            .collect()
    }

    /// B A⁻¹ b for the B of the plan, without the backward sweep: B T = E_n reads B x off
    /// the kept coordinates of x̃ = Ã⁻¹ Tᵀ b, which the forward sweep and S⁻¹ give.
    pub fn contact_rows_of_solve(&self, b: &[c64]) -> Vec<c64> {
        let plan = &*self.plan;
        let mut x = self.transformed(&[b]);
        pulp::Arch::new().dispatch(Sweeps {
            factor: self,
            x: &mut x,
            r: 1,
            backward: false,
        });
        plan.kept_of_row
            .iter()
            .map(|k| k.map_or(c64::new(0.0, 0.0), |k| x[plan.eliminated + k]))
            .collect()
    }

    /// Tᵀ b per right-hand side: x[q * r + c] is coordinate q of right-hand side c.
    fn transformed<B: AsRef<[c64]>>(&self, rhs: &[B]) -> Vec<c64> {
        let (n, r) = (self.plan.dim(), rhs.len());
        let mut x = vec![c64::new(0.0, 0.0); n * r];
        for (c, b) in rhs.iter().enumerate() {
            for (bd, e) in b.as_ref().iter().zip(&self.plan.expansion) {
                for &(q, w) in e {
                    x[q * r + c] += bd * w;
                }
            }
        }
        x
    }

    /// x ← D⁻¹ L⁻¹ x over the eliminated coordinates (the kept ones receive their updates).
    /// A supernode whose pivot rows are all zero changes nothing and is skipped: a right-hand
    /// side on the contact normals alone (Bᵀy) passes through untouched.
    #[inline(always)]
    fn forward<S: pulp::Simd>(&self, simd: S, x: &mut [c64], r: usize) {
        let mut local = Vec::new();
        let zero = c64::new(0.0, 0.0);
        for (s, node) in self.plan.supernodes.iter().enumerate() {
            let pivots = &node.rows[..node.pivots];
            if pivots
                .iter()
                .all(|&q| x[q * r..(q + 1) * r].iter().all(|v| *v == zero))
            {
                continue;
            }
            let l = self.panel(s);
            gather(&mut local, x, &node.rows, r);
            let m = node.rows.len();
            for k in 0..node.pivots {
                let (head, tail) = local.split_at_mut((k + 1) * r);
                let below = &trapezoid_column(l, m, k)[1..];
                if r == 1 {
                    subtract_multiple(simd, tail, below, head[k]);
                    continue;
                }
                let xk = &head[k * r..];
                for (row, &lik) in tail.chunks_exact_mut(r).zip(below) {
                    for (v, &xc) in row.iter_mut().zip(xk) {
                        *v -= lik * xc;
                    }
                }
            }
            for k in 0..node.pivots {
                let inv = trapezoid_column(l, m, k)[0].inv();
                local[k * r..(k + 1) * r].iter_mut().for_each(|v| *v *= inv);
            }
            scatter(&local, x, &node.rows, r);
        }
    }

    /// x_n ← S⁻¹ x_n on the kept coordinates.
    fn apply_s_inverse(&self, x: &mut [c64], r: usize) {
        let (e, nk) = (self.plan.eliminated, self.plan.kept());
        if nk > 0 {
            let xn = MatRef::from_row_major_slice(&x[e * r..], nk, r);
            let y = &self.s_inverse * xn;
            for i in 0..nk {
                for c in 0..r {
                    x[(e + i) * r + c] = y[(i, c)];
                }
            }
        }
    }

    /// x ← L⁻ᵀ x over the eliminated coordinates.
    #[inline(always)]
    fn backward<S: pulp::Simd>(&self, simd: S, x: &mut [c64], r: usize) {
        let mut local = Vec::new();
        for (s, node) in self.plan.supernodes.iter().enumerate().rev() {
            let l = self.panel(s);
            gather(&mut local, x, &node.rows, r);
            let m = node.rows.len();
            for k in (0..node.pivots).rev() {
                let (head, tail) = local.split_at_mut((k + 1) * r);
                let below = &trapezoid_column(l, m, k)[1..];
                if r == 1 {
                    head[k] -= dot(simd, tail, below);
                    continue;
                }
                let xk = &mut head[k * r..];
                for (row, &lik) in tail.chunks_exact(r).zip(below) {
                    for (v, &xc) in xk.iter_mut().zip(row) {
                        *v -= lik * xc;
                    }
                }
            }
            scatter(&local[..node.pivots * r], x, &node.rows[..node.pivots], r);
        }
    }
}

/// A solve's sweeps (forward, S⁻¹ and, if asked, backward) as a `pulp::WithSimd`
/// operation, compiled like `Elimination` for the widest instruction set the machine has:
/// their column updates are complex mul-adds, which SSE2 does by shuffles.
struct Sweeps<'a> {
    pub(super) factor: &'a LdltFactor,
    pub(super) x: &'a mut [c64],
    pub(super) r: usize,
    backward: bool,
}

impl pulp::WithSimd for Sweeps<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        let Sweeps {
            factor,
            x,
            r,
            backward,
        } = self;
        factor.forward(simd, x, r);
        factor.apply_s_inverse(x, r);
        if backward {
            factor.backward(simd, x, r);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::linalg::{LuPattern, SparseLu};

    /// TEST GOAL: the kept LDLᵀ (with contact rows kept last, and without contact) solves
    /// A x = b like a pivoting sparse LU, to round-off (reference: faer's LU), for a full
    /// right-hand side and for Bᵀy (whose forward sweep is skipped); and its contact rows of
    /// a solve (forward sweep and S⁻¹ only) are B times the LU's solution.
    #[test]
    fn kept_ldlt_solves_like_the_lu() {
        let (nx, ny) = (30, 20);
        let (a, _) = crate::linalg::schur::tests::grid_for(nx, ny, 3.7);
        let im: Vec<f64> = a.values.iter().map(|v| 0.05 * v).collect();
        let lu = SparseLu::factor_complex(&LuPattern::analyse(&a).unwrap(), &a, &im).unwrap();
        let rhs: Vec<c64> = (0..a.ncols)
            .map(|i| c64::new((i % 5) as f64 - 2.0, (i % 3) as f64))
            .collect();
        let reference = lu.solve(&rhs);
        let rows: Vec<(usize, usize, f64)> = (0..nx)
            .flat_map(|x| {
                let t = 0.2 + 0.07 * x as f64;
                [(x, 2 * x, t.sin()), (x, 2 * x + 1, t.cos())]
            })
            .collect();
        let b = Csc::from_entries(nx, a.ncols, &rows);
        for plan in [
            SchurPlan::without_contact(&a),
            SchurPlan::new(&a, &b).unwrap(),
        ] {
            let plan = Arc::new(plan);
            let f = plan.factor(&a.values, Some(&im), PIVOT_TOLERANCE).unwrap();
            let x = f.solve(&rhs);
            let scale = reference.iter().fold(0.0f64, |m, z| m.max(z.norm()));
            let err = x
                .iter()
                .zip(&reference)
                .fold(0.0f64, |m, (p, q)| m.max((p - q).norm()));
            assert!(err < 1e-11 * scale, "{err:e} of {scale:e}");
            assert!(plan.fronts().1 > 1);
        }
        let close = |p: &[c64], q: &[c64]| {
            let scale = q.iter().fold(0.0f64, |m, z| m.max(z.norm()));
            let err = p
                .iter()
                .zip(q)
                .fold(0.0f64, |m, (p, q)| m.max((p - q).norm()));
            assert!(
                p.len() == q.len() && err < 1e-11 * scale,
                "{err:e} of {scale:e}"
            );
        };
        let plan = Arc::new(SchurPlan::new(&a, &b).unwrap());
        let f = plan.factor(&a.values, Some(&im), PIVOT_TOLERANCE).unwrap();
        let y: Vec<c64> = (0..nx).map(|i| c64::new(1.0, i as f64 / 7.0)).collect();
        let bty = b.mul_transpose_complex(&y);
        close(&f.solve(&bty), &lu.solve(&bty));
        close(&f.contact_rows_of_solve(&rhs), &b.mul_complex(&reference));
    }
}
