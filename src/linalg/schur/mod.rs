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

use faer::c64;
use faer::Mat;

use super::Csc;

mod factor;
mod kernels;
mod plan;

pub use factor::LdltFactor;
use factor::*;
use kernels::*;
use plan::*;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{LuPattern, SparseLu};
    use std::sync::Arc;

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
