//! The stages in order, as the user sees them:
//! mesh (gmsh) → read → model (fem, contact, mass) → solve (harmonic balance or time marching)
//! → output (staged, then committed), returning a typed `Summary` (also written as
//! `summary.json`) that says what was simulated, how big it was, how accurate and what each
//! stage cost.

pub mod compare;
pub mod end_state;
pub mod floquet_vector;
pub mod late;
pub mod model;
pub mod modes;
pub mod outputs;
pub mod plots;
pub mod publish;
pub mod report;
pub mod resonance;
pub mod sanity;
pub mod scene;
pub mod stability;
pub mod stages;
pub mod summary;
pub mod times;

use std::path::PathBuf;

use schemars::JsonSchema;
use serde::Serialize;

use crate::config::{Pipeline, TransientStart};
use crate::contact::geometry::{build_contact_set, ContactSet};
use crate::output::staging::Replace;
use crate::output::StagedDir;
use crate::progress::Reporter;
use crate::Result;
pub use model::{build, Model, Purpose};
pub use modes::{modes, ModesResult, ModesSummary};
pub use publish::WriteLevel;
use report::Sampled;
pub use scene::{open, prepare, Scene};
pub use stages::{hb_settings, Stages};
use summary::MeshInfo;
pub use summary::{summary_schema, Summary};
pub use times::{Stage, StageTimes};

/// Options from the command line.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Overrides `output.directory`.
    pub out: Option<PathBuf>,
    /// How much to write: the summary only or with the amplitudes (study points), or all.
    pub write: WriteLevel,
    /// Who may replace an existing output folder (`--force`: move one not ours aside).
    pub replace: Replace,
    /// `run_transient`: an interruption (`transient::request_stop`) stops the march and the
    /// whole periods marched are written as a partial result (`transient.stopped` in the
    /// summary). The command line's `transient` sets it; a study's points leave it off.
    pub keep_interrupted_march: bool,
}

/// A finished run: where its files are and what it reports.
#[derive(Clone, Debug)]
pub struct RunResult {
    pub dir: PathBuf,
    pub summary: Summary,
}

/// The directory results go to.
/// The pipeline at `path` with `overrides` applied, validated field by field (`config`) and
/// as a scene (`sanity::check_spline_scene`).
pub fn load_pipeline(path: &std::path::Path, overrides: &[String]) -> Result<Pipeline> {
    let p = crate::config::load_pipeline(path, overrides)?;
    sanity::check_spline_scene(path, &p)?;
    Ok(p)
}

pub fn output_dir(p: &Pipeline, options: &RunOptions) -> PathBuf {
    options
        .out
        .clone()
        .unwrap_or_else(|| p.output.directory.clone())
}

/// `hbcontact run`: the harmonic-balance steady state.
pub fn run(p: &Pipeline, options: &RunOptions, reporter: &dyn Reporter) -> Result<RunResult> {
    let out = output_dir(p, options);
    let (scene, stages) = scene::open(p, &out, options, Purpose::HarmonicBalance, reporter)?;
    run_scene(p, options, scene, stages)
}

/// `run` from its opened scene: solve, check, judge stability, publish into the output
/// folder `open` claimed.
pub fn run_scene(
    p: &Pipeline,
    options: &RunOptions,
    scene: Scene,
    mut stages: Stages,
) -> Result<RunResult> {
    let out = output_dir(p, options);
    let Scene {
        model,
        mesh_info,
        mut warnings,
    } = scene;
    stages.run(Stage::Check, || stages::check_stability_march(p, &model))?;
    stages::touch_solve_memory(p, &model);
    let modes = stability::RunModes::of(p, &model);
    let resonance = stages::resonance(&model, &modes, &mut stages);
    let solution = stages::solve(p, &model, &mut stages)?;
    stages.run(Stage::Check, || finite_solution(&solution))?;
    warnings.extend(sanity::check_contact_result(&model, &solution));
    let mut stability = stages::stability(p, (&model, &modes), &solution, &mut stages)?;
    warnings.extend(stability.warning());
    let staged = StagedDir::create(&out, "run", options.replace)?;
    let (level, reporter) = (options.write, stages.reporter);
    let (mut summary, sampled) = stages.run(Stage::Write, || {
        let info = mesh_info.clone();
        let at = staged.path();
        let written = publish::harmonic_balance(p, (&model, info), &solution, level, at, reporter)?;
        if level == WriteLevel::Full {
            stages::copy_mesh(&mesh_info, staged.path())?;
            stability.floquet_vector_file = unstable_vector(&stability)
                .map(|v| floquet_vector::write(at, &model, v, solution.omega))
                .transpose()?;
        }
        Ok(written)
    })?;
    if publish::plotting(p, level) {
        let (plots, period) = (staged.path().join("plots"), 1.0 / summary.frequency_hz);
        stages.run(Stage::Plots, || {
            publish::plots(p, (&model, &sampled), &plots, period)
        })?;
    }
    let (check, resonance_warnings) = resonance;
    summary.resonance = check;
    summary.stability = Some(stability);
    summary.warnings.extend(resonance_warnings);
    summary.warnings.extend(warnings);
    summary.stage_seconds = stages.times;
    let dir = stages::commit(staged, &summary)?;
    Ok(RunResult { dir, summary })
}

/// The Floquet vector of an unstable verdict, the motion the run writes (`floquet_vector`).
fn unstable_vector(stability: &stability::Stability) -> Option<&crate::hbm::hill::FloquetVector> {
    (stability.verdict == stability::Verdict::Unstable)
        .then_some(stability.floquet_vector.as_ref())
        .flatten()
}

/// The warning of a march whose contact force runs away (`LateRecord::runaway`).
fn runaway_warning(late: &crate::transient::late::LateRecord, courant: f64) -> Option<String> {
    let (rate, span) = late.runaway()?;
    Some(format!(
        "the march gains energy the scene does not supply: its peak contact force grew ×{rate:.3} a period over the last {} periods, to {span:.0}× its smallest: the explicit contact step is too long for this scene; lower transient.courant (now {courant}; e.g. to {}) or add damping, and compare",
        crate::transient::late::RUNAWAY_PERIODS,
        0.5 * courant
    ))
}

/// The setting that bounds a `transient`'s periods (its late-response advice names it).
const PERIODS: &str = "transient.max_periods";

/// A solution with a non-finite coefficient is a model error (inputs of extreme magnitude
/// whose products overflow), never output.
fn finite_solution(solution: &crate::hbm::Solution) -> Result<()> {
    let finite = |v: &Vec<faer::c64>| v.iter().all(|z| z.re.is_finite() && z.im.is_finite());
    if solution.free.values().all(finite) && solution.motion.values().all(finite) {
        return Ok(());
    }
    Err(crate::Error::Model(
        "the solution holds non-finite values: the loads, sizes or material constants are of such extreme magnitudes that their products overflow; rescale the units (e.g. mm–N–s) or check the magnitudes".into(),
    ))
}

/// The harmonic-balance solution of the transient's own model (diagonal mass) at t = 0, on
/// the free dofs, scaled by 1 + `transient.perturbation`: the state a stability check
/// marches from (the same discrete system, so a stable state is kept up to the time step's
/// error); with the Floquet verdict on that state (`late::floquet_of_start`, stage
/// `stability`; a verdict that fails is a warning).
fn harmonic_balance_start(
    p: &Pipeline,
    model: &Model,
    stages: &mut Stages,
    warnings: &mut Vec<String>,
) -> Result<(crate::transient::InitialState, Option<stability::Stability>)> {
    let solution = stages::solve(p, model, stages)?;
    stages.run(Stage::Check, || finite_solution(&solution))?;
    let verdict = match stages.run(Stage::Stability, || {
        Ok(late::floquet_of_start(p, model, &solution))
    })? {
        Some(Ok(v)) => Some(v),
        Some(Err(e)) => {
            warnings.push(format!(
                "no Floquet verdict on the harmonic-balance start: {e}"
            ));
            None
        }
        None => None,
    };
    let dofs = &model.system.dofs;
    let start = stability::marching_start(&solution, dofs, p.transient.perturbation);
    Ok((start, verdict))
}

/// Where `hbcontact transient` starts (`transient.start`) and, from a harmonic-balance state,
/// that state's Floquet verdict.
fn transient_start(
    p: &Pipeline,
    model: &Model,
    mesh_info: &summary::MeshInfo,
    out: &std::path::Path,
    stages: &mut Stages,
    warnings: &mut Vec<String>,
) -> Result<(
    Option<crate::transient::InitialState>,
    Option<stability::Stability>,
)> {
    Ok(match &p.transient.start {
        TransientStart::Rest => (None, None),
        TransientStart::Rigid {
            group,
            displacement,
            velocity,
        } => {
            let nodes = match group {
                Some(g) => {
                    model::node_group(p, &model.mesh, "transient.start.rigid.group", g)?.clone()
                }
                None => (0..model.mesh.nodes.len()).collect(),
            };
            let start = rigid_start(&model.system.dofs, &nodes, *displacement, *velocity);
            (Some(start.scaled(1.0 + p.transient.perturbation)), None)
        }
        TransientStart::State(path) => {
            let free = model.system.dofs.free.len();
            (Some(end_state::read_named(path, p, mesh_info, free)?), None)
        }
        TransientStart::HarmonicBalance => {
            let (start, verdict) = harmonic_balance_start(p, model, stages, warnings)?;
            (Some(start), verdict)
        }
        TransientStart::Previous => {
            let free = model.system.dofs.free.len();
            (Some(end_state::read(out, p, mesh_info, free)?), None)
        }
    })
}

/// A rigid offset and velocity of `nodes` on the free dofs, every other dof at rest.
fn rigid_start(
    dofs: &crate::fem::DofMap,
    nodes: &[usize],
    displacement: [f64; 2],
    velocity: [f64; 2],
) -> crate::transient::InitialState {
    let n = dofs.free.len();
    let mut start = crate::transient::InitialState {
        displacement: vec![0.0; n],
        velocity: vec![0.0; n],
    };
    for &node in nodes {
        for c in 0..2 {
            if let Some(i) = dofs.free_index(2 * node + c) {
                start.displacement[i] = displacement[c];
                start.velocity[i] = velocity[c];
            }
        }
    }
    start
}

/// The directory time-marching results go to: `--out`, else `output.directory` with
/// `-transient` appended (`output/<name>-transient`), never over the harmonic-balance result.
pub fn transient_output_dir(p: &Pipeline, options: &RunOptions) -> PathBuf {
    options.out.clone().unwrap_or_else(|| {
        let mut d = p.output.directory.clone().into_os_string();
        d.push("-transient");
        PathBuf::from(d)
    })
}

/// `hbcontact transient`: explicit time marching from rest (or from the harmonic-balance
/// state, `transient.start`) to the periodic state. With `keep_interrupted_march`, a march an
/// interruption stops is written like a finished one, marked partial in the summary
/// (`transient.stopped`), which the caller turns into exit code 130.
pub fn run_transient(
    p: &Pipeline,
    options: &RunOptions,
    reporter: &dyn Reporter,
) -> Result<RunResult> {
    let out = transient_output_dir(p, options);
    let (scene, mut stages) = scene::open(p, &out, options, Purpose::Transient, reporter)?;
    let Scene {
        model,
        mesh_info,
        mut warnings,
    } = scene;
    let (initial, floquet) =
        transient_start(p, &model, &mesh_info, &out, &mut stages, &mut warnings)?;
    let (marching, result) = {
        let _armed = options
            .keep_interrupted_march
            .then(crate::transient::StopOnInterrupt::arm);
        stages::march(p, &model, initial, &mut stages)?
    };
    let staged = StagedDir::create(&out, "transient", options.replace)?;
    let full = options.write == WriteLevel::Full;
    let (mut summary, sampled, signals) = stages.run(Stage::Write, || {
        let sampled = Sampled::transient(&model, &marching, &result);
        if full {
            let (contact, fields) = (p.contact.as_ref(), &p.output.fields);
            sampled.write(staged.path(), &model, contact, fields, reporter)?;
            stages::copy_mesh(&mesh_info, staged.path())?;
        }
        end_state::write(staged.path(), p, &mesh_info, &result)?;
        let signals = late::LateSignals::of(&model, &marching, &result.late);
        let f = p.harmonic_balance.frequency;
        let converged = result.converged;
        let late_response = late::characterize(
            &signals,
            &result.late,
            converged,
            (floquet.as_ref(), f),
            PERIODS,
        );
        let summary = summary::transient(p, mesh_info, &model, &result, &sampled, late_response);
        Ok((summary, sampled, signals))
    })?;
    summary.warnings.extend(warnings);
    summary
        .warnings
        .extend(runaway_warning(&result.late, p.transient.courant));
    if let Some(verdict) = floquet {
        summary.stability = Some(verdict);
    }
    if publish::plotting(p, options.write) {
        let dir = staged.path().join("plots");
        let f = p.harmonic_balance.frequency;
        stages.run(Stage::Plots, || {
            publish::plots(p, (&model, &sampled), &dir, 1.0 / f)?;
            let unit = model.material.force_unit();
            plots::write_late_plots(&dir, &signals, (f, unit)).map(|_| ())
        })?;
    }
    summary.stage_seconds = stages.times;
    let dir = stages::commit(staged, &summary)?;
    Ok(RunResult { dir, summary })
}

/// The marches the scene's commands would make, estimated (`transient::budget`): the
/// stability check of `run` refused as it would be (exit 2), `hbcontact transient` beyond
/// the machine a warning. A model that does not build is left to `run` to report.
fn check_marches(p: &Pipeline, mesh: &crate::mesh::Mesh2d, reporter: &dyn Reporter) -> Result<()> {
    let Ok(model) = build(p, mesh.clone(), Purpose::Transient) else {
        return Ok(());
    };
    stages::check_stability_march(p, &model)?;
    if let Err(e) = stages::check_transient_march(p, &model) {
        reporter.warning(&format!("`hbcontact transient` would stop: {e}"));
    }
    Ok(())
}

/// What `check` found on one contact pair.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct PairCheck {
    /// The pair's pipeline key: `contact` or `contact.pairs[i]`.
    pub key: String,
    pub boundary: String,
    /// Contact nodes kept, of the boundary's candidates.
    pub nodes: usize,
    pub candidates: usize,
    /// Candidates dropped: off the obstacle, and farther than the search distance.
    pub dropped: [usize; 2],
    /// The smallest initial gap of the kept nodes (negative: penetration).
    pub smallest_gap: f64,
    /// Kept nodes that start inside the obstacle, and the deepest penetration (≥ 0).
    pub penetrated_nodes: usize,
    pub deepest_penetration: f64,
    /// Against another body: its boundary group and how many of its nodes the rows touch.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<(String, usize)>,
}

/// What `check` found.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct CheckReport {
    pub mesh: MeshInfo,
    /// The gmsh command a `.geo` is meshed with (the pipeline's `geometry.gmsh`, else
    /// `.venv/bin/gmsh`, else gmsh on PATH): what a pipeline from elsewhere would run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gmsh: Option<String>,
    /// Contact nodes kept (contact scenes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_nodes: Option<usize>,
    /// Nodes of the contact boundary group (contact scenes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_candidates: Option<usize>,
    /// Kept contact nodes that start inside the obstacle (a negative initial gap).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub penetrated_nodes: Option<usize>,
    /// The deepest initial penetration, a length ≥ 0 (0: none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deepest_penetration: Option<f64>,
    /// Candidates dropped: off the obstacle, and farther than `contact.search_distance`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_dropped: Option<[usize; 2]>,
    /// The smallest initial gap of the kept nodes (negative: penetration).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smallest_gap: Option<f64>,
    /// Against another body: its boundary group and how many of its nodes the pairs touch
    /// (the first pair against a body).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<(String, usize)>,
    /// Each contact pair's own counts (the fields above add them up over the pairs).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub contact_pairs: Vec<PairCheck>,
    /// The mesh's physical groups: name → what they hold.
    pub groups: std::collections::BTreeMap<String, GroupInfo>,
}

/// What one physical group holds.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct GroupInfo {
    pub nodes: usize,
    /// 1-D elements (a curve group).
    pub edges: usize,
    /// 2-D cells (a surface group).
    pub cells: usize,
}

/// `hbcontact check`: the config, the geometry's groups and the scene's checks, without
/// solving; it writes nothing.
pub fn check(p: &Pipeline, options: &RunOptions, reporter: &dyn Reporter) -> Result<CheckReport> {
    let out = output_dir(p, options);
    let mut stages = Stages::new(p, reporter);
    let scene = scene::prepare(p, &out, Purpose::HarmonicBalance, &mut stages)?;
    for w in &scene.warnings {
        reporter.warning(w);
    }
    let (mesh, info) = (&scene.model.mesh, scene.mesh_info);
    // Every node of the contact group, held ones too (the model keeps the free ones).
    let pairs = p
        .contact
        .iter()
        .flat_map(|spec| &spec.pairs)
        .map(|pair| {
            let set = build_contact_set(mesh, &model::contact_scene(pair))?;
            Ok(pair_check(pair, &set))
        })
        .collect::<Result<Vec<_>>>()?;
    // The totals over the pairs (`None` without contact).
    let total = |f: &dyn Fn(&PairCheck) -> usize| {
        (!pairs.is_empty()).then(|| pairs.iter().map(f).sum::<usize>())
    };
    let extreme = |f: &dyn Fn(&PairCheck) -> f64, pick: fn(f64, f64) -> f64, from: f64| {
        (!pairs.is_empty()).then(|| pairs.iter().map(f).fold(from, pick))
    };
    stages.run(Stage::Check, || check_marches(p, mesh, reporter))?;
    let groups = mesh
        .node_groups
        .iter()
        .map(|(name, nodes)| {
            let info = GroupInfo {
                nodes: nodes.len(),
                edges: mesh.edge_groups.get(name).map_or(0, Vec::len),
                cells: mesh.cell_groups.get(name).map_or(0, Vec::len),
            };
            (name.clone(), info)
        })
        .collect();
    let geo = &p.geometry.file;
    let gmsh = geo.extension().is_some_and(|e| e == "geo").then(|| {
        crate::mesh::gmsh::find_gmsh(p.geometry.gmsh.as_deref(), geo.parent())
            .map_or_else(|e| e.to_string(), |c| c.describe())
    });
    Ok(CheckReport {
        gmsh,
        groups,
        mesh: info,
        contact_nodes: total(&|c| c.nodes),
        contact_candidates: total(&|c| c.candidates),
        penetrated_nodes: total(&|c| c.penetrated_nodes),
        deepest_penetration: extreme(&|c| c.deepest_penetration, f64::max, 0.0),
        contact_dropped: total(&|c| c.dropped[0])
            .zip(total(&|c| c.dropped[1]))
            .map(|(a, b)| [a, b]),
        smallest_gap: extreme(&|c| c.smallest_gap, f64::min, f64::INFINITY),
        target: pairs.iter().find_map(|c| c.target.clone()),
        contact_pairs: pairs,
    })
}

/// A body obstacle's boundary and how many of its nodes the pair's rows touch.
fn target(pair: &crate::config::ContactPair, set: &ContactSet) -> Option<(String, usize)> {
    match &pair.obstacle {
        crate::config::ObstacleSpec::Body { group } => {
            Some((group.clone(), set.target_nodes.len()))
        }
        _ => None,
    }
}

fn pair_check(pair: &crate::config::ContactPair, set: &ContactSet) -> PairCheck {
    let (penetrated, deepest) = sanity::initial_penetration(set);
    PairCheck {
        key: pair.key.clone(),
        boundary: pair.boundary.clone(),
        nodes: set.nodes.len(),
        candidates: set.candidates,
        dropped: [set.dropped_off_obstacle, set.dropped_beyond_search],
        smallest_gap: set.gaps.iter().copied().fold(f64::INFINITY, f64::min),
        penetrated_nodes: penetrated,
        deepest_penetration: deepest,
        target: target(pair, set),
    }
}
