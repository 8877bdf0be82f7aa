//! `hbcontact sweep --resume`: continue a sweep saved in its output directory from its last
//! point. sweep.json keeps what that needs (`SweepSummary::resume`, a
//! `hbm::continuation::ContinuationState`): everything the continuation carries from one point to
//! the next, so that the points after it are those of the uninterrupted sweep bit for bit:
//! the point's index and ω, the step the next point is tried with, the unit direction τ in
//! the scaled unknowns (λ/F, ω/Ω), whose sign of τ_ω says whether the curve was running
//! forward or back, the multipliers λ, the scaling F with the c and N the first point fixed,
//! the largest ‖λ‖ so far (a grazing corner is judged against it), the frequencies at which
//! the reduced model of the frames learned from exact ones and whether the point's own frame
//! was reduced (the model is built again and taught the same, and the point is taken on the
//! same kind of frame), the Krylov hint of the Newton, and the trail of the points before it
//! (a retrace is checked against it). The saved λ is checked to solve its frame (a Newton
//! from it takes no step; a cold solve could land on another branch where the curve is
//! multi-valued). Rows, frames and point folders from before are kept.
//!
//! sweep.json is read back like user input (a file anyone may edit): at most
//! `MAX_FILE_BYTES`, and every field checked before it sizes or steers anything (`check_rows`,
//! `check_continuation`, `check_lists`, `check_state`), each refusal naming the file and the
//! field, exit 2:
//! - rows: at least one, row i has index i (the order the sweep writes), finite positive
//!   frequencies, one value per output (finite, or null for an output the scene lacks);
//! - the continuation state: the last row's index, ω = 2π f of that row (relative 1e-9), a
//!   finite positive step (brought within `sweep.min_step`, `max_step`), a unit tangent (‖τ‖ − 1 within 1e-6)
//!   of one entry per multiplier plus τ_ω, τ_ω the last row's `tangent_frequency`, finite
//!   multipliers, a turn limit (if any) in (0, 180) degrees, and `stopped.point` that same row;
//! - with contact: as many multipliers as the model has contact unknowns, c and F finite and
//!   positive, and N = N₀ 2^k (N₀ the pipeline's samples, k ≤ `MAX_DOUBLINGS`, the doublings
//!   the first point's knob check may make); without contact: τ = [±1], no multipliers,
//!   c = F = N = 0;
//! - the history (`check_history`), with contact: a trail of one point per row before the last,
//!   each of one entry per multiplier plus ω/Ω, finite, its ω that row's (relative 1e-9); the
//!   largest ‖λ‖ the largest of the trail's and the point's (relative 1e-9); at most
//!   `max_enrichments` frequencies the model learned at, each finite and within the range
//!   widened by its span on either side, and none, nor a reduced frame, with
//!   `sweep.reduced_frames: false`; without contact: none of these (largest 0);
//! - folds, frames, written points and earlier resumes: rows that exist, in order.

use std::path::Path;

use serde::Deserialize;

use super::{FoldReport, Stopped, SweepRow, WrittenPoint};
use crate::config::{Pipeline, SweepSpec};
use crate::hbm::continuation::ContinuationState;
use crate::hbm::knobs::MAX_DOUBLINGS;
use crate::linalg::norm2;
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

/// The command that continues the sweep written to `out`, as the hints of a stopped sweep
/// print it: the pipeline, its `--set` overrides in order, `--out` where `out` is not the
/// default folder, `--trust-geometry` where it was given, then `--resume`; each word quoted
/// for a POSIX shell where it needs it.
pub fn command(p: &Pipeline, out: &Path) -> String {
    let mut words = invocation(p, "sweep", &[]);
    if out != super::output_dir(p, &crate::pipeline::RunOptions::default()) {
        words.extend(["--out".to_string(), out.display().to_string()]);
    }
    words.push("--resume".to_string());
    quoted(&words)
}

/// The command that marches the sweep's scene from rest at `hz` (`hbcontact transient`, the
/// sweep's `--set`s and the frequency's).
pub fn march_command(p: &Pipeline, hz: f64) -> String {
    let at = format!("harmonic_balance.frequency={hz:.4}");
    quoted(&invocation(p, "transient", &[at]))
}

/// `hbcontact SUBCOMMAND PIPELINE`, the pipeline's `--set`s followed by `more`, each key
/// once, where its last setting stands (as the command line applies them), and
/// `--trust-geometry` where the geometry was trusted.
fn invocation(p: &Pipeline, subcommand: &str, more: &[String]) -> Vec<String> {
    let mut words = vec![
        "hbcontact".to_string(),
        subcommand.to_string(),
        p.source.display().to_string(),
    ];
    let sets: Vec<&String> = p.overrides.iter().chain(more).collect();
    let key = |o: &str| o.split('=').next().unwrap_or_default().trim().to_string();
    for (i, o) in sets.iter().enumerate() {
        if !sets[i + 1..].iter().any(|later| key(later) == key(o)) {
            words.extend(["--set".to_string(), o.to_string()]);
        }
    }
    if p.geometry.trusted {
        words.push("--trust-geometry".to_string());
    }
    words
}

/// `words` as one shell command line.
fn quoted(words: &[String]) -> String {
    let quoted: Vec<String> = words.iter().map(|w| shell_word(w)).collect();
    quoted.join(" ")
}

/// `word` as a POSIX shell reads it back: as is when it holds only characters no shell
/// treats specially, else in single quotes (a quote inside as `'\''`).
fn shell_word(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-./=:,+@%".contains(c));
    if plain {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// The largest sweep.json read back (1 GiB, parsed into about half that): the trail holds
/// every point's multipliers, e.g. 21 MB for 500 points of 100 contact nodes at H = 10 (the
/// shipped strip sweep: 0.9 MB for 148 points of 9 nodes).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

fn refuse(message: String) -> Error {
    Error::Input(format!(
        "--resume: {message}; or sweep again from the start without --resume"
    ))
}

/// A refusal of field `field` of the sweep.json at `path`.
fn bad_field(path: &Path, field: &str, why: String) -> Error {
    refuse(format!(
        "{}: `{field}` {why}: the file was not written by this sweep or was changed since",
        path.display()
    ))
}

/// `Err` naming `field` unless `ok`.
fn require(ok: bool, path: &Path, field: &str, why: impl FnOnce() -> String) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(bad_field(path, field, why()))
    }
}

/// The text of `path`, refused beyond `MAX_FILE_BYTES` before it is read.
fn read_bounded(path: &Path) -> Result<String> {
    let cannot = |e: std::io::Error| {
        refuse(format!(
            "cannot read {} ({e}): there is no sweep to continue",
            path.display()
        ))
    };
    crate::files::read_capped(path, MAX_FILE_BYTES)
        .map_err(cannot)?
        .ok_or_else(|| {
            refuse(format!(
                "{} is larger than {} MiB, more than a resume reads",
                path.display(),
                MAX_FILE_BYTES >> 20
            ))
        })
}

/// The sweep saved in `out`, checked against the pipeline's `sweep` block: the same range
/// and H (they fix the scaling), unfinished, and more points allowed than it has.
pub fn read(out: &Path, p: &Pipeline, spec: &SweepSpec) -> Result<Saved> {
    let path = out.join("sweep.json");
    let text = read_bounded(&path)?;
    let mut saved: Saved = serde_json::from_str(&text).map_err(|e| {
        refuse(format!(
            "{} is not a sweep.json this version can continue ({e})",
            path.display()
        ))
    })?;
    check_settings(&path, &saved, p, spec)?;
    let Some(state) = &saved.resume else {
        return Err(refuse(format!(
            "{} holds no continuation state",
            path.display()
        )));
    };
    check_rows(&path, &saved.rows, super::outputs(p).len())?;
    check_continuation(&path, &saved, state)?;
    check_history(&path, &saved, state, spec)?;
    check_lists(&path, &saved)?;
    let saved_points = state.index + 1;
    if spec.max_points <= saved_points {
        return Err(refuse(format!(
            "sweep.max_points = {} allows no point after the {saved_points} saved in {}: raise it, e.g. --set sweep.max_points={}",
            spec.max_points,
            path.display(),
            2 * spec.max_points.max(saved_points)
        )));
    }
    if let Some(state) = &mut saved.resume {
        // A step saved under other sweep.min_step, max_step than the resume's.
        state.step = state.step.max(spec.min_step).min(spec.max_step);
    }
    Ok(saved)
}

/// The same range and H as the pipeline's (they fix the scaling), and unfinished.
fn check_settings(path: &Path, saved: &Saved, p: &Pipeline, spec: &SweepSpec) -> Result<()> {
    let same = |key: &str, now: f64, then: f64| {
        if now == then {
            Ok(())
        } else {
            Err(refuse(format!(
                "{key} is {now} but the sweep saved in {} used {then}: resume with the same {key}",
                path.display()
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
            path.display(),
            saved.to_hz
        )));
    }
    Ok(())
}

/// Rows as the sweep writes them: at least one, row i with index i, finite positive
/// frequencies, one value per output (finite or NaN), finite numbers elsewhere.
fn check_rows(path: &Path, rows: &[SweepRow], columns: usize) -> Result<()> {
    require(!rows.is_empty(), path, "rows", || "is empty".into())?;
    for (i, r) in rows.iter().enumerate() {
        let field = |name: &str| format!("rows[{i}].{name}");
        require(r.index == i, path, &field("index"), || {
            format!("is {} (rows are written in order)", r.index)
        })?;
        let hz = r.frequency_hz;
        require(
            hz.is_finite() && hz > 0.0,
            path,
            &field("frequency_hz"),
            || format!("= {hz} is not a positive frequency"),
        )?;
        require(r.values.len() == columns, path, &field("values"), || {
            format!(
                "has {} values, not one per column ({columns})",
                r.values.len()
            )
        })?;
        require(
            !r.values.iter().any(|v| v.is_infinite()),
            path,
            &field("values"),
            || "holds an infinity".into(),
        )?;
        let numbers = [r.step, r.tangent_frequency, r.seconds];
        let optional = [r.multiplier, r.argument, r.underdamped_share];
        let finite = numbers
            .iter()
            .chain(optional.iter().flatten())
            .all(|v| v.is_finite());
        require(finite, path, &field("step"), || {
            "or another number of the row is not finite".into()
        })?;
    }
    Ok(())
}

/// The continuation state against the rows: the last row's index, ω and τ_ω, a positive
/// step, a unit tangent of one entry per multiplier plus τ_ω, and `stopped` at that row.
fn check_continuation(path: &Path, saved: &Saved, state: &ContinuationState) -> Result<()> {
    let last = &saved.rows[saved.rows.len() - 1];
    require(state.index == last.index, path, "resume.index", || {
        format!(
            "= {} is not the last row's index {}",
            state.index, last.index
        )
    })?;
    let omega = 2.0 * std::f64::consts::PI * last.frequency_hz;
    let same = (state.omega - omega).abs() <= 1e-9 * omega;
    require(same, path, "resume.omega", || {
        format!(
            "= {} is not 2π times the last row's {} Hz",
            state.omega, last.frequency_hz
        )
    })?;
    require(
        state.step.is_finite() && state.step > 0.0,
        path,
        "resume.step",
        || format!("= {} is not a positive step", state.step),
    )?;
    check_tangent(path, state, last.tangent_frequency)?;
    let finite = state.multipliers.iter().all(|v| v.is_finite());
    require(finite, path, "resume.multipliers", || {
        "holds a non-finite value".into()
    })?;
    let turn = state.max_turn.is_none_or(|t| t > 0.0 && t < 180.0);
    require(turn, path, "resume.max_turn", || {
        format!("= {:?} is not an angle in (0, 180) degrees", state.max_turn)
    })?;
    if let Some(stopped) = &saved.stopped {
        let at_last = stopped.point == last.index && stopped.frequency_hz == last.frequency_hz;
        require(at_last, path, "stopped", || {
            format!(
                "names row {} at {} Hz, not the last row",
                stopped.point, stopped.frequency_hz
            )
        })?;
    }
    Ok(())
}

/// The most frequencies a curve of `points` points can have taught the reduced model: one per
/// attempt of each point verified on a reduced frame, and a point tries at most every step
/// from `sweep.max_step` halved down to `min_step`, then two grazing ones.
pub fn max_enrichments(points: usize, spec: &SweepSpec) -> usize {
    let halvings = (spec.max_step / spec.min_step).log2().ceil().max(0.0);
    let attempts = if halvings.is_finite() {
        halvings as usize + 3
    } else {
        3
    };
    points.saturating_mul(attempts)
}

/// The history the continuation carries (trail, largest ‖λ‖, the reduced model's lessons,
/// the frame's kind, `check_history` in the module's header) against the rows and the state.
fn check_history(
    path: &Path,
    saved: &Saved,
    state: &ContinuationState,
    spec: &SweepSpec,
) -> Result<()> {
    if state.multipliers.is_empty() {
        let none = state.trail.is_empty()
            && state.enriched_at.is_empty()
            && !state.reduced_frame
            && state.largest == 0.0;
        return require(none, path, "resume", || {
            "holds a contact history (trail, enriched_at, reduced_frame, largest) for a curve without multipliers".into()
        });
    }
    let largest = check_trail(path, saved, state, spec)?;
    let close = (state.largest - largest).abs() <= 1e-9 * largest;
    require(
        state.largest.is_finite() && close,
        path,
        "resume.largest",
        || {
            format!(
                "= {} is not the largest ‖λ‖ of the trail and the point ({largest})",
                state.largest
            )
        },
    )?;
    check_enriched(path, state, spec)?;
    require(
        !state.reduced_frame || spec.reduced_frames,
        path,
        "resume.reduced_frame",
        || {
            "is true but sweep.reduced_frames is false: resume with the same sweep.reduced_frames"
                .into()
        },
    )
}

/// Each point of `resume.trail`: one entry per multiplier plus ω/Ω, finite, at its row's
/// frequency; returns the largest ‖λ‖ of the trail and the point.
fn check_trail(
    path: &Path,
    saved: &Saved,
    state: &ContinuationState,
    spec: &SweepSpec,
) -> Result<f64> {
    let two_pi = 2.0 * std::f64::consts::PI;
    let span = (two_pi * spec.to_hz - two_pi * spec.from_hz).abs();
    let t = &state.trail;
    require(t.len() == state.index, path, "resume.trail", || {
        format!(
            "has {} points, not one per row before the last ({})",
            t.len(),
            state.index
        )
    })?;
    let width = state.multipliers.len() + 1;
    let mut largest = norm2(&state.multipliers);
    for (i, (y, row)) in t.iter().zip(&saved.rows).enumerate() {
        let field = format!("resume.trail[{i}]");
        require(y.len() == width, path, &field, || {
            format!(
                "has {} entries, not one per multiplier plus ω/Ω ({width})",
                y.len()
            )
        })?;
        require(y.iter().all(|v| v.is_finite()), path, &field, || {
            "holds a non-finite value".into()
        })?;
        let omega = two_pi * row.frequency_hz;
        let same = (y[width - 1] * span - omega).abs() <= 1e-9 * omega;
        require(same, path, &field, || {
            format!(
                "ends in ω/Ω = {}, not row {i}'s {} Hz over the span",
                y[width - 1],
                row.frequency_hz
            )
        })?;
        largest = largest.max(state.force_scale * norm2(&y[..width - 1]));
    }
    Ok(largest)
}

/// `resume.enriched_at`: no more frequencies than the curve can have taught the reduced
/// model, each within the sweep's range widened by its span.
fn check_enriched(path: &Path, state: &ContinuationState, spec: &SweepSpec) -> Result<()> {
    let two_pi = 2.0 * std::f64::consts::PI;
    let span = (two_pi * spec.to_hz - two_pi * spec.from_hz).abs();
    let e = &state.enriched_at;
    let most = if spec.reduced_frames {
        max_enrichments(state.index + 1, spec)
    } else {
        0
    };
    require(e.len() <= most, path, "resume.enriched_at", || {
        format!(
            "lists more frequencies ({}) than a curve of {} points can teach the reduced model ({most}{})",
            e.len(),
            state.index + 1,
            if spec.reduced_frames { "" } else { ": sweep.reduced_frames is false" }
        )
    })?;
    let (lo, hi) = (
        two_pi * spec.from_hz.min(spec.to_hz),
        two_pi * spec.from_hz.max(spec.to_hz),
    );
    for (i, &w) in e.iter().enumerate() {
        let inside = w.is_finite() && w > 0.0 && w >= lo - span && w <= hi + span;
        require(inside, path, &format!("resume.enriched_at[{i}]"), || {
            format!("= {w} rad/s lies outside the sweep's range widened by its span")
        })?;
    }
    Ok(())
}

fn check_tangent(path: &Path, state: &ContinuationState, tangent_frequency: f64) -> Result<()> {
    let t = &state.tangent;
    require(
        t.len() == state.multipliers.len() + 1,
        path,
        "resume.tangent",
        || {
            format!(
                "has {} entries for {} multipliers (one more is τ_ω)",
                t.len(),
                state.multipliers.len()
            )
        },
    )?;
    let length = norm2(t);
    require((length - 1.0).abs() <= 1e-6, path, "resume.tangent", || {
        format!("has length {length}, not 1")
    })?;
    require(
        t[t.len() - 1] == tangent_frequency,
        path,
        "resume.tangent",
        || {
            format!(
                "ends in τ_ω = {}, not the last row's tangent_frequency {tangent_frequency}",
                t[t.len() - 1]
            )
        },
    )
}

/// Folds, frames, written points and earlier resumes name rows that exist, in order.
fn check_lists(path: &Path, saved: &Saved) -> Result<()> {
    let n = saved.rows.len();
    let increasing = |v: &[usize]| v.windows(2).all(|w| w[0] < w[1]) && v.iter().all(|&i| i < n);
    require(increasing(&saved.frames), path, "frames", || {
        format!("are not increasing rows below {n}")
    })?;
    require(
        increasing(&saved.resumed_from),
        path,
        "resumed_from",
        || format!("are not increasing rows below {n}"),
    )?;
    let folds: Vec<usize> = saved.folds.iter().map(|f| f.after).collect();
    let fold_hz = saved
        .folds
        .iter()
        .all(|f| f.frequency_hz.is_finite() && f.frequency_hz > 0.0);
    require(increasing(&folds) && fold_hz, path, "folds", || {
        format!("are not increasing rows below {n} at positive frequencies")
    })?;
    for (i, w) in saved.written.iter().enumerate() {
        let name = w.folder.strip_prefix("points/").unwrap_or("");
        let plain = !name.is_empty() && !name.contains(['/', '\\']) && name != "..";
        require(w.row < n && plain, path, &format!("written[{i}]"), || {
            format!(
                "names row {} and folder {}",
                w.row,
                crate::error::excerpt(&w.folder)
            )
        })?;
    }
    Ok(())
}

/// The saved state fits the model: as many contact unknowns (rows × (2H + 1), two rows a
/// node with friction, H = ⌊S/2⌋ for a spline basis of S segments), and the scalars of a
/// contact curve (c, F, N) or of a linear one (none).
pub fn check_state(saved: &Saved, model: &Model, p: &Pipeline, out: &Path) -> Result<()> {
    let rows = model
        .contact
        .as_ref()
        .map_or(0, |c| c.operator.reduced_rows());
    let have = saved.resume.as_ref().map_or(0, |s| s.multipliers.len());
    let hb = &p.harmonic_balance;
    let h = match hb.basis {
        crate::config::BasisSpec::Spline { segments, .. } => segments / 2,
        // With H chosen per point the saved point's H is any of the range's.
        crate::config::BasisSpec::Fourier if hb.harmonics_max > hb.harmonics && rows > 0 => {
            let saved_h = (have / rows).saturating_sub(1) / 2;
            if (hb.harmonics..=hb.harmonics_max).contains(&saved_h) {
                saved_h
            } else {
                hb.harmonics
            }
        }
        crate::config::BasisSpec::Fourier => hb.harmonics,
    };
    let want = rows * (2 * h + 1);
    if have != want {
        return Err(refuse(format!(
            "the saved sweep has {have} contact unknowns and this scene {want}: the mesh or the contact set changed since"
        )));
    }
    let path = out.join("sweep.json");
    match (&saved.resume, model.contact.is_some()) {
        (Some(state), true) => {
            check_contact_scalars(&path, state, p)?;
            check_reduced_model(&path, state, model, p, h)
        }
        (Some(state), false) => {
            let linear = state.tangent.len() == 1 && state.c == 0.0 && state.force_scale == 0.0;
            require(linear && state.samples == 0, &path, "resume", || {
                "holds contact scalars (tangent, c, force_scale, samples) for a scene without contact".into()
            })
        }
        (None, _) => Ok(()),
    }
}

/// A reduced frame or lessons of a reduced model only where this scene's sweep builds one
/// (`hbm::continuation::reduced_model_pays`).
fn check_reduced_model(
    path: &Path,
    state: &ContinuationState,
    model: &Model,
    p: &Pipeline,
    harmonics: usize,
) -> Result<()> {
    let asked = p.sweep.as_ref().is_some_and(|s| s.reduced_frames);
    let frequencies = if asked {
        crate::hbm::frames::SHIFTS_PER_HARMONIC
    } else {
        0
    };
    let nodes = model
        .contact
        .as_ref()
        .map_or(0, |c| c.operator.reduced_rows());
    if crate::hbm::continuation::reduced_model_pays(&model.system, nodes, harmonics, frequencies) {
        return Ok(());
    }
    let why = "but this scene's sweep builds no reduced model of its frames";
    require(!state.reduced_frame, path, "resume.reduced_frame", || {
        format!("is true {why}")
    })?;
    require(
        state.enriched_at.is_empty(),
        path,
        "resume.enriched_at",
        || format!("names frequencies the reduced model learned at {why}"),
    )
}

/// c and F finite and positive; N one the first point's knob check can reach from the
/// pipeline's samples N₀: N₀ 2^k, k ≤ `MAX_DOUBLINGS`.
fn check_contact_scalars(path: &Path, state: &ContinuationState, p: &Pipeline) -> Result<()> {
    for (field, v) in [
        ("resume.c", state.c),
        ("resume.force_scale", state.force_scale),
    ] {
        require(v.is_finite() && v > 0.0, path, field, || {
            format!("= {v} is not positive")
        })?;
    }
    let n0 = crate::pipeline::hb_settings(p).samples;
    let allowed: Vec<usize> = (0..=MAX_DOUBLINGS as u32).map(|k| n0 << k).collect();
    require(
        allowed.contains(&state.samples),
        path,
        "resume.samples",
        || {
            format!(
            "= {} is not one the pipeline's samples allow ({allowed:?}: harmonic_balance.samples, doubled by the knob check)",
            state.samples
        )
        },
    )
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

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a printed command sets each key once, to its last setting, as the command
    /// line applies them: the march replaces the pipeline's frequency, and the curve swept
    /// from the other end (its `--set`s appended) names its own range once.
    #[test]
    fn a_printed_command_sets_each_key_once_to_its_last_setting() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenes/blade_mode1.yaml");
        let sets = ["harmonic_balance.frequency=700", "sweep.from=700"].map(String::from);
        let p = crate::config::load_pipeline(&path, &sets).unwrap_or_else(|e| panic!("{e}"));
        let march = march_command(&p, 800.0);
        assert!(
            march.ends_with("--set sweep.from=700 --set harmonic_balance.frequency=800.0000"),
            "{march}"
        );
        assert_eq!(
            march.matches("harmonic_balance.frequency").count(),
            1,
            "{march}"
        );
        let spec = p.sweep.clone().expect("a sweep block");
        let (other, _) = super::super::other_end::reversed(&p, &spec);
        let resume = command(&other, Path::new("out/from_the_end"));
        assert_eq!(resume.matches("sweep.from=").count(), 1, "{resume}");
        assert!(
            resume.contains("--set sweep.from=1291.9 --set sweep.to=700"),
            "{resume}"
        );
    }
}
