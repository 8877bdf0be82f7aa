//! From a validated pipeline and a mesh to the discrete model: material, matrices, held dofs,
//! harmonic loads, contact operator and mass model. Everything here is decided by what the
//! scene contains, and recorded in `Effects` for the run summary.

use std::collections::BTreeMap;

use faer::c64;
use schemars::JsonSchema;
use serde::Serialize;

use crate::config::{ContactMass, LoadKind, ObstacleSpec, Pipeline, PlaneModelSpec, Signal};
use crate::contact::geometry::{build_contact_set, ContactSet};
use crate::contact::mass::{redistribute_mass, Redistribution};
use crate::contact::{contact_operator, ContactOperator};
use crate::fem::DofMap;
use crate::fem::{self, MassKind, Material, PlaneModel};
use crate::hbm::{HarmonicInput, System};
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

/// What the scene simulates (and so what the run pays for).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Effects {
    pub static_load: bool,
    /// Harmonics excited by loads or prescribed motion.
    pub excited_harmonics: Vec<usize>,
    pub prescribed_motion: bool,
    pub damping: Option<String>,
    pub contact: Option<String>,
    pub mass: MassModel,
}

pub struct ContactModel {
    pub set: ContactSet,
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

fn node_group<'m>(
    p: &Pipeline,
    mesh: &'m Mesh2d,
    field: &str,
    group: &str,
) -> Result<&'m Vec<usize>> {
    mesh.node_groups
        .get(group)
        .ok_or_else(|| missing_group(p, field, group, mesh))
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
    if let Some(c) = &p.contact {
        node_group(p, mesh, "contact.boundary", &c.boundary)?;
        if let ObstacleSpec::Curve { group } = &c.obstacle {
            node_group(p, mesh, "contact.obstacle.curve", group)?;
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

fn has_content<const C: usize>(s: &Signal<C>) -> bool {
    s.static_part.iter().any(|&v| v != 0.0) || !s.harmonics.is_empty()
}

/// Build the discrete model.
pub fn build(p: &Pipeline, mesh: Mesh2d, purpose: Purpose) -> Result<Model> {
    check_groups(p, &mesh)?;
    let material = material(p);
    let ndof = 2 * mesh.nodes.len();
    let stiffness = fem::assemble_stiffness(&mesh, &material)?;

    // Held dofs.
    let mut active = vec![false; ndof];
    for n in mesh.body_nodes() {
        active[2 * n] = true;
        active[2 * n + 1] = true;
    }
    let mut held = vec![false; ndof];
    for g in &p.boundaries.fixed {
        for &n in node_group(p, &mesh, "boundaries.fixed", g)? {
            held[2 * n] = true;
            held[2 * n + 1] = true;
        }
    }
    for pr in &p.boundaries.prescribed {
        for &n in node_group(p, &mesh, "boundaries.prescribed.group", &pr.group)? {
            held[2 * n + pr.component] = true;
        }
    }
    let dofs = DofMap::new(&active, &held);

    // Contact candidates and the mass model.
    let contact_set = match &p.contact {
        Some(spec) => Some(build_contact_set(&mesh, spec)?),
        None => None,
    };
    let mass_model = match (&p.contact, purpose) {
        (Some(spec), _) if spec.mass == ContactMass::Redistributed => MassModel::Redistributed,
        (Some(_), _) => MassModel::Lumped,
        (None, Purpose::Transient) => MassModel::Lumped,
        (None, Purpose::HarmonicBalance) => MassModel::Consistent,
    };
    let mut redistribution = None;
    let (mass, mass_diagonal) = match mass_model {
        MassModel::Consistent => (
            fem::assemble_mass(&mesh, &material, MassKind::Consistent)?,
            None,
        ),
        MassModel::Lumped | MassModel::Redistributed => {
            let lumped = fem::assemble_mass(&mesh, &material, MassKind::Lumped)?.diagonal();
            let diag = if let (MassModel::Redistributed, Some(set)) = (mass_model, &contact_set) {
                let r = redistribute_mass(&mesh, &lumped, &set.nodes)?;
                let d = r.mass.clone();
                redistribution = Some(r);
                d
            } else {
                lumped
            };
            let mut t = Triplets::new(ndof);
            for (i, &m) in diag.iter().enumerate() {
                if active[i] {
                    t.push(i, i, m);
                }
            }
            (t, Some(diag))
        }
    };

    // Harmonic loads and motions.
    let (nf, np) = (dofs.free.len(), dofs.prescribed.len());
    let mut inputs: BTreeMap<usize, HarmonicInput> = BTreeMap::new();
    let zero_input = || HarmonicInput {
        force: vec![c64::new(0.0, 0.0); nf],
        motion: vec![c64::new(0.0, 0.0); np],
    };
    let nodal = |kind: LoadKind, group: &str, value: [f64; 2]| -> Vec<f64> {
        match kind {
            LoadKind::Traction => {
                let edges = mesh
                    .edge_groups
                    .get(group)
                    .map(Vec::as_slice)
                    .unwrap_or(&[]);
                fem::edge_traction_load(&mesh, edges, value, material.thickness)
            }
            LoadKind::Force => {
                let nodes = mesh
                    .node_groups
                    .get(group)
                    .map(Vec::as_slice)
                    .unwrap_or(&[]);
                fem::point_force_load(&mesh, nodes, value)
            }
        }
    };
    let mut add_force = |k: usize, v: &[f64], imaginary: bool| {
        let input = inputs.entry(k).or_insert_with(zero_input);
        for (i, &d) in dofs.free.iter().enumerate() {
            // z = a − i b for a cos + b sin.
            if imaginary {
                input.force[i] -= c64::new(0.0, v[d]);
            } else {
                input.force[i] += c64::new(v[d], 0.0);
            }
        }
    };
    for l in &p.boundaries.loads {
        if l.signal.static_part.iter().any(|&v| v != 0.0) {
            add_force(0, &nodal(l.kind, &l.group, l.signal.static_part), false);
        }
        for &(k, cos, sin) in &l.signal.harmonics {
            if cos.iter().any(|&v| v != 0.0) {
                add_force(k, &nodal(l.kind, &l.group, cos), false);
            }
            if sin.iter().any(|&v| v != 0.0) {
                add_force(k, &nodal(l.kind, &l.group, sin), true);
            }
        }
    }
    let mut prescribed_motion = false;
    for pr in &p.boundaries.prescribed {
        let nodes = node_group(p, &mesh, "boundaries.prescribed.group", &pr.group)?;
        let mut add_motion = |k: usize, value: c64| {
            let input = inputs.entry(k).or_insert_with(zero_input);
            for &n in nodes {
                if let Some(d) = dofs.prescribed_index(2 * n + pr.component) {
                    input.motion[d] = value;
                }
            }
        };
        if pr.signal.static_part[0] != 0.0 {
            add_motion(0, c64::new(pr.signal.static_part[0], 0.0));
            prescribed_motion = true;
        }
        for &(k, cos, sin) in &pr.signal.harmonics {
            add_motion(k, c64::new(cos[0], -sin[0]));
            prescribed_motion = true;
        }
    }
    let _ = has_content::<2>;

    let omega = 2.0 * std::f64::consts::PI * p.harmonic_balance.frequency;
    let rayleigh = p
        .damping
        .map(|d| (d.alpha, d.beta))
        .filter(|&(a, b)| a != 0.0 || b != 0.0);
    let excited: Vec<usize> = inputs
        .iter()
        .filter(|(_, i)| i.force.iter().chain(&i.motion).any(|z| z.norm() != 0.0))
        .map(|(&k, _)| k)
        .collect();
    let static_load = excited.first() == Some(&0);
    let system = System::new(dofs, &stiffness, &mass, rayleigh, omega, inputs)?;

    let contact = match (contact_set, &p.contact) {
        (Some(set), Some(spec)) => {
            let operator = contact_operator(&set, &system.dofs);
            let _ = spec;
            Some(ContactModel {
                set,
                operator,
                redistribution,
            })
        }
        _ => None,
    };

    let probes = p
        .output
        .probes
        .iter()
        .map(|g| Ok((g.clone(), node_group(p, &mesh, "output.probes", g)?.clone())))
        .collect::<Result<Vec<_>>>()?;

    let effects = Effects {
        static_load,
        excited_harmonics: excited.into_iter().filter(|&k| k > 0).collect(),
        prescribed_motion,
        damping: rayleigh.map(|(a, b)| format!("Rayleigh: alpha = {a:e} 1/s, beta = {b:e} s")),
        contact: p.contact.as_ref().map(|c| match &c.obstacle {
            ObstacleSpec::Curve { group } => format!(
                "unilateral, `{}` against the rigid curve `{group}`",
                c.boundary
            ),
            ObstacleSpec::Line { .. } => {
                format!("unilateral, `{}` against a rigid line", c.boundary)
            }
            ObstacleSpec::Circle { body_inside, .. } => format!(
                "unilateral, `{}` against a rigid circle (body {})",
                c.boundary,
                if *body_inside { "inside" } else { "outside" }
            ),
        }),
        mass: mass_model,
    };
    Ok(Model {
        mesh,
        material,
        system,
        contact,
        mass_diagonal,
        effects,
        probes,
    })
}
