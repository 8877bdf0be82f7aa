//! The YAML schema as written by users (serde types, unknown keys denied); `read` reads it
//! and applies `--set`, `validate` makes a `Pipeline` of it.
//!
//! serde_yaml (deprecated upstream, still working) stays behind this file so that a move to a
//! maintained fork is a one-line change.
//!
//! The `///` comments on the raw types are the descriptions of the pipeline's JSON Schema
//! (`docs/pipeline.schema.json`, see `super::schema`): keep them to meaning, unit and default.

use std::collections::BTreeMap;
use std::path::PathBuf;

use schemars::JsonSchema;
use serde::Deserialize;

/// An hbcontact pipeline: one scene (geometry, material, supports, loads, contact) and how to
/// solve and write it. Lengths, forces and times are in one consistent unit system of your
/// choice (SI: m, N, s, Pa, kg/m³; or mm, N, s, MPa, t/mm³); frequencies are in Hz.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Pipeline", title = "hbcontact pipeline")]
pub(super) struct RawPipeline {
    /// The scene's name: letters, digits, `_` and `-` only. It names the default output
    /// directory `output/<name>`. Required.
    pub(super) name: String,
    /// The gmsh geometry and how to mesh it. Required.
    pub(super) geometry: RawGeometry,
    /// The linear-elastic, isotropic material. Required.
    pub(super) material: RawMaterial,
    /// Supports, prescribed motion and loads, on gmsh physical groups. Default: none.
    #[serde(default)]
    pub(super) boundaries: RawBoundaries,
    /// Rayleigh damping D = alpha·M + beta·K. Default: none (undamped, real arithmetic).
    #[serde(default)]
    pub(super) damping: Option<RawDamping>,
    /// The periodic steady state sought: fundamental frequency, harmonics, samples, contact
    /// solver. Required.
    pub(super) harmonic_balance: RawHarmonicBalance,
    /// Frictionless unilateral contact of a body boundary with a rigid obstacle or with the
    /// boundary of another meshed body. Default: none
    /// (a linear scene).
    #[serde(default)]
    pub(super) contact: Option<RawContact>,
    /// Settings of `hbcontact transient` (explicit time marching to the periodic state).
    /// Default: each key's default.
    #[serde(default)]
    pub(super) transient: Option<RawTransient>,
    /// Settings of `hbcontact sweep` (a frequency-response curve by continuation).
    #[serde(default)]
    pub(super) sweep: Option<RawSweep>,
    /// The stability verdict of `run` and of each sweep point (time marching from the
    /// perturbed harmonic-balance state). Default: each key's default.
    #[serde(default)]
    pub(super) stability: Option<RawStability>,
    /// What is written and where. Default: each key's default.
    #[serde(default)]
    pub(super) output: Option<RawOutput>,
}

/// The gmsh geometry and how to mesh it.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Geometry")]
pub(super) struct RawGeometry {
    /// The gmsh `.geo` file, or a ready `.msh` (then `parameters`, `mesh_size`, `order` and
    /// `quads` are not used). A relative path is looked up next to the pipeline file, then in
    /// its parent directory (so `geometries/x.geo` works from `pipelines/`), then in the
    /// working directory; the first that exists is used. Required.
    pub(super) file: PathBuf,
    /// Numbers passed to gmsh as `-setnumber NAME VALUE` (the `.geo`'s `DefineConstant`s), in
    /// the geometry's units. Default: none.
    #[serde(default)]
    pub(super) parameters: BTreeMap<String, f64>,
    /// Largest element size (gmsh `-clmax`), a length, > 0. Default: the sizes set in the
    /// `.geo`.
    #[serde(default)]
    pub(super) mesh_size: Option<f64>,
    /// Element order: 1 (linear) or 2 (quadratic). Default: 1.
    #[serde(default)]
    #[schemars(range(min = 1, max = 2))]
    pub(super) order: Option<u8>,
    /// Ask for quadrilaterals: passes `-setnumber quads 1` to gmsh (the `.geo` decides what
    /// to recombine). Default: false.
    #[serde(default)]
    pub(super) quads: bool,
    /// The gmsh executable (path as for `file`). Default: `.venv/bin/gmsh` (made by
    /// `make venv`), then `gmsh` on PATH.
    #[serde(default)]
    pub(super) gmsh: Option<PathBuf>,
    /// Refuse to mesh when the estimated number of elements exceeds this (the estimate comes
    /// from gmsh on a coarsened mesh, before the real one), ≥ 1. Default: 2000000.
    #[serde(default)]
    #[schemars(range(min = 1))]
    pub(super) max_elements: Option<u64>,
    /// Time limit of one gmsh run, in seconds, > 0 and at most 1e7: gmsh (with its process
    /// group) is killed beyond it. Default: 600.
    #[serde(default)]
    pub(super) gmsh_timeout: Option<f64>,
    /// Refuse a mesh with a cell whose aspect ratio (longest edge² over the area, halved for
    /// triangles: a/b for an a × b rectangle or its halves) exceeds this, ≥ 1 and finite;
    /// above 20 a run warns. Default: 1000.
    #[serde(default)]
    pub(super) max_aspect_ratio: Option<f64>,
    /// Accept a mesh whose cells form several disconnected parts (each then needs its own
    /// support or contact). Default: false (refused, exit code 2).
    #[serde(default)]
    pub(super) allow_disconnected: bool,
}

/// The 2-D model of the out-of-plane direction.
#[derive(Deserialize, JsonSchema, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "PlaneModel")]
pub(super) enum RawPlaneModel {
    /// Plane strain (ε_zz = 0): a long body.
    PlaneStrain,
    /// Plane stress (σ_zz = 0): a thin plate.
    PlaneStress,
}

/// The linear-elastic, isotropic material.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Material")]
pub(super) struct RawMaterial {
    /// Young's modulus E, a stress (Pa in SI, MPa in mm–N–s), > 0. Required.
    pub(super) youngs_modulus: f64,
    /// Poisson's ratio ν (dimensionless), in (−1, 0.5), and in plane strain also
    /// < 0.4999995 (λ/μ = 2ν/(1 − 2ν) under 1e6; beyond, the stiffness is singular to working
    /// precision). From 0.49 on, plane strain warns: displacement elements lock. Required.
    pub(super) poisson_ratio: f64,
    /// Mass density ρ (kg/m³ in SI, t/mm³ in mm–N–s), > 0. Required.
    pub(super) density: f64,
    /// `plane_strain` or `plane_stress`. Required.
    pub(super) model: RawPlaneModel,
    /// Out-of-plane thickness, a length, > 0: multiplies stiffness, mass and tractions.
    /// Default: 1.
    #[serde(default)]
    pub(super) thickness: Option<f64>,
}

/// Supports, prescribed motion and loads, on gmsh physical groups.
#[derive(Deserialize, JsonSchema, Default)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Boundaries")]
pub(super) struct RawBoundaries {
    /// Groups whose nodes have both displacement components held at zero. Default: none.
    #[serde(default)]
    pub(super) fixed: Vec<String>,
    /// Groups whose nodes have one displacement component moved by a given periodic signal.
    /// Default: none.
    #[serde(default)]
    pub(super) prescribed: Vec<RawPrescribed>,
    /// External loads on groups: static part plus harmonics. Default: none.
    #[serde(default)]
    pub(super) loads: Vec<RawLoad>,
    /// A uniform static acceleration [x, y] of gravity, in length/s² (e.g. [0, -9.81]): the
    /// body force ρg on every cell, a static load. Default: none.
    #[serde(default)]
    pub(super) gravity: Option<[f64; 2]>,
    /// The body turns at a constant speed about an axis normal to the plane and is described
    /// in the turning frame: the centrifugal force, the spin softening and (on request) the
    /// Coriolis force it brings. Default: not turning.
    #[serde(default)]
    pub(super) rotation: Option<RawRotation>,
}

/// Rotation about an axis normal to the plane, in the rotating frame.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Rotation")]
pub(super) struct RawRotation {
    /// The rotation speed Ω about +z, in rad/s: positive counter-clockwise (the sense
    /// matters only to the Coriolis force). Give this or `turns_per_period`.
    #[serde(default)]
    pub(super) speed: Option<f64>,
    /// The speed tied to the fundamental frequency f: Ω = 2π f × this (1: one period is one
    /// turn, so a lobed casing or an engine-order load excites harmonic n of Ω). A sweep then
    /// sweeps the rotation speed with the frequency, and the centrifugal force, the spin
    /// softening and the Coriolis force follow it. Give this or `speed`; negative turns
    /// clockwise.
    #[serde(default)]
    pub(super) turns_per_period: Option<f64>,
    /// The axis' point [x, y], a length. Default: [0, 0].
    #[serde(default)]
    pub(super) center: [f64; 2],
    /// The centrifugal body force ρΩ²r, a static load (r from the axis, undeformed).
    /// Default: true.
    #[serde(default)]
    pub(super) centrifugal: Option<bool>,
    /// The spin softening −Ω²M added to the stiffness (the centrifugal force follows the
    /// displacement), which lowers every in-plane natural frequency: ω² − Ω². Default: true.
    #[serde(default)]
    pub(super) spin_softening: Option<bool>,
    /// The Coriolis (gyroscopic) force 2Ω ẑ × u̇ per unit mass, 2ΩMJu̇ in the velocity term:
    /// it couples the in-plane directions and splits pairs of modes. Z_k is then not
    /// symmetric (factored by LU), a contact sweep needs `sweep.reduced_frames: false`, and
    /// the stability check marches (Hill's method does not take it yet). Default: false.
    #[serde(default)]
    pub(super) coriolis: bool,
}

/// A displacement component.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "Component")]
pub(super) enum RawComponent {
    /// The x component.
    X,
    /// The y component.
    Y,
}

/// One harmonic of a scalar signal: cos·cos(kωt) + sin·sin(kωt).
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "ScalarHarmonic")]
pub(super) struct RawHarmonic1 {
    /// The harmonic index k ≥ 1 (frequency k·f); each k at most once. Required.
    #[schemars(range(min = 1))]
    pub(super) k: usize,
    /// Amplitude of cos(kωt), a length. Default: 0.
    #[serde(default)]
    pub(super) cos: f64,
    /// Amplitude of sin(kωt), a length. Default: 0.
    #[serde(default)]
    pub(super) sin: f64,
}

/// A prescribed periodic motion of one displacement component of a group's nodes.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Prescribed")]
pub(super) struct RawPrescribed {
    /// The gmsh physical group (curve or point) whose nodes move. Required.
    pub(super) group: String,
    /// The component held: `x` or `y`. Required.
    pub(super) component: RawComponent,
    /// The constant part of the motion, a length. Default: 0.
    #[serde(default, rename = "static")]
    pub(super) static_part: f64,
    /// The harmonic part of the motion. Default: none.
    #[serde(default)]
    pub(super) harmonics: Vec<RawHarmonic1>,
}

/// How a load's value is applied to its group.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "LoadType")]
pub(super) enum RawLoadKind {
    /// A force per unit area on the edges of a curve group (times the thickness).
    Traction,
    /// A total force shared equally by the nodes of the group.
    Force,
}

/// One harmonic of a vector signal: cos·cos(kωt) + sin·sin(kωt), as [x, y].
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "VectorHarmonic")]
pub(super) struct RawHarmonic2 {
    /// The harmonic index k ≥ 1 (frequency k·f); each k at most once. Required.
    #[schemars(range(min = 1))]
    pub(super) k: usize,
    /// Amplitude [x, y] of cos(kωt), a traction or a force. Default: [0, 0].
    #[serde(default)]
    pub(super) cos: [f64; 2],
    /// Amplitude [x, y] of sin(kωt), a traction or a force. Default: [0, 0].
    #[serde(default)]
    pub(super) sin: [f64; 2],
}

/// An external periodic load on a group: static part plus harmonics.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Load")]
pub(super) struct RawLoad {
    /// The gmsh physical group loaded (a curve for `traction`). Required.
    pub(super) group: String,
    /// `traction` (force per area on edges) or `force` (total force over the nodes). Required.
    #[serde(rename = "type")]
    pub(super) kind: RawLoadKind,
    /// The constant part [x, y], a traction or a force. Default: none; give `static`,
    /// `harmonics` or both.
    #[serde(default, rename = "static")]
    pub(super) static_part: Option<[f64; 2]>,
    /// The harmonic part. Default: none; give `static`, `harmonics` or both.
    #[serde(default)]
    pub(super) harmonics: Vec<RawHarmonic2>,
}

/// Rayleigh damping D = alpha·M + beta·K.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Damping")]
pub(super) struct RawDamping {
    /// Mass-proportional coefficient α, in 1/s, ≥ 0. Default: 0.
    #[serde(default)]
    pub(super) alpha: f64,
    /// Stiffness-proportional coefficient β, in s, ≥ 0. Default: 0.
    #[serde(default)]
    pub(super) beta: f64,
}

/// The contact solver (semi-smooth Newton on the sampled complementarity residual).
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Solver")]
pub(super) struct RawSolver {
    /// Relative tolerance on the complementarity residual (‖R‖∞ over the force scale), in
    /// (0, 1e-2]: a looser one stops Newton before the contact forces mean anything (at 1e29
    /// after one iteration, 2% off). Default: 1e-8.
    #[serde(default)]
    pub(super) tolerance: Option<f64>,
    /// Iteration limit of each Newton run (direct, each ladder rung, each c; a smoothing level
    /// and a step of the damping continuation stop at 30). Default: 200.
    #[serde(default)]
    pub(super) max_iterations: Option<usize>,
    /// The complementarity parameter c as a multiple of 1/mean|G_0,ii| (the inverse of the
    /// contact nodes' mean static compliance), in [1e-3, 1e3] (the six orders over which the
    /// answer is the same; beyond, the residual's scale hides an unconverged state). Default: 1.
    #[serde(default)]
    pub(super) c_scale: Option<f64>,
    /// Wall-time budget of the whole contact solve (every attempt), in seconds, > 0: beyond it
    /// the solve stops (exit code 4) saying so. Default: 3600.
    #[serde(default)]
    pub(super) max_seconds: Option<f64>,
}

/// The periodic steady state sought.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "HarmonicBalance")]
pub(super) struct RawHarmonicBalance {
    /// The fundamental frequency f, in Hz (ω = 2πf, period 1/f), > 0 and at most 1e9.
    /// Required.
    pub(super) frequency: f64,
    /// The highest harmonic H of the contact solve (≥ every harmonic the loads excite), at
    /// most 1000: a number, or a range `{min, max}` within which each run (and each sweep
    /// point) chooses H by the truncation estimate and `tolerance`. Linear scenes solve the
    /// harmonics their loads excite. Required.
    pub(super) harmonics: RawHarmonics,
    /// With a range of harmonics: the relative change of the answer (the contact nodes'
    /// vibration and the mean contact force) from one H to the next below which H is
    /// settled, in (0, 0.5]. Default: 0.01.
    #[serde(default)]
    pub(super) tolerance: Option<f64>,
    /// Time samples N per period for the contact terms, > 2·harmonics, at most 1000000.
    /// Default: 16·H, at least 64 (1 for H = 0). With a spline basis: a multiple of its
    /// segments S with at least degree + 1 per segment (Gauss points in each segment); default
    /// 8·S.
    #[serde(default)]
    pub(super) samples: Option<usize>,
    /// The contact solver's settings. Default: each key's default.
    #[serde(default)]
    pub(super) solver: Option<RawSolver>,
    /// The time basis of one period: `fourier` (harmonics 0..H) or
    /// `{spline: {degree, segments}}` (uniform periodic B-splines; no sweeps yet).
    /// Default: fourier.
    #[serde(
        default,
        deserialize_with = "serde_yaml::with::singleton_map::deserialize"
    )]
    #[schemars(with = "Option<RawBasis>")]
    pub(super) basis: Option<RawBasis>,
}

/// `harmonic_balance.harmonics`: one H, or a range to choose from.
#[derive(Deserialize, JsonSchema)]
#[serde(untagged)]
pub(super) enum RawHarmonics {
    /// The highest harmonic H (≥ every harmonic the loads excite), at most 1000, fixed.
    Fixed(usize),
    /// H chosen between `min` and `max` (Fourier basis, frictionless contact).
    Range(RawHarmonicRange),
}

/// A range of harmonics: the first level solved is `min`, then 2·min, 4·min, … up to `max`.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct RawHarmonicRange {
    /// The first H tried, ≥ 1.
    pub(super) min: usize,
    /// The largest H tried, ≥ min, at most 1000.
    pub(super) max: usize,
}

/// The time basis, written `fourier` or `{spline: {degree: 3, segments: 32}}`.
#[derive(Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schemars(rename = "TimeBasis")]
pub(super) enum RawBasis {
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

/// An obstacle, written as a one-key mapping: `{curve: NAME}`, `{line: {point, normal}}`,
/// `{circle: {center, radius, body_inside}}` (rigid), or `{body: NAME}` (another body).
#[derive(Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
#[schemars(rename = "Obstacle")]
pub(super) enum RawObstacle {
    /// A curve of the geometry: a gmsh physical group meshed as line elements only, sharing
    /// no node with the body.
    Curve(String),
    /// A boundary curve of another meshed body (a gmsh physical group of edges on a second
    /// surface): elastic–elastic contact, each node of `contact.boundary` paired with its
    /// closest point on this curve in the reference configuration (node to segment). Both
    /// sides move; both get the contact fields.
    Body(String),
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
        /// An out-of-round circle turning once per period about its centre relative to the
        /// body (a casing seen from a blade rotating at the drive frequency): radius
        /// R + amplitude·cos(count·(θ + ωt) + phase) at polar angle θ. Default: round.
        #[serde(default)]
        lobes: Option<RawLobes>,
    },
}

/// The lobes of an out-of-round circle obstacle.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Lobes")]
pub(super) struct RawLobes {
    /// The number of lobes n, 1 to 1000: the gap varies at harmonic n of the drive frequency,
    /// which harmonic_balance.harmonics must reach. Required.
    pub(super) count: usize,
    /// The radial amplitude δ of the lobes, a length ≥ 0, below the circle's radius.
    /// Required.
    pub(super) amplitude: f64,
    /// The lobes' phase φ, in radians. Default: 0.
    #[serde(default)]
    pub(super) phase: f64,
}

/// A rigid obstacle's prescribed translation d(t) = static + Σ_k (cos_k cos kωt + sin_k sin
/// kωt): each contact node's gap changes by n·d(t).
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "ObstacleMotion")]
pub(super) struct RawObstacleMotion {
    /// A constant offset [x, y] of the obstacle, a length. Default: [0, 0].
    #[serde(default, rename = "static")]
    pub(super) static_part: Option<[f64; 2]>,
    /// The harmonic part, `{k, cos: [x, y], sin: [x, y]}` in lengths. Default: none.
    #[serde(default)]
    pub(super) harmonics: Vec<RawHarmonic2>,
}

/// The mass model of a contact scene.
#[derive(Deserialize, JsonSchema, Default, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "ContactMass")]
pub(super) enum RawMass {
    /// Lumped mass with the contact nodes' mass moved to their neighbours (total mass and
    /// centre of mass kept): the default.
    #[default]
    Redistributed,
    /// Plain lumped mass: contact nodes keep their inertia (impacts; shows why redistribution
    /// is needed).
    Lumped,
}

/// Frictionless unilateral contact of body boundaries with rigid obstacles or other bodies:
/// one pair (`boundary`, `obstacle`, `search_distance`, `motion`) or several (`pairs`).
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Contact")]
pub(super) struct RawContact {
    /// The body's boundary curve group whose nodes may touch the obstacle. Required unless
    /// `pairs` is given.
    #[serde(default)]
    pub(super) boundary: Option<String>,
    /// The obstacle: `{curve: NAME}`, `{line: {point: [x, y], normal: [x, y]}}`,
    /// `{circle: {center: [x, y], radius: R, body_inside: BOOL}}` (rigid), or `{body: NAME}`
    /// (a boundary curve of another meshed body). Required unless `pairs` is given.
    #[serde(
        default,
        deserialize_with = "serde_yaml::with::singleton_map::deserialize"
    )]
    #[schemars(with = "Option<RawObstacle>")]
    pub(super) obstacle: Option<RawObstacle>,
    /// Drop candidate nodes whose initial gap exceeds this length, > 0. Default: keep all.
    #[serde(default)]
    pub(super) search_distance: Option<f64>,
    /// `redistributed` (contact nodes carry no inertia) or `lumped`. Default: `redistributed`.
    #[serde(default)]
    pub(super) mass: RawMass,
    /// Accept contact nodes that start inside the obstacle deeper than 0.1% of the body's size
    /// (a deliberate interference or preload). Default: false (refused, exit code 2: usually an
    /// obstacle on the wrong side of the body or a unit slip).
    #[serde(default)]
    pub(super) allow_initial_penetration: bool,
    /// A rigid obstacle's periodic translation (a shaker table, a moving stop): `{static: [x,
    /// y], harmonics: [{k, cos: [x, y], sin: [x, y]}]}`, lengths. Default: fixed. Not with a
    /// `body` obstacle (move that body by its own loads or supports).
    #[serde(default)]
    pub(super) motion: Option<RawObstacleMotion>,
    /// Coulomb friction `{coefficient: μ}` at every contact node (a pair's own `friction`
    /// overrides it). Default: frictionless.
    #[serde(default)]
    pub(super) friction: Option<RawFriction>,
    /// Several contact pairs (a blade tip and its shroud, a joint's two faces, a beam between
    /// two stops), each `{boundary, obstacle, search_distance, motion, friction}` as above, in
    /// place of the single pair's keys; `mass`, `allow_initial_penetration` and `friction`
    /// hold for all.
    #[serde(default)]
    pub(super) pairs: Option<Vec<RawPair>>,
}

/// Coulomb friction of a contact pair.
#[derive(Clone, Copy, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Friction")]
pub(super) struct RawFriction {
    /// The friction coefficient μ, in [0, 10]. Required.
    pub(super) coefficient: f64,
}

/// One contact pair of `contact.pairs`.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "ContactPair")]
pub(super) struct RawPair {
    /// The body's boundary curve group whose nodes may touch this obstacle. Required.
    pub(super) boundary: String,
    /// The obstacle, as `contact.obstacle`. Required.
    #[serde(with = "serde_yaml::with::singleton_map")]
    #[schemars(with = "RawObstacle")]
    pub(super) obstacle: RawObstacle,
    /// As `contact.search_distance`, for this pair. Default: keep all.
    #[serde(default)]
    pub(super) search_distance: Option<f64>,
    /// As `contact.motion`, for this pair's rigid obstacle. Default: fixed.
    #[serde(default)]
    pub(super) motion: Option<RawObstacleMotion>,
    /// As `contact.friction`, for this pair. Default: `contact.friction`.
    #[serde(default)]
    pub(super) friction: Option<RawFriction>,
}

/// Settings of `hbcontact transient`.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Transient")]
pub(super) struct RawTransient {
    /// Stop when the state at the start of two successive periods differs by less than this
    /// (relative), in (0, 1e-2]: a state that changes by more than 1% per period is not
    /// periodic. Default: 1e-6.
    #[serde(default)]
    pub(super) periodic_tolerance: Option<f64>,
    /// The most periods marched (0 counts as 1). Default: 2000.
    #[serde(default)]
    pub(super) max_periods: Option<usize>,
    /// Fraction of the stable time step used, in (0, 1]. Default: 0.8.
    #[serde(default)]
    pub(super) courant: Option<f64>,
    /// Where the marching starts: `rest`; `harmonic_balance` (the harmonic-balance
    /// solution of the same discrete model at t = 0); or `previous` (the end state the last
    /// `hbcontact transient` of this pipeline wrote to its output directory, `end_state.json`:
    /// a brute-force sweep changes the frequency and starts where the last run ended);
    /// `{rigid: {group, displacement: [x, y], velocity: [x, y]}}` (a rigid offset and velocity
    /// of a group's nodes, or of every node, at t = 0); or `{state: FILE}` (an
    /// `end_state.json` of an earlier `hbcontact transient` of the same mesh, relative to this
    /// file). Default: `rest`.
    #[serde(
        default,
        deserialize_with = "serde_yaml::with::singleton_map::deserialize"
    )]
    #[schemars(with = "Option<RawStart>")]
    pub(super) start: Option<RawStart>,
    /// With `start: harmonic_balance` or `previous`, scale the starting state by 1 + this (a perturbation
    /// that shows whether the state is kept or left), |·| ≤ 1. Default: 0.
    #[serde(default)]
    pub(super) perturbation: Option<f64>,
}

/// The stability check: is the harmonic-balance state one the structure settles into?
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Stability")]
pub(super) struct RawStability {
    /// Judge contact scenes' states (a linear scene's verdict follows from its damping, a
    /// static one has none). Default: true.
    #[serde(default)]
    pub(super) check: Option<bool>,
    /// `floquet` (the default): the Floquet multipliers of the harmonic-balance state on its
    /// own discrete model (Hill's method on the Fourier basis, docs/method.md §15), with the
    /// kind of loss of stability; `march`: time marching from the perturbed state (another
    /// discretization: diagonal mass, explicit steps); `both`: Floquet's verdict audited by
    /// marching, disagreements flagged.
    #[serde(default)]
    pub(super) method: Option<super::StabilityMethod>,
    /// The most periods marched per check (it ends early once the verdict is clear), ≥ 1.
    /// Default: 200.
    #[serde(default)]
    pub(super) max_periods: Option<usize>,
    /// The starting state is the harmonic-balance state scaled by 1 + this, in (0, 0.5].
    /// Default: 0.001.
    #[serde(default)]
    pub(super) perturbation: Option<f64>,
    /// In a sweep, check every this many points (folds' neighbours are always checked), ≥ 1.
    /// Default: 1.
    #[serde(default)]
    pub(super) every: Option<usize>,
    /// Wall-time budget of one check's marching [s], > 0; a check that reaches it gives the
    /// verdict the periods so far allow (often `undecided`). Default: 60.
    #[serde(default)]
    pub(super) max_seconds: Option<f64>,
}

/// Where time marching starts: `rest`, `harmonic_balance`, `previous`, or a one-key mapping
/// `{rigid: {group, displacement, velocity}}` or `{state: FILE}`.
#[derive(Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum RawStart {
    Rest,
    HarmonicBalance,
    Previous,
    /// A rigid offset and velocity of a group's nodes (every node when no group is named) at
    /// t = 0, the rest of the model at rest: a body thrown at a stop, an impact with a known
    /// initial state.
    Rigid(RawRigidStart),
    /// An `end_state.json` that an earlier `hbcontact transient` of the same mesh and
    /// boundary conditions wrote (any output directory), relative to this file.
    State(PathBuf),
}

/// A rigid initial motion.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "RigidStart")]
pub(super) struct RawRigidStart {
    /// The physical group whose nodes move (a surface: a whole body). Default: every node.
    #[serde(default)]
    pub(super) group: Option<String>,
    /// The offset [x, y] (lengths) added to the nodes' displacement at t = 0. Default: 0.
    #[serde(default)]
    pub(super) displacement: Option<[f64; 2]>,
    /// The velocity [x, y] (lengths/s) of the nodes at t = 0. Default: 0.
    #[serde(default)]
    pub(super) velocity: Option<[f64; 2]>,
}

/// Settings of `hbcontact sweep`: the fundamental frequency runs from `from` to `to` along the
/// response curve (through its folds), in arc-length steps measured with the frequency span
/// as 1.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Sweep")]
pub(super) struct RawSweep {
    /// Start frequency [Hz], > 0 and at most 1e9 (the curve starts with a single-frequency
    /// solve there).
    pub(super) from: f64,
    /// End frequency [Hz], > 0 and at most 1e9, ≠ from (below `from` sweeps down).
    pub(super) to: f64,
    /// Initial arc-length step, a fraction of the span, in (0, 1]. Default: 0.01.
    #[serde(default)]
    pub(super) step: Option<f64>,
    /// Smallest step before the sweep stops with a diagnosis, > 0. Default: 1e-5.
    #[serde(default)]
    pub(super) min_step: Option<f64>,
    /// Largest step, ≥ step. Default: 0.05.
    #[serde(default)]
    pub(super) max_step: Option<f64>,
    /// At most this many points, ≥ 2 and at most 100000. Default: 500.
    #[serde(default)]
    pub(super) max_points: Option<usize>,
    /// Largest relative change of the contact gaps (without contact: of the response) from
    /// one point to the next, > 0. Default: 0.1.
    #[serde(default)]
    pub(super) max_change: Option<f64>,
    /// Largest angle [degrees] by which one step may turn the curve from the last point's
    /// direction, in (0, 180): a step that turns it more is halved (down to a few smallest
    /// steps, where a kink of the sampled contact law turns it for real). Default: no limit;
    /// a sweep that then stops (no next point, or running back onto its own curve) is swept
    /// again from its start with 60.
    #[serde(default)]
    pub(super) max_turn: Option<f64>,
    /// Frequencies [Hz] (within the range) at which the full VTU series of a `run` is written,
    /// at the point of the curve nearest each, into `points/at_<f>Hz/`. Default: none (the
    /// folds and the peak are always written).
    #[serde(default)]
    pub(super) write_at: Vec<f64>,
    /// Write every n-th point of the curve as a frame of `frames.pvd` (0: none). Default: 1.
    #[serde(default)]
    pub(super) save_every: Option<usize>,
    /// Take the frames (ω-dependent factorizations) from a reduced model of the stiffness and
    /// mass pencil where the scene is small enough in contact nodes for it to pay; every point
    /// from it is checked against the harmonic-balance equations (backward error 1e-10) and
    /// re-solved on factorizations where it fails. false factors every frame (a curve exact to
    /// round-off; slower). Default: true.
    #[serde(default)]
    pub(super) reduced_frames: Option<bool>,
    /// After the curve, follow the period-doubled (2T) branch from each period doubling the
    /// stability check locates on it (harmonic balance at half the drive frequency, started
    /// along the period doubling's Floquet vector), to where it rejoins the curve or leaves
    /// the range. Needs Hill's check (frictionless contact, Fourier basis). Default: false.
    #[serde(default)]
    pub(super) follow_period_doubling: Option<bool>,
}

/// A field written to the VTU snapshots.
#[derive(Deserialize, JsonSchema, Clone, Copy)]
#[serde(rename_all = "snake_case")]
#[schemars(rename = "Field")]
pub(super) enum RawField {
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
    /// `contact_force_series` (contact scenes), and with friction `contact_tangential_force`,
    /// `contact_slip`, `contact_slip_velocity`, `contact_friction_energy`.
    Contact,
}

/// What is written and where.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "Output")]
pub(super) struct RawOutput {
    /// The results directory of `hbcontact run` (relative to the working directory);
    /// `transient`, `sweep`, `modes` and `accuracy` write beside it, appending `-transient`,
    /// `-sweep`, `-modes` and `-accuracy`; a command's `--out` names its folder instead.
    /// Default: `output/<name>`.
    #[serde(default)]
    pub(super) directory: Option<PathBuf>,
    /// Snapshots written over one period (also the transient's samples per period), ≥ 1.
    /// Default: 24.
    #[serde(default)]
    #[schemars(range(min = 1))]
    pub(super) frames: Option<usize>,
    /// The most frames `output.frames` may ask for (a guard against typos that would write
    /// millions of files), ≥ 1. Default: 10000.
    #[serde(default)]
    #[schemars(range(min = 1))]
    pub(super) max_frames: Option<usize>,
    /// The fields written to the snapshots. Default: all six.
    #[serde(default)]
    pub(super) fields: Option<Vec<RawField>>,
    /// Node groups whose displacement histories go to `probes.csv`. Default: none.
    #[serde(default)]
    pub(super) probes: Vec<String>,
    /// Draw the run's plots (`plots/`: probe displacement, total contact force, contact
    /// pressure at the peak; SVG and PNG). Default: true.
    #[serde(default)]
    pub(super) plots: Option<bool>,
}

/// The JSON Schema (draft 07) of the pipeline YAML, generated from the types above.
pub(super) fn raw_schema() -> schemars::Schema {
    schemars::generate::SchemaSettings::draft07()
        .into_generator()
        .into_root_schema_for::<RawPipeline>()
}
