//! The stages `run`, `run_transient`, `check` and `modes` string together, each timed into
//! `StageTimes` (`times`) and announced to the `Reporter`: meshing, the resonance check, solving by
//! harmonic balance or by time marching, the stability verdict, and committing the staged
//! output with its summary.

use std::path::{Path, PathBuf};

use super::model::{build, Model, Purpose};
use super::resonance::ResonanceCheck;
use super::stability::{self, RunModes, Stability};
use super::summary::{MeshInfo, Summary};
use super::times::{Stage, StageTimes};
use crate::config::{BasisSpec, Pipeline, StabilityMethod};
use crate::hbm::{self, HbSettings, Solution};
use crate::mesh::{self, Mesh2d};
use crate::output::tables::write_json;
use crate::output::StagedDir;
use crate::progress::Reporter;
use crate::transient::setup::Marching;
use crate::transient::{self, TransientResult, TransientSettings};
use crate::{Error, Result};

/// The run's bookkeeping: which pipeline, the reporter, and the stage times so far. Every
/// stage runs through it, so each is timed, announced, and its error names pipeline and stage.
pub struct Stages<'a> {
    pipeline: &'a Path,
    pub reporter: &'a dyn Reporter,
    pub times: StageTimes,
}

impl<'a> Stages<'a> {
    pub fn new(p: &'a Pipeline, reporter: &'a dyn Reporter) -> Self {
        Stages {
            pipeline: &p.source,
            reporter,
            times: StageTimes::default(),
        }
    }

    /// Run `stage`: timed, announced, its error in context.
    pub fn run<T>(&mut self, stage: Stage, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let pipeline = self.pipeline;
        self.times
            .time(stage, self.reporter, f)
            .map_err(|e| e.in_stage(pipeline, stage.name()))
    }

    /// `e` in the context of `stage`.
    pub fn context(&self, stage: Stage, e: Error) -> Error {
        e.in_stage(self.pipeline, stage.name())
    }
}

/// The mesh cache a run writing to `out` uses: `.mesh-cache` beside `out`.
pub fn mesh_cache_dir(out: &Path) -> PathBuf {
    out.parent()
        .map(|d| d.join(".mesh-cache"))
        .unwrap_or_else(|| PathBuf::from(".mesh-cache"))
}

/// What to ask gmsh for, and within which limits.
pub fn mesh_request(p: &Pipeline) -> (mesh::gmsh::MeshRequest, mesh::gmsh::MeshLimits) {
    let request = mesh::gmsh::MeshRequest {
        geo: p.geometry.file.clone(),
        parameters: p.geometry.parameters.clone(),
        mesh_size: p.geometry.mesh_size,
        order: p.geometry.order,
        quads: p.geometry.quads,
        gmsh: p.geometry.gmsh.clone(),
        trusted: p.geometry.trusted,
    };
    let limits = mesh::gmsh::MeshLimits {
        max_elements: p.geometry.max_elements,
        timeout: std::time::Duration::from_secs_f64(p.geometry.gmsh_timeout),
    };
    (request, limits)
}

/// Mesh the geometry (or reuse the cache under the output's parent) and read it.
pub fn mesh(p: &Pipeline, out: &Path, stages: &mut Stages) -> Result<(Mesh2d, MeshInfo)> {
    let cache_dir = mesh_cache_dir(out);
    let (request, limits) = mesh_request(p);
    let reporter = stages.reporter;
    let mut meshed = stages.run(Stage::Mesh, || {
        mesh::gmsh::mesh_geometry_with(&request, &limits, &cache_dir, reporter)
    })?;
    crate::output::staging::mark_kept(&cache_dir, "mesh-cache")?;
    let first = stages.run(Stage::Read, || Ok(mesh::msh::read_msh(&meshed.msh)))?;
    let mesh = match first {
        // A cached mesh that passed its checksum but does not read (a damaged write) is made
        // again, once; a mesh the pipeline names itself is never touched.
        Err(e) if meshed.cache_hit && meshed.msh.starts_with(&cache_dir) => {
            reporter.warning(&format!("{e}: meshing again"));
            mesh::gmsh::evict(&meshed.msh);
            meshed = stages.run(Stage::Mesh, || {
                mesh::gmsh::mesh_geometry_with(&request, &limits, &cache_dir, reporter)
            })?;
            stages.run(Stage::Read, || mesh::msh::read_msh(&meshed.msh))?
        }
        other => other.map_err(|e| stages.context(Stage::Read, e))?,
    };
    let info = MeshInfo {
        geometry: p.geometry.file.clone(),
        parameters: p.geometry.parameters.clone(),
        mesh_size: p.geometry.mesh_size,
        order: p.geometry.order,
        msh: meshed.msh,
        cache_hit: meshed.cache_hit,
        gmsh_version: meshed.gmsh_version,
        nodes: mesh.nodes.len(),
        cells: mesh.cells.len(),
        min_edge_length: mesh.min_edge_length(),
    };
    Ok((mesh, info))
}

/// The solver settings a pipeline asks for (N defaults to 16H; with a spline basis to 8
/// Gauss points per segment).
pub fn hb_settings(p: &Pipeline) -> HbSettings {
    let hb = &p.harmonic_balance;
    let default = match hb.basis {
        BasisSpec::Spline { segments, .. } => {
            crate::hbm::sampler::SPLINE_SAMPLES_PER_SEGMENT * segments
        }
        BasisSpec::Fourier => HbSettings::default_samples(hb.harmonics),
    };
    HbSettings {
        harmonics: hb.harmonics,
        samples: hb.samples.unwrap_or(default),
        c_scale: hb.solver.c_scale,
        tolerance: hb.solver.tolerance,
        max_iterations: hb.solver.max_iterations,
        max_seconds: hb.solver.max_seconds,
    }
}

/// The range H is chosen in (`harmonic_balance.harmonics: {min, max}`); `None` at a fixed H.
pub fn harmonic_range(p: &Pipeline) -> Option<hbm::adaptive::HarmonicRange> {
    let hb = &p.harmonic_balance;
    (hb.harmonics_max > hb.harmonics).then_some(hbm::adaptive::HarmonicRange {
        min: hb.harmonics,
        max: hb.harmonics_max,
        tolerance: hb.tolerance,
    })
}

/// Harmonic balance on the model; the solver's own phases go into the stage times (its
/// reporter hears the whole solve as the stage `solve`).
pub fn solve(p: &Pipeline, model: &Model, stages: &mut Stages) -> Result<Solution> {
    stages.reporter.stage(Stage::Solve.name());
    let start = std::time::Instant::now();
    let contact = model.contact.as_ref().map(|c| &c.operator);
    let solution = hbm::solve_within(
        &model.system,
        contact,
        &hb_settings(p),
        harmonic_range(p),
        stages.reporter,
    )
    .map_err(|e| stages.context(Stage::Solve, e))?;
    // The line `[solve] 0.05 s`; the summary holds the solve's phases instead.
    let seconds = start.elapsed().as_secs_f64();
    stages.reporter.stage_done(Stage::Solve.name(), seconds);
    let t = &solution.timings;
    for (name, secs) in [
        (Stage::Factor, t.factor),
        (Stage::LinearSolve, t.linear_solve),
        (Stage::Reduce, t.reduce),
        (Stage::Newton, t.newton),
        (Stage::KnobCheck, t.knob_check),
        (Stage::Recover, t.recover),
    ] {
        stages.times.add(name, secs);
    }
    Ok(solution)
}

/// Before the resonance check, which runs on one core: the memory of the solve's
/// factorizations touched on another (`hbm::touch_factor_memory`).
pub fn touch_solve_memory(p: &Pipeline, model: &Model) {
    let contact = model.contact.as_ref().map(|c| &c.operator);
    hbm::touch_factor_memory(&model.system, contact, &hb_settings(p));
}

/// The resonance check (`resonance`): the natural frequencies nearest each load-excited
/// harmonic, and warnings for those within a half-power band. A check that fails does not
/// stop the run: it becomes a warning.
pub fn resonance(
    model: &Model,
    modes: &RunModes,
    stages: &mut Stages,
) -> (Option<ResonanceCheck>, Vec<String>) {
    let check = || {
        let lowest = modes.get(model).and_then(|m| m.ok());
        super::resonance::check(model, lowest)
    };
    match stages.run(Stage::Resonance, check) {
        Ok((check, warnings)) => (Some(check), warnings),
        Err(e) => (None, vec![format!("the resonance check failed: {e}")]),
    }
}

/// Time marching from rest to the periodic state.
pub fn march<'m>(
    p: &Pipeline,
    model: &'m Model,
    initial: Option<crate::transient::InitialState>,
    stages: &mut Stages,
) -> Result<(Marching<'m>, TransientResult)> {
    let Some(diag) = &model.mass_diagonal else {
        return Err(Error::Model(
            "internal: transient needs a diagonal mass".into(),
        ));
    };
    let contact = model.contact.as_ref().map(|c| &c.operator);
    let marching = Marching::new(&model.system, diag, contact, &probe_nodes(model))
        .map_err(|e| stages.context(Stage::March, e))?;
    let settings = TransientSettings {
        courant: p.transient.courant,
        periodic_tolerance: p.transient.periodic_tolerance,
        max_periods: p.transient.max_periods,
        samples_per_period: p.output.frames,
    };
    let reporter = stages.reporter;
    let result = stages.run(Stage::March, || {
        let mut problem = marching.problem();
        problem.initial = initial;
        transient::run_to_periodic(&problem, &settings, reporter)
    })?;
    reporter.task_done("periods");
    Ok((marching, result))
}

/// Stage `stability`: the verdict on the harmonic-balance `solution` of `model`. Contact
/// scenes: the Floquet multipliers of the state (`stability.method: floquet`, the default),
/// time marching (`march`: a model of the same mesh with a diagonal mass from its own
/// harmonic-balance state, solved from `solution`'s multipliers) or both (a frictional
/// state: marching alone, Floquet leaves it undecided); linear scenes judge by their
/// damping, static states (H = 0) are not judged.
pub fn stability(
    p: &Pipeline,
    (model, modes): (&Model, &RunModes),
    solution: &Solution,
    stages: &mut Stages,
) -> Result<Stability> {
    let spec = &p.stability;
    let Some(contact) = solution.contact.as_ref().filter(|_| spec.check) else {
        return Ok(match (&solution.contact, spec.check) {
            (None, _) => stability::linear(model),
            _ => Stability::not_checked(),
        });
    };
    // A frictional state has no Floquet multipliers here: marching judges it where asked.
    if contact.friction.is_some() && spec.method != StabilityMethod::Floquet {
        return march_verdict(p, model, contact, None, stages);
    }
    let segments = match stability::shortcut(model, &solution.basis, solution.omega, contact) {
        Ok(verdict) => return Ok(verdict),
        Err(segments) => segments,
    };
    let floquet = match spec.method {
        StabilityMethod::March => None,
        _ => Some(stages.run(Stage::Stability, || {
            floquet_verdict((model, modes), solution, contact, &segments)
        })),
    };
    match (spec.method, floquet) {
        (StabilityMethod::Floquet, Some(Ok(verdict))) => return Ok(verdict),
        (StabilityMethod::Both, Some(Ok(verdict))) => {
            let marched = march_verdict(p, model, contact, Some(&verdict), stages)?;
            return Ok(stability::audited(verdict, marched));
        }
        (_, Some(Err(e))) => stages.reporter.warning(&format!(
            "no Floquet multipliers ({e}): judged by time marching instead"
        )),
        _ => {}
    }
    march_verdict(p, model, contact, None, stages)
}

/// The Floquet verdict on `contact`, the contact part of `solution`, a state of `model`
/// (`stability::by_floquet_state`, on a Hill model of the run's `modes`).
fn floquet_verdict(
    (model, modes): (&Model, &RunModes),
    solution: &Solution,
    contact: &crate::hbm::ContactSolution,
    segments: &[crate::hbm::floquet::Segment],
) -> Result<Stability> {
    let hill = match (modes.get(model), &model.contact) {
        (Some(found), Some(cm)) => Some(crate::hbm::hill::HillModel::with_modes(
            &model.system,
            &cm.operator.b_free,
            found?,
        )?),
        _ => stability::hill_model(model, &solution.basis)?,
    };
    stability::by_floquet_state(model, hill.as_ref(), solution.omega, contact, segments)
}

/// The time-marching verdict on `contact`, a state of `model` (what the march did compared
/// with the `floquet` verdict's prediction, where given).
fn march_verdict(
    p: &Pipeline,
    model: &Model,
    contact: &crate::hbm::ContactSolution,
    floquet: Option<&Stability>,
    stages: &mut Stages,
) -> Result<Stability> {
    let spec = &p.stability;
    let reporter = stages.reporter;
    stages.run(Stage::Stability, || {
        let marching = build(p, model.mesh.clone(), Purpose::Transient)?;
        let verdict = stability::by_marching(
            p,
            spec,
            &marching,
            model.system.omega,
            Some(contact),
            floquet,
            reporter,
        );
        // A scene time marching cannot take (e.g. prescribed motion on contact nodes) gets no
        // verdict, and says why; the harmonic-balance result stands. A march refused as
        // beyond the machine (`transient::budget`) is bad input, as `check` says.
        match verdict {
            Err(e) if e.exit_code() == 2 => Err(stability_march_refused(e)),
            v => Ok(v.unwrap_or_else(|e| Stability::cannot_march(&e))),
        }
    })
}

/// The march of the stability check `run` makes on a contact scene, estimated on `model`
/// (whose diagonal mass and stiffness the march takes) before anything is solved, and refused
/// now (exit 2) if it is beyond the machine (`transient::budget`). The estimate samples once
/// per period, the march a few times: their steps per period differ by fewer than its samples.
pub fn check_stability_march(p: &Pipeline, model: &Model) -> Result<()> {
    // A Coriolis scene is judged by marching whatever the method (`stability::by_floquet_state`).
    let marches =
        p.stability.method != StabilityMethod::Floquet || model.system.gyroscopic.is_some();
    if model.contact.is_none() || !p.stability.check || !marches {
        return Ok(());
    }
    let settings = TransientSettings {
        courant: p.transient.courant,
        periodic_tolerance: 0.0,
        max_periods: p.stability.max_periods,
        samples_per_period: 1,
    };
    admit_march(model, &settings, &[]).map_err(stability_march_refused)
}

/// The march of `hbcontact transient` on `model` (a `Purpose::Transient` one): `Err` with the
/// refusal it would meet (`transient::budget`).
pub fn check_transient_march(p: &Pipeline, model: &Model) -> Result<()> {
    let settings = TransientSettings {
        courant: p.transient.courant,
        periodic_tolerance: p.transient.periodic_tolerance,
        max_periods: p.transient.max_periods,
        samples_per_period: p.output.frames,
    };
    admit_march(model, &settings, &probe_nodes(model))
}

/// `Err` with the refusal of a march of `model` with `settings` that is beyond the machine;
/// `Ok` for one within it, and for one that cannot be set up (its own run says why).
fn admit_march(model: &Model, settings: &TransientSettings, probes: &[usize]) -> Result<()> {
    let Some(diag) = &model.mass_diagonal else {
        return Ok(());
    };
    let contact = model.contact.as_ref().map(|c| &c.operator);
    let Ok(marching) = Marching::new(&model.system, diag, contact, probes) else {
        return Ok(());
    };
    match transient::estimate(&marching.problem(), settings) {
        Ok(estimate) => estimate
            .admit(&transient::budget::Limits::of_machine())
            .map(|_| ()),
        Err(_) => Ok(()),
    }
}

/// A refusal of the stability check's march, saying whose march it is and how to skip it.
fn stability_march_refused(e: Error) -> Error {
    match e {
        Error::Input(why) => Error::Input(format!(
            "the stability check of `run` marches in time (`stability.check: false` skips it, \
             stability.max_periods bounds its periods): {why}"
        )),
        e => e,
    }
}

fn probe_nodes(model: &Model) -> Vec<usize> {
    model.probes.iter().flat_map(|(_, n)| n.clone()).collect()
}

/// Write `summary.json` (with the stage times so far) into the staged directory and commit it.
pub fn commit(staged: StagedDir, summary: &Summary) -> Result<PathBuf> {
    write_json(&staged.path().join("summary.json"), summary)?;
    staged.commit()
}

/// The mesh the run used, next to its results (`mesh.msh`), so the output stands alone.
pub fn copy_mesh(info: &MeshInfo, dir: &Path) -> Result<()> {
    let target = dir.join("mesh.msh");
    std::fs::copy(&info.msh, &target).map_err(|e| Error::io(&target, e))?;
    Ok(())
}
