//! The YAML schema as written by users, and its validation into `Pipeline`.
//!
//! serde_yaml (deprecated upstream, still working) stays behind this file so that a move to a
//! maintained fork is a one-line change.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_yaml::Value;

use super::*;
use crate::{Error, Result};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPipeline {
    name: String,
    geometry: RawGeometry,
    material: RawMaterial,
    #[serde(default)]
    boundaries: RawBoundaries,
    #[serde(default)]
    damping: Option<RawDamping>,
    harmonic_balance: RawHarmonicBalance,
    #[serde(default)]
    contact: Option<RawContact>,
    #[serde(default)]
    transient: Option<RawTransient>,
    #[serde(default)]
    output: Option<RawOutput>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGeometry {
    file: PathBuf,
    #[serde(default)]
    parameters: BTreeMap<String, f64>,
    #[serde(default)]
    mesh_size: Option<f64>,
    #[serde(default)]
    order: Option<u8>,
    #[serde(default)]
    quads: bool,
    #[serde(default)]
    gmsh: Option<PathBuf>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum RawPlaneModel {
    PlaneStrain,
    PlaneStress,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    youngs_modulus: f64,
    poisson_ratio: f64,
    density: f64,
    model: RawPlaneModel,
    #[serde(default)]
    thickness: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawBoundaries {
    #[serde(default)]
    fixed: Vec<String>,
    #[serde(default)]
    prescribed: Vec<RawPrescribed>,
    #[serde(default)]
    loads: Vec<RawLoad>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum RawComponent {
    X,
    Y,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHarmonic1 {
    k: usize,
    #[serde(default)]
    cos: f64,
    #[serde(default)]
    sin: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPrescribed {
    group: String,
    component: RawComponent,
    #[serde(default, rename = "static")]
    static_part: f64,
    #[serde(default)]
    harmonics: Vec<RawHarmonic1>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum RawLoadKind {
    Traction,
    Force,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHarmonic2 {
    k: usize,
    #[serde(default)]
    cos: [f64; 2],
    #[serde(default)]
    sin: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLoad {
    group: String,
    #[serde(rename = "type")]
    kind: RawLoadKind,
    #[serde(default, rename = "static")]
    static_part: Option<[f64; 2]>,
    #[serde(default)]
    harmonics: Vec<RawHarmonic2>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDamping {
    #[serde(default)]
    alpha: f64,
    #[serde(default)]
    beta: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSolver {
    #[serde(default)]
    tolerance: Option<f64>,
    #[serde(default)]
    max_iterations: Option<usize>,
    #[serde(default)]
    c_scale: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHarmonicBalance {
    frequency: f64,
    harmonics: usize,
    #[serde(default)]
    samples: Option<usize>,
    #[serde(default)]
    solver: Option<RawSolver>,
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum RawObstacle {
    Curve(String),
    Line {
        point: [f64; 2],
        normal: [f64; 2],
    },
    Circle {
        center: [f64; 2],
        radius: f64,
        #[serde(default)]
        body_inside: bool,
    },
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum RawMass {
    #[default]
    Redistributed,
    Lumped,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawContact {
    boundary: String,
    #[serde(with = "serde_yaml::with::singleton_map")]
    obstacle: RawObstacle,
    #[serde(default)]
    search_distance: Option<f64>,
    #[serde(default)]
    mass: RawMass,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTransient {
    #[serde(default)]
    periodic_tolerance: Option<f64>,
    #[serde(default)]
    max_periods: Option<usize>,
    #[serde(default)]
    courant: Option<f64>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum RawField {
    Displacement,
    Velocity,
    Acceleration,
    Stress,
    VonMises,
    Contact,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOutput {
    #[serde(default)]
    directory: Option<PathBuf>,
    #[serde(default)]
    frames: Option<usize>,
    #[serde(default)]
    fields: Option<Vec<RawField>>,
    #[serde(default)]
    probes: Vec<String>,
}

fn config_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Config {
        path: path.to_path_buf(),
        message: message.into(),
    }
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

/// Set `a.b.c` to `value` (a YAML scalar or flow value), creating mappings on the way.
fn apply_override(root: &mut Value, spec: &str, path: &Path) -> Result<()> {
    let Some((key, value)) = spec.split_once('=') else {
        return Err(config_error(
            path,
            format!("--set {spec}: expected KEY=VALUE, e.g. --set harmonic_balance.harmonics=20"),
        ));
    };
    let parsed: Value = serde_yaml::from_str(value).map_err(|e| {
        config_error(
            path,
            format!("--set {spec}: the value is not valid YAML: {e}"),
        )
    })?;
    let mut node = root;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(config_error(
            path,
            format!("--set {spec}: empty key segment"),
        ));
    }
    for (i, part) in parts.iter().enumerate() {
        if !node.is_mapping() {
            *node = Value::Mapping(Default::default());
        }
        let Value::Mapping(map) = node else {
            unreachable!("just made a mapping")
        };
        let k = Value::String(part.to_string());
        if i + 1 == parts.len() {
            map.insert(k, parsed);
            return Ok(());
        }
        node = map.entry(k).or_insert(Value::Null);
    }
    Ok(())
}

/// Read `path`, apply `--set key.path=value` overrides, and validate.
pub fn load_pipeline(path: &Path, overrides: &[String]) -> Result<Pipeline> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| config_error(path, format!("cannot read the pipeline file: {e}")))?;
    let raw: RawPipeline = if overrides.is_empty() {
        serde_yaml::from_str(&text).map_err(|e| yaml_error(path, &e, None))?
    } else {
        let mut value: Value =
            serde_yaml::from_str(&text).map_err(|e| yaml_error(path, &e, None))?;
        for o in overrides {
            apply_override(&mut value, o, path)?;
        }
        match serde_yaml::from_value(value) {
            Ok(raw) => raw,
            Err(e) => {
                // The file itself may be at fault: then show its line and column.
                if let Err(file_error) = serde_yaml::from_str::<RawPipeline>(&text) {
                    if file_error.to_string() == e.to_string() {
                        return Err(yaml_error(path, &file_error, None));
                    }
                }
                let context = format!(
                    "with {}",
                    overrides
                        .iter()
                        .map(|o| format!("--set {o}"))
                        .collect::<Vec<_>>()
                        .join(" ")
                );
                return Err(yaml_error(path, &e, Some(&context)));
            }
        }
    };
    validate(path, raw)
}

fn positive(path: &Path, field: &str, v: f64) -> Result<f64> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(config_error(
            path,
            format!("{field} = {v} must be a positive number"),
        ))
    }
}

/// A relative path from the pipeline: next to it, then one level up (the project root for
/// `pipelines/x.yaml`), else an error naming both.
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
    let candidates = [dir.join(file), dir.join("..").join(file)];
    for c in &candidates {
        if c.exists() {
            return Ok(c.clone());
        }
    }
    Err(config_error(
        path,
        format!(
            "{field}: {} not found (tried {} and {}); paths are relative to the pipeline file or its parent directory",
            file.display(),
            candidates[0].display(),
            candidates[1].display()
        ),
    ))
}

fn validate(path: &Path, raw: RawPipeline) -> Result<Pipeline> {
    let bad = |m: String| config_error(path, m);
    if raw.name.is_empty()
        || !raw
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(bad(format!(
            "name = {:?}: use letters, digits, `_` and `-` only (it names the output directory)",
            raw.name
        )));
    }
    // Geometry.
    let g = raw.geometry;
    let order = g.order.unwrap_or(1);
    if !(1..=2).contains(&order) {
        return Err(bad(format!("geometry.order = {order}: must be 1 or 2")));
    }
    if let Some(h) = g.mesh_size {
        positive(path, "geometry.mesh_size", h)?;
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
    // Material.
    let m = raw.material;
    positive(path, "material.youngs_modulus", m.youngs_modulus)?;
    positive(path, "material.density", m.density)?;
    if !(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5) {
        return Err(bad(format!(
            "material.poisson_ratio = {} must lie in (−1, 0.5)",
            m.poisson_ratio
        )));
    }
    let thickness = positive(path, "material.thickness", m.thickness.unwrap_or(1.0))?;
    // Boundaries.
    let mut prescribed = Vec::new();
    for (i, p) in raw.boundaries.prescribed.into_iter().enumerate() {
        let mut seen = Vec::new();
        let mut harmonics = Vec::new();
        for h in p.harmonics {
            if h.k == 0 || seen.contains(&h.k) {
                return Err(bad(format!("boundaries.prescribed[{i}].harmonics: k = {} must be ≥ 1 and appear once (put the constant part in `static`)", h.k)));
            }
            seen.push(h.k);
            harmonics.push((h.k, [h.cos], [h.sin]));
        }
        prescribed.push(PrescribedSpec {
            group: p.group,
            component: match p.component {
                RawComponent::X => 0,
                RawComponent::Y => 1,
            },
            signal: Signal {
                static_part: [p.static_part],
                harmonics,
            },
        });
    }
    let mut loads = Vec::new();
    for (i, l) in raw.boundaries.loads.into_iter().enumerate() {
        let mut seen = Vec::new();
        let mut harmonics = Vec::new();
        for h in l.harmonics {
            if h.k == 0 || seen.contains(&h.k) {
                return Err(bad(format!("boundaries.loads[{i}].harmonics: k = {} must be ≥ 1 and appear once (put the constant part in `static`)", h.k)));
            }
            seen.push(h.k);
            harmonics.push((h.k, h.cos, h.sin));
        }
        if l.static_part.is_none() && harmonics.is_empty() {
            return Err(bad(format!(
                "boundaries.loads[{i}] (group {}): give a `static` part, `harmonics`, or both",
                l.group
            )));
        }
        loads.push(LoadSpec {
            group: l.group,
            kind: match l.kind {
                RawLoadKind::Traction => LoadKind::Traction,
                RawLoadKind::Force => LoadKind::Force,
            },
            signal: Signal {
                static_part: l.static_part.unwrap_or([0.0; 2]),
                harmonics,
            },
        });
    }
    let damping = match raw.damping {
        Some(d) => {
            if !(d.alpha >= 0.0 && d.beta >= 0.0) {
                return Err(bad(format!(
                    "damping: alpha = {} and beta = {} must be ≥ 0",
                    d.alpha, d.beta
                )));
            }
            Some(Rayleigh {
                alpha: d.alpha,
                beta: d.beta,
            })
        }
        None => None,
    };
    // Harmonic balance.
    let hb = raw.harmonic_balance;
    positive(path, "harmonic_balance.frequency", hb.frequency)?;
    if let Some(n) = hb.samples {
        if n <= 2 * hb.harmonics {
            return Err(bad(format!(
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
        }
        if let Some(n) = s.max_iterations {
            solver.max_iterations = n;
        }
        if let Some(c) = s.c_scale {
            solver.c_scale = positive(path, "harmonic_balance.solver.c_scale", c)?;
        }
    }
    // Contact.
    let contact = match raw.contact {
        None => None,
        Some(c) => {
            let obstacle = match c.obstacle {
                RawObstacle::Curve(group) => ObstacleSpec::Curve { group },
                RawObstacle::Line { point, normal } => {
                    let len = (normal[0] * normal[0] + normal[1] * normal[1]).sqrt();
                    if !(len > 0.0) || !len.is_finite() {
                        return Err(bad("contact.obstacle.line.normal must be a non-zero vector (pointing out of the obstacle, toward the body)".into()));
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
                    center,
                    radius: positive(path, "contact.obstacle.circle.radius", radius)?,
                    body_inside,
                },
            };
            if let Some(d) = c.search_distance {
                positive(path, "contact.search_distance", d)?;
            }
            Some(ContactSpec {
                boundary: c.boundary,
                obstacle,
                search_distance: c.search_distance,
                mass: match c.mass {
                    RawMass::Redistributed => ContactMass::Redistributed,
                    RawMass::Lumped => ContactMass::Lumped,
                },
            })
        }
    };
    let mut transient = TransientSpec::default();
    if let Some(t) = raw.transient {
        if let Some(v) = t.periodic_tolerance {
            transient.periodic_tolerance = positive(path, "transient.periodic_tolerance", v)?;
        }
        if let Some(v) = t.max_periods {
            transient.max_periods = v.max(1);
        }
        if let Some(v) = t.courant {
            if !(v > 0.0 && v <= 1.0) {
                return Err(bad(format!("transient.courant = {v} must lie in (0, 1]")));
            }
            transient.courant = v;
        }
    }
    let out = raw.output;
    let frames = out.as_ref().and_then(|o| o.frames).unwrap_or(24);
    if frames == 0 {
        return Err(bad("output.frames must be at least 1".into()));
    }
    let fields = out
        .as_ref()
        .and_then(|o| o.fields.clone())
        .map(|f| {
            f.into_iter()
                .map(|x| match x {
                    RawField::Displacement => FieldName::Displacement,
                    RawField::Velocity => FieldName::Velocity,
                    RawField::Acceleration => FieldName::Acceleration,
                    RawField::Stress => FieldName::Stress,
                    RawField::VonMises => FieldName::VonMises,
                    RawField::Contact => FieldName::Contact,
                })
                .collect()
        })
        .unwrap_or_else(|| {
            vec![
                FieldName::Displacement,
                FieldName::Velocity,
                FieldName::Acceleration,
                FieldName::Stress,
                FieldName::VonMises,
                FieldName::Contact,
            ]
        });
    let directory = out
        .as_ref()
        .and_then(|o| o.directory.clone())
        .unwrap_or_else(|| PathBuf::from("output").join(&raw.name));
    let probes = out.map(|o| o.probes).unwrap_or_default();
    Ok(Pipeline {
        name: raw.name,
        source: path.to_path_buf(),
        geometry: Geometry {
            file,
            parameters: g.parameters,
            mesh_size: g.mesh_size,
            order,
            quads: g.quads,
            gmsh,
        },
        material: MaterialSpec {
            youngs_modulus: m.youngs_modulus,
            poisson_ratio: m.poisson_ratio,
            density: m.density,
            model: match m.model {
                RawPlaneModel::PlaneStrain => PlaneModelSpec::PlaneStrain,
                RawPlaneModel::PlaneStress => PlaneModelSpec::PlaneStress,
            },
            thickness,
        },
        boundaries: Boundaries {
            fixed: raw.boundaries.fixed,
            prescribed,
            loads,
        },
        damping,
        harmonic_balance: HarmonicBalance {
            frequency: hb.frequency,
            harmonics: hb.harmonics,
            samples: hb.samples,
            solver,
        },
        contact,
        transient,
        output: OutputSpec {
            directory,
            frames,
            fields,
            probes,
        },
    })
}
