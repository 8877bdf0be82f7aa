//! Sparse linear algebra over faer: matrices built from triplets, restricted to the free dofs,
//! and LU factorizations whose symbolic analysis is shared by every matrix of the same pattern
//! (all harmonics, all frequencies of a sweep): `sparse` (triplets, CSC), `lu` (the sparse
//! LUs), `dense` (dense LU, inverse, eigenvalues), `gmres` (restarted flexible GMRES),
//! `schur` (the Schur-complement LDLᵀ) and `modal` (the modal reduction).

mod dense;
mod gmres;
mod lu;
pub mod modal;
pub mod schur;
mod sparse;

pub use dense::*;
pub use gmres::*;
pub use lu::*;
pub use sparse::*;
