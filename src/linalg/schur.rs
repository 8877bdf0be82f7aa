//! The contact compliance G = B A⁻¹ Bᵀ of a complex symmetric sparse A (A = Aᵀ, not
//! Hermitian: A = Z_k = K − (kω)²M + ikωD) from the Schur complement of the contact
//! normals, without any solve with the n_c rows of B:
//!
//! A change of basis u = T ũ per contact node (ũ = (ũ_t, ũ_n): T e_n = b_i/|b_i|², T e_t ⟂ b_i)
//! gives B T = E_n (each row of B picks one coordinate), so with Ã = Tᵀ A T
//!
//! G = B A⁻¹ Bᵀ = E_nᵀ Ã⁻¹ E_n = (Ã⁻¹)_nn = S⁻¹,   S = Ã_nn − Ã_ne Ã_ee⁻¹ Ã_en,
//!
//! the Schur complement of the n_c normal coordinates ("kept", ordered last) after
//! eliminating every other coordinate e. S comes out of a multifrontal LDLᵀ (no pivoting:
//! A complex symmetric, pivots checked) of Ã in an AMD order of the eliminated coordinates,
//! stopped before the kept ones: the roots' contribution blocks sum to S − Ã_nn. No factor is
//! kept (only S is wanted), and G is one dense inverse of size n_c.
//!
//! Glossary: front = the dense matrix of one supernode (its pivot columns and the rows of
//! their structure); contribution block (CB) = the front's trailing Schur complement, added
//! into the parent's front ("extend-add"); plan = everything that depends on the patterns of
//! A and B only, built once and shared by every harmonic and frequency.
//!
//! Cost (mul-adds): Σ_j c_j(c_j + 3)/2 over eliminated columns j with c_j entries below the
//! diagonal in L, plus n_c³ for the inverse; the solve path costs n_c · 2 nnz(L + U).

use faer::c64;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::linalg::solvers::DenseSolveCore;
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::Csc;

/// How much slower per estimated mul-add the Schur path runs than the blocked solves
/// (measured by `cargo bench --bench goals -- reduction`: 1.3× at 601 contact nodes, 2–5× at
/// 63–301, 13–37× at 9, where the fronts are small): the path is chosen on the estimate
/// times this.
const SCHUR_SLOWDOWN: f64 = 4.0;

/// Coordinates of the transformed basis touched by one old dof, with T's weights.
type Expansion = Vec<(usize, f64)>;

/// One supernode: pivot columns `first..first + pivots` (elimination order) and its front's
/// rows (sorted, the pivots first).
#[derive(Clone, Debug)]
struct Supernode {
    first: usize,
    pivots: usize,
    rows: Vec<usize>,
    children: Vec<usize>,
}

/// The symbolic analysis of G = B A⁻¹ Bᵀ for one pattern of A and one B.
#[derive(Clone, Debug)]
pub struct SchurPlan {
    /// Coordinates eliminated (the kept ones are `eliminated..eliminated + kept`).
    eliminated: usize,
    /// Per contact node (row of B): its kept coordinate, or `None` for an all-zero row.
    kept_of_row: Vec<Option<usize>>,
    /// Ã's lower triangle in elimination order (CSC).
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For A's nonzero p (its CSC order): the slots of Ã it adds into, with T's weights.
    scatter_ptr: Vec<usize>,
    scatter: Vec<(usize, f64)>,
    supernodes: Vec<Supernode>,
    /// Estimated mul-adds of this path and of n_c solves with a sparse LU of A.
    pub schur_cost: f64,
    pub solve_cost: f64,
}

/// The basis change T: per old dof the coordinates it expands into, which coordinates are
/// kept, and each row of B's kept coordinate.
struct Basis {
    exp: Vec<Expansion>,
    kept: Vec<bool>,
    kept_dof: Vec<Option<usize>>,
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
    let mut exp: Vec<Expansion> = (0..n).map(|d| vec![(d, 1.0)]).collect();
    let mut kept = vec![false; n];
    let mut used = vec![false; n];
    let mut kept_dof = vec![None; b.nrows];
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
                exp[d] = vec![(d, 1.0 / v)];
                kept[d] = true;
                kept_dof[i] = Some(d);
            }
            [(d1, v1), (d2, v2)] => {
                // coordinate d1 := t (eliminated), d2 := n (kept).
                let s2 = v1 * v1 + v2 * v2;
                let s = s2.sqrt();
                exp[d1] = vec![(d1, -v2 / s), (d2, v1 / s2)];
                exp[d2] = vec![(d1, v1 / s), (d2, v2 / s2)];
                kept[d2] = true;
                kept_dof[i] = Some(d2);
            }
            _ => return None,
        }
    }
    Some(Basis {
        exp,
        kept,
        kept_dof,
    })
}

/// The sorted, deduplicated full pattern of Ã on the coordinates (CSC column lists).
fn transformed_pattern(a: &Csc, exp: &[Expansion]) -> Vec<Vec<usize>> {
    let mut cols: Vec<Vec<usize>> = vec![Vec::new(); a.ncols];
    for c in 0..a.ncols {
        for p in a.col_ptr[c]..a.col_ptr[c + 1] {
            let r = a.row_idx[p];
            for &(q, _) in &exp[c] {
                cols[q].extend(exp[r].iter().map(|&(x, _)| x));
            }
        }
    }
    for col in &mut cols {
        col.sort_unstable();
        col.dedup();
    }
    cols
}

/// AMD order of the eliminated coordinates, then the kept ones in the order of B's rows:
/// `order[new] = coordinate`.
fn elimination_order(cols: &[Vec<usize>], kept: &[bool], kept_dof: &[Option<usize>]) -> Vec<usize> {
    let elim: Vec<usize> = (0..cols.len()).filter(|&c| !kept[c]).collect();
    let mut compact = vec![usize::MAX; cols.len()];
    for (i, &c) in elim.iter().enumerate() {
        compact[c] = i;
    }
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for &c in &elim {
        row_idx.extend(cols[c].iter().filter(|&&r| !kept[r]).map(|&r| compact[r]));
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

impl SchurPlan {
    /// The plan for A's pattern (`a`, values unused) and B; `None` when B is not one row per
    /// contact node on at most two dofs of its own.
    pub fn new(a: &Csc, b: &Csc) -> Option<SchurPlan> {
        let Basis {
            exp,
            kept,
            kept_dof,
        } = expansions(b)?;
        let cols = transformed_pattern(a, &exp);
        let order = elimination_order(&cols, &kept, &kept_dof);
        let n = order.len();
        let mut position = vec![0usize; n];
        for (new, &c) in order.iter().enumerate() {
            position[c] = new;
        }
        let eliminated = n - kept.iter().filter(|&&k| k).count();
        // Ã's lower triangle in the new order.
        let mut lower: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (c, rows) in cols.iter().enumerate() {
            let q = position[c];
            lower[q].extend(rows.iter().map(|&r| position[r]).filter(|&p| p >= q));
        }
        let mut col_ptr = vec![0usize];
        let mut row_idx = Vec::new();
        for col in &mut lower {
            col.sort_unstable();
            row_idx.extend_from_slice(col);
            col_ptr.push(row_idx.len());
        }
        let slot = |p: usize, q: usize| -> usize {
            let rows = &row_idx[col_ptr[q]..col_ptr[q + 1]];
            col_ptr[q] + rows.binary_search(&p).unwrap_or(0)
        };
        let mut scatter_ptr = vec![0usize];
        let mut scatter = Vec::new();
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
        let kept_of_row = kept_dof
            .iter()
            .map(|d| d.map(|d| position[d] - eliminated))
            .collect();
        let (supernodes, l_entries) = supernodes(&col_ptr, &row_idx, eliminated);
        let nk = n - eliminated;
        let nc = b.nrows as f64;
        let column_cost: f64 = l_entries.iter().map(|&c| (c * (c + 3)) as f64 / 2.0).sum();
        let nnz_l: f64 = l_entries.iter().map(|&c| (c + 1) as f64).sum();
        Some(SchurPlan {
            eliminated,
            kept_of_row,
            col_ptr,
            row_idx,
            scatter_ptr,
            scatter,
            supernodes,
            schur_cost: column_cost + (nk as f64).powi(3),
            solve_cost: nc * 2.0 * 2.0 * nnz_l,
        })
    }

    /// Whether the Schur path is estimated cheaper than n_c solves with a sparse LU.
    pub fn preferred(&self) -> bool {
        SCHUR_SLOWDOWN * self.schur_cost < self.solve_cost
    }

    /// G = B A⁻¹ Bᵀ (row-major n_c × n_c) for A = `re` + i `im` (values on the pattern the
    /// plan was built for); `Err` names a vanishing pivot (the caller then solves instead).
    pub fn compliance(&self, re: &[f64], im: Option<&[f64]>) -> Result<Vec<c64>, String> {
        let mut values = vec![c64::new(0.0, 0.0); self.row_idx.len()];
        for p in 0..self.scatter_ptr.len() - 1 {
            let a = c64::new(re[p], im.map_or(0.0, |v| v[p]));
            for &(s, w) in &self.scatter[self.scatter_ptr[p]..self.scatter_ptr[p + 1]] {
                values[s] += a * w;
            }
        }
        let nk = self.col_ptr.len() - 1 - self.eliminated;
        let mut schur = vec![c64::new(0.0, 0.0); nk * nk];
        for q in self.eliminated..self.col_ptr.len() - 1 {
            let range = self.col_ptr[q]..self.col_ptr[q + 1];
            for (&r, &v) in self.row_idx[range.clone()].iter().zip(&values[range]) {
                schur[(q - self.eliminated) * nk + (r - self.eliminated)] += v;
            }
        }
        self.eliminate_all(&values, &mut schur, nk)?;
        let s = Mat::from_fn(nk, nk, |i, j| {
            let (hi, lo) = if i >= j { (i, j) } else { (j, i) };
            schur[lo * nk + hi]
        });
        let inv = s.partial_piv_lu().inverse();
        let nc = self.kept_of_row.len();
        let mut g = vec![c64::new(0.0, 0.0); nc * nc];
        for (i, ki) in self.kept_of_row.iter().enumerate() {
            for (j, kj) in self.kept_of_row.iter().enumerate() {
                if let (Some(a), Some(b)) = (ki, kj) {
                    // Symmetric by construction; average the round-off away.
                    g[i * nc + j] = (inv[(*a, *b)] + inv[(*b, *a)]) * 0.5;
                }
            }
        }
        if g.iter().any(|z| !z.re.is_finite() || !z.im.is_finite()) {
            return Err("the Schur complement of the contact normals is singular".into());
        }
        Ok(g)
    }

    /// The multifrontal elimination of every non-kept coordinate: the roots' contribution
    /// blocks are added into `schur` (lower triangle, column-major nk × nk).
    fn eliminate_all(&self, values: &[c64], schur: &mut [c64], nk: usize) -> Result<(), String> {
        let n = self.col_ptr.len() - 1;
        let mut local = vec![usize::MAX; n];
        let mut blocks: Vec<Option<Vec<c64>>> = vec![None; self.supernodes.len()];
        let mut panel = Vec::new();
        for (s, node) in self.supernodes.iter().enumerate() {
            let m = node.rows.len();
            for (i, &r) in node.rows.iter().enumerate() {
                local[r] = i;
            }
            let mut front = vec![c64::new(0.0, 0.0); m * m];
            for j in node.first..node.first + node.pivots {
                let col = (j - node.first) * m;
                for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                    front[col + local[self.row_idx[p]]] += values[p];
                }
            }
            for &c in &node.children {
                let child = &self.supernodes[c];
                let cb = blocks[c].take().unwrap_or_default();
                extend_add(&mut front, m, &cb, &child.rows[child.pivots..], &local);
            }
            eliminate(&mut front, m, node.pivots, &mut panel).map_err(|k| {
                format!("pivot {} of the Schur elimination vanished", node.first + k)
            })?;
            let p = node.pivots;
            let mc = m - p;
            let mut cb = vec![c64::new(0.0, 0.0); mc * mc];
            for b in 0..mc {
                let from = (p + b) * m + p;
                cb[b * mc + b..(b + 1) * mc].copy_from_slice(&front[from + b..from + mc]);
            }
            let is_root = node.rows.get(p).is_none_or(|&r| r >= self.eliminated);
            if is_root {
                for &r in &node.rows[p..] {
                    local[r] = r - self.eliminated;
                }
                extend_add(schur, nk, &cb, &node.rows[p..], &local);
            } else {
                blocks[s] = Some(cb);
            }
        }
        Ok(())
    }
}

/// Add the lower triangle of a contribution block (column-major, rows `rows`) into `front`
/// (column-major m × m) at the positions `local[row]`.
fn extend_add(front: &mut [c64], m: usize, cb: &[c64], rows: &[usize], local: &[usize]) {
    let mc = rows.len();
    for b in 0..mc {
        let col = local[rows[b]] * m;
        for a in b..mc {
            front[col + local[rows[a]]] += cb[b * mc + a];
        }
    }
}

/// Partial LDLᵀ (no pivoting) of the front's first p columns: afterwards its trailing
/// (m − p)² lower triangle is the Schur complement. `Err(k)` when pivot k vanishes.
fn eliminate(front: &mut [c64], m: usize, p: usize, panel: &mut Vec<c64>) -> Result<(), usize> {
    for k in 0..p {
        let d = front[k * m + k];
        let scale = front[k * m + k..(k + 1) * m]
            .iter()
            .fold(0.0f64, |a, z| a.max(z.norm()));
        if !(d.norm() > 1e-300_f64.max(1e-14 * scale)) || !d.re.is_finite() {
            return Err(k);
        }
        let inv = d.inv();
        let (head, tail) = front.split_at_mut((k + 1) * m);
        let colk = &head[k * m..];
        for j in k + 1..p {
            let s = colk[j] * inv;
            let colj = &mut tail[(j - k - 1) * m..(j - k) * m];
            for i in j..m {
                colj[i] -= colk[i] * s;
            }
        }
        for v in &mut front[k * m + k + 1..(k + 1) * m] {
            *v *= inv;
        }
    }
    let mc = m - p;
    if mc == 0 || p == 0 {
        return Ok(());
    }
    // W = L21 D, then F22 −= L21 Wᵀ (lower triangle).
    panel.clear();
    panel.resize(mc * p, c64::new(0.0, 0.0));
    for k in 0..p {
        let d = front[k * m + k];
        for i in 0..mc {
            panel[k * mc + i] = front[k * m + p + i] * d;
        }
    }
    let (left, right) = front.split_at_mut(p * m);
    let l21 = MatRef::from_column_major_slice_with_stride(&left[p..], mc, p, m);
    let w = MatRef::from_column_major_slice(&panel[..], mc, p);
    let f22 = MatMut::from_column_major_slice_with_stride_mut(&mut right[p..], mc, mc, m);
    let par = if mc * mc * p > 1 << 21 {
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
    Ok(())
}

/// Fundamental supernodes of the elimination of the first `eliminated` columns of a lower
/// pattern (CSC, sorted), in an order where children come first; and c_j, the entries below
/// the diagonal of each eliminated column of L.
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
    for j in 0..eliminated {
        merged.clear();
        merged.extend(
            row_idx[col_ptr[j]..col_ptr[j + 1]]
                .iter()
                .filter(|&&r| r > j),
        );
        for &c in &waiting[j] {
            let child = &nodes[c];
            merged.extend(child.rows[child.pivots..].iter().filter(|&&r| r > j));
        }
        merged.sort_unstable();
        merged.dedup();
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
                first: j,
                pivots: 1,
                rows,
                children,
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
    (nodes, counts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{LuPattern, SparseLu};

    /// A 2-D grid of nodes with two dofs each, a 5-point coupling between neighbours and a
    /// complex diagonal shift: complex symmetric, sparse, FE-like.
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
        assert!(plan.schur_cost > 0.0 && plan.solve_cost > 0.0);
    }
}
