//! The closing every harmonic-balance result shares (`run`, a sweep's written points, a
//! study's points): sample the solution over its period, write what the write level asks
//! for, build the summary, draw the plots.
//!
//! Glossary: the *write level* is how much of a result goes to disk: its summary only, the
//! summary and the harmonic amplitudes (`amplitudes.vtu`, what an accuracy rung compares), or
//! everything (the frame series, the contact history, the amplitudes and the plots).

use std::path::Path;

use super::report::{self, Sampled};
use super::stages::hb_settings;
use super::summary::{self, MeshInfo, Summary};
use super::{plots, Model};
use crate::config::Pipeline;
use crate::hbm::Solution;
use crate::progress::Reporter;
use crate::Result;

/// How much of a result is written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WriteLevel {
    /// `summary.json` only.
    Summary,
    /// The summary and the harmonic amplitudes of a harmonic-balance result.
    Amplitudes,
    /// Everything: frames, histories, amplitudes, the mesh, plots.
    #[default]
    Full,
}

/// Sample `solution` over its period and write it into `dir` as `level` asks (the frame
/// series and contact history at `Full`, the amplitudes from `Amplitudes` up); returns its
/// summary (the solution's own frequency; no stage times, stability or check warnings yet)
/// and the samples the plots draw.
pub fn harmonic_balance(
    p: &Pipeline,
    (model, mesh_info): (&Model, MeshInfo),
    solution: &Solution,
    level: WriteLevel,
    dir: &Path,
    reporter: &dyn Reporter,
) -> Result<(Summary, Sampled)> {
    // The N the contact solve settled on (adaptive), so the law is sampled where it holds.
    let samples = solution
        .contact
        .as_ref()
        .map_or(hb_settings(p).samples, |c| c.samples);
    let sampled = Sampled::harmonic_balance(model, solution, p.output.frames, samples);
    if level == WriteLevel::Full {
        let (contact, fields) = (p.contact.as_ref(), &p.output.fields);
        sampled.write(dir, model, contact, fields, reporter)?;
    }
    if level != WriteLevel::Summary {
        report::write_amplitudes(dir, model, solution)?;
    }
    let summary = summary::harmonic_balance(p, mesh_info, model, solution, &sampled);
    Ok((summary, sampled))
}

/// Whether a result written at `level` gets plots: at `Full`, when `output.plots` is on.
pub fn plotting(p: &Pipeline, level: WriteLevel) -> bool {
    level == WriteLevel::Full && p.output.plots
}

/// The result's plots into `dir`; `period` [s] is the time axis's length.
pub fn plots(
    p: &Pipeline,
    (model, sampled): (&Model, &Sampled),
    dir: &Path,
    period: f64,
) -> Result<()> {
    let boundaries: Vec<&str> = p
        .contact
        .iter()
        .flat_map(|c| &c.pairs)
        .map(|pair| pair.boundary.as_str())
        .collect();
    plots::write_run_plots(dir, model, sampled, &boundaries, period).map(|_| ())
}
