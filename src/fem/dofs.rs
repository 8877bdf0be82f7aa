//! Which degrees of freedom are solved for: every dof `2·node + component` of a node that
//! belongs to a cell is either free (an unknown) or prescribed (held at zero or at a given
//! motion); dofs of nodes without cells are neither.

/// Free and prescribed dofs among all 2·nodes dofs.
#[derive(Clone, Debug)]
pub struct DofMap {
    /// global dof → free index.
    free_of: Vec<Option<usize>>,
    /// global dof → prescribed index.
    prescribed_of: Vec<Option<usize>>,
    /// free index → global dof.
    pub free: Vec<usize>,
    /// prescribed index → global dof.
    pub prescribed: Vec<usize>,
}

impl DofMap {
    /// `active[d]`: the dof belongs to a cell; `held[d]`: held (zero or a given motion).
    pub fn new(active: &[bool], held: &[bool]) -> Self {
        let n = active.len();
        let (mut free_of, mut prescribed_of) = (vec![None; n], vec![None; n]);
        let (mut free, mut prescribed) = (Vec::new(), Vec::new());
        for d in (0..n).filter(|&d| active[d]) {
            if held[d] {
                prescribed_of[d] = Some(prescribed.len());
                prescribed.push(d);
            } else {
                free_of[d] = Some(free.len());
                free.push(d);
            }
        }
        DofMap {
            free_of,
            prescribed_of,
            free,
            prescribed,
        }
    }

    /// All dofs, 2 per mesh node.
    pub fn total(&self) -> usize {
        self.free_of.len()
    }

    /// The free index of global dof `d`, if it is free.
    pub fn free_index(&self, d: usize) -> Option<usize> {
        self.free_of[d]
    }

    /// The prescribed index of global dof `d`, if it is prescribed.
    pub fn prescribed_index(&self, d: usize) -> Option<usize> {
        self.prescribed_of[d]
    }

    /// global dof → free index, for `Triplets::block`.
    pub fn free_map(&self) -> &[Option<usize>] {
        &self.free_of
    }

    /// global dof → prescribed index, for `Triplets::block`.
    pub fn prescribed_map(&self) -> &[Option<usize>] {
        &self.prescribed_of
    }

    /// Free values scattered onto all dofs (prescribed and inactive dofs zero).
    pub fn scatter_free(&self, free: &[f64]) -> Vec<f64> {
        let mut u = vec![0.0; self.total()];
        for (&d, &v) in self.free.iter().zip(free) {
            u[d] = v;
        }
        u
    }
}
