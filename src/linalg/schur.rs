//! A multifrontal LDLᵀ of a complex symmetric sparse A (A = Aᵀ, not Hermitian: A = Z_k =
//! K − (kω)²M + ikωD) that is kept, so that one elimination per harmonic gives the load
//! solve, the recovery solves and the contact compliance G = B A⁻¹ Bᵀ:
//!
//! A change of basis u = T ũ per contact node (ũ = (ũ_t, ũ_n): T e_n = b_i/|b_i|², T e_t ⟂ b_i)
//! gives B T = E_n (each row of B picks one coordinate), so with Ã = Tᵀ A T
//!
//! Ã = [L_ee 0; L_ne I] [D 0; 0 S] [L_eeᵀ L_neᵀ; 0 I],   G = E_nᵀ Ã⁻¹ E_n = S⁻¹,
//! S = Ã_nn − Ã_ne Ã_ee⁻¹ Ã_en,
//!
//! where the n_c normal coordinates are "kept" (ordered last) and every other coordinate e is
//! eliminated, in an AMD order, without pivoting (A is complex symmetric; each pivot is
//! checked against its column and a vanishing one is an error, the caller then uses a
//! pivoting LU). S is inverted densely (n_c × n_c): its inverse is G and serves the solves.
//! A solve is x = T Ã⁻¹ Tᵀ b: forward with L, D⁻¹ and S⁻¹, backward with Lᵀ. Without contact
//! (no B) nothing is kept and T = I: a plain LDLᵀ.
//!
//! Glossary: front = the dense matrix of one supernode (its pivot columns and the rows of
//! their structure); panel = the front's pivot columns after elimination (L below a unit
//! diagonal, D on it), kept as the factor; contribution block (CB) = the front's trailing
//! Schur complement, added into the parent's front ("extend-add"); relaxed amalgamation =
//! merging a supernode into its parent when the explicit zeros this adds are few (CHOLMOD's
//! rule), so fronts are wide enough for the dense kernels; plan = everything that depends on
//! the patterns of A and B only, built once and shared by every harmonic and frequency.
//!
//! Cost (complex mul-adds): Σ over supernodes and their pivots k of c(c + 3)/2, c = m − k − 1
//! the rows below pivot k in a front of m rows, plus n_c³ for the inverse of S; a solve costs
//! 2 nnz(L) + n_c². A sparse LU of A costs about twice the factorization (L and U) plus
//! n_c · 4 nnz(L) for G by blocked solves.

use std::sync::Arc;

use faer::c64;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::Csc;

/// Time per estimated mul-add of this LDLᵀ (factor, S⁻¹, G and its checks) over that of
/// faer's numeric sparse LU, measured by `cargo bench --bench goals -- paths`.
pub const SCHUR_SLOWDOWN: f64 = 1.0;

/// Time per estimated mul-add of the LU's blocked multi-right-hand-side solves for G over
/// that of its factorization (same bench).
pub const BLOCKED_SOLVE_WEIGHT: f64 = 0.2;

/// Pivot columns per panel of the blocked front elimination.
const PANEL: usize = 32;

/// The default pivot threshold: |d| > this × max |column| (else the pivot "vanished").
pub const PIVOT_TOLERANCE: f64 = 1e-14;

/// Coordinates of the transformed basis touched by one old dof, with T's weights.
type Expansion = Vec<(usize, f64)>;

/// Every supernode's panel in one array, at `panel_start`: per pivot column k its rows k..m
/// (D on top, then L below its unit diagonal), columns one after the other (`trapezoid_column`).
type Panels = Vec<c64>;

/// S⁻¹ (n_k × n_k) and G (row-major n_c × n_c).
type Kept = (Mat<c64>, Vec<c64>);

/// One supernode: its pivot coordinates (elimination order) and its front's rows (the
/// pivots first), the supernodes whose CBs it receives, and where its own CB goes (`None`:
/// into S).
#[derive(Clone, Debug, Default)]
struct Supernode {
    pivots: usize,
    rows: Vec<usize>,
    children: Vec<usize>,
    parent: Option<usize>,
}

/// The symbolic analysis of the LDLᵀ of Ã for one pattern of A and one B (or none).
#[derive(Clone, Debug)]
pub struct SchurPlan {
    /// Coordinates eliminated (the kept ones are `eliminated..eliminated + kept`).
    eliminated: usize,
    /// Per contact node (row of B): its kept coordinate, or `None` for an all-zero row.
    kept_of_row: Vec<Option<usize>>,
    /// Per dof of A: the coordinates (elimination order) of T's row, with its weights.
    expansion: Vec<Expansion>,
    /// Ã's lower triangle in elimination order (CSC).
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For A's nonzero p (its CSC order): the slots of Ã it adds into, with T's weights.
    scatter_ptr: Vec<usize>,
    scatter: Vec<(usize, f64)>,
    /// Supernodes, children before parents.
    supernodes: Vec<Supernode>,
    /// Where each supernode's panel starts in the factor's one array (and its length).
    panel_start: Vec<usize>,
    /// The eliminations' scratch buffers, handed back after each one for the next.
    scratch: Pool<Scratch>,
    /// Panels of dropped factors, for the next eliminations.
    spare_panels: Pool<Panels>,
    /// Estimated mul-adds of this LDLᵀ (with S⁻¹), of a sparse LU of A, and of G by n_c
    /// blocked solves with it.
    pub schur_cost: f64,
    pub lu_cost: f64,
    pub blocked_cost: f64,
    /// Entries of L (with the explicit zeros amalgamation adds).
    pub factor_entries: usize,
    /// The B whose rows are kept (`None`: no contact).
    b: Option<Csc>,
}

/// The basis change T: per old dof the coordinates it expands into, which coordinates are
/// kept, and each row of B's kept coordinate.
struct Basis {
    exp: Vec<Expansion>,
    kept: Vec<bool>,
    kept_dof: Vec<Option<usize>>,
}

impl Basis {
    /// T = I, nothing kept (no contact).
    fn identity(n: usize) -> Basis {
        Basis {
            exp: (0..n).map(|d| vec![(d, 1.0)]).collect(),
            kept: vec![false; n],
            kept_dof: Vec::new(),
        }
    }
}

/// The basis change for B; `None` when B is not one row per node on at most two dofs of its
/// own (then only the solve path applies).
fn expansions(b: &Csc) -> Option<Basis> {
    let n = b.ncols;
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); b.nrows];
    for j in 0..n {
        for p in b.col_ptr[j]..b.col_ptr[j + 1] {
            if b.values[p] != 0.0 {
                rows[b.row_idx[p]].push((j, b.values[p]));
            }
        }
    }
    let mut basis = Basis::identity(n);
    let mut used = vec![false; n];
    basis.kept_dof = vec![None; b.nrows];
    for (i, row) in rows.iter().enumerate() {
        if row
            .iter()
            .any(|&(d, _)| std::mem::replace(&mut used[d], true))
        {
            return None; // a dof in two rows of B
        }
        match row[..] {
            [] => {}
            [(d, v)] => {
                basis.exp[d] = vec![(d, 1.0 / v)];
                basis.kept[d] = true;
                basis.kept_dof[i] = Some(d);
            }
            [(d1, v1), (d2, v2)] => {
                // coordinate d1 := t (eliminated), d2 := n (kept).
                let s2 = v1 * v1 + v2 * v2;
                let s = s2.sqrt();
                basis.exp[d1] = vec![(d1, -v2 / s), (d2, v1 / s2)];
                basis.exp[d2] = vec![(d1, v1 / s), (d2, v2 / s2)];
                basis.kept[d2] = true;
                basis.kept_dof[i] = Some(d2);
            }
            _ => return None,
        }
    }
    Some(basis)
}

/// A column-compressed pattern: column c's rows, ascending and distinct, at ptr[c]..ptr[c + 1].
struct Pattern {
    ptr: Vec<usize>,
    idx: Vec<usize>,
}

impl Pattern {
    fn col(&self, c: usize) -> &[usize] {
        &self.idx[self.ptr[c]..self.ptr[c + 1]]
    }

    fn cols(&self) -> usize {
        self.ptr.len() - 1
    }

    /// From per-column counts (an upper bound) and a fill that pushes each entry by `put`:
    /// counted, filled, then each column sorted and deduplicated in place and compacted.
    fn gather(counts: Vec<usize>, fill: impl FnOnce(&mut dyn FnMut(usize, usize))) -> Pattern {
        let n = counts.len();
        let mut ptr = vec![0usize; n + 1];
        for c in 0..n {
            ptr[c + 1] = ptr[c] + counts[c];
        }
        let mut next = ptr[..n].to_vec();
        let mut idx = vec![0usize; ptr[n]];
        fill(&mut |col: usize, row: usize| {
            idx[next[col]] = row;
            next[col] += 1;
        });
        let mut out = 0;
        let mut compact = vec![0usize; n + 1];
        for c in 0..n {
            let (start, end) = (ptr[c], ptr[c + 1]);
            idx[start..end].sort_unstable();
            let mut last = None;
            for k in start..end {
                if last != Some(idx[k]) {
                    last = Some(idx[k]);
                    idx[out] = idx[k];
                    out += 1;
                }
            }
            compact[c + 1] = out;
        }
        idx.truncate(out);
        Pattern { ptr: compact, idx }
    }
}

/// The sorted, deduplicated full pattern of Ã on the coordinates: column q gathers, for every
/// entry (r, c) of A and every coordinate q of c's expansion, the coordinates of r's.
fn transformed_pattern(a: &Csc, exp: &[Expansion]) -> Pattern {
    let entries = |c: usize| a.row_idx[a.col_ptr[c]..a.col_ptr[c + 1]].iter();
    let mut counts = vec![0usize; a.ncols];
    for c in 0..a.ncols {
        let width: usize = entries(c).map(|&r| exp[r].len()).sum();
        for &(q, _) in &exp[c] {
            counts[q] += width;
        }
    }
    Pattern::gather(counts, |put| {
        for c in 0..a.ncols {
            for &r in entries(c) {
                for &(q, _) in &exp[c] {
                    exp[r].iter().for_each(|&(x, _)| put(q, x));
                }
            }
        }
    })
}

/// AMD order of the eliminated coordinates, then the kept ones in the order of B's rows:
/// `order[new] = coordinate`.
fn elimination_order(cols: &Pattern, kept: &[bool], kept_dof: &[Option<usize>]) -> Vec<usize> {
    let elim: Vec<usize> = (0..cols.cols()).filter(|&c| !kept[c]).collect();
    let mut compact = vec![usize::MAX; cols.cols()];
    for (i, &c) in elim.iter().enumerate() {
        compact[c] = i;
    }
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for &c in &elim {
        row_idx.extend(
            cols.col(c)
                .iter()
                .filter(|&&r| !kept[r])
                .map(|&r| compact[r]),
        );
        col_ptr.push(row_idx.len());
    }
    let ne = elim.len();
    let mut order: Vec<usize> = elim.clone();
    if ne > 0 {
        let (mut perm, mut perm_inv) = (vec![0usize; ne], vec![0usize; ne]);
        let pattern = SymbolicSparseColMatRef::new_checked(ne, ne, &col_ptr, None, &row_idx);
        let req = amd::order_maybe_unsorted_scratch::<usize>(ne, row_idx.len());
        let mut buf = MemBuffer::new(req);
        let ok = amd::order_maybe_unsorted(
            &mut perm,
            &mut perm_inv,
            pattern,
            amd::Control::default(),
            MemStack::new(&mut buf),
        );
        if ok.is_ok() {
            order = perm.iter().map(|&i| elim[i]).collect();
        }
    }
    order.extend(kept_dof.iter().flatten());
    order
}

/// Ã's lower triangle in the new order (CSC) and, per nonzero of A, the slots it adds into.
struct Transformed {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    scatter_ptr: Vec<usize>,
    scatter: Vec<(usize, f64)>,
}

fn transform(a: &Csc, exp: &[Expansion], cols: &Pattern, position: &[usize]) -> Transformed {
    let n = cols.cols();
    let mut counts = vec![0usize; n];
    for c in 0..n {
        let q = position[c];
        counts[q] = cols.col(c).iter().filter(|&&r| position[r] >= q).count();
    }
    let Pattern {
        ptr: col_ptr,
        idx: row_idx,
    } = Pattern::gather(counts, |put| {
        for c in 0..n {
            let q = position[c];
            for &r in cols.col(c) {
                if position[r] >= q {
                    put(q, position[r]);
                }
            }
        }
    });
    // slot(p, q): where row p sits in column q, through a row-to-slot map of the last column
    // asked for (an entry of A adds into its own column's, but for the contact coordinates).
    let (mut slots, mut marked) = (vec![0usize; n], usize::MAX);
    let mut slot = |p: usize, q: usize| -> usize {
        if q != marked {
            for s in col_ptr[q]..col_ptr[q + 1] {
                slots[row_idx[s]] = s;
            }
            marked = q;
        }
        slots[p]
    };
    let mut scatter_ptr = Vec::with_capacity(a.nnz() + 1);
    scatter_ptr.push(0);
    let mut scatter = Vec::with_capacity(a.nnz());
    for c in 0..a.ncols {
        for p in a.col_ptr[c]..a.col_ptr[c + 1] {
            let r = a.row_idx[p];
            for &(x, w) in &exp[r] {
                for &(y, v) in &exp[c] {
                    let (px, py) = (position[x], position[y]);
                    if px >= py {
                        scatter.push((slot(px, py), w * v));
                    }
                }
            }
            scatter_ptr.push(scatter.len());
        }
    }
    Transformed {
        col_ptr,
        row_idx,
        scatter_ptr,
        scatter,
    }
}

/// Mul-adds of eliminating `pivots` columns of a front of `m` rows (LDLᵀ, lower triangle).
fn front_cost(pivots: usize, m: usize) -> f64 {
    (0..pivots)
        .map(|k| {
            let c = (m - k - 1) as f64;
            c * (c + 3.0) / 2.0
        })
        .sum()
}

impl SchurPlan {
    /// The plan for A's pattern (`a`, values unused) and B; `None` when B is not one row per
    /// contact node on at most two dofs of its own.
    pub fn new(a: &Csc, b: &Csc) -> Option<SchurPlan> {
        let mut plan = Self::build(a, expansions(b)?);
        plan.b = Some(b.clone());
        Some(plan)
    }

    /// The plan of a plain LDLᵀ of A (no contact: nothing kept).
    pub fn without_contact(a: &Csc) -> SchurPlan {
        Self::build(a, Basis::identity(a.ncols))
    }

    fn build(a: &Csc, basis: Basis) -> SchurPlan {
        let Basis {
            exp,
            kept,
            kept_dof,
        } = basis;
        let cols = transformed_pattern(a, &exp);
        let order = elimination_order(&cols, &kept, &kept_dof);
        let n = order.len();
        let mut position = vec![0usize; n];
        for (new, &c) in order.iter().enumerate() {
            position[c] = new;
        }
        let eliminated = n - kept.iter().filter(|&&k| k).count();
        let t = transform(a, &exp, &cols, &position);
        let kept_of_row = kept_dof
            .iter()
            .map(|d| d.map(|d| position[d] - eliminated))
            .collect();
        let expansion = exp
            .iter()
            .map(|e| e.iter().map(|&(q, w)| (position[q], w)).collect())
            .collect();
        let (fundamental, counts) = supernodes(&t.col_ptr, &t.row_idx, eliminated);
        let nodes = amalgamate(fundamental);
        let nk = (n - eliminated) as f64;
        let nc = kept_dof.len() as f64;
        // A sparse LU does L and U: twice the symmetric count (in the fundamental structure).
        let lu_cost: f64 = counts.iter().map(|&c| (c * (c + 3)) as f64).sum();
        let nnz_l: f64 = counts.iter().map(|&c| (c + 1) as f64).sum();
        let ldlt_cost: f64 = nodes
            .iter()
            .map(|s| front_cost(s.pivots, s.rows.len()))
            .sum();
        let panel_start = nodes.iter().fold(vec![0], |mut v, s| {
            v.push(v[v.len() - 1] + trapezoid(s.pivots, s.rows.len()));
            v
        });
        SchurPlan {
            eliminated,
            kept_of_row,
            expansion,
            col_ptr: t.col_ptr,
            row_idx: t.row_idx,
            scatter_ptr: t.scatter_ptr,
            scatter: t.scatter,
            factor_entries: panel_start[nodes.len()],
            panel_start,
            supernodes: nodes,
            scratch: Pool::default(),
            spare_panels: Pool::default(),
            schur_cost: ldlt_cost + nk.powi(3),
            lu_cost,
            blocked_cost: nc * 2.0 * 2.0 * nnz_l,
            b: None,
        }
    }

    /// Whether G of this plan is B A⁻¹ Bᵀ for this `b`.
    pub fn built_for(&self, b: &Csc) -> bool {
        self.b.as_ref() == Some(b)
    }

    /// The LU path's estimated cost in LU-factorization mul-adds: factor and G by n_c
    /// blocked solves.
    pub fn solve_cost(&self) -> f64 {
        self.lu_cost + BLOCKED_SOLVE_WEIGHT * self.blocked_cost
    }

    /// Whether this LDLᵀ is estimated cheaper than a sparse LU with n_c blocked solves.
    pub fn preferred(&self) -> bool {
        SCHUR_SLOWDOWN * self.schur_cost < self.solve_cost()
    }

    /// Bytes of one factor's panels.
    pub fn panel_bytes(&self) -> usize {
        self.panel_start[self.supernodes.len()] * std::mem::size_of::<c64>()
    }

    /// Touch the memory of `count` factors' panels and keep it for the next eliminations.
    /// Fresh memory costs a page fault per 4 KiB: on the strip that is about a third of
    /// each elimination's time in a fresh process, so a caller with an idle core touches
    /// the memory ahead of the factorizations (`hbm::touch_factor_memory`).
    /// Stops early when an elimination has found the pool empty (it took fresh memory; more
    /// touched panels would only add to the memory held).
    pub fn touch_panels(&self, count: usize) {
        let len = self.panel_start[self.supernodes.len()];
        self.spare_panels.refill_from_now();
        for _ in 0..count {
            if self.spare_panels.ran_dry() {
                break;
            }
            let mut panels = Vec::with_capacity(len);
            // Written, not `vec![0; len]`: a zeroed allocation is mapped untouched.
            panels.resize(len, c64::new(0.0, 0.0));
            self.spare_panels.give_back(panels);
        }
    }

    /// Free the panels kept for the next eliminations (a single solve is done with them; a
    /// sweep, which refactors at every frequency, keeps them).
    pub fn release_spare_panels(&self) {
        self.spare_panels.clear();
    }

    /// The dimension of A.
    pub fn dim(&self) -> usize {
        self.expansion.len()
    }

    /// Supernodes and the largest front (rows), for the benches.
    pub fn fronts(&self) -> (usize, usize) {
        let widest = self.supernodes.iter().map(|s| s.rows.len()).max();
        (self.supernodes.len(), widest.unwrap_or(0))
    }

    fn kept(&self) -> usize {
        self.col_ptr.len() - 1 - self.eliminated
    }

    /// G = B A⁻¹ Bᵀ alone (row-major n_c × n_c), from a factorization thrown away.
    pub fn compliance(&self, re: &[f64], im: Option<&[f64]>) -> Result<Vec<c64>, String> {
        let (_, (_, g)) = self.eliminate(re, im, PIVOT_TOLERANCE)?;
        Ok(g)
    }

    /// Factor A = `re` + i `im` (values on the pattern the plan was built for); `Err` names a
    /// pivot that vanished (|d| ≤ `pivot_tolerance` × its column) or a singular S.
    pub fn factor(
        self: &Arc<Self>,
        re: &[f64],
        im: Option<&[f64]>,
        pivot_tolerance: f64,
    ) -> Result<LdltFactor, String> {
        let (panels, (s_inverse, compliance)) = self.eliminate(re, im, pivot_tolerance)?;
        Ok(LdltFactor {
            plan: Arc::clone(self),
            panels,
            s_inverse,
            compliance,
            checked: None,
        })
    }

    /// The panels, S⁻¹ and G.
    fn eliminate(
        &self,
        re: &[f64],
        im: Option<&[f64]>,
        tolerance: f64,
    ) -> Result<(Panels, Kept), String> {
        let mut scratch = self.scratch.take();
        let result = self.eliminate_with(re, im, tolerance, &mut scratch);
        self.scratch.give_back(scratch);
        result
    }

    fn eliminate_with(
        &self,
        re: &[f64],
        im: Option<&[f64]>,
        tolerance: f64,
        scratch: &mut Scratch,
    ) -> Result<(Panels, Kept), String> {
        let zero = c64::new(0.0, 0.0);
        let values = refill(&mut scratch.values, self.row_idx.len());
        for p in 0..self.scatter_ptr.len() - 1 {
            let a = c64::new(re[p], im.map_or(0.0, |v| v[p]));
            for &(s, w) in &self.scatter[self.scatter_ptr[p]..self.scatter_ptr[p + 1]] {
                values[s] += a * w;
            }
        }
        let nk = self.kept();
        let mut schur = std::mem::take(&mut scratch.schur);
        refill(&mut schur, nk * nk);
        for q in self.eliminated..self.col_ptr.len() - 1 {
            let range = self.col_ptr[q]..self.col_ptr[q + 1];
            for (&r, &v) in self.row_idx[range.clone()].iter().zip(&values[range]) {
                schur[(q - self.eliminated) * nk + (r - self.eliminated)] += v;
            }
        }
        let panels = pulp::Arch::new().dispatch(Elimination {
            plan: self,
            schur: &mut schur,
            nk,
            tolerance,
            scratch,
        })?;
        let s = Mat::from_fn(nk, nk, |i, j| {
            let (hi, lo) = if i >= j { (i, j) } else { (j, i) };
            schur[lo * nk + hi]
        });
        scratch.schur = schur;
        let inv = if nk > 0 {
            super::dense_inverse(s)
        } else {
            Mat::zeros(0, 0)
        };
        let nc = self.kept_of_row.len();
        let mut g = vec![zero; nc * nc];
        for (i, ki) in self.kept_of_row.iter().enumerate() {
            for (j, kj) in self.kept_of_row.iter().enumerate() {
                if let (Some(a), Some(b)) = (ki, kj) {
                    // Symmetric by construction; average the round-off away.
                    g[i * nc + j] = (inv[(*a, *b)] + inv[(*b, *a)]) * 0.5;
                }
            }
        }
        let finite = |z: &c64| z.re.is_finite() && z.im.is_finite();
        if !g.iter().all(finite) || !(0..nk).all(|j| inv.col(j).iter().all(finite)) {
            return Err("the Schur complement of the contact normals is singular".into());
        }
        Ok((panels, (inv, g)))
    }

    /// The multifrontal elimination of every non-kept coordinate (Ã's values in
    /// `scratch.values`): returns the panels; the roots' contribution blocks are added into
    /// `schur` (lower triangle, column-major nk × nk).
    #[inline(always)]
    fn eliminate_all<S: pulp::Simd>(
        &self,
        simd: S,
        schur: &mut [c64],
        nk: usize,
        tolerance: f64,
        scratch: &mut Scratch,
    ) -> Result<Panels, String> {
        let zero = c64::new(0.0, 0.0);
        let n = self.col_ptr.len() - 1;
        let Scratch {
            values,
            local,
            front: buffer,
            work,
            blocks,
            spare,
            at,
            ..
        } = scratch;
        local.clear();
        local.resize(n, usize::MAX);
        blocks.clear();
        blocks.resize_with(self.supernodes.len(), || None);
        let mut panels = self.spare_panels.take();
        panels.clear();
        panels.reserve(self.panel_start[self.supernodes.len()]);
        for (s, node) in self.supernodes.iter().enumerate() {
            let m = node.rows.len();
            for (i, &r) in node.rows.iter().enumerate() {
                local[r] = i;
            }
            let front = lower_zeros(buffer, m);
            for &j in &node.rows[..node.pivots] {
                let lj = local[j];
                for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                    let li = local[self.row_idx[p]];
                    front[lj.min(li) * m + lj.max(li)] += values[p];
                }
            }
            for &c in &node.children {
                let child = &self.supernodes[c];
                let cb = blocks[c].take().unwrap_or_default();
                extend_add(front, m, &cb, &child.rows[child.pivots..], local, at);
                spare.push(cb);
            }
            let p = node.pivots;
            eliminate(simd, front, m, p, tolerance, work)
                .map_err(|k| format!("pivot {} of the LDLᵀ elimination vanished", node.rows[k]))?;
            let mc = m - p;
            let mut cb = spare.pop().unwrap_or_default();
            // Every entry extend-add reads (the lower triangle) is copied just below.
            if cb.len() < mc * mc {
                cb.resize(mc * mc, zero);
            }
            for b in 0..mc {
                let from = (p + b) * m + p;
                cb[b * mc + b..(b + 1) * mc].copy_from_slice(&front[from + b..from + mc]);
            }
            // Supernode s's panel at panel_start[s]: its columns from the diagonal down.
            for k in 0..p {
                panels.extend_from_slice(&front[k * m + k..(k + 1) * m]);
            }
            debug_assert_eq!(panels.len(), self.panel_start[s + 1]);
            match node.parent {
                Some(_) => blocks[s] = Some(cb),
                None => {
                    for &r in &node.rows[p..] {
                        local[r] = r - self.eliminated;
                    }
                    extend_add(schur, nk, &cb, &node.rows[p..], local, at);
                    spare.push(cb);
                }
            }
        }
        Ok(panels)
    }
}

/// `SchurPlan::eliminate_all` as a `pulp::WithSimd` operation, so that `Arch::dispatch`
/// compiles it (and the front kernels it inlines) for the widest instruction set the machine
/// has, with a baseline fallback.
struct Elimination<'a> {
    plan: &'a SchurPlan,
    schur: &'a mut [c64],
    nk: usize,
    tolerance: f64,
    scratch: &'a mut Scratch,
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
struct Scratch {
    values: Vec<c64>,
    local: Vec<usize>,
    front: Vec<c64>,
    work: Vec<c64>,
    blocks: Vec<Option<Vec<c64>>>,
    spare: Vec<Vec<c64>>,
    schur: Vec<c64>,
    at: Vec<usize>,
}

/// Buffers handed back for reuse: the eliminations' scratch (one per elimination running at
/// a time) and the panels of dropped factors (a sweep refactors every harmonic at each ω;
/// fresh memory costs a page fault per 4 KiB, two thirds of the time of the strip's
/// elimination that fills it). It remembers whether a `take` found it empty, so that memory
/// touched ahead stops once the eliminations outrun it. A clone is an empty pool.
struct Pool<T> {
    items: std::sync::Mutex<Vec<T>>,
    ran_dry: std::sync::atomic::AtomicBool,
}

impl<T: Default> Pool<T> {
    fn take(&self) -> T {
        let mut items = self.items.lock().unwrap_or_else(|e| e.into_inner());
        items.pop().unwrap_or_else(|| {
            self.ran_dry
                .store(true, std::sync::atomic::Ordering::Relaxed);
            T::default()
        })
    }

    fn give_back(&self, item: T) {
        self.items
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(item);
    }

    fn clear(&self) {
        self.items.lock().unwrap_or_else(|e| e.into_inner()).clear();
    }

    fn ran_dry(&self) -> bool {
        self.ran_dry.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn refill_from_now(&self) {
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
fn lower_zeros(v: &mut Vec<c64>, m: usize) -> &mut [c64] {
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
fn refill(v: &mut Vec<c64>, len: usize) -> &mut [c64] {
    v.clear();
    v.resize(len, c64::new(0.0, 0.0));
    v
}

/// The kept LDLᵀ of one A: solves with A and, with contact, G = B A⁻¹ Bᵀ.
pub struct LdltFactor {
    plan: Arc<SchurPlan>,
    panels: Panels,
    s_inverse: Mat<c64>,
    compliance: Vec<c64>,
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
    fn panel(&self, s: usize) -> &[c64] {
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
    factor: &'a LdltFactor,
    x: &'a mut [c64],
    r: usize,
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

/// Column k of a panel of m rows stored as a trapezoid: its rows k..m (the diagonal first).
#[inline(always)]
fn trapezoid_column(panel: &[c64], m: usize, k: usize) -> &[c64] {
    let at = trapezoid(k, m);
    &panel[at..at + m - k]
}

/// local[i * r + c] = x[rows[i] * r + c].
#[inline(always)]
fn gather(local: &mut Vec<c64>, x: &[c64], rows: &[usize], r: usize) {
    local.clear();
    for &row in rows {
        local.extend_from_slice(&x[row * r..(row + 1) * r]);
    }
}

/// x[rows[i] * r + c] = local[i * r + c].
#[inline(always)]
fn scatter(local: &[c64], x: &mut [c64], rows: &[usize], r: usize) {
    for (i, &row) in rows.iter().enumerate() {
        x[row * r..(row + 1) * r].copy_from_slice(&local[i * r..(i + 1) * r]);
    }
}

/// Add the lower triangle of a contribution block (column-major, rows `rows`) into `front`
/// (column-major m × m, lower triangle) at the positions `local[row]`. Fronts list their
/// rows in elimination order, so those positions rise with the CB's rows and entry (a, b),
/// a ≥ b, lands in the lower triangle at column `local[rows[b]]`; `at` is scratch for them.
#[inline(always)]
fn extend_add(
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
fn eliminate<S: pulp::Simd>(
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
fn subtract_multiple<S: pulp::Simd>(simd: S, y: &mut [c64], x: &[c64], s: c64) {
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
fn dot<S: pulp::Simd>(simd: S, x: &[c64], y: &[c64]) -> c64 {
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

/// Fundamental supernodes of the elimination of the first `eliminated` columns of a lower
/// pattern (CSC, sorted), children before parents; and c_j, the entries below the diagonal
/// of each eliminated column of L.
fn supernodes(
    col_ptr: &[usize],
    row_idx: &[usize],
    eliminated: usize,
) -> (Vec<Supernode>, Vec<usize>) {
    let mut nodes: Vec<Supernode> = Vec::new();
    let mut owner = vec![usize::MAX; eliminated];
    // Supernodes whose contribution block goes to column j (their parent column).
    let mut waiting: Vec<Vec<usize>> = vec![Vec::new(); eliminated];
    let mut counts = Vec::with_capacity(eliminated);
    let mut merged: Vec<usize> = Vec::new();
    // seen[r] == j + 1: row r is in column j's structure already (the children's rows
    // overlap, so they are deduplicated before the sort).
    let mut seen = vec![0usize; col_ptr.len() - 1];
    for j in 0..eliminated {
        merged.clear();
        let own = row_idx[col_ptr[j]..col_ptr[j + 1]].iter();
        let from_children = waiting[j].iter().flat_map(|&c| {
            let child = &nodes[c];
            child.rows[child.pivots..].iter()
        });
        for &r in own.chain(from_children) {
            if r > j && seen[r] != j + 1 {
                seen[r] = j + 1;
                merged.push(r);
            }
        }
        merged.sort_unstable();
        counts.push(merged.len());
        let children = std::mem::take(&mut waiting[j]);
        // Extend the previous supernode when column j − 1's structure is {j} ∪ merged.
        let extend = j > 0
            && owner[j - 1] != usize::MAX
            && children.len() == 1
            && children[0] == owner[j - 1]
            && {
                let prev = &nodes[owner[j - 1]];
                let tail = &prev.rows[prev.pivots..];
                tail.first() == Some(&j) && tail[1..] == merged[..]
            };
        let s = if extend {
            let s = owner[j - 1];
            nodes[s].pivots += 1;
            s
        } else {
            let mut rows = Vec::with_capacity(merged.len() + 1);
            rows.push(j);
            rows.extend_from_slice(&merged);
            nodes.push(Supernode {
                pivots: 1,
                rows,
                children,
                parent: None,
            });
            nodes.len() - 1
        };
        owner[j] = s;
        // Column j's parent is its first structure row; the supernode's, once it ends.
        // (An extension consumed the link to j; the supernode now waits for j's parent.)
        if let Some(&parent) = merged.first().filter(|&&r| r < eliminated) {
            waiting[parent].push(s);
        }
    }
    for s in 0..nodes.len() {
        for c in nodes[s].children.clone() {
            nodes[c].parent = Some(s);
        }
    }
    (nodes, counts)
}

/// Entries of a supernode's L: `pivots` columns of a front of `m` rows.
#[inline(always)]
fn trapezoid(pivots: usize, m: usize) -> usize {
    pivots * m - pivots * (pivots.saturating_sub(1)) / 2
}

/// Relaxed amalgamation (CHOLMOD's rule, cholmod_super.c: nrelax = 4, 16, 48 and zrelax =
/// 0.8, 0.1, 0.05): a supernode merges into its parent when the merged one has at most 4
/// pivots, or at most 16 and under 80% explicit zeros in its L, or at most 48 and under 10%,
/// or any size and under 5%. The merged front's rows are the child's pivots, then the
/// parent's rows (the child's CB rows are among them). Children before parents, greedily.
fn amalgamate(mut nodes: Vec<Supernode>) -> Vec<Supernode> {
    let count = nodes.len();
    let mut zeros = vec![0usize; count];
    let mut alive = vec![true; count];
    for s in 0..count {
        let Some(p) = nodes[s].parent else { continue };
        let (ns, np) = (nodes[s].pivots, nodes[p].pivots);
        let cols = ns + np;
        let m = ns + nodes[p].rows.len();
        let total = trapezoid(cols, m);
        let actual = trapezoid(ns, nodes[s].rows.len()) - zeros[s]
            + trapezoid(np, nodes[p].rows.len())
            - zeros[p];
        let z = total.saturating_sub(actual) as f64 / total as f64;
        let merge = cols <= 4 || (cols <= 16 && z < 0.8) || (cols <= 48 && z < 0.1) || z < 0.05;
        if !merge {
            continue;
        }
        let child = std::mem::take(&mut nodes[s].children);
        for &c in &child {
            nodes[c].parent = Some(p);
        }
        let mut rows = nodes[s].rows[..ns].to_vec();
        rows.extend_from_slice(&nodes[p].rows);
        let parent = &mut nodes[p];
        parent.rows = rows;
        parent.pivots = cols;
        parent.children.retain(|&c| c != s);
        parent.children.extend(child);
        zeros[p] = total - actual;
        alive[s] = false;
    }
    let mut index = vec![usize::MAX; count];
    let mut next = 0;
    for s in 0..count {
        if alive[s] {
            index[s] = next;
            next += 1;
        }
    }
    nodes
        .into_iter()
        .zip(alive)
        .filter(|(_, a)| *a)
        .map(|(mut node, _)| {
            node.children.iter_mut().for_each(|c| *c = index[*c]);
            node.parent = node.parent.map(|p| index[p]);
            node
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{LuPattern, SparseLu};

    /// A 2-D grid of nodes with two dofs each, a 5-point coupling between neighbours and a
    /// complex diagonal shift: complex symmetric, sparse, FE-like.
    pub(super) fn grid_for(nx: usize, ny: usize, shift: f64) -> (Csc, Vec<f64>) {
        grid(nx, ny, shift)
    }

    fn grid(nx: usize, ny: usize, shift: f64) -> (Csc, Vec<f64>) {
        let node = |x: usize, y: usize| y * nx + x;
        let mut e = Vec::new();
        for y in 0..ny {
            for x in 0..nx {
                let a = node(x, y);
                for c in 0..2 {
                    e.push((2 * a + c, 2 * a + c, 4.5 - shift));
                    e.push((2 * a + c, 2 * a + 1 - c, 0.3));
                }
                let mut link = |b: usize| {
                    for c in 0..2 {
                        e.push((2 * a + c, 2 * b + c, -1.0));
                        e.push((2 * b + c, 2 * a + c, -1.0));
                        e.push((2 * a + c, 2 * b + 1 - c, 0.2));
                        e.push((2 * b + 1 - c, 2 * a + c, 0.2));
                    }
                };
                if x + 1 < nx {
                    link(node(x + 1, y));
                }
                if y + 1 < ny {
                    link(node(x, y + 1));
                }
            }
        }
        let a = Csc::from_entries(2 * nx * ny, 2 * nx * ny, &e);
        // Damping proportional to the matrix itself keeps the imaginary part symmetric.
        let im = a.values.iter().map(|v| 0.05 * v).collect();
        (a, im)
    }

    /// TEST GOAL: G = B A⁻¹ Bᵀ from the Schur complement of the contact normals equals the
    /// blocked solve with a sparse LU to round-off, for an indefinite complex symmetric A,
    /// B rows on two dofs (oblique normals) and on one dof, and an all-zero row.
    #[test]
    fn schur_compliance_equals_the_blocked_solve_to_round_off() {
        let (nx, ny) = (12, 9);
        let (a, im) = grid(nx, ny, 3.7);
        let mut rows = Vec::new();
        for x in 0..nx {
            let d = 2 * x; // bottom row of nodes
            let t = 0.3 + 0.1 * x as f64;
            match x {
                3 => rows.push((x, d + 1, 1.0)),
                5 => {}
                _ => {
                    rows.push((x, d, t.sin()));
                    rows.push((x, d + 1, t.cos()));
                }
            }
        }
        let b = Csc::from_entries(nx, a.ncols, &rows);
        let plan = SchurPlan::new(&a, &b).expect("one row per node");
        let g = plan.compliance(&a.values, Some(&im)).expect("regular");
        let lu = SparseLu::factor_complex(&LuPattern::analyse(&a).unwrap(), &a, &im).unwrap();
        let reference = lu.compliance(&b);
        let scale = reference.iter().fold(0.0f64, |m, z| m.max(z.norm()));
        let err = g
            .iter()
            .zip(&reference)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).norm()));
        assert!(
            scale > 0.0 && err < 1e-12 * scale,
            "error {err:e} of scale {scale:e}"
        );
        assert!(g[5 * nx + 5].norm() == 0.0 && reference[5 * nx + 5].norm() == 0.0);
        assert!(plan.schur_cost > 0.0 && plan.solve_cost() > 0.0);
    }

    /// TEST GOAL: memory reused between factorizations changes nothing. A plan whose fronts,
    /// contribution blocks and panel pool hold another matrix's leftovers (fronts are zeroed
    /// in their lower triangle only; a dropped factor's panels go back to the pool), and
    /// panels touched ahead (`touch_panels`), gives bit for bit the G and the solve of a
    /// fresh plan.
    #[test]
    fn reused_scratch_and_panels_give_the_fresh_plans_factor_bit_for_bit() {
        let (nx, ny) = (10, 7);
        let (a, im) = grid(nx, ny, 2.9);
        let (other, other_im) = grid(nx, ny, -1.3);
        let rows: Vec<(usize, usize, f64)> = (0..nx).map(|x| (x, 2 * x + 1, 1.0)).collect();
        let b = Csc::from_entries(nx, a.ncols, &rows);
        let rhs: Vec<c64> = (0..a.ncols)
            .map(|i| c64::new((i as f64).sin(), 0.5 - (i % 3) as f64))
            .collect();
        let plan = Arc::new(SchurPlan::new(&a, &b).expect("one row per node"));
        let fresh = plan
            .factor(&a.values, Some(&im), PIVOT_TOLERANCE)
            .expect("regular");
        let (g, x) = (fresh.compliance().to_vec(), fresh.solve(&rhs));
        let reused = Arc::new(SchurPlan::new(&a, &b).expect("one row per node"));
        for _ in 0..2 {
            drop(reused.factor(&other.values, Some(&other_im), PIVOT_TOLERANCE));
        }
        reused.touch_panels(3);
        let again = reused
            .factor(&a.values, Some(&im), PIVOT_TOLERANCE)
            .expect("regular");
        assert_eq!(again.compliance(), &g[..]);
        assert_eq!(again.solve(&rhs), x);
        assert_ne!(
            g,
            other_g(&other, &other_im, &b),
            "the leftovers differ from A's"
        );
    }

    fn other_g(a: &Csc, im: &[f64], b: &Csc) -> Vec<c64> {
        let plan = Arc::new(SchurPlan::new(a, b).expect("one row per node"));
        let f = plan
            .factor(&a.values, Some(im), PIVOT_TOLERANCE)
            .expect("regular");
        f.compliance().to_vec()
    }
}

#[cfg(test)]
mod kernel_tests {
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

#[cfg(test)]
mod factor_tests {
    use super::*;
    use crate::linalg::{LuPattern, SparseLu};

    /// TEST GOAL: the kept LDLᵀ (with contact rows kept last, and without contact) solves
    /// A x = b like a pivoting sparse LU, to round-off (reference: faer's LU), for a full
    /// right-hand side and for Bᵀy (whose forward sweep is skipped); and its contact rows of
    /// a solve (forward sweep and S⁻¹ only) are B times the LU's solution.
    #[test]
    fn kept_ldlt_solves_like_the_lu() {
        let (nx, ny) = (30, 20);
        let (a, _) = tests::grid_for(nx, ny, 3.7);
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
