//! A contact sweep that stops short, swept again from its start with a turn limit per step.
//!
//! The sampled contact law makes a curve piecewise smooth: at its kinks a long step can cross
//! onto another sheet of the law's solutions, which may end (no next point down to the
//! smallest step) or run back onto the curve already traced. Halving every step that turns
//! the curve by more than `RETRY_TURN` keeps to the sheet, but it changes curves that pass
//! without it (the strip's light-damped sweep then runs back onto itself at 1347.47 Hz), so
//! it is not the default: a sweep without `sweep.max_turn` that stops at a dead end or on its
//! own trail is swept again, from its start, with `max_turn = RETRY_TURN`, and the second
//! curve is kept unless it stops so too (it may run out of `max_points` or be interrupted;
//! its state resumes with the limit); else the first is, its stop naming the second's.
//! The second-mode blade and the quadratic cantilever of pipelines/scenes/ reach their end so
//! (both first stop among unstable states). A failing curve costs its time twice; a passing
//! one nothing. The curve swept from the other end of a range (`other_end`) is not swept
//! again where it stops among unstable states: its stable states end there.
//!
//! Where the second curve stops too, neither stop among unstable states, and H is fixed, the
//! curve is swept a third time from its start with the contact law's samples doubled
//! (`finer`, its `--set` in the commands the output prints): the law's kinks and dead ends
//! are the sampling's, and the first-mode blade's starts that stop twice at its upper fold at
//! 80 samples all reach the end at 160. Kept unless it stops too.

use std::path::Path;

use schemars::JsonSchema;
use serde::Serialize;

use super::bifurcations::in_unstable_stretch;
use super::{continue_curve, points, resume, Start};
use crate::config::{Pipeline, SweepSpec};
use crate::hbm::continuation::SweepOutcome;
use crate::output::staging::Replace;
use crate::output::StagedDir;
use crate::pipeline::summary::MeshInfo;
use crate::pipeline::Model;
use crate::progress::Reporter;
use crate::Result;

/// The turn limit per step [degrees] of a sweep swept again (30° passes the stopped scenes
/// too; 15° stops the blade in its kinks).
pub const RETRY_TURN: f64 = 60.0;

/// `spec` with the turn limit of a sweep swept again.
pub fn turn_limited(spec: &SweepSpec) -> SweepSpec {
    SweepSpec {
        max_turn: Some(RETRY_TURN),
        ..spec.clone()
    }
}

/// How the curve was swept again, in sweep.json.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct SweptAgain {
    /// The second sweep's turn limit per step [degrees].
    pub max_turn: f64,
    /// Where the first sweep stopped [Hz], after how many points, and why.
    pub first_stop_hz: f64,
    pub first_points: usize,
    pub first_reason: String,
    /// The second curve is the one written (it did not stop short); false: the first is.
    pub kept: bool,
    /// Where the second stopped too, neither stop among unstable states, and H is fixed: the
    /// samples per period of a third sweep from the start, with the contact law's samples
    /// doubled (`harmonic_balance.samples`, its `--set` in the commands the output prints).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finer_samples: Option<usize>,
    /// The third curve is the one written.
    pub finer_kept: bool,
}

/// One continuation of the curve into its own staged folder.
pub(super) struct Attempt<'a> {
    /// The pipeline it was swept with.
    pub p: &'a Pipeline,
    pub staged: StagedDir,
    pub writer: points::Writer<'a>,
    pub starts: Vec<Start>,
    /// Seconds the continuation waited for Hill's verdicts.
    pub judging: f64,
    pub ended: Result<SweepOutcome>,
    /// Its wall time [s].
    pub seconds: f64,
}

/// What every attempt of a sweep shares.
pub(super) struct Curve<'a> {
    pub p: &'a Pipeline,
    pub model: &'a Model,
    pub mesh: &'a MeshInfo,
    pub saved: Option<&'a resume::Saved>,
    pub reporter: &'a dyn Reporter,
    /// A curve stopped among unstable states is swept again too (false: the curve from the
    /// other end, `other_end`, whose stable states end there).
    pub again_among_unstable: bool,
    /// The pipeline with the contact law's samples doubled (`finer`), for a third sweep.
    pub finer: Option<&'a Pipeline>,
}

/// `p` with the contact law's samples per period doubled and its `--set` saying so; `None`
/// where H is chosen per point (each H sets its own samples).
pub fn finer(p: &Pipeline) -> Option<Pipeline> {
    let hb = &p.harmonic_balance;
    if hb.harmonics_max > hb.harmonics {
        return None;
    }
    let samples = 2 * crate::pipeline::hb_settings(p).samples;
    let mut finer = p.clone();
    finer.harmonic_balance.samples = Some(samples);
    (finer.overrides).push(format!("harmonic_balance.samples={samples}"));
    Some(finer)
}

impl<'a> Curve<'a> {
    /// The curve swept with `spec` into a staged folder for `out` (a resumed one with its
    /// saved frames and points carried over), swept again with `again` where
    /// `again_if_stopped` says (not when `spec` sets its own `max_turn`).
    pub fn sweep(
        &self,
        (spec, again): (&'a SweepSpec, &'a SweepSpec),
        out: &Path,
        replace: Replace,
    ) -> Result<(Attempt<'a>, Option<SweptAgain>)> {
        let staged = StagedDir::create(out, "sweep", replace)?;
        if self.saved.is_some() {
            resume::carry_over(out, staged.path())?;
        }
        let first = self.attempt(self.p, spec, staged)?;
        self.again_if_stopped(first, (spec, spec.max_turn.is_none().then_some(again)))
    }

    /// The curve of `p` swept with `spec` into `staged`.
    fn attempt(
        &self,
        p: &'a Pipeline,
        spec: &'a SweepSpec,
        staged: StagedDir,
    ) -> Result<Attempt<'a>> {
        let clock = std::time::Instant::now();
        crate::pipeline::stages::copy_mesh(self.mesh, staged.path())?;
        let mut writer =
            points::Writer::new(p, spec, self.model, self.mesh, staged.path(), self.saved);
        let (mut starts, mut judging) = (Vec::new(), 0.0);
        let ended = continue_curve(
            p,
            spec,
            self.model,
            &mut writer,
            (&mut starts, &mut judging),
            self.saved,
            self.reporter,
        );
        Ok(Attempt {
            p,
            staged,
            writer,
            starts,
            judging,
            ended,
            seconds: clock.elapsed().as_secs_f64(),
        })
    }

    /// `first`, or where it stopped at a dead end or on its own trail (a contact sweep from
    /// its start), the curve swept again with `again` (`None`: the sweep set its own
    /// `max_turn`) unless that stops so too; with how it was swept again. The time of both
    /// is the kept attempt's.
    fn again_if_stopped(
        &self,
        mut first: Attempt<'a>,
        (spec, again): (&'a SweepSpec, Option<&'a SweepSpec>),
    ) -> Result<(Attempt<'a>, Option<SweptAgain>)> {
        let stopped = match &first.ended {
            Ok(outcome) => outcome.stopped.clone(),
            Err(_) => None,
        };
        let unstable = !self.again_among_unstable && in_unstable_stretch(&first.writer.rows);
        let retry = self.saved.is_none() && self.model.contact.is_some() && !unstable;
        let rows = first.writer.rows.last();
        let (Some(reason), Some(again), true, Some(last)) = (stopped, again, retry, rows) else {
            return Ok((first, None));
        };
        let max_turn = again.max_turn.unwrap_or(RETRY_TURN);
        let mut how = SweptAgain {
            max_turn,
            first_stop_hz: last.frequency_hz,
            first_points: first.writer.rows.len(),
            first_reason: reason,
            kept: false,
            finer_samples: None,
            finer_kept: false,
        };
        let status = format!(
            "stopped at {:.4} Hz after {} points; sweeping again from the start with sweep.max_turn = {max_turn}°",
            how.first_stop_hz, how.first_points
        );
        self.reporter.progress("sweep", 0, None, &status);
        let second = self.attempt(self.p, again, first.staged.again()?)?;
        // Interrupted (or failed otherwise) on its way, the second curve is the one to resume.
        if !stopped_short(&second) {
            how.kept = true;
            return Ok((later_kept(second, &first), Some(how)));
        }
        let turned = format!("swept again from its start with sweep.max_turn = {max_turn}°");
        absorb(&mut first, second, &turned);
        let unstable = in_unstable_stretch(&first.writer.rows) || first.ended.is_err();
        match self.finer.filter(|_| !unstable) {
            Some(finer) => self.finer_sweep(first, (finer, spec), how),
            None => Ok((first, Some(how))),
        }
    }

    /// A third sweep from the start, of `finer` (the contact law's samples doubled) with
    /// `spec`, after the first two stopped elsewhere than among unstable states: kept unless
    /// it stops too (then the first is, its stop naming the third's).
    fn finer_sweep(
        &self,
        mut first: Attempt<'a>,
        (finer, spec): (&'a Pipeline, &'a SweepSpec),
        mut how: SweptAgain,
    ) -> Result<(Attempt<'a>, Option<SweptAgain>)> {
        let samples = finer.harmonic_balance.samples.unwrap_or_default();
        how.finer_samples = Some(samples);
        let status = format!(
            "stopped again; sweeping from the start with harmonic_balance.samples = {samples}"
        );
        self.reporter.progress("sweep", 0, None, &status);
        let third = self.attempt(finer, spec, first.staged.again()?)?;
        if !stopped_short(&third) {
            how.finer_kept = true;
            return Ok((later_kept(third, &first), Some(how)));
        }
        let finer = format!("swept again with harmonic_balance.samples = {samples}");
        absorb(&mut first, third, &finer);
        Ok((first, Some(how)))
    }
}

/// `later` kept over `first`, its time including `first`'s.
fn later_kept<'a>(mut later: Attempt<'a>, first: &Attempt) -> Attempt<'a> {
    later.seconds += first.seconds;
    later.judging += first.judging;
    later
}

/// The attempt stopped short (not interrupted or failed otherwise).
fn stopped_short(a: &Attempt) -> bool {
    matches!(&a.ended, Ok(o) if o.stopped.is_some())
}

/// `first` kept over `later`, which stopped too (`how` it was swept): `first`'s stop names
/// where, and its time includes `later`'s; `later`'s staged folder is removed.
fn absorb(first: &mut Attempt, later: Attempt, how: &str) {
    if let (Ok(outcome), Some(row)) = (&mut first.ended, later.writer.rows.last()) {
        let stop = outcome.stopped.get_or_insert_with(String::new);
        stop.push_str(&format!(
            "; {how}, it stopped too, at {:.4} Hz after {} points",
            row.frequency_hz,
            later.writer.rows.len()
        ));
    }
    first.seconds += later.seconds;
    first.judging += later.judging;
}
