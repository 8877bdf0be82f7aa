//! From a study to its points: the design (grid, list, Latin hypercube) gives each point's
//! parameter values; each point's pipeline is resolved with the same `--set` machinery as the
//! command line, and keyed by a hash of the resolved pipeline, so a point already computed
//! (by this run, an interrupted one, or another shard) is recognised.
//!
//! Latin hypercube of n samples over d parameters: for each parameter an independent random
//! permutation π of 0..n; sample i takes u = (π(i) + r)/n with r uniform in [0, 1), mapped
//! onto the parameter's range (linearly, or geometrically for `scale: log`). Every one of the
//! n strata of every parameter holds exactly one sample. The random numbers come from
//! SplitMix64 seeded with `seed`, so a study file always yields the same points.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::spec::{Design, Reference, Scale, Study, Value};
use crate::config::Pipeline;
use crate::error::excerpt;
use crate::pipeline::load_pipeline;
use crate::{Error, Result};

/// Which solver a point runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    HarmonicBalance,
    Transient,
}

/// One point of the study, resolved.
#[derive(Clone, Debug)]
pub struct Point {
    /// Row in the table (0-based).
    pub index: usize,
    /// The varied parameters' values, in the study's parameter order (accuracy studies: the
    /// ladder's key and value).
    pub values: Vec<(String, Value)>,
    pub pipeline: Pipeline,
    pub mode: Mode,
    /// Hex SHA-256 (first 16 digits) of the resolved pipeline, the mode and the geometry file.
    pub key: String,
    /// Write the full VTU series.
    pub full: bool,
}

/// SplitMix64: a tiny, well-mixed generator; enough for sampling designs.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// The parameter values of every point, in table order.
pub fn design_values(study: &Study) -> Vec<Vec<Value>> {
    let params = &study.parameters;
    match &study.design {
        Design::Grid => {
            let mut rows: Vec<Vec<Value>> = vec![Vec::new()];
            for p in params {
                rows = rows
                    .iter()
                    .flat_map(|row| {
                        p.values.iter().map(move |v| {
                            let mut r = row.clone();
                            r.push(v.clone());
                            r
                        })
                    })
                    .collect();
            }
            rows
        }
        Design::List => {
            let n = params.first().map_or(0, |p| p.values.len());
            (0..n)
                .map(|i| params.iter().map(|p| p.values[i].clone()).collect())
                .collect()
        }
        Design::LatinHypercube { samples, seed } => {
            let mut rng = SplitMix(*seed);
            let n = *samples;
            let columns: Vec<Vec<Value>> = params
                .iter()
                .map(|p| {
                    let mut perm: Vec<usize> = (0..n).collect();
                    for i in (1..n).rev() {
                        perm.swap(i, rng.below(i + 1));
                    }
                    // A hypercube's parameters all have a numeric range (spec.rs).
                    let (from, to, scale) = p.range.unwrap_or((0.0, 0.0, Scale::Linear));
                    perm.iter()
                        .map(|&s| {
                            let u = (s as f64 + rng.unit()) / n as f64;
                            Value::Number(match scale {
                                Scale::Linear => from + u * (to - from),
                                Scale::Log => (from.ln() + u * (to.ln() - from.ln())).exp(),
                            })
                        })
                        .collect()
                })
                .collect();
            (0..n)
                .map(|i| columns.iter().map(|c| c[i].clone()).collect())
                .collect()
        }
    }
}

/// The key of a resolved pipeline: what it computes, not where it came from or writes to.
pub fn point_key(p: &Pipeline, mode: Mode) -> String {
    let mut q = p.clone();
    q.source = PathBuf::new();
    q.output.directory = PathBuf::new();
    let geo = std::fs::read(&p.geometry.file).unwrap_or_default();
    q.geometry.file = p
        .geometry
        .file
        .file_name()
        .map(PathBuf::from)
        .unwrap_or_default();
    let mut h = Sha256::new();
    h.update(format!("hbcontact {}|{mode:?}|{q:?}|", env!("CARGO_PKG_VERSION")).as_bytes());
    h.update(&geo);
    h.finalize()
        .iter()
        .take(8)
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Resolve one point: load the pipeline with the study's and the point's overrides, and
/// check `.geo` parameter names against the geometry file. Errors name the study file.
pub fn resolve(
    study: &Study,
    index: usize,
    values: Vec<(String, Value)>,
    mode: Mode,
) -> Result<Point> {
    let mut set = study.set.clone();
    set.extend(values.iter().map(|(k, v)| v.assignment(k)));
    let in_study = |e: Error| Error::Config {
        path: study.source.clone(),
        message: format!("point {index} ({}): {e}", describe(&values)),
    };
    let pipeline = load_pipeline(&study.pipeline, &set).map_err(in_study)?;
    let geo = &pipeline.geometry.file;
    if geo.extension().is_some_and(|e| e == "geo") {
        crate::mesh::geo::check_parameters(geo, &pipeline.geometry.parameters).map_err(in_study)?;
    }
    if let Some(probe) = &study.probe {
        if !pipeline.output.probes.contains(probe) {
            return Err(Error::Config {
                path: study.source.clone(),
                message: format!(
                    "probe: `{}` is not one of the pipeline's output.probes {:?}",
                    excerpt(probe),
                    pipeline.output.probes
                ),
            });
        }
    }
    let key = point_key(&pipeline, mode);
    let full = study.write == super::spec::WriteLevel::Full || study.full_points.contains(&index);
    Ok(Point {
        index,
        values,
        pipeline,
        mode,
        key,
        full,
    })
}

/// `gap = 1e-7, drive = 2e5`.
pub fn describe(values: &[(String, Value)]) -> String {
    values
        .iter()
        .map(|(k, v)| {
            let (k, v) = (excerpt(k), excerpt(&v.to_string()));
            format!("{k} = {v}")
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Every point of the study, resolved (a parameter study's design, or an accuracy study's
/// ladder rungs then its transient reference). Fails before anything runs on a bad key.
pub fn plan(study: &Study) -> Result<Vec<Point>> {
    let mut points = Vec::new();
    if let Some(acc) = &study.accuracy {
        for ladder in &acc.ladders {
            for &v in &ladder.values {
                let values = vec![(ladder.key.clone(), Value::Number(v))];
                points.push(resolve(study, points.len(), values, Mode::HarmonicBalance)?);
            }
        }
        if points
            .first()
            .is_some_and(|p: &Point| p.pipeline.output.probes.is_empty())
        {
            return Err(Error::Config {
                path: study.pipeline.clone(),
                message: "output.probes: an accuracy study measures a probe's amplitude; name a probe group".into(),
            });
        }
        if acc.reference == Reference::Transient {
            points.push(resolve(study, points.len(), Vec::new(), Mode::Transient)?);
        }
    } else {
        for row in design_values(study) {
            let values = study
                .parameters
                .iter()
                .zip(row)
                .map(|(p, v)| (p.key.clone(), v))
                .collect();
            points.push(resolve(study, points.len(), values, Mode::HarmonicBalance)?);
        }
    }
    if let Some(&bad) = study.full_points.iter().find(|&&i| i >= points.len()) {
        return Err(Error::Config {
            path: study.source.clone(),
            message: format!(
                "full_points: point {bad} does not exist (the study has {} points, 0 to {})",
                points.len(),
                points.len().saturating_sub(1)
            ),
        });
    }
    Ok(points)
}

/// Where a point's files go.
pub fn point_dir(out: &Path, key: &str) -> PathBuf {
    out.join("points").join(key)
}
