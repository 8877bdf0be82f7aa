//! `hbcontact compare HB_DIR TRANSIENT_DIR`: the differences between a harmonic-balance result
//! and a time-marching one of the same scene, read back from their directories
//! (`summary.json`, `probes.csv`, `contact.csv`, `contact_steps.csv`).
//!
//! Glossary: for a signal x sampled evenly over one period at times t_j (j < n), its harmonic
//! k is z_k = a_k − i b_k with a_k = (2/n) Σ x_j cos kωt_j, b_k = (2/n) Σ x_j sin kωt_j (the
//! convention of `hbm::fourier`), amplitude |z_k|; both solvers write phases in [0, T), so the
//! phase difference arg z_k,HB − arg z_k,TM is meaningful. Relative differences are
//! (HB − TM)/|TM|: the time marching is the reference.
//!
//! Compared: per probe and component, the first-harmonic amplitude (HB at the N samples of
//! `probes.csv`, TM at its frames) and half the peak-to-peak range; for contact scenes, the
//! summaries' mean and peak total contact force (HB over its samples, TM over every time
//! step), and the first three harmonics of the total contact force (TM from
//! `contact_steps.csv`, every step).
//!
//! Same scene: the two summaries must describe one mesh (`MESH_KEYS`: order, node and cell
//! counts, shortest edge) and one frequency, else `compare` refuses (exit 2): differences
//! between meshes are not the solvers'. Other differences of the scene as the summaries record
//! it (`SCENE_KEYS`: name, geometry parameters and mesh size, supports, loads' harmonics,
//! damping, contact set and gaps) are `warnings`, printed before the table (parameters written
//! out at their `.geo` default give the same mesh).
//!
//! Overlays: `Comparison::overlays` keeps both time series of every probe column, of the
//! opening of the contact node with the largest HB force (`contact.csv`; time marching at its
//! frames) and of the total contact force; `write` draws them (`write_overlays`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use faer::c64;
use schemars::JsonSchema;
use serde::Serialize;

use super::plots::{over_period, style, time_axis};
use crate::hbm::fourier;
use crate::output::plot::{Axis, Figure};
use crate::output::tables::{write_json, write_text};
use crate::{Error, Result};

/// One compared quantity.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Difference {
    /// What is compared, e.g. `probe ux first harmonic`.
    pub quantity: String,
    /// Its unit.
    pub unit: String,
    pub harmonic_balance: f64,
    pub transient: f64,
    /// harmonic_balance − transient.
    pub difference: f64,
    /// (harmonic_balance − transient) / |transient|; null when the transient value is 0.
    pub relative: Option<f64>,
    /// For harmonics: arg z_HB − arg z_TM in degrees, wrapped to (−180, 180].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_difference_deg: Option<f64>,
}

/// A time series over one period.
#[derive(Clone, Debug, Default)]
pub struct Series {
    pub times: Vec<f64>,
    pub values: Vec<f64>,
}

/// Both solvers' series of one signal, for plotting.
#[derive(Clone, Debug)]
pub struct Overlay {
    /// Names the plot file (`compare_<quantity>`), e.g. `probe_ux`.
    pub quantity: String,
    /// For a person (plot title and axis), e.g. `probe u_x`.
    pub title: String,
    pub unit: String,
    pub harmonic_balance: Series,
    pub transient: Series,
}

/// What `compare` found (`compare.json`).
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct Comparison {
    /// The harmonic-balance result directory.
    pub harmonic_balance: PathBuf,
    /// The time-marching result directory.
    pub transient: PathBuf,
    /// The fundamental frequency both share [Hz].
    pub frequency_hz: f64,
    pub differences: Vec<Difference>,
    /// How the two scenes differ, as their summaries record them (name, supports, loads'
    /// harmonics, damping, contact set and gaps): each makes the differences the scenes' as
    /// much as the solvers'. Empty when the scenes agree.
    pub warnings: Vec<String>,
    /// Things to know about the comparison (missing probes, contact in one result only).
    pub notes: Vec<String>,
    /// Both solvers' series of every compared signal (not written; for plots).
    #[serde(skip)]
    #[schemars(skip)]
    pub overlays: Vec<Overlay>,
}

/// One result directory read back.
struct ResultDir {
    dir: PathBuf,
    summary: serde_json::Value,
    probes: Table,
    contact: Option<Table>,
    /// Time marching: every step's total force.
    steps: Option<Table>,
}

/// A CSV table: column name → values.
type Table = BTreeMap<String, Vec<f64>>;

/// Compare a harmonic-balance result directory with a time-marching one.
pub fn compare(hb_dir: &Path, transient_dir: &Path) -> Result<Comparison> {
    let hb = read_dir(hb_dir, "harmonic_balance", "hbcontact run")?;
    let tm = read_dir(transient_dir, "transient", "hbcontact transient")?;
    let frequency_hz = number(&hb, &["frequency_hz"])?;
    let tm_frequency = number(&tm, &["frequency_hz"])?;
    if (frequency_hz - tm_frequency).abs() > 1e-9 * frequency_hz.abs() {
        return Err(Error::Input(format!(
            "{} is at {frequency_hz} Hz but {} at {tm_frequency} Hz: compare results of the same scene",
            hb.dir.display(),
            tm.dir.display()
        )));
    }
    let meshes = differing(&hb, &tm, MESH_KEYS);
    if !meshes.is_empty() {
        return Err(Error::Input(format!(
            "{} and {} are results on different meshes ({}): their differences would be the meshes', not the solvers'; compare a `run` and a `transient` of the same pipeline and geometry settings",
            hb.dir.display(),
            tm.dir.display(),
            meshes.join("; ")
        )));
    }
    let scene = differing(&hb, &tm, SCENE_KEYS);
    let mut c = Comparison {
        harmonic_balance: hb.dir.clone(),
        transient: tm.dir.clone(),
        frequency_hz,
        differences: Vec::new(),
        warnings: scene
            .into_iter()
            .map(|d| format!("the scenes differ in {d}: the differences below are partly the scenes', not only the solvers'"))
            .collect(),
        notes: Vec::new(),
        overlays: Vec::new(),
    };
    let omega = 2.0 * std::f64::consts::PI * frequency_hz;
    compare_probes(&hb, &tm, omega, &mut c);
    compare_contact(&hb, &tm, omega, &mut c)?;
    Ok(c)
}

/// The summary fields that fix the mesh: results that differ in one are refused.
const MESH_KEYS: &[&str] = &[
    "/mesh/order",
    "/mesh/nodes",
    "/mesh/cells",
    "/mesh/min_edge_length",
];

/// The summary fields that describe the rest of the scene both solvers see (not the mass
/// model, the time basis or the harmonics computed, which are the solvers' own): results that
/// differ in one are compared with a warning naming it.
const SCENE_KEYS: &[&str] = &[
    "/name",
    "/pipeline",
    "/mesh/geometry",
    "/mesh/parameters",
    "/mesh/mesh_size",
    "/sizes/free_dofs",
    "/sizes/prescribed_dofs",
    "/effects/static_load",
    "/effects/excited_harmonics",
    "/effects/prescribed_motion",
    "/effects/damping",
    "/effects/contact",
    "/contact_setup/candidates",
    "/contact_setup/kept",
    "/contact_setup/min_initial_gap",
    "/contact_setup/max_initial_gap",
];

/// Whether two summary values are the same: numbers to 1e-9 relative, the rest exactly,
/// objects and lists element by element.
fn same(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-9 * x.abs().max(y.abs()),
            _ => x == y,
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
        }
        _ => a == b,
    }
}

/// Each of `keys` (JSON pointers into the summaries) whose values differ, as
/// "`mesh.nodes` 1787 (harmonic balance) and 1950 (transient)".
fn differing(hb: &ResultDir, tm: &ResultDir, keys: &[&str]) -> Vec<String> {
    let shown = |v: Option<&serde_json::Value>| {
        v.map_or("absent".to_string(), |v| {
            crate::error::excerpt(&v.to_string())
        })
    };
    keys.iter()
        .filter_map(|key| {
            let (a, b) = (hb.summary.pointer(key), tm.summary.pointer(key));
            let equal = match (a, b) {
                (Some(a), Some(b)) => same(a, b),
                (None, None) => true,
                _ => false,
            };
            (!equal).then(|| {
                format!(
                    "`{}` {} (harmonic balance) and {} (transient)",
                    key.trim_start_matches('/').replace('/', "."),
                    shown(a),
                    shown(b)
                )
            })
        })
        .collect()
}

/// The largest summary.json and CSV `compare` reads (a summary is kilobytes; a transient's
/// contact_steps.csv holds one line per time step, 100 bytes a line).
const MAX_SUMMARY_BYTES: u64 = 64 << 20;
const MAX_TABLE_BYTES: u64 = 1 << 30;

/// The text of `path`, or bad input naming it when it cannot be read or exceeds `limit`.
fn read_text(path: &Path, limit: u64, what: impl Fn() -> String) -> Result<String> {
    crate::files::read_capped(path, limit)
        .map_err(|e| Error::Input(format!("{}: {e}: {}", path.display(), what())))?
        .ok_or_else(|| {
            Error::Input(format!(
                "{}: larger than {} MiB, more than hbcontact writes: {}",
                path.display(),
                limit >> 20,
                what()
            ))
        })
}

fn read_dir(dir: &Path, mode: &str, producer: &str) -> Result<ResultDir> {
    let path = dir.join("summary.json");
    let text = read_text(&path, MAX_SUMMARY_BYTES, || {
        format!("is {} a result directory of `{producer}`?", dir.display())
    })?;
    let summary: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| Error::Input(format!("{}: not JSON ({e})", path.display())))?;
    if summary["mode"] != mode {
        return Err(Error::Input(format!(
            "{}: mode is {} where {mode} was expected: give the `hbcontact run` directory first, \
             then the `hbcontact transient` one (`<dir>-transient`)",
            path.display(),
            summary["mode"]
        )));
    }
    let optional = |name: &str| {
        let p = dir.join(name);
        p.exists().then(|| read_csv(&p)).transpose()
    };
    let probes_path = dir.join("probes.csv");
    let probes = read_csv(&probes_path)?;
    if probes
        .values()
        .next()
        .is_none_or(|column| column.is_empty())
    {
        return Err(Error::Input(format!(
            "{}: no rows: run `{producer}` again to write it",
            probes_path.display()
        )));
    }
    Ok(ResultDir {
        dir: dir.to_path_buf(),
        probes,
        contact: optional("contact.csv")?,
        steps: optional("contact_steps.csv")?,
        summary,
    })
}

/// A number of the summary at `keys`, or bad input naming the file and the field.
fn number(r: &ResultDir, keys: &[&str]) -> Result<f64> {
    let mut v = &r.summary;
    for k in keys {
        v = &v[*k];
    }
    v.as_f64().ok_or_else(|| {
        Error::Input(format!(
            "{}: no number at `{}` (a summary.json of another hbcontact version?)",
            r.dir.join("summary.json").display(),
            keys.join(".")
        ))
    })
}

/// Read a CSV of finite numbers with a header line.
fn read_csv(path: &Path) -> Result<Table> {
    let text = read_text(path, MAX_TABLE_BYTES, || {
        "give two hbcontact result directories".into()
    })?;
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap_or_default()
        .split(',')
        .map(|h| h.trim().to_string())
        .collect();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); header.len()];
    for (row, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != header.len() {
            return Err(Error::Input(format!(
                "{}: line {} has {} values for {} columns",
                path.display(),
                row + 2,
                fields.len(),
                header.len()
            )));
        }
        for (col, f) in columns.iter_mut().zip(fields) {
            match f.trim().parse::<f64>() {
                Ok(v) if v.is_finite() => col.push(v),
                _ => {
                    return Err(Error::Input(format!(
                        "{}: line {}: `{}` is not a finite number: the file was not written \
                         by hbcontact or was changed since",
                        path.display(),
                        row + 2,
                        crate::error::excerpt(f)
                    )))
                }
            }
        }
    }
    Ok(header.into_iter().zip(columns).collect())
}

/// Harmonic k of evenly spaced samples over one period, z_k = a_k − i b_k.
pub fn harmonic(times: &[f64], values: &[f64], omega: f64, k: usize) -> c64 {
    let n = values.len().max(1) as f64;
    let (mut a, mut b) = (0.0, 0.0);
    for (&t, &x) in times.iter().zip(values) {
        let phase = k as f64 * omega * t;
        a += x * phase.cos();
        b += x * phase.sin();
    }
    fourier::from_cos_sin(2.0 * a / n, 2.0 * b / n)
}

fn half_range(v: &[f64]) -> f64 {
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    0.5 * (max - min)
}

fn difference(quantity: String, unit: &str, hb: f64, tm: f64) -> Difference {
    Difference {
        quantity,
        unit: unit.into(),
        harmonic_balance: hb,
        transient: tm,
        difference: hb - tm,
        relative: (tm != 0.0).then(|| (hb - tm) / tm.abs()),
        phase_difference_deg: None,
    }
}

fn harmonic_difference(quantity: String, unit: &str, hb: c64, tm: c64) -> Difference {
    let mut phase = (hb.arg() - tm.arg()).to_degrees();
    if phase > 180.0 {
        phase -= 360.0;
    } else if phase <= -180.0 {
        phase += 360.0;
    }
    Difference {
        phase_difference_deg: Some(phase),
        ..difference(quantity, unit, hb.norm(), tm.norm())
    }
}

/// Each probe column both results have: first-harmonic amplitude and half peak-to-peak.
fn compare_probes(hb: &ResultDir, tm: &ResultDir, omega: f64, c: &mut Comparison) {
    let (Some(t_hb), Some(t_tm)) = (hb.probes.get("time"), tm.probes.get("time")) else {
        c.notes.push("a probes.csv has no time column".into());
        return;
    };
    for (name, v_hb) in hb.probes.iter().filter(|(n, _)| *n != "time") {
        let Some(v_tm) = tm.probes.get(name) else {
            c.notes.push(format!("{name} is in the HB probes.csv only"));
            continue;
        };
        let (z_hb, z_tm) = (
            harmonic(t_hb, v_hb, omega, 1),
            harmonic(t_tm, v_tm, omega, 1),
        );
        let label = name.replace('_', " ");
        c.differences.push(harmonic_difference(
            format!("{label} first harmonic"),
            "m",
            z_hb,
            z_tm,
        ));
        c.differences.push(difference(
            format!("{label} half peak-to-peak"),
            "m",
            half_range(v_hb),
            half_range(v_tm),
        ));
        c.overlays.push(Overlay {
            quantity: name.clone(),
            title: name.replace("_ux", " u_x").replace("_uy", " u_y"),
            unit: "m".into(),
            harmonic_balance: Series {
                times: t_hb.clone(),
                values: v_hb.clone(),
            },
            transient: Series {
                times: t_tm.clone(),
                values: v_tm.clone(),
            },
        });
    }
}

/// Mean and peak total force from the summaries, harmonics 1–3 of the total force history.
fn compare_contact(hb: &ResultDir, tm: &ResultDir, omega: f64, c: &mut Comparison) -> Result<()> {
    let (Some(hb_contact), Some(tm_contact)) = (&hb.contact, &tm.contact) else {
        if hb.contact.is_some() != tm.contact.is_some() {
            c.notes
                .push("only one of the results has contact.csv".into());
        }
        return Ok(());
    };
    for (key, label) in [
        ("mean_contact_force", "mean"),
        ("peak_contact_force", "peak"),
    ] {
        let (a, b) = (
            number(hb, &["contact", key])?,
            number(tm, &["contact", key])?,
        );
        c.differences.push(difference(
            format!("total contact force {label}"),
            "N",
            a,
            b,
        ));
    }
    let series = |table: &Table, path: &Path| -> Result<Series> {
        match (table.get("time"), table.get("total_force")) {
            (Some(t), Some(f)) => Ok(Series {
                times: t.clone(),
                values: f.clone(),
            }),
            _ => Err(Error::Input(format!(
                "{}: no time or total_force column",
                path.display()
            ))),
        }
    };
    let s_hb = series(hb_contact, &hb.dir.join("contact.csv"))?;
    let s_tm = match &tm.steps {
        Some(steps) => series(steps, &tm.dir.join("contact_steps.csv"))?,
        None => series(tm_contact, &tm.dir.join("contact.csv"))?,
    };
    for k in 1..=3 {
        let (a, b) = (
            harmonic(&s_hb.times, &s_hb.values, omega, k),
            harmonic(&s_tm.times, &s_tm.values, omega, k),
        );
        c.differences.push(harmonic_difference(
            format!("total contact force harmonic {k}"),
            "N",
            a,
            b,
        ));
    }
    c.overlays.push(Overlay {
        quantity: "total_force".into(),
        title: "total contact force".into(),
        unit: "N".into(),
        harmonic_balance: s_hb,
        transient: s_tm,
    });
    if let Some(o) = opening_overlay(hb_contact, tm_contact) {
        c.overlays.push(o);
    }
    Ok(())
}

/// The opening of the contact node whose HB law force peaks highest (`nodeN_opening` of both
/// `contact.csv`), or `None` when the files share no such node.
fn opening_overlay(hb: &Table, tm: &Table) -> Option<Overlay> {
    let peak = |v: &Vec<f64>| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (node, _) = hb
        .iter()
        .filter_map(|(k, v)| Some((k.strip_suffix("_force")?.strip_prefix("node")?, peak(v))))
        .filter(|(n, _)| tm.contains_key(&format!("node{n}_opening")))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let column = format!("node{node}_opening");
    let series = |t: &Table| {
        Some(Series {
            times: t.get("time")?.clone(),
            values: t.get(&column)?.clone(),
        })
    };
    Some(Overlay {
        quantity: format!("node{node}_opening"),
        title: format!("opening of node {node} (largest force)"),
        unit: "m".into(),
        harmonic_balance: series(hb)?,
        transient: series(tm)?,
    })
}

/// Write `compare.json` and `compare.csv` into `dir` (each written under a temporary name and
/// renamed), and the overlays into `dir/plots` (`compare_<quantity>.svg` and `.png`).
pub fn write(c: &Comparison, dir: &Path) -> Result<()> {
    crate::output::staging::claim_entries(
        dir,
        "compare",
        &["compare.json", "compare.csv", "plots"],
    )?;
    write_overlays(c, &dir.join("plots"))?;
    write_json(&dir.join("compare.json"), c)?;
    let mut csv = String::from(
        "quantity,unit,harmonic_balance,transient,difference,relative,phase_difference_deg\n",
    );
    let opt = |v: Option<f64>| v.map(|x| format!("{x:e}")).unwrap_or_default();
    for d in &c.differences {
        csv.push_str(&format!(
            "{},{},{:e},{:e},{:e},{},{}\n",
            d.quantity,
            d.unit,
            d.harmonic_balance,
            d.transient,
            d.difference,
            opt(d.relative),
            opt(d.phase_difference_deg)
        ));
    }
    write_text(&dir.join("compare.csv"), &csv)
}

/// The JSON Schema (draft 07) of `compare.json` (`docs/compare.schema.json`).
pub fn compare_schema() -> serde_json::Value {
    let schema = schemars::generate::SchemaSettings::draft07()
        .into_generator()
        .into_root_schema_for::<Comparison>();
    serde_json::Value::from(schema)
}

/// `compare`'s overlays: one figure per compared signal, harmonic balance against time
/// marching over one period, as `compare_<quantity>` in `dir` (created); returns the files.
pub fn write_overlays(c: &Comparison, dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let period = 1.0 / c.frequency_hz;
    let mut files = Vec::new();
    for o in &c.overlays {
        let stem = format!("compare_{}", o.quantity);
        overlay_figure(o, period).save(&dir.join(&stem))?;
        files.extend(["svg", "png"].map(|ext| dir.join(format!("{stem}.{ext}"))));
    }
    Ok(files)
}

fn overlay_figure(o: &Overlay, period: f64) -> Figure {
    let (hb, tm) = (&o.harmonic_balance, &o.transient);
    Figure::new(
        format!("{}: harmonic balance against time marching", o.title),
        time_axis(period),
        Axis::linear(format!("{} [{}]", o.title, o.unit)),
    )
    .curve(
        "harmonic balance",
        over_period(&hb.times, &hb.values, period),
    )
    .add(
        "time marching",
        over_period(&tm.times, &tm.values, period),
        style(tm.times.len()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn temp(name: &str, text: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("hbcontact-compare-{}", crate::files::unique_tag()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn a_table_with_a_non_finite_value_is_refused_naming_the_file_and_line() {
        for bad in ["NaN", "inf", "-inf", "1e400", "x"] {
            let path = temp("probes.csv", &format!("time,u_x\n0,1\n1,{bad}\n"));
            let err = read_csv(&path).unwrap_err().to_string();
            let _ = std::fs::remove_dir_all(path.parent().unwrap());
            assert!(
                err.contains("probes.csv: line 3") && err.contains("not a finite number"),
                "{bad}: {err}"
            );
        }
    }

    proptest! {
        /// Whatever a tampered CSV holds, reading it gives finite columns of equal length or
        /// an error naming the file: never a panic.
        #[test]
        fn mutated_tables_read_or_are_refused_naming_the_file(text in "[-0-9a-z.,e\n ]{0,200}") {
            let path = temp("contact.csv", &text);
            let read = read_csv(&path);
            let _ = std::fs::remove_dir_all(path.parent().unwrap());
            match read {
                Ok(table) => {
                    let lengths: Vec<usize> = table.values().map(Vec::len).collect();
                    prop_assert!(lengths.windows(2).all(|w| w[0] == w[1]));
                    prop_assert!(table.values().flatten().all(|v| v.is_finite()));
                }
                Err(e) => prop_assert!(e.to_string().contains("contact.csv"), "{e}"),
            }
        }
    }
}
