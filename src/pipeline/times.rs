//! The wall time of each stage of a run (`stages`), in run order, in seconds; the summaries
//! write them as a map with their `total`. A stage run in parts (the checks between mesh,
//! assembly and solve) is one entry holding the sum of its parts, so that the map has each
//! key once.

use std::time::Instant;

use schemars::JsonSchema;
use serde::{Serialize, Serializer};

use crate::progress::Reporter;
use crate::Result;

/// Per-stage wall times in seconds, in run order; serialized as a map with their `total`.
#[derive(Clone, Debug, Default, JsonSchema)]
#[schemars(with = "std::collections::BTreeMap<String, f64>")]
pub struct StageTimes(Vec<(String, f64)>);

impl StageTimes {
    /// Run stage `name`, timing it (added to its earlier parts) and telling the reporter.
    pub fn time<T>(
        &mut self,
        name: &str,
        reporter: &dyn Reporter,
        f: impl FnOnce() -> Result<T>,
    ) -> Result<T> {
        reporter.stage(name);
        let start = Instant::now();
        let out = f();
        let secs = start.elapsed().as_secs_f64();
        reporter.stage_done(name, secs);
        self.add(name, secs);
        out
    }

    /// Record `secs` for stage `name` (added to its earlier parts).
    pub fn push(&mut self, name: &str, secs: f64) {
        self.add(name, secs);
    }

    /// Add `secs` to stage `name`'s time (a stage done in parts, e.g. a sweep's checks made
    /// as its points are found), or push it when the stage has not run.
    pub fn add(&mut self, name: &str, secs: f64) {
        match self.0.iter_mut().find(|(n, _)| n == name) {
            Some((_, v)) => *v += secs,
            None => self.0.push((name.to_string(), secs)),
        }
    }

    /// The time of stage `name` (summed if it ran several times; 0 if it never ran).
    pub fn get(&self, name: &str) -> f64 {
        self.0
            .iter()
            .filter(|(n, _)| n == name)
            .map(|(_, v)| v)
            .sum()
    }

    pub fn total(&self) -> f64 {
        self.0.iter().map(|(_, v)| v).sum()
    }
}

impl Serialize for StageTimes {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = serializer.serialize_map(Some(self.0.len() + 1))?;
        for (k, v) in &self.0 {
            map.serialize_entry(k, v)?;
        }
        map.serialize_entry("total", &self.total())?;
        map.end()
    }
}
