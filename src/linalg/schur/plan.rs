//! The plan of the Schur-complement LDLᵀ (see `schur`): everything that depends on the
//! patterns of A and B only. The basis change T per contact node, the pattern of Ã = Tᵀ A T,
//! an AMD order of the eliminated coordinates e with the kept ones n last, the fundamental
//! supernodes and their relaxed amalgamation, and the cost Σ c(c + 3)/2 of the fronts.

use std::sync::Arc;

use faer::c64;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;
use faer::Mat;

use super::*;
use crate::linalg::Csc;

/// The basis change T: per old dof the coordinates it expands into, which coordinates are
/// kept, and each row of B's kept coordinate.
struct Basis {
    exp: Vec<Expansion>,
    pub(super) kept: Vec<bool>,
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
    pub(super) fn gather(
        counts: Vec<usize>,
        fill: impl FnOnce(&mut dyn FnMut(usize, usize)),
    ) -> Pattern {
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
    pub(super) col_ptr: Vec<usize>,
    pub(super) row_idx: Vec<usize>,
    pub(super) scatter_ptr: Vec<usize>,
    pub(super) scatter: Vec<(usize, f64)>,
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

    pub(super) fn kept(&self) -> usize {
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
    pub(super) fn eliminate(
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
            crate::linalg::dense_inverse(s)
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
    pub(super) fn eliminate_all<S: pulp::Simd>(
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

/// Fundamental supernodes of the elimination of the first `eliminated` columns of a lower
/// pattern (CSC, sorted), children before parents; and c_j, the entries below the diagonal
/// of each eliminated column of L.
pub(super) fn supernodes(
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
pub(super) fn trapezoid(pivots: usize, m: usize) -> usize {
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
