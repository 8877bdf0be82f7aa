//! The YAML schema as written by users, and its validation into `Pipeline`.
//!
//! serde_yaml (deprecated upstream, still working) stays behind this file so that a move to a
//! maintained fork is a one-line change.
//!
//! The `///` comments on the raw types are the descriptions of the pipeline's JSON Schema
//! (`docs/pipeline.schema.json`, see `super::schema`): keep them to meaning, unit and default.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use schemars::JsonSchema;
use serde::Deserialize;
use serde_yaml::Value;

use super::*;
use crate::{Error, Result};

/// An hbcontact pipeline: one scene (geometry, material, supports, loads, contact) and how to
/// solve and write it. Lengths, forces and times are in one consistent unit system of your
/// choice (SI: m, N, s, Pa, kg/m³; or mm, N, s, MPa, t/mm³); frequencies are in Hz.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Pipeline", title = "hbcontact pipeline")]
struct RawPipeline {
    /// The scene's name: letters, digits, `_` and `-` only. It names the default output
    /// directory `output/<name>`. Required.
    name: String,
    /// The gmsh geometry and how to mesh it. Required.
    geometry: RawGeometry,
    /// The linear-elastic, isotropic material. Required.
    material: RawMaterial,
    /// Supports, prescribed motion and loads, on gmsh physical groups. Default: none.
    #[serde(default)]
    boundaries: RawBoundaries,
    /// Rayleigh damping D = alpha·M + beta·K. Default: none (undamped, real arithmetic).
    #[serde(default)]
    damping: Option<RawDamping>,
    /// The periodic steady state sought: fundamental frequency, harmonics, samples, contact
    /// solver. Required.
    harmonic_balance: RawHarmonicBalance,
    /// Frictionless unilateral contact of a body boundary with a rigid obstacle. Default: none
    /// (a linear scene).
    #[serde(default)]
    contact: Option<RawContact>,
    /// Settings of `hbcontact transient` (explicit time marching to the periodic state).
    /// Default: each key's default.
    #[serde(default)]
    transient: Option<RawTransient>,
    /// Settings of `hbcontact sweep` (a frequency-response curve by continuation).
    #[serde(default)]
    sweep: Option<RawSweep>,
    /// The stability verdict of `run` and of each sweep point (time marching from the
    /// perturbed harmonic-balance state). Default: each key's default.
    #[serde(default)]
    stability: Option<RawStability>,
    /// What is written and where. Default: each key's default.
    #[serde(default)]
    output: Option<RawOutput>,
}

/// The gmsh geometry and how to mesh it.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Geometry")]
struct RawGeometry {
    /// The gmsh `.geo` file, or a ready `.msh` (then `parameters`, `mesh_size`, `order` and
    /// `quads` are not used). A relative path is looked up next to the pipeline file, then in
    /// its parent directory (so `geometries/x.geo` works from `pipelines/`), then in the
    /// working directory; the first that exists is used. Required.
    file: PathBuf,
    /// Numbers passed to gmsh as `-setnumber NAME VALUE` (the `.geo`'s `DefineConstant`s), in
    /// the geometry's units. Default: none.
    #[serde(default)]
    parameters: BTreeMap<String, f64>,
    /// Largest element size (gmsh `-clmax`), a length, > 0. Default: the sizes set in the
    /// `.geo`.
    #[serde(default)]
    mesh_size: Option<f64>,
    /// Element order: 1 (linear) or 2 (quadratic). Default: 1.
    #[serde(default)]
    #[schemars(range(min = 1, max = 2))]
    order: Option<u8>,
    /// Ask for quadrilaterals: passes `-setnumber quads 1` to gmsh (the `.geo` decides what
    /// to recombine). Default: false.
    #[serde(default)]
    quads: bool,
    /// The gmsh executable (path as for `file`). Default: `.venv/bin/gmsh` (made by
    /// `make venv`), then `gmsh` on PATH.
    #[serde(default)]
    gmsh: Option<PathBuf>,
    /// Refuse to mesh when the estimated number of elements exceeds this (the estimate comes
    /// from gmsh on a coarsened mesh, before the real one), ≥ 1. Default: 2000000.
    #[serde(default)]
    #[schemars(range(min = 1))]
    max_elements: Option<u64>,
    /// Time limit of one gmsh run, in seconds, > 0 and at most 1e7: gmsh (with its process
    /// group) is killed beyond it. Default: 600.
    #[serde(default)]
    gmsh_timeout: Option<f64>,
    /// Refuse a mesh with a cell whose aspect ratio (longest edge² over the area, halved for
    /// triangles: a/b for an a × b rectangle or its halves) exceeds this, ≥ 1 and finite;
    /// above 20 a run warns. Default: 1000.
    #[serde(default)]
    max_aspect_ratio: Option<f64>,
    /// Accept a mesh whose cells form several disconnected parts (each then needs its own
    /// support or contact). Default: false (refused, exit code 2).
    #[serde(default)]
    allow_disconnected: bool,
}

/// The 2-D model of the out-of-plane direction.
#[derive(Deserialize, JsonSchema, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "PlaneModel")]
enum RawPlaneModel {
    /// Plane strain (ε_zz = 0): a long body.
    PlaneStrain,
    /// Plane stress (σ_zz = 0): a thin plate.
    PlaneStress,
}

/// The linear-elastic, isotropic material.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Material")]
struct RawMaterial {
    /// Young's modulus E, a stress (Pa in SI, MPa in mm–N–s), > 0. Required.
    youngs_modulus: f64,
    /// Poisson's ratio ν (dimensionless), in (−1, 0.5), and in plane strain also
    /// < 0.4999995 (λ/μ = 2ν/(1 − 2ν) under 1e6; beyond, the stiffness is singular to working
    /// precision). From 0.49 on, plane strain warns: displacement elements lock. Required.
    poisson_ratio: f64,
    /// Mass density ρ (kg/m³ in SI, t/mm³ in mm–N–s), > 0. Required.
    density: f64,
    /// `plane_strain` or `plane_stress`. Required.
    model: RawPlaneModel,
    /// Out-of-plane thickness, a length, > 0: multiplies stiffness, mass and tractions.
    /// Default: 1.
    #[serde(default)]
    thickness: Option<f64>,
}

/// Supports, prescribed motion and loads, on gmsh physical groups.
#[derive(Deserialize, JsonSchema, Default)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Boundaries")]
struct RawBoundaries {
    /// Groups whose nodes have both displacement components held at zero. Default: none.
    #[serde(default)]
    fixed: Vec<String>,
    /// Groups whose nodes have one displacement component moved by a given periodic signal.
    /// Default: none.
    #[serde(default)]
    prescribed: Vec<RawPrescribed>,
    /// External loads on groups: static part plus harmonics. Default: none.
    #[serde(default)]
    loads: Vec<RawLoad>,
}

/// A displacement component.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "Component")]
enum RawComponent {
    /// The x component.
    X,
    /// The y component.
    Y,
}

/// One harmonic of a scalar signal: cos·cos(kωt) + sin·sin(kωt).
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "ScalarHarmonic")]
struct RawHarmonic1 {
    /// The harmonic index k ≥ 1 (frequency k·f); each k at most once. Required.
    #[schemars(range(min = 1))]
    k: usize,
    /// Amplitude of cos(kωt), a length. Default: 0.
    #[serde(default)]
    cos: f64,
    /// Amplitude of sin(kωt), a length. Default: 0.
    #[serde(default)]
    sin: f64,
}

/// A prescribed periodic motion of one displacement component of a group's nodes.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Prescribed")]
struct RawPrescribed {
    /// The gmsh physical group (curve or point) whose nodes move. Required.
    group: String,
    /// The component held: `x` or `y`. Required.
    component: RawComponent,
    /// The constant part of the motion, a length. Default: 0.
    #[serde(default, rename = "static")]
    static_part: f64,
    /// The harmonic part of the motion. Default: none.
    #[serde(default)]
    harmonics: Vec<RawHarmonic1>,
}

/// How a load's value is applied to its group.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "LoadType")]
enum RawLoadKind {
    /// A force per unit area on the edges of a curve group (times the thickness).
    Traction,
    /// A total force shared equally by the nodes of the group.
    Force,
}

/// One harmonic of a vector signal: cos·cos(kωt) + sin·sin(kωt), as [x, y].
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "VectorHarmonic")]
struct RawHarmonic2 {
    /// The harmonic index k ≥ 1 (frequency k·f); each k at most once. Required.
    #[schemars(range(min = 1))]
    k: usize,
    /// Amplitude [x, y] of cos(kωt), a traction or a force. Default: [0, 0].
    #[serde(default)]
    cos: [f64; 2],
    /// Amplitude [x, y] of sin(kωt), a traction or a force. Default: [0, 0].
    #[serde(default)]
    sin: [f64; 2],
}

/// An external periodic load on a group: static part plus harmonics.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Load")]
struct RawLoad {
    /// The gmsh physical group loaded (a curve for `traction`). Required.
    group: String,
    /// `traction` (force per area on edges) or `force` (total force over the nodes). Required.
    #[serde(rename = "type")]
    kind: RawLoadKind,
    /// The constant part [x, y], a traction or a force. Default: none; give `static`,
    /// `harmonics` or both.
    #[serde(default, rename = "static")]
    static_part: Option<[f64; 2]>,
    /// The harmonic part. Default: none; give `static`, `harmonics` or both.
    #[serde(default)]
    harmonics: Vec<RawHarmonic2>,
}

/// Rayleigh damping D = alpha·M + beta·K.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Damping")]
struct RawDamping {
    /// Mass-proportional coefficient α, in 1/s, ≥ 0. Default: 0.
    #[serde(default)]
    alpha: f64,
    /// Stiffness-proportional coefficient β, in s, ≥ 0. Default: 0.
    #[serde(default)]
    beta: f64,
}

/// The contact solver (semi-smooth Newton on the sampled complementarity residual).
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Solver")]
struct RawSolver {
    /// Relative tolerance on the complementarity residual (‖R‖∞ over the force scale), in
    /// (0, 1e-2]: a looser one stops Newton before the contact forces mean anything (at 1e29
    /// after one iteration, 2% off). Default: 1e-8.
    #[serde(default)]
    tolerance: Option<f64>,
    /// Iteration limit of each Newton run (direct, each ladder rung, each c; a smoothing level
    /// and a step of the damping continuation stop at 30). Default: 200.
    #[serde(default)]
    max_iterations: Option<usize>,
    /// The complementarity parameter c as a multiple of 1/mean|G_0,ii| (the inverse of the
    /// contact nodes' mean static compliance), in [1e-3, 1e3] (the six orders over which the
    /// answer is the same; beyond, the residual's scale hides an unconverged state). Default: 1.
    #[serde(default)]
    c_scale: Option<f64>,
    /// Wall-time budget of the whole contact solve (every attempt), in seconds, > 0: beyond it
    /// the solve stops (exit code 4) saying so. Default: 3600.
    #[serde(default)]
    max_seconds: Option<f64>,
}

/// The periodic steady state sought.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "HarmonicBalance")]
struct RawHarmonicBalance {
    /// The fundamental frequency f, in Hz (ω = 2πf, period 1/f), > 0 and at most 1e9.
    /// Required.
    frequency: f64,
    /// The highest harmonic H of the contact solve (≥ every harmonic the loads excite), at
    /// most 1000. Linear scenes solve the harmonics their loads excite. Required.
    harmonics: usize,
    /// Time samples N per period for the contact terms, > 2·harmonics, at most 1000000.
    /// Default: 16·H, at least 64 (1 for H = 0). With a spline basis: a multiple of its
    /// segments S with at least degree + 1 per segment (Gauss points in each segment); default
    /// 8·S.
    #[serde(default)]
    samples: Option<usize>,
    /// The contact solver's settings. Default: each key's default.
    #[serde(default)]
    solver: Option<RawSolver>,
    /// The time basis of one period: `fourier` (harmonics 0..H) or
    /// `{spline: {degree, segments}}` (uniform periodic B-splines; no sweeps yet).
    /// Default: fourier.
    #[serde(
        default,
        deserialize_with = "serde_yaml::with::singleton_map::deserialize"
    )]
    #[schemars(with = "Option<RawBasis>")]
    basis: Option<RawBasis>,
}

/// The time basis, written `fourier` or `{spline: {degree: 3, segments: 32}}`.
#[derive(Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schemars(rename = "TimeBasis")]
enum RawBasis {
    /// The Fourier series of harmonics 0..H.
    Fourier,
    /// Uniform periodic B-splines over the period.
    Spline {
        /// The polynomial degree p, 2 … 7 (C^{p−1} in time). Default: 3.
        #[serde(default)]
        degree: Option<usize>,
        /// The number S of uniform segments per period (S unknowns per scalar), ≥ degree + 1
        /// and > 2 × the highest harmonic a load or motion excites, at most 100000. Required.
        segments: usize,
    },
}

/// A rigid obstacle, written as a one-key mapping: `{curve: NAME}`,
/// `{line: {point, normal}}` or `{circle: {center, radius, body_inside}}`.
#[derive(Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schemars(rename = "Obstacle")]
enum RawObstacle {
    /// A curve of the geometry: a gmsh physical group meshed as line elements only, sharing
    /// no node with the body.
    Curve(String),
    /// The half-plane behind a straight line.
    Line {
        /// A point [x, y] of the line (lengths). Required.
        point: [f64; 2],
        /// The line's normal [x, y], pointing out of the obstacle toward the body; non-zero,
        /// normalized by the code. Required.
        normal: [f64; 2],
    },
    /// A circle.
    Circle {
        /// The centre [x, y] (lengths). Required.
        center: [f64; 2],
        /// The radius, a length, > 0. Required.
        radius: f64,
        /// true: the body lies inside the circle (a casing); false: outside (a cylinder).
        /// Default: false.
        #[serde(default)]
        body_inside: bool,
    },
}

/// The mass model of a contact scene.
#[derive(Deserialize, JsonSchema, Default, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "ContactMass")]
enum RawMass {
    /// Lumped mass with the contact nodes' mass moved to their neighbours (total mass and
    /// centre of mass kept): the default.
    #[default]
    Redistributed,
    /// Plain lumped mass: contact nodes keep their inertia (impacts; shows why redistribution
    /// is needed).
    Lumped,
}

/// Frictionless unilateral contact of a body boundary with a rigid obstacle.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Contact")]
struct RawContact {
    /// The body's boundary curve group whose nodes may touch the obstacle. Required.
    boundary: String,
    /// The rigid obstacle: `{curve: NAME}`, `{line: {point: [x, y], normal: [x, y]}}` or
    /// `{circle: {center: [x, y], radius: R, body_inside: BOOL}}`. Required.
    #[serde(with = "serde_yaml::with::singleton_map")]
    #[schemars(with = "RawObstacle")]
    obstacle: RawObstacle,
    /// Drop candidate nodes whose initial gap exceeds this length, > 0. Default: keep all.
    #[serde(default)]
    search_distance: Option<f64>,
    /// `redistributed` (contact nodes carry no inertia) or `lumped`. Default: `redistributed`.
    #[serde(default)]
    mass: RawMass,
    /// Accept contact nodes that start inside the obstacle deeper than 0.1% of the body's size
    /// (a deliberate interference or preload). Default: false (refused, exit code 2: usually an
    /// obstacle on the wrong side of the body or a unit slip).
    #[serde(default)]
    allow_initial_penetration: bool,
}

/// Settings of `hbcontact transient`.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Transient")]
struct RawTransient {
    /// Stop when the state at the start of two successive periods differs by less than this
    /// (relative), in (0, 1e-2]: a state that changes by more than 1% per period is not
    /// periodic. Default: 1e-6.
    #[serde(default)]
    periodic_tolerance: Option<f64>,
    /// The most periods marched (0 counts as 1). Default: 2000.
    #[serde(default)]
    max_periods: Option<usize>,
    /// Fraction of the stable time step used, in (0, 1]. Default: 0.8.
    #[serde(default)]
    courant: Option<f64>,
    /// Where the marching starts: `rest`; `harmonic_balance` (the harmonic-balance
    /// solution of the same discrete model at t = 0); or `previous` (the end state the last
    /// `hbcontact transient` of this pipeline wrote to its output directory, `end_state.json`:
    /// a brute-force sweep changes the frequency and starts where the last run ended).
    /// Default: `rest`.
    #[serde(default)]
    start: Option<RawStart>,
    /// With `start: harmonic_balance` or `previous`, scale the starting state by 1 + this (a perturbation
    /// that shows whether the state is kept or left), |·| ≤ 1. Default: 0.
    #[serde(default)]
    perturbation: Option<f64>,
}

/// The stability check: is the harmonic-balance state one the structure settles into?
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Stability")]
struct RawStability {
    /// Judge contact scenes' states (a linear scene's verdict follows from its damping, a
    /// static one has none). Default: true.
    #[serde(default)]
    check: Option<bool>,
    /// `floquet` (the default): the Floquet multipliers of the harmonic-balance state on its
    /// own discrete model (Hill's method on the Fourier basis, docs/method.md §15), with the
    /// kind of loss of stability; `march`: time marching from the perturbed state (another
    /// discretization: diagonal mass, explicit steps); `both`: Floquet's verdict audited by
    /// marching, disagreements flagged.
    #[serde(default)]
    method: Option<super::StabilityMethod>,
    /// The most periods marched per check (it ends early once the verdict is clear), ≥ 1.
    /// Default: 200.
    #[serde(default)]
    max_periods: Option<usize>,
    /// The starting state is the harmonic-balance state scaled by 1 + this, in (0, 0.5].
    /// Default: 0.001.
    #[serde(default)]
    perturbation: Option<f64>,
    /// In a sweep, check every this many points (folds' neighbours are always checked), ≥ 1.
    /// Default: 1.
    #[serde(default)]
    every: Option<usize>,
    /// Wall-time budget of one check's marching [s], > 0; a check that reaches it gives the
    /// verdict the periods so far allow (often `undecided`). Default: 60.
    #[serde(default)]
    max_seconds: Option<f64>,
}

/// Where time marching starts.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum RawStart {
    Rest,
    HarmonicBalance,
    Previous,
}

/// Settings of `hbcontact sweep`: the fundamental frequency runs from `from` to `to` along the
/// response curve (through its folds), in arc-length steps measured with the frequency span
/// as 1.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Sweep")]
struct RawSweep {
    /// Start frequency [Hz], > 0 and at most 1e9 (the curve starts with a single-frequency
    /// solve there).
    from: f64,
    /// End frequency [Hz], > 0 and at most 1e9, ≠ from (below `from` sweeps down).
    to: f64,
    /// Initial arc-length step, a fraction of the span, in (0, 1]. Default: 0.01.
    #[serde(default)]
    step: Option<f64>,
    /// Smallest step before the sweep stops with a diagnosis, > 0. Default: 1e-5.
    #[serde(default)]
    min_step: Option<f64>,
    /// Largest step, ≥ step. Default: 0.05.
    #[serde(default)]
    max_step: Option<f64>,
    /// At most this many points, ≥ 2 and at most 100000. Default: 500.
    #[serde(default)]
    max_points: Option<usize>,
    /// Largest relative change of the contact gaps (without contact: of the response) from
    /// one point to the next, > 0. Default: 0.1.
    #[serde(default)]
    max_change: Option<f64>,
    /// Frequencies [Hz] (within the range) at which the full VTU series of a `run` is written,
    /// at the point of the curve nearest each, into `points/at_<f>Hz/`. Default: none (the
    /// folds and the peak are always written).
    #[serde(default)]
    write_at: Vec<f64>,
    /// Write every n-th point of the curve as a frame of `frames.pvd` (0: none). Default: 1.
    #[serde(default)]
    save_every: Option<usize>,
    /// Take the frames (ω-dependent factorizations) from a reduced model of the stiffness and
    /// mass pencil where the scene is small enough in contact nodes for it to pay; every point
    /// from it is checked against the harmonic-balance equations (backward error 1e-10) and
    /// re-solved on factorizations where it fails. false factors every frame (a curve exact to
    /// round-off; slower). Default: true.
    #[serde(default)]
    reduced_frames: Option<bool>,
}

/// A field written to the VTU snapshots.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "Field")]
enum RawField {
    /// Point data `displacement`.
    Displacement,
    /// Point data `velocity`.
    Velocity,
    /// Point data `acceleration`.
    Acceleration,
    /// Cell data `stress` (xx, yy, zz, xy, yz, xz).
    Stress,
    /// Cell data `von_mises`.
    VonMises,
    /// Point data `contact_opening`, `contact_force`, `contact_pressure`, `contact_status`,
    /// `contact_force_series` (contact scenes).
    Contact,
}

/// What is written and where.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Output")]
struct RawOutput {
    /// The results directory of `hbcontact run` (relative to the working directory);
    /// `transient`, `sweep`, `modes` and `accuracy` write beside it, appending `-transient`,
    /// `-sweep`, `-modes` and `-accuracy`; a command's `--out` names its folder instead.
    /// Default: `output/<name>`.
    #[serde(default)]
    directory: Option<PathBuf>,
    /// Snapshots written over one period (also the transient's samples per period), ≥ 1.
    /// Default: 24.
    #[serde(default)]
    #[schemars(range(min = 1))]
    frames: Option<usize>,
    /// The most frames `output.frames` may ask for (a guard against typos that would write
    /// millions of files), ≥ 1. Default: 10000.
    #[serde(default)]
    #[schemars(range(min = 1))]
    max_frames: Option<usize>,
    /// The fields written to the snapshots. Default: all six.
    #[serde(default)]
    fields: Option<Vec<RawField>>,
    /// Node groups whose displacement histories go to `probes.csv`. Default: none.
    #[serde(default)]
    probes: Vec<String>,
    /// Draw the run's plots (`plots/`: probe displacement, total contact force, contact
    /// pressure at the peak; SVG and PNG). Default: true.
    #[serde(default)]
    plots: Option<bool>,
}

/// The JSON Schema (draft 07) of the pipeline YAML, generated from the types above.
pub(super) fn raw_schema() -> schemars::Schema {
    schemars::generate::SchemaSettings::draft07()
        .into_generator()
        .into_root_schema_for::<RawPipeline>()
}

/// The highest fundamental frequency accepted, in Hz. Elastic waves at 1 GHz have wavelengths
/// of micrometres in metals, where a continuum model without dispersion stops describing the
/// body; a frequency like 1e300 only overflows ω² and is blamed on resonance later.
pub const MAX_FREQUENCY: f64 = 1e9;
/// The most harmonics (H, and any load's k): the dense contact solve grows as H² and N = 16H
/// samples per period; 1000 harmonics is far past where the accuracy table stops paying.
pub const MAX_HARMONICS: usize = 1000;
/// The most time samples per period (`harmonic_balance.samples`).
pub const MAX_SAMPLES: usize = 1_000_000;
/// The default of `output.max_frames`: 10 000 snapshot files are already more than a viewer
/// plays usefully, and each frame is a full VTU file.
pub const DEFAULT_MAX_FRAMES: usize = 10_000;
/// The largest magnitude of any number in a pipeline: far beyond any physical value in any
/// consistent unit system, and small enough that squares and products stay finite.
pub const MAX_MAGNITUDE: f64 = 1e30;
/// The longest group name accepted.
pub const MAX_NAME_CHARS: usize = 256;
/// The loosest `harmonic_balance.solver.tolerance`: on strip_wall 1e-2 moves the peak contact
/// force by 3e-4 of itself, while 1e29 stops after one iteration 7% off.
pub const MAX_SOLVER_TOLERANCE: f64 = 1e-2;
/// The range of `harmonic_balance.solver.c_scale`: over these six orders the answer is the same
/// to 1% (`hard.rs::c_over_six_orders_converges_near_the_default_answer`); at 1e29 the
/// residual, measured against c, is small before the contact force has formed.
pub const C_SCALE_RANGE: (f64, f64) = (1e-3, 1e3);
/// The largest Poisson's ratio in plane strain (λ/μ just under 1e6): the cantilever's static
/// stiffness is singular from 0.49999999 on; 0.4999995 still leaves it six digits.
pub const MAX_PLANE_STRAIN_POISSON: f64 = 0.4999995;
/// The loosest `transient.periodic_tolerance`.
pub const MAX_PERIODIC_TOLERANCE: f64 = 1e-2;

pub(crate) fn config_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Config {
        path: path.to_path_buf(),
        message: crate::error::shorten_quoted(&message.into()),
    }
}

/// A number as a message shows it: plain when moderate, in exponent form when huge or tiny.
fn show(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// A number that must be finite and at most `MAX_MAGNITUDE` in size.
fn finite(path: &Path, field: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v.abs() <= MAX_MAGNITUDE {
        Ok(v)
    } else {
        Err(config_error(
            path,
            format!(
                "{field} = {} must be a finite number of magnitude at most {MAX_MAGNITUDE:e}",
                show(v)
            ),
        ))
    }
}

fn finite_all(path: &Path, field: &str, values: &[f64]) -> Result<()> {
    for (i, &v) in values.iter().enumerate() {
        let name = if values.len() > 1 {
            format!("{field}[{i}]")
        } else {
            field.to_string()
        };
        finite(path, &name, v)?;
    }
    Ok(())
}

/// A group name: non-empty and at most `MAX_NAME_CHARS` characters.
fn group_name(path: &Path, field: &str, name: &str) -> Result<()> {
    let n = name.chars().count();
    if n == 0 || n > MAX_NAME_CHARS {
        return Err(config_error(
            path,
            format!(
                "{field} = {:?}: a group name has 1 to {MAX_NAME_CHARS} characters",
                crate::error::excerpt(name)
            ),
        ));
    }
    Ok(())
}

/// The names listed in serde's "expected one of `a`, `b`" / "expected `a` or `b`".
fn expected_names(message: &str) -> Vec<String> {
    let Some(pos) = message.find("expected") else {
        return Vec::new();
    };
    message[pos..]
        .split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// serde's message plus a "did you mean" for unknown keys and values.
fn explain(message: &str) -> String {
    let unknown = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|p| {
            message.find(p).and_then(|i| {
                let rest = &message[i + p.len()..];
                rest.find('`').map(|j| rest[..j].to_string())
            })
        });
    let Some(word) = unknown else {
        return message.to_string();
    };
    let best = expected_names(message)
        .into_iter()
        .map(|c| (strsim::jaro_winkler(&word, &c), c))
        .filter(|(s, _)| *s > 0.75)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match best {
        Some((_, c)) => format!("{message}; did you mean `{c}`?"),
        None => message.to_string(),
    }
}

fn yaml_error(path: &Path, e: &serde_yaml::Error, context: Option<&str>) -> Error {
    let location = e
        .location()
        .map(|l| format!("line {}, column {}: ", l.line(), l.column()))
        .unwrap_or_default();
    let message = explain(&e.to_string());
    let message = match context {
        Some(c) => format!("{c}: {message}"),
        None => format!("{location}{message}"),
    };
    config_error(path, message)
}

/// Set `a.b.c` to `value` (a YAML scalar or flow value), creating mappings on the way. A
/// segment of digits indexes an existing list (`boundaries.loads.0.static=[0, 1]`).
fn apply_override(root: &mut Value, spec: &str, path: &Path) -> Result<()> {
    let shown = crate::error::excerpt(spec);
    let Some((key, value)) = spec.split_once('=') else {
        return Err(config_error(
            path,
            format!("--set {shown}: expected KEY=VALUE, e.g. --set harmonic_balance.harmonics=20"),
        ));
    };
    super::limits::check_yaml(value, "pipeline")
        .map_err(|m| config_error(path, format!("--set {shown}: {m}")))?;
    let parsed: Value = serde_yaml::from_str(value).map_err(|e| {
        config_error(
            path,
            format!(
                "--set {shown}: the value is not valid YAML: {}",
                crate::error::excerpt(&e.to_string())
            ),
        )
    })?;
    let mut node = root;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(config_error(
            path,
            format!("--set {shown}: empty key segment"),
        ));
    }
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        let so_far = parts[..i].join(".");
        if let Ok(index) = part.parse::<usize>() {
            match node {
                Value::Sequence(list) => {
                    let len = list.len();
                    let Some(entry) = list.get_mut(index) else {
                        return Err(config_error(
                            path,
                            format!(
                                "--set {shown}: {so_far} has {len} entries (indices 0 to {}); to add or remove entries set the whole list, e.g. --set '{so_far}=[...]'",
                                len.saturating_sub(1)
                            ),
                        ));
                    };
                    if last {
                        *entry = parsed;
                        return Ok(());
                    }
                    node = entry;
                    continue;
                }
                _ => {
                    return Err(config_error(
                        path,
                        format!(
                            "--set {shown}: `{part}` indexes a list, but {} is not a list in the pipeline; set the whole value instead, e.g. --set '{}=[...]'",
                            if so_far.is_empty() { "the top level".to_string() } else { so_far.clone() },
                            if so_far.is_empty() { "KEY".to_string() } else { so_far.clone() }
                        ),
                    ));
                }
            }
        }
        if !node.is_mapping() {
            *node = Value::Mapping(Default::default());
        }
        let Value::Mapping(map) = node else {
            unreachable!("just made a mapping")
        };
        let k = Value::String(part.to_string());
        if last {
            map.insert(k, parsed);
            return Ok(());
        }
        node = map.entry(k).or_insert(Value::Null);
    }
    Ok(())
}

/// Read `path`, apply `--set key.path=value` overrides, and validate.
pub fn load_pipeline(path: &Path, overrides: &[String]) -> Result<Pipeline> {
    let text = super::limits::read_yaml(path, "pipeline").map_err(|m| config_error(path, m))?;
    parse_pipeline(path, &text, overrides)
}

/// A pipeline from its YAML `text`, as if read from `path` (relative files resolve from it,
/// errors name it), with the `--set` overrides applied.
pub fn parse_pipeline(path: &Path, text: &str, overrides: &[String]) -> Result<Pipeline> {
    super::limits::check_yaml(text, "pipeline").map_err(|m| config_error(path, m))?;
    let raw: RawPipeline = if overrides.is_empty() {
        serde_yaml::from_str(text).map_err(|e| yaml_error(path, &e, None))?
    } else {
        let mut value: Value =
            serde_yaml::from_str(text).map_err(|e| yaml_error(path, &e, None))?;
        for o in overrides {
            apply_override(&mut value, o, path)?;
        }
        match serde_yaml::from_value(value) {
            Ok(raw) => raw,
            Err(e) => {
                // The file itself may be at fault: then show its line and column.
                if let Err(file_error) = serde_yaml::from_str::<RawPipeline>(text) {
                    if file_error.to_string() == e.to_string() {
                        return Err(yaml_error(path, &file_error, None));
                    }
                }
                let context = format!(
                    "with {}",
                    overrides
                        .iter()
                        .map(|o| format!("--set {}", crate::error::excerpt(o)))
                        .collect::<Vec<_>>()
                        .join(" ")
                );
                return Err(yaml_error(path, &e, Some(&context)));
            }
        }
    };
    let mut pipeline = validate(path, raw)?;
    pipeline.overrides = overrides.to_vec();
    Ok(pipeline)
}

fn positive(path: &Path, field: &str, v: f64) -> Result<f64> {
    if v > 0.0 && v.is_finite() && v <= MAX_MAGNITUDE {
        Ok(v)
    } else {
        Err(config_error(
            path,
            format!(
                "{field} = {} must be a positive number, at most {MAX_MAGNITUDE:e}",
                show(v)
            ),
        ))
    }
}

/// A relative path from the pipeline: next to it, then one level up (the project root for
/// `pipelines/x.yaml`), then from the working directory; else an error naming each place tried.
fn resolve(path: &Path, field: &str, file: &Path) -> Result<PathBuf> {
    if file.is_absolute() {
        return if file.exists() {
            Ok(file.to_path_buf())
        } else {
            Err(config_error(
                path,
                format!("{field}: {} does not exist", file.display()),
            ))
        };
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut candidates = vec![dir.join(file), dir.join("..").join(file)];
    if !candidates.iter().any(|c| c == file) {
        candidates.push(file.to_path_buf());
    }
    if let Some(found) = candidates.iter().find(|c| c.exists()) {
        return Ok(found.clone());
    }
    let tried: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
    Err(config_error(
        path,
        format!(
            "{field}: {} not found (tried {}); a relative path is looked up next to the pipeline file, then in its parent directory, then in the working directory",
            file.display(),
            tried.join(", ")
        ),
    ))
}

/// Check the raw pipeline block by block, in file order (the first error wins), and build the
/// validated `Pipeline`.
fn validate(path: &Path, raw: RawPipeline) -> Result<Pipeline> {
    validate_name(path, &raw.name)?;
    let geometry = validate_geometry(path, raw.geometry)?;
    let material = validate_material(path, raw.material)?;
    let boundaries = validate_boundaries(path, raw.boundaries)?;
    let damping = validate_damping(path, raw.damping)?;
    let harmonic_balance = validate_harmonic_balance(path, raw.harmonic_balance)?;
    let contact = validate_contact(path, raw.contact)?;
    if contact.is_some() {
        check_contact_harmonics(path, &boundaries, harmonic_balance.harmonics)?;
    }
    let transient = validate_transient(path, raw.transient)?;
    let sweep = raw.sweep.map(|s| validate_sweep(path, s)).transpose()?;
    let stability = validate_stability(path, raw.stability)?;
    let output = validate_output(path, raw.output, &raw.name)?;
    let pipeline = Pipeline {
        name: raw.name,
        source: path.to_path_buf(),
        overrides: Vec::new(),
        geometry,
        material,
        boundaries,
        damping,
        harmonic_balance,
        contact,
        transient,
        sweep,
        stability,
        output,
    };
    Ok(pipeline)
}

/// A contact solve computes harmonics 0..H only: every harmonic a load or motion excites must
/// be among them.
fn check_contact_harmonics(path: &Path, b: &Boundaries, h: usize) -> Result<()> {
    let loads = b.loads.iter().enumerate().flat_map(|(i, l)| {
        l.signal
            .harmonics
            .iter()
            .map(move |x| (format!("boundaries.loads[{i}]"), x.0))
    });
    let motions = b.prescribed.iter().enumerate().flat_map(|(i, p)| {
        p.signal
            .harmonics
            .iter()
            .map(move |x| (format!("boundaries.prescribed[{i}]"), x.0))
    });
    if let Some((field, k)) = loads.chain(motions).max_by_key(|(_, k)| *k) {
        if k > h {
            return Err(config_error(
                path,
                format!(
                    "harmonic_balance.harmonics = {h} is below harmonic k = {k} of {field}: a contact solve computes harmonics 0..H only; set harmonic_balance.harmonics ≥ {k} (several times more resolves the contact's higher harmonics)"
                ),
            ));
        }
    }
    Ok(())
}

fn validate_name(path: &Path, name: &str) -> Result<()> {
    if name.chars().count() > 100 {
        return Err(config_error(
            path,
            format!(
                "name = {:?}: at most 100 characters (it names the output directory)",
                crate::error::excerpt(name),
            ),
        ));
    }
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(config_error(
            path,
            format!(
                "name = {:?}: use letters, digits, `_` and `-` only (it names the output directory)",
                crate::error::excerpt(name)
            ),
        ));
    }
    Ok(())
}

fn validate_geometry(path: &Path, g: RawGeometry) -> Result<Geometry> {
    let order = g.order.unwrap_or(1);
    if !(1..=2).contains(&order) {
        return Err(config_error(
            path,
            format!("geometry.order = {order}: must be 1 or 2"),
        ));
    }
    if let Some(h) = g.mesh_size {
        positive(path, "geometry.mesh_size", h)?;
    }
    for (k, v) in &g.parameters {
        finite(
            path,
            &format!("geometry.parameters.{}", crate::error::excerpt(k)),
            *v,
        )?;
    }
    let file = resolve(path, "geometry.file", &g.file)?;
    let gmsh = match g.gmsh {
        Some(p) => Some(resolve(path, "geometry.gmsh", &p).map_err(|_| {
            Error::Gmsh(format!(
                "geometry.gmsh = {} does not exist: fix the path, or remove the key to use .venv/bin/gmsh (made by `make venv`) or gmsh on PATH",
                p.display()
            ))
        })?),
        None => None,
    };
    let max_elements = g
        .max_elements
        .unwrap_or(crate::mesh::gmsh::DEFAULT_MAX_ELEMENTS);
    if max_elements == 0 {
        return Err(config_error(
            path,
            "geometry.max_elements must be at least 1",
        ));
    }
    let gmsh_timeout = positive(
        path,
        "geometry.gmsh_timeout",
        g.gmsh_timeout
            .unwrap_or(crate::mesh::gmsh::DEFAULT_GMSH_TIMEOUT),
    )?;
    if gmsh_timeout > 1e7 {
        return Err(config_error(
            path,
            format!("geometry.gmsh_timeout = {gmsh_timeout} s: at most 1e7 s (about 4 months)"),
        ));
    }
    let max_aspect_ratio = g.max_aspect_ratio.unwrap_or(super::DEFAULT_MAX_ASPECT);
    if !(1.0..=MAX_MAGNITUDE).contains(&max_aspect_ratio) {
        return Err(config_error(
            path,
            format!(
                "geometry.max_aspect_ratio = {} must be a finite number of at least 1 (default {}; a cell beyond 1000 is a mesh error, not a shape)",
                show(max_aspect_ratio),
                super::DEFAULT_MAX_ASPECT
            ),
        ));
    }
    Ok(Geometry {
        file,
        parameters: g.parameters,
        mesh_size: g.mesh_size,
        order,
        quads: g.quads,
        gmsh,
        max_elements,
        gmsh_timeout,
        max_aspect_ratio,
        allow_disconnected: g.allow_disconnected,
        trusted: false,
    })
}

fn validate_material(path: &Path, m: RawMaterial) -> Result<MaterialSpec> {
    positive(path, "material.youngs_modulus", m.youngs_modulus)?;
    positive(path, "material.density", m.density)?;
    if !(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5) {
        return Err(config_error(
            path,
            format!(
                "material.poisson_ratio = {} must lie in (−1, 0.5)",
                m.poisson_ratio
            ),
        ));
    }
    if m.model == RawPlaneModel::PlaneStrain && m.poisson_ratio >= MAX_PLANE_STRAIN_POISSON {
        let ratio = 2.0 * m.poisson_ratio / (1.0 - 2.0 * m.poisson_ratio);
        return Err(config_error(
            path,
            format!(
                "material.poisson_ratio = {} in plane strain is near-incompressible beyond what displacement elements compute (λ/μ = {ratio:.1e}, at least 1e6: the stiffness matrix loses the digits that tell bending from volume change, and the solve finds it singular); use ν ≤ 0.49 (it already models rubber-like solids within a few percent, with geometry.order: 2), or plane_stress for a thin plate; mixed u–p elements are not available",
                m.poisson_ratio
            ),
        ));
    }
    let thickness = positive(path, "material.thickness", m.thickness.unwrap_or(1.0))?;
    Ok(MaterialSpec {
        youngs_modulus: m.youngs_modulus,
        poisson_ratio: m.poisson_ratio,
        density: m.density,
        model: match m.model {
            RawPlaneModel::PlaneStrain => PlaneModelSpec::PlaneStrain,
            RawPlaneModel::PlaneStress => PlaneModelSpec::PlaneStress,
        },
        thickness,
    })
}

/// Harmonic indices of one signal: each k ≥ 1 and at most once; `field` names the entry.
fn check_harmonic_indices(path: &Path, field: &str, ks: &[usize]) -> Result<()> {
    for (j, &k) in ks.iter().enumerate() {
        if k == 0 || ks[..j].contains(&k) {
            return Err(config_error(path, format!("{field}.harmonics[{j}].k = {k} must be ≥ 1 and appear once (put the constant part in `static`)")));
        }
        if k > MAX_HARMONICS {
            return Err(config_error(
                path,
                format!(
                    "{field}.harmonics[{j}].k = {k} is above the limit of {MAX_HARMONICS} harmonics"
                ),
            ));
        }
    }
    Ok(())
}

fn validate_boundaries(path: &Path, b: RawBoundaries) -> Result<Boundaries> {
    for (i, g) in b.fixed.iter().enumerate() {
        group_name(path, &format!("boundaries.fixed[{i}]"), g)?;
    }
    let prescribed = b
        .prescribed
        .into_iter()
        .enumerate()
        .map(|(i, p)| validate_prescribed(path, i, p))
        .collect::<Result<Vec<_>>>()?;
    let loads = b
        .loads
        .into_iter()
        .enumerate()
        .map(|(i, l)| validate_load(path, i, l))
        .collect::<Result<Vec<_>>>()?;
    Ok(Boundaries {
        fixed: b.fixed,
        prescribed,
        loads,
    })
}

/// `boundaries.prescribed[i]`: a group name, distinct harmonic indices, finite values.
fn validate_prescribed(path: &Path, i: usize, p: RawPrescribed) -> Result<PrescribedSpec> {
    let field = format!("boundaries.prescribed[{i}]");
    group_name(path, &format!("{field}.group"), &p.group)?;
    let ks: Vec<usize> = p.harmonics.iter().map(|h| h.k).collect();
    check_harmonic_indices(path, &field, &ks)?;
    finite(path, &format!("{field}.static"), p.static_part)?;
    for h in &p.harmonics {
        finite(path, &format!("{field}.harmonics (k = {}).cos", h.k), h.cos)?;
        finite(path, &format!("{field}.harmonics (k = {}).sin", h.k), h.sin)?;
    }
    Ok(PrescribedSpec {
        group: p.group,
        component: match p.component {
            RawComponent::X => 0,
            RawComponent::Y => 1,
        },
        signal: Signal {
            static_part: [p.static_part],
            harmonics: p
                .harmonics
                .iter()
                .map(|h| (h.k, [h.cos], [h.sin]))
                .collect(),
        },
    })
}

/// `boundaries.loads[i]`: a group name, distinct harmonic indices, finite values, and a
/// static part or harmonics.
fn validate_load(path: &Path, i: usize, l: RawLoad) -> Result<LoadSpec> {
    let field = format!("boundaries.loads[{i}]");
    group_name(path, &format!("{field}.group"), &l.group)?;
    let ks: Vec<usize> = l.harmonics.iter().map(|h| h.k).collect();
    check_harmonic_indices(path, &field, &ks)?;
    if let Some(s) = l.static_part {
        finite_all(path, &format!("{field}.static"), &s)?;
    }
    for h in &l.harmonics {
        let at = |part: &str| format!("{field}.harmonics (k = {}).{part}", h.k);
        finite_all(path, &at("cos"), &h.cos)?;
        finite_all(path, &at("sin"), &h.sin)?;
    }
    if l.static_part.is_none() && l.harmonics.is_empty() {
        return Err(config_error(
            path,
            format!(
                "boundaries.loads[{i}] (group {}): give a `static` part, `harmonics`, or both",
                l.group
            ),
        ));
    }
    Ok(LoadSpec {
        group: l.group,
        kind: match l.kind {
            RawLoadKind::Traction => LoadKind::Traction,
            RawLoadKind::Force => LoadKind::Force,
        },
        signal: Signal {
            static_part: l.static_part.unwrap_or([0.0; 2]),
            harmonics: l.harmonics.iter().map(|h| (h.k, h.cos, h.sin)).collect(),
        },
    })
}

fn validate_damping(path: &Path, damping: Option<RawDamping>) -> Result<Option<Rayleigh>> {
    let Some(d) = damping else {
        return Ok(None);
    };
    finite(path, "damping.alpha", d.alpha)?;
    finite(path, "damping.beta", d.beta)?;
    for (field, v) in [("damping.alpha", d.alpha), ("damping.beta", d.beta)] {
        if !(v >= 0.0) {
            return Err(config_error(
                path,
                format!("{field} = {} must be ≥ 0 (0: no such damping)", show(v)),
            ));
        }
    }
    Ok(Some(Rayleigh {
        alpha: d.alpha,
        beta: d.beta,
    }))
}

fn validate_harmonic_balance(path: &Path, hb: RawHarmonicBalance) -> Result<HarmonicBalance> {
    if hb.frequency.is_finite() && hb.frequency > MAX_FREQUENCY {
        return Err(config_error(
            path,
            format!(
                "harmonic_balance.frequency = {:e} Hz is above {MAX_FREQUENCY:e} Hz: at such frequencies elastic waves are micrometres long and the continuum model does not apply (is the unit Hz?)",
                hb.frequency
            ),
        ));
    }
    positive(path, "harmonic_balance.frequency", hb.frequency)?;
    if hb.harmonics > MAX_HARMONICS {
        return Err(config_error(
            path,
            format!(
                "harmonic_balance.harmonics = {} is above the limit of {MAX_HARMONICS}: the contact solve grows as H² (and N = 16H samples); the accuracy table shows where more harmonics stop paying",
                hb.harmonics
            ),
        ));
    }
    if let Some(n) = hb.samples {
        if n > MAX_SAMPLES {
            return Err(config_error(
                path,
                format!("harmonic_balance.samples = {n} is above the limit of {MAX_SAMPLES}"),
            ));
        }
        if n <= 2 * hb.harmonics {
            return Err(config_error(path, format!(
                "harmonic_balance.samples = {n} must exceed 2·harmonics = {}: use at least {} (16·H = {} converges reliably)",
                2 * hb.harmonics,
                2 * hb.harmonics + 1,
                (16 * hb.harmonics).max(1)
            )));
        }
    }
    let mut solver = SolverSpec::default();
    if let Some(s) = hb.solver {
        if let Some(t) = s.tolerance {
            solver.tolerance = positive(path, "harmonic_balance.solver.tolerance", t)?;
            if t > MAX_SOLVER_TOLERANCE {
                return Err(config_error(
                    path,
                    format!(
                        "harmonic_balance.solver.tolerance = {} is above {MAX_SOLVER_TOLERANCE:e}: Newton would stop before the contact forces are converged; use at most {MAX_SOLVER_TOLERANCE:e} (default 1e-8)",
                        show(t)
                    ),
                ));
            }
        }
        if let Some(n) = s.max_iterations {
            solver.max_iterations = n;
        }
        if let Some(c) = s.c_scale {
            if !(C_SCALE_RANGE.0..=C_SCALE_RANGE.1).contains(&c) {
                return Err(config_error(
                    path,
                    format!(
                        "harmonic_balance.solver.c_scale = {} must lie in [{:e}, {:e}]: beyond, the residual's scale hides an unconverged contact state; use 1 (the default), or 0.3 or 0.1 when contact solves stall",
                        show(c),
                        C_SCALE_RANGE.0,
                        C_SCALE_RANGE.1
                    ),
                ));
            }
            solver.c_scale = c;
        }
        if let Some(t) = s.max_seconds {
            solver.max_seconds = positive(path, "harmonic_balance.solver.max_seconds", t)?;
        }
    }
    Ok(HarmonicBalance {
        frequency: hb.frequency,
        harmonics: hb.harmonics,
        samples: hb.samples,
        solver,
        basis: validate_basis(path, hb.basis)?,
    })
}

/// The most segments of a spline basis (as many unknowns per scalar as samples).
const MAX_SEGMENTS: usize = 100_000;

fn validate_basis(path: &Path, basis: Option<RawBasis>) -> Result<BasisSpec> {
    let Some(RawBasis::Spline { degree, segments }) = basis else {
        return Ok(BasisSpec::Fourier);
    };
    let degree = degree.unwrap_or(3);
    if !(2..=7).contains(&degree) {
        return Err(config_error(
            path,
            format!("harmonic_balance.basis.spline.degree = {degree} must be 2 … 7 (2 is the lowest C¹ basis; 3, the default, is usually best)"),
        ));
    }
    if segments < degree + 1 || segments > MAX_SEGMENTS {
        return Err(config_error(
            path,
            format!(
                "harmonic_balance.basis.spline.segments = {segments} must be {} … {MAX_SEGMENTS} (at least degree + 1)",
                degree + 1
            ),
        ));
    }
    Ok(BasisSpec::Spline { degree, segments })
}

fn validate_contact(path: &Path, contact: Option<RawContact>) -> Result<Option<ContactSpec>> {
    let Some(c) = contact else {
        return Ok(None);
    };
    group_name(path, "contact.boundary", &c.boundary)?;
    let obstacle = match c.obstacle {
        RawObstacle::Curve(group) => {
            group_name(path, "contact.obstacle.curve", &group)?;
            ObstacleSpec::Curve { group }
        }
        RawObstacle::Line { point, normal } => {
            finite_all(path, "contact.obstacle.line.point", &point)?;
            finite_all(path, "contact.obstacle.line.normal", &normal)?;
            let len = (normal[0] * normal[0] + normal[1] * normal[1]).sqrt();
            if !(len > 0.0) || !len.is_finite() {
                return Err(config_error(path, "contact.obstacle.line.normal must be a non-zero vector (pointing out of the obstacle, toward the body)"));
            }
            ObstacleSpec::Line {
                point,
                normal: [normal[0] / len, normal[1] / len],
            }
        }
        RawObstacle::Circle {
            center,
            radius,
            body_inside,
        } => ObstacleSpec::Circle {
            center: {
                finite_all(path, "contact.obstacle.circle.center", &center)?;
                center
            },
            radius: positive(path, "contact.obstacle.circle.radius", radius)?,
            body_inside,
        },
    };
    if let Some(d) = c.search_distance {
        positive(path, "contact.search_distance", d)?;
    }
    Ok(Some(ContactSpec {
        boundary: c.boundary,
        obstacle,
        search_distance: c.search_distance,
        allow_initial_penetration: c.allow_initial_penetration,
        mass: match c.mass {
            RawMass::Redistributed => ContactMass::Redistributed,
            RawMass::Lumped => ContactMass::Lumped,
        },
    }))
}

fn validate_transient(path: &Path, transient: Option<RawTransient>) -> Result<TransientSpec> {
    let mut spec = TransientSpec::default();
    let Some(t) = transient else {
        return Ok(spec);
    };
    if let Some(v) = t.periodic_tolerance {
        spec.periodic_tolerance = positive(path, "transient.periodic_tolerance", v)?;
        if v > MAX_PERIODIC_TOLERANCE {
            return Err(config_error(
                path,
                format!(
                    "transient.periodic_tolerance = {} is above {MAX_PERIODIC_TOLERANCE:e}: a state that changes by more than 1% per period is not periodic; use at most {MAX_PERIODIC_TOLERANCE:e} (default 1e-6)",
                    show(v)
                ),
            ));
        }
    }
    if let Some(v) = t.max_periods {
        spec.max_periods = v.max(1);
    }
    if let Some(v) = t.courant {
        if !(v > 0.0 && v <= 1.0) {
            return Err(config_error(
                path,
                format!("transient.courant = {v} must lie in (0, 1]"),
            ));
        }
        spec.courant = v;
    }
    if let Some(start) = t.start {
        spec.start = match start {
            RawStart::Rest => TransientStart::Rest,
            RawStart::HarmonicBalance => TransientStart::HarmonicBalance,
            RawStart::Previous => TransientStart::Previous,
        };
    }
    if let Some(v) = t.perturbation {
        if !(v.abs() <= 1.0) {
            return Err(config_error(
                path,
                format!("transient.perturbation = {} must lie in [-1, 1]", show(v)),
            ));
        }
        if spec.start == TransientStart::Rest && v != 0.0 {
            return Err(config_error(
                path,
                "transient.perturbation needs transient.start: harmonic_balance or previous (rest has nothing to perturb)".to_string(),
            ));
        }
        spec.perturbation = v;
    }
    Ok(spec)
}

fn validate_stability(path: &Path, raw: Option<RawStability>) -> Result<StabilitySpec> {
    let mut spec = StabilitySpec::default();
    let Some(r) = raw else {
        return Ok(spec);
    };
    if let Some(v) = r.check {
        spec.check = v;
    }
    if let Some(v) = r.method {
        spec.method = v;
    }
    if let Some(v) = r.max_periods {
        if v == 0 {
            return Err(config_error(
                path,
                "stability.max_periods = 0: give at least 1 (default 200), or set stability.check: false".to_string(),
            ));
        }
        spec.max_periods = v;
    }
    if let Some(v) = r.perturbation {
        if !(v > 0.0 && v <= 0.5) {
            return Err(config_error(
                path,
                format!(
                    "stability.perturbation = {} must lie in (0, 0.5] (default 0.001)",
                    show(v)
                ),
            ));
        }
        spec.perturbation = v;
    }
    if let Some(v) = r.every {
        if v == 0 {
            return Err(config_error(
                path,
                "stability.every = 0: give at least 1 (1, the default, checks every point), or set stability.check: false".to_string(),
            ));
        }
        spec.every = v;
    }
    if let Some(v) = r.max_seconds {
        spec.max_seconds = positive(path, "stability.max_seconds", v)?;
    }
    Ok(spec)
}

fn validate_sweep(path: &Path, s: RawSweep) -> Result<SweepSpec> {
    let mut spec = SweepSpec {
        from_hz: sweep_frequency(path, "sweep.from", s.from)?,
        to_hz: sweep_frequency(path, "sweep.to", s.to)?,
        ..SweepSpec::default()
    };
    if spec.from_hz == spec.to_hz {
        return Err(config_error(
            path,
            "sweep.from and sweep.to are equal: give a frequency range (for one frequency, use `hbcontact run`)",
        ));
    }
    if let Some(v) = s.step {
        spec.step = positive(path, "sweep.step", v)?;
        if v > 1.0 {
            return Err(config_error(
                path,
                format!(
                    "sweep.step = {} must lie in (0, 1]: it is a fraction of the frequency span (default 0.01)",
                    show(v)
                ),
            ));
        }
    }
    if let Some(v) = s.min_step {
        spec.min_step = positive(path, "sweep.min_step", v)?;
    }
    if let Some(v) = s.max_step {
        spec.max_step = positive(path, "sweep.max_step", v)?;
    }
    if let Some(v) = s.max_change {
        spec.max_change = positive(path, "sweep.max_change", v)?;
    }
    if let Some(v) = s.max_points {
        spec.max_points = v;
    }
    if let Some(v) = s.save_every {
        spec.save_every = v;
    }
    if let Some(v) = s.reduced_frames {
        spec.reduced_frames = v;
    }
    let (lo, hi) = (spec.from_hz.min(spec.to_hz), spec.from_hz.max(spec.to_hz));
    for (i, &f) in s.write_at.iter().enumerate() {
        if !(f >= lo && f <= hi) {
            return Err(config_error(
                path,
                format!("sweep.write_at[{i}] = {f} Hz lies outside the swept range [{lo}, {hi}] Hz: give a frequency between sweep.from and sweep.to"),
            ));
        }
    }
    spec.write_at = s.write_at;
    if spec.max_points < 2 || spec.max_points > MAX_SWEEP_POINTS {
        return Err(config_error(
            path,
            format!(
                "sweep.max_points = {} must lie in [2, {MAX_SWEEP_POINTS}]",
                spec.max_points
            ),
        ));
    }
    if !(spec.min_step <= spec.step && spec.step <= spec.max_step) {
        let field = if spec.step > spec.max_step {
            "sweep.max_step"
        } else {
            "sweep.min_step"
        };
        return Err(config_error(
            path,
            format!(
                "{field}: sweep.min_step ({}) ≤ sweep.step ({}) ≤ sweep.max_step ({}) must hold",
                show(spec.min_step),
                show(spec.step),
                show(spec.max_step)
            ),
        ));
    }
    Ok(spec)
}

/// The most points one sweep may take (each is a set of factorizations).
const MAX_SWEEP_POINTS: usize = 100_000;

/// `sweep.from` and `sweep.to`: positive and at most `MAX_FREQUENCY`, like
/// `harmonic_balance.frequency`.
fn sweep_frequency(path: &Path, field: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v > MAX_FREQUENCY {
        return Err(config_error(
            path,
            format!(
                "{field} = {} Hz is above {MAX_FREQUENCY:e} Hz: at such frequencies elastic waves are micrometres long and the continuum model does not apply (is the unit Hz?)",
                show(v)
            ),
        ));
    }
    positive(path, field, v)
}

fn validate_output(path: &Path, output: Option<RawOutput>, name: &str) -> Result<OutputSpec> {
    let out = output.unwrap_or(RawOutput {
        directory: None,
        frames: None,
        max_frames: None,
        fields: None,
        probes: Vec::new(),
        plots: None,
    });
    let frames = out.frames.unwrap_or(24);
    if frames == 0 {
        return Err(config_error(path, "output.frames must be at least 1"));
    }
    let max_frames = out.max_frames.unwrap_or(DEFAULT_MAX_FRAMES);
    if frames > max_frames {
        return Err(config_error(
            path,
            format!(
                "output.frames = {frames} is above output.max_frames = {max_frames} (each frame is a VTU file of the whole mesh): write fewer, or raise output.max_frames"
            ),
        ));
    }
    for (i, g) in out.probes.iter().enumerate() {
        group_name(path, &format!("output.probes[{i}]"), g)?;
    }
    let fields = match out.fields {
        Some(f) => f
            .into_iter()
            .map(|x| match x {
                RawField::Displacement => FieldName::Displacement,
                RawField::Velocity => FieldName::Velocity,
                RawField::Acceleration => FieldName::Acceleration,
                RawField::Stress => FieldName::Stress,
                RawField::VonMises => FieldName::VonMises,
                RawField::Contact => FieldName::Contact,
            })
            .collect(),
        None => vec![
            FieldName::Displacement,
            FieldName::Velocity,
            FieldName::Acceleration,
            FieldName::Stress,
            FieldName::VonMises,
            FieldName::Contact,
        ],
    };
    Ok(OutputSpec {
        directory: out
            .directory
            .unwrap_or_else(|| PathBuf::from("output").join(name)),
        frames,
        fields,
        probes: out.probes,
        plots: out.plots.unwrap_or(true),
    })
}
