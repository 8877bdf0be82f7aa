//! The opening every command shares: claim the output folder, then mesh → read → check →
//! assemble → penetration check, each a timed stage. `run`, `run_transient`, `check`,
//! `modes`, `sweep` and the study's points all start here, so a scene is judged the same way
//! whichever command reads it.
//!
//! Glossary: a *scene* is the assembled model of one pipeline with its mesh's facts and the
//! warnings its checks raised; the *purpose* decides the mass (consistent for harmonic
//! balance, diagonal for time marching).

use std::path::Path;

use super::model::{build, Model, Purpose};
use super::sanity;
use super::stages::{self, Stages};
use super::summary::MeshInfo;
use super::times::Stage;
use super::RunOptions;
use crate::config::Pipeline;
use crate::output::staging;
use crate::progress::Reporter;
use crate::Result;

/// A meshed, checked and assembled scene.
pub struct Scene {
    pub model: Model,
    pub mesh_info: MeshInfo,
    /// What the checks found that the user should know (the run's summary lists them).
    pub warnings: Vec<String>,
}

/// Claim `out` for this run (`options.replace`), start the run's stage times, and prepare
/// the scene for `purpose`.
pub fn open<'a>(
    p: &'a Pipeline,
    out: &Path,
    options: &RunOptions,
    purpose: Purpose,
    reporter: &'a dyn Reporter,
) -> Result<(Scene, Stages<'a>)> {
    staging::claim(out, options.replace, reporter)?;
    let mut stages = Stages::new(p, reporter);
    let scene = prepare(p, out, purpose, &mut stages)?;
    Ok((scene, stages))
}

/// Mesh (or reuse the cache beside `out`), read, check the mesh and the supports, assemble
/// for `purpose`, and check the initial penetration of the contact nodes.
pub fn prepare(p: &Pipeline, out: &Path, purpose: Purpose, stages: &mut Stages) -> Result<Scene> {
    let (mesh, mesh_info) = stages::mesh(p, out, stages)?;
    let mut warnings = stages.run(Stage::Check, || sanity::check_mesh(p, &mesh))?;
    warnings.extend(stages.run(Stage::Check, || sanity::check_supports(p, &mesh, purpose))?);
    let model = stages.run(Stage::Assemble, || build(p, mesh, purpose))?;
    warnings.extend(stages.run(Stage::Check, || {
        sanity::check_initial_penetration(p, &model)
    })?);
    Ok(Scene {
        model,
        mesh_info,
        warnings,
    })
}
