//! The study file (`studies/*.yaml`): the raw serde types a user writes (unknown keys denied;
//! their JSON Schema is `docs/study.schema.json`) and the validated `Study` the runner uses.
//! Every error names the study file and the field, and says what to write instead.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use schemars::JsonSchema;
use serde::Deserialize;

use crate::error::excerpt;
use crate::pipeline::outputs::Output;
use crate::{Error, Result};

/// A parameter study over one pipeline: which keys vary, over which values, and what to
/// tabulate.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RawStudy {
    /// The study's name: results go to `output/<name>` unless `out` (or `--out`) says otherwise.
    pub name: String,
    /// The pipeline YAML varied, relative to the study file or its parent directory.
    pub pipeline: PathBuf,
    /// Values set on every point before its parameters, as with `--set KEY=VALUE`, e.g.
    /// `{harmonic_balance.harmonics: 10}`.
    #[serde(default)]
    pub set: BTreeMap<String, serde_json::Value>,
    /// How the points are laid out. Default: `grid`.
    #[serde(default, with = "serde_yaml::with::singleton_map")]
    #[schemars(with = "RawDesign")]
    pub design: RawDesign,
    /// The parameters varied: gmsh `.geo` parameters (`geometry.parameters.NAME`) or any
    /// pipeline key (`harmonic_balance.harmonics`, `boundaries.loads.0.harmonics.0.cos.0`;
    /// with `values`, also keys whose values are words, e.g. `contact.mass`).
    #[serde(default)]
    pub parameters: Vec<RawParameter>,
    /// What to tabulate and plot for each point (see docs/study.md for the names). Default:
    /// the probe's first-harmonic amplitude and peak-to-peak, peak and mean contact force,
    /// contact fraction, max von Mises stress, Newton iterations and wall time.
    pub outputs: Option<Vec<String>>,
    /// The probe group whose amplitudes are tabulated. Default: the pipeline's first probe.
    pub probe: Option<String>,
    /// What each point writes: `summary` (summary.json only, the default) or `full` (the VTU
    /// series, histories and mesh as `hbcontact run` does).
    #[serde(default)]
    pub write: WriteLevel,
    /// Points (0-based, in table order) written in full whatever `write` says.
    #[serde(default)]
    pub full_points: Vec<usize>,
    /// Points run at once on this machine. Default: one per core (accuracy studies: 1, so
    /// that wall times are not shared).
    pub threads: Option<usize>,
    /// The results directory. Default: `output/<name>`.
    pub out: Option<PathBuf>,
    /// Makes this an accuracy study: ladders of settings, each rung's error against a
    /// reference (replaces `parameters`).
    pub accuracy: Option<RawAccuracy>,
}

/// The layout of the points.
#[derive(Clone, Debug, Default, Deserialize, serde::Serialize, JsonSchema, PartialEq)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum RawDesign {
    /// Every combination of the parameters' values.
    #[default]
    Grid,
    /// The i-th value of every parameter together (all lists equally long).
    List,
    /// A Latin hypercube of `samples` points over each parameter's `range` (`seed` makes it
    /// repeatable).
    LatinHypercube {
        samples: usize,
        #[serde(default)]
        seed: u64,
    },
}

#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RawParameter {
    /// The pipeline key set, as after `--set` (e.g. `geometry.parameters.clearance`).
    pub key: String,
    /// Explicit values (`grid`, `list`): numbers, or strings for keys whose values are words
    /// (`contact.mass: [redistributed, lumped]`).
    pub values: Option<Vec<Value>>,
    /// A range instead of values (`grid`, `list`: `count` values; `latin_hypercube`: sampled).
    pub range: Option<RawRange>,
    /// Axis label; default the key's last word.
    pub label: Option<String>,
    /// Unit shown on the axes, e.g. `m`.
    pub unit: Option<String>,
}

#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RawRange {
    pub from: f64,
    pub to: f64,
    /// Values in the range, ends included (`grid`, `list`). Default 5.
    pub count: Option<usize>,
    /// `linear` (default) or `log` spacing (log: both ends > 0).
    #[serde(default)]
    pub scale: Scale,
}

#[derive(Clone, Copy, Debug, Default, Deserialize, JsonSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Scale {
    #[default]
    Linear,
    Log,
}

#[derive(Clone, Copy, Debug, Default, Deserialize, JsonSchema, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WriteLevel {
    #[default]
    Summary,
    Full,
}

/// What accuracy costs: ladders of settings, errors against a reference.
#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RawAccuracy {
    /// `finest`: each ladder's last rung (the default); `transient`: a time-marching run of
    /// the pipeline (the cross-check, independent of every harmonic-balance knob).
    #[serde(default)]
    pub reference: Reference,
    /// Each ladder varies one key over values, cheapest first; the others stay at the
    /// pipeline's values.
    pub ladders: Vec<RawLadder>,
}

#[derive(Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RawLadder {
    /// e.g. `harmonic_balance.harmonics`, `harmonic_balance.samples`,
    /// `harmonic_balance.solver.c_scale`, `geometry.parameters.lc`, `geometry.order`.
    pub key: String,
    pub values: Vec<f64>,
}

#[derive(Clone, Copy, Debug, Default, Deserialize, JsonSchema, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reference {
    #[default]
    Finest,
    Transient,
}

/// A parameter's value: a number, or a string (`grid` and `list` designs).
#[derive(Clone, Debug, PartialEq, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Value {
    Number(f64),
    Text(String),
}

impl Value {
    pub fn number(&self) -> Option<f64> {
        match self {
            Value::Number(v) => Some(*v),
            Value::Text(_) => None,
        }
    }

    /// `KEY=VALUE` as `--set` reads it: integers without a fraction (so `harmonics=10` stays
    /// an integer), strings quoted (so `"1"` or `"yes"` stay strings).
    pub fn assignment(&self, key: &str) -> String {
        match self {
            Value::Number(v) if v.fract() == 0.0 && v.abs() < 1e15 => {
                format!("{key}={}", *v as i64)
            }
            Value::Number(v) => format!("{key}={v:e}"),
            Value::Text(t) => format!(
                "{key}={}",
                serde_json::to_string(t).unwrap_or_else(|_| t.clone())
            ),
        }
    }
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Number(v) => write!(f, "{v}"),
            Value::Text(t) => f.write_str(t),
        }
    }
}

/// One varied parameter, validated.
#[derive(Clone, Debug)]
pub struct Parameter {
    pub key: String,
    pub label: String,
    pub unit: Option<String>,
    pub values: Vec<Value>,
    /// (from, to, scale) for a Latin hypercube.
    pub range: Option<(f64, f64, Scale)>,
}

impl Parameter {
    /// Whether every value is a number (plots and heat maps need that).
    pub fn numeric(&self) -> bool {
        self.values.iter().all(|v| v.number().is_some())
    }

    /// `label [unit]`.
    pub fn axis_label(&self) -> String {
        match &self.unit {
            Some(u) => format!("{} [{u}]", self.label),
            None => self.label.clone(),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum Design {
    Grid,
    List,
    LatinHypercube { samples: usize, seed: u64 },
}

#[derive(Clone, Debug)]
pub struct Ladder {
    pub key: String,
    pub values: Vec<f64>,
}

#[derive(Clone, Debug)]
pub struct Accuracy {
    pub reference: Reference,
    pub ladders: Vec<Ladder>,
}

/// A validated study.
#[derive(Clone, Debug)]
pub struct Study {
    pub name: String,
    /// The study file (for messages; the pipeline is resolved against it).
    pub source: PathBuf,
    pub pipeline: PathBuf,
    /// `KEY=VALUE` overrides for every point (the study's `set`, then the command line's).
    pub set: Vec<String>,
    pub design: Design,
    pub parameters: Vec<Parameter>,
    pub outputs: Vec<Output>,
    pub probe: Option<String>,
    pub write: WriteLevel,
    pub full_points: Vec<usize>,
    pub threads: Option<usize>,
    pub out: PathBuf,
    pub accuracy: Option<Accuracy>,
}

/// The most points one study may have (each is a solve; a typo such as `count: 100000000`
/// must not expand into a table the machine cannot hold).
pub const MAX_POINTS: usize = 100_000;
/// The most points run at once (`threads`).
pub const MAX_THREADS: usize = 1024;

impl Study {
    /// How many points the study runs: the design's rows, or an accuracy study's rungs (and
    /// its transient reference); saturating, so a count beyond `MAX_POINTS` stays beyond it.
    pub fn point_count(&self) -> usize {
        if let Some(a) = &self.accuracy {
            let rungs = a.ladders.iter().map(|l| l.values.len()).sum::<usize>();
            return rungs + usize::from(a.reference == Reference::Transient);
        }
        match self.design {
            Design::Grid => self
                .parameters
                .iter()
                .fold(1usize, |n, p| n.saturating_mul(p.values.len())),
            Design::List => self.parameters.first().map_or(0, |p| p.values.len()),
            Design::LatinHypercube { samples, .. } => samples,
        }
    }

    /// The natural frequencies the outputs ask for: 1..=K for the largest `natural_frequency_K`.
    pub fn natural_frequencies(&self) -> usize {
        self.outputs
            .iter()
            .filter_map(|o| match o {
                Output::NaturalFrequency(k) => Some(*k),
                _ => None,
            })
            .max()
            .unwrap_or(0)
    }
}

fn bad(path: &Path, message: impl Into<String>) -> Error {
    Error::Config {
        path: path.to_path_buf(),
        message: crate::error::shorten_quoted(&message.into()),
    }
}

/// The JSON Schema (draft 07) of a study file (`docs/study.schema.json`).
pub fn study_schema() -> serde_json::Value {
    let schema = schemars::generate::SchemaSettings::draft07()
        .into_generator()
        .into_root_schema_for::<RawStudy>();
    serde_json::Value::from(schema)
}

/// Read and validate a study file; `set` adds command-line overrides after the study's own.
pub fn load_study(path: &Path, set: &[String]) -> Result<Study> {
    let text = crate::config::limits::read_yaml(path, "study").map_err(|m| bad(path, m))?;
    parse_study(path, &text, set)
}

/// A study from its YAML `text`, as if read from `path` (the pipeline resolves from it,
/// errors name it); `set` adds command-line overrides after the study's own.
pub fn parse_study(path: &Path, text: &str, set: &[String]) -> Result<Study> {
    crate::config::limits::check_yaml(text, "study").map_err(|m| bad(path, m))?;
    let raw: RawStudy = serde_yaml::from_str(text).map_err(|e| {
        let at = e
            .location()
            .map(|l| format!("line {}, column {}: ", l.line(), l.column()))
            .unwrap_or_default();
        bad(
            path,
            format!("{at}{}", crate::error::shorten_quoted(&e.to_string())),
        )
    })?;
    validate(path, raw, set)
}

/// A relative path from the study: next to it, then one level up.
fn resolve(path: &Path, file: &Path) -> Result<PathBuf> {
    if file.is_absolute() {
        return Ok(file.to_path_buf());
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    for candidate in [dir.join(file), dir.join("..").join(file)] {
        if candidate.is_file() {
            return Ok(candidate);
        }
    }
    Err(bad(
        path,
        format!(
            "pipeline: {} not found next to the study file or in its parent directory",
            excerpt(&file.display().to_string())
        ),
    ))
}

fn validate(path: &Path, raw: RawStudy, extra_set: &[String]) -> Result<Study> {
    if raw.name.trim().is_empty() || raw.name.contains(['/', '\\']) {
        return Err(bad(path, "name: give a non-empty name without slashes"));
    }
    let pipeline = resolve(path, &raw.pipeline)?;
    let keys = raw.set.keys().map(|k| ("set".to_string(), k.as_str()));
    let varied = raw.parameters.iter().enumerate();
    let varied = varied.map(|(i, p)| (format!("parameters[{i}]"), p.key.as_str()));
    let ladders = raw
        .accuracy
        .iter()
        .flat_map(|a| a.ladders.iter().enumerate());
    let ladders = ladders.map(|(i, l)| (format!("accuracy.ladders[{i}]"), l.key.as_str()));
    for (field, key) in keys.chain(varied).chain(ladders) {
        check_key(path, &field, key)?;
    }
    let mut set: Vec<String> = raw.set.iter().map(|(k, v)| format!("{k}={v}")).collect();
    set.extend(extra_set.iter().cloned());
    let design = design(path, raw.design)?;
    let parameters = raw
        .parameters
        .into_iter()
        .enumerate()
        .map(|(i, p)| parameter(path, i, p, &design))
        .collect::<Result<Vec<_>>>()?;
    let accuracy = raw.accuracy.map(|a| accuracy(path, a)).transpose()?;
    check_layout(path, &design, &parameters, accuracy.is_some())?;
    let outputs = outputs(path, raw.outputs.as_deref())?;
    if let Some(t) = raw.threads.filter(|&t| t == 0 || t > MAX_THREADS) {
        return Err(bad(
            path,
            format!("threads = {t}: give 1 to {MAX_THREADS} (points run at once)"),
        ));
    }
    let study = Study {
        name: raw.name,
        source: path.to_path_buf(),
        pipeline,
        set,
        design,
        parameters,
        outputs,
        probe: raw.probe,
        write: raw.write,
        full_points: raw.full_points,
        threads: raw.threads,
        out: PathBuf::new(),
        accuracy,
    };
    let n = study.point_count();
    if n > MAX_POINTS {
        return Err(bad(
            path,
            format!("the study has {n} points (the product of its parameters' value counts), above the limit of {MAX_POINTS}: vary fewer values, or split it into several studies"),
        ));
    }
    let out = raw
        .out
        .unwrap_or_else(|| PathBuf::from("output").join(&study.name));
    Ok(Study { out, ..study })
}

/// The design, its sample count within `MAX_POINTS`.
fn design(path: &Path, raw: RawDesign) -> Result<Design> {
    Ok(match raw {
        RawDesign::Grid => Design::Grid,
        RawDesign::List => Design::List,
        RawDesign::LatinHypercube { samples, seed } => {
            if samples == 0 || samples > MAX_POINTS {
                return Err(bad(
                    path,
                    format!("design.latin_hypercube.samples = {samples}: give 1 to {MAX_POINTS} (the most points a study may have)"),
                ));
            }
            Design::LatinHypercube { samples, seed }
        }
    })
}

/// The outputs named (each one a study knows), or the defaults.
fn outputs(path: &Path, names: Option<&[String]>) -> Result<Vec<Output>> {
    match names {
        None => Ok(Output::defaults()),
        Some(names) => names
            .iter()
            .enumerate()
            .map(|(i, n)| {
                Output::parse(n).map_err(|why| bad(path, format!("outputs[{i}] `{n}`: {why}")))
            })
            .collect(),
    }
}

fn check_layout(path: &Path, design: &Design, params: &[Parameter], accuracy: bool) -> Result<()> {
    if accuracy {
        if !params.is_empty() {
            return Err(bad(
                path,
                "parameters: an accuracy study varies its `accuracy.ladders`; remove `parameters`",
            ));
        }
        return Ok(());
    }
    if params.is_empty() {
        return Err(bad(
            path,
            "parameters: name at least one, e.g. `- {key: geometry.parameters.gap, values: [1e-7, 2e-7]}`",
        ));
    }
    if *design == Design::List {
        let n = params[0].values.len();
        if let Some(p) = params.iter().find(|p| p.values.len() != n) {
            return Err(bad(
                path,
                format!(
                    "parameters: design `list` takes the i-th value of each parameter together, but {} has {} values and {} has {n}",
                    excerpt(&p.key),
                    p.values.len(),
                    excerpt(&params[0].key)
                ),
            ));
        }
    }
    Ok(())
}

/// Pipeline keys a study file may not set or vary: they name a program to run.
pub const PROGRAM_KEYS: [&str; 1] = ["geometry.gmsh"];

/// Refuse a key of `PROGRAM_KEYS` (a study someone else wrote must not choose what runs).
fn check_key(path: &Path, field: &str, key: &str) -> Result<()> {
    if PROGRAM_KEYS.contains(&key.trim()) {
        return Err(bad(
            path,
            format!(
                "{field}: `{}` names a program to run, which a study may not set or vary: set it in the pipeline, or leave it out to use .venv/bin/gmsh or gmsh on PATH",
                key.trim()
            ),
        ));
    }
    Ok(())
}

fn parameter(path: &Path, i: usize, p: RawParameter, design: &Design) -> Result<Parameter> {
    let field = format!("parameters[{i}] ({})", excerpt(&p.key));
    let lhs = matches!(design, Design::LatinHypercube { .. });
    let range = match &p.range {
        Some(r) => {
            let ok = r.from.is_finite() && r.to.is_finite();
            let log_ok = r.scale == Scale::Linear || (r.from > 0.0 && r.to > 0.0);
            if !ok || !log_ok {
                return Err(bad(
                    path,
                    format!("{field}.range: from and to must be finite (and > 0 for scale: log)"),
                ));
            }
            Some((r.from, r.to, r.scale))
        }
        None => None,
    };
    if let Some(count) = p.range.as_ref().and_then(|r| r.count) {
        if count > MAX_POINTS {
            return Err(bad(
                path,
                format!("{field}.range.count = {count} is above {MAX_POINTS}, the most points a study may have"),
            ));
        }
    }
    let values = match (&p.values, &p.range) {
        (Some(v), None) if !lhs => v.clone(),
        (None, Some(r)) => spaced(r.from, r.to, r.count.unwrap_or(5), r.scale)
            .into_iter()
            .map(Value::Number)
            .collect(),
        (Some(_), None) => {
            return Err(bad(
                path,
                format!("{field}: a latin_hypercube samples a `range: {{from, to}}`, not `values`"),
            ))
        }
        _ => {
            return Err(bad(
                path,
                format!("{field}: give either `values: [...]` or `range: {{from, to, count}}`"),
            ))
        }
    };
    let finite = |v: &Value| v.number().is_none_or(f64::is_finite);
    if values.is_empty() || !values.iter().all(finite) {
        return Err(bad(path, format!("{field}: needs values, numbers finite")));
    }
    let label = p.label.unwrap_or_else(|| {
        p.key
            .rsplit('.')
            .find(|s| s.parse::<usize>().is_err())
            .unwrap_or(&p.key)
            .to_string()
    });
    Ok(Parameter {
        key: p.key,
        label,
        unit: p.unit,
        values,
        range,
    })
}

/// `count` values from `from` to `to`, ends included, evenly spaced (log: geometrically).
pub fn spaced(from: f64, to: f64, count: usize, scale: Scale) -> Vec<f64> {
    if count <= 1 {
        return vec![from];
    }
    (0..count)
        .map(|i| {
            let t = i as f64 / (count - 1) as f64;
            match scale {
                Scale::Linear => from + t * (to - from),
                Scale::Log => (from.ln() + t * (to.ln() - from.ln())).exp(),
            }
        })
        .collect()
}

fn accuracy(path: &Path, a: RawAccuracy) -> Result<Accuracy> {
    if a.ladders.is_empty() {
        return Err(bad(
            path,
            "accuracy.ladders: name at least one, e.g. `- {key: harmonic_balance.harmonics, values: [5, 10, 20]}`",
        ));
    }
    for (i, l) in a.ladders.iter().enumerate() {
        let need = if a.reference == Reference::Finest {
            2
        } else {
            1
        };
        if l.values.len() < need || l.values.iter().any(|v| !v.is_finite()) {
            return Err(bad(
                path,
                format!(
                    "accuracy.ladders[{i}] ({}): needs at least {need} finite values (the last is the reference with `reference: finest`)",
                    excerpt(&l.key)
                ),
            ));
        }
    }
    Ok(Accuracy {
        reference: a.reference,
        ladders: a
            .ladders
            .into_iter()
            .map(|l| Ladder {
                key: l.key,
                values: l.values,
            })
            .collect(),
    })
}
