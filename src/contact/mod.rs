//! Unilateral contact with rigid obstacles and between meshed bodies: candidates, normals and
//! gaps (`geometry`; node-to-segment pairing with another body in `pairing`), the
//! operator B and g0 on the solver's dofs (`operator`), and the mass redistribution that
//! removes the contact nodes' inertia (`mass`).

pub mod geometry;
pub mod mass;
pub mod operator;
pub mod pairing;

pub use operator::{contact_operator, tangential_rows, ContactOperator, Tangential};
