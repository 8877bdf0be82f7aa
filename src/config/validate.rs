//! Validation of the raw YAML into `Pipeline`: every field checked against its bounds (the
//! `MAX_*` limits below), defaults filled in, and an error naming the file, the field and
//! the fix.

use std::path::{Path, PathBuf};

use super::raw::*;
use super::*;
use crate::{Error, Result};

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
pub(super) fn validate(path: &Path, raw: RawPipeline) -> Result<Pipeline> {
    validate_name(path, &raw.name)?;
    let geometry = validate_geometry(path, raw.geometry)?;
    let material = validate_material(path, raw.material)?;
    let boundaries = validate_boundaries(path, raw.boundaries)?;
    let damping = validate_damping(path, raw.damping)?;
    let harmonic_balance = validate_harmonic_balance(path, raw.harmonic_balance)?;
    let contact = validate_contact(path, raw.contact)?;
    if let Some(c) = &contact {
        check_contact_harmonics(path, &boundaries, c, harmonic_balance.harmonics)?;
        check_friction(path, &boundaries, c)?;
        let friction = c.pairs.iter().find(|p| p.friction > 0.0);
        if let (Some(pair), true) = (
            friction,
            harmonic_balance.harmonics_max > harmonic_balance.harmonics,
        ) {
            return Err(config_error(path, format!(
                "harmonic_balance.harmonics: a range of harmonics is chosen on frictionless contact only, and {}.friction is set: give harmonics one value (e.g. {})",
                pair.key, harmonic_balance.harmonics_max
            )));
        }
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

/// Friction against a surface that slides past the contact nodes needs its sliding speed,
/// which is not modelled: a lobed casing (its lobes turn past the body) and a circle in a
/// turning frame (a casing at rest seen from the rotor) are refused with friction.
fn check_friction(path: &Path, b: &Boundaries, c: &ContactSpec) -> Result<()> {
    for pair in c.pairs.iter().filter(|p| p.friction > 0.0) {
        let ObstacleSpec::Circle { lobes, .. } = &pair.obstacle else {
            continue;
        };
        let why = if lobes.is_some() {
            "a lobed casing turns past the body"
        } else if b.rotation.is_some() {
            "in boundaries.rotation's turning frame a casing at rest slides past the body"
        } else {
            continue;
        };
        return Err(config_error(path, format!("{}.friction: {why}, and the sliding speed that friction depends on is not modelled; remove the friction (or the {})", pair.key, if lobes.is_some() { "lobes" } else { "rotation" })));
    }
    Ok(())
}

/// A contact solve computes harmonics 0..H only: every harmonic a load, a motion or the
/// obstacle's gap excites must be among them.
fn check_contact_harmonics(path: &Path, b: &Boundaries, c: &ContactSpec, h: usize) -> Result<()> {
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
    let gap = c.gap_harmonics();
    let all = loads.chain(motions).chain(gap);
    if let Some((field, k)) = all.max_by_key(|(_, k)| *k) {
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
    if let Some(g) = b.gravity {
        finite_all(path, "boundaries.gravity", &g)?;
    }
    let rotation = b.rotation.map(|r| validate_rotation(path, r)).transpose()?;
    Ok(Boundaries {
        fixed: b.fixed,
        prescribed,
        loads,
        gravity: b.gravity.filter(|g| *g != [0.0; 2]),
        rotation: rotation.filter(|r| {
            r.speed_at(1.0) != 0.0 && (r.centrifugal || r.spin_softening || r.coriolis)
        }),
    })
}

fn validate_rotation(path: &Path, r: RawRotation) -> Result<Rotation> {
    let field = "boundaries.rotation";
    let speed = match (r.speed, r.turns_per_period) {
        (Some(w), None) => {
            finite(path, &format!("{field}.speed"), w)?;
            RotationSpeed::Fixed(w)
        }
        (None, Some(t)) => {
            finite(path, &format!("{field}.turns_per_period"), t)?;
            RotationSpeed::TurnsPerPeriod(t)
        }
        (w, _) => {
            let what = if w.is_some() { "both" } else { "neither" };
            return Err(Error::Config {
                path: path.to_path_buf(),
                message: format!(
                    "{field}: {what} of `speed` and `turns_per_period` given; give one: `speed` (rad/s) for a fixed speed, `turns_per_period` (e.g. 1) for a speed that follows the frequency"
                ),
            });
        }
    };
    finite_all(path, &format!("{field}.center"), &r.center)?;
    Ok(Rotation {
        speed,
        center: r.center,
        centrifugal: r.centrifugal.unwrap_or(true),
        spin_softening: r.spin_softening.unwrap_or(true),
        coriolis: r.coriolis,
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
    let signal = vector_signal(path, &field, l.static_part, &l.harmonics)?;
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
        signal,
    })
}

/// A vector signal's static part and harmonics at `field`: distinct harmonic indices, finite
/// values.
fn vector_signal(
    path: &Path,
    field: &str,
    static_part: Option<[f64; 2]>,
    harmonics: &[RawHarmonic2],
) -> Result<Signal<2>> {
    let ks: Vec<usize> = harmonics.iter().map(|h| h.k).collect();
    check_harmonic_indices(path, field, &ks)?;
    if let Some(s) = static_part {
        finite_all(path, &format!("{field}.static"), &s)?;
    }
    for h in harmonics {
        let at = |part: &str| format!("{field}.harmonics (k = {}).{part}", h.k);
        finite_all(path, &at("cos"), &h.cos)?;
        finite_all(path, &at("sin"), &h.sin)?;
    }
    Ok(Signal {
        static_part: static_part.unwrap_or([0.0; 2]),
        harmonics: harmonics.iter().map(|h| (h.k, h.cos, h.sin)).collect(),
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

/// The largest `harmonic_balance.tolerance`: a change of half the answer settles nothing.
const MAX_HARMONICS_TOLERANCE: f64 = 0.5;
/// The default `harmonic_balance.tolerance`: the knob check's own threshold on c
/// (`hbm::knobs::C_TOLERANCE`).
pub const DEFAULT_HARMONICS_TOLERANCE: f64 = 0.01;

/// `harmonic_balance.harmonics` as (smallest H, largest H, tolerance): a fixed H is its own
/// range. A range needs the Fourier basis and no explicit `samples` (each H takes 16·H).
fn harmonic_range(path: &Path, hb: &RawHarmonicBalance) -> Result<(usize, usize, f64)> {
    let tolerance = match hb.tolerance {
        Some(t) if !(t > 0.0 && t <= MAX_HARMONICS_TOLERANCE) => {
            return Err(config_error(path, format!(
                "harmonic_balance.tolerance = {} must lie in (0, {MAX_HARMONICS_TOLERANCE}]: it is the relative change of the answer that settles H (default {DEFAULT_HARMONICS_TOLERANCE})",
                show(t)
            )));
        }
        Some(t) => t,
        None => DEFAULT_HARMONICS_TOLERANCE,
    };
    let (min, max) = match &hb.harmonics {
        RawHarmonics::Fixed(h) => {
            if hb.tolerance.is_some() {
                return Err(config_error(path, format!(
                    "harmonic_balance.tolerance needs a range of harmonics to choose from: write harmonics: {{min: {h}, max: {}}}, or leave tolerance out",
                    4 * h.max(&1)
                )));
            }
            if *h > MAX_HARMONICS {
                return Err(config_error(path, format!(
                    "harmonic_balance.harmonics = {h} is above the limit of {MAX_HARMONICS}: the contact solve grows as H² (and N = 16H samples); the accuracy table shows where more harmonics stop paying"
                )));
            }
            return Ok((*h, *h, tolerance));
        }
        RawHarmonics::Range(r) => (r.min, r.max),
    };
    let problem = if min == 0 {
        Some("harmonic_balance.harmonics.min = 0 must be ≥ 1: a range of harmonics chooses among 1 or more (give harmonics: 0 for a static solve)".into())
    } else if max < min {
        Some(format!("harmonic_balance.harmonics.max = {max} is below harmonic_balance.harmonics.min = {min}: use max ≥ min (e.g. {{min: {min}, max: {}}})", 4 * min))
    } else if max > MAX_HARMONICS {
        Some(format!("harmonic_balance.harmonics.max = {max} is above the limit of {MAX_HARMONICS}: the contact solve grows as H²"))
    } else if hb.samples.is_some() {
        Some("harmonic_balance.samples cannot be fixed with a range of harmonics: each H takes 16·H samples; leave samples out".into())
    } else if matches!(hb.basis, Some(RawBasis::Spline { .. })) {
        Some("harmonic_balance.harmonics: a range needs the Fourier basis (a spline basis is refined by its segments); give harmonics one value".into())
    } else {
        None
    };
    match problem {
        Some(message) => Err(config_error(path, message)),
        None => Ok((min, max, tolerance)),
    }
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
    let (harmonics, harmonics_max, tolerance) = harmonic_range(path, &hb)?;
    if let Some(n) = hb.samples {
        if n > MAX_SAMPLES {
            return Err(config_error(
                path,
                format!("harmonic_balance.samples = {n} is above the limit of {MAX_SAMPLES}"),
            ));
        }
        if n <= 2 * harmonics {
            return Err(config_error(path, format!(
                "harmonic_balance.samples = {n} must exceed 2·harmonics = {}: use at least {} (16·H = {} converges reliably)",
                2 * harmonics,
                2 * harmonics + 1,
                (16 * harmonics).max(1)
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
        harmonics,
        harmonics_max,
        tolerance,
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

fn validate_lobes(path: &Path, key: &str, l: RawLobes, radius: f64) -> Result<Lobes> {
    let field = format!("{key}.obstacle.circle.lobes");
    if l.count == 0 || l.count > MAX_HARMONICS {
        return Err(config_error(path, format!("{field}.count = {} must be in 1..={MAX_HARMONICS} (the gap varies at harmonic `count`)", l.count)));
    }
    finite(path, &format!("{field}.phase"), l.phase)?;
    if !(l.amplitude >= 0.0 && l.amplitude < radius) {
        return Err(config_error(
            path,
            format!(
                "{field}.amplitude = {} must be ≥ 0 and below the radius {radius}",
                l.amplitude
            ),
        ));
    }
    Ok(Lobes {
        count: l.count,
        amplitude: l.amplitude,
        phase: l.phase,
    })
}

fn validate_obstacle_motion(
    path: &Path,
    key: &str,
    m: RawObstacleMotion,
    obstacle: &ObstacleSpec,
) -> Result<Signal<2>> {
    let field = format!("{key}.motion");
    if matches!(obstacle, ObstacleSpec::Body { .. }) {
        return Err(config_error(path, format!("{field}: a `body` obstacle is an elastic body; move it by its own loads or boundaries.prescribed, not by {field}")));
    }
    vector_signal(path, &field, m.static_part, &m.harmonics)
}

fn validate_contact(path: &Path, contact: Option<RawContact>) -> Result<Option<ContactSpec>> {
    let Some(c) = contact else {
        return Ok(None);
    };
    let single = c.boundary.is_some() || c.obstacle.is_some();
    let pairs = match (c.pairs, c.boundary, c.obstacle) {
        (Some(_), _, _) if single || c.search_distance.is_some() || c.motion.is_some() => {
            return Err(config_error(path, "contact: give either one pair (boundary, obstacle, search_distance, motion) or `pairs`, not both: move the single pair's keys into an entry of contact.pairs".to_string()));
        }
        (Some(raw), _, _) if raw.is_empty() => {
            return Err(config_error(path, "contact.pairs is empty: give at least one {boundary, obstacle} pair, or remove the contact block".to_string()));
        }
        (Some(raw), _, _) => raw
            .into_iter()
            .enumerate()
            .map(|(i, r)| {
                let r = RawPair {
                    friction: r.friction.or(c.friction),
                    ..r
                };
                validate_pair(path, format!("contact.pairs[{i}]"), r)
            })
            .collect::<Result<Vec<_>>>()?,
        (None, Some(boundary), Some(obstacle)) => {
            let raw = RawPair {
                boundary,
                obstacle,
                search_distance: c.search_distance,
                motion: c.motion,
                friction: c.friction,
            };
            vec![validate_pair(path, "contact".to_string(), raw)?]
        }
        (None, boundary, _) => {
            let missing = if boundary.is_none() {
                "boundary"
            } else {
                "obstacle"
            };
            return Err(config_error(path, format!("contact.{missing} is required (or give contact.pairs): name the body's boundary curve group and what it touches, e.g. `boundary: tip` and `obstacle: {{curve: wall}}`")));
        }
    };
    Ok(Some(ContactSpec {
        pairs,
        allow_initial_penetration: c.allow_initial_penetration,
        mass: match c.mass {
            RawMass::Redistributed => ContactMass::Redistributed,
            RawMass::Lumped => ContactMass::Lumped,
        },
    }))
}

/// One contact pair, its errors named by `key` (`contact` or `contact.pairs[i]`).
fn validate_pair(path: &Path, key: String, c: RawPair) -> Result<ContactPair> {
    group_name(path, &format!("{key}.boundary"), &c.boundary)?;
    let obstacle = validate_obstacle(path, &key, c.obstacle, &c.boundary)?;
    let motion = c
        .motion
        .map(|m| validate_obstacle_motion(path, &key, m, &obstacle))
        .transpose()?;
    if let Some(d) = c.search_distance {
        positive(path, &format!("{key}.search_distance"), d)?;
    }
    let friction = c.friction.map_or(0.0, |f| f.coefficient);
    if !(0.0..=10.0).contains(&friction) {
        return Err(config_error(path, format!("{key}.friction.coefficient = {friction} must be in [0, 10] (steel on steel is about 0.15–0.6)")));
    }
    Ok(ContactPair {
        boundary: c.boundary,
        obstacle,
        search_distance: c.search_distance,
        motion,
        friction,
        key,
    })
}

fn validate_obstacle(
    path: &Path,
    key: &str,
    obstacle: RawObstacle,
    boundary: &str,
) -> Result<ObstacleSpec> {
    let field = |name: &str| format!("{key}.obstacle.{name}");
    Ok(match obstacle {
        RawObstacle::Curve(group) => {
            group_name(path, &field("curve"), &group)?;
            ObstacleSpec::Curve { group }
        }
        RawObstacle::Body(group) => {
            group_name(path, &field("body"), &group)?;
            if group == boundary {
                return Err(config_error(path, format!("{}: `{group}` is the contact boundary itself; name the other body's boundary curve", field("body"))));
            }
            ObstacleSpec::Body { group }
        }
        RawObstacle::Line { point, normal } => {
            finite_all(path, &field("line.point"), &point)?;
            finite_all(path, &field("line.normal"), &normal)?;
            let len = (normal[0] * normal[0] + normal[1] * normal[1]).sqrt();
            if !(len > 0.0) || !len.is_finite() {
                return Err(config_error(path, format!("{} must be a non-zero vector (pointing out of the obstacle, toward the body)", field("line.normal"))));
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
            lobes,
        } => ObstacleSpec::Circle {
            center: {
                finite_all(path, &field("circle.center"), &center)?;
                center
            },
            radius: positive(path, &field("circle.radius"), radius)?,
            body_inside,
            lobes: lobes
                .map(|l| validate_lobes(path, key, l, radius))
                .transpose()?,
        },
    })
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
        spec.start = validate_start(path, start)?;
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
                "transient.perturbation needs a transient.start other than rest (rest has nothing to perturb)".to_string(),
            ));
        }
        spec.perturbation = v;
    }
    Ok(spec)
}

fn validate_start(path: &Path, start: RawStart) -> Result<TransientStart> {
    Ok(match start {
        RawStart::Rest => TransientStart::Rest,
        RawStart::HarmonicBalance => TransientStart::HarmonicBalance,
        RawStart::Previous => TransientStart::Previous,
        RawStart::Rigid(r) => {
            let displacement = r.displacement.unwrap_or([0.0; 2]);
            let velocity = r.velocity.unwrap_or([0.0; 2]);
            for (key, v) in [("displacement", displacement), ("velocity", velocity)] {
                if !v.iter().all(|x| x.is_finite()) {
                    return Err(config_error(
                        path,
                        format!("transient.start.rigid.{key} = {v:?} must be finite"),
                    ));
                }
            }
            if r.group.as_deref() == Some("") {
                return Err(config_error(
                    path,
                    "transient.start.rigid.group is empty: name a physical group, or leave the key out to move every node".to_string(),
                ));
            }
            TransientStart::Rigid {
                group: r.group,
                displacement,
                velocity,
            }
        }
        RawStart::State(file) => {
            let dir = path.parent().unwrap_or(Path::new("."));
            TransientStart::State(if file.is_absolute() {
                file
            } else {
                dir.join(file)
            })
        }
    })
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
    if let Some(v) = s.max_turn {
        if !(v > 0.0 && v < 180.0) {
            return Err(config_error(
                path,
                format!(
                    "sweep.max_turn = {} must lie in (0, 180) degrees (e.g. 60), or be left out",
                    show(v)
                ),
            ));
        }
        spec.max_turn = Some(v);
    }
    if let Some(v) = s.max_points {
        spec.max_points = v;
    }
    if let Some(v) = s.save_every {
        spec.save_every = v;
    }
    spec.follow_period_doubling = s.follow_period_doubling.unwrap_or(false);
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
