//! The stages in order, as the user sees them:
//! mesh (gmsh) → read → model (fem, contact, mass) → solve (harmonic balance or time marching)
//! → output (staged, then committed), with a `summary.json` saying what was simulated, how big
//! it was, how accurate and what each stage cost.

pub mod accuracy;
pub mod model;
pub mod report;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::{json, Value};

use crate::config::Pipeline;
use crate::hbm::{self, fourier, HbSettings};
use crate::mesh::{self, Mesh2d};
use crate::output::tables::write_json;
use crate::output::StagedDir;
use crate::transient;
use crate::{Error, Result};
pub use model::{build, Model, Purpose};
use report::Snapshot;

/// Options from the command line.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Overrides `output.directory`.
    pub out: Option<PathBuf>,
    pub quiet: bool,
}

/// Per-stage wall times in seconds, in run order.
#[derive(Default)]
pub struct StageTimes(Vec<(String, f64)>);

impl StageTimes {
    fn time<T>(&mut self, name: &str, quiet: bool, f: impl FnOnce() -> Result<T>) -> Result<T> {
        if !quiet {
            eprint!("[{name}] ");
        }
        let start = Instant::now();
        let out = f();
        let secs = start.elapsed().as_secs_f64();
        if !quiet {
            eprintln!("{secs:.3} s");
        }
        self.0.push((name.to_string(), secs));
        out
    }

    fn push(&mut self, name: &str, secs: f64) {
        self.0.push((name.to_string(), secs));
    }

    fn to_json(&self) -> Value {
        let mut map = serde_json::Map::new();
        for (k, v) in &self.0 {
            map.insert(k.clone(), json!(v));
        }
        map.insert(
            "total".into(),
            json!(self.0.iter().map(|(_, v)| v).sum::<f64>()),
        );
        Value::Object(map)
    }
}

/// The directory results go to.
pub fn output_dir(p: &Pipeline, options: &RunOptions) -> PathBuf {
    options
        .out
        .clone()
        .unwrap_or_else(|| p.output.directory.clone())
}

/// Mesh the geometry (or reuse the cache) and read it.
pub fn mesh_stage(
    p: &Pipeline,
    out: &Path,
    times: &mut StageTimes,
    quiet: bool,
) -> Result<(Mesh2d, Value)> {
    let cache_dir = out
        .parent()
        .map(|d| d.join(".mesh-cache"))
        .unwrap_or_else(|| PathBuf::from(".mesh-cache"));
    let request = mesh::gmsh::MeshRequest {
        geo: p.geometry.file.clone(),
        parameters: p.geometry.parameters.clone(),
        mesh_size: p.geometry.mesh_size,
        order: p.geometry.order,
        quads: p.geometry.quads,
        gmsh: p.geometry.gmsh.clone(),
    };
    let meshed = times.time("mesh", quiet, || {
        mesh::gmsh::mesh_geometry(&request, &cache_dir)
    })?;
    let msh = meshed.msh.clone();
    let mesh = times.time("read", quiet, || mesh::msh::read_msh(&msh))?;
    let info = json!({
        "geometry": p.geometry.file,
        "parameters": p.geometry.parameters,
        "mesh_size": p.geometry.mesh_size,
        "order": p.geometry.order,
        "msh": meshed.msh,
        "cache_hit": meshed.cache_hit,
        "gmsh_version": meshed.gmsh_version,
        "nodes": mesh.nodes.len(),
        "cells": mesh.cells.len(),
        "min_edge_length": mesh.min_edge_length(),
    });
    Ok((mesh, info))
}

/// `hbcontact check`: the config and the geometry's groups, without solving.
pub fn check(p: &Pipeline, options: &RunOptions) -> Result<Value> {
    let out = output_dir(p, options);
    let mut times = StageTimes::default();
    let (mesh, info) = mesh_stage(p, &out, &mut times, options.quiet)?;
    model::check_groups(p, &mesh)?;
    if let Some(spec) = &p.contact {
        let set = crate::contact::geometry::build_contact_set(&mesh, spec)?;
        return Ok(
            json!({"mesh": info, "contact_nodes": set.nodes.len(), "contact_candidates": set.candidates}),
        );
    }
    Ok(json!({ "mesh": info }))
}

fn sizes(model: &Model) -> Value {
    json!({
        "nodes": model.mesh.nodes.len(),
        "cells": model.mesh.cells.len(),
        "dofs": model.system.dofs.total(),
        "free_dofs": model.system.free_count(),
        "prescribed_dofs": model.system.dofs.prescribed.len(),
        "stiffness_nonzeros": model.system.k_ff.nnz(),
    })
}

fn contact_setup(model: &Model) -> Value {
    match &model.contact {
        None => Value::Null,
        Some(c) => json!({
            "candidates": c.set.candidates,
            "kept": c.set.nodes.len(),
            "dropped_off_obstacle": c.set.dropped_off_obstacle,
            "dropped_beyond_search": c.set.dropped_beyond_search,
            "min_initial_gap": c.set.gaps.iter().cloned().fold(f64::INFINITY, f64::min),
            "max_initial_gap": c.set.gaps.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
            "mass_moved_fraction": c.redistribution.as_ref().map(|r| r.moved_fraction),
            "inertia_change": c.redistribution.as_ref().map(|r| r.inertia_change),
        }),
    }
}

/// Peak and mean over samples of the total contact force (positive = pressing).
fn contact_force_stats(forces: &[Vec<f64>]) -> (f64, f64) {
    let totals: Vec<f64> = forces.iter().map(|f| -f.iter().sum::<f64>()).collect();
    let peak = totals.iter().cloned().fold(0.0, f64::max);
    let mean = totals.iter().sum::<f64>() / totals.len().max(1) as f64;
    (peak, mean)
}

fn probe_amplitudes(model: &Model, displacements: &[Vec<f64>]) -> Value {
    // Over evenly spaced samples of one period: half the peak-to-peak range (what a gauge
    // shows) and the first-harmonic amplitude (a smooth measure that converges cleanly in H).
    let mut map = serde_json::Map::new();
    let count = displacements.len().max(1) as f64;
    for (name, nodes) in &model.probes {
        let n = nodes.len().max(1) as f64;
        let series: Vec<[f64; 2]> = displacements
            .iter()
            .map(|u| [0, 1].map(|c| nodes.iter().map(|&i| u[2 * i + c]).sum::<f64>() / n))
            .collect();
        let mut entry = serde_json::Map::new();
        for (c, axis) in ["x", "y"].iter().enumerate() {
            let max = series
                .iter()
                .map(|s| s[c])
                .fold(f64::NEG_INFINITY, f64::max);
            let min = series.iter().map(|s| s[c]).fold(f64::INFINITY, f64::min);
            let (mut a, mut b) = (0.0, 0.0);
            for (j, s) in series.iter().enumerate() {
                let phase = 2.0 * std::f64::consts::PI * j as f64 / count;
                a += s[c] * phase.cos();
                b += s[c] * phase.sin();
            }
            entry.insert(
                format!("half_peak_to_peak_{axis}"),
                json!(0.5 * (max - min)),
            );
            entry.insert(
                format!("first_harmonic_{axis}"),
                json!(2.0 * (a * a + b * b).sqrt() / count),
            );
        }
        map.insert(name.clone(), Value::Object(entry));
    }
    Value::Object(map)
}

/// The solver settings a pipeline asks for (N defaults to 16H).
pub fn hb_settings(p: &Pipeline) -> HbSettings {
    let hb = &p.harmonic_balance;
    HbSettings {
        harmonics: hb.harmonics,
        samples: hb
            .samples
            .unwrap_or_else(|| HbSettings::default_samples(hb.harmonics)),
        c_scale: hb.solver.c_scale,
        tolerance: hb.solver.tolerance,
        max_iterations: hb.solver.max_iterations,
    }
}

/// `hbcontact run`: the harmonic-balance steady state.
pub fn run(p: &Pipeline, options: &RunOptions) -> Result<PathBuf> {
    let quiet = options.quiet;
    let out = output_dir(p, options);
    let mut times = StageTimes::default();
    let (mesh, mesh_info) = mesh_stage(p, &out, &mut times, quiet)?;
    let model = times.time("assemble", quiet, || {
        build(p, mesh, Purpose::HarmonicBalance)
    })?;

    let settings = hb_settings(p);
    let progress = |msg: &str| {
        if !quiet {
            eprintln!("  {msg}");
        }
    };
    if !quiet {
        eprintln!("[solve]");
    }
    let solution = hbm::solve(
        &model.system,
        model.contact.as_ref().map(|c| &c.operator),
        &settings,
        &progress,
    )?;
    for w in &solution.warnings {
        if !quiet {
            eprintln!("warning: {w}");
        }
    }
    if let (false, Some(c)) = (quiet, &solution.contact) {
        print_newton_log(&c.newton.log);
    }
    let t = &solution.timings;
    for (name, secs) in [
        ("factor", t.factor),
        ("linear_solve", t.linear_solve),
        ("reduce", t.reduce),
        ("newton", t.newton),
        ("recover", t.recover),
    ] {
        times.push(name, secs);
    }

    let omega = solution.omega;
    let period = 2.0 * std::f64::consts::PI / omega;
    let frames = p.output.frames;
    let contact_at = |time: f64| -> Option<Vec<f64>> {
        let c = solution.contact.as_ref()?;
        let m = 2 * c.harmonics + 1;
        Some(
            c.multipliers
                .chunks(m)
                .map(|coeffs| fourier::evaluate(coeffs, omega, time)[0])
                .collect(),
        )
    };
    let dofs = &model.system.dofs;
    let snapshot = |time: f64| Snapshot {
        time,
        displacement: solution.field_at(dofs, time, 0),
        velocity: solution.field_at(dofs, time, 1),
        acceleration: solution.field_at(dofs, time, 2),
        contact_force: contact_at(time),
    };

    let staged = StagedDir::create(&out)?;
    copy_mesh(&mesh_info, staged.path())?;
    let dir = staged.path().to_path_buf();
    let summary = times.time("write", quiet, || {
        let snapshots: Vec<Snapshot> = (0..frames).map(|j| snapshot(j as f64 * period / frames as f64)).collect();
        report::write_series(&dir, &model, &snapshots, &p.output.fields)?;
        let amplitudes: Vec<_> = solution.harmonics().into_iter().map(|k| (k, solution.amplitude(dofs, k))).collect();
        report::write_amplitudes(&dir.join("amplitudes.vtu"), &model, &amplitudes)?;
        // Histories at the solver's samples (at least 4 per frame) for accurate amplitudes.
        let n_hist = settings.samples.max(4 * frames).max(64);
        let hist_times: Vec<f64> = (0..n_hist).map(|j| j as f64 * period / n_hist as f64).collect();
        let hist_u: Vec<Vec<f64>> = hist_times.iter().map(|&t| solution.field_at(dofs, t, 0)).collect();
        report::write_probes(&dir.join("probes.csv"), &model, &hist_times, &hist_u)?;
        let mut contact_json = Value::Null;
        if let Some(c) = &solution.contact {
            let forces: Vec<Vec<f64>> = hist_times.iter().filter_map(|&t| contact_at(t)).collect();
            let gaps: Vec<Vec<f64>> = hist_u.iter().map(|u| report::contact_gaps(&model, u)).collect();
            report::write_contact_history(&dir.join("contact.csv"), &model, &hist_times, &gaps, &forces)?;
            let (peak, mean) = contact_force_stats(&forces);
            let max_pen = gaps.iter().flatten().cloned().fold(0.0, f64::max);
            contact_json = json!({
                "harmonics": c.harmonics,
                "samples": c.samples,
                "c": c.c,
                "newton_iterations": c.newton.iterations,
                "relative_residual": c.newton.relative_residual,
                "ladder": c.ladder,
                "complementarity": c.complementarity,
                "max_sampled_penetration": c.complementarity.max_penetration,
                "max_penetration_on_history": max_pen,
                "peak_contact_force": peak,
                "mean_contact_force": mean,
                "newton_log": c.newton.log,
            });
        }
        let mut effects = serde_json::to_value(&model.effects).unwrap_or(Value::Null);
        if let Value::Object(map) = &mut effects {
            map.insert("harmonics_computed".into(), json!(solution.harmonics()));
            map.insert(
                "arithmetic".into(),
                json!(if solution.complex_arithmetic { "complex" } else { "real" }),
            );
        }
        Ok(json!({
            "name": p.name,
            "mode": "harmonic_balance",
            "pipeline": p.source,
            "frequency_hz": p.harmonic_balance.frequency,
            "period_s": period,
            "mesh": mesh_info,
            "effects": effects,
            "sizes": sizes(&model),
            "contact_setup": contact_setup(&model),
            "linear_residuals": solution.residuals.iter().map(|(k, r)| (k.to_string(), json!(r))).collect::<serde_json::Map<_, _>>(),
            "contact": contact_json,
            "probes": probe_amplitudes(&model, &hist_u),
            "warnings": solution.warnings,
            "frames": frames,
        }))
    })?;
    finish(staged, summary, &times, quiet)
}

/// The mesh the run used, next to its results (`mesh.msh`), so the output stands alone.
fn copy_mesh(mesh_info: &Value, dir: &Path) -> Result<()> {
    if let Some(msh) = mesh_info["msh"].as_str() {
        let target = dir.join("mesh.msh");
        std::fs::copy(msh, &target).map_err(|e| Error::io(&target, e))?;
    }
    Ok(())
}

/// The contact Newton's log, one line per iteration (long logs are elided in the middle).
fn print_newton_log(log: &[hbm::IterationLog]) {
    for (i, l) in log.iter().enumerate() {
        if i < 30 || i + 5 >= log.len() {
            eprintln!(
                "    iteration {i:>3}: residual {:.3e}, active samples {:>5}, step {}",
                l.residual, l.active_samples, l.step
            );
        } else if i == 30 {
            eprintln!("    …");
        }
    }
}

fn finish(
    staged: StagedDir,
    mut summary: Value,
    times: &StageTimes,
    quiet: bool,
) -> Result<PathBuf> {
    if let Value::Object(map) = &mut summary {
        map.insert("stage_seconds".into(), times.to_json());
    }
    write_json(&staged.path().join("summary.json"), &summary)?;
    let out = staged.commit()?;
    if !quiet {
        eprintln!("wrote {}", out.display());
        if let Some(effects) = summary.get("effects") {
            eprintln!("simulated: {effects}");
        }
    }
    Ok(out)
}

/// `hbcontact transient`: explicit time marching from rest to the periodic state.
pub fn run_transient(p: &Pipeline, options: &RunOptions) -> Result<PathBuf> {
    let quiet = options.quiet;
    let out = output_dir(p, options);
    let mut times = StageTimes::default();
    let (mesh, mesh_info) = mesh_stage(p, &out, &mut times, quiet)?;
    let model = times.time("assemble", quiet, || build(p, mesh, Purpose::Transient))?;
    let system = &model.system;
    let dofs = &system.dofs;
    let Some(diag) = &model.mass_diagonal else {
        return Err(Error::Model(
            "internal: transient needs a diagonal mass".into(),
        ));
    };
    let mass: Vec<f64> = dofs.free.iter().map(|&d| diag[d]).collect();
    let omega = system.omega;
    let period = 2.0 * std::f64::consts::PI / omega;
    let loads: Vec<(usize, Vec<faer::c64>)> =
        system.inputs.keys().map(|&k| (k, system.load(k))).collect();
    let force = move |t: f64, f: &mut [f64]| {
        f.iter_mut().for_each(|v| *v = 0.0);
        for (k, z) in &loads {
            let rot = faer::c64::from_polar(1.0, *k as f64 * omega * t);
            for (fi, zi) in f.iter_mut().zip(z) {
                *fi += (zi * rot).re;
            }
        }
    };
    if let Some(c) = &model.contact {
        let moving = system
            .inputs
            .iter()
            .any(|(_, i)| i.motion.iter().any(|z| z.norm() != 0.0));
        if c.operator.b_prescribed.nnz() > 0 && moving {
            return Err(Error::Model(
                "transient mode does not support prescribed motion on contact nodes; hold them \
                 with boundaries.fixed or move the prescribed group"
                    .into(),
            ));
        }
    }
    let contact_rows = model.contact.as_ref().map(|c| transient::ContactRows {
        b: &c.operator.b_free,
        g0: &c.operator.g0,
    });
    let probes: Vec<usize> = model
        .probes
        .iter()
        .flat_map(|(_, nodes)| nodes.iter().flat_map(|&n| [2 * n, 2 * n + 1]))
        .filter_map(|d| (dofs.free_of[d] != usize::MAX).then_some(dofs.free_of[d]))
        .collect();
    let problem = transient::TransientProblem {
        stiffness: &system.k_ff,
        mass: &mass,
        rayleigh: system.rayleigh,
        force: &force,
        contact: contact_rows,
        period,
        probes,
    };
    let frames = p.output.frames;
    let settings = transient::TransientSettings {
        courant: p.transient.courant,
        periodic_tolerance: p.transient.periodic_tolerance,
        max_periods: p.transient.max_periods,
        samples_per_period: frames,
    };
    let progress = |period: usize, change: f64| {
        if !quiet && (period < 10 || period.is_multiple_of(10)) {
            eprintln!("  period {period}: change {change:.3e}");
        }
    };
    if !quiet {
        eprintln!("[march]");
    }
    let start = Instant::now();
    let result = transient::run_to_periodic(&problem, &settings, Some(&progress))?;
    times.push("march", start.elapsed().as_secs_f64());

    let to_global = |free: &[f64], t: f64, derivative: u32| -> Vec<f64> {
        let mut u = vec![0.0; dofs.total()];
        for (i, &d) in dofs.free.iter().enumerate() {
            u[d] = free[i];
        }
        for (&k, input) in &system.inputs {
            let kw = k as f64 * omega;
            let f = faer::c64::from_polar(1.0, kw * t) * faer::c64::new(0.0, kw).powu(derivative);
            for (i, &d) in dofs.prescribed.iter().enumerate() {
                u[d] += (input.motion[i] * f).re;
            }
        }
        u
    };
    let staged = StagedDir::create(&out)?;
    copy_mesh(&mesh_info, staged.path())?;
    let dir = staged.path().to_path_buf();
    let summary = times.time("write", quiet, || {
        let snapshots: Vec<Snapshot> = (0..result.times.len())
            .map(|j| {
                let t = result.times[j];
                Snapshot {
                    time: t,
                    displacement: to_global(&result.displacement[j], t, 0),
                    velocity: to_global(&result.velocity[j], t, 1),
                    acceleration: to_global(&result.acceleration[j], t, 2),
                    contact_force: model
                        .contact
                        .as_ref()
                        .map(|_| result.contact_force[j].clone()),
                }
            })
            .collect();
        report::write_series(&dir, &model, &snapshots, &p.output.fields)?;
        let us: Vec<Vec<f64>> = snapshots.iter().map(|s| s.displacement.clone()).collect();
        report::write_probes(&dir.join("probes.csv"), &model, &result.times, &us)?;
        let mut contact_json = Value::Null;
        if model.contact.is_some() {
            let gaps: Vec<Vec<f64>> = us.iter().map(|u| report::contact_gaps(&model, u)).collect();
            report::write_contact_history(
                &dir.join("contact.csv"),
                &model,
                &result.times,
                &gaps,
                &result.contact_force,
            )?;
            let totals = &result.total_contact_history;
            let peak = totals.iter().map(|v| -v).fold(0.0, f64::max);
            let mean = -totals.iter().sum::<f64>() / totals.len().max(1) as f64;
            contact_json = json!({
                "peak_contact_force": peak,
                "mean_contact_force": mean,
                "max_sampled_penetration": gaps.iter().flatten().cloned().fold(0.0, f64::max),
            });
        }
        // Probe amplitudes from every step of the last period.
        let mut probe_json = serde_json::Map::new();
        for (j, h) in result.probe_history.iter().enumerate() {
            let max = h.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let min = h.iter().cloned().fold(f64::INFINITY, f64::min);
            probe_json.insert(format!("probe_dof_{j}"), json!(0.5 * (max - min)));
        }
        Ok(json!({
            "name": p.name,
            "mode": "transient",
            "pipeline": p.source,
            "frequency_hz": p.harmonic_balance.frequency,
            "period_s": period,
            "mesh": mesh_info,
            "effects": model.effects,
            "sizes": sizes(&model),
            "contact_setup": contact_setup(&model),
            "transient": {
                "dt": result.dt,
                "steps_per_period": result.steps_per_period,
                "periods": result.periods,
                "converged": result.converged,
                "periodicity_error": result.periodicity_error,
            },
            "contact": contact_json,
            "probes": probe_amplitudes(&model, &us),
            "probe_dof_amplitudes": probe_json,
            "frames": frames,
        }))
    })?;
    if !result.converged && !quiet {
        eprintln!(
            "warning: not periodic after {} periods (change {:.3e} > {:.1e}); raise transient.max_periods or add damping",
            result.periods, result.periodicity_error, p.transient.periodic_tolerance
        );
    }
    finish(staged, summary, &times, quiet)
}
