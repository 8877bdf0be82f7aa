//! A parameter study's results: `study.csv` (one row per point: parameters, outputs, status,
//! exit class, error, key, and the point's warnings joined by ` | `), plots of each output
//! against each parameter (lines for grids, one per value of the other parameter; a heat map
//! per output for two-parameter grids; points for lists and Latin hypercubes), and
//! `manifest.json`. Built from the points' records only, so a
//! one-process run and merged shards give the same table.
//!
//! Publishing is staged: everything is written into `<out>/.results.partial-<pid>` and moved
//! into place at the end, manifest last; the previous study's results are removed when a
//! study starts, so none is ever left looking current.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::execute::{read_record, results_files, Execution, PointRecord, Recorded};
use super::plan::Point;
use super::spec::{Design, Parameter, Study, Value};
use crate::output::plot::{tick, Axis, Figure, HeatMap};
use crate::output::tables::csv_number;
use crate::output::tables::write_json;
use crate::pipeline::outputs::Output;
use crate::{Error, Result};

/// One row of the table.
#[derive(Clone, Debug)]
pub struct Row {
    pub point: Point,
    /// None: not run yet (a shard missing from a merge).
    pub record: Option<PointRecord>,
}

impl Row {
    pub fn status(&self) -> &str {
        self.record
            .as_ref()
            .map_or("missing", |r| r.status.as_str())
    }
    pub fn output(&self, o: &Output) -> f64 {
        self.record.as_ref().map_or(f64::NAN, |r| r.output(o))
    }
    /// What the point's run warned of (nothing without a record).
    pub fn warnings(&self) -> &[String] {
        self.record.as_ref().map_or(&[], |r| r.warnings.as_slice())
    }
}

/// A point's warnings as one CSV field, joined by ` | ` (last in a row: text with commas
/// quoted, and every column before it where a reader splitting at commas expects it).
pub fn warnings_field(warnings: &[String]) -> String {
    csv_field(&warnings.join(" | "))
}

/// The rows of every point, from their records (`read_record`): a point without one is
/// missing; a record cut short, or one that does not check, is an error naming it (a merge
/// runs nothing, so it cannot run the point again).
pub fn rows(out: &Path, points: &[Point]) -> Result<Vec<Row>> {
    points
        .iter()
        .map(|p| {
            let record = match read_record(out, p)? {
                Recorded::Missing => None,
                Recorded::CutShort(what) => {
                    return Err(Error::Input(format!(
                        "{what}: run the study again without --merge (or the shard holding the point), which runs the point again, or delete the folder {}",
                        super::plan::point_dir(out, &p.key).display()
                    )))
                }
                Recorded::Valid(r) => Some(r),
            };
            Ok(Row {
                point: p.clone(),
                record,
            })
        })
        .collect()
}

/// A CSV field, quoted when it holds a comma, quote or line break.
pub fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The table as CSV text.
pub fn csv(study: &Study, rows: &[Row]) -> String {
    let mut s = String::from("point");
    for p in &study.parameters {
        let _ = write!(s, ",{}", csv_field(&p.key));
    }
    for o in &study.outputs {
        let _ = write!(s, ",{}", o.name());
    }
    s.push_str(",status,exit_class,error,key,warnings\n");
    for row in rows {
        let _ = write!(s, "{}", row.point.index);
        for (_, v) in &row.point.values {
            let field = match v {
                Value::Number(x) => csv_number(*x),
                Value::Text(t) => csv_field(t),
            };
            let _ = write!(s, ",{field}");
        }
        for o in &study.outputs {
            let _ = write!(s, ",{}", csv_number(row.output(o)));
        }
        let r = row.record.as_ref();
        let class = r.and_then(|r| r.exit_class.clone()).unwrap_or_default();
        let error = r.and_then(|r| r.error.clone()).unwrap_or_default();
        let _ = writeln!(
            s,
            ",{},{},{},{},{}",
            row.status(),
            class,
            csv_field(&error),
            row.point.key,
            warnings_field(row.warnings())
        );
    }
    s
}

/// A file-name-safe version of a label.
pub fn slug(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// Where a point's value of parameter `p` sits on its axis: the number, or for a parameter
/// with string values the value's position in its list (a categorical axis).
fn position(p: &Parameter, v: &Value) -> f64 {
    if p.numeric() {
        v.number().unwrap_or(f64::NAN)
    } else {
        p.values
            .iter()
            .position(|w| w == v)
            .map_or(f64::NAN, |i| i as f64)
    }
}

/// The x axis of parameter `p`: linear, or categorical (the values as tick labels) when its
/// values are strings.
fn parameter_axis(p: &Parameter) -> Axis {
    if p.numeric() {
        Axis::linear(p.axis_label())
    } else {
        Axis::categorical(
            p.axis_label(),
            p.values.iter().map(Value::to_string).collect(),
        )
    }
}

/// The legend of the points whose run warned (study.csv's `warnings` says of what).
pub const WARNED: &str = "warned (study.csv says of what)";

/// `o`'s axis label; forces and energies per metre of thickness where every point's body has
/// the default thickness of 1 m (as `Material::force_unit` says for the run's plots).
fn output_label(o: &Output, rows: &[Row]) -> String {
    let material = |r: &Row| crate::pipeline::model::material(&r.point.pipeline);
    let per_metre = rows.iter().all(|r| material(r).thickness == 1.0);
    match (o.unit(), per_metre) {
        (unit @ ("N" | "J"), true) => format!("{} [{unit} per m of thickness]", o.name()),
        _ => o.axis_label(),
    }
}

/// The plots of one output against each parameter (and its heat map when both parameters of
/// a two-parameter grid are numeric), into `dir`, the points whose run warned marked. A parameter with string values is a
/// categorical axis (its values as tick labels); in a two-parameter grid it also names the
/// lines of the plot against the other.
fn plot_output(study: &Study, rows: &[Row], o: &Output, dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let params = &study.parameters;
    let two_grid = study.design == Design::Grid && params.len() == 2;
    let x = |r: &Row, j: usize| position(&params[j], &r.point.values[j].1);
    for (j, p) in params.iter().enumerate() {
        let title = format!("{}: {} against {}", study.name, o.name(), p.label);
        let mut fig = Figure::new(
            title,
            parameter_axis(p),
            Axis::linear(output_label(o, rows)),
        );
        let point = |r: &Row| (x(r, j), r.output(o));
        if two_grid {
            let other = &params[1 - j];
            for v in &other.values {
                let mut pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| r.point.values[1 - j].1 == *v)
                    .map(point)
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                let unit = other
                    .unit
                    .as_deref()
                    .map(|u| format!(" {u}"))
                    .unwrap_or_default();
                let shown = v.number().map_or_else(|| v.to_string(), tick);
                fig = fig.line(format!("{} = {shown}{unit}", other.label), pts);
            }
        } else if study.design == Design::Grid && params.len() == 1 && p.numeric() {
            fig = fig.line(o.name(), rows.iter().map(point).collect());
        } else {
            fig = fig.scatter("points", rows.iter().map(point).collect());
        }
        // Points whose run warned, marked over their curve: their values need the warning read.
        let warned: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| !r.warnings().is_empty())
            .map(point)
            .collect();
        if !warned.is_empty() {
            fig = fig.scatter(WARNED, warned);
        }
        let stem = dir.join(format!("{}_vs_{}", o.name(), slug(&p.label)));
        fig.save(&stem)?;
        files.push(stem);
    }
    if two_grid && params.iter().all(|p| p.numeric()) {
        let (px, py) = (&params[0], &params[1]);
        let numbers = |p: &super::spec::Parameter| -> Vec<f64> {
            p.values.iter().filter_map(Value::number).collect()
        };
        let (xs, ys) = (numbers(px), numbers(py));
        let values = ys
            .iter()
            .map(|&y| {
                xs.iter()
                    .map(|&xv| {
                        rows.iter()
                            .find(|r| x(r, 0) == xv && x(r, 1) == y)
                            .map_or(f64::NAN, |r| r.output(o))
                    })
                    .collect()
            })
            .collect();
        let map = HeatMap {
            title: format!("{}: {}", study.name, output_label(o, rows)),
            x: Axis::linear(px.axis_label()),
            y: Axis::linear(py.axis_label()),
            xs,
            ys,
            values,
        };
        let stem = dir.join(format!("{}_heatmap", o.name()));
        map.save(&stem)?;
        files.push(stem);
    }
    Ok(files)
}

/// What `manifest.json` says.
#[derive(Serialize)]
struct Manifest<'a> {
    study: &'a str,
    study_file: &'a Path,
    pipeline: &'a Path,
    hbcontact_version: &'static str,
    kind: &'static str,
    points: usize,
    ok: usize,
    /// Points that ran and warned (study.csv's `warnings` column says of what).
    warned: usize,
    failed: usize,
    missing: usize,
    parameters: Vec<ManifestParameter<'a>>,
    outputs: Vec<String>,
    files: Vec<String>,
    /// This process's run (absent after `--merge`).
    execution: Option<&'a Execution>,
    point_keys: Vec<&'a str>,
}

#[derive(Serialize)]
struct ManifestParameter<'a> {
    key: &'a str,
    label: &'a str,
    unit: Option<&'a str>,
}

/// Counts of ok, failed and missing rows.
pub fn counts(rows: &[Row]) -> (usize, usize, usize) {
    let ok = rows.iter().filter(|r| r.status() == "ok").count();
    let failed = rows.iter().filter(|r| r.status() == "failed").count();
    (ok, failed, rows.len() - ok - failed)
}

/// Points whose run warned.
pub fn warned(rows: &[Row]) -> usize {
    rows.iter().filter(|r| !r.warnings().is_empty()).count()
}

/// Remove a previous study's table, plots and manifest.
pub fn clear_results(out: &Path) -> Result<()> {
    for path in results_files(out).iter().chain(
        [
            out.join("accuracy.csv"),
            out.join("accuracy.svg"),
            out.join("accuracy.png"),
        ]
        .iter(),
    ) {
        let gone = if path.is_dir() {
            std::fs::remove_dir_all(path)
        } else {
            std::fs::remove_file(path)
        };
        match gone {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(Error::io(path, e)),
            _ => {}
        }
    }
    Ok(())
}

/// A staging directory for results, moved into `out` by `Staged::publish`.
pub struct Staged {
    pub dir: PathBuf,
    out: PathBuf,
}

impl Staged {
    pub fn new(out: &Path) -> Result<Self> {
        let dir = out.join(format!(".results.partial-{}", std::process::id()));
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        }
        std::fs::create_dir_all(dir.join("plots")).map_err(|e| Error::io(&dir, e))?;
        crate::output::staging::mark(&dir, "study", ".results")?;
        Ok(Staged {
            dir,
            out: out.to_path_buf(),
        })
    }

    /// Move every staged entry into `out`, `manifest.json` last.
    pub fn publish(self) -> Result<()> {
        let mut names: Vec<_> = std::fs::read_dir(&self.dir)
            .map_err(|e| Error::io(&self.dir, e))?
            .flatten()
            .map(|e| e.file_name())
            .filter(|n| n != crate::output::staging::MARKER)
            .collect();
        names.sort_by_key(|n| n == "manifest.json");
        for name in names {
            let (from, to) = (self.dir.join(&name), self.out.join(&name));
            if to.is_dir() {
                std::fs::remove_dir_all(&to).map_err(|e| Error::io(&to, e))?;
            }
            std::fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
        std::fs::remove_dir_all(&self.dir).map_err(|e| Error::io(&self.dir, e))
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Write the table, plots and manifest of a parameter study.
pub fn publish(
    study: &Study,
    out: &Path,
    rows: &[Row],
    execution: Option<&Execution>,
) -> Result<PathBuf> {
    let staged = Staged::new(out)?;
    let table = staged.dir.join("study.csv");
    std::fs::write(&table, csv(study, rows)).map_err(|e| Error::io(&table, e))?;
    let mut files = vec!["study.csv".to_string()];
    for o in &study.outputs {
        if rows.iter().any(|r| r.output(o).is_finite()) {
            for stem in plot_output(study, rows, o, &staged.dir.join("plots"))? {
                let name = stem.file_name().map(|n| n.to_string_lossy().to_string());
                files.extend(
                    name.iter()
                        .flat_map(|n| [format!("plots/{n}.svg"), format!("plots/{n}.png")]),
                );
            }
        }
    }
    let (ok, failed, missing) = counts(rows);
    let manifest = Manifest {
        study: &study.name,
        study_file: &study.source,
        pipeline: &study.pipeline,
        hbcontact_version: env!("CARGO_PKG_VERSION"),
        kind: "parameters",
        points: rows.len(),
        ok,
        warned: warned(rows),
        failed,
        missing,
        parameters: study
            .parameters
            .iter()
            .map(|p| ManifestParameter {
                key: &p.key,
                label: &p.label,
                unit: p.unit.as_deref(),
            })
            .collect(),
        outputs: study.outputs.iter().map(Output::name).collect(),
        files,
        execution,
        point_keys: rows.iter().map(|r| r.point.key.as_str()).collect(),
    };
    write_json(&staged.dir.join("manifest.json"), &manifest)?;
    staged.publish()?;
    Ok(out.join("study.csv"))
}
