//! Unilateral contact with rigid obstacles: candidates, normals and gaps (`geometry`), the
//! operator B and g0 on the solver's dofs (`operator`), and the mass redistribution that
//! removes the contact nodes' inertia (`mass`).

pub mod geometry;
pub mod mass;
pub mod operator;

pub use operator::{contact_operator, ContactOperator};
