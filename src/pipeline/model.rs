//! From a validated pipeline and a mesh to the discrete model: material, matrices, held dofs,
//! harmonic loads, contact operator and mass model. Everything here is decided by what the
//! scene contains, and recorded in `Effects` for the run summary.

use std::collections::{BTreeMap, BTreeSet};

use faer::c64;
use schemars::JsonSchema;
use serde::Serialize;

use crate::config::{
    BasisSpec, ContactMass, ContactPair, ContactSpec, LoadKind, LoadSpec, ObstacleSpec, Pipeline,
    PlaneModelSpec, Rotation,
};
use crate::contact::geometry::{build_contact_set, ContactScene, ContactSet, Obstacle};
use crate::contact::mass::{redistribute_mass, Redistribution};
use crate::contact::{contact_operator, tangential_rows, ContactOperator, Tangential};
use crate::fem::DofMap;
use crate::fem::{self, MassKind, Material, PlaneModel};
use crate::hbm::basis::{SplineBasis, TimeBasis};
use crate::hbm::{fourier, HarmonicInput, Spin, System};
use crate::linalg::Triplets;
use crate::mesh::Mesh2d;
use crate::{Error, Result};

/// Which mass the run uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MassModel {
    /// Consistent mass: the accurate choice for linear harmonic balance.
    Consistent,
    /// HRZ-lumped diagonal mass (explicit time marching, or contact without redistribution).
    Lumped,
    /// Lumped with the contact nodes' mass moved to their neighbours (KLR 2008).
    Redistributed,
}

impl MassModel {
    /// The name the summary writes (serde's).
    pub fn name(self) -> &'static str {
        match self {
            MassModel::Consistent => "consistent",
            MassModel::Lumped => "lumped",
            MassModel::Redistributed => "redistributed",
        }
    }
}

/// What the scene simulates (and so what the run pays for).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Effects {
    pub static_load: bool,
    /// Harmonics excited by loads or prescribed motion.
    pub excited_harmonics: Vec<usize>,
    pub prescribed_motion: bool,
    pub damping: Option<String>,
    pub contact: Option<String>,
    /// Gravity's acceleration [x, y] (a static body force), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 2]>,
    /// The rotating frame, in words: speed, axis and the effects simulated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotation: Option<String>,
    /// Harmonics of the gap that a moving or out-of-round obstacle excites (H covers them).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub gap_harmonics: Vec<usize>,
    pub mass: MassModel,
}

pub struct ContactModel {
    /// Every pair's rows, in the order of `contact.pairs`.
    pub set: ContactSet,
    /// Each pair's own set (its rows are consecutive in `set`, in this order).
    pub pairs: Vec<ContactSet>,
    pub operator: ContactOperator,
    pub redistribution: Option<Redistribution>,
}

pub struct Model {
    pub mesh: Mesh2d,
    pub material: Material,
    pub system: System,
    pub contact: Option<ContactModel>,
    /// Diagonal mass on all dofs when the mass is diagonal (lumped or redistributed).
    pub mass_diagonal: Option<Vec<f64>>,
    pub effects: Effects,
    /// Probe name → its nodes.
    pub probes: Vec<(String, Vec<usize>)>,
}

/// Why a model is being built: time marching needs a diagonal mass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    HarmonicBalance,
    Transient,
}

pub fn material(p: &Pipeline) -> Material {
    Material {
        youngs_modulus: p.material.youngs_modulus,
        poisson_ratio: p.material.poisson_ratio,
        density: p.material.density,
        model: match p.material.model {
            PlaneModelSpec::PlaneStrain => PlaneModel::PlaneStrain,
            PlaneModelSpec::PlaneStress => PlaneModel::PlaneStress,
        },
        thickness: p.material.thickness,
    }
}

/// An error for a group the pipeline names but the mesh lacks, with a suggestion.
pub fn missing_group(p: &Pipeline, field: &str, group: &str, mesh: &Mesh2d) -> Error {
    let hint = mesh.group_hint(group);
    Error::Config {
        path: p.source.clone(),
        message: format!(
            "{field}: the mesh of {} has no physical group `{group}`.{hint}",
            p.geometry.file.display()
        ),
    }
}

pub fn node_group<'m>(
    p: &Pipeline,
    mesh: &'m Mesh2d,
    field: &str,
    group: &str,
) -> Result<&'m Vec<usize>> {
    let nodes = mesh
        .node_groups
        .get(group)
        .ok_or_else(|| missing_group(p, field, group, mesh))?;
    if nodes.is_empty() {
        return Err(Error::Config {
            path: p.source.clone(),
            message: format!(
                "{field}: the physical group `{group}` of {} is empty (no elements): give it its curves, points or surfaces in the .geo",
                p.geometry.file.display()
            ),
        });
    }
    Ok(nodes)
}

/// Check that every group the pipeline names exists (the `check` command and `build`).
pub fn check_groups(p: &Pipeline, mesh: &Mesh2d) -> Result<()> {
    for g in &p.boundaries.fixed {
        node_group(p, mesh, "boundaries.fixed", g)?;
    }
    for pr in &p.boundaries.prescribed {
        node_group(p, mesh, "boundaries.prescribed.group", &pr.group)?;
    }
    for l in &p.boundaries.loads {
        node_group(p, mesh, "boundaries.loads.group", &l.group)?;
        if l.kind == LoadKind::Traction && !mesh.edge_groups.contains_key(&l.group) {
            return Err(Error::Config {
                path: p.source.clone(),
                message: format!(
                    "boundaries.loads: a traction needs a curve (edge) group, but `{}` has no edges; \
                     use `type: force` for a point group",
                    l.group
                ),
            });
        }
    }
    for g in &p.output.probes {
        node_group(p, mesh, "output.probes", g)?;
    }
    if let crate::config::TransientStart::Rigid { group: Some(g), .. } = &p.transient.start {
        node_group(p, mesh, "transient.start.rigid.group", g)?;
    }
    for pair in p.contact.iter().flat_map(|c| &c.pairs) {
        node_group(p, mesh, &format!("{}.boundary", pair.key), &pair.boundary)?;
        match &pair.obstacle {
            ObstacleSpec::Curve { group } => {
                node_group(p, mesh, &format!("{}.obstacle.curve", pair.key), group)?;
            }
            ObstacleSpec::Body { group } => {
                node_group(p, mesh, &format!("{}.obstacle.body", pair.key), group)?;
            }
            _ => {}
        }
    }
    if mesh.cells.is_empty() {
        return Err(Error::Mesh {
            path: p.geometry.file.clone(),
            message: "the mesh has no 2-D cells (is the surface in a physical group?)".into(),
        });
    }
    Ok(())
}

/// Build the discrete model: stiffness, held dofs, contact set, mass model, harmonic inputs,
/// the per-harmonic system, the contact operator, probes and what the scene simulates.
/// The pipeline's time basis for a harmonic-balance model; time marching (and the harmonic-
/// balance state it may start from) keeps Fourier, its loads being Fourier harmonics.
pub fn time_basis(p: &Pipeline, purpose: Purpose) -> TimeBasis {
    match (p.harmonic_balance.basis, purpose) {
        (BasisSpec::Spline { degree, segments }, Purpose::HarmonicBalance) => {
            TimeBasis::Spline(SplineBasis::new(degree, segments))
        }
        _ => TimeBasis::Fourier,
    }
}

pub fn build(p: &Pipeline, mesh: Mesh2d, purpose: Purpose) -> Result<Model> {
    check_groups(p, &mesh)?;
    let material = material(p);
    let stiffness = fem::assemble_stiffness(&mesh, &material)?;
    let dofs = dof_map(p, &mesh)?;
    let pair_sets = match &p.contact {
        Some(spec) => Some(contact_sets(spec, &mesh, &dofs)?),
        None => None,
    };
    let contact_set = pair_sets.as_deref().map(ContactSet::concat);
    let mass = mass(p, &mesh, &material, purpose, contact_set.as_ref())?;
    let (inputs, prescribed_motion) = harmonic_inputs(p, &mesh, &material, &dofs)?;
    let centrifugal = centrifugal_unit(p, &mesh, &mass.matrix, &dofs);
    let body = (centrifugal.as_deref(), &mass.matrix);
    let inputs = with_body_forces(p, &mesh, body, &dofs, inputs);
    let excited: Vec<usize> = inputs
        .iter()
        .filter(|(_, i)| i.force.iter().chain(&i.motion).any(|z| z.norm() != 0.0))
        .map(|(&k, _)| k)
        .collect();
    let rayleigh = p
        .damping
        .map(|d| (d.alpha, d.beta))
        .filter(|&(a, b)| a != 0.0 || b != 0.0);
    let system = system(
        p,
        centrifugal,
        (dofs, stiffness, &mass.matrix),
        rayleigh,
        inputs,
    )?
    .with_basis(time_basis(p, purpose));
    let contact = (contact_set.zip(pair_sets)).map(|(set, pairs)| ContactModel {
        operator: operator(p, &set, &pairs, &system.dofs),
        set,
        pairs,
        redistribution: mass.redistribution,
    });
    if let (Purpose::HarmonicBalance, Some(c)) = (purpose, &contact) {
        // The LDLᵀ's symbolic analysis, with the contact normals kept. The LU's (the
        // resonance check's shift-invert, and the fallback of a failed LDLᵀ) is done where
        // it is first needed: run beside this one, it slowed both on a 2-core machine.
        system.schur_plan(&c.operator.reduction_rows());
    }
    let probes = p
        .output
        .probes
        .iter()
        .map(|g| Ok((g.clone(), node_group(p, &mesh, "output.probes", g)?.clone())))
        .collect::<Result<Vec<_>>>()?;
    let effects = Effects {
        static_load: excited.first() == Some(&0),
        excited_harmonics: excited.into_iter().filter(|&k| k > 0).collect(),
        prescribed_motion,
        damping: rayleigh.map(|(a, b)| format!("Rayleigh: alpha = {a:e} 1/s, beta = {b:e} s")),
        contact: p.contact.as_ref().map(describe_contact),
        gravity: p.boundaries.gravity,
        rotation: p
            .boundaries
            .rotation
            .map(|r| describe_rotation(r, p.harmonic_balance.frequency)),
        gap_harmonics: contact.as_ref().map_or(Vec::new(), |c| {
            c.operator.gap_harmonics.keys().copied().collect()
        }),
        mass: mass.model,
    };
    Ok(Model {
        mesh,
        material,
        system,
        contact,
        mass_diagonal: mass.diagonal,
        effects,
        probes,
    })
}

/// The per-harmonic system at the pipeline's frequency: the stiffness with the rotating
/// frame's spin softening, and its Coriolis matrix where simulated; a speed that follows
/// the frequency keeps `centrifugal`, the load per Ω² (`centrifugal_unit`).
fn system(
    p: &Pipeline,
    centrifugal: Option<Vec<c64>>,
    (dofs, stiffness, mass): (DofMap, Triplets, &Triplets),
    rayleigh: Option<(f64, f64)>,
    inputs: BTreeMap<usize, HarmonicInput>,
) -> Result<System> {
    let f = p.harmonic_balance.frequency;
    let speed = p.boundaries.rotation.map(|r| (r, r.speed_at(f)));
    let stiffness = spin_softened(stiffness, mass, speed);
    let coriolis = gyroscopic(mass, speed);
    let gyro = coriolis.as_ref().map(|(speed, g)| (*speed, g));
    let omega = 2.0 * std::f64::consts::PI * f;
    let spin = speed.and_then(|(r, reference)| {
        Some(Spin {
            turns: r.turns_per_period()?,
            reference,
            softening: r.spin_softening,
            centrifugal,
        })
    });
    Ok(System::new(dofs, &stiffness, mass, rayleigh, omega, inputs, gyro)?.with_spin(spin))
}

/// Free and prescribed dofs: every dof of a cell's node is free unless `boundaries.fixed` or
/// `boundaries.prescribed` holds it.
fn dof_map(p: &Pipeline, mesh: &Mesh2d) -> Result<DofMap> {
    let ndof = 2 * mesh.nodes.len();
    let mut active = vec![false; ndof];
    for n in mesh.body_nodes() {
        active[2 * n] = true;
        active[2 * n + 1] = true;
    }
    let mut held = vec![false; ndof];
    for g in &p.boundaries.fixed {
        for &n in node_group(p, mesh, "boundaries.fixed", g)? {
            held[2 * n] = true;
            held[2 * n + 1] = true;
        }
    }
    for pr in &p.boundaries.prescribed {
        for &n in node_group(p, mesh, "boundaries.prescribed.group", &pr.group)? {
            held[2 * n + pr.component] = true;
        }
    }
    Ok(DofMap::new(&active, &held))
}

/// The mass the run uses, as a matrix and (when diagonal) its diagonal.
struct Mass {
    model: MassModel,
    matrix: Triplets,
    diagonal: Option<Vec<f64>>,
    redistribution: Option<Redistribution>,
}

/// Consistent mass for linear harmonic balance; lumped for time marching; lumped with the
/// contact nodes' mass redistributed for contact (unless `contact.mass: lumped`).
fn mass(
    p: &Pipeline,
    mesh: &Mesh2d,
    material: &Material,
    purpose: Purpose,
    contact_set: Option<&ContactSet>,
) -> Result<Mass> {
    let model = match (&p.contact, purpose) {
        (Some(spec), _) if spec.mass == ContactMass::Redistributed => MassModel::Redistributed,
        (Some(_), _) | (None, Purpose::Transient) => MassModel::Lumped,
        (None, Purpose::HarmonicBalance) => MassModel::Consistent,
    };
    if model == MassModel::Consistent {
        return Ok(Mass {
            model,
            matrix: fem::assemble_mass(mesh, material, MassKind::Consistent)?,
            diagonal: None,
            redistribution: None,
        });
    }
    let lumped = fem::assemble_mass(mesh, material, MassKind::Lumped)?.diagonal();
    let redistribution = match (model, contact_set) {
        (MassModel::Redistributed, Some(set)) => {
            Some(redistribute_mass(mesh, &lumped, &set.touched_nodes())?)
        }
        _ => None,
    };
    let diagonal = redistribution.as_ref().map_or(lumped, |r| r.mass.clone());
    let active: BTreeSet<usize> = mesh.body_nodes().into_iter().collect();
    let mut matrix = Triplets::new(diagonal.len());
    for (i, &m) in diagonal.iter().enumerate() {
        if active.contains(&(i / 2)) {
            matrix.push(i, i, m);
        }
    }
    Ok(Mass {
        model,
        matrix,
        diagonal: Some(diagonal),
        redistribution,
    })
}

/// K − Ω²M: the spin softening of a rotating frame at Ω (the model's own mass), where
/// simulated.
fn spin_softened(
    stiffness: Triplets,
    mass: &Triplets,
    rotation: Option<(Rotation, f64)>,
) -> Triplets {
    match rotation {
        Some((r, speed)) if r.spin_softening => {
            let mut k = stiffness;
            let w2 = speed * speed;
            k.entries
                .extend(mass.entries.iter().map(|&(i, j, m)| (i, j, -w2 * m)));
            k
        }
        _ => stiffness,
    }
}

/// The Coriolis matrix G = 2Ω M⊗J of the rotating frame, where simulated: the force 2Ω ẑ × u̇
/// per unit mass, so the row of node a's x holds −2Ω M_ab at node b's y and the row of a's y
/// +2Ω M_ab at b's x (M's x–x and y–y blocks are equal; G is skew).
fn gyroscopic(mass: &Triplets, rotation: Option<(Rotation, f64)>) -> Option<(f64, Triplets)> {
    let (_, speed) = rotation.filter(|(r, _)| r.coriolis)?;
    let w2 = 2.0 * speed;
    let mut g = Triplets::new(mass.n);
    for &(i, j, m) in &mass.entries {
        if i % 2 == 0 && j % 2 == 0 {
            g.push(i, j + 1, -w2 * m);
            g.push(i + 1, j, w2 * m);
        }
    }
    Some((speed, g))
}

/// The static body forces added to harmonic 0: gravity M g and the centrifugal force
/// M Ω² (x − c), with the model's own mass (consistent, lumped or redistributed: the same
/// resultant and moment, and the inertia the dynamics use); `centrifugal` is M (x − c)
/// (`centrifugal_unit`).
fn with_body_forces(
    p: &Pipeline,
    mesh: &Mesh2d,
    (centrifugal, mass): (Option<&[c64]>, &Triplets),
    dofs: &DofMap,
    mut inputs: BTreeMap<usize, HarmonicInput>,
) -> BTreeMap<usize, HarmonicInput> {
    let mut forces = Vec::new();
    if let Some(g) = p.boundaries.gravity {
        forces.push(free_mass_times(mesh, mass, dofs, |_| g));
    }
    if let Some((r, unit)) = p.boundaries.rotation.zip(centrifugal) {
        let w2 = r.speed_at(p.harmonic_balance.frequency).powi(2);
        forces.push(unit.iter().map(|u| u * w2).collect());
    }
    if forces.is_empty() {
        return inputs;
    }
    let target = &mut inputs
        .entry(0)
        .or_insert_with(|| HarmonicInput {
            force: vec![c64::new(0.0, 0.0); dofs.free.len()],
            motion: vec![c64::new(0.0, 0.0); dofs.prescribed.len()],
        })
        .force;
    for force in forces {
        target.iter_mut().zip(force).for_each(|(t, f)| *t += f);
    }
    inputs
}

/// M (x − c) on the free dofs: the centrifugal force per Ω² (`None` when not simulated).
fn centrifugal_unit(
    p: &Pipeline,
    mesh: &Mesh2d,
    mass: &Triplets,
    dofs: &DofMap,
) -> Option<Vec<c64>> {
    let r = p.boundaries.rotation.filter(|r| r.centrifugal)?;
    let c = r.center;
    Some(free_mass_times(mesh, mass, dofs, |x| {
        [x[0] - c[0], x[1] - c[1]]
    }))
}

/// M a on the free dofs for the nodal acceleration field a(x).
fn free_mass_times(
    mesh: &Mesh2d,
    mass: &Triplets,
    dofs: &DofMap,
    field: impl Fn([f64; 2]) -> [f64; 2],
) -> Vec<c64> {
    let values: Vec<f64> = mesh
        .nodes
        .iter()
        .flat_map(|x| field([x[0], x[1]]))
        .collect();
    let force = mass.mul_vec(&values);
    dofs.free.iter().map(|&d| c64::new(force[d], 0.0)).collect()
}

/// The loads' and prescribed motions' complex amplitudes per harmonic (z = a − i b for
/// a cos + b sin), and whether any motion is prescribed.
fn harmonic_inputs(
    p: &Pipeline,
    mesh: &Mesh2d,
    material: &Material,
    dofs: &DofMap,
) -> Result<(BTreeMap<usize, HarmonicInput>, bool)> {
    let (nf, np) = (dofs.free.len(), dofs.prescribed.len());
    let mut inputs: BTreeMap<usize, HarmonicInput> = BTreeMap::new();
    let zero = HarmonicInput {
        force: vec![c64::new(0.0, 0.0); nf],
        motion: vec![c64::new(0.0, 0.0); np],
    };
    for l in &p.boundaries.loads {
        let mut add = |k: usize, cos: [f64; 2], sin: [f64; 2]| {
            let (fc, fs) = (
                nodal_load(mesh, material, l, cos),
                nodal_load(mesh, material, l, sin),
            );
            let target = &mut inputs.entry(k).or_insert_with(|| zero.clone()).force;
            for (i, &d) in dofs.free.iter().enumerate() {
                target[i] += fourier::from_cos_sin(fc[d], fs[d]);
            }
        };
        if l.signal.static_part.iter().any(|&v| v != 0.0) {
            add(0, l.signal.static_part, [0.0; 2]);
        }
        for &(k, cos, sin) in &l.signal.harmonics {
            if cos.iter().chain(&sin).any(|&v| v != 0.0) {
                add(k, cos, sin);
            }
        }
    }
    let mut prescribed_motion = false;
    for pr in &p.boundaries.prescribed {
        let nodes = node_group(p, mesh, "boundaries.prescribed.group", &pr.group)?;
        let mut set = |k: usize, value: c64| {
            let target = &mut inputs.entry(k).or_insert_with(|| zero.clone()).motion;
            for &n in nodes {
                if let Some(d) = dofs.prescribed_index(2 * n + pr.component) {
                    target[d] = value;
                }
            }
        };
        if pr.signal.static_part[0] != 0.0 {
            set(0, c64::new(pr.signal.static_part[0], 0.0));
            prescribed_motion = true;
        }
        for &(k, cos, sin) in &pr.signal.harmonics {
            set(k, fourier::from_cos_sin(cos[0], sin[0]));
            prescribed_motion = true;
        }
    }
    Ok((inputs, prescribed_motion))
}

/// The nodal force vector (all dofs) of one load with the value `value` (traction per area or
/// total force); zero for a zero value.
fn nodal_load(mesh: &Mesh2d, material: &Material, load: &LoadSpec, value: [f64; 2]) -> Vec<f64> {
    if value == [0.0; 2] {
        return vec![0.0; 2 * mesh.nodes.len()];
    }
    let empty = Vec::new();
    match load.kind {
        LoadKind::Traction => {
            let edges = mesh.edge_groups.get(&load.group).unwrap_or(&empty);
            fem::edge_traction_load(mesh, edges, value, material.thickness)
        }
        LoadKind::Force => {
            let nodes = mesh
                .node_groups
                .get(&load.group)
                .map(Vec::as_slice)
                .unwrap_or(&[]);
            fem::point_force_load(mesh, nodes, value)
        }
    }
}

/// A contact pair as the contact module takes it.
pub fn contact_scene(pair: &ContactPair) -> ContactScene {
    ContactScene {
        boundary: pair.boundary.clone(),
        obstacle: obstacle(&pair.obstacle),
        search_distance: pair.search_distance,
    }
}

/// Each pair's contact set: built, its held nodes dropped, its gaps shifted by a static
/// obstacle offset.
fn contact_sets(spec: &ContactSpec, mesh: &Mesh2d, dofs: &DofMap) -> Result<Vec<ContactSet>> {
    spec.pairs
        .iter()
        .map(|pair| {
            let mut set = build_contact_set(mesh, &contact_scene(pair))?;
            set.drop_held(|d| dofs.free_index(d).is_some());
            shift_gaps(pair, &mut set);
            Ok(set)
        })
        .collect()
}

/// Every pair's gap harmonics (`gap_harmonics`) on the rows of all pairs (zero on the other
/// pairs' rows).
fn all_gap_harmonics(spec: &ContactSpec, sets: &[ContactSet]) -> BTreeMap<usize, Vec<c64>> {
    let total: usize = sets.iter().map(|s| s.nodes.len()).sum();
    let mut out: BTreeMap<usize, Vec<c64>> = BTreeMap::new();
    let mut offset = 0;
    for (pair, set) in spec.pairs.iter().zip(sets) {
        for (k, rows) in gap_harmonics(pair, set) {
            let all = out
                .entry(k)
                .or_insert_with(|| vec![c64::new(0.0, 0.0); total]);
            all[offset..offset + rows.len()].copy_from_slice(&rows);
        }
        offset += set.nodes.len();
    }
    out
}

/// B and g0 of the contact set, with the obstacles' gap harmonics and the friction rows.
fn operator(
    p: &Pipeline,
    set: &ContactSet,
    pairs: &[ContactSet],
    dofs: &DofMap,
) -> ContactOperator {
    let mut operator = contact_operator(set, dofs);
    if let Some(spec) = &p.contact {
        operator.gap_harmonics = all_gap_harmonics(spec, pairs);
        operator.tangential = friction_rows(spec, pairs, set, dofs);
    }
    operator
}

/// The tangential rows and μ per node where any pair has friction (`None`: frictionless),
/// with each translating obstacle's tangential motion t·d(t).
fn friction_rows(
    spec: &ContactSpec,
    sets: &[ContactSet],
    all: &ContactSet,
    dofs: &DofMap,
) -> Option<Tangential> {
    if spec.pairs.iter().all(|p| p.friction == 0.0) {
        return None;
    }
    let coefficients = (spec.pairs.iter().zip(sets))
        .flat_map(|(p, s)| std::iter::repeat_n(p.friction, s.nodes.len()))
        .collect();
    let mut rows = tangential_rows(all, dofs, coefficients);
    let (total, mut offset) = (all.nodes.len(), 0);
    for (pair, set) in spec.pairs.iter().zip(sets) {
        for &(k, cos, sin) in pair.motion.iter().flat_map(|m| &m.harmonics) {
            let row = (rows.motion.entry(k)).or_insert_with(|| vec![c64::new(0.0, 0.0); total]);
            for (z, n) in row[offset..].iter_mut().zip(&set.normals) {
                *z += along([-n[1], n[0]], cos, sin);
            }
        }
        offset += set.nodes.len();
    }
    Some(rows)
}

/// The phasor (x = Re(z e^{ikωt})) of the component along `v` of a translation
/// cos·cos kωt + sin·sin kωt.
fn along(v: [f64; 2], cos: [f64; 2], sin: [f64; 2]) -> c64 {
    c64::new(
        v[0] * cos[0] + v[1] * cos[1],
        -(v[0] * sin[0] + v[1] * sin[1]),
    )
}

/// The pipeline's obstacle as the contact module takes it.
pub fn obstacle(spec: &ObstacleSpec) -> Obstacle {
    match spec {
        ObstacleSpec::Curve { group } => Obstacle::Curve {
            group: group.clone(),
        },
        ObstacleSpec::Line { point, normal } => Obstacle::Line {
            point: *point,
            normal: *normal,
        },
        ObstacleSpec::Circle {
            center,
            radius,
            body_inside,
            ..
        } => Obstacle::Circle {
            center: *center,
            radius: *radius,
            body_inside: *body_inside,
        },
        ObstacleSpec::Body { group } => Obstacle::Body {
            boundary: group.clone(),
        },
    }
}

/// A moving obstacle's constant offset d0 moves each gap by n_i·d0.
fn shift_gaps(spec: &ContactPair, set: &mut ContactSet) {
    if let Some(d) = spec.motion.as_ref().map(|m| m.static_part) {
        for (g, n) in set.gaps.iter_mut().zip(&set.normals) {
            *g += n[0] * d[0] + n[1] * d[1];
        }
    }
}

/// The gap harmonics ĝ_k of each row (`ContactOperator::gap_harmonics`): a translation d(t)
/// gives n_i·d̂_k (d̂_k = cos_k − i sin_k); n lobes of amplitude δ turning once per period
/// give ±δ e^{i(nθ_i + φ)} at k = n, θ_i the closest point's polar angle (+ for a body
/// inside the circle, whose gap R(θ, t) − r grows with the radius; − outside).
fn gap_harmonics(spec: &ContactPair, set: &ContactSet) -> BTreeMap<usize, Vec<c64>> {
    let mut out: BTreeMap<usize, Vec<c64>> = BTreeMap::new();
    let nc = set.nodes.len();
    for &(k, cos, sin) in spec.motion.iter().flat_map(|m| &m.harmonics) {
        let row = out.entry(k).or_insert_with(|| vec![c64::new(0.0, 0.0); nc]);
        for (z, &n) in row.iter_mut().zip(&set.normals) {
            *z += along(n, cos, sin);
        }
    }
    if let ObstacleSpec::Circle {
        center,
        body_inside,
        lobes: Some(l),
        ..
    } = &spec.obstacle
    {
        let sign = if *body_inside { 1.0 } else { -1.0 };
        let row = out
            .entry(l.count)
            .or_insert_with(|| vec![c64::new(0.0, 0.0); nc]);
        for (z, c) in row.iter_mut().zip(&set.closest) {
            let theta = (c[1] - center[1]).atan2(c[0] - center[0]);
            *z += c64::from_polar(sign * l.amplitude, l.count as f64 * theta + l.phase);
        }
    }
    out.retain(|_, z| z.iter().any(|v| v.norm() > 0.0));
    out
}

/// How the summary names the rotating frame.
fn describe_rotation(r: Rotation, frequency_hz: f64) -> String {
    let mut effects = Vec::new();
    if r.centrifugal {
        effects.push("centrifugal force");
    }
    if r.spin_softening {
        effects.push("spin softening");
    }
    if r.coriolis {
        effects.push("Coriolis force");
    }
    let coriolis = if r.coriolis { "" } else { "; no Coriolis" };
    let follows = r.turns_per_period().map_or(String::new(), |t| {
        format!(" ({t:e} turns per period: follows the frequency)")
    });
    format!(
        "{:e} rad/s{follows} about ({:e}, {:e}): {}{coriolis}",
        r.speed_at(frequency_hz),
        r.center[0],
        r.center[1],
        effects.join(", ")
    )
}

/// How the summary names the scene's contact: each pair, joined by "; ".
fn describe_contact(c: &ContactSpec) -> String {
    let pairs: Vec<String> = c.pairs.iter().map(describe_pair).collect();
    pairs.join("; ")
}

fn describe_pair(c: &ContactPair) -> String {
    match &c.obstacle {
        ObstacleSpec::Curve { group } => format!(
            "unilateral, `{}` against the rigid curve `{group}`",
            c.boundary
        ),
        ObstacleSpec::Line { .. } => format!("unilateral, `{}` against a rigid line", c.boundary),
        ObstacleSpec::Circle {
            body_inside, lobes, ..
        } => format!(
            "unilateral, `{}` against a rigid circle (body {}{})",
            c.boundary,
            if *body_inside { "inside" } else { "outside" },
            lobes.map_or(String::new(), |l| format!(
                ", {} lobes of {:e}, turning once per period",
                l.count, l.amplitude
            ))
        ),
        ObstacleSpec::Body { group } => format!(
            "unilateral, `{}` against the boundary `{group}` of another body",
            c.boundary
        ),
    }
}
