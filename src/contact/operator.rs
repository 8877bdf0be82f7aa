//! The contact operator of (1)–(2) in docs/method.md: row i of B is the unit normal n_i at
//! contact node i's (x, y) dofs, pointing from the body toward the obstacle, so (B u)_i is the
//! node's displacement toward the obstacle and g = B u − g0 ≤ 0 is the non-penetration
//! condition (g0 the initial gap along n_i, positive = open). Against another meshed body the
//! row also holds −N_a n_i on each target node a (`pairing`): (B u)_i is the node's approach
//! toward the target surface, and Bᵀλ puts the opposite force on the target.
//!
//! A moving or out-of-round rigid obstacle makes the gap periodic in time: g0_i(t) = g0_i +
//! Σ_k Re(ĝ_{k,i} e^{ikωt}), k ≥ 1 (the note's g̃0 of (18), projected on the time basis where
//! the linear gap is formed).

use std::collections::BTreeMap;

use faer::c64;

use crate::fem::DofMap;
use crate::linalg::Csc;

use super::geometry::ContactSet;

/// B split into the columns of the free and of the prescribed dofs, and g0.
#[derive(Clone, Debug)]
pub struct ContactOperator {
    /// B restricted to the free dofs (nc × free).
    pub b_free: Csc,
    /// B restricted to the prescribed dofs (nc × prescribed): prescribed motion moves gaps.
    pub b_prescribed: Csc,
    /// Initial gaps along the normals (the mean gap of a moving obstacle).
    pub g0: Vec<f64>,
    /// The gap's harmonics ĝ_k (k ≥ 1, one phasor per row, x = Re(ĝ e^{ikωt})): empty for a
    /// fixed obstacle.
    pub gap_harmonics: BTreeMap<usize, Vec<c64>>,
    /// Coulomb friction: the tangential rows and each node's coefficient (`None`:
    /// frictionless).
    pub tangential: Option<Tangential>,
}

/// The tangential rows of B: row i is t_i = ẑ × n_i at node i's dofs (with the same weights
/// as its normal row), so (B_t u)_i is the node's tangential displacement relative to the
/// obstacle; μ_i its friction coefficient.
#[derive(Clone, Debug)]
pub struct Tangential {
    pub b_free: Csc,
    pub b_prescribed: Csc,
    pub coefficients: Vec<f64>,
    /// The obstacle's tangential translation per row (k ≥ 1 phasors, as `gap_harmonics`).
    pub motion: BTreeMap<usize, Vec<c64>>,
}

impl ContactOperator {
    pub fn nodes(&self) -> usize {
        self.g0.len()
    }

    /// The rows the contact problem is reduced to: the nodes', and as many tangential ones
    /// with friction (`stacked`).
    pub fn reduced_rows(&self) -> usize {
        self.nodes() * if self.tangential.is_some() { 2 } else { 1 }
    }

    /// The gap g0(t) of every row at time t, the fundamental being ω.
    pub fn gap_at(&self, omega: f64, t: f64, out: &mut [f64]) {
        periodic_gap(&self.g0, &self.gap_harmonics, omega, t, out);
    }

    /// With friction, the operator of the normal rows followed by the tangential rows (the
    /// reduction of the frictional problem, `hbm::friction`): a zero initial tangential gap,
    /// the obstacle's tangential translation as that row's gap harmonics.
    pub fn stacked(&self) -> Option<ContactOperator> {
        let t = self.tangential.as_ref()?;
        let nc = self.nodes();
        let mut gap_harmonics = BTreeMap::new();
        for k in self.gap_harmonics.keys().chain(t.motion.keys()) {
            let zero = vec![c64::new(0.0, 0.0); nc];
            let mut row = self.gap_harmonics.get(k).unwrap_or(&zero).clone();
            row.extend_from_slice(t.motion.get(k).unwrap_or(&zero));
            gap_harmonics.insert(*k, row);
        }
        let mut g0 = self.g0.clone();
        g0.resize(2 * nc, 0.0);
        Some(ContactOperator {
            b_free: self.b_free.stacked(&t.b_free),
            b_prescribed: self.b_prescribed.stacked(&t.b_prescribed),
            g0,
            gap_harmonics,
            tangential: None,
        })
    }

    /// The rows the solver reduces to: the stacked ones with friction, else B itself.
    pub fn reduction_rows(&self) -> std::borrow::Cow<'_, Csc> {
        match &self.tangential {
            Some(t) => std::borrow::Cow::Owned(self.b_free.stacked(&t.b_free)),
            None => std::borrow::Cow::Borrowed(&self.b_free),
        }
    }
}

/// g0(t) = g0 + Σ_k Re(ĝ_k e^{ikωt}) of every row into `out`.
pub fn periodic_gap(
    g0: &[f64],
    harmonics: &BTreeMap<usize, Vec<c64>>,
    omega: f64,
    t: f64,
    out: &mut [f64],
) {
    out.copy_from_slice(g0);
    for (&k, z) in harmonics {
        let rotor = c64::from_polar(1.0, k as f64 * omega * t);
        for (o, z) in out.iter_mut().zip(z) {
            *o += (z * rotor).re;
        }
    }
}

/// B and g0 from the contact set's normals and gaps.
pub fn contact_operator(set: &ContactSet, dofs: &DofMap) -> ContactOperator {
    let (b_free, b_prescribed) = rows(set, dofs, |n| n);
    ContactOperator {
        b_free,
        b_prescribed,
        g0: set.gaps.clone(),
        gap_harmonics: BTreeMap::new(),
        tangential: None,
    }
}

/// The tangential rows t_i = ẑ × n_i = (−n_y, n_x) of the contact set, with μ per node.
pub fn tangential_rows(set: &ContactSet, dofs: &DofMap, coefficients: Vec<f64>) -> Tangential {
    let (b_free, b_prescribed) = rows(set, dofs, |n| [-n[1], n[0]]);
    Tangential {
        b_free,
        b_prescribed,
        coefficients,
        motion: BTreeMap::new(),
    }
}

/// The rows `direction(n_i)` at each contact node's dofs (and its target's, weighted), split
/// into free and prescribed columns.
fn rows(set: &ContactSet, dofs: &DofMap, direction: impl Fn([f64; 2]) -> [f64; 2]) -> (Csc, Csc) {
    let (mut free, mut held) = (Vec::new(), Vec::new());
    for (i, normal) in set.normals.iter().enumerate() {
        let vector = direction(*normal);
        for (n, w) in set.row_nodes(i) {
            for (c, &component) in vector.iter().enumerate() {
                let d = 2 * n + c;
                if let Some(f) = dofs.free_index(d) {
                    free.push((i, f, w * component));
                } else if let Some(p) = dofs.prescribed_index(d) {
                    held.push((i, p, w * component));
                }
            }
        }
    }
    let nc = set.nodes.len();
    (
        Csc::from_entries(nc, dofs.free.len(), &free),
        Csc::from_entries(nc, dofs.prescribed.len(), &held),
    )
}
