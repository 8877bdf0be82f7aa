//! `hbcontact sweep --resume`: continue a sweep saved in its output directory from its last
//! point. sweep.json keeps what that needs (`SweepSummary::resume`, a
//! `hbm::sweep::ContinuationState`): the point's index and ω, the step the next point is
//! tried with, the unit direction τ in the scaled unknowns (λ/F, ω/Ω), whose sign of τ_ω says
//! whether the curve was running forward or back, the multipliers λ, and the scaling F with
//! the c and N the first point fixed. The point is re-solved at its ω by Newton from its own
//! λ (a cold solve could land on another branch where the curve is multi-valued), and the
//! continuation goes on with the same scaling and step, so the points after it are those of
//! an uninterrupted sweep. Rows, frames and point folders from before are kept.

use std::path::Path;

use serde::Deserialize;

use super::{FoldReport, Stopped, SweepRow, WrittenPoint};
use crate::config::{Pipeline, SweepSpec};
use crate::hbm::sweep::ContinuationState;
use crate::pipeline::Model;
use crate::{Error, Result};

/// The parts of a saved sweep.json a resume continues.
#[derive(Deserialize)]
pub struct Saved {
    pub from_hz: f64,
    pub to_hz: f64,
    pub harmonics: usize,
    pub rows: Vec<SweepRow>,
    pub folds: Vec<FoldReport>,
    pub stopped: Option<Stopped>,
    #[serde(default)]
    pub frames: Vec<usize>,
    #[serde(default)]
    pub written: Vec<WrittenPoint>,
    #[serde(default)]
    pub resumed_from: Vec<usize>,
    pub resume: Option<ContinuationState>,
}

fn refuse(message: String) -> Error {
    Error::Input(format!(
        "--resume: {message}; or sweep again from the start without --resume"
    ))
}

/// The sweep saved in `out`, checked against the pipeline's `sweep` block: the same range
/// and H (they fix the scaling), unfinished, and more points allowed than it has.
pub fn read(out: &Path, p: &Pipeline, spec: &SweepSpec) -> Result<Saved> {
    let path = out.join("sweep.json");
    let text = std::fs::read_to_string(&path).map_err(|e| {
        refuse(format!(
            "cannot read {} ({e}): there is no sweep to continue",
            path.display()
        ))
    })?;
    let saved: Saved = serde_json::from_str(&text).map_err(|e| {
        refuse(format!(
            "{} is not a sweep.json this version can continue ({e})",
            path.display()
        ))
    })?;
    let same = |key: &str, now: f64, then: f64| {
        if now == then {
            Ok(())
        } else {
            Err(refuse(format!(
                "{key} is {now} but the sweep saved in {} used {then}: resume with the same {key}",
                out.display()
            )))
        }
    };
    same("sweep.from", spec.from_hz, saved.from_hz)?;
    same("sweep.to", spec.to_hz, saved.to_hz)?;
    let h = p.harmonic_balance.harmonics;
    same(
        "harmonic_balance.harmonics",
        h as f64,
        saved.harmonics as f64,
    )?;
    if saved.stopped.is_none() {
        return Err(refuse(format!(
            "the sweep saved in {} reached {} Hz: nothing to continue",
            out.display(),
            saved.to_hz
        )));
    }
    let Some(state) = &saved.resume else {
        return Err(refuse(format!(
            "{} holds no continuation state",
            path.display()
        )));
    };
    if spec.max_points <= state.index + 1 {
        return Err(refuse(format!(
            "sweep.max_points = {} allows no point after the {} saved: raise it, e.g. --set sweep.max_points={}",
            spec.max_points,
            state.index + 1,
            2 * spec.max_points.max(state.index + 1)
        )));
    }
    Ok(saved)
}

/// The saved state fits the model: as many contact unknowns (nodes × (2H + 1), with
/// H = ⌊S/2⌋ for a spline basis of S segments).
pub fn check_state(saved: &Saved, model: &Model, p: &Pipeline) -> Result<()> {
    let h = match p.harmonic_balance.basis {
        crate::config::BasisSpec::Spline { segments, .. } => segments / 2,
        crate::config::BasisSpec::Fourier => p.harmonic_balance.harmonics,
    };
    let m = 2 * h + 1;
    let want = model.contact.as_ref().map_or(0, |c| c.operator.nodes() * m);
    let have = saved.resume.as_ref().map_or(0, |s| s.multipliers.len());
    if have != want {
        return Err(refuse(format!(
            "the saved sweep has {have} contact unknowns and this scene {want}: the mesh or the contact set changed since"
        )));
    }
    Ok(())
}

/// The rows each resume continued from, this one's included.
pub fn resumed_from(saved: Option<&Saved>) -> Vec<usize> {
    let Some(s) = saved else {
        return Vec::new();
    };
    let mut from = s.resumed_from.clone();
    from.extend(s.resume.as_ref().map(|r| r.index));
    from
}

/// Copy the saved sweep's frames and point folders into the staged directory.
pub fn carry_over(out: &Path, staged: &Path) -> Result<()> {
    for sub in ["frames", "points"] {
        let from = out.join(sub);
        if from.is_dir() {
            copy_tree(&from, &staged.join(sub))?;
        }
    }
    Ok(())
}

fn copy_tree(from: &Path, to: &Path) -> Result<()> {
    std::fs::create_dir_all(to).map_err(|e| Error::io(to, e))?;
    let entries = std::fs::read_dir(from).map_err(|e| Error::io(from, e))?;
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(from, e))?;
        let (source, target) = (entry.path(), to.join(entry.file_name()));
        if source.is_dir() {
            copy_tree(&source, &target)?;
        } else {
            std::fs::copy(&source, &target).map_err(|e| Error::io(&target, e))?;
        }
    }
    Ok(())
}
