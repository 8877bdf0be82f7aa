//! Writing results: VTU snapshots and `.pvd` collections for ParaView (`vtu`), CSV time
//! histories and JSON summaries (`tables`), a ParaView script opening the series (`paraview`),
//! all staged in a temporary directory that is renamed
//! into place only when complete (`staging`).

pub mod outline;
pub mod paraview;
pub mod plot;
pub mod staging;
pub mod tables;
pub mod vtu;

pub use staging::StagedDir;
pub use vtu::{write_lines_vtu, write_pvd, write_vtu, Field};
