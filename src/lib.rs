//! hbcontact: periodic steady-state vibration of 2-D elastic bodies with unilateral contact,
//! by harmonic-balance finite elements.
//!
//! Data flows one way through the stages:
//! `config` → `mesh` (gmsh, .msh) → `fem` (K, M, D, loads) → `contact` (B, g0) → `hbm` (solve)
//! → `output` (VTU/PVD/CSV/summary). `pipeline` strings them together; `transient` is the
//! independent time-marching cross-check.

// `!(x > 0.0)` is how this crate rejects NaN together with non-positive values: keep it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod config;
pub mod contact;
pub mod error;
pub mod fem;
pub mod files;
pub mod hbm;
pub mod linalg;
pub mod mesh;
pub mod output;
pub mod pipeline;
pub mod progress;
pub mod study;
pub mod sweep;
pub mod transient;

pub use error::{Error, Result};
pub use progress::{Reporter, Silent};
