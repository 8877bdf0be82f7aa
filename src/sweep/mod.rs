//! `hbcontact sweep`: a frequency-response curve of a pipeline's scene, by the continuation of
//! `hbm::sweep`, written as `<output.directory>/sweep/` (staged, then committed):
//! `sweep.csv` (one row per point: frequency, the outputs, how the point was found) and
//! `sweep.json` (the typed `SweepSummary`: folds, why it stopped, stage times).
//!
//! Each point's outputs are read from the same typed `Summary` a single-frequency `run`
//! produces at that frequency (`study::outputs` names them), so a sweep point and a run agree
//! by construction.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use schemars::JsonSchema;
use serde::Serialize;

use crate::config::{Pipeline, SweepSpec};
use crate::hbm::sweep::{self as continuation, Corrector, Fold, PointInfo, SweepSettings};
use crate::hbm::{ContactSolution, Solution};
use crate::mesh::Mesh2d;
use crate::output::tables::{write_json, write_text};
use crate::output::StagedDir;
use crate::pipeline::report::Sampled;
use crate::pipeline::stability::{self, Stability};
use crate::pipeline::summary::MeshInfo;
use crate::pipeline::{self, build, hb_settings, Model, Purpose, RunOptions, Stages};
use crate::progress::{Reporter, Silent};
use crate::study::outputs::Output;
use crate::study::table::csv_number;
use crate::{Error, Result};

/// The outputs every sweep tabulates.
pub fn outputs() -> Vec<Output> {
    vec![
        Output::ProbeFirstHarmonic,
        Output::ProbePeakToPeak,
        Output::PeakContactForce,
        Output::MeanContactForce,
        Output::ContactFraction,
    ]
}

/// One row of sweep.csv.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct SweepRow {
    pub index: usize,
    pub frequency_hz: f64,
    /// The outputs of `outputs()`, in order (NaN when the scene lacks one).
    pub values: Vec<f64>,
    pub corrector: Corrector,
    pub newton_iterations: usize,
    pub factorizations: usize,
    pub step: f64,
    pub tangent_frequency: f64,
    pub seconds: f64,
    /// The stability verdict at this point (`None`: not checked, or undecided).
    pub stable: Option<bool>,
    /// The estimated largest Floquet multiplier modulus (`pipeline::stability`), where the
    /// point was checked by marching.
    pub multiplier: Option<f64>,
}

/// A fold as the user reads it.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct FoldReport {
    /// Where the curve turns [Hz] (τ_ω interpolated to zero between two points).
    pub frequency_hz: f64,
    /// The row before it.
    pub after: usize,
    /// The first output (probe first harmonic) at the nearer of the two points.
    pub amplitude: f64,
}

/// What `sweep.json` holds.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct SweepSummary {
    pub name: String,
    pub from_hz: f64,
    pub to_hz: f64,
    pub harmonics: usize,
    pub points: usize,
    /// Column names of `values` in the rows.
    pub columns: Vec<String>,
    pub folds: Vec<FoldReport>,
    /// Why the curve stops short of `to_hz` (`None`: it reached it).
    pub stopped: Option<String>,
    /// What the mesh and model checks found (as `run` reports them).
    pub warnings: Vec<String>,
    pub rows: Vec<SweepRow>,
    /// Wall time [s]: mesh, assemble, the continuation (factorizations and each point's
    /// outputs included), write.
    pub stage_seconds: pipeline::StageTimes,
    /// The continuation's solver phases [s] summed over every point and rejected attempt:
    /// factorizations, linear solves, reductions, the correctors (`newton`: Newton, bordered
    /// solves and ∂g/∂ω) and the recoveries.
    pub solver_seconds: crate::hbm::Timings,
}

/// A finished sweep.
pub struct SweepResult {
    pub dir: PathBuf,
    pub summary: SweepSummary,
}

/// The sweep's output directory: `<output.directory>/sweep`, or `--out`.
pub fn output_dir(p: &Pipeline, options: &RunOptions) -> PathBuf {
    options
        .out
        .clone()
        .unwrap_or_else(|| p.output.directory.join("sweep"))
}

/// `hbcontact sweep`: mesh, assemble, continue along ω, write.
pub fn run(p: &Pipeline, options: &RunOptions, reporter: &dyn Reporter) -> Result<SweepResult> {
    let spec = p.sweep.clone().ok_or_else(|| Error::Config {
        path: p.source.clone(),
        message:
            "the pipeline has no `sweep` block: add one, e.g. `sweep: {from: 1100, to: 1400}` (Hz)"
                .into(),
    })?;
    let out = output_dir(p, options);
    crate::output::staging::remove_stale_partials(&out, reporter);
    let mut stages = Stages::new(p, reporter);
    let (mesh, mesh_info) = pipeline::stages::mesh(p, &out, &mut stages)?;
    let mut warnings = stages.run("check", || pipeline::sanity::check_mesh(p, &mesh))?;
    let model = stages.run("assemble", || {
        build(p, mesh.clone(), Purpose::HarmonicBalance)
    })?;
    warnings.extend(pipeline::sanity::check_initial_penetration(&model));
    let clock = Instant::now();
    let (mut rows, starts, outcome) = continue_curve(p, &spec, &model, &mesh_info, reporter)
        .map_err(|e| stages.context("sweep", e))?;
    stages.times.push("sweep", clock.elapsed().as_secs_f64());
    stages.run("stability", || {
        judge_points(
            p,
            mesh,
            &model,
            &mut rows,
            &starts,
            &outcome.folds,
            reporter,
        )
    })?;
    let folds = outcome
        .folds
        .iter()
        .map(|f| fold_report(f, &rows))
        .collect();
    let mut summary = SweepSummary {
        name: p.name.clone(),
        from_hz: spec.from_hz,
        to_hz: spec.to_hz,
        harmonics: p.harmonic_balance.harmonics,
        points: rows.len(),
        columns: outputs().iter().map(Output::name).collect(),
        folds,
        stopped: outcome.stopped,
        warnings,
        rows,
        stage_seconds: Default::default(),
        solver_seconds: outcome.timings,
    };
    let staged = StagedDir::create(&out)?;
    stages.run("write", || {
        write_text(&staged.path().join("sweep.csv"), &csv(&summary))
    })?;
    summary.stage_seconds = stages.times;
    write_json(&staged.path().join("sweep.json"), &summary)?;
    let dir = staged.commit()?;
    Ok(SweepResult { dir, summary })
}

/// The continuation, each point read into a row through the run's own summary.
fn continue_curve(
    p: &Pipeline,
    spec: &SweepSpec,
    model: &Model,
    mesh: &MeshInfo,
    reporter: &dyn Reporter,
) -> Result<(Vec<SweepRow>, Vec<Start>, continuation::SweepOutcome)> {
    let hb = hb_settings(p);
    let two_pi = 2.0 * std::f64::consts::PI;
    let settings = SweepSettings {
        omega_start: two_pi * spec.from_hz,
        omega_end: two_pi * spec.to_hz,
        step: spec.step,
        min_step: spec.min_step,
        max_step: spec.max_step,
        max_points: spec.max_points,
        max_change: spec.max_change,
    };
    let mut system = model.system.clone();
    let contact = model.contact.as_ref().map(|c| &c.operator);
    let (mut rows, mut starts) = (Vec::new(), Vec::new());
    let mut on_point = |info: &PointInfo, solution: &Solution| -> Result<()> {
        rows.push(row(p, model, mesh, info, solution));
        starts.push((info.omega, solution.contact.clone()));
        Ok(())
    };
    let outcome = continuation::sweep(
        &mut system,
        contact,
        &hb,
        &settings,
        reporter,
        &mut on_point,
    )?;
    Ok((rows, starts, outcome))
}

/// A point's ω and contact solution: where a stability check starts from.
type Start = (f64, Option<ContactSolution>);

/// Stage `stability`: the verdict at every `stability.every`-th point and on both sides of
/// every fold (`pipeline::stability`; contact scenes by marching, the points in parallel).
fn judge_points(
    p: &Pipeline,
    mesh: Mesh2d,
    model: &Model,
    rows: &mut [SweepRow],
    starts: &[Start],
    folds: &[Fold],
    reporter: &dyn Reporter,
) -> Result<()> {
    let spec = &p.stability;
    if model.contact.is_none() {
        let verdict = stability::linear(model);
        rows.iter_mut().for_each(|r| r.stable = verdict.stable());
        return Ok(());
    }
    if !spec.check {
        return Ok(());
    }
    let beside_fold = |i: usize| folds.iter().any(|f| i == f.after || i == f.after + 1);
    let chosen: Vec<usize> = (0..rows.len())
        .filter(|&i| i % spec.every == 0 || beside_fold(i) || i + 1 == rows.len())
        .collect();
    let marching = build(p, mesh, Purpose::Transient)?;
    let done = AtomicUsize::new(0);
    let total = Some(chosen.len() as u64);
    let verdicts: Vec<Result<Stability>> = chosen
        .par_iter()
        .map(|&i| {
            let (omega, start) = &starts[i];
            let verdict =
                stability::by_marching(p, spec, &marching, *omega, start.as_ref(), &Silent);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            reporter.progress("stability", n as u64, total, "points checked by marching");
            verdict
        })
        .collect();
    reporter.task_done("stability");
    for (&i, verdict) in chosen.iter().zip(verdicts) {
        let verdict = verdict.unwrap_or_else(|e| Stability::cannot_march(&e));
        rows[i].stable = verdict.stable();
        rows[i].multiplier = verdict.multiplier;
    }
    Ok(())
}

/// One point's row: the outputs a single-frequency run's summary would give.
fn row(
    p: &Pipeline,
    model: &Model,
    mesh: &MeshInfo,
    info: &PointInfo,
    solution: &Solution,
) -> SweepRow {
    let samples = solution
        .contact
        .as_ref()
        .map_or(hb_settings(p).samples, |c| c.samples);
    let sampled = Sampled::harmonic_balance(model, solution, p.output.frames, samples);
    let summary = pipeline::summary::harmonic_balance(p, mesh.clone(), model, solution, &sampled);
    SweepRow {
        index: info.index,
        frequency_hz: info.omega / (2.0 * std::f64::consts::PI),
        values: outputs().iter().map(|o| o.value(&summary, None)).collect(),
        corrector: info.corrector,
        newton_iterations: info.newton_iterations,
        factorizations: info.factorizations,
        step: info.step,
        tangent_frequency: info.tangent_omega,
        seconds: info.seconds,
        stable: None,
        multiplier: None,
    }
}

fn fold_report(f: &Fold, rows: &[SweepRow]) -> FoldReport {
    let frequency_hz = f.omega / (2.0 * std::f64::consts::PI);
    let nearer = [f.after, f.after + 1]
        .into_iter()
        .filter_map(|i| rows.get(i))
        .min_by(|a, b| {
            (a.frequency_hz - frequency_hz)
                .abs()
                .total_cmp(&(b.frequency_hz - frequency_hz).abs())
        });
    FoldReport {
        frequency_hz,
        after: f.after,
        amplitude: nearer.map_or(f64::NAN, |r| r.values[0]),
    }
}

/// sweep.csv: frequency, the outputs, then how each point was found.
pub fn csv(s: &SweepSummary) -> String {
    let mut text = format!(
        "index,frequency_hz,{},stable,multiplier,corrector,newton_iterations,factorizations,step,tangent_frequency,seconds\n",
        s.columns.join(",")
    );
    for r in &s.rows {
        let values: Vec<String> = r.values.iter().map(|&v| csv_number(v)).collect();
        let corrector = serde_json::to_value(r.corrector)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let stable = r.stable.map_or(String::new(), |s| s.to_string());
        let multiplier = r.multiplier.map_or(String::new(), csv_number);
        text.push_str(&format!(
            "{},{},{},{stable},{multiplier},{corrector},{},{},{},{},{}\n",
            r.index,
            csv_number(r.frequency_hz),
            values.join(","),
            r.newton_iterations,
            r.factorizations,
            csv_number(r.step),
            csv_number(r.tangent_frequency),
            csv_number(r.seconds)
        ));
    }
    text
}

/// The JSON Schema of sweep.json.
pub fn sweep_schema() -> serde_json::Value {
    serde_json::to_value(schemars::schema_for!(SweepSummary)).unwrap_or_default()
}
