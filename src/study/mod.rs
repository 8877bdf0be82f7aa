//! Parameter studies: one pipeline run over many points (geometry parameters or any pipeline
//! key, as a grid, lists, or a seeded Latin hypercube), in parallel on one machine or sliced
//! into shards for a Slurm job array, with one table, plots and a manifest at the end. An
//! accuracy study is the same machinery over ladders of settings, tabulating errors against a
//! reference (`accuracy`).
//!
//! Layout of a study's directory (`output/<name>` by default):
//! `study.csv`, `manifest.json`, `plots/` (published together at the end), `points/<key>/`
//! (each point's summary.json and point.json, kept for resuming), `points/.mesh-cache/`, and
//! `slurm/` when `--slurm` wrote its scripts.
//!
//! Glossary: point = one resolved pipeline; key = hash of it (plan.rs); record = what a point
//! left (execute.rs); shard i/n = the unique points whose position p has p mod n = i.

pub mod accuracy;
pub mod displacement;
pub mod execute;
pub mod plan;
pub mod slurm;
pub mod spec;
pub mod table;

use std::collections::HashSet;
use std::path::PathBuf;

pub use crate::pipeline::outputs::Output;
pub use execute::Execution;
pub use spec::{load_study, parse_study, study_schema, Study};

use crate::progress::Reporter;
use crate::{Error, Result};

/// One slice of a study: `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// `i/n` with 0 ≤ i < n.
    pub fn parse(text: &str) -> std::result::Result<Shard, String> {
        let parsed = text
            .split_once('/')
            .and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)));
        match parsed {
            Some((index, count)) if index < count => Ok(Shard { index, count }),
            _ => Err(format!(
                "--shard {text}: expected i/n with 0 ≤ i < n, e.g. --shard 0/4 (Slurm: --shard $SLURM_ARRAY_TASK_ID/4)"
            )),
        }
    }
}

/// Options from the command line.
#[derive(Clone, Debug, Default)]
pub struct StudyOptions {
    /// Overrides the study's `out`.
    pub out: Option<PathBuf>,
    /// Overrides the study's `threads`.
    pub threads: Option<usize>,
    /// Run only this slice, and write no table.
    pub shard: Option<Shard>,
    /// Let gmsh read the points' `.geo` without the scan for statements that run programs or
    /// touch other files (`--trust-geometry`; no study file can set it).
    pub trust_geometry: bool,
}

/// How a study went.
#[derive(Clone, Debug)]
pub struct StudyReport {
    pub out: PathBuf,
    /// `study.csv` or `accuracy.csv` (None for a shard).
    pub table: Option<PathBuf>,
    pub points: usize,
    pub ok: usize,
    /// Points that ran and warned (the tables' `warnings` columns say of what).
    pub warned: usize,
    pub failed: usize,
    /// Points without a record (shards not run yet).
    pub missing: usize,
    /// This process's run (None after `--merge`).
    pub execution: Option<Execution>,
    /// The accuracy study's rungs (accuracy studies only).
    pub accuracy: Option<accuracy::AccuracyReport>,
}

impl StudyReport {
    /// `Err(StudyIncomplete)` when some point failed or is missing, so the exit code says so.
    pub fn complete(self) -> Result<StudyReport> {
        match (&self.table, self.failed + self.missing) {
            (Some(table), n) if n > 0 => Err(Error::StudyIncomplete {
                failed: n,
                total: self.points,
                table: table.clone(),
            }),
            _ => Ok(self),
        }
    }
}

/// What a study writes into its results folder: it replaces these and touches nothing else
/// there (a user's own files beside them stay); a folder without the marker that already
/// holds one of them is refused (`output::staging::claim_entries`).
pub const OWNED_ENTRIES: [&str; 9] = [
    "study.csv",
    "manifest.json",
    "plots",
    "points",
    "accuracy.csv",
    "accuracy.svg",
    "accuracy.png",
    "slurm",
    ".results",
];

/// The study's results directory.
pub fn output_dir(study: &Study, options: &StudyOptions) -> PathBuf {
    options.out.clone().unwrap_or_else(|| study.out.clone())
}

/// Run the study's points not done yet (all of them, or one shard's), then, unless a shard,
/// publish the table, plots and manifest.
pub fn run(study: &Study, options: &StudyOptions, reporter: &dyn Reporter) -> Result<StudyReport> {
    let out = output_dir(study, options);
    let mut points = plan::plan(study)?;
    for p in &mut points {
        p.pipeline.geometry.trusted = options.trust_geometry;
    }
    crate::output::staging::claim_entries(&out, "study", &OWNED_ENTRIES)?;
    crate::output::staging::remove_stale_partials(&out.join(".results"), reporter);
    if options.shard.is_none() {
        table::clear_results(&out)?;
    }
    let mut seen = HashSet::new();
    let unique: Vec<&plan::Point> = points
        .iter()
        .filter(|p| seen.insert(p.key.clone()))
        .collect();
    let mine: Vec<&plan::Point> = match options.shard {
        Some(s) => unique
            .iter()
            .enumerate()
            .filter(|(i, _)| i % s.count == s.index)
            .map(|(_, p)| *p)
            .collect(),
        None => unique,
    };
    // Accuracy studies time their rungs, so they run one at a time unless told otherwise.
    let default_threads = study.accuracy.as_ref().map(|_| 1);
    let threads = execute::thread_count(
        options.threads.or(study.threads).or(default_threads),
        reporter,
    );
    let needs = execute::Needs {
        probe: study.probe.clone(),
        modes: study.natural_frequencies(),
        // The process's peak is the point's only while points run one at a time.
        peak_memory: threads == 1
            && (study.accuracy.is_some() || study.outputs.contains(&Output::PeakMemory)),
        amplitudes: study.accuracy.is_some(),
        stability: study.outputs.iter().any(Output::needs_stability),
    };
    let execution = execute::execute(&out, &mine, &needs, threads, reporter)?;
    if options.shard.is_some() {
        return Ok(StudyReport {
            out,
            table: None,
            points: mine.len(),
            ok: 0,
            warned: 0,
            failed: 0,
            missing: 0,
            execution: Some(execution),
            accuracy: None,
        });
    }
    finish(study, out, &points, Some(execution))
}

/// Join the shards' records into the table, plots and manifest a one-process run writes.
pub fn merge(study: &Study, options: &StudyOptions) -> Result<StudyReport> {
    let out = output_dir(study, options);
    let points = plan::plan(study)?;
    crate::output::staging::claim_entries(&out, "study", &OWNED_ENTRIES)?;
    table::clear_results(&out)?;
    finish(study, out, &points, None)
}

fn finish(
    study: &Study,
    out: PathBuf,
    points: &[plan::Point],
    execution: Option<Execution>,
) -> Result<StudyReport> {
    let rows = table::rows(&out, points)?;
    let (ok, failed, missing) = table::counts(&rows);
    let (table, accuracy) = match &study.accuracy {
        Some(spec) => {
            let report = accuracy::evaluate(spec, &rows, &out)?;
            let path = accuracy::publish(study, &out, &report, execution.as_ref())?;
            (path, Some(report))
        }
        None => (
            table::publish(study, &out, &rows, execution.as_ref())?,
            None,
        ),
    };
    Ok(StudyReport {
        out,
        table: Some(table),
        points: rows.len(),
        ok,
        warned: table::warned(&rows),
        failed,
        missing,
        execution,
        accuracy,
    })
}
