//! `hbcontact modes`: the scene's natural frequencies with its supports and the contact open,
//! the mode shapes as a VTU series, and the effective modal masses, from the same discrete
//! model `run` solves (same mesh, supports and mass matrix: consistent without contact,
//! lumped and redistributed with it).
//!
//! Glossary (formulas in `fem::modes`): f_n = ω_n/2π the natural frequency of mode n; ζ_n the
//! modal damping ratio Rayleigh damping gives there; m_eff,x and m_eff,y the effective modal
//! masses, reported with their fraction of the mass the supports let move (r_dᵀ M r_d) and the
//! cumulative fraction over modes 1..n, which tends to 1 as modes are added.
//!
//! Pictures (`mode_NNNN.svg`/`.png`, the first `MAX_PICTURES` modes): the body's outline
//! (`output::outline`) undeformed in grey and displaced by the mode shape φ (largest |φ| = 1)
//! times S = 0.1 · the outline's largest bounding-box side, so the largest drawn
//! displacement is 10% of the body's size, on axes of equal scale.

use std::path::{Path, PathBuf};

use schemars::JsonSchema;
use serde::Serialize;

use super::model::{MassModel, Model, Purpose};
use super::stages;
use super::summary::{sizes, MeshInfo, Sizes};
use super::times::{Stage, StageTimes};
use super::RunOptions;
use crate::config::Pipeline;
use crate::fem::modes::{effective_mass, free_mass, lowest_modes, rayleigh_damping_ratio};
use crate::mesh::Mesh2d;
use crate::output::outline::outline_polylines;
use crate::output::plot::{tick, Axis, Figure};
use crate::output::tables::write_json;
use crate::output::{write_pvd, write_vtu, Field, StagedDir};
use crate::progress::Reporter;
use crate::{Error, Result};

/// The most modes one call computes (the Rayleigh–Ritz step is dense in the subspace size).
pub const MAX_MODES: usize = 500;

/// The most modes drawn as pictures (`mode_NNNN.svg` and `.png`): the first 12; the VTU
/// series and modes.json hold every mode.
pub const MAX_PICTURES: usize = 12;

/// What `modes` computed (`modes.json`; its JSON Schema is `docs/modes.schema.json`).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ModesSummary {
    /// The pipeline's `name`.
    pub name: String,
    /// The pipeline file.
    pub pipeline: PathBuf,
    pub mesh: MeshInfo,
    pub sizes: Sizes,
    /// The mass matrix used, the one `run` uses.
    pub mass: MassModel,
    /// The scene's Rayleigh damping (gives each mode's damping ratio), if any.
    pub damping: Option<String>,
    /// The mass the supports let move in x, r_xᵀ M r_x [kg] (plane strain: per metre of
    /// thickness): what the effective masses in x of all modes sum to.
    pub free_mass_x: f64,
    /// The same in y [kg].
    pub free_mass_y: f64,
    /// The modes, lowest first.
    pub modes: Vec<ModeInfo>,
    /// Wall time per stage [s], in run order, with their `total`.
    pub stage_seconds: StageTimes,
}

/// One natural mode.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct ModeInfo {
    /// Mode number, 1 for the lowest.
    pub mode: usize,
    /// Natural frequency f_n [Hz].
    pub frequency_hz: f64,
    /// Modal damping ratio ζ = α/(2ω_n) + βω_n/2 of the scene's Rayleigh damping (0 without).
    pub damping_ratio: f64,
    /// Effective modal mass in x [kg].
    pub effective_mass_x: f64,
    /// Effective modal mass in y [kg].
    pub effective_mass_y: f64,
    /// effective_mass_x / free_mass_x.
    pub mass_fraction_x: f64,
    /// effective_mass_y / free_mass_y.
    pub mass_fraction_y: f64,
    /// Sum of mass_fraction_x over modes 1..this one.
    pub cumulative_fraction_x: f64,
    /// Sum of mass_fraction_y over modes 1..this one.
    pub cumulative_fraction_y: f64,
    /// The mode shape's file in the output directory (`mode_shape`, largest |u| = 1).
    pub file: String,
    /// The mode's picture, `<picture>.svg` and `<picture>.png` in the output directory (the
    /// outline undeformed and deformed by the shape): the first 12 modes have one, null after.
    pub picture: Option<String>,
}

/// A finished `modes`: where its files are and what it found.
#[derive(Clone, Debug)]
pub struct ModesResult {
    pub dir: PathBuf,
    pub summary: ModesSummary,
}

/// The directory `modes` writes to: `--out`, else `output.directory` with `-modes` appended.
pub fn modes_output_dir(p: &Pipeline, options: &RunOptions) -> PathBuf {
    options.out.clone().unwrap_or_else(|| {
        let mut d = p.output.directory.clone().into_os_string();
        d.push("-modes");
        PathBuf::from(d)
    })
}

/// `hbcontact modes`: the scene (`open`: mesh, checks, assembly) → modes → write, committed
/// atomically like `run`.
pub fn modes(
    p: &Pipeline,
    options: &RunOptions,
    count: usize,
    reporter: &dyn Reporter,
) -> Result<ModesResult> {
    if count == 0 || count > MAX_MODES {
        return Err(Error::Input(format!(
            "--count {count}: ask for between 1 and {MAX_MODES} modes (e.g. --count 10)"
        )));
    }
    let out = modes_output_dir(p, options);
    let (scene, mut stages) = super::open(p, &out, options, Purpose::HarmonicBalance, reporter)?;
    for w in &scene.warnings {
        reporter.warning(w);
    }
    if p.boundaries.rotation.is_some_and(|r| r.coriolis) {
        reporter.warning(
            "the modes are those of K − Ω²M and M: the Coriolis force, which splits pairs of \
             modes of a turning body, is not in them",
        );
    }
    let (model, mesh_info) = (scene.model, scene.mesh_info);
    let modes = stages.run(Stage::Modes, || natural_modes(&model, count))?;
    let staged = StagedDir::create(&out, "modes", options.replace)?;
    let mut summary = stages.run(Stage::Write, || {
        let infos = write_mode_shapes(staged.path(), &p.name, &model, &modes)?;
        stages::copy_mesh(&mesh_info, staged.path())?;
        Ok(modes_summary(p, mesh_info, &model, infos))
    })?;
    summary.stage_seconds = stages.times;
    write_json(&staged.path().join("modes.json"), &summary)?;
    let dir = staged.commit()?;
    Ok(ModesResult { dir, summary })
}

/// The `count` lowest modes of the model's free-dof K and M (fewer when it has fewer dofs).
pub fn natural_modes(model: &Model, count: usize) -> Result<Vec<(f64, Vec<f64>)>> {
    let system = &model.system;
    let count = count.min(system.free_count());
    lowest_modes(&system.k_ff, &system.m_ff, count, 0.0)
}

/// One VTU per mode (`mode_shape`, scaled to a largest |u| of 1) and `modes.pvd`, whose
/// "time" is the mode number, and the pictures of the first `MAX_PICTURES` modes; returns
/// each mode's frequency, damping and effective masses.
fn write_mode_shapes(
    dir: &Path,
    name: &str,
    model: &Model,
    modes: &[(f64, Vec<f64>)],
) -> Result<Vec<ModeInfo>> {
    let system = &model.system;
    let component_of: Vec<usize> = system.dofs.free.iter().map(|d| d % 2).collect();
    let totals = [0, 1].map(|c| free_mass(&system.m_ff, &component_of, c));
    let fraction = |m: f64, c: usize| if totals[c] > 0.0 { m / totals[c] } else { 0.0 };
    let (mut cumulative, mut infos, mut entries) = ([0.0; 2], Vec::new(), Vec::new());
    let outline = outline_polylines(&model.mesh);
    for (i, (w2, phi)) in modes.iter().enumerate() {
        let omega = w2.max(0.0).sqrt();
        let file = format!("mode_{:04}.vtu", i + 1);
        let shape = shape_field(model, phi);
        write_vtu(
            &dir.join(&file),
            &model.mesh,
            std::slice::from_ref(&shape),
            &[],
        )?;
        entries.push(((i + 1) as f64, file.clone()));
        let m_eff = [0, 1].map(|c| effective_mass(&system.m_ff, phi, &component_of, c));
        let f = [fraction(m_eff[0], 0), fraction(m_eff[1], 1)];
        cumulative = [cumulative[0] + f[0], cumulative[1] + f[1]];
        infos.push(ModeInfo {
            mode: i + 1,
            frequency_hz: omega / (2.0 * std::f64::consts::PI),
            damping_ratio: rayleigh_damping_ratio(system.rayleigh, omega),
            effective_mass_x: m_eff[0],
            effective_mass_y: m_eff[1],
            mass_fraction_x: f[0],
            mass_fraction_y: f[1],
            cumulative_fraction_x: cumulative[0],
            cumulative_fraction_y: cumulative[1],
            file,
            picture: None,
        });
        if let Some(info) = infos.last_mut().filter(|_| i < MAX_PICTURES) {
            let stem = format!("mode_{:04}", info.mode);
            let figure = mode_figure(name, info, &model.mesh, &outline, &shape.values);
            figure.save(&dir.join(&stem))?;
            info.picture = Some(stem);
        }
    }
    write_pvd(&dir.join("modes.pvd"), &entries)?;
    Ok(infos)
}

/// The picture of one mode: the outline's polylines undeformed (grey, dashed) and displaced
/// by `shape` (3 components per mesh node, largest |u| = 1) times S = 10% of the outline's
/// largest bounding-box side, titled with the frequency to 4 significant digits, on axes
/// of equal scale.
fn mode_figure(
    name: &str,
    info: &ModeInfo,
    mesh: &Mesh2d,
    outline: &[Vec<usize>],
    shape: &[f64],
) -> Figure {
    let scale = 0.1 * largest_side(mesh, outline);
    let f = four_significant(info.frequency_hz);
    let title = format!("{name}: mode {}, f = {f} Hz", info.mode);
    let mut fig = Figure::new(title, Axis::linear("x [m]"), Axis::linear("y [m]")).equal_aspect();
    let at = |n: usize, s: f64| {
        let p = mesh.nodes[n];
        (p[0] + s * shape[3 * n], p[1] + s * shape[3 * n + 1])
    };
    for (k, line) in outline.iter().enumerate() {
        let label = if k == 0 { "undeformed" } else { "" };
        fig = fig
            .dashed(label, line.iter().map(|&n| at(n, 0.0)).collect())
            .grey();
    }
    let deformed = format!("mode shape (scaled ×{})", tick(scale));
    for (k, line) in outline.iter().enumerate() {
        let label = if k == 0 { deformed.as_str() } else { "" };
        fig = fig
            .curve(label, line.iter().map(|&n| at(n, scale)).collect())
            .colour(0);
    }
    fig
}

/// The largest side of the bounding box of the outline's nodes [m] (0 without any).
fn largest_side(mesh: &Mesh2d, outline: &[Vec<usize>]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &n in outline.iter().flatten() {
        for c in 0..2 {
            lo[c] = lo[c].min(mesh.nodes[n][c]);
            hi[c] = hi[c].max(mesh.nodes[n][c]);
        }
    }
    let side = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    if side.is_finite() {
        side
    } else {
        0.0
    }
}

/// `x` to 4 significant digits: plain from 1e-3 to below 1e4 (`17.63`, `222.5`, `2596`),
/// otherwise in exponent form (`1.235e4`).
pub fn four_significant(x: f64) -> String {
    let sci = format!("{x:.3e}");
    let exponent = sci.split_once('e').and_then(|(_, e)| e.parse::<i32>().ok());
    match (exponent, sci.parse::<f64>()) {
        (Some(e @ -3..=3), Ok(rounded)) => format!("{rounded:.*}", (3 - e) as usize),
        _ => sci,
    }
}

/// The mode shape on all mesh nodes as a 3-vector field, scaled to a largest |u| of 1.
fn shape_field(model: &Model, phi: &[f64]) -> Field {
    let mut u = vec![0.0; 2 * model.mesh.nodes.len()];
    for (i, &d) in model.system.dofs.free.iter().enumerate() {
        u[d] = phi[i];
    }
    let largest = u.chunks(2).map(|c| c[0].hypot(c[1])).fold(0.0f64, f64::max);
    let scale = if largest > 0.0 { 1.0 / largest } else { 1.0 };
    Field {
        name: "mode_shape".into(),
        components: 3,
        values: u
            .chunks(2)
            .flat_map(|c| [scale * c[0], scale * c[1], 0.0])
            .collect(),
    }
}

fn modes_summary(
    p: &Pipeline,
    mesh: MeshInfo,
    model: &Model,
    modes: Vec<ModeInfo>,
) -> ModesSummary {
    let component_of: Vec<usize> = model.system.dofs.free.iter().map(|d| d % 2).collect();
    ModesSummary {
        name: p.name.clone(),
        pipeline: p.source.clone(),
        mesh,
        sizes: sizes(model),
        mass: model.effects.mass,
        damping: model.effects.damping.clone(),
        free_mass_x: free_mass(&model.system.m_ff, &component_of, 0),
        free_mass_y: free_mass(&model.system.m_ff, &component_of, 1),
        modes,
        stage_seconds: StageTimes::default(),
    }
}

/// The JSON Schema (draft 07) of `modes.json` (`docs/modes.schema.json`).
pub fn modes_schema() -> serde_json::Value {
    let schema = schemars::generate::SchemaSettings::draft07()
        .into_generator()
        .into_root_schema_for::<ModesSummary>();
    serde_json::Value::from(schema)
}
