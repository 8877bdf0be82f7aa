//! `hbcontact sweep`: a frequency-response curve of a pipeline's scene, by the continuation of
//! `hbm::continuation`, written as `<output.directory>-sweep/` or `--out` (staged, then committed):
//! - `sweep.csv` (one row per point: frequency, the outputs, how the point was found) and
//!   `sweep.json` (the typed `SweepSummary`: folds, why it stopped, what `--resume` needs);
//! - `sweep.svg`/`.png` and (contact scenes) `sweep_force.svg`/`.png`: the curves (`plot`);
//! - `frames.pvd` + `frames/point_XXXX.vtu`: every `save_every`-th point (`points`);
//! - `points/<why>/`: the full output of a `run` at every fold, the peak and the points
//!   nearest `sweep.write_at` (`points`).
//!
//! A sweep that fails part-way keeps the curve so far: everything above is written for the
//! points found, `stopped` says where and why, and the error comes back in
//! `SweepResult::failure` (main exits with its class). `resume` continues a saved sweep from
//! its last point (`resume`).
//!
//! Each point's outputs are read from the same typed `Summary` a single-frequency `run`
//! produces at that frequency (`pipeline::outputs` names them), so a sweep point and a run agree
//! by construction.

mod again;
pub mod bifurcations;
pub mod branch;
pub mod other_end;
mod plot;
mod points;
pub mod reference;
mod resume;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::config::{Pipeline, StabilityMethod, SweepSpec};
use crate::hbm::basis::TimeBasis;
use crate::hbm::continuation::{self, ContinuationState, Corrector, SweepSettings};
use crate::hbm::floquet::{self, Crossing};
use crate::hbm::hill::HillModel;
use crate::hbm::knobs::{underdamped_from, UNDERDAMPED_TOLERANCE};
use crate::hbm::ContactSolution;
use crate::output::staging::Replace as StagedReplace;
use crate::output::tables::csv_number;
use crate::output::tables::{write_json, write_text};
use crate::output::StagedDir;
use crate::pipeline::outputs::Output;
use crate::pipeline::report::Sampled;
use crate::pipeline::stability::{self, Stability};
use crate::pipeline::summary::MeshInfo;
use crate::pipeline::{self, build, hb_settings, Model, Purpose, RunOptions, Stage, Stages};
use crate::progress::{Reporter, Silent};
use crate::{Error, Result};
use bifurcations::BifurcationReport;

pub use plot::WARNED;
pub use points::WrittenPoint;

/// The outputs a sweep of `p` tabulates: the response (`pipeline::outputs::RESPONSE`), with
/// friction the energy it dissipates per period, the peak tangential force and the slip share.
pub fn outputs(p: &Pipeline) -> Vec<Output> {
    let frictional = (p.contact.iter().flat_map(|c| &c.pairs)).any(|c| c.friction > 0.0);
    let friction = [
        Output::DissipatedEnergy,
        Output::PeakTangentialForce,
        Output::SlipShare,
    ];
    let friction = friction.into_iter().filter(|_| frictional);
    crate::pipeline::outputs::RESPONSE
        .into_iter()
        .chain(friction)
        .collect()
}

/// One row of sweep.csv.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
pub struct SweepRow {
    pub index: usize,
    pub frequency_hz: f64,
    /// The outputs of `outputs(p)`, in order (NaN, in JSON null, when the scene lacks one).
    #[serde(deserialize_with = "nan_for_null")]
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
    /// Floquet: the largest multiplier's argument [rad], in [0, π].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub argument: Option<f64>,
    /// Floquet: how the largest multiplier crosses (unstable) or would cross (stable) the
    /// unit circle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crossing: Option<Crossing>,
    /// Spline basis with contact: the share of the contact nodes' vibration in the basis'
    /// underdamped discrete frequencies (`hbm::knobs::underdamped_share`; the summary warns
    /// over the rows above `UNDERDAMPED_TOLERANCE`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub underdamped_share: Option<f64>,
    /// H of the point's contact solve: chosen per point within `harmonic_balance.harmonics:
    /// {min, max}`, else the pipeline's (0 in sweeps saved before the column existed).
    #[serde(default)]
    pub harmonics: usize,
    /// With H chosen per point: the point's truncation estimate, the relative change of the
    /// answer from ⌊H/2⌋ to H (`hbm::continuation` levels); above the tolerance only at
    /// H = max, where the summary warns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truncation_estimate: Option<f64>,
    /// On a 2T branch (`branch`): the probe's amplitude at half the drive frequency [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subharmonic: Option<f64>,
}

#[cfg(test)]
impl SweepRow {
    /// A row at `frequency_hz` found by the arc-length corrector, unjudged, with one value 1.
    pub(crate) fn for_tests(index: usize, frequency_hz: f64) -> Self {
        SweepRow {
            index,
            frequency_hz,
            values: vec![1.0],
            corrector: Corrector::Arclength,
            newton_iterations: 1,
            factorizations: 1,
            step: 0.01,
            tangent_frequency: 1.0,
            seconds: 0.0,
            stable: None,
            multiplier: None,
            argument: None,
            crossing: None,
            underdamped_share: None,
            harmonics: 10,
            truncation_estimate: None,
            subharmonic: None,
        }
    }
}

impl SweepRow {
    /// The row's underdamped share where it is above `UNDERDAMPED_TOLERANCE` (the rows the
    /// summary's warning counts and the plot marks).
    pub fn underdamped(&self) -> Option<f64> {
        self.underdamped_share
            .filter(|&v| v > UNDERDAMPED_TOLERANCE)
    }

    /// A row solved at H = `max` whose truncation estimate is above `tolerance` or unknown
    /// (with H chosen per point).
    pub fn unsettled(&self, max: usize, tolerance: f64) -> bool {
        self.harmonics == max && self.truncation_estimate.is_none_or(|e| e > tolerance)
    }
}

/// JSON writes NaN as null; read it back as NaN.
fn nan_for_null<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Vec<f64>, D::Error> {
    let values: Vec<Option<f64>> = Deserialize::deserialize(d)?;
    Ok(values.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
}

fn nan_for_null_one<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<f64, D::Error> {
    let value: Option<f64> = Deserialize::deserialize(d)?;
    Ok(value.unwrap_or(f64::NAN))
}

/// A fold as the user reads it.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
pub struct FoldReport {
    /// Where the curve turns back [Hz]: the frequency of the point where ω turns (within one
    /// step of the fold).
    pub frequency_hz: f64,
    /// That point's row.
    pub after: usize,
    /// The first output (probe first harmonic) at that point (NaN, in JSON null, without a
    /// probe).
    #[serde(deserialize_with = "nan_for_null_one")]
    pub amplitude: f64,
}

/// Why a sweep ended before `to_hz`.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
pub struct Stopped {
    /// The last point of the curve [Hz] (where `--resume` continues).
    pub frequency_hz: f64,
    /// Its row.
    pub point: usize,
    /// `max_points` (the budget ran out: exit 0), `unstable_stretch` (stopped among unstable
    /// states, the curve from the other end covering the rest: exit 0, `other_end`), else the
    /// error class of the exit code: `not_converged` (4), `model` (3), `io` (5),
    /// `interrupted` (130).
    pub class: String,
    pub reason: String,
}

/// What `sweep.json` holds.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct SweepSummary {
    pub name: String,
    pub from_hz: f64,
    pub to_hz: f64,
    pub harmonics: usize,
    /// The time basis: `fourier` (with `harmonics`) or `spline (degree p, S segments)`.
    pub basis: String,
    pub points: usize,
    /// Column names of `values` in the rows.
    pub columns: Vec<String>,
    pub folds: Vec<FoldReport>,
    /// Where the states change stability other than at a fold, and how
    /// (`sweep::bifurcations`): period doublings, Neimark–Sacker bifurcations, branch points
    /// and grazings, each located between two judged rows.
    pub bifurcations: Vec<BifurcationReport>,
    /// Why the curve stops short of `to_hz` (`None`: it reached it).
    pub stopped: Option<Stopped>,
    /// What the mesh and model checks found (as `run` reports them).
    pub warnings: Vec<String>,
    pub rows: Vec<SweepRow>,
    /// The rows written as frames of `frames.pvd` (its "time" is the row index).
    pub frames: Vec<usize>,
    /// The points written with a run's full output under `points/`.
    pub written: Vec<WrittenPoint>,
    /// The rows each `--resume` continued from (empty: swept in one go).
    pub resumed_from: Vec<usize>,
    /// The continuation's state at the last row: what `hbcontact sweep --resume` continues
    /// from, as the uninterrupted sweep would have (index, ω [rad/s], the next step, the unit
    /// direction τ in the scaled unknowns (its last entry τ_ω < 0 on a branch running back),
    /// the multipliers, the scaling F, the c and N of the curve, the largest ‖λ‖, the
    /// reduced model's lessons and the kind of the point's frame, the Krylov hint, and the
    /// trail of the points before it).
    pub resume: Option<ContinuationState>,
    /// Wall time [s] of this invocation: mesh, assemble, the continuation (factorizations,
    /// each point's outputs and frames included), points (the full outputs), write, plots.
    /// Hill's verdicts are found beside the continuation, on the other cores: `stability` is
    /// the time the continuation waited for them, and their work shows as a slower `sweep`
    /// (what the check costs is this sweep's time against one with `stability.check: false`).
    pub stage_seconds: pipeline::StageTimes,
    /// The continuation's solver phases [s] summed over every point and rejected attempt:
    /// factorizations, linear solves, reductions, the correctors (`newton`: Newton, bordered
    /// solves and ∂g/∂ω) and the recoveries.
    pub solver_seconds: crate::hbm::Timings,
    /// The reduced model of Z_k(ω)⁻¹ the frames came from (docs/method.md, "Reduced
    /// frames"): its dimension, the frames it gave, the points whose check failed and were
    /// solved again on factored frames, and the largest backward error of a point it kept.
    /// Dimension 0: every frame was factored.
    pub reduced_frames: crate::hbm::continuation::ReducedFrames,
    /// A contact sweep with plots: the probe's first-harmonic amplitude with the contact open
    /// over the band, drawn dashed on `sweep.png` (`sweep::reference`); `None` without a
    /// probe or a harmonic-1 load.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub linear_reference: Option<reference::LinearReference>,
    /// The initial gap [m] where the probe sits on the contact against a fixed rigid obstacle
    /// (`sweep::reference::probe_gap`), drawn on `sweep.png`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub probe_gap: Option<f64>,
    /// With H chosen per point (`harmonic_balance.harmonics: {min, max}`): the range, the
    /// tolerance, the points solved at each H and the changes of H along the curve.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harmonics_chosen: Option<HarmonicsAlong>,
    /// The 2T branches followed from the period doublings (`sweep.follow_period_doubling`),
    /// each also in `branch_K.csv`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub branches: Vec<branch::Branch>,
    /// The sweep stopped short and was swept again from its start with a turn limit per
    /// step (`again`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub swept_again: Option<again::SweptAgain>,
    /// Times the continuation ran back along a sliver of the sampled contact law (a thin
    /// sheet of its solutions that leaves the curve and turns back along it) and was led round
    /// it from where it left (docs/method.md, "Slivers"); the sliver's points stay in the rows.
    pub slivers: usize,
    /// The sweep stopped among unstable states and was swept from the other end of its range
    /// (`other_end`), into `from_the_end/`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from_the_end: Option<other_end::FromTheEnd>,
}

/// How H was chosen along a curve.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct HarmonicsAlong {
    pub min: usize,
    pub max: usize,
    pub tolerance: f64,
    /// (H, points solved at it), by H.
    pub points: Vec<(usize, usize)>,
    /// Times the curve moved to another H.
    pub changes: usize,
    /// Points at H = max whose truncation estimate is above the tolerance (or unknown):
    /// the points the summary warns of and the plots mark.
    pub unsettled: usize,
}

impl HarmonicsAlong {
    fn of(rows: &[SweepRow], (min, max, tolerance): (usize, usize, f64), changes: usize) -> Self {
        let mut points: Vec<(usize, usize)> = Vec::new();
        for r in rows {
            match points.iter_mut().find(|(h, _)| *h == r.harmonics) {
                Some((_, n)) => *n += 1,
                None => points.push((r.harmonics, 1)),
            }
        }
        points.sort_unstable();
        let unsettled = rows.iter().filter(|r| r.unsettled(max, tolerance)).count();
        HarmonicsAlong {
            min,
            max,
            tolerance,
            points,
            changes,
            unsettled,
        }
    }
}

impl SweepSummary {
    /// How finely the curve is resolved in time, for headlines and plot titles: `H = 10`,
    /// `H = 10–40 per point`, or the spline basis.
    pub fn resolution(&self) -> String {
        match &self.harmonics_chosen {
            Some(c) => format!("H = {}–{} per point", c.min, c.max),
            None if self.basis == crate::hbm::basis::TimeBasis::Fourier.describe() => {
                format!("H = {}", self.harmonics)
            }
            None => self.basis.clone(),
        }
    }

    /// Rows a warning names: in a spline basis' underdamped band, or at H = max above the
    /// tolerance.
    pub fn warned(&self, r: &SweepRow) -> bool {
        let unsettled =
            (self.harmonics_chosen.as_ref()).is_some_and(|c| r.unsettled(c.max, c.tolerance));
        r.underdamped().is_some() || unsettled
    }
}

/// A finished sweep, complete or not.
pub struct SweepResult {
    pub dir: PathBuf,
    pub summary: SweepSummary,
    /// The error that stopped the sweep part-way (the curve so far is written); main exits
    /// with its class. `None` also when `max_points` ended it (`summary.stopped` says so).
    pub failure: Option<Error>,
}

/// The sweep's output directory: `--out`, else `output.directory` with `-sweep` appended
/// (`output/<name>-sweep`), beside the run's as `transient` and `modes` write theirs.
pub fn output_dir(p: &Pipeline, options: &RunOptions) -> PathBuf {
    options.out.clone().unwrap_or_else(|| {
        let mut d = p.output.directory.clone().into_os_string();
        d.push("-sweep");
        PathBuf::from(d)
    })
}

static RUNNING: AtomicBool = AtomicBool::new(false);
static STOP: AtomicBool = AtomicBool::new(false);

/// Ask a running sweep to stop after its current point and write the curve so far (the
/// command line's Ctrl-C). Returns false when no sweep runs or one was already asked: the
/// caller then ends the process itself.
pub fn request_stop() -> bool {
    RUNNING.load(Ordering::SeqCst) && !STOP.swap(true, Ordering::SeqCst)
}

/// `hbcontact sweep`: mesh, assemble, continue along ω, write.
pub fn run(p: &Pipeline, options: &RunOptions, reporter: &dyn Reporter) -> Result<SweepResult> {
    execute(p, options, false, reporter)
}

/// `hbcontact sweep --resume`: continue the sweep saved in the output directory from its last
/// point (re-solved there), keeping its rows, frames and written points.
pub fn resume(p: &Pipeline, options: &RunOptions, reporter: &dyn Reporter) -> Result<SweepResult> {
    execute(p, options, true, reporter)
}

/// A contact sweep's reduced frames stand on the pencil of K and M, which the Coriolis force
/// leaves: with it they are refused (exit 2) naming the key that turns them off.
fn refuse_coriolis(p: &Pipeline, spec: &SweepSpec) -> Result<()> {
    let coriolis = p.boundaries.rotation.is_some_and(|r| r.coriolis);
    if !(coriolis && p.contact.is_some() && spec.reduced_frames) {
        return Ok(());
    }
    Err(Error::Config {
        path: p.source.clone(),
        message: "boundaries.rotation.coriolis: the sweep's reduced frames assume a symmetric \
                  Z_k, which the Coriolis force is not; set sweep.reduced_frames: false (exact \
                  frames take it; the points are then judged by time marching)"
            .into(),
    })
}

fn execute(
    p: &Pipeline,
    options: &RunOptions,
    resuming: bool,
    reporter: &dyn Reporter,
) -> Result<SweepResult> {
    let spec = p.sweep.clone().ok_or_else(|| Error::Config {
        path: p.source.clone(),
        message:
            "the pipeline has no `sweep` block: add one, e.g. `sweep: {from: 1100, to: 1400}` (Hz)"
                .into(),
    })?;
    refuse_coriolis(p, &spec)?;
    let out = output_dir(p, options);
    let saved = resuming.then(|| resume::read(&out, p, &spec)).transpose()?;
    let (scene, mut stages) = pipeline::open(p, &out, options, Purpose::HarmonicBalance, reporter)?;
    let pipeline::Scene {
        model,
        mesh_info,
        warnings,
    } = scene;
    if let Some(s) = &saved {
        resume::check_state(s, &model, p, &out)?;
    }
    let finer = again::finer(p);
    let curve = again::Curve {
        p,
        model: &model,
        mesh: &mesh_info,
        saved: saved.as_ref(),
        reporter,
        again_among_unstable: true,
        finer: finer.as_ref(),
    };
    let again = again::turn_limited(&spec);
    let place = (out.as_path(), options.replace, out.as_path());
    let mut traced = trace(&curve, (&spec, &again), place, warnings, &mut stages)?;
    if other_end::called_for(
        &traced.summary,
        traced.failure.as_ref(),
        model.contact.is_some(),
    ) {
        from_the_end(&curve, (&spec, &out), &mut traced, &mut stages)?;
    }
    let Traced {
        staged,
        writer,
        starts,
        mut summary,
        failure,
    } = traced;
    add_period_doublings(p, (&model, &mesh_info), &starts, &mut summary, &mut stages);
    add_reference(p, &model, &mut summary, &mut stages);
    let (dir, summary) = write(p, staged, &writer, summary, stages)?;
    Ok(SweepResult {
        dir,
        summary,
        failure,
    })
}

/// One curve of a sweep, traced (swept again where `again` says), judged and summarized, in
/// its staged folder.
struct Traced<'a> {
    staged: StagedDir,
    writer: points::Writer<'a>,
    starts: Vec<Start>,
    summary: SweepSummary,
    /// The error that stopped it part-way (main exits with its class).
    failure: Option<Error>,
}

/// The curve of `spec` staged for `out`: swept, judged by Hill's method, summarized (a stop
/// among unstable states says so, `bifurcations::unstable_tail`; its resume command names
/// the folder `shown`, where `out` will be once committed).
fn trace<'a>(
    curve: &again::Curve<'a>,
    (spec, again): (&'a SweepSpec, &'a SweepSpec),
    (out, replace, shown): (&Path, StagedReplace, &Path),
    warnings: Vec<String>,
    stages: &mut Stages,
) -> Result<Traced<'a>> {
    let (attempt, swept_again) = curve.sweep((spec, again), out, replace)?;
    let model = curve.model;
    let again::Attempt {
        p,
        staged,
        mut writer,
        starts,
        judging,
        ended,
        seconds,
    } = attempt;
    stages.times.add(Stage::Sweep, seconds - judging);
    let folds: Vec<usize> = writer.folds(spec).iter().map(|f| f.after).collect();
    let reporter = curve.reporter;
    stages.run(Stage::Stability, || {
        judge_points(p, model, &mut writer, &starts, &folds, reporter)
    })?;
    stages.times.add(Stage::Stability, judging);
    let (outcome, failure) = match ended {
        Ok(outcome) => (outcome, None),
        // Nothing found at all (the first point failed): nothing to keep.
        Err(e) if writer.seen() == 0 => return Err(stages.context(Stage::Sweep, e)),
        Err(e) => (Default::default(), Some(e)),
    };
    // A curve that stopped among unstable states says so (judged by now).
    let march = |hz| resume::march_command(p, hz);
    let tail = || bifurcations::unstable_tail(&writer.rows, march).unwrap_or_default();
    let stopped = outcome.stopped.map(|s| Error::NotConverged(s + &tail()));
    let failure = failure.or(stopped).map(|e| stages.context(Stage::Sweep, e));
    let slivers = outcome.slivers;
    let ended = Ended {
        warnings,
        timings: outcome.timings,
        reduced: outcome.reduced,
        level_changes: outcome.level_changes,
        failure,
        out: shown,
    };
    let (mut summary, failure) = summarize(p, spec, &mut writer, curve.saved, ended, stages)?;
    summary.swept_again = swept_again;
    summary.slivers = slivers;
    Ok(Traced {
        staged,
        writer,
        starts,
        summary,
        failure,
    })
}

/// The curve swept from the other end of the range toward `main`'s stop (`other_end`),
/// written whole under `other_end::FOLDER` of `main`'s staged folder (for `out`) with stages
/// of its own
/// (their total counted as `main`'s sweep); what the two cover settles `main`'s failure. A
/// curve from the other end that fails at its first point leaves `main` as it was, saying
/// so.
fn from_the_end(
    curve: &again::Curve,
    (spec, out): (&SweepSpec, &Path),
    main: &mut Traced,
    stages: &mut Stages,
) -> Result<()> {
    let (p, reporter) = (curve.p, curve.reporter);
    let (p_other, spec_other) = other_end::reversed(p, spec);
    let again_other = again::turn_limited(&spec_other);
    let other = again::Curve {
        p: &p_other,
        saved: None,
        again_among_unstable: false,
        finer: None,
        ..*curve
    };
    let status = format!("sweeping from the other end, {} Hz", spec_other.from_hz);
    reporter.progress("sweep", 0, None, &status);
    let dir = main.staged.path().join(other_end::FOLDER);
    let mut own = Stages::new(&p_other, reporter);
    let shown = out.join(other_end::FOLDER);
    let place = (dir.as_path(), StagedReplace::Owned, shown.as_path());
    let traced = match trace(
        &other,
        (&spec_other, &again_other),
        place,
        Vec::new(),
        &mut own,
    ) {
        Ok(t) => t,
        Err(e) => {
            let why = format!(
                "swept from the other end ({} Hz), the curve found no first point: {e}",
                spec_other.from_hz
            );
            main.summary.warnings.push(why);
            return Ok(());
        }
    };
    let (_, written) = write(&p_other, traced.staged, &traced.writer, traced.summary, own)?;
    stages
        .times
        .add(Stage::Sweep, written.stage_seconds.total());
    let march = |hz| resume::march_command(p, hz);
    if other_end::settle(&mut main.summary, written, march) {
        main.failure = None;
    }
    Ok(())
}

/// The period doublings the curve lists checked on the 2T problem (`branch::confirm`, timed
/// with the stability check), and with `sweep.follow_period_doubling` the 2T branch of each
/// (`branch`), judged by Hill's method, which they need (timed with the sweep).
fn add_period_doublings(
    p: &Pipeline,
    (model, mesh): (&Model, &MeshInfo),
    starts: &[Start],
    summary: &mut SweepSummary,
    stages: &mut Stages,
) {
    let doubling = |b: &BifurcationReport| b.kind == bifurcations::BifurcationKind::PeriodDoubling;
    if !summary.bifurcations.iter().any(doubling) {
        return;
    }
    let (clock, reporter) = (Instant::now(), stages.reporter);
    let unconfirmed = branch::confirm(p, model, starts, &mut summary.bifurcations);
    summary.warnings.extend(unconfirmed);
    (stages.times).add(Stage::Stability, clock.elapsed().as_secs_f64());
    let Some(spec) = p.sweep.as_ref().filter(|s| s.follow_period_doubling) else {
        return;
    };
    let clock = Instant::now();
    let Some(hill) = inline_judge(p, model, reporter) else {
        summary.warnings.push(
            "sweep.follow_period_doubling: no 2T branch followed: period doublings are \
             located by Hill's check (stability.method: floquet or both, frictionless \
             contact on a Fourier basis)"
                .into(),
        );
        return;
    };
    let bifurcations = &summary.bifurcations;
    let (branches, warnings) = branch::follow_all(
        p,
        spec,
        (model, mesh),
        starts,
        bifurcations,
        Some(&hill),
        reporter,
    );
    summary.branches = branches;
    summary.warnings.extend(warnings);
    stages
        .times
        .add(Stage::Sweep, clock.elapsed().as_secs_f64());
}

/// The linear reference and the probe's gap of a contact sweep's plot, where plots are drawn
/// (timed with them; a reference that cannot be formed is a warning, not a failed sweep).
fn add_reference(p: &Pipeline, model: &Model, summary: &mut SweepSummary, stages: &mut Stages) {
    if !p.output.plots || model.contact.is_none() {
        return;
    }
    let rows: Vec<f64> = summary.rows.iter().map(|r| r.frequency_hz).collect();
    let band = [summary.from_hz, summary.to_hz];
    match stages.run(Stage::Plots, || {
        reference::linear_reference(model, band, &rows)
    }) {
        Ok(found) => summary.linear_reference = found,
        Err(e) => summary
            .warnings
            .push(format!("the plot has no linear reference: {e}")),
    }
    summary.probe_gap = reference::probe_gap(model);
}

/// How the continuation ended, for the summary.
struct Ended<'a> {
    warnings: Vec<String>,
    timings: crate::hbm::Timings,
    reduced: crate::hbm::continuation::ReducedFrames,
    level_changes: usize,
    failure: Option<Error>,
    out: &'a Path,
}

/// One warning per reason for the points no method could judge (a frictional state's), with
/// how many they are: their `stable` column is empty.
fn unjudged_rows(verdicts: &[(usize, Stability)]) -> Vec<String> {
    let mut reasons: Vec<(&str, usize)> = Vec::new();
    let unjudged = verdicts.iter().map(|(_, v)| v);
    let undecided = |v: &&Stability| v.verdict == stability::Verdict::Undecided;
    for v in unjudged
        .filter(|v| v.method == stability::Method::None)
        .filter(undecided)
    {
        match reasons.iter_mut().find(|(r, _)| *r == v.reason) {
            Some((_, count)) => *count += 1,
            None => reasons.push((&v.reason, 1)),
        }
    }
    (reasons.into_iter())
        .map(|(reason, count)| format!("the stability of {count} points is undecided: {reason}"))
        .collect()
}

/// The curve's summary: the folds, the point folders (written here, stage `points`), why
/// it stopped; the failure handed back.
fn summarize(
    p: &Pipeline,
    spec: &SweepSpec,
    writer: &mut points::Writer,
    saved: Option<&resume::Saved>,
    mut ended: Ended,
    stages: &mut Stages,
) -> Result<(SweepSummary, Option<Error>)> {
    let folds = writer.folds(spec);
    let (written, missing) = stages.run(Stage::Points, || writer.write_points(&folds))?;
    ended.warnings.extend(missing);
    let basis = crate::pipeline::model::time_basis(p, crate::pipeline::Purpose::HarmonicBalance);
    ended
        .warnings
        .extend(underdamped_rows(&writer.rows, &basis));
    ended.warnings.extend(unjudged_rows(&writer.verdicts));
    let stopped = stop_report(spec, writer, ended.failure.as_ref(), ended.out, p);
    let summary = SweepSummary {
        name: p.name.clone(),
        from_hz: spec.from_hz,
        to_hz: spec.to_hz,
        harmonics: p.harmonic_balance.harmonics,
        basis: basis.describe(),
        points: writer.rows.len(),
        columns: outputs(p).iter().map(Output::name).collect(),
        bifurcations: bifurcations::locate(&writer.rows, &folds),
        folds,
        stopped,
        warnings: ended.warnings,
        frames: writer.frame_rows(),
        written,
        resumed_from: resume::resumed_from(saved),
        resume: writer.resume_state(),
        rows: std::mem::take(&mut writer.rows),
        stage_seconds: Default::default(),
        solver_seconds: ended.timings,
        reduced_frames: ended.reduced,
        linear_reference: None,
        probe_gap: None,
        harmonics_chosen: None,
        branches: Vec::new(),
        swept_again: None,
        slivers: 0,
        from_the_end: None,
    };
    let summary = with_harmonics_chosen(p, summary, ended.level_changes);
    Ok((summary, ended.failure))
}

/// With H chosen per point: the summary's account of it, and a warning for the points at
/// H = max that do not meet the tolerance.
fn with_harmonics_chosen(p: &Pipeline, mut s: SweepSummary, changes: usize) -> SweepSummary {
    let hb = &p.harmonic_balance;
    if hb.harmonics_max <= hb.harmonics || !s.rows.iter().any(|r| r.truncation_estimate.is_some()) {
        return s;
    }
    let range = (hb.harmonics, hb.harmonics_max, hb.tolerance);
    let along = HarmonicsAlong::of(&s.rows, range, changes);
    let unsettled: Vec<&SweepRow> = (s.rows.iter())
        .filter(|r| r.unsettled(along.max, along.tolerance))
        .collect();
    if let (Some(first), Some(last)) = (unsettled.first(), unsettled.last()) {
        let worst = unsettled
            .iter()
            .filter_map(|r| r.truncation_estimate)
            .fold(0.0, f64::max);
        s.warnings.push(format!(
            "{} points at H = {} (rows {}–{}, {:.4}–{:.4} Hz) still change by up to {:.2}% from H = {} (harmonic_balance.tolerance = {:.2}%; marked `warned` on the plots): raise harmonic_balance.harmonics.max",
            unsettled.len(),
            along.max,
            first.index,
            last.index,
            first.frequency_hz,
            last.frequency_hz,
            100.0 * worst,
            along.max / 2,
            100.0 * along.tolerance
        ));
    }
    s.harmonics_chosen = Some(along);
    s
}

/// sweep.csv, frames.pvd, the plots and sweep.json (with the stage times) into the staged
/// directory, then commit it.
fn write(
    p: &Pipeline,
    staged: StagedDir,
    writer: &points::Writer,
    mut summary: SweepSummary,
    mut stages: Stages,
) -> Result<(PathBuf, SweepSummary)> {
    stages.run(Stage::Write, || {
        writer.write_pvd()?;
        write_text(&staged.path().join("sweep.csv"), &csv(&summary))?;
        for (k, b) in summary.branches.iter().enumerate() {
            let name = format!("branch_{}.csv", k + 1);
            write_text(&staged.path().join(name), &branch::csv(&summary.columns, b))?;
        }
        Ok(())
    })?;
    if p.output.plots {
        let unit = crate::pipeline::model::material(p).force_unit();
        stages.run(Stage::Plots, || {
            plot::write_plots(staged.path(), &summary, unit)
        })?;
    }
    summary.stage_seconds = stages.times;
    write_json(&staged.path().join("sweep.json"), &summary)?;
    Ok((staged.commit()?, summary))
}

/// The continuation, each point handed to the writer (row, frame, kept solutions) and, with
/// Hill's method, judged beside it (`Judge`; the seconds the continuation waited for the
/// verdicts added to `judging`). A `request_stop` ends it after the current point with
/// `Error::Interrupted`.
fn continue_curve(
    p: &Pipeline,
    spec: &SweepSpec,
    model: &Model,
    writer: &mut points::Writer,
    (starts, judging): (&mut Vec<Start>, &mut f64),
    saved: Option<&resume::Saved>,
    reporter: &dyn Reporter,
) -> Result<continuation::SweepOutcome> {
    let hb = hb_settings(p);
    let settings = SweepSettings {
        harmonics: pipeline::stages::harmonic_range(p),
        ..settings(spec, saved.and_then(|s| s.resume.clone()))
    };
    let mut system = model.system.clone();
    let contact = model.contact.as_ref().map(|c| &c.operator);
    STOP.store(false, Ordering::SeqCst);
    RUNNING.store(true, Ordering::SeqCst);
    let hill = inline_judge(p, model, reporter);
    std::thread::scope(|scope| {
        let judge = hill.as_ref().map(|hill| Judge::start(scope, model, hill));
        let mut on_point = |info: &continuation::PointInfo, solution: &crate::hbm::Solution| {
            writer.point(info, solution)?;
            // A resumed sweep's saved rows keep the verdicts they were saved with.
            let saved_verdict = (writer.rows.iter())
                .any(|r| r.index == info.index && (r.stable.is_some() || r.multiplier.is_some()));
            if let (Some(judge), Some(contact), false) = (&judge, &solution.contact, saved_verdict)
            {
                judge.submit(info.index, info.omega, contact, judging);
                judge.record_done(writer);
            }
            // The compliance is kept only as long as a verdict may need it.
            let contact = solution.contact.clone().map(|c| ContactSolution {
                compliance: None,
                ..c
            });
            starts.push((info.index, info.omega, contact));
            if STOP.load(Ordering::SeqCst) {
                return Err(Error::Interrupted(format!(
                    "interrupted after the point at {:.6} Hz",
                    info.omega / (2.0 * std::f64::consts::PI)
                )));
            }
            Ok(())
        };
        let outcome = continuation::sweep(
            &mut system,
            contact,
            &hb,
            &settings,
            reporter,
            &mut on_point,
        );
        if let Some(judge) = judge {
            judge.finish(writer, judging);
        }
        RUNNING.store(false, Ordering::SeqCst);
        outcome
    })
}

/// Points waiting for Hill's verdict before the continuation blocks: each holds its
/// compliance, (H + 1)·n_c² complex numbers.
const JUDGE_QUEUE: usize = 8;

/// Hill's verdicts of a sweep's points on a thread beside the continuation: the points go in
/// as they are found (the continuation waits when `JUDGE_QUEUE` are pending), the verdicts
/// come back into the writer as they are done, and all of them before the sweep is written.
/// A verdict is a function of its point alone, so the rows are those of judging in turn. The
/// check's stage time is the wall time it adds: what the continuation waited for it (a full
/// queue, the last verdicts).
struct Judge<'scope> {
    points: std::sync::mpsc::SyncSender<(usize, f64, ContactSolution)>,
    verdicts: std::sync::mpsc::Receiver<(usize, Stability)>,
    workers: Vec<std::thread::ScopedJoinHandle<'scope, ()>>,
}

impl<'scope> Judge<'scope> {
    /// One worker per core: while the continuation waits on a full queue, every core judges.
    fn start<'env>(
        scope: &'scope std::thread::Scope<'scope, 'env>,
        model: &'env Model,
        hill: &'env HillModel,
    ) -> Self {
        let (points, queue) = std::sync::mpsc::sync_channel(JUDGE_QUEUE);
        let queue = std::sync::Arc::new(std::sync::Mutex::new(queue));
        let (done, verdicts) = std::sync::mpsc::channel();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let workers = (0..cores.clamp(1, 4))
            .map(|_| {
                let (queue, done) = (std::sync::Arc::clone(&queue), done.clone());
                scope.spawn(move || loop {
                    // The lock is held only to take the next point.
                    let next = queue.lock().ok().and_then(|q| q.recv().ok());
                    let Some((i, omega, contact)) = next else {
                        return;
                    };
                    let verdict = judge_state(model, hill, omega, &contact);
                    if done.send((i, verdict)).is_err() {
                        return;
                    }
                })
            })
            .collect();
        Judge {
            points,
            verdicts,
            workers,
        }
    }

    /// Queues point `i` at ω with its contact state (the wait for room added to `waited`).
    fn submit(&self, i: usize, omega: f64, contact: &ContactSolution, waited: &mut f64) {
        let start = Instant::now();
        // A worker that is gone has panicked; `finish` passes the panic on.
        let _ = self.points.send((i, omega, contact.clone()));
        *waited += start.elapsed().as_secs_f64();
    }

    /// Records the verdicts done so far.
    fn record_done(&self, writer: &mut points::Writer) {
        record_all(&self.verdicts, writer);
    }

    /// Waits for the pending verdicts (the wait added to `waited`) and records them.
    fn finish(self, writer: &mut points::Writer, waited: &mut f64) {
        let start = Instant::now();
        let Judge {
            points,
            verdicts,
            workers,
        } = self;
        drop(points);
        // A panic in the check is the sweep's, as it was when the check ran inline.
        for worker in workers {
            if let Err(panic) = worker.join() {
                std::panic::resume_unwind(panic);
            }
        }
        *waited += start.elapsed().as_secs_f64();
        record_all(&verdicts, writer);
    }
}

/// Records every verdict `verdicts` holds now.
fn record_all(
    verdicts: &std::sync::mpsc::Receiver<(usize, Stability)>,
    writer: &mut points::Writer,
) {
    for (i, verdict) in verdicts.try_iter() {
        record(writer, i, verdict);
    }
}

/// `stopped` of sweep.json: the failure, or the budget `max_points` ran out before `to_hz`.
fn stop_report(
    spec: &SweepSpec,
    writer: &points::Writer,
    failure: Option<&Error>,
    out: &Path,
    p: &Pipeline,
) -> Option<Stopped> {
    let last = writer.rows.last()?;
    let resume_hint = format!(
        "`{}` continues from here into {}",
        resume::command(p, out),
        out.display()
    );
    // A curve that left the range through its start would leave it again when resumed.
    let range = (spec.from_hz, spec.to_hz);
    let left = continuation::leaves_through_start(last.frequency_hz, last.tangent_frequency, range);
    let (class, reason) = match failure {
        Some(e) if left => (e.class().to_string(), e.to_string()),
        Some(e) => (e.class().to_string(), format!("{e}; {resume_hint}")),
        None => {
            let span = (spec.to_hz - spec.from_hz).abs();
            let at_end = (last.frequency_hz - spec.to_hz).abs() <= 1e-9 * span;
            if at_end || writer.rows.len() < spec.max_points {
                return None;
            }
            let reason = format!(
                "reached sweep.max_points = {} before {} Hz; raise it (--set sweep.max_points=...) and {resume_hint}",
                spec.max_points, spec.to_hz
            );
            ("max_points".to_string(), reason)
        }
    };
    Some(Stopped {
        frequency_hz: last.frequency_hz,
        point: last.index,
        class,
        reason,
    })
}

/// The solver's view of a `sweep` block (ω in rad/s), continuing from `resume` if given.
pub fn settings(spec: &SweepSpec, resume: Option<ContinuationState>) -> SweepSettings {
    let two_pi = 2.0 * std::f64::consts::PI;
    SweepSettings {
        omega_start: two_pi * spec.from_hz,
        omega_end: two_pi * spec.to_hz,
        step: spec.step,
        min_step: spec.min_step,
        max_step: spec.max_step,
        max_points: spec.max_points,
        max_change: spec.max_change,
        // A resumed curve keeps the limit it was swept with.
        max_turn: spec.max_turn.or(resume.as_ref().and_then(|r| r.max_turn)),
        resume,
        model_frequencies: if spec.reduced_frames {
            crate::hbm::frames::SHIFTS_PER_HARMONIC
        } else {
            0
        },
        harmonics: None,
    }
}

/// The Hill model that judges each point as it is found (`stability.method` floquet or both
/// on a Fourier basis); `None` otherwise, or with a warning where the modes fail (the points
/// are then judged afterwards as `judge_points` says).
fn inline_judge(p: &Pipeline, model: &Model, reporter: &dyn Reporter) -> Option<HillModel> {
    // A frictional state has no multipliers to find (`judge_points` says so, or marches).
    if !stability::hill_judges(p, model) {
        return None;
    }
    let basis = pipeline::model::time_basis(p, Purpose::HarmonicBalance);
    stability::hill_model(model, &basis).unwrap_or_else(|e| {
        reporter.warning(&format!(
            "no Hill model ({e}): the points are judged afterwards"
        ));
        None
    })
}

/// One point's Floquet verdict by Hill's method: a static state is not judged, a contact set
/// that does not change over the period is judged by its damping.
fn judge_state(
    model: &Model,
    hill: &HillModel,
    omega: f64,
    contact: &ContactSolution,
) -> Stability {
    let basis = crate::hbm::basis::TimeBasis::Fourier;
    let segments = match stability::shortcut(model, &basis, omega, contact) {
        Ok(verdict) => return verdict,
        Err(segments) => segments,
    };
    stability::by_floquet_state(model, Some(hill), omega, contact, &segments)
        .unwrap_or_else(|e| Stability::no_multipliers(&e))
}

/// A point's ω and contact solution: where a stability check starts from.
type Start = (usize, f64, Option<ContactSolution>);

/// Stage `stability`: the verdict at every `stability.every`-th point and on both sides of
/// every fold (`pipeline::stability`): the Floquet multipliers of each point's state, on one
/// reduced model for the whole curve (`stability.method: floquet`), time marching (`march`,
/// the points in parallel), or both (marching audits Floquet).
fn judge_points(
    p: &Pipeline,
    model: &Model,
    writer: &mut points::Writer,
    starts: &[Start],
    folds: &[usize],
    reporter: &dyn Reporter,
) -> Result<()> {
    let spec = &p.stability;
    if model.contact.is_none() {
        let verdict = stability::linear(model);
        for r in writer.rows.iter_mut() {
            r.stable = verdict.stable();
            writer.verdicts.push((r.index, verdict.clone()));
        }
        return Ok(());
    }
    let rows = &writer.rows;
    if !spec.check {
        return Ok(());
    }
    let method = judging_method(model, spec.method);
    let beside_fold = |i: usize| folds.iter().any(|&f| i == f || i == f + 1);
    let last = rows.last().map_or(0, |r| r.index);
    // Points found in this run; a resumed sweep keeps the verdicts its saved rows have.
    // Hill's method judged each point as it was found (`inline_judge`): what remains is the
    // marching audit of `both`, or the points it could not judge.
    let inline: Vec<(usize, Stability)> = writer.verdicts.clone();
    let judged_inline = |i: usize| inline.iter().any(|(j, _)| *j == i);
    let judged = |i: usize| {
        rows.iter()
            .any(|r| r.index == i && (r.stable.is_some() || r.multiplier.is_some()))
    };
    let audit = method == StabilityMethod::Both;
    let chosen: Vec<&Start> = starts
        .iter()
        .filter(|(i, _, _)| i % spec.every == 0 || beside_fold(*i) || *i == last)
        .filter(|(i, _, _)| {
            if judged_inline(*i) {
                audit
            } else {
                !judged(*i)
            }
        })
        .collect();
    let (judged_here, varying) = shortcuts(p, model, chosen, method);
    for (i, verdict) in judged_here {
        record(writer, i, verdict);
    }
    let (chosen, segments): (Vec<&Start>, Vec<_>) = varying.into_iter().unzip();
    let floquet = match method {
        StabilityMethod::March => None,
        _ if chosen.iter().all(|(i, _, _)| judged_inline(*i)) => Some(
            chosen
                .iter()
                .map(|(i, _, _)| {
                    inline
                        .iter()
                        .find(|(j, _)| j == i)
                        .map_or_else(Stability::not_checked, |(_, v)| v.clone())
                })
                .collect(),
        ),
        _ => by_floquet(model, &chosen, &segments, reporter),
    };
    let marched = match (method, &floquet) {
        (StabilityMethod::Floquet, Some(_)) => None,
        _ => Some(by_marching(p, model, &chosen, reporter)?),
    };
    for (k, (i, _, _)) in chosen.iter().enumerate() {
        let verdict = match (&floquet, &marched) {
            (Some(f), Some(m)) => stability::audited(f[k].clone(), m[k].clone()),
            (Some(f), None) => f[k].clone(),
            (None, Some(m)) => m[k].clone(),
            (None, None) => Stability::not_checked(),
        };
        record(writer, *i, verdict);
    }
    Ok(())
}

/// Whether `model`'s contact has friction (tangential rows).
fn frictional(model: &Model) -> bool {
    (model.contact.as_ref()).is_some_and(|c| c.operator.tangential.is_some())
}

/// The method the points of `model` are judged by: `asked`, but a frictional scene's states
/// have no Floquet multipliers, so `both` marches alone there.
fn judging_method(model: &Model, asked: StabilityMethod) -> StabilityMethod {
    match (frictional(model), asked) {
        (true, StabilityMethod::Both) => StabilityMethod::March,
        (_, asked) => asked,
    }
}

/// The `chosen` points that need no multipliers, with their verdicts (`stability::shortcut`),
/// and the others with their closed sets over the period (`None`: no contact state kept).
#[allow(clippy::type_complexity)]
fn shortcuts<'a>(
    p: &Pipeline,
    model: &Model,
    chosen: Vec<&'a Start>,
    method: StabilityMethod,
) -> (
    Vec<(usize, Stability)>,
    Vec<(&'a Start, Option<Vec<floquet::Segment>>)>,
) {
    let basis = pipeline::model::time_basis(p, Purpose::HarmonicBalance);
    let (mut judged, mut varying) = (Vec::new(), Vec::new());
    for start in chosen {
        let (i, omega, contact) = start;
        // A frictional state has no multipliers; where marching judges, it marches.
        let marches = method == StabilityMethod::March;
        match contact
            .as_ref()
            .filter(|c| !(marches && c.friction.is_some()))
            .map(|c| stability::shortcut(model, &basis, *omega, c))
        {
            Some(Ok(verdict)) => judged.push((*i, verdict)),
            Some(Err(segments)) => varying.push((start, Some(segments))),
            None => varying.push((start, None)),
        }
    }
    (judged, varying)
}

/// Point `i`'s verdict, into its row (`stable`, `multiplier`) and the writer's verdicts.
fn record(writer: &mut points::Writer, i: usize, verdict: Stability) {
    if let Some(row) = writer.rows.iter_mut().find(|r| r.index == i) {
        row.stable = verdict.stable();
        row.multiplier = verdict.multiplier;
        row.argument = verdict.argument;
        row.crossing = verdict.crossing;
    }
    writer.verdicts.retain(|(j, _)| *j != i);
    // A Floquet vector per point would hold a field per harmonic for every row.
    let verdict = Stability {
        floquet_vector: None,
        ..verdict
    };
    writer.verdicts.push((i, verdict));
}

/// The Floquet verdicts of the `chosen` points (their closed sets `segments`), on one
/// reduced model (the nodes any of them closes); `None`, with a warning, where the scene
/// allows none (then time marching judges).
fn by_floquet(
    model: &Model,
    chosen: &[&Start],
    segments: &[Option<Vec<floquet::Segment>>],
    reporter: &dyn Reporter,
) -> Option<Vec<Stability>> {
    let op = &model.contact.as_ref()?.operator;
    if model.system.spin.is_some() {
        reporter.warning(
            "no Floquet multipliers by the monodromy: its model is built at one rotation speed \
             and boundaries.rotation.turns_per_period moves it with the frequency; the points \
             are judged by time marching instead",
        );
        return None;
    }
    let nodes = floquet::closed_nodes(segments.iter().flatten().flatten());
    let reduced = match floquet::FloquetModel::new(&model.system, &op.b_free, &nodes) {
        Ok(r) => r,
        Err(e) => {
            reporter.warning(&format!(
                "no Floquet multipliers ({e}): the points are judged by time marching instead"
            ));
            return None;
        }
    };
    let verdicts = chosen
        .iter()
        .zip(segments)
        .map(|((_, omega, _), seg)| match seg {
            Some(seg) => stability::floquet_verdict(&reduced, seg, *omega)
                .unwrap_or_else(|e| Stability::no_multipliers(&e)),
            None => Stability::not_checked(),
        })
        .collect();
    Some(verdicts)
}

/// The time-marching verdicts of the `chosen` points, in parallel.
fn by_marching(
    p: &Pipeline,
    model: &Model,
    chosen: &[&Start],
    reporter: &dyn Reporter,
) -> Result<Vec<Stability>> {
    let spec = &p.stability;
    let marching = build(p, model.mesh.clone(), Purpose::Transient)?;
    let done = AtomicUsize::new(0);
    let total = Some(chosen.len() as u64);
    let verdicts: Vec<Stability> = chosen
        .par_iter()
        .map(|(_, omega, start)| {
            let verdict =
                stability::by_marching(p, spec, &marching, *omega, start.as_ref(), None, &Silent);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            reporter.progress("stability", n as u64, total, "points checked by marching");
            verdict.unwrap_or_else(|e| Stability::cannot_march(&e))
        })
        .collect();
    reporter.task_done("stability");
    Ok(verdicts)
}

/// One point's row: the outputs a single-frequency run's summary would give.
fn row(
    p: &Pipeline,
    model: &Model,
    mesh: &MeshInfo,
    info: &continuation::PointInfo,
    solution: &crate::hbm::Solution,
) -> SweepRow {
    row_of(p, &point_summary(p, model, mesh, solution), info, solution)
}

/// The summary a single-frequency run would give of a point's solution.
fn point_summary(
    p: &Pipeline,
    model: &Model,
    mesh: &MeshInfo,
    solution: &crate::hbm::Solution,
) -> pipeline::Summary {
    let samples = solution
        .contact
        .as_ref()
        .map_or(hb_settings(p).samples, |c| c.samples);
    let sampled = Sampled::harmonic_balance_history(model, solution, p.output.frames, samples);
    pipeline::summary::harmonic_balance(p, mesh.clone(), model, solution, &sampled)
}

/// A point's row from its summary.
fn row_of(
    p: &Pipeline,
    summary: &pipeline::Summary,
    info: &continuation::PointInfo,
    solution: &crate::hbm::Solution,
) -> SweepRow {
    SweepRow {
        index: info.index,
        frequency_hz: info.omega / (2.0 * std::f64::consts::PI),
        values: outputs(p).iter().map(|o| o.value(summary, None)).collect(),
        corrector: info.corrector,
        newton_iterations: info.newton_iterations,
        factorizations: info.factorizations,
        step: info.step,
        tangent_frequency: info.tangent_omega,
        seconds: info.seconds,
        stable: None,
        multiplier: None,
        argument: None,
        crossing: None,
        underdamped_share: solution
            .contact
            .as_ref()
            .and_then(|c| c.knob_check.underdamped_share),
        harmonics: solution
            .contact
            .as_ref()
            .map_or(p.harmonic_balance.harmonics, |c| c.harmonics),
        truncation_estimate: info.harmonics_estimate,
        subharmonic: None,
    }
}

/// The rows of a spline curve whose vibration lives in the basis' underdamped frequencies
/// (docs/method.md §16): a single run warns of its own; a sweep passes many frequencies, so
/// it names the stretch, the worst point and the key to raise.
fn underdamped_rows(rows: &[SweepRow], basis: &TimeBasis) -> Option<String> {
    let TimeBasis::Spline(s) = basis else {
        return None;
    };
    let over: Vec<(&SweepRow, f64)> = (rows.iter())
        .filter_map(|r| Some((r, r.underdamped()?)))
        .collect();
    let &(worst, share) = over.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    let hz = over.iter().map(|(r, _)| r.frequency_hz);
    let (lo, hi) = (
        hz.clone().fold(f64::INFINITY, f64::min),
        hz.fold(0.0, f64::max),
    );
    Some(format!(
        "at {} of {} points ({lo:.1}-{hi:.1} Hz; the largest {:.1}% at {:.1} Hz, row {}) more than {:.0}% of the contact nodes' vibration lies in the spline basis' discrete frequencies j >= {} (of {}), whose damping its time derivative loses: there the curve follows a resonance of the basis, not of the structure; raise {} (the share falls as S grows) or use basis: fourier, and compare",
        over.len(),
        rows.len(),
        100.0 * share,
        worst.frequency_hz,
        worst.index,
        100.0 * UNDERDAMPED_TOLERANCE,
        underdamped_from(s),
        s.segments / 2,
        basis.refine_key()
    ))
}

/// sweep.csv: frequency, the outputs, then how each point was found.
pub fn csv(s: &SweepSummary) -> String {
    rows_csv(&s.columns, &s.rows)
}

/// The rows under the header of sweep.csv.
fn rows_csv(columns: &[String], rows: &[SweepRow]) -> String {
    let mut text = format!(
        "index,frequency_hz,{},stable,multiplier,argument_deg,crossing,harmonics,truncation_estimate,corrector,newton_iterations,factorizations,step,tangent_frequency,seconds\n",
        columns.join(",")
    );
    for r in rows {
        let values: Vec<String> = r.values.iter().map(|&v| csv_number(v)).collect();
        let corrector = serde_json::to_value(r.corrector)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let stable = r.stable.map_or(String::new(), |s| s.to_string());
        let multiplier = r.multiplier.map_or(String::new(), csv_number);
        let argument = r
            .argument
            .map_or(String::new(), |a| csv_number(a.to_degrees()));
        let crossing = r
            .crossing
            .and_then(|c| serde_json::to_value(c).ok())
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let estimate = r.truncation_estimate.map_or(String::new(), csv_number);
        text.push_str(&format!(
            "{},{},{},{stable},{multiplier},{argument},{crossing},{},{estimate},{corrector},{},{},{},{},{}\n",
            r.index,
            csv_number(r.frequency_hz),
            values.join(","),
            r.harmonics,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hbm::basis::SplineBasis;

    fn row(index: usize, frequency_hz: f64, share: Option<f64>) -> SweepRow {
        SweepRow {
            underdamped_share: share,
            ..SweepRow::for_tests(index, frequency_hz)
        }
    }

    /// TEST GOAL: a spline curve warns over exactly the rows whose underdamped share exceeds
    /// the single run's tolerance, naming their count, their stretch (wherever the curve ran
    /// back), the worst point and the segments key; rows at or below it, rows without
    /// contact and Fourier curves do not warn.
    #[test]
    fn the_underdamped_warning_counts_the_rows_above_tolerance_and_names_the_worst() {
        let spline = TimeBasis::Spline(SplineBasis::new(3, 41));
        let rows = vec![
            row(0, 1000.0, None),
            row(1, 1001.0, Some(0.02)),
            row(2, 1002.0, Some(UNDERDAMPED_TOLERANCE)),
            row(3, 1004.0, Some(0.3)),
            row(4, 1003.0, Some(0.9)),
            row(5, 1001.5, Some(0.06)),
        ];
        let w = underdamped_rows(&rows, &spline).expect("a warning");
        assert!(
            w.starts_with(
                "at 3 of 6 points (1001.5-1004.0 Hz; the largest 90.0% at 1003.0 Hz, row 4)"
            ),
            "{w}"
        );
        // Cubic, S = 41: σ_j/jω = 0.956 near j = 3S/8 = 15.4, below 0.95 from j = 16.
        assert!(w.contains("j >= 16 (of 20)"), "{w}");
        assert!(w.contains("harmonic_balance.basis.spline.segments"), "{w}");
        assert_eq!(underdamped_rows(&rows[..3], &spline), None);
        assert_eq!(underdamped_rows(&rows, &TimeBasis::Fourier), None);
    }
}
