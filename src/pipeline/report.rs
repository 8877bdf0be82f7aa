//! Turning a periodic solution into files: the VTU snapshot series and its `.pvd`, the
//! per-harmonic amplitudes, CSV time histories of probes and contact nodes. `Sampled` is what
//! gets written, from either solver.

use std::path::Path;

use super::model::Model;
use crate::config::FieldName;
use crate::fem;
use crate::hbm::{fourier, Snapshot, Solution};
use crate::output::tables::write_csv;
use crate::output::{write_pvd, write_vtu, Field};
use crate::transient::setup::Marching;
use crate::transient::TransientResult;
use crate::Result;

/// One period as written: snapshots at the output frames and finer time histories.
pub struct Sampled {
    pub frames: Vec<Snapshot>,
    pub history: History,
}

/// Time histories over one period.
pub struct History {
    pub times: Vec<f64>,
    /// Displacement on all dofs at each time.
    pub displacement: Vec<Vec<f64>>,
    /// Per time, each contact node's gap B u − g0 (empty without contact).
    pub gaps: Vec<Vec<f64>>,
    /// Per time, each contact node's multiplier λ (≤ 0 pressing; empty without contact).
    pub forces: Vec<Vec<f64>>,
}

impl History {
    /// The total pressing force −Σλ at each time.
    pub fn total_force(&self) -> Vec<f64> {
        self.forces.iter().map(|f| -f.iter().sum::<f64>()).collect()
    }

    /// The largest gap over the history (0 when never penetrating).
    pub fn max_penetration(&self) -> f64 {
        self.gaps.iter().flatten().cloned().fold(0.0, f64::max)
    }
}

impl Sampled {
    /// `frames` snapshots, and histories at the solver's samples (at least 4 per frame and
    /// 64 per period) for accurate amplitudes and force statistics.
    pub fn harmonic_balance(
        model: &Model,
        solution: &Solution,
        frame_count: usize,
        samples: usize,
    ) -> Self {
        let dofs = &model.system.dofs;
        let period = solution.period();
        let at = |j: usize, n: usize| j as f64 * period / n as f64;
        let frames = (0..frame_count)
            .map(|j| solution.snapshot(dofs, at(j, frame_count)))
            .collect();
        let n = samples.max(4 * frame_count).max(64);
        let times: Vec<f64> = (0..n).map(|j| at(j, n)).collect();
        let displacement: Vec<Vec<f64>> = times
            .iter()
            .map(|&t| solution.field_at(dofs, t, 0))
            .collect();
        let history = History {
            gaps: displacement
                .iter()
                .map(|u| contact_gaps(model, u))
                .collect(),
            forces: times
                .iter()
                .filter_map(|&t| solution.multipliers_at(t))
                .collect(),
            times,
            displacement,
        };
        Sampled { frames, history }
    }

    /// The last marched period: snapshots at the frames, histories at the same instants.
    pub fn transient(model: &Model, marching: &Marching, result: &TransientResult) -> Self {
        let frames: Vec<Snapshot> = result
            .times
            .iter()
            .enumerate()
            .map(|(j, &t)| Snapshot {
                time: t,
                displacement: marching.to_global(&result.displacement[j], t, 0),
                velocity: marching.to_global(&result.velocity[j], t, 1),
                acceleration: marching.to_global(&result.acceleration[j], t, 2),
                contact_force: model
                    .contact
                    .as_ref()
                    .map(|_| result.contact_force[j].clone()),
            })
            .collect();
        let displacement: Vec<Vec<f64>> = frames.iter().map(|s| s.displacement.clone()).collect();
        let contact = model.contact.is_some();
        let history = History {
            times: result.times.clone(),
            gaps: if contact {
                displacement
                    .iter()
                    .map(|u| contact_gaps(model, u))
                    .collect()
            } else {
                Vec::new()
            },
            forces: if contact {
                result.contact_force.clone()
            } else {
                Vec::new()
            },
            displacement,
        };
        Sampled { frames, history }
    }

    /// Every file of the run but the summary: the VTU series and its `.pvd`, `probes.csv`,
    /// `contact.csv` (contact scenes).
    pub fn write(&self, dir: &Path, model: &Model, fields: &[FieldName]) -> Result<()> {
        write_series(dir, model, &self.frames, fields)?;
        let h = &self.history;
        write_probes(&dir.join("probes.csv"), model, &h.times, &h.displacement)?;
        if model.contact.is_some() {
            write_contact_history(
                &dir.join("contact.csv"),
                model,
                &h.times,
                &h.gaps,
                &h.forces,
            )?;
        }
        Ok(())
    }
}

fn vector3(u: &[f64]) -> Vec<f64> {
    u.chunks(2).flat_map(|c| [c[0], c[1], 0.0]).collect()
}

/// Normal gap B u − g0 of every contact node for a displacement on all dofs.
pub fn contact_gaps(model: &Model, u: &[f64]) -> Vec<f64> {
    let Some(c) = &model.contact else {
        return Vec::new();
    };
    c.set
        .nodes
        .iter()
        .zip(&c.set.normals)
        .zip(&c.set.gaps)
        .map(|((&n, nrm), &g0)| nrm[0] * u[2 * n] + nrm[1] * u[2 * n + 1] - g0)
        .collect()
}

/// Write one VTU per snapshot and the `.pvd`; returns the file names.
pub fn write_series(
    dir: &Path,
    model: &Model,
    snapshots: &[Snapshot],
    fields: &[FieldName],
) -> Result<Vec<String>> {
    let nn = model.mesh.nodes.len();
    let mut entries = Vec::new();
    let mut files = Vec::new();
    let want = |f: FieldName| fields.contains(&f);
    for (j, s) in snapshots.iter().enumerate() {
        let mut points = Vec::new();
        if want(FieldName::Displacement) {
            points.push(Field {
                name: "displacement".into(),
                components: 3,
                values: vector3(&s.displacement),
            });
        }
        if want(FieldName::Velocity) {
            points.push(Field {
                name: "velocity".into(),
                components: 3,
                values: vector3(&s.velocity),
            });
        }
        if want(FieldName::Acceleration) {
            points.push(Field {
                name: "acceleration".into(),
                components: 3,
                values: vector3(&s.acceleration),
            });
        }
        if let (true, Some(c), Some(lambda)) =
            (want(FieldName::Contact), &model.contact, &s.contact_force)
        {
            let gaps = contact_gaps(model, &s.displacement);
            let (mut gap, mut force, mut pressure) = (vec![0.0; nn], vec![0.0; nn], vec![0.0; nn]);
            let mut status = vec![-1.0; nn];
            let scale = lambda.iter().fold(0.0f64, |a, &l| a.max(l.abs()));
            for (i, &n) in c.set.nodes.iter().enumerate() {
                gap[n] = gaps[i];
                force[n] = -lambda[i];
                let area = c.set.tributary[i] * model.material.thickness;
                pressure[n] = if area > 0.0 { -lambda[i] / area } else { 0.0 };
                status[n] = if -lambda[i] > 1e-6 * scale && scale > 0.0 {
                    1.0
                } else {
                    0.0
                };
            }
            for (name, values) in [
                ("contact_gap", gap),
                ("contact_force", force),
                ("contact_pressure", pressure),
                ("contact_status", status),
            ] {
                points.push(Field {
                    name: name.into(),
                    components: 1,
                    values,
                });
            }
        }
        let mut cells = Vec::new();
        if want(FieldName::Stress) || want(FieldName::VonMises) {
            let stresses = fem::cell_stresses(&model.mesh, &model.material, &s.displacement);
            if want(FieldName::Stress) {
                cells.push(Field {
                    name: "stress".into(),
                    components: 6,
                    values: stresses
                        .iter()
                        .flat_map(|t| [t.xx, t.yy, t.zz, t.xy, 0.0, 0.0])
                        .collect(),
                });
            }
            if want(FieldName::VonMises) {
                cells.push(Field {
                    name: "von_mises".into(),
                    components: 1,
                    values: stresses.iter().map(|t| t.von_mises()).collect(),
                });
            }
        }
        let name = format!("frame_{j:04}.vtu");
        write_vtu(&dir.join(&name), &model.mesh, &points, &cells)?;
        entries.push((s.time, name.clone()));
        files.push(name);
    }
    write_pvd(&dir.join("series.pvd"), &entries)?;
    Ok(files)
}

/// `amplitudes.vtu`: the cos/sin amplitude field of every computed harmonic (`static` for
/// the mean).
pub fn write_amplitudes(dir: &Path, model: &Model, solution: &Solution) -> Result<()> {
    let dofs = &model.system.dofs;
    let mut points = Vec::new();
    for k in solution.harmonics() {
        let z = solution.amplitude(dofs, k);
        let (cos, sin): (Vec<f64>, Vec<f64>) = z.iter().map(|&v| fourier::cos_sin(v)).unzip();
        if k == 0 {
            points.push(Field {
                name: "static".into(),
                components: 3,
                values: vector3(&cos),
            });
        } else {
            points.push(Field {
                name: format!("harmonic_{k}_cos"),
                components: 3,
                values: vector3(&cos),
            });
            points.push(Field {
                name: format!("harmonic_{k}_sin"),
                components: 3,
                values: vector3(&sin),
            });
        }
    }
    write_vtu(&dir.join("amplitudes.vtu"), &model.mesh, &points, &[])
}

/// `probes.csv`: time and each probe's mean displacement (x, y) over its nodes.
pub fn write_probes(
    path: &Path,
    model: &Model,
    times: &[f64],
    displacements: &[Vec<f64>],
) -> Result<()> {
    let mut header = vec!["time".to_string()];
    for (name, _) in &model.probes {
        header.push(format!("{name}_ux"));
        header.push(format!("{name}_uy"));
    }
    let rows: Vec<Vec<f64>> = times
        .iter()
        .zip(displacements)
        .map(|(&t, u)| {
            let mut row = vec![t];
            for (_, nodes) in &model.probes {
                let n = nodes.len().max(1) as f64;
                row.push(nodes.iter().map(|&i| u[2 * i]).sum::<f64>() / n);
                row.push(nodes.iter().map(|&i| u[2 * i + 1]).sum::<f64>() / n);
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)
}

/// `contact.csv`: time, total contact force, then each contact node's gap and force.
pub fn write_contact_history(
    path: &Path,
    model: &Model,
    times: &[f64],
    gaps: &[Vec<f64>],
    forces: &[Vec<f64>],
) -> Result<()> {
    let Some(c) = &model.contact else {
        return Ok(());
    };
    let mut header = vec!["time".to_string(), "total_force".to_string()];
    for &n in &c.set.nodes {
        header.push(format!("node{n}_gap"));
        header.push(format!("node{n}_force"));
    }
    let rows: Vec<Vec<f64>> = times
        .iter()
        .enumerate()
        .map(|(j, &t)| {
            let mut row = vec![t, -forces[j].iter().sum::<f64>()];
            for i in 0..c.set.nodes.len() {
                row.push(gaps[j][i]);
                row.push(-forces[j][i]);
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)
}
