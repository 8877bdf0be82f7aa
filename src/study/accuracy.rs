//! What accuracy costs, as a study: ladders of settings (harmonics H, samples N, contact
//! parameter c, mesh size, element order, …), each rung's relative error against a reference
//! in several measures, and its wall time.
//!
//! Relative error of measure m at a rung: e_m = |m − m_ref| / |m_ref|, where m_ref is the
//! ladder's last rung (`reference: finest`) or a time-marching run of the pipeline
//! (`reference: transient`). Measures: the probe's first-harmonic amplitude and peak-to-peak
//! range, the mean and the peak total contact force, and the displacement over space and
//! period (`displacement_l2`, below). Wall time excludes meshing (the cache makes it free
//! after the first rung) and writing (rungs write their harmonic amplitudes); peak memory is
//! the run's peak resident memory (execute.rs). A failed rung is tabulated with its error and
//! the others go on; a rung that warned keeps its warnings (the last column of
//! `accuracy.csv`, the status column, and notes under the printed table). Outputs:
//! `accuracy.csv`, `accuracy.svg|png` (the Pareto plot of the probe's first-harmonic error
//! against wall time, reference named in the title) and `plots/pareto_<measure>.svg|png`,
//! and `manifest.json`.
//!
//! Displacement L2 error over space and period, from the harmonic amplitudes on the nodes
//! (`amplitudes.vtu`: a_0 = `static`, a_k, b_k = `harmonic_k_cos`, `harmonic_k_sin`) by
//! Parseval, (1/T)∫|u|² dt = |a_0|² + ½ Σ_k (|a_k|² + |b_k|²), a harmonic one side lacks
//! counting as zero:
//!   e_L2 = √( Σ_n (1/T)∫|u_n − u_ref,n|² dt ) / √( Σ_n (1/T)∫|u_ref,n|² dt ),
//! summed over nodes n, each weighted equally. Over every node when the rung's mesh is the
//! reference's (ladders of H, N, c); over the nodes both meshes have (same coordinates to
//! 1e-9 of the reference's size: at least the geometry's points, where probes sit) when the
//! mesh differs (ladders of mesh size or order); `displacement_l2_nodes` says how many. Not
//! available against a transient reference (the time marching keeps no amplitudes).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::displacement::{read_amplitudes, relative_l2};
use super::execute::Execution;
use super::plan::{point_dir, Mode};
use super::spec::{Accuracy, Design, Ladder, Reference, Study, WriteLevel};
use super::table::{csv_field, slug, warnings_field, Row, Staged};
use crate::config::Pipeline;
use crate::output::plot::{tick, Axis, Figure};
use crate::output::tables::csv_number;
use crate::output::tables::write_json;
use crate::pipeline::outputs::Output;
use crate::{Error, Result};

/// The measures compared by value, in table order.
pub const MEASURES: [Output; 4] = [
    Output::ProbeFirstHarmonic,
    Output::ProbePeakToPeak,
    Output::MeanContactForce,
    Output::PeakContactForce,
];

/// Every error measure, in table order: `MEASURES`, then the displacement L2 error.
pub const ERROR_NAMES: [&str; 5] = [
    "probe_first_harmonic",
    "probe_peak_to_peak",
    "mean_contact_force",
    "peak_contact_force",
    "displacement_l2",
];

/// Index of the displacement L2 error in `Rung::errors`.
const L2: usize = 4;

/// One rung of a ladder (or the transient reference).
#[derive(Clone, Debug, Serialize)]
pub struct Rung {
    /// The ladder's key (`reference` for the transient reference run).
    pub key: String,
    pub value: f64,
    pub status: String,
    pub exit_class: Option<String>,
    pub message: Option<String>,
    /// Wall time without meshing and writing [s].
    pub seconds: f64,
    /// Peak resident memory of the run [MB] (NaN: not measured).
    pub peak_memory: f64,
    pub free_dofs: f64,
    pub newton_iterations: f64,
    /// The measures' values, in `MEASURES` order.
    pub values: Vec<f64>,
    /// Relative errors against the reference in `ERROR_NAMES` order (NaN: no reference or
    /// no value).
    pub errors: Vec<f64>,
    /// Nodes the displacement L2 error summed over (0: none).
    pub l2_nodes: usize,
    /// What the rung's run warned of: an answer that depends on c, or that the solve reached
    /// by a detour, can be another periodic state than the reference's.
    pub warnings: Vec<String>,
    /// The rung's point directory (its `amplitudes.vtu`).
    #[serde(skip)]
    pub dir: PathBuf,
    pub is_reference: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct AccuracyReport {
    pub reference: Reference,
    pub rungs: Vec<Rung>,
}

/// The cheapest rung meeting `tolerance` in one measure.
#[derive(Clone, Debug)]
pub struct Cheapest {
    pub measure: &'static str,
    /// (ladder key, value, error, seconds, peak memory [MB]); None when no rung meets the
    /// tolerance.
    pub rung: Option<(String, f64, f64, f64, f64)>,
    /// The rung warned (its error may be between periodic states, `warning_notes`).
    pub warned: bool,
    /// The other rungs within the tolerance whose wall time is within `TIME_NOISE` of the
    /// chosen one's, as `key = value`.
    pub tied: Vec<String>,
}

fn rung(out: &Path, row: &Row, key: String, value: f64) -> Rung {
    let r = row.record.as_ref();
    Rung {
        key,
        value,
        status: row.status().to_string(),
        exit_class: r.and_then(|r| r.exit_class.clone()),
        message: r.and_then(|r| r.error.clone()),
        seconds: row.output(&Output::SolveTime),
        peak_memory: row.output(&Output::PeakMemory),
        free_dofs: row.output(&Output::FreeDofs),
        newton_iterations: row.output(&Output::NewtonIterations),
        values: MEASURES.iter().map(|m| row.output(m)).collect(),
        errors: vec![f64::NAN; ERROR_NAMES.len()],
        l2_nodes: 0,
        warnings: row.warnings().to_vec(),
        dir: point_dir(out, &row.point.key),
        is_reference: false,
    }
}

impl Rung {
    /// Whether the rung's run warned.
    fn warned(&self) -> bool {
        !self.warnings.is_empty()
    }

    /// The rung's value as the table prints it (`transient` for the transient reference).
    fn value_label(&self) -> String {
        if self.key == "reference" {
            "transient".into()
        } else {
            tick(self.value)
        }
    }
}

fn relative(v: f64, reference: f64) -> f64 {
    if reference == 0.0 && v == 0.0 {
        0.0
    } else {
        ((v - reference) / reference).abs()
    }
}

/// The rungs with their errors, from the study's rows and the rungs' amplitudes under `out`
/// (ladders in order, then the transient reference if there is one).
pub fn evaluate(spec: &Accuracy, rows: &[Row], out: &Path) -> crate::Result<AccuracyReport> {
    let transient = rows
        .iter()
        .find(|r| r.point.mode == Mode::Transient)
        .map(|r| rung(out, r, "reference".into(), f64::NAN));
    let mut rungs = Vec::new();
    let mut at = 0;
    for ladder in &spec.ladders {
        let mut ladder_rungs: Vec<Rung> = rows[at..at + ladder.values.len()]
            .iter()
            .zip(&ladder.values)
            .map(|(row, &v)| rung(out, row, ladder.key.clone(), v))
            .collect();
        at += ladder.values.len();
        let reference = match spec.reference {
            Reference::Finest => ladder_rungs.last_mut().map(|r| {
                r.is_reference = true;
                r.values.clone()
            }),
            Reference::Transient => transient.as_ref().map(|t| t.values.clone()),
        };
        if let Some(reference) = reference {
            for r in &mut ladder_rungs {
                r.errors = r
                    .values
                    .iter()
                    .zip(&reference)
                    .map(|(&v, &m)| relative(v, m))
                    .chain([f64::NAN])
                    .collect();
            }
        }
        if spec.reference == Reference::Finest {
            displacement_errors(&mut ladder_rungs)?;
        }
        rungs.extend(ladder_rungs);
    }
    if let Some(mut t) = transient {
        t.is_reference = true;
        t.errors = vec![0.0; ERROR_NAMES.len()];
        t.errors[L2] = f64::NAN;
        rungs.push(t);
    }
    Ok(AccuracyReport {
        reference: spec.reference,
        rungs,
    })
}

/// Each rung's displacement L2 error against its ladder's reference rung (the one marked
/// `is_reference`), from their `amplitudes.vtu`.
fn displacement_errors(rungs: &mut [Rung]) -> crate::Result<()> {
    let reference = match rungs.iter().find(|r| r.is_reference && r.status == "ok") {
        Some(r) => read_amplitudes(&r.dir.join("amplitudes.vtu"))?,
        None => None,
    };
    let Some(reference) = reference else {
        return Ok(());
    };
    for r in rungs.iter_mut().filter(|r| r.status == "ok") {
        let amplitudes = read_amplitudes(&r.dir.join("amplitudes.vtu"))?;
        if let Some((e, nodes)) = amplitudes.and_then(|a| relative_l2(&a, &reference)) {
            r.errors[L2] = e;
            r.l2_nodes = nodes;
        }
    }
    Ok(())
}

/// Wall times within this factor of the fastest are taken as equal: on a shared machine two
/// runs of one rung differ by up to about a tenth, and two rungs of nearly equal work were
/// measured in either order (0.232/0.230 s, 0.217/0.197 s, 0.207/0.215 s for H = 15/20 of
/// the 0.5%-damped reference strip, issue #51). The cheapest rung is then the earliest of
/// the tied ones in the study's order (each ladder lists its values cheapest first), which
/// does not depend on the machine's load.
pub const TIME_NOISE: f64 = 1.5;

impl AccuracyReport {
    /// Per measure, the cheapest rung whose error is at most `tolerance` (the reference itself
    /// does not count): of the rungs whose wall time is within `TIME_NOISE` of the least, the
    /// first in the study's order; `tied` names the others.
    pub fn cheapest(&self, tolerance: f64) -> Vec<Cheapest> {
        ERROR_NAMES
            .iter()
            .enumerate()
            .map(|(m, measure)| {
                let within: Vec<&Rung> = self
                    .rungs
                    .iter()
                    .filter(|r| !r.is_reference && r.errors[m] <= tolerance)
                    .collect();
                let least = within
                    .iter()
                    .map(|r| r.seconds)
                    .fold(f64::INFINITY, f64::min);
                let mut tied = within
                    .into_iter()
                    .filter(|r| !(r.seconds > TIME_NOISE * least));
                let best = tied.next();
                Cheapest {
                    measure,
                    rung: best.map(|r| {
                        let (key, value) = (r.key.clone(), r.value);
                        (key, value, r.errors[m], r.seconds, r.peak_memory)
                    }),
                    warned: best.is_some_and(Rung::warned),
                    tied: tied
                        .map(|r| format!("{} = {}", short(&r.key), r.value_label()))
                        .collect(),
                }
            })
            .collect()
    }

    /// What the errors are measured against, for titles and messages.
    pub fn reference_name(&self) -> String {
        match self.reference {
            Reference::Transient => "a time-marching (transient) run".into(),
            Reference::Finest => {
                let names: Vec<String> = self
                    .rungs
                    .iter()
                    .filter(|r| r.is_reference)
                    .map(|r| format!("{} = {}", short(&r.key), tick(r.value)))
                    .collect();
                format!("the finest rung ({})", names.join(", "))
            }
        }
    }

    /// A Markdown table of every rung.
    pub fn markdown(&self) -> String {
        let mut s = String::from("| setting | value | wall time [s] | peak memory [MB] | probe 1st-harmonic amplitude [m] | error | probe peak-to-peak error | mean contact force error | peak contact force error | displacement L2 error | Newton its | free dofs | status |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        let e = |v: f64| {
            if v.is_finite() {
                format!("{v:.2e}")
            } else {
                "-".into()
            }
        };
        for r in &self.rungs {
            let value = r.value_label();
            let _ = writeln!(
                s,
                "| {} | {value} | {:.3} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.key,
                r.seconds,
                if r.peak_memory.is_finite() {
                    format!("{:.0}", r.peak_memory)
                } else {
                    "-".into()
                },
                e(r.values[0]),
                e(r.errors[0]),
                e(r.errors[1]),
                e(r.errors[2]),
                e(r.errors[3]),
                e(r.errors[L2]),
                if r.newton_iterations.is_finite() {
                    format!("{}", r.newton_iterations)
                } else {
                    "-".into()
                },
                if r.free_dofs.is_finite() {
                    format!("{}", r.free_dofs)
                } else {
                    "-".into()
                },
                match r.warnings.len() {
                    0 => r.status.clone(),
                    n => format!("{}, {n} warning{}", r.status, if n == 1 { "" } else { "s" }),
                },
            );
        }
        s
    }

    /// The warnings of the rungs that warned, one line each, after a line on what they mean
    /// for the errors (empty when none warned).
    pub fn warning_notes(&self) -> Vec<String> {
        let warned: Vec<&Rung> = self.rungs.iter().filter(|r| r.warned()).collect();
        if warned.is_empty() {
            return Vec::new();
        }
        let mut notes = vec![format!(
            "{} of {} rungs warned: a rung whose answer depends on c, or that its solve reached by \
             a detour, can be another periodic state than the reference's, and its error then \
             measures the distance between states rather than what the setting costs",
            warned.len(),
            self.rungs.len()
        )];
        for r in warned {
            for w in &r.warnings {
                notes.push(format!("{} = {}: {w}", short(&r.key), r.value_label()));
            }
        }
        notes
    }

    /// `accuracy.csv`.
    pub fn csv(&self) -> String {
        let mut s = String::from(
            "ladder,value,status,exit_class,wall_time,peak_memory,free_dofs,newton_iterations",
        );
        for m in &MEASURES {
            let _ = write!(s, ",{0},error_{0}", m.name());
        }
        s.push_str(",error_displacement_l2,displacement_l2_nodes,error,warnings\n");
        for r in &self.rungs {
            let value = if r.key == "reference" {
                "transient".into()
            } else {
                csv_number(r.value)
            };
            let _ = write!(
                s,
                "{},{value},{},{},{},{},{},{}",
                csv_field(&r.key),
                r.status,
                r.exit_class.clone().unwrap_or_default(),
                csv_number(r.seconds),
                csv_number(r.peak_memory),
                csv_number(r.free_dofs),
                csv_number(r.newton_iterations)
            );
            for (v, e) in r.values.iter().zip(&r.errors) {
                let _ = write!(s, ",{},{}", csv_number(*v), csv_number(*e));
            }
            let _ = writeln!(
                s,
                ",{},{},{},{}",
                csv_number(r.errors[L2]),
                r.l2_nodes,
                csv_field(r.message.as_deref().unwrap_or("")),
                warnings_field(&r.warnings)
            );
        }
        s
    }

    /// The Pareto plot of measure `m`: relative error against wall time, one line per ladder.
    pub fn pareto(&self, m: usize) -> Figure {
        let title = format!(
            "error of {} vs wall time; reference: {}",
            ERROR_NAMES[m],
            self.reference_name()
        );
        let mut fig = Figure::new(
            title,
            Axis::log("wall time without meshing and writing [s]"),
            Axis::log(format!("relative error of {}", ERROR_NAMES[m])),
        );
        let mut keys: Vec<&str> = Vec::new();
        for r in &self.rungs {
            if r.key != "reference" && !keys.contains(&r.key.as_str()) {
                keys.push(&r.key);
            }
        }
        for key in keys {
            let pts = self
                .rungs
                .iter()
                .filter(|r| r.key == key && !r.is_reference)
                .map(|r| (r.seconds, r.errors[m]))
                .collect();
            fig = fig.line(short(key), pts);
        }
        // A warned rung's error may be between states, not what its setting costs.
        for r in self.rungs.iter().filter(|r| r.warned()) {
            let (x, y) = (r.seconds, r.errors[m]);
            if !r.is_reference && x > 0.0 && y > 0.0 && y.is_finite() {
                fig = fig.mark(
                    format!("{} = {}: warned", short(&r.key), r.value_label()),
                    (x, y),
                );
            }
        }
        fig
    }
}

/// `harmonic_balance.harmonics` → `harmonics`, for legends.
fn short(key: &str) -> &str {
    key.rsplit('.')
        .find(|s| s.parse::<usize>().is_err())
        .unwrap_or(key)
}

#[derive(Serialize)]
struct Manifest<'a> {
    study: &'a str,
    pipeline: &'a Path,
    hbcontact_version: &'static str,
    kind: &'static str,
    reference: String,
    rungs: usize,
    failed: usize,
    /// Rungs that ran and warned (`accuracy.csv`'s `warnings` column says of what).
    warned: usize,
    files: Vec<String>,
    execution: Option<&'a Execution>,
}

/// Write `accuracy.csv`, the Pareto plots and `manifest.json` (staged, moved in at the end).
pub fn publish(
    study: &Study,
    out: &Path,
    report: &AccuracyReport,
    execution: Option<&Execution>,
) -> Result<PathBuf> {
    let staged = Staged::new(out)?;
    let table = staged.dir.join("accuracy.csv");
    std::fs::write(&table, report.csv()).map_err(|e| Error::io(&table, e))?;
    report.pareto(0).save(&staged.dir.join("accuracy"))?;
    let mut files = vec![
        "accuracy.csv".to_string(),
        "accuracy.svg".into(),
        "accuracy.png".into(),
    ];
    for (m, measure) in ERROR_NAMES.iter().enumerate() {
        if report.rungs.iter().any(|r| r.errors[m] > 0.0) {
            let stem = format!("pareto_{}", slug(measure));
            report
                .pareto(m)
                .save(&staged.dir.join("plots").join(&stem))?;
            files.extend([format!("plots/{stem}.svg"), format!("plots/{stem}.png")]);
        }
    }
    let manifest = Manifest {
        study: &study.name,
        pipeline: &study.pipeline,
        hbcontact_version: env!("CARGO_PKG_VERSION"),
        kind: "accuracy",
        reference: report.reference_name(),
        rungs: report.rungs.len(),
        failed: report.rungs.iter().filter(|r| r.status != "ok").count(),
        warned: report.rungs.iter().filter(|r| r.warned()).count(),
        files,
        execution,
    };
    write_json(&staged.dir.join("manifest.json"), &manifest)?;
    staged.publish()?;
    Ok(out.join("accuracy.csv"))
}

/// The ladders `hbcontact accuracy` climbs when none is given: with contact the harmonics
/// H/4, H/2, H, 2H of the pipeline's H (those at least 1, each once), then element order 1, 2.
pub fn default_ladders(pipeline: &Pipeline) -> Vec<Ladder> {
    let mut ladders = Vec::new();
    if pipeline.contact.is_some() {
        let h = pipeline.harmonic_balance.harmonics.max(1);
        let mut values: Vec<f64> = Vec::new();
        for v in [h / 4, h / 2, h, 2 * h] {
            if v >= 1 && !values.contains(&(v as f64)) {
                values.push(v as f64);
            }
        }
        ladders.push(Ladder {
            key: "harmonic_balance.harmonics".into(),
            values,
        });
    }
    ladders.push(Ladder {
        key: "geometry.order".into(),
        values: vec![1.0, 2.0],
    });
    ladders
}

/// Where `hbcontact accuracy` writes without `--out`: `<output.directory>-accuracy`.
pub fn output_dir(pipeline: &Pipeline) -> PathBuf {
    let mut d = pipeline.output.directory.clone().into_os_string();
    d.push("-accuracy");
    PathBuf::from(d)
}

/// The accuracy study of `hbcontact accuracy`: `ladders` (none: `default_ladders`) over the
/// pipeline `pipeline` was read from, with `set` applied to every rung, against `reference`,
/// written to `out` (None: `output_dir`). Its rungs run one at a time, so that no rung's wall
/// time is measured beside another's. A ladder with fewer values than the reference needs
/// (two with `Finest`: the last is the reference) or a value that is not finite is refused
/// with the pipeline named.
pub fn from_ladders(
    pipeline: &Pipeline,
    set: &[String],
    ladders: Vec<Ladder>,
    reference: Reference,
    out: Option<&Path>,
) -> Result<Study> {
    let need = if reference == Reference::Finest { 2 } else { 1 };
    for l in &ladders {
        if l.values.len() < need || l.values.iter().any(|v| !v.is_finite()) {
            return Err(Error::Config {
                path: pipeline.source.clone(),
                message: format!(
                    "--ladder {}: needs at least {need} finite values, cheapest first (the last is the reference unless --transient-reference), e.g. {}=5,10,20",
                    crate::error::excerpt(&l.key),
                    crate::error::excerpt(&l.key)
                ),
            });
        }
    }
    let ladders = if ladders.is_empty() {
        default_ladders(pipeline)
    } else {
        ladders
    };
    Ok(Study {
        name: format!("{}-accuracy", pipeline.name),
        source: pipeline.source.clone(),
        pipeline: pipeline.source.clone(),
        set: set.to_vec(),
        design: Design::Grid,
        parameters: Vec::new(),
        outputs: Output::defaults(),
        probe: None,
        write: WriteLevel::Summary,
        full_points: Vec::new(),
        threads: Some(1),
        out: out.map_or_else(|| output_dir(pipeline), Path::to_path_buf),
        accuracy: Some(Accuracy { reference, ladders }),
    })
}
