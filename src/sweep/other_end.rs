//! A sweep that stops among unstable states, swept from the other end of its range.
//!
//! A curve that stops where every point judged since its last stable one is unstable
//! (`bifurcations::in_unstable_stretch`) was stopped by states no structure follows: the
//! 0.5%-damped strip at H = 40 tangles in folds at 1345–1358 Hz, where a march from rest is
//! quasi-periodic or irregular. Beyond that stretch lie the states that come back: the
//! resonance's upper branch and its fold, then the open branch to the end of the range. So
//! the curve is swept again from `to_hz` toward `from_hz` (`reversed`), and what the two
//! curves cover settles the stop (`settle`):
//! - the curve from the end reaches `from_hz`: it covers the range alone;
//! - it stops among unstable states too: the range is covered but for the stretch between
//!   the two stops (`untraced_hz`; none where the two overlap in frequency), bracketed by
//!   unstable states on both sides;
//! - else (it stops elsewhere, or at `max_points`): the stop stands.
//!
//! In the first two cases the sweep ends with exit 0; its stop keeps its reason with the
//! class `unstable_stretch`, and a warning names what neither curve traced and the march
//! that shows what the structure does there. The curve from the end is written whole, as
//! `hbcontact sweep` with `from` and `to` exchanged writes it, under `from_the_end/` (its
//! own `sweep.csv`, frames, points and plots); its rows are also in sweep.json and on
//! `sweep.png`. It costs a curve's time on a stopped sweep only.

use schemars::JsonSchema;
use serde::Serialize;

use super::bifurcations::{in_unstable_stretch, last_stable_hz};
use super::{FoldReport, Stopped, SweepRow, SweepSummary};
use crate::config::{Pipeline, SweepSpec};
use crate::Error;

/// The folder of the curve swept from the other end, in the sweep's.
pub const FOLDER: &str = "from_the_end";

/// `Stopped::class` of a curve that stopped among unstable states where the curve from the
/// other end covers the rest (exit 0).
pub const CLASS: &str = "unstable_stretch";

/// The curve swept from the other end of the range, in sweep.json.
#[derive(Clone, Debug, Serialize, JsonSchema)]
pub struct FromTheEnd {
    /// Its folder in the sweep's (`from_the_end`), with its own sweep.json.
    pub folder: String,
    /// It runs from the sweep's `to_hz` toward its `from_hz` [Hz].
    pub from_hz: f64,
    pub to_hz: f64,
    pub points: usize,
    pub folds: Vec<FoldReport>,
    /// Why it ended before `to_hz` (`None`: it reached it).
    pub stopped: Option<Stopped>,
    /// The two curves settle the sweep's stop (exit 0): this one reaches `to_hz`, or both
    /// stopped among unstable states.
    pub settles: bool,
    /// The stretch [Hz, Hz] between the two stops that neither curve traced, when both
    /// stopped among unstable states without overlapping in frequency.
    pub untraced_hz: Option<[f64; 2]>,
    /// Its rows, in its order.
    pub rows: Vec<SweepRow>,
}

/// A sweep to sweep again from the other end: a contact sweep stopped by the solver (exit 4)
/// among unstable states.
pub fn called_for(s: &SweepSummary, failure: Option<&Error>, contact: bool) -> bool {
    let by_solver = failure.is_some_and(|e| e.class() == "not_converged");
    contact && by_solver && s.stopped.is_some() && in_unstable_stretch(&s.rows)
}

/// The pipeline and sweep from `spec.to_hz` toward `spec.from_hz`, starting there; its
/// `--set`s say so, so that the commands its output prints sweep it again.
pub fn reversed(p: &Pipeline, spec: &SweepSpec) -> (Pipeline, SweepSpec) {
    let spec = SweepSpec {
        from_hz: spec.to_hz,
        to_hz: spec.from_hz,
        ..spec.clone()
    };
    let mut p = p.clone();
    p.sweep = Some(spec.clone());
    p.harmonic_balance.frequency = spec.from_hz;
    p.overrides.extend([
        format!("sweep.from={}", spec.from_hz),
        format!("sweep.to={}", spec.to_hz),
        format!("harmonic_balance.frequency={}", spec.from_hz),
    ]);
    (p, spec)
}

/// The farthest frequency `rows` reach going from `from` toward `to` [Hz].
fn reached(rows: &[SweepRow], (from, to): (f64, f64)) -> f64 {
    let sign = if to >= from { 1.0 } else { -1.0 };
    let far = (rows.iter()).fold(f64::NEG_INFINITY, |m, r| m.max(sign * r.frequency_hz));
    sign * far
}

/// What the curve swept from the other end covers with the stopped one.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Cover {
    /// It reaches the start of the range.
    Whole,
    /// It stops among unstable states too, with the stretch [Hz, Hz] neither reaches
    /// (`None`: they overlap in frequency).
    Bracketed(Option<[f64; 2]>),
    /// It stops elsewhere: the stop stands.
    Short,
}

/// How `other` (the rows swept from `range.1` toward `range.0`, stopped with `other_class`,
/// `None`: not stopped) covers with `main` (swept from `range.0`, stopped among unstable
/// states); with the farthest frequency each reaches [Hz].
fn cover(
    range: (f64, f64),
    main: &[SweepRow],
    other: &[SweepRow],
    other_class: Option<&str>,
) -> (Cover, f64, f64) {
    let (a, b) = (reached(main, range), reached(other, (range.1, range.0)));
    let by_solver = other_class == Some("not_converged");
    let cover = match other_class {
        None => Cover::Whole,
        Some(_) if by_solver && in_unstable_stretch(other) => {
            let apart = (b - a) * (range.1 - range.0) > 0.0;
            Cover::Bracketed(apart.then(|| [a.min(b), a.max(b)]))
        }
        Some(_) => Cover::Short,
    };
    (cover, a, b)
}

/// A curve's last stable frequency [Hz] in words.
fn last_stable(rows: &[SweepRow]) -> String {
    last_stable_hz(rows).map_or("none".to_string(), |f| format!("{f:.4}"))
}

/// `main`'s stop settled by `other`, the curve swept from the other end: true where the two
/// cover the range as the module's header says (the stop's class becomes `CLASS`); a warning
/// says what they cover, with the march (`march`, of the frequency [Hz]) into what neither
/// traced. `other` is kept as `main.from_the_end`.
pub fn settle(main: &mut SweepSummary, other: SweepSummary, march: impl Fn(f64) -> String) -> bool {
    let range = (main.from_hz, main.to_hz);
    let stop = other.stopped.as_ref();
    let (cover, a, b) = cover(
        range,
        &main.rows,
        &other.rows,
        stop.map(|s| s.class.as_str()),
    );
    let (n, from) = (other.rows.len(), other.from_hz);
    let warning = match cover {
        Cover::Whole => format!(
            "the curve reaches {a:.4} Hz and stops among unstable states; swept from the other \
             end ({from} Hz, {FOLDER}/, {n} points), the curve reaches {} Hz and covers the \
             range",
            other.to_hz
        ),
        Cover::Bracketed(Some([lo, hi])) => format!(
            "no curve traces {lo:.4}–{hi:.4} Hz: the curve reaches {a:.4} Hz and stops among \
             unstable states, and the curve swept from the other end ({from} Hz, {FOLDER}/, \
             {n} points) reaches {b:.4} Hz and stops among unstable states too; their last \
             stable states are at {} and {} Hz. A march shows what the structure does between \
             them: `{}`",
            last_stable(&main.rows),
            last_stable(&other.rows),
            march(0.5 * (lo + hi))
        ),
        Cover::Bracketed(None) => format!(
            "the curve reaches {a:.4} Hz and stops among unstable states, and the curve swept \
             from the other end ({from} Hz, {FOLDER}/, {n} points) reaches {b:.4} Hz and stops \
             among unstable states too: together they reach every frequency of the range, but \
             not the states that join them"
        ),
        Cover::Short => {
            let (at, class) = stop.map_or((b, ""), |s| (s.frequency_hz, s.class.as_str()));
            format!(
                "swept from the other end ({from} Hz, {FOLDER}/, {n} points), the curve \
                 stopped too, at {at:.4} Hz ({class}), not among unstable states: the stop \
                 stands"
            )
        }
    };
    main.warnings.push(warning);
    let settles = cover != Cover::Short;
    if let (true, Some(stop)) = (settles, main.stopped.as_mut()) {
        stop.class = CLASS.to_string();
    }
    main.from_the_end = Some(FromTheEnd {
        folder: FOLDER.to_string(),
        from_hz: other.from_hz,
        to_hz: other.to_hz,
        points: n,
        folds: other.folds,
        stopped: other.stopped,
        settles,
        untraced_hz: match cover {
            Cover::Bracketed(untraced) => untraced,
            _ => None,
        },
        rows: other.rows,
    });
    settles
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row at `f` Hz, stable or not.
    fn row(index: usize, f: f64, stable: bool) -> SweepRow {
        SweepRow {
            stable: Some(stable),
            ..SweepRow::for_tests(index, f)
        }
    }

    /// Stable rows at `stable`, then unstable ones at `unstable` [Hz].
    fn curve(stable: &[f64], unstable: &[f64]) -> Vec<SweepRow> {
        let verdicts =
            (stable.iter().map(|&f| (f, true))).chain(unstable.iter().map(|&f| (f, false)));
        verdicts
            .enumerate()
            .map(|(i, (f, s))| row(i, f, s))
            .collect()
    }

    /// TEST GOAL: the curve from the other end settles a stop among unstable states where it
    /// reaches the start, or stops among unstable states too (the stretch between the two
    /// named when they do not overlap, whichever way the range runs); stopped elsewhere, or
    /// before enough unstable points, it leaves the stop standing.
    #[test]
    fn the_curve_from_the_other_end_settles_a_stop_only_by_reaching_the_start_or_by_unstable_states(
    ) {
        let main = curve(&[100.0, 110.0], &[120.0, 121.0, 122.0, 123.0, 121.5]);
        let far = [200.0, 180.0, 160.0, 140.0];
        let nc = Some("not_converged");
        let other = curve(&far, &[141.0, 142.0, 143.0, 144.0, 145.0]);
        let up = (100.0, 200.0);
        assert_eq!(
            cover(up, &main, &other, nc),
            (Cover::Bracketed(Some([123.0, 140.0])), 123.0, 140.0)
        );
        assert_eq!(cover(up, &main, &other, None).0, Cover::Whole);
        assert_eq!(cover(up, &main, &other, Some("max_points")).0, Cover::Short);
        let short = curve(&far, &[141.0, 142.0, 143.0, 144.0]);
        assert_eq!(
            cover(up, &main, &short, nc).0,
            Cover::Short,
            "four unstable points"
        );
        let past = curve(&[200.0, 150.0], &[120.0, 119.0, 118.0, 117.0, 116.0]);
        assert_eq!(
            cover(up, &main, &past, nc).0,
            Cover::Bracketed(None),
            "overlapping"
        );
        // Swept down: the same curves with the range the other way round.
        let (down_main, down_other) = (other, main);
        let down = (200.0, 100.0);
        assert_eq!(
            cover(down, &down_main, &down_other, nc).0,
            Cover::Bracketed(Some([123.0, 140.0]))
        );
    }
}
