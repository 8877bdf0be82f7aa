//! Turning a periodic solution into files: the VTU snapshot series and its `.pvd`, the
//! per-harmonic amplitudes, CSV time histories of probes and contact nodes. `Sampled` is what
//! gets written, from either solver.

use std::path::Path;

use rayon::prelude::*;

use super::model::Model;
use crate::config::{ContactSpec, FieldName};
use crate::contact::geometry::obstacle_outline;
use crate::fem;
use crate::hbm::{fourier, Snapshot, Solution};
use crate::output::tables::write_csv;
use crate::output::{write_lines_vtu, write_pvd, write_vtu, Field};
use crate::progress::Reporter;
use crate::transient::setup::Marching;
use crate::transient::TransientResult;
use crate::Result;

/// One period as written: snapshots at the output frames and finer time histories.
pub struct Sampled {
    pub frames: Vec<Snapshot>,
    /// The contact state at each frame (empty without contact).
    pub frame_contact: Vec<ContactState>,
    pub history: History,
    /// A node counts as closed when its law force is positive and its opening at most this
    /// [m]: the largest of 1e-3 × the largest opening, the largest penetration over the
    /// history and the gaps' round-off (`GAP_ROUND_OFF`; 0 without contact).
    pub closed_tolerance: f64,
    /// The total pressing force at every time step of the last period (time marching only;
    /// written as `contact_steps.csv`).
    pub steps: Option<StepHistory>,
    /// With friction (harmonic balance): the hysteresis loop of the contact node that
    /// dissipates most.
    pub friction_loop: Option<FrictionLoop>,
}

/// One contact node's tangential displacement w(t) relative to the obstacle and tangential
/// force λ_t(t) at the history's times, and the energy it dissipates per period [J].
pub struct FrictionLoop {
    /// The node's mesh index.
    pub node: usize,
    pub slip: Vec<f64>,
    pub force: Vec<f64>,
    pub energy: f64,
}

impl FrictionLoop {
    /// The loop of the node of `solution` that dissipates most, at `times`.
    fn of(model: &Model, solution: &Solution, times: &[f64]) -> Option<FrictionLoop> {
        let c = solution.contact.as_ref()?;
        let f = c.friction.as_ref()?;
        let m = c.coefficients();
        let (i, energy) = f.most_dissipating(c.harmonics)?;
        let node = *model.contact.as_ref()?.set.nodes.get(i)?;
        let series = |coeffs: &[f64]| -> Vec<f64> {
            let at = |&t: &f64| {
                crate::hbm::sampler::evaluate(&solution.basis, coeffs, solution.omega, t)
            };
            times.iter().map(at).collect()
        };
        Some(FrictionLoop {
            node,
            slip: series(&f.slips[i * m..(i + 1) * m]),
            force: series(&f.tangential[i * m..(i + 1) * m]),
            energy,
        })
    }
}

/// The total pressing contact force −Σλ at every time step of the marched period.
pub struct StepHistory {
    pub times: Vec<f64>,
    pub total_force: Vec<f64>,
}

/// The contact state at one instant, per contact node (in `ContactSet::nodes` order).
#[derive(Clone, Debug, Default)]
pub struct ContactState {
    /// g = B u − g0 [m]: the solver's sign (> 0 penetrating); the output writes −g.
    pub gap: Vec<f64>,
    /// The pressing force the contact law gives at this instant [N], ≥ 0: harmonic balance
    /// max(0, c g − λ) from the series λ(t) and g(t) (the projection in the complementarity
    /// function; at a solution λ's coefficients are Q of these samples); time marching the
    /// step's LCP force −λ.
    pub force: Vec<f64>,
    /// −λ(t) [N]: harmonic balance the truncated Fourier series of the multipliers (may be
    /// negative, tension, near impacts); time marching the same as `force`.
    pub series: Vec<f64>,
    /// With friction, per node: λ_t(t) [N] along t = ẑ × n (harmonic balance the series of
    /// the tangential multipliers, time marching the step's), the slip velocity, μ, and the
    /// energy dissipated per period [J] (time marching: over the last period).
    pub tangential: Option<crate::hbm::Tangential>,
}

impl ContactState {
    /// From the multipliers λ (≤ 0 pressing) and the gaps, with the law's c (harmonic
    /// balance) or without (time marching: the multipliers are the law's).
    fn new(gap: Vec<f64>, lambda: &[f64], c: Option<f64>) -> Self {
        let force = gap
            .iter()
            .zip(lambda)
            .map(|(&g, &l)| match c {
                Some(c) => (c * g - l).max(0.0),
                None => (-l).max(0.0),
            })
            .collect();
        ContactState {
            gap,
            force,
            series: lambda.iter().map(|l| -l).collect(),
            tangential: None,
        }
    }

    /// Per node: 1 slipping (|λ_t| at the cone μ|λ_n| to 0.1%), 0 stuck, −1 open (or
    /// frictionless); `None` without friction.
    fn slipping(&self, tolerance: f64) -> Option<Vec<f64>> {
        let crate::hbm::Tangential { force: t, mu, .. } = self.tangential.as_ref()?;
        let state = |i: usize| match self.closed(i, tolerance) {
            false => -1.0,
            true if t[i].abs() >= 0.999 * mu[i] * self.force[i] => 1.0,
            true => 0.0,
        };
        Some((0..t.len()).map(state).collect())
    }

    /// Whether node i is closed: a pressing law force and an opening −g within `tolerance`.
    pub fn closed(&self, i: usize, tolerance: f64) -> bool {
        self.force[i] > 0.0 && -self.gap[i] <= tolerance
    }
}

/// Time histories over one period.
pub struct History {
    pub times: Vec<f64>,
    /// Per probe group (`Model::probes` order), its nodes' mean u_x and u_y at each time.
    pub probe_means: Vec<[Vec<f64>; 2]>,
    /// The contact state at each time (empty without contact).
    pub contact: Vec<ContactState>,
    /// The largest |n·u| + |g0| of a contact node, and |u_x| + |u_y| of a probe node, over
    /// the history [m]: the scale of the gaps' round-off (a contact held closed all period
    /// has n·u ≈ g0 ≈ 0, while the u it is recovered from is the structure's).
    pub gap_scale: f64,
}

/// An opening below this fraction of `History::gap_scale` is round-off of the gap's terms,
/// not an opening (a contact preloaded 1 µm and closed all period shows openings and
/// penetrations of 10⁻²¹ m, both signs).
const GAP_ROUND_OFF: f64 = 1e-9;

impl History {
    /// The total pressing force of the contact law at each time.
    pub fn total_force(&self) -> Vec<f64> {
        self.contact.iter().map(|c| c.force.iter().sum()).collect()
    }

    /// The total pressing force of the multipliers' series −Σλ(t) at each time.
    pub fn total_force_series(&self) -> Vec<f64> {
        self.contact.iter().map(|c| c.series.iter().sum()).collect()
    }

    /// The largest gap over the history (0 when never penetrating).
    pub fn max_penetration(&self) -> f64 {
        self.contact
            .iter()
            .flat_map(|c| &c.gap)
            .cloned()
            .fold(0.0, f64::max)
    }

    /// The largest opening −g over the history (0 when never open).
    pub fn max_opening(&self) -> f64 {
        self.contact
            .iter()
            .flat_map(|c| &c.gap)
            .fold(0.0, |a: f64, &g| a.max(-g))
    }

    /// See `Sampled::closed_tolerance`.
    fn closed_tolerance(&self) -> f64 {
        (1e-3 * self.max_opening())
            .max(self.max_penetration())
            .max(GAP_ROUND_OFF * self.gap_scale)
    }

    /// The history at `times` of the displacement `u(j, dof)` at instant j (read at the probe
    /// and contact nodes only), with the multipliers λ(t_j) where there is contact (`None`:
    /// none) and the law's c (harmonic balance) or none (time marching); ω times the gaps of
    /// a moving obstacle.
    fn new(
        model: &Model,
        omega: f64,
        times: Vec<f64>,
        u: impl Fn(usize, usize) -> f64,
        lambda: impl Fn(usize) -> Option<Vec<f64>>,
        c: Option<f64>,
    ) -> History {
        let mut probe_means: Vec<[Vec<f64>; 2]> =
            vec![[Vec::new(), Vec::new()]; model.probes.len()];
        let (mut contact, mut gap_scale) = (Vec::new(), 0.0f64);
        for (j, &t) in times.iter().enumerate() {
            for ((_, nodes), means) in model.probes.iter().zip(&mut probe_means) {
                let n = nodes.len().max(1) as f64;
                let moved = nodes
                    .iter()
                    .map(|&i| u(j, 2 * i).abs() + u(j, 2 * i + 1).abs());
                gap_scale = moved.fold(gap_scale, f64::max);
                for (comp, series) in means.iter_mut().enumerate() {
                    series.push(nodes.iter().map(|&i| u(j, 2 * i + comp)).sum::<f64>() / n);
                }
            }
            if let Some(l) = lambda(j) {
                let g0 = gaps_at(model, omega, t);
                let terms: Vec<(f64, f64)> = normal_terms(model, &g0, |d| u(j, d)).collect();
                let scale = terms.iter().map(|(nu, g0)| nu.abs() + g0.abs());
                gap_scale = scale.fold(gap_scale, f64::max);
                let gaps = terms.into_iter().map(gap).collect();
                contact.push(ContactState::new(gaps, &l, c));
            }
        }
        History {
            times,
            probe_means,
            contact,
            gap_scale,
        }
    }
}

/// The dofs a history reads: both components of every probe and contact node, ascending.
fn history_dofs(model: &Model) -> Vec<usize> {
    let contact = model
        .contact
        .as_ref()
        .map_or(Vec::new(), |c| c.set.touched_nodes());
    let probes = model.probes.iter().flat_map(|(_, nodes)| nodes);
    let mut dofs: Vec<usize> = probes
        .chain(&contact)
        .flat_map(|&n| [2 * n, 2 * n + 1])
        .collect();
    dofs.sort_unstable();
    dofs.dedup();
    dofs
}

/// With friction, each marched contact state's tangential part: λ_t and the slip velocity at
/// its sample, μ and the energy each node dissipated over the last period
/// (`ContactState::tangential`).
fn marched_friction(model: &Model, result: &TransientResult, states: &mut [ContactState]) {
    let mu = model
        .contact
        .as_ref()
        .and_then(|c| c.operator.tangential.as_ref());
    let (Some(mu), Some(friction)) = (mu, result.friction.as_ref()) else {
        return;
    };
    let samples = result.tangential_force.iter().zip(&result.slip_velocity);
    for (state, (force, velocity)) in states.iter_mut().zip(samples) {
        if force.len() == mu.coefficients.len() {
            state.tangential = Some(crate::hbm::Tangential {
                force: force.clone(),
                velocity: velocity.clone(),
                mu: mu.coefficients.clone(),
                energy: friction.node_energy.clone(),
            });
        }
    }
}

/// The contact state of a harmonic-balance solution at time t with displacement u (`None`
/// without contact).
fn harmonic_balance_contact(
    model: &Model,
    solution: &Solution,
    t: f64,
    u: &[f64],
) -> Option<ContactState> {
    let lambda = solution.multipliers_at(t)?;
    let c = solution.contact.as_ref().map(|c| c.c);
    let omega = 2.0 * std::f64::consts::PI / solution.period();
    let mut state = ContactState::new(contact_gaps(model, omega, t, u), &lambda, c);
    state.tangential = solution.tangential_at(t);
    Some(state)
}

impl Sampled {
    /// `frames` snapshots, and histories at the solver's samples (at least 4 per frame and
    /// 64 per period) for accurate amplitudes and force statistics, rounded up to a multiple
    /// of the frames so that every frame's instant is a row of the histories (a Fourier N
    /// already is; a spline basis' N = 8S is not for odd S, and its solver instants are
    /// Gauss points anyway).
    pub fn harmonic_balance(
        model: &Model,
        solution: &Solution,
        frame_count: usize,
        samples: usize,
    ) -> Self {
        let mut sampled = Self::harmonic_balance_history(model, solution, frame_count, samples);
        let dofs = &model.system.dofs;
        let period = solution.period();
        sampled.frames = (0..frame_count)
            .into_par_iter()
            .map(|j| solution.snapshot(dofs, j as f64 * period / frame_count as f64))
            .collect();
        sampled.frame_contact = sampled
            .frames
            .iter()
            .filter_map(|s| harmonic_balance_contact(model, solution, s.time, &s.displacement))
            .collect();
        sampled
    }

    /// The histories of `harmonic_balance` (the same instants, so the same amplitudes and
    /// force statistics) without its frame snapshots: what a sweep row needs.
    pub fn harmonic_balance_history(
        model: &Model,
        solution: &Solution,
        frame_count: usize,
        samples: usize,
    ) -> Self {
        let dofs = &model.system.dofs;
        let period = solution.period();
        let n = samples
            .max(4 * frame_count)
            .max(64)
            .next_multiple_of(frame_count.max(1));
        let times: Vec<f64> = (0..n).map(|j| j as f64 * period / n as f64).collect();
        // The field at the probe and contact nodes only: the whole field at every sample
        // cost more than the solve (H = 40 on the strip: 1280 samples of 1762 dofs).
        let read = history_dofs(model);
        let values: Vec<Vec<f64>> = times
            .iter()
            .map(|&t| solution.field_on(dofs, &read, t, 0))
            .collect();
        let at = |j: usize, d: usize| read.binary_search(&d).map_or(0.0, |r| values[j][r]);
        let c = solution.contact.as_ref().map(|c| c.c);
        let history = History::new(
            model,
            2.0 * std::f64::consts::PI / period,
            times.clone(),
            at,
            |j| solution.multipliers_at(times[j]),
            c,
        );
        Sampled {
            frames: Vec::new(),
            frame_contact: Vec::new(),
            closed_tolerance: history.closed_tolerance(),
            friction_loop: FrictionLoop::of(model, solution, &times),
            history,
            steps: None,
        }
    }

    /// The last marched period: snapshots at the frames, histories at the same instants, and
    /// the total contact force at every step.
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
        let steps = model.contact.as_ref().map(|_| {
            let count = result.total_contact_history.len();
            StepHistory {
                times: (0..count).map(|i| i as f64 * result.dt).collect(),
                total_force: result.total_contact_history.iter().map(|v| -v).collect(),
            }
        });
        let mut history = History::new(
            model,
            model.system.omega,
            result.times.clone(),
            |j, d| frames[j].displacement[d],
            |j| frames[j].contact_force.clone(),
            None,
        );
        marched_friction(model, result, &mut history.contact);
        // The history is taken at the frames: its contact states are the frames'.
        Sampled {
            frame_contact: history.contact.clone(),
            frames,
            closed_tolerance: history.closed_tolerance(),
            history,
            steps,
            friction_loop: None,
        }
    }

    /// Every file of the run but the summary: the VTU series and its `.pvd`, `probes.csv`,
    /// and for contact scenes `contact.csv`, `obstacle.vtu` + `obstacle.pvd` (a rigid
    /// obstacle) and (time
    /// marching) `contact_steps.csv`. Returns what the series found on the way. Each frame
    /// written is reported to `reporter` (task `WRITE_TASK`).
    pub fn write(
        &self,
        dir: &Path,
        model: &Model,
        spec: Option<&ContactSpec>,
        fields: &[FieldName],
        reporter: &dyn Reporter,
    ) -> Result<SeriesWritten> {
        let written = write_series(dir, model, self, fields, reporter)?;
        crate::output::paraview::write_view_script(dir, model.contact.is_some())?;
        let h = &self.history;
        write_probes(&dir.join("probes.csv"), model, h)?;
        if let (Some(c), Some(spec)) = (&model.contact, spec) {
            write_contact_history(&dir.join("contact.csv"), model, &h.times, &h.contact)?;
            // Every rigid obstacle's outline in one file; a body obstacle is in the mesh itself.
            let (mut points, mut segments) = (Vec::new(), Vec::new());
            for (pair, set) in spec.pairs.iter().zip(&c.pairs) {
                let o = obstacle_outline(&model.mesh, &super::model::obstacle(&pair.obstacle), set);
                let base = points.len();
                segments.extend(o.segments.iter().map(|[a, b]| [a + base, b + base]));
                points.extend(o.points);
            }
            if !points.is_empty() {
                write_lines_vtu(&dir.join("obstacle.vtu"), &points, &segments)?;
                write_pvd(&dir.join("obstacle.pvd"), &[(0.0, "obstacle.vtu".into())])?;
            }
        }
        if let Some(steps) = &self.steps {
            let rows: Vec<Vec<f64>> = steps
                .times
                .iter()
                .zip(&steps.total_force)
                .map(|(&t, &f)| vec![t, f])
                .collect();
            let header = ["time".to_string(), "total_force".to_string()];
            write_csv(&dir.join("contact_steps.csv"), &header, &rows)?;
        }
        Ok(written)
    }
}

/// What writing the VTU series found.
pub struct SeriesWritten {
    /// The frames' file names.
    pub files: Vec<String>,
}

fn vector3(u: &[f64]) -> Vec<f64> {
    u.chunks(2).flat_map(|c| [c[0], c[1], 0.0]).collect()
}

/// Normal gap B u − g0(t) of every contact row for a displacement on all dofs at time t
/// (fundamental ω).
pub fn contact_gaps(model: &Model, omega: f64, t: f64, u: &[f64]) -> Vec<f64> {
    let g0 = gaps_at(model, omega, t);
    normal_terms(model, &g0, |d| u[d]).map(gap).collect()
}

/// The obstacle's gaps g0(t) of every contact row (none without contact).
fn gaps_at(model: &Model, omega: f64, t: f64) -> Vec<f64> {
    let Some(c) = &model.contact else {
        return Vec::new();
    };
    let mut g0 = vec![0.0; c.operator.nodes()];
    c.operator.gap_at(omega, t, &mut g0);
    g0
}

/// The gap g = n·u − g0 from its two terms (n·u, g0).
fn gap((nu, g0): (f64, f64)) -> f64 {
    nu - g0
}

/// The two terms of every contact row's gap B u − g0: ((B u)_i, g0_i), (B u)_i = n_i·u of the
/// node, less n_i·Σ N_a u_a of a target body's nodes, with the gaps `gaps` (none without
/// contact).
fn normal_terms<'m>(
    model: &'m Model,
    gaps: &'m [f64],
    u: impl Fn(usize) -> f64 + 'm,
) -> impl Iterator<Item = (f64, f64)> + 'm {
    let set = model.contact.as_ref().map(|c| &c.set);
    let normals = set.map_or(&[][..], |s| &s.normals[..]);
    normals
        .iter()
        .zip(gaps)
        .enumerate()
        .map(move |(i, (nrm, &g0))| {
            let rows = set.into_iter().flat_map(move |s| s.row_nodes(i));
            let bu = rows
                .map(|(n, w)| w * (nrm[0] * u(2 * n) + nrm[1] * u(2 * n + 1)))
                .sum();
            (bu, g0)
        })
}

/// The pressure [Pa] of contact node i (in `ContactSet::nodes` order) carrying `force` [N]:
/// the force over its tributary area (tributary length × thickness); 0 without area.
pub fn nodal_pressure(model: &Model, i: usize, force: f64) -> f64 {
    let Some(c) = &model.contact else {
        return 0.0;
    };
    let area = c.set.tributary[i] * model.material.thickness;
    if area > 0.0 {
        force / area
    } else {
        0.0
    }
}

/// The progress task of the VTU series: one step per frame file written.
pub const WRITE_TASK: &str = "write frames";

/// Write one VTU per snapshot and the `.pvd`; returns the file names. The frames are written
/// a thread's worth at a time, side by side, and reported to `reporter` in frame order once
/// written (`WRITE_TASK`, j of the frame count, the file name).
pub fn write_series(
    dir: &Path,
    model: &Model,
    sampled: &Sampled,
    fields: &[FieldName],
    reporter: &dyn Reporter,
) -> Result<SeriesWritten> {
    let total = sampled.frames.len() as u64;
    let mut entries = Vec::new();
    let mut files = Vec::new();
    // As many frames at a time as there are threads, each batch reported in frame order.
    let batch = rayon::current_num_threads().max(1);
    for (b, chunk) in sampled.frames.chunks(batch).enumerate() {
        let names = chunk
            .par_iter()
            .enumerate()
            .map(|(i, s)| write_frame(dir, model, sampled, b * batch + i, s, fields))
            .collect::<Result<Vec<String>>>()?;
        for ((i, s), name) in chunk.iter().enumerate().zip(names) {
            let j = b * batch + i;
            reporter.progress(WRITE_TASK, j as u64 + 1, Some(total), &name);
            entries.push((s.time, name.clone()));
            files.push(name);
        }
    }
    reporter.task_done(WRITE_TASK);
    write_pvd(&dir.join("series.pvd"), &entries)?;
    Ok(SeriesWritten { files })
}

/// `frame_<j>.vtu`: frame j's point fields (displacement, velocity, acceleration, contact)
/// and cell fields (stresses) that `fields` asks for; returns the file's name.
fn write_frame(
    dir: &Path,
    model: &Model,
    sampled: &Sampled,
    j: usize,
    s: &Snapshot,
    fields: &[FieldName],
) -> Result<String> {
    let want = |f: FieldName| fields.contains(&f);
    let mut points = Vec::new();
    for (field, name, values) in [
        (FieldName::Displacement, "displacement", &s.displacement),
        (FieldName::Velocity, "velocity", &s.velocity),
        (FieldName::Acceleration, "acceleration", &s.acceleration),
    ] {
        if want(field) {
            points.push(Field {
                name: name.into(),
                components: 3,
                values: vector3(values),
            });
        }
    }
    if let (true, Some(state)) = (want(FieldName::Contact), sampled.frame_contact.get(j)) {
        points.extend(contact_fields(model, state, sampled.closed_tolerance));
    }
    let cells = stress_fields(model, &s.displacement, fields);
    let name = format!("frame_{j:04}.vtu");
    write_vtu(&dir.join(&name), &model.mesh, &points, &cells)?;
    Ok(name)
}

/// The contact point fields of one frame: opening, law force, pressure, status (1 closed, 0
/// open, −1 not a contact node) and series force at the contact nodes. On a target body's
/// nodes: the reaction of each row shared by the weights N_a ≥ 0 at its closest point
/// (normalized; a quadratic edge's negative corner weight gets none, so the field stays a
/// pressure ≥ 0 with the same total), the smallest opening of the rows that touch the node,
/// and status 1 where that reaction presses and that opening is within the tolerance.
fn contact_fields(model: &Model, state: &ContactState, closed_tolerance: f64) -> Vec<Field> {
    let Some(c) = &model.contact else {
        return Vec::new();
    };
    let nn = model.mesh.nodes.len();
    let (mut opening, mut force) = (vec![0.0; nn], vec![0.0; nn]);
    let (mut pressure, mut series) = (vec![0.0; nn], vec![0.0; nn]);
    let mut status = vec![-1.0f64; nn];
    let closed = |i: usize| f64::from(u8::from(state.closed(i, closed_tolerance)));
    // A node of several pairs gets the sum of their forces, the smallest opening and closed
    // if any row is.
    for &n in &c.set.nodes {
        opening[n] = f64::INFINITY;
    }
    for (i, &n) in c.set.nodes.iter().enumerate() {
        opening[n] = opening[n].min(-state.gap[i]);
        force[n] += state.force[i];
        series[n] += state.series[i];
        pressure[n] += nodal_pressure(model, i, state.force[i]);
        status[n] = status[n].max(closed(i));
    }
    for &a in &c.set.target_nodes {
        opening[a] = f64::INFINITY;
    }
    for (i, targets) in c.set.targets.iter().enumerate() {
        let total: f64 = targets.iter().map(|&(_, w)| w.max(0.0)).sum();
        for &(a, w) in targets {
            let share = w.max(0.0) / total;
            force[a] += share * state.force[i];
            series[a] += share * state.series[i];
            opening[a] = opening[a].min(-state.gap[i]);
        }
    }
    for (&a, &length) in c.set.target_nodes.iter().zip(&c.set.target_tributary) {
        let area = length * model.material.thickness;
        pressure[a] = if area > 0.0 { force[a] / area } else { 0.0 };
        status[a] = f64::from(u8::from(force[a] > 0.0 && opening[a] <= closed_tolerance));
    }
    let mut fields = vec![
        ("contact_opening", opening),
        ("contact_force", force),
        ("contact_pressure", pressure),
        ("contact_status", status),
        ("contact_force_series", series),
    ];
    if let (Some(f), Some(slip)) = (&state.tangential, state.slipping(closed_tolerance)) {
        let (t, e, v) = (&f.force, &f.energy, &f.velocity);
        let (mut tangential, mut energy) = (vec![0.0; nn], vec![0.0; nn]);
        let mut velocity = vec![0.0; nn];
        let mut slipping = vec![-1.0f64; nn];
        for (i, &n) in c.set.nodes.iter().enumerate() {
            tangential[n] += t[i];
            energy[n] += e[i];
            velocity[n] = v[i];
            slipping[n] = slipping[n].max(slip[i]);
        }
        fields.push(("contact_tangential_force", tangential));
        fields.push(("contact_slip", slipping));
        fields.push(("contact_slip_velocity", velocity));
        fields.push(("contact_friction_energy", energy));
    }
    fields
        .into_iter()
        .map(|(name, values)| Field {
            name: name.into(),
            components: 1,
            values,
        })
        .collect()
}

/// The cell fields of one frame that `fields` asks for (`stress`, `von_mises`); the
/// summary's largest von Mises stress is computed where the summary is.
fn stress_fields(model: &Model, u: &[f64], fields: &[FieldName]) -> Vec<Field> {
    if !fields.contains(&FieldName::Stress) && !fields.contains(&FieldName::VonMises) {
        return Vec::new();
    }
    let stresses = fem::cell_stresses(&model.mesh, &model.material, u);
    let mut cells = Vec::new();
    if fields.contains(&FieldName::Stress) {
        cells.push(Field {
            name: "stress".into(),
            components: 6,
            values: stresses
                .iter()
                .flat_map(|t| [t.xx, t.yy, t.zz, t.xy, 0.0, 0.0])
                .collect(),
        });
    }
    if fields.contains(&FieldName::VonMises) {
        cells.push(Field {
            name: "von_mises".into(),
            components: 1,
            values: stresses.iter().map(|t| t.von_mises()).collect(),
        });
    }
    cells
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
pub fn write_probes(path: &Path, model: &Model, history: &History) -> Result<()> {
    let mut header = vec!["time".to_string()];
    for (name, _) in &model.probes {
        header.push(format!("{name}_ux"));
        header.push(format!("{name}_uy"));
    }
    let rows: Vec<Vec<f64>> = (0..history.times.len())
        .map(|j| {
            let mut row = vec![history.times[j]];
            for [x, y] in &history.probe_means {
                row.extend([x[j], y[j]]);
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)
}

/// `contact.csv`: time, total pressing force of the contact law and of the multipliers'
/// series, then each contact node's opening, law force and series force.
pub fn write_contact_history(
    path: &Path,
    model: &Model,
    times: &[f64],
    states: &[ContactState],
) -> Result<()> {
    let Some(c) = &model.contact else {
        return Ok(());
    };
    let mut header = vec![
        "time".to_string(),
        "total_force".to_string(),
        "total_force_series".to_string(),
    ];
    for &n in &c.set.nodes {
        header.push(format!("node{n}_opening"));
        header.push(format!("node{n}_force"));
        header.push(format!("node{n}_force_series"));
    }
    let rows: Vec<Vec<f64>> = times
        .iter()
        .zip(states)
        .map(|(&t, s)| {
            let mut row = vec![t, s.force.iter().sum(), s.series.iter().sum()];
            for i in 0..c.set.nodes.len() {
                row.extend([-s.gap[i], s.force[i], s.series[i]]);
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)
}

/// The total pressing force of the contact law, Σ_i max(0, c g_i(t) − λ_i(t)), at `times`,
/// from the solved multipliers' and gaps' Fourier series cut to their first `harmonics`
/// harmonics (`fourier`'s coefficient order puts them first): the summary's H/2 truncation
/// indicator. It re-evaluates the solved coefficients; it is not a solve at H/2. `None`
/// without contact.
pub fn truncated_law_force(
    solution: &Solution,
    times: &[f64],
    harmonics: usize,
) -> Option<Vec<f64>> {
    let c = solution.contact.as_ref()?;
    let m = c.coefficients();
    let kept = (2 * harmonics.min(c.harmonics) + 1).min(m);
    let series = |coeffs: &[f64], t: f64| {
        crate::hbm::sampler::evaluate(&solution.basis, &coeffs[..kept], solution.omega, t)
    };
    let totals = times
        .iter()
        .map(|&t| {
            c.multipliers
                .chunks(m)
                .zip(c.gaps.chunks(m))
                .map(|(lambda, gap)| (c.c * series(gap, t) - series(lambda, t)).max(0.0))
                .sum()
        })
        .collect();
    Some(totals)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a contact closed all period, whose gaps are round-off of 1 µm terms
    /// (±10⁻²¹ m, both signs, a pressing force everywhere), counts closed at every node and
    /// instant: the closed tolerance has the gaps' round-off as its floor, not the largest
    /// penetration alone (which here is smaller than the largest round-off opening).
    #[test]
    fn round_off_openings_of_a_preloaded_contact_count_as_closed() {
        let state = |gap: Vec<f64>| ContactState::new(gap, &[-3e3, -3e3], Some(1e9));
        let history = History {
            times: vec![0.0, 0.5],
            probe_means: Vec::new(),
            contact: vec![state(vec![1.06e-21, -1.27e-21]), state(vec![-4e-22, 2e-22])],
            gap_scale: 1e-6,
        };
        let tolerance = history.closed_tolerance();
        assert!(tolerance >= 1e-15, "{tolerance:e}");
        for c in &history.contact {
            assert!((0..2).all(|i| c.closed(i, tolerance)), "{:?}", c.gap);
        }
        // Without the round-off scale the second node's 1.27e-21 m counts as open.
        let bare = History {
            gap_scale: 0.0,
            ..history
        };
        assert!(!bare.contact[0].closed(1, bare.closed_tolerance()));
    }
}
