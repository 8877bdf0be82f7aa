//! Running a study's points on the cores of one machine.
//!
//! Thread split: `threads` points run at once on a rayon pool of that size; while more than
//! one runs, faer's sparse factorizations are sequential (`faer::Par::Seq`), so the cores are
//! shared between points and never oversubscribed. With one thread, points run one after
//! another and faer keeps its default (every core). Small 2-D meshes factor in milliseconds, so
//! points-in-parallel is where the speed-up is (benches/study.rs measures both).
//!
//! Each point writes `points/<key>/summary.json` (and the full series when asked) through
//! `pipeline::run`, then `point.json`: its outputs or its error and exit class. A point whose
//! `point.json` says ok (for the same probe, in full if full is wanted, and with what `Needs`
//! asks) is done and skipped.
//!
//! point.json is read back like user input (a file anyone may edit, or a shard copied from
//! elsewhere): at most `MAX_RECORD_BYTES`, then every field checked before it counts
//! (`check_record`: the folder's key and mode, status `ok` or `failed` with a known exit
//! class and its code, known outputs with finite values within ±`MAX_OUTPUT_MAGNITUDE` in
//! their ranges, a finite time). A record that fails a check is an error (exit 2) naming the
//! file and the field, with the fix: delete the point's folder to run it again. A record
//! whose JSON ends early (a copy or a write that did not finish) is not trusted either: a run
//! says so and runs the point again, a merge (which runs nothing) refuses it.
//!
//! Beyond the summary (`Needs`): natural frequencies (from the scene the run solves, meshed
//! and assembled once: `pipeline::modes::natural_modes`, K and M of the free dofs, the contact
//! open; a marching point's from the harmonic-balance model of its cached mesh); the
//! peak resident memory (Linux: writing "5" to /proc/self/clear_refs resets VmHWM, the peak
//! RSS, to the current RSS; VmHWM in /proc/self/status after the run is the run's peak, so it
//! is measured only when points run one at a time); and the harmonic amplitudes on every
//! node (`amplitudes.vtu`, the run's write level `Amplitudes`: no frame series is written),
//! which the accuracy study's displacement L2 error reads.
//! Meshes are made once per distinct geometry before the points run, into the cache the points
//! share (`points/.mesh-cache`, its entries locked while written).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::plan::{describe, point_dir, Mode, Point};
use crate::config::Pipeline;
use crate::output::tables::write_json;
use crate::pipeline::modes::natural_modes;
use crate::pipeline::outputs::Output;
use crate::pipeline::stability::Verdict;
use crate::pipeline::{self, stages, Purpose, RunOptions, Stages, Summary, WriteLevel};
use crate::progress::{Reporter, Silent};
use crate::{Error, Result};

/// What a point left behind (`points/<key>/point.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PointRecord {
    pub key: String,
    pub mode: Mode,
    /// `ok` or `failed`.
    pub status: String,
    /// `bad_input`, `model`, `not_converged`, `io` or `internal` (failed points).
    pub exit_class: Option<String>,
    pub exit_code: Option<u8>,
    pub error: Option<String>,
    /// The probe the outputs are of (None: the pipeline's first).
    pub probe: Option<String>,
    /// Every output a study can ask for, by name (NaN written as null).
    pub outputs: BTreeMap<String, Option<f64>>,
    pub full: bool,
    /// `amplitudes.vtu` kept beside the summary (accuracy rungs).
    #[serde(default)]
    pub amplitudes: bool,
    /// Wall time of the whole point, meshing included [s].
    pub seconds: f64,
    pub warnings: Vec<String>,
}

impl PointRecord {
    pub fn ok(&self) -> bool {
        self.status == "ok"
    }
    pub fn output(&self, o: &Output) -> f64 {
        self.outputs
            .get(&o.name())
            .copied()
            .flatten()
            .unwrap_or(f64::NAN)
    }
}

/// The largest point.json read back [bytes]: a record holds a few dozen outputs, an error
/// message (cut to a few thousand characters) and the run's warnings, a few kB in all.
pub const MAX_RECORD_BYTES: u64 = 1 << 20;

/// The largest magnitude an output of a record may have: no run in any unit system comes
/// near it, and squares and differences of values below it stay finite in the plots and the
/// accuracy errors (a tampered 1e308 does not).
pub const MAX_OUTPUT_MAGNITUDE: f64 = 1e100;

/// The exit classes a failed point's record may name, with their exit codes
/// (`Error::class`, `Error::exit_code`).
const EXIT_CLASSES: [(&str, u8); 7] = [
    ("bad_input", 2),
    ("model", 3),
    ("not_converged", 4),
    ("io", 5),
    ("study_incomplete", 6),
    ("interrupted", 130),
    ("internal", 1),
];

/// What a point's folder holds.
#[derive(Clone, Debug)]
pub enum Recorded {
    /// No point.json: the point has not run (here, or in its shard).
    Missing,
    /// A point.json that ends before its JSON does (a copy or a write that did not finish):
    /// the message names the file; the point is to be run again.
    CutShort(String),
    /// A record that reads and holds what a run writes.
    Valid(PointRecord),
}

/// The point's `point.json`, read back like user input: at most `MAX_RECORD_BYTES`, then
/// every field checked (`check_record`). Missing and cut-short files are told apart from
/// the rest; any other fault is an error (exit 2) naming the file and the field, with the
/// fix (delete the point's folder to run it again).
pub fn read_record(out: &Path, point: &Point) -> Result<Recorded> {
    use std::io::Read as _;
    let dir = point_dir(out, &point.key);
    let path = dir.join("point.json");
    let file = match std::fs::File::open(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Recorded::Missing),
        Err(e) => return Err(Error::io(&path, e)),
        Ok(f) => f,
    };
    let mut bytes = Vec::new();
    file.take(MAX_RECORD_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(&path, e))?;
    if bytes.len() as u64 > MAX_RECORD_BYTES {
        return Err(bad_record(
            &path,
            format!(
                " is larger than {} MiB, more than any point writes",
                MAX_RECORD_BYTES >> 20
            ),
        ));
    }
    let value: serde_json::Value = match serde_json::from_slice(&bytes) {
        Ok(v) => v,
        Err(e) if e.classify() == serde_json::error::Category::Eof => {
            return Ok(Recorded::CutShort(format!(
                "{} is cut short ({} bytes, its JSON unfinished: a copy or a write that did not finish)",
                path.display(),
                bytes.len()
            )))
        }
        Err(e) => {
            return Err(bad_record(
                &path,
                format!(" is not JSON ({})", crate::error::shorten_quoted(&e.to_string())),
            ))
        }
    };
    let record = parse_record(&value).map_err(|(field, why)| bad_field(&path, &field, why))?;
    check_record(&record, point).map_err(|(field, why)| bad_field(&path, &field, why))?;
    Ok(Recorded::Valid(record))
}

/// The refusal of the record at `path` (`why` follows its name: " is …" or ": `field` …"),
/// with the fix.
fn bad_record(path: &Path, why: String) -> Error {
    let dir = path.parent().unwrap_or(path);
    Error::Input(format!(
        "{}{why}: it was not written by this study's run or was changed since; delete the folder {} to run the point again",
        path.display(),
        dir.display()
    ))
}

fn bad_field(path: &Path, field: &str, why: String) -> Error {
    bad_record(path, format!(": `{}` {why}", crate::error::excerpt(field)))
}

/// A field fault: the field's name and what is wrong with it.
type FieldFault = (String, String);

/// The record's fields, each from its own JSON value (so a fault names its field). Fields a
/// run does not write are ignored.
fn parse_record(value: &serde_json::Value) -> std::result::Result<PointRecord, FieldFault> {
    use serde::de::DeserializeOwned;
    let Some(object) = value.as_object() else {
        return Err(("(top level)".into(), "is not a JSON object".into()));
    };
    fn take<T: DeserializeOwned>(
        object: &serde_json::Map<String, serde_json::Value>,
        name: &str,
        default: Option<T>,
    ) -> std::result::Result<T, FieldFault> {
        match (object.get(name), default) {
            (None, Some(d)) => Ok(d),
            (None, None) => Err((name.into(), "is missing".into())),
            (Some(v), _) => serde_json::from_value(v.clone()).map_err(|e| {
                let shown = crate::error::excerpt(&v.to_string());
                (
                    name.to_string(),
                    format!(
                        "= {shown} does not read ({})",
                        crate::error::shorten_quoted(&e.to_string())
                    ),
                )
            }),
        }
    }
    Ok(PointRecord {
        key: take(object, "key", None)?,
        mode: take(object, "mode", None)?,
        status: take(object, "status", None)?,
        exit_class: take(object, "exit_class", Some(None))?,
        exit_code: take(object, "exit_code", Some(None))?,
        error: take(object, "error", Some(None))?,
        probe: take(object, "probe", Some(None))?,
        outputs: take(object, "outputs", None)?,
        full: take(object, "full", None)?,
        amplitudes: take(object, "amplitudes", Some(false))?,
        seconds: take(object, "seconds", None)?,
        warnings: take(object, "warnings", None)?,
    })
}

/// A record as `run_point` writes it for `point`: its key and mode; status `ok` (no exit
/// class, code or error) or `failed` (a known exit class, its code, an error message); every
/// output a known name with a finite value within ±`MAX_OUTPUT_MAGNITUDE` (or null) in the
/// output's range (amplitudes, times, frequencies, stresses and the multiplier ≥ 0, the
/// contact fraction in [0, 1], counts whole, `stable` 0 or 1); a finite, non-negative time.
pub fn check_record(r: &PointRecord, point: &Point) -> std::result::Result<(), FieldFault> {
    let fault = |field: &str, why: String| Err((field.to_string(), why));
    if r.key != point.key {
        return fault(
            "key",
            format!(
                "is \"{}\", not the key of the point whose folder holds it ({})",
                crate::error::excerpt(&r.key),
                point.key
            ),
        );
    }
    if r.mode != point.mode {
        return fault(
            "mode",
            format!("is {:?}, not the point's {:?}", r.mode, point.mode),
        );
    }
    match r.status.as_str() {
        "ok" => {
            if r.exit_class.is_some() || r.exit_code.is_some() || r.error.is_some() {
                return fault(
                    "status",
                    "is \"ok\" but the record holds an exit class, exit code or error".into(),
                );
            }
        }
        "failed" => {
            let class = r.exit_class.as_deref().unwrap_or("");
            let Some((_, code)) = EXIT_CLASSES.iter().find(|(c, _)| *c == class) else {
                let known: Vec<&str> = EXIT_CLASSES.iter().map(|(c, _)| *c).collect();
                return fault(
                    "exit_class",
                    format!(
                        "is \"{}\", not one of {}",
                        crate::error::excerpt(class),
                        known.join(", ")
                    ),
                );
            };
            if r.exit_code != Some(*code) {
                return fault(
                    "exit_code",
                    format!(
                        "is {:?}, not {code}, the code of exit class {class}",
                        r.exit_code
                    ),
                );
            }
            if r.error.is_none() {
                return fault("error", "is missing from a failed point's record".into());
            }
        }
        other => {
            return fault(
                "status",
                format!(
                    "is \"{}\", not \"ok\" or \"failed\"",
                    crate::error::excerpt(other)
                ),
            )
        }
    }
    for (name, value) in &r.outputs {
        let field = format!("outputs.{name}");
        let output = match Output::parse(name) {
            Ok(o) => o,
            Err(_) => return fault(&field, "is not an output a study knows".into()),
        };
        let Some(v) = *value else { continue };
        if let Err(why) = check_output(&output, v) {
            return fault(&field, format!("= {v:e} {why}"));
        }
    }
    if !(r.seconds.is_finite() && r.seconds >= 0.0 && r.seconds <= MAX_OUTPUT_MAGNITUDE) {
        return fault("seconds", format!("= {:e} is not a time", r.seconds));
    }
    Ok(())
}

/// `v` within ±`MAX_OUTPUT_MAGNITUDE` and in the range of output `o`; else why not.
fn check_output(o: &Output, v: f64) -> std::result::Result<(), String> {
    /// Times are differences of sums of stage times: they may round a hair below zero.
    const TIME_ROUNDING: f64 = 1e-9;
    if !v.is_finite() || v.abs() > MAX_OUTPUT_MAGNITUDE {
        return Err(format!(
            "is beyond ±{MAX_OUTPUT_MAGNITUDE:e}, not a value a run writes"
        ));
    }
    let whole = v.fract() == 0.0;
    match o {
        Output::ContactFraction if !(0.0..=1.0).contains(&v) => Err("is not in [0, 1]".into()),
        Output::Stable if v != 0.0 && v != 1.0 => Err("is not 0 or 1".into()),
        Output::NewtonIterations | Output::FreeDofs if !(whole && v >= 0.0) => {
            Err("is not a whole number ≥ 0".into())
        }
        Output::WallTime | Output::SolveTime if v < -TIME_ROUNDING => {
            Err("is a negative time".into())
        }
        Output::ProbeFirstHarmonic
        | Output::ProbeFirstHarmonicX
        | Output::ProbeFirstHarmonicY
        | Output::ProbeHarmonic(_)
        | Output::ProbePeakToPeak
        | Output::ProbePeakToPeakX
        | Output::ProbePeakToPeakY
        | Output::MaxVonMises
        | Output::NaturalFrequency(_)
        | Output::PeakMemory
        | Output::Multiplier
        | Output::PeakTangentialForce
        | Output::SlipShare
            if v < 0.0 =>
        {
            Err("is negative, and this output is not".into())
        }
        _ => Ok(()),
    }
}

/// What the points are asked for beyond their summary.
#[derive(Clone, Debug, Default)]
pub struct Needs {
    /// The probe group of the probe outputs (None: the pipeline's first).
    pub probe: Option<String>,
    /// Natural frequencies 1..=modes (0: none).
    pub modes: usize,
    /// Measure each point's peak resident memory (only meaningful one point at a time).
    pub peak_memory: bool,
    /// Keep the harmonic amplitudes on every node (`amplitudes.vtu`).
    pub amplitudes: bool,
    /// Run the stability check by time marching (outputs `stable`, `multiplier`). Without
    /// it the points skip the check, which costs several times their solve.
    pub stability: bool,
}

/// Whether a point is done: an ok record for this probe, in full when wanted, with what
/// `needs` asks. A record cut short is not (the point runs again, and `reporter` is told);
/// a record that does not check is an error (`read_record`).
pub fn is_done(out: &Path, point: &Point, needs: &Needs, reporter: &dyn Reporter) -> Result<bool> {
    let r = match read_record(out, point)? {
        Recorded::Missing => return Ok(false),
        Recorded::CutShort(what) => {
            reporter.warning(&format!("{what}: running the point again"));
            return Ok(false);
        }
        Recorded::Valid(r) => r,
    };
    let has = |name: String| r.outputs.contains_key(&name);
    Ok(r.ok()
        && r.probe == needs.probe
        && (r.full || !point.full)
        && (1..=needs.modes).all(|k| has(Output::NaturalFrequency(k).name()))
        && (!needs.peak_memory || has(Output::PeakMemory.name()))
        && (!needs.stability || has(Output::Stable.name()))
        && (r.amplitudes || !needs.amplitudes || point.mode == Mode::Transient))
}

/// Every output of the catalogue for this summary (probe harmonics up to those computed).
fn all_outputs(s: &Summary, probe: Option<&str>) -> BTreeMap<String, Option<f64>> {
    let mut outputs = Output::from_summary();
    let harmonics = s
        .probes
        .values()
        .map(|a| a.harmonics_x.len())
        .max()
        .unwrap_or(0);
    outputs.extend((1..=harmonics).map(Output::ProbeHarmonic));
    // Present (if empty when undecided) exactly when the check ran.
    if s.stability
        .as_ref()
        .is_some_and(|st| st.verdict != Verdict::NotChecked)
    {
        outputs.extend([Output::Stable, Output::Multiplier]);
    }
    outputs
        .iter()
        .map(|o| {
            let v = o.value(s, probe);
            // What a record may hold (`check_output`): finite, within the magnitude bound.
            let kept = v.is_finite() && v.abs() <= MAX_OUTPUT_MAGNITUDE;
            (o.name(), kept.then_some(v))
        })
        .collect()
}

/// Run one point and write its record; a failure is recorded, never returned (only failing to
/// write the record is an error).
fn run_point(out: &Path, point: &Point, needs: &Needs) -> Result<PointRecord> {
    let dir = point_dir(out, &point.key);
    let amplitudes = needs.amplitudes && point.mode == Mode::HarmonicBalance;
    let write = match (point.full, amplitudes) {
        (true, _) => WriteLevel::Full,
        (false, true) => WriteLevel::Amplitudes,
        (false, false) => WriteLevel::Summary,
    };
    let options = RunOptions {
        out: Some(dir.clone()),
        write,
        // The point's folder is the study's own (under its `points/`).
        replace: crate::output::staging::Replace::Owned,
        keep_interrupted_march: false,
    };
    let probe = needs.probe.as_deref();
    let start = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        solve_point(point, needs, &dir, &options)
    }));
    let seconds = start.elapsed().as_secs_f64();
    let base = PointRecord {
        key: point.key.clone(),
        mode: point.mode,
        status: "ok".into(),
        exit_class: None,
        exit_code: None,
        error: None,
        probe: probe.map(str::to_string),
        outputs: BTreeMap::new(),
        full: point.full,
        amplitudes: false,
        seconds,
        warnings: Vec::new(),
    };
    let record = match result {
        Ok(Ok((r, peak, modes))) => {
            let mut outputs = all_outputs(&r.summary, probe);
            if let Some(peak) = peak {
                outputs.insert(Output::PeakMemory.name(), peak);
            }
            for (k, f) in modes.iter().enumerate() {
                outputs.insert(Output::NaturalFrequency(k + 1).name(), Some(*f));
            }
            PointRecord {
                outputs,
                amplitudes,
                warnings: r.summary.warnings.clone(),
                ..base
            }
        }
        Ok(Err(e)) => PointRecord {
            status: "failed".into(),
            exit_class: Some(e.class().into()),
            exit_code: Some(e.exit_code()),
            error: Some(e.to_string()),
            ..base
        },
        Err(_) => PointRecord {
            status: "failed".into(),
            exit_class: Some("internal".into()),
            exit_code: Some(1),
            error: Some("internal error (a panic); please report it with the study file".into()),
            ..base
        },
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    write_json(&dir.join("point.json"), &record)?;
    Ok(record)
}

/// The point's run (the marching check only where the study tabulates it), its peak memory
/// [MB] where asked, and its natural frequencies.
fn solve_point(
    point: &Point,
    needs: &Needs,
    dir: &Path,
    options: &RunOptions,
) -> Result<(pipeline::RunResult, Option<Option<f64>>, Vec<f64>)> {
    let mut p = point.pipeline.clone();
    p.stability.check &= needs.stability;
    let (run, modes, memory) = match point.mode {
        // One mesh and one assembly for the modes and the run.
        Mode::HarmonicBalance => {
            let purpose = Purpose::HarmonicBalance;
            let (scene, stages) = pipeline::open(&p, dir, options, purpose, &Silent)?;
            let modes = natural_frequencies(&scene.model, needs.modes)?;
            let memory = needs.peak_memory.then(reset_peak_memory);
            let run = pipeline::run_scene(&p, options, scene, stages)?;
            (run, modes, memory)
        }
        Mode::Transient => {
            let memory = needs.peak_memory.then(reset_peak_memory);
            let run = pipeline::run_transient(&p, options, &Silent)?;
            let modes = harmonic_balance_modes(&point.pipeline, dir, needs.modes)?;
            (run, modes, memory)
        }
    };
    let peak = memory.map(|reset| reset.and_then(|()| peak_memory_mb()));
    Ok((run, peak, modes))
}

/// The `count` lowest natural frequencies [Hz] of `model`, as `hbcontact modes` computes them.
fn natural_frequencies(model: &pipeline::Model, count: usize) -> Result<Vec<f64>> {
    if count == 0 {
        return Ok(Vec::new());
    }
    let modes = natural_modes(model, count)?;
    Ok(modes
        .iter()
        .map(|(w2, _)| w2.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        .collect())
}

/// `natural_frequencies` of the harmonic-balance model of a point that marched (its own
/// model has the diagonal mass of time marching), its mesh from the cache.
fn harmonic_balance_modes(p: &Pipeline, dir: &Path, count: usize) -> Result<Vec<f64>> {
    if count == 0 {
        return Ok(Vec::new());
    }
    let mut stages = Stages::new(p, &Silent);
    let scene = pipeline::prepare(p, dir, Purpose::HarmonicBalance, &mut stages)?;
    natural_frequencies(&scene.model, count)
}

/// Reset this process's peak resident memory (VmHWM) to its current RSS: Linux's
/// `echo 5 > /proc/self/clear_refs`. None where that is unavailable.
fn reset_peak_memory() -> Option<()> {
    std::fs::write("/proc/self/clear_refs", "5").ok()
}

/// This process's peak resident memory since the last reset [MB] (VmHWM of
/// /proc/self/status, in kB).
fn peak_memory_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Mesh every distinct geometry of `points` once (in parallel), into the points' shared
/// cache. Failures are left for the points themselves to report. Returns the seconds spent.
fn premesh(out: &Path, points: &[&Point]) -> f64 {
    let start = Instant::now();
    let cache = stages::mesh_cache_dir(&point_dir(out, "any"));
    let mut seen = std::collections::BTreeSet::new();
    let requests: Vec<_> = points
        .iter()
        .map(|p| stages::mesh_request(&p.pipeline))
        .filter(|(r, _)| seen.insert(format!("{r:?}")))
        .collect();
    requests.par_iter().for_each(|(request, limits)| {
        let _ = crate::mesh::gmsh::mesh_geometry_with(request, limits, &cache, &Silent);
    });
    start.elapsed().as_secs_f64()
}

/// How the run went.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Execution {
    /// Points run now (the others were done before or belong to other shards).
    pub ran: usize,
    /// Points skipped because an earlier run had done them.
    pub skipped: usize,
    pub threads: usize,
    /// Distinct geometries meshed (or found cached) before the points ran.
    pub geometries: usize,
    pub meshing_seconds: f64,
    /// Wall time of running the points (after meshing).
    pub points_seconds: f64,
}

/// Points run at once: the option, else one per core; never more than the cores this process
/// may use (more would only share them, each point holding its model's memory), with a
/// warning to `reporter` when a request is cut (`--threads 1000000` started that many).
pub fn thread_count(requested: Option<usize>, reporter: &dyn Reporter) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    match requested {
        Some(n) if n > cores => {
            reporter.warning(&format!(
                "threads = {n} is more than the {cores} cores here: running {cores} points at once"
            ));
            cores
        }
        Some(n) => n.max(1),
        None => cores,
    }
}

/// Run the points not done yet, `threads` at once, telling `reporter` about each.
pub fn execute(
    out: &Path,
    points: &[&Point],
    needs: &Needs,
    threads: usize,
    reporter: &dyn Reporter,
) -> Result<Execution> {
    let mut todo: Vec<&Point> = Vec::new();
    for &p in points {
        if !is_done(out, p, needs, reporter)? {
            todo.push(p);
        }
    }
    let mut execution = Execution {
        skipped: points.len() - todo.len(),
        ran: todo.len(),
        threads,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("study-{i}"))
        .build()
        .map_err(|e| Error::Model(format!("internal: cannot start {threads} threads: {e}")))?;
    let faer_before = faer::get_global_parallelism();
    if threads > 1 {
        faer::set_global_parallelism(faer::Par::Seq);
    }
    execution.geometries = {
        let mut seen = std::collections::BTreeSet::new();
        todo.iter()
            .filter(|p| seen.insert(format!("{:?}", stages::mesh_request(&p.pipeline).0)))
            .count()
    };
    reporter.stage("mesh");
    execution.meshing_seconds = pool.install(|| premesh(out, &todo));
    reporter.stage_done("mesh", execution.meshing_seconds);
    let start = Instant::now();
    let total = todo.len() as u64;
    let done = AtomicU64::new(0);
    reporter.progress("points", 0, Some(total), "");
    let results: Vec<Result<PointRecord>> = pool.install(|| {
        todo.par_iter()
            .map(|p| {
                let record = run_point(out, p, needs);
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                let status = match &record {
                    Ok(r) if r.ok() => format!("point {} done ({})", p.index, describe(&p.values)),
                    _ => format!("point {} FAILED ({})", p.index, describe(&p.values)),
                };
                reporter.progress("points", n, Some(total), &status);
                record
            })
            .collect()
    });
    reporter.task_done("points");
    faer::set_global_parallelism(faer_before);
    execution.points_seconds = start.elapsed().as_secs_f64();
    for r in results {
        r?;
    }
    Ok(execution)
}

/// The table's directory for merged or single-process results.
pub fn results_files(out: &Path) -> [PathBuf; 3] {
    [
        out.join("study.csv"),
        out.join("manifest.json"),
        out.join("plots"),
    ]
}
