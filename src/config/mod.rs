//! Pipeline configuration: the YAML a user writes (`raw`, serde types with unknown keys denied)
//! and the validated `Pipeline` the stages consume (this file), whose invariants hold by
//! construction: positive material constants, N > 2H, existing geometry file, and so on.

pub mod limits;
pub mod raw;
mod read;
pub mod schema;
mod validate;

use std::collections::BTreeMap;
use std::path::PathBuf;

pub use read::{load_pipeline, parse_pipeline};
pub use schema::pipeline_schema;
pub(crate) use validate::config_error;

/// Default of `geometry.max_aspect_ratio`, above which a mesh is refused
/// (`pipeline::sanity`).
pub const DEFAULT_MAX_ASPECT: f64 = 1e3;

/// A validated pipeline.
#[derive(Clone, Debug)]
pub struct Pipeline {
    pub name: String,
    /// The YAML file it came from (for messages).
    pub source: PathBuf,
    /// The `--set KEY=VALUE` overrides applied to it, in order (for the commands hints repeat).
    pub overrides: Vec<String>,
    pub geometry: Geometry,
    pub material: MaterialSpec,
    pub boundaries: Boundaries,
    /// Rayleigh damping D = αM + βK; `None` when the scene has none.
    pub damping: Option<Rayleigh>,
    pub harmonic_balance: HarmonicBalance,
    pub contact: Option<ContactSpec>,
    pub transient: TransientSpec,
    /// `hbcontact sweep`'s range and steps; `None` when the pipeline has no `sweep` block.
    pub sweep: Option<SweepSpec>,
    pub stability: StabilitySpec,
    pub output: OutputSpec,
}

#[derive(Clone, Debug)]
pub struct Geometry {
    /// Absolute or cwd-relative path of the `.geo` (or a ready `.msh`).
    pub file: PathBuf,
    /// Passed to gmsh as `-setnumber name value`, in name order.
    pub parameters: BTreeMap<String, f64>,
    /// Target mesh size (gmsh `-clmax`); `None` leaves the .geo's own sizes.
    pub mesh_size: Option<f64>,
    /// Element order, 1 or 2.
    pub order: u8,
    /// Recombine triangles into quadrilaterals.
    pub quads: bool,
    /// Explicit gmsh executable; otherwise `.venv/bin/gmsh`, then `PATH`.
    pub gmsh: Option<PathBuf>,
    /// Refuse to mesh beyond this estimated number of elements.
    pub max_elements: u64,
    /// Time limit of one gmsh run, in seconds.
    pub gmsh_timeout: f64,
    /// Refuse cells whose aspect ratio exceeds this (`pipeline::sanity`).
    pub max_aspect_ratio: f64,
    /// Accept a mesh of several disconnected parts.
    pub allow_disconnected: bool,
    /// Let gmsh read the `.geo` without the scan for statements that run programs or touch
    /// other files (`mesh::guard`). Never read from a file: only `--trust-geometry` sets it.
    pub trusted: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlaneModelSpec {
    PlaneStrain,
    PlaneStress,
}

#[derive(Clone, Debug)]
pub struct MaterialSpec {
    pub youngs_modulus: f64,
    pub poisson_ratio: f64,
    pub density: f64,
    pub model: PlaneModelSpec,
    pub thickness: f64,
}

/// A periodic signal: static part plus Fourier content, per component where it is a vector.
#[derive(Clone, Debug, PartialEq)]
pub struct Signal<const C: usize> {
    pub static_part: [f64; C],
    /// (harmonic index k ≥ 1, cos amplitude, sin amplitude): value(t) = static + Σ cos·cos(kωt) + sin·sin(kωt).
    pub harmonics: Vec<(usize, [f64; C], [f64; C])>,
}

impl<const C: usize> Default for Signal<C> {
    fn default() -> Self {
        Signal {
            static_part: [0.0; C],
            harmonics: Vec::new(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadKind {
    /// Force per unit area on an edge group (times the thickness).
    Traction,
    /// A total force shared equally by the nodes of the group.
    Force,
}

#[derive(Clone, Debug)]
pub struct LoadSpec {
    pub group: String,
    pub kind: LoadKind,
    pub signal: Signal<2>,
}

#[derive(Clone, Debug)]
pub struct PrescribedSpec {
    pub group: String,
    /// 0 = x, 1 = y.
    pub component: usize,
    pub signal: Signal<1>,
}

#[derive(Clone, Debug, Default)]
pub struct Boundaries {
    /// Groups with both displacement components held at zero.
    pub fixed: Vec<String>,
    pub prescribed: Vec<PrescribedSpec>,
    pub loads: Vec<LoadSpec>,
    /// Gravity's acceleration [x, y] (a static body force ρg), if any.
    pub gravity: Option<[f64; 2]>,
    /// Rotation about an axis normal to the plane (the rotating frame), if any.
    pub rotation: Option<Rotation>,
}

/// The rotating frame: speed Ω [rad/s] about `center`, and which of its effects are simulated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    pub speed: RotationSpeed,
    pub center: [f64; 2],
    pub centrifugal: bool,
    pub spin_softening: bool,
    /// The Coriolis force 2ΩMJu̇ (the sense of rotation matters: Ω > 0 counter-clockwise).
    pub coriolis: bool,
}

/// How fast the frame turns: at a fixed speed, or tied to the fundamental frequency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RotationSpeed {
    /// Ω [rad/s], whatever the frequency.
    Fixed(f64),
    /// Ω = τ ω: τ turns per period (a sweep sweeps the speed with the frequency).
    TurnsPerPeriod(f64),
}

impl Rotation {
    /// Ω [rad/s] at the fundamental frequency `frequency_hz`.
    pub fn speed_at(&self, frequency_hz: f64) -> f64 {
        match self.speed {
            RotationSpeed::Fixed(w) => w,
            RotationSpeed::TurnsPerPeriod(t) => t * 2.0 * std::f64::consts::PI * frequency_hz,
        }
    }

    /// τ when the speed follows the frequency (Ω = τ ω).
    pub fn turns_per_period(&self) -> Option<f64> {
        match self.speed {
            RotationSpeed::Fixed(_) => None,
            RotationSpeed::TurnsPerPeriod(t) => Some(t),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rayleigh {
    pub alpha: f64,
    pub beta: f64,
}

#[derive(Clone, Debug)]
pub struct HarmonicBalance {
    /// Fundamental frequency in Hz (ω = 2π f).
    pub frequency: f64,
    /// Highest harmonic H kept in the contact solve (the linear solve keeps the loads' harmonics);
    /// with a range, the smallest H tried.
    pub harmonics: usize,
    /// The largest H tried (`harmonics` when H is fixed).
    pub harmonics_max: usize,
    /// The relative change of the answer that settles H within a range.
    pub tolerance: f64,
    /// Time samples per period for the contact terms; `None` = the default (16 H, at least 64).
    pub samples: Option<usize>,
    pub solver: SolverSpec,
    /// The time basis (`fourier` unless the pipeline asks for splines).
    pub basis: BasisSpec,
}

/// The time basis of a harmonic-balance solve, as validated (`hbm::basis` builds it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BasisSpec {
    #[default]
    Fourier,
    /// Uniform periodic B-splines of degree 2 … 7 on `segments` ≥ degree + 1 segments.
    Spline { degree: usize, segments: usize },
}

#[derive(Clone, Debug)]
pub struct SolverSpec {
    /// Relative tolerance on the complementarity residual.
    pub tolerance: f64,
    pub max_iterations: usize,
    /// The complementarity parameter c as a multiple of the automatic scale 1/mean|G_0,ii|.
    pub c_scale: f64,
    /// Wall-time budget of the contact solve [s].
    pub max_seconds: f64,
}

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec {
            tolerance: 1e-8,
            max_iterations: 200,
            c_scale: 1.0,
            max_seconds: 3600.0,
        }
    }
}

/// An obstacle: rigid, or another meshed body's boundary.
#[derive(Clone, Debug, PartialEq)]
pub enum ObstacleSpec {
    /// A curve of the geometry (a physical group meshed as 1-D elements only).
    Curve { group: String },
    /// The half-plane behind the line through `point`; `normal` points out of the obstacle,
    /// into the free space where the body is.
    Line { point: [f64; 2], normal: [f64; 2] },
    /// A circle; `body_inside` = the body lies inside it (a casing), else outside (a cylinder);
    /// `lobes` makes it out of round and turning once per period relative to the body.
    Circle {
        center: [f64; 2],
        radius: f64,
        body_inside: bool,
        lobes: Option<Lobes>,
    },
    /// The boundary curve of another meshed body (elastic–elastic contact, node to segment).
    Body { group: String },
}

/// Radius R + amplitude·cos(count·(θ + ωt) + phase) at polar angle θ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobes {
    pub count: usize,
    pub amplitude: f64,
    pub phase: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactMass {
    /// Contact nodes carry no inertia (Khenous–Laborde–Renard); total mass and centre of mass kept.
    Redistributed,
    /// Plain lumped mass (kept to show why redistribution is needed).
    Lumped,
}

#[derive(Clone, Debug)]
pub struct ContactSpec {
    /// The contact pairs (one for `contact.boundary` and `contact.obstacle`).
    pub pairs: Vec<ContactPair>,
    pub mass: ContactMass,
    /// Accept nodes that start deeper inside the obstacle than a small strain of the body
    /// (`pipeline::sanity::check_initial_penetration`).
    pub allow_initial_penetration: bool,
}

/// One body boundary against one obstacle.
#[derive(Clone, Debug)]
pub struct ContactPair {
    /// The body boundary whose nodes are contact candidates.
    pub boundary: String,
    pub obstacle: ObstacleSpec,
    /// Candidates farther than this from the obstacle are dropped; `None` keeps all.
    pub search_distance: Option<f64>,
    /// A rigid obstacle's translation d(t) (`None`: fixed).
    pub motion: Option<Signal<2>>,
    /// The Coulomb friction coefficient μ (0: frictionless).
    pub friction: f64,
    /// The pipeline key of this pair: `contact` or `contact.pairs[i]`.
    pub key: String,
}

impl ContactSpec {
    /// The harmonics the obstacles' gaps vary at, each with the key that sets it (every
    /// pair's, `ContactPair::gap_harmonics`).
    pub fn gap_harmonics(&self) -> impl Iterator<Item = (String, usize)> + '_ {
        self.pairs.iter().flat_map(ContactPair::gap_harmonics)
    }
}

impl ContactPair {
    /// The harmonics this pair's obstacle gap varies at, each with the key that sets it: the
    /// translation's (`motion`) and a lobed circle's count.
    pub fn gap_harmonics(&self) -> impl Iterator<Item = (String, usize)> + '_ {
        let moving = self.motion.iter().flat_map(|m| &m.harmonics);
        let lobes = match &self.obstacle {
            ObstacleSpec::Circle { lobes: Some(l), .. } => Some(l.count),
            _ => None,
        };
        moving
            .map(|h| (format!("{}.motion", self.key), h.0))
            .chain(lobes.map(|k| (format!("{}.obstacle.circle.lobes", self.key), k)))
    }
}

#[derive(Clone, Debug)]
pub struct TransientSpec {
    /// Stop when two successive periods differ by less than this (relative).
    pub periodic_tolerance: f64,
    pub max_periods: usize,
    /// Fraction of the stable time step used.
    pub courant: f64,
    pub start: TransientStart,
    /// With `start: HarmonicBalance`, the starting state is scaled by 1 + this.
    pub perturbation: f64,
}

/// How contact states are judged.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum StabilityMethod {
    /// Floquet multipliers of the harmonic-balance state on its own discrete model: Hill's
    /// method on the Fourier basis, the monodromy of a modal reduction on splines
    /// (docs/method.md §15).
    #[default]
    Floquet,
    /// Time marching from the perturbed state (the diagonal-mass explicit model).
    March,
    /// Floquet's verdict, audited by time marching: disagreements are flagged.
    Both,
}

/// The stability check of `run` and the sweep points.
#[derive(Clone, Debug)]
pub struct StabilitySpec {
    /// Judge contact scenes (`method`).
    pub check: bool,
    pub method: StabilityMethod,
    pub max_periods: usize,
    /// The start state is scaled by 1 + this.
    pub perturbation: f64,
    /// In a sweep, every this many points.
    pub every: usize,
    /// Wall-time budget of one march [s]; beyond it the verdict is what the periods so far say.
    pub max_seconds: f64,
}

impl Default for StabilitySpec {
    fn default() -> Self {
        StabilitySpec {
            check: true,
            method: StabilityMethod::Floquet,
            max_periods: 200,
            perturbation: 1e-3,
            every: 1,
            max_seconds: 60.0,
        }
    }
}

/// Where time marching starts.
#[derive(Clone, Debug, PartialEq)]
pub enum TransientStart {
    Rest,
    /// The harmonic-balance solution of the same discrete model, at t = 0.
    HarmonicBalance,
    /// The end state of the last time marching written to the same output directory
    /// (`end_state.json`): a brute-force sweep starts each frequency where the last ended.
    Previous,
    /// A rigid offset and velocity of a group's nodes (`None`: every node), the rest at rest.
    Rigid {
        group: Option<String>,
        displacement: [f64; 2],
        velocity: [f64; 2],
    },
    /// An `end_state.json` of an earlier marching of the same model (resolved path).
    State(PathBuf),
}

impl TransientStart {
    /// The name the pipeline and the summary use.
    pub fn name(&self) -> &'static str {
        match self {
            TransientStart::Rest => "rest",
            TransientStart::HarmonicBalance => "harmonic_balance",
            TransientStart::Previous => "previous",
            TransientStart::Rigid { .. } => "rigid",
            TransientStart::State(_) => "state",
        }
    }
}

impl Default for TransientSpec {
    fn default() -> Self {
        TransientSpec {
            periodic_tolerance: 1e-6,
            max_periods: 2000,
            courant: 0.8,
            start: TransientStart::Rest,
            perturbation: 0.0,
        }
    }
}

/// A frequency sweep: the range [Hz] and the arc-length steps (fractions of the span).
#[derive(Clone, Debug)]
pub struct SweepSpec {
    pub from_hz: f64,
    pub to_hz: f64,
    pub step: f64,
    pub min_step: f64,
    pub max_step: f64,
    pub max_points: usize,
    pub max_change: f64,
    /// Largest turn of the curve in one step [degrees] (`None`: no limit, and a sweep that
    /// stops at a dead end or on its own trail is swept again with `sweep::RETRY_TURN`).
    pub max_turn: Option<f64>,
    /// Frequencies [Hz] whose nearest point gets the full VTU series of a run.
    pub write_at: Vec<f64>,
    /// Every n-th point is a frame of `frames.pvd` (0: none).
    pub save_every: usize,
    /// Frames from a reduced model of the pencil where it pays (false: factor every frame).
    pub reduced_frames: bool,
    /// Follow the 2T branch from each located period doubling (`sweep::branch`).
    pub follow_period_doubling: bool,
}

impl Default for SweepSpec {
    fn default() -> Self {
        SweepSpec {
            from_hz: 0.0,
            to_hz: 0.0,
            step: 0.01,
            min_step: 1e-5,
            max_step: 0.05,
            max_points: 500,
            max_change: 0.1,
            max_turn: None,
            write_at: Vec::new(),
            save_every: 1,
            reduced_frames: true,
            follow_period_doubling: false,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum FieldName {
    Displacement,
    Velocity,
    Acceleration,
    Stress,
    VonMises,
    Contact,
}

#[derive(Clone, Debug)]
pub struct OutputSpec {
    pub directory: PathBuf,
    /// Snapshots written over one period.
    pub frames: usize,
    pub fields: Vec<FieldName>,
    /// Named node groups whose displacement is reported as probe time histories.
    pub probes: Vec<String>,
    /// Draw the run's plots into `plots/`.
    pub plots: bool,
}
