//! Unilateral contact with rigid obstacles: candidates, normals and gaps (`geometry`), and the
//! mass redistribution that removes the contact nodes' inertia (`mass`).

pub mod geometry;
pub mod mass;
