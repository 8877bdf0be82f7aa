//! Finite elements for 2-D linear elasticity: shape functions and Gauss rules (`shapes`),
//! element matrices (`elasticity`), global assembly (`assembly`), the free/prescribed dof
//! numbering (`dofs`), edge loads (`loads`), modes (`modes`) and stress recovery (`stress`).
//!
//! Degrees of freedom are numbered node-major over *all* mesh nodes: dof `2*node + component`
//! (component 0 = x, 1 = y). Nodes without cells simply have empty rows.

pub mod assembly;
pub mod dofs;
pub mod elasticity;
pub mod loads;
pub mod modes;
pub mod shapes;
pub mod stress;

pub use assembly::{assemble_mass, assemble_stiffness, MassKind};
pub use dofs::DofMap;
pub use loads::{body_force_load, edge_traction_load, point_force_load};
pub use stress::{cell_stresses, CellStress};

/// How the out-of-plane direction is treated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlaneModel {
    /// ε_zz = 0; loads and matrices are per unit thickness times `thickness`.
    PlaneStrain,
    /// σ_zz = 0.
    PlaneStress,
}

/// Isotropic linear-elastic material with the plane model and thickness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub youngs_modulus: f64,
    pub poisson_ratio: f64,
    pub density: f64,
    pub model: PlaneModel,
    /// Out-of-plane thickness (1 for plane strain unless given).
    pub thickness: f64,
}

impl Material {
    /// The unit of a force on the body for plot axes: the model's forces are for `thickness`,
    /// so per metre of thickness at the default 1 m (a plane-strain slice), newtons of the
    /// given thickness otherwise.
    pub fn force_unit(&self) -> &'static str {
        if self.thickness == 1.0 {
            "N per m of thickness"
        } else {
            "N"
        }
    }
}
