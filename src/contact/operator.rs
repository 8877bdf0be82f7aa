//! The contact operator of (1)–(2) in docs/method.md: row i of B is the unit normal n_i at
//! contact node i's (x, y) dofs, pointing from the body toward the obstacle, so (B u)_i is the
//! node's displacement toward the obstacle and g = B u − g0 ≤ 0 is the non-penetration
//! condition (g0 the initial gap along n_i, positive = open).

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
    /// Initial gaps along the normals.
    pub g0: Vec<f64>,
}

impl ContactOperator {
    pub fn nodes(&self) -> usize {
        self.g0.len()
    }
}

/// B and g0 from the contact set's normals and gaps.
pub fn contact_operator(set: &ContactSet, dofs: &DofMap) -> ContactOperator {
    let (mut free, mut held) = (Vec::new(), Vec::new());
    for (i, (&n, normal)) in set.nodes.iter().zip(&set.normals).enumerate() {
        for (c, &component) in normal.iter().enumerate() {
            let d = 2 * n + c;
            if let Some(f) = dofs.free_index(d) {
                free.push((i, f, component));
            } else if let Some(p) = dofs.prescribed_index(d) {
                held.push((i, p, component));
            }
        }
    }
    let nc = set.nodes.len();
    ContactOperator {
        b_free: Csc::from_entries(nc, dofs.free.len(), &free),
        b_prescribed: Csc::from_entries(nc, dofs.prescribed.len(), &held),
        g0: set.gaps.clone(),
    }
}
