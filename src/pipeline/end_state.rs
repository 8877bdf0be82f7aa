//! `end_state.json`: the state a time marching ended in, written next to its results so the
//! next run can start from it (`transient.start: previous`). A brute-force frequency sweep
//! is then a loop that changes the frequency and starts each run where the last ended,
//! which is how a sweep by time marching follows one branch until it jumps at a fold.
//!
//! The state is u and the half-step velocity v = (u_{n+1/2} − u_{n−1/2})/Δt of the central
//! difference scheme on the free dofs at the end of the last period marched (phase 0 of the
//! load), so a restart at the same Δt continues the marching exactly.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::config::Pipeline;
use crate::transient::{InitialState, TransientResult};
use crate::{Error, Result};

use super::summary::MeshInfo;

/// The file's name in a transient output directory.
pub const FILE: &str = "end_state.json";

/// What `end_state.json` holds.
#[derive(Serialize, Deserialize)]
struct EndState {
    /// The fundamental frequency the state was marched at [Hz].
    frequency: f64,
    /// The mesh file (in the mesh cache, named by a hash of geometry, parameters and size).
    mesh: PathBuf,
    /// Periods marched, and whether the state had become periodic.
    periods: usize,
    converged: bool,
    /// u on the free dofs [m].
    displacement: Vec<f64>,
    /// The half-step velocity on the free dofs [m/s].
    velocity: Vec<f64>,
}

/// Write the end state of `result` into `dir` (the staged output directory).
pub fn write(dir: &Path, p: &Pipeline, mesh: &MeshInfo, result: &TransientResult) -> Result<()> {
    let marched = Marched {
        periods: result.periods,
        converged: result.converged,
    };
    let frequency = p.harmonic_balance.frequency;
    save(dir, frequency, &mesh.msh, &result.end_state, marched)
}

/// How the saved state was reached (any state can be saved, e.g. a harmonic-balance one to
/// march from: then 0 periods, not converged).
#[derive(Clone, Copy, Debug, Default)]
pub struct Marched {
    pub periods: usize,
    pub converged: bool,
}

/// Save `state` (on the free dofs of the model meshed as `mesh`, at `frequency` Hz) as
/// `dir`/end_state.json, for the next `transient.start: previous` run into `dir`.
pub fn save(
    dir: &Path,
    frequency: f64,
    mesh: &Path,
    state: &InitialState,
    marched: Marched,
) -> Result<()> {
    let state = EndState {
        frequency,
        mesh: mesh.to_path_buf(),
        periods: marched.periods,
        converged: marched.converged,
        displacement: state.displacement.clone(),
        velocity: state.velocity.clone(),
    };
    // The folder counts end_state.json as the tool's own (a state saved here to march from
    // is replaced by the next run, like its results).
    crate::output::staging::claim_entries(dir, "transient", &[FILE])?;
    let path = dir.join(FILE);
    let text = serde_json::to_string(&state)
        .map_err(|e| Error::Model(format!("internal: cannot encode the end state: {e}")))?;
    std::fs::write(&path, text).map_err(|e| Error::io(&path, e))
}

/// The state `transient.start: previous` starts from: `dir`/end_state.json, checked to belong
/// to the same mesh and to have `free_dofs` entries, scaled by 1 + `transient.perturbation`.
pub fn read(dir: &Path, p: &Pipeline, mesh: &MeshInfo, free_dofs: usize) -> Result<InitialState> {
    let hint = "transient.start: previous starts from the end state an earlier \
                `hbcontact transient` of this pipeline wrote there (run once with start: rest)";
    read_file(&dir.join(FILE), hint, p, mesh, free_dofs)
}

/// The state `transient.start: {state: FILE}` starts from, checked as `read`'s.
pub fn read_named(path: &Path, p: &Pipeline, mesh: &MeshInfo, free: usize) -> Result<InitialState> {
    let hint = "transient.start.state names an end_state.json that `hbcontact transient` \
                wrote for the same mesh and boundary conditions";
    read_file(path, hint, p, mesh, free)
}

fn read_file(
    path: &Path,
    hint: &str,
    p: &Pipeline,
    mesh: &MeshInfo,
    free_dofs: usize,
) -> Result<InitialState> {
    let input = |why: String| Error::Input(format!("{}: {why}; {hint}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| input(format!("cannot read it ({e})")))?;
    let state: EndState =
        serde_json::from_str(&text).map_err(|e| input(format!("not an end state ({e})")))?;
    if state.mesh != mesh.msh {
        return Err(input(format!(
            "it was marched on the mesh {}, this run's mesh is {} (the geometry, its \
             parameters or the mesh size changed)",
            state.mesh.display(),
            mesh.msh.display()
        )));
    }
    let sizes = [state.displacement.len(), state.velocity.len()];
    if sizes != [free_dofs, free_dofs] {
        return Err(input(format!(
            "it has {} displacements and {} velocities, this model has {free_dofs} free dofs \
             (the boundary conditions changed)",
            sizes[0], sizes[1]
        )));
    }
    if !state
        .displacement
        .iter()
        .chain(&state.velocity)
        .all(|v| v.is_finite())
    {
        return Err(input("it holds values that are not finite".into()));
    }
    let start = InitialState {
        displacement: state.displacement,
        velocity: state.velocity,
    };
    Ok(start.scaled(1.0 + p.transient.perturbation))
}
