//! What a sweep writes per point as the curve is found: its row, a frame of `frames.pvd`
//! (every `sweep.save_every`-th point), and the solutions kept for the full outputs written
//! at the end under `points/`: the folds, the peak, and the point nearest each frequency of
//! `sweep.write_at`.
//!
//! A frame (`frames/point_XXXX.vtu`, "time" = the row index, since ω runs back along a fold):
//! point data `displacement` [m], u(t = 0), and `first_harmonic_amplitude` [m], the amplitude
//! |û_1| of each displacement component's first harmonic, (|û_x,1|, |û_y,1|, 0); cell data
//! `frequency_hz` (constant). A point folder holds what `hbcontact run` writes at that
//! frequency (series, amplitudes, CSV histories, summary.json, plots).
//!
//! Folds are the continuation's: where the direction's ω-component τ_ω changes sign between
//! consecutive points (the point before the change is the fold), kinks of the sampled law
//! removed by `hbm::continuation::without_kinks`; the rule is applied here to the points as they
//! come, so the folds are known also when the sweep fails part-way or is resumed.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::resume::Saved;
use super::{FoldReport, SweepRow};
use crate::config::{Pipeline, SweepSpec};
use crate::hbm::continuation::{without_kinks, ContinuationState, Fold, PointInfo, KINK};
use crate::hbm::Solution;
use crate::output::tables::write_json;
use crate::output::{write_pvd, write_vtu, Field};
use crate::pipeline::stability::Stability;
use crate::pipeline::summary::MeshInfo;
use crate::pipeline::{publish, sanity, Model, WriteLevel};
use crate::{Error, Result};

/// A point written with a run's full output.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
pub struct WrittenPoint {
    /// `fold K`, `peak` (largest probe first harmonic) or `at F Hz` (nearest to a
    /// `sweep.write_at` frequency).
    pub reason: String,
    pub row: usize,
    pub frequency_hz: f64,
    /// Relative to the sweep directory, e.g. `points/fold_1_1668.9Hz`.
    pub folder: String,
}

/// The best point so far for one purpose: its row, its measure (smaller is better) and, when
/// found in this invocation, its solution.
struct Kept {
    row: Option<usize>,
    measure: f64,
    solution: Option<Solution>,
}

impl Kept {
    fn new() -> Self {
        Kept {
            row: None,
            measure: f64::INFINITY,
            solution: None,
        }
    }

    /// Seeded with the best of earlier rows (resume), whose solution is not at hand.
    fn seeded(rows: &[SweepRow], measure: impl Fn(&SweepRow) -> f64) -> Self {
        let mut k = Kept::new();
        for r in rows {
            let m = measure(r);
            if m < k.measure {
                (k.row, k.measure) = (Some(r.index), m);
            }
        }
        k
    }

    fn offer(&mut self, row: usize, measure: f64, solution: &Solution) {
        if measure < self.measure {
            (self.row, self.measure) = (Some(row), measure);
            self.solution = Some(solution.clone());
        }
    }
}

/// −(probe first harmonic), so that the peak is the smallest; +∞ without a value.
fn peak_measure(r: &SweepRow) -> f64 {
    let v = r.values.first().copied().unwrap_or(f64::NAN);
    if v.is_finite() {
        -v
    } else {
        f64::INFINITY
    }
}

/// Receives the points of the continuation; writes frames as they come and the point folders
/// at the end.
pub struct Writer<'a> {
    p: &'a Pipeline,
    spec: &'a SweepSpec,
    model: &'a Model,
    mesh: &'a MeshInfo,
    dir: PathBuf,
    pub rows: Vec<SweepRow>,
    /// The stability verdicts of this invocation's checked rows (row index, verdict), for
    /// the point folders' summaries.
    pub verdicts: Vec<(usize, Stability)>,
    frames: Vec<usize>,
    last_state: Option<ContinuationState>,
    /// Every point so far in the continuation's scaled unknowns (`PointInfo::scaled`), the
    /// saved sweep's first: the trail `resume_state` saves.
    trail: Vec<Vec<f64>>,
    /// The resumed point (re-solved, its row kept from before).
    resumed_at: Option<usize>,
    seen: usize,
    peak: Kept,
    near: Vec<Kept>,
    previous: Option<(usize, f64, Solution)>,
    /// Raw folds of this invocation: row and solution.
    candidates: Vec<(usize, Solution)>,
    old_folds: Vec<FoldReport>,
    old_written: Vec<WrittenPoint>,
}

impl<'a> Writer<'a> {
    pub fn new(
        p: &'a Pipeline,
        spec: &'a SweepSpec,
        model: &'a Model,
        mesh: &'a MeshInfo,
        dir: &Path,
        saved: Option<&Saved>,
    ) -> Self {
        let rows = saved.map_or(Vec::new(), |s| s.rows.clone());
        let near = spec
            .write_at
            .iter()
            .map(|&f| Kept::seeded(&rows, |r| (r.frequency_hz - f).abs()))
            .collect();
        Writer {
            p,
            spec,
            model,
            mesh,
            dir: dir.to_path_buf(),
            peak: Kept::seeded(&rows, peak_measure),
            near,
            rows,
            frames: saved.map_or(Vec::new(), |s| s.frames.clone()),
            trail: saved
                .and_then(|s| s.resume.as_ref())
                .map_or(Vec::new(), |r| r.trail.clone()),
            last_state: saved.and_then(|s| s.resume.clone()),
            resumed_at: saved.and_then(|s| s.resume.as_ref().map(|r| r.index)),
            seen: 0,
            previous: None,
            candidates: Vec::new(),
            verdicts: Vec::new(),
            old_folds: saved.map_or(Vec::new(), |s| s.folds.clone()),
            old_written: saved.map_or(Vec::new(), |s| s.written.clone()),
        }
    }

    /// Points received (the resumed point included).
    pub fn seen(&self) -> usize {
        self.seen
    }

    pub fn frame_rows(&self) -> Vec<usize> {
        self.frames.clone()
    }

    /// One accepted point of the continuation.
    pub fn point(&mut self, info: &PointInfo, solution: &Solution) -> Result<()> {
        self.seen += 1;
        if Some(info.index) != self.resumed_at {
            let row = super::row(self.p, self.model, self.mesh, info, solution);
            let every = self.spec.save_every;
            if every > 0 && info.index.is_multiple_of(every) {
                self.write_frame(info.index, solution)?;
                self.frames.push(info.index);
            }
            self.peak.offer(info.index, peak_measure(&row), solution);
            for (kept, &f) in self.near.iter_mut().zip(&self.spec.write_at) {
                kept.offer(info.index, (row.frequency_hz - f).abs(), solution);
            }
            self.rows.push(row);
        }
        if let Some((i, t, before)) = self.previous.take() {
            if info.index > 1 && t * info.tangent_omega < 0.0 {
                self.candidates.push((i, before));
            }
        }
        self.previous = Some((info.index, info.tangent_omega, solution.clone()));
        if !info.scaled.is_empty() {
            self.trail.push(info.scaled.clone());
        }
        self.last_state = info.state.clone();
        Ok(())
    }

    /// What `--resume` continues from: the continuation's state after the last point, with
    /// the trail of the points before it.
    pub fn resume_state(&self) -> Option<ContinuationState> {
        let mut state = self.last_state.clone()?;
        state.trail = self.trail[..state.index.min(self.trail.len())].to_vec();
        Some(state)
    }

    /// `frames/point_XXXX.vtu`: u(t = 0), the first-harmonic amplitude, the frequency.
    fn write_frame(&self, index: usize, solution: &Solution) -> Result<()> {
        let dir = self.dir.join("frames");
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        let dofs = &self.model.system.dofs;
        let u = solution.field_at(dofs, 0.0, 0);
        let z = solution.amplitude(dofs, 1);
        let points = vec![
            Field {
                name: "displacement".into(),
                components: 3,
                values: u.chunks(2).flat_map(|c| [c[0], c[1], 0.0]).collect(),
            },
            Field {
                name: "first_harmonic_amplitude".into(),
                components: 3,
                values: z
                    .chunks(2)
                    .flat_map(|c| [c[0].norm(), c[1].norm(), 0.0])
                    .collect(),
            },
        ];
        let cells = vec![Field {
            name: "frequency_hz".into(),
            components: 1,
            values: vec![solution.omega / (2.0 * PI); self.model.mesh.cells.len()],
        }];
        let path = dir.join(frame_name(index));
        write_vtu(&path, &self.model.mesh, &points, &cells)
    }

    /// `frames.pvd` over every frame (also those of the sweep before a resume).
    pub fn write_pvd(&self) -> Result<()> {
        if self.frames.is_empty() {
            return Ok(());
        }
        let entries: Vec<(f64, String)> = self
            .frames
            .iter()
            .map(|&i| (i as f64, format!("frames/{}", frame_name(i))))
            .collect();
        write_pvd(&self.dir.join("frames.pvd"), &entries)
    }

    /// The folds of the whole curve: those saved before a resume, then this invocation's,
    /// kinks removed.
    pub fn folds(&self, spec: &SweepSpec) -> Vec<FoldReport> {
        let span = 2.0 * PI * (spec.to_hz - spec.from_hz).abs();
        let mut all: Vec<Fold> = self
            .old_folds
            .iter()
            .map(|f| Fold {
                after: f.after,
                omega: 2.0 * PI * f.frequency_hz,
            })
            .collect();
        all.extend(self.candidates.iter().map(|(i, s)| Fold {
            after: *i,
            omega: s.omega,
        }));
        without_kinks(all, KINK * span)
            .into_iter()
            .map(|f| FoldReport {
                frequency_hz: f.omega / (2.0 * PI),
                after: f.after,
                amplitude: self
                    .row(f.after)
                    .map_or(f64::NAN, |r| r.values.first().copied().unwrap_or(f64::NAN)),
            })
            .collect()
    }

    fn verdict(&self, row: usize) -> Option<&Stability> {
        self.verdicts
            .iter()
            .find(|(i, _)| *i == row)
            .map(|(_, v)| v)
    }

    fn row(&self, index: usize) -> Option<&SweepRow> {
        self.rows.iter().find(|r| r.index == index)
    }

    /// The full outputs under `points/`: every fold, the peak, the points nearest
    /// `sweep.write_at`. A point found before a resume keeps the folder written then; stale
    /// folders (a peak since overtaken) are removed. Returns what is there, and a warning for
    /// each wanted point that is not (found before a resume that wrote no folder for it).
    pub fn write_points(&self, folds: &[FoldReport]) -> Result<(Vec<WrittenPoint>, Vec<String>)> {
        let root = self.dir.join("points");
        let (mut written, mut warnings) = (Vec::new(), Vec::new());
        for (reason, folder, row, solution) in self.wanted(folds) {
            let path = root.join(&folder);
            let kept_before = self
                .old_written
                .iter()
                .any(|w| w.folder == format!("points/{folder}") && w.row == row);
            match solution {
                Some(s) => {
                    if path.exists() {
                        std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
                    }
                    self.write_point(&path, s, self.verdict(row))?;
                }
                None if kept_before && path.is_dir() => {}
                None => {
                    warnings.push(format!(
                        "no full output for {reason} (row {row}): it was found before the resume, which had not written it; sweep again without --resume to have it"
                    ));
                    continue;
                }
            }
            let frequency_hz = self.row(row).map_or(f64::NAN, |r| r.frequency_hz);
            written.push(WrittenPoint {
                reason,
                row,
                frequency_hz,
                folder: format!("points/{folder}"),
            });
        }
        remove_unlisted(&root, &written)?;
        Ok((written, warnings))
    }

    /// The points wanted under `points/`: (reason, folder, row, the solution if found in this
    /// invocation), folds first, then the peak and the `write_at` points.
    fn wanted(&self, folds: &[FoldReport]) -> Vec<(String, String, usize, Option<&Solution>)> {
        let mut wanted = Vec::new();
        for (k, f) in folds.iter().enumerate() {
            let solution = self
                .candidates
                .iter()
                .find(|(i, _)| *i == f.after)
                .map(|(_, s)| s);
            let folder = format!("fold_{}_{:.1}Hz", k + 1, f.frequency_hz);
            wanted.push((format!("fold {}", k + 1), folder, f.after, solution));
        }
        if let Some(row) = self.peak.row {
            let hz = self.row(row).map_or(f64::NAN, |r| r.frequency_hz);
            let folder = format!("peak_{hz:.1}Hz");
            wanted.push(("peak".into(), folder, row, self.peak.solution.as_ref()));
        }
        for (kept, f) in self.near.iter().zip(&self.spec.write_at) {
            if let Some(row) = kept.row {
                let folder = format!("at_{f}Hz");
                wanted.push((format!("at {f} Hz"), folder, row, kept.solution.as_ref()));
            }
        }
        wanted
    }

    /// What `hbcontact run` writes, at this point's frequency, into `dir`, with the row's
    /// stability verdict (and its warning) where it was checked.
    fn write_point(
        &self,
        dir: &Path,
        solution: &Solution,
        verdict: Option<&Stability>,
    ) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let (p, model, full) = (self.p, self.model, WriteLevel::Full);
        let (mut s, sampled) = publish::harmonic_balance(
            p,
            (model, self.mesh.clone()),
            solution,
            full,
            dir,
            &crate::progress::Silent,
        )?;
        s.warnings
            .extend(sanity::check_contact_result(model, solution));
        s.warnings.extend(verdict.and_then(Stability::warning));
        s.stability = verdict.cloned();
        if publish::plotting(p, full) {
            let period = 1.0 / s.frequency_hz;
            publish::plots(p, (model, &sampled), &dir.join("plots"), period)?;
        }
        write_json(&dir.join("summary.json"), &s)
    }
}

fn frame_name(index: usize) -> String {
    format!("point_{index:04}.vtu")
}

/// Remove the folders of `root` that `written` does not list (carried over from before a
/// resume and no longer wanted).
fn remove_unlisted(root: &Path, written: &[WrittenPoint]) -> Result<()> {
    let Ok(entries) = std::fs::read_dir(root) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = format!("points/{}", entry.file_name().to_string_lossy());
        if !written.iter().any(|w| w.folder == name) {
            let path = entry.path();
            std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    Ok(())
}
