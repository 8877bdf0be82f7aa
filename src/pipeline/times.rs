//! The wall time of each stage of a run (`stages`), in run order, in seconds; the summaries
//! write them as a map with their `total`. A stage run in parts (the checks between mesh,
//! assembly and solve) is one entry holding the sum of its parts, so that the map has each
//! key once.

use std::time::Instant;

use schemars::JsonSchema;
use serde::{Serialize, Serializer};

use crate::progress::Reporter;
use crate::Result;

/// A stage of a run, or a phase of the solve, as summary.json's `stage_seconds` names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Mesh,
    Read,
    Check,
    Assemble,
    Resonance,
    /// The harmonic-balance solve as a whole (its phases are timed as the six below).
    Solve,
    Factor,
    LinearSolve,
    Reduce,
    Newton,
    KnobCheck,
    Recover,
    March,
    Modes,
    Sweep,
    Stability,
    Points,
    Write,
    Plots,
}

impl Stage {
    /// The key in `stage_seconds` and the reporter's `[name]`.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Mesh => "mesh",
            Stage::Read => "read",
            Stage::Check => "check",
            Stage::Assemble => "assemble",
            Stage::Resonance => "resonance",
            Stage::Solve => "solve",
            Stage::Factor => "factor",
            Stage::LinearSolve => "linear_solve",
            Stage::Reduce => "reduce",
            Stage::Newton => "newton",
            Stage::KnobCheck => "knob_check",
            Stage::Recover => "recover",
            Stage::March => "march",
            Stage::Modes => "modes",
            Stage::Sweep => "sweep",
            Stage::Stability => "stability",
            Stage::Points => "points",
            Stage::Write => "write",
            Stage::Plots => "plots",
        }
    }
}

/// Per-stage wall times in seconds, in run order; serialized as a map with their `total`.
#[derive(Clone, Debug, Default, JsonSchema)]
#[schemars(with = "std::collections::BTreeMap<String, f64>")]
pub struct StageTimes(Vec<(Stage, f64)>);

impl StageTimes {
    /// Run `stage`, timing it (added to its earlier parts) and telling the reporter.
    pub fn time<T>(
        &mut self,
        stage: Stage,
        reporter: &dyn Reporter,
        f: impl FnOnce() -> Result<T>,
    ) -> Result<T> {
        reporter.stage(stage.name());
        let start = Instant::now();
        let out = f();
        let secs = start.elapsed().as_secs_f64();
        reporter.stage_done(stage.name(), secs);
        self.add(stage, secs);
        out
    }

    /// Add `secs` to `stage`'s time (a stage done in parts, e.g. a sweep's checks made as its
    /// points are found), or push it when the stage has not run.
    pub fn add(&mut self, stage: Stage, secs: f64) {
        match self.0.iter_mut().find(|(n, _)| *n == stage) {
            Some((_, v)) => *v += secs,
            None => self.0.push((stage, secs)),
        }
    }

    /// The time of `stage` (summed if it ran several times; 0 if it never ran).
    pub fn get(&self, stage: Stage) -> f64 {
        self.0
            .iter()
            .filter(|(n, _)| *n == stage)
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
            map.serialize_entry(k.name(), v)?;
        }
        map.serialize_entry("total", &self.total())?;
        map.end()
    }
}
