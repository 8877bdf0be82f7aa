//! Where along a curve its periodic states change stability, and how: the bifurcations
//! between judged rows.
//!
//! Walking the rows in curve order, a change of the verdict between two consecutive decided
//! rows a and b (rows whose check was undecided or not made are skipped) is
//! - the fold's, when a located fold lies between them (a ≤ fold ≤ b): listed with the folds;
//! - otherwise a bifurcation, classified by the leading Floquet multiplier μ of the unstable
//!   side: real through −1, a period doubling (a motion at f/2); a complex pair, a
//!   Neimark–Sacker bifurcation (a second frequency |arg μ|/(2π)·f); real through +1 where
//!   the curve turns (τ_ω changes sign from the row before a to the row after b) but too
//!   little to be listed as a fold, a kink of the sampled law; real through +1 where it does
//!   not turn, a branch point; and a grazing where the stable side's contact set did not change
//!   over the period (judged by its damping, no multiplier): the loss comes with the contact
//!   starting to open and close within the period.
//!
//! Located where |μ| crosses 1, linearly between the two rows:
//!   t = (1 − |μ_a|)/(|μ_b| − |μ_a|) clamped to [0, 1],   f* = f_a + t (f_b − f_a),
//! so within the step between them (a grazing, without |μ| on one side, at the midpoint).
//!
//! Glossary: μ, the multiplier of largest modulus at a row (`SweepRow::multiplier`,
//! `argument`, `crossing`); f_a, f_b the rows' frequencies; `loses`: whether stability is lost
//! going along the curve (from a to b).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{FoldReport, SweepRow};
use crate::hbm::floquet::Crossing;

/// How a curve's state changes stability between two rows (not at a fold).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BifurcationKind {
    /// A real multiplier through −1: a motion at half the drive frequency.
    PeriodDoubling,
    /// A complex pair through the unit circle: a second, incommensurate frequency.
    NeimarkSacker,
    /// A real multiplier through +1 where the curve turns within a step or two, too little to
    /// list as a fold: a kink of the sampled contact law (or a tangle of turns).
    Kink,
    /// A real multiplier through +1 where the curve does not turn: a branch point.
    BranchPoint,
    /// The contact set starts (or stops) changing within the period.
    Grazing,
    /// Judged by time marching: no multiplier to classify it by.
    Unclassified,
}

impl BifurcationKind {
    /// The short tag of plots and headlines.
    pub fn tag(self) -> &'static str {
        match self {
            BifurcationKind::PeriodDoubling => "PD",
            BifurcationKind::NeimarkSacker => "NS",
            BifurcationKind::Kink => "K",
            BifurcationKind::BranchPoint => "BP",
            BifurcationKind::Grazing => "G",
            BifurcationKind::Unclassified => "S",
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            BifurcationKind::PeriodDoubling => "period doubling",
            BifurcationKind::NeimarkSacker => "Neimark–Sacker",
            BifurcationKind::Kink => "kink",
            BifurcationKind::BranchPoint => "branch point",
            BifurcationKind::Grazing => "grazing",
            BifurcationKind::Unclassified => "change of stability",
        }
    }
}

/// A bifurcation located between two rows of a curve.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
pub struct BifurcationReport {
    pub kind: BifurcationKind,
    /// Where |μ| crosses 1, interpolated between the two rows [Hz].
    pub frequency_hz: f64,
    /// The rows on either side, in curve order.
    pub between: [usize; 2],
    /// Going along the curve, stability is lost (true) or regained (false) there.
    pub loses: bool,
    /// |μ| and arg μ [degrees] of the leading multiplier on the unstable side.
    pub multiplier: f64,
    pub argument_deg: f64,
    /// The frequency of the motion the unstable side's multiplier brings [Hz] (half the
    /// drive's at a period doubling; none for a branch point or a grazing).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub new_frequency_hz: Option<f64>,
    /// The first output (probe first harmonic) at the row nearer the crossing.
    #[serde(deserialize_with = "super::nan_for_null_one")]
    pub amplitude: f64,
    /// A period doubling checked on the 2T problem (`sweep::branch::confirm`): whether the
    /// determinant of its odd-harmonic Newton matrix changes sign over the rows around it, as
    /// it does where a real multiplier of the harmonic-balance model itself passes −1
    /// (`None`: not checked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub confirmed: Option<bool>,
}

/// The bifurcations of the curve `rows` (in curve order) whose folds are `folds`.
pub fn locate(rows: &[SweepRow], folds: &[FoldReport]) -> Vec<BifurcationReport> {
    let decided: Vec<(usize, &SweepRow)> = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.stable.is_some())
        .collect();
    decided
        .windows(2)
        .filter(|w| w[0].1.stable != w[1].1.stable)
        .filter(|w| {
            !folds
                .iter()
                .any(|f| w[0].1.index <= f.after && f.after <= w[1].1.index)
        })
        .map(|w| {
            let near = &rows[w[0].0.saturating_sub(1)..rows.len().min(w[1].0 + 2)];
            let turns = near
                .windows(2)
                .any(|p| p[0].tangent_frequency * p[1].tangent_frequency < 0.0);
            between(w[0].1, w[1].1, turns)
        })
        .collect()
}

/// Judged rows, all unstable, at the end of a stopped curve that make it a stretch of states
/// no structure follows.
pub const UNSTABLE_TAIL: usize = 5;

/// What the stop of a curve (`rows`, in curve order) adds where it stopped in a stretch of
/// unstable states: how many points were judged since the last stable one, all unstable, how
/// many by a complex pair, and the command that marches the scene at the stop frequency
/// (`march`, of the frequency [Hz]); `None` where fewer than `UNSTABLE_TAIL` were.
pub fn unstable_tail(rows: &[SweepRow], march: impl Fn(f64) -> String) -> Option<String> {
    let (judged, since) = judged_since_stable(rows);
    let tail = &judged[since.map_or(0, |i| i + 1)..];
    let stop = tail.last().filter(|_| tail.len() >= UNSTABLE_TAIL)?;
    let from = match since {
        Some(i) => format!(
            "since its last stable point, at {:.4} Hz (point {}),",
            judged[i].frequency_hz, judged[i].index
        ),
        None => "from its start".to_string(),
    };
    let pairs = (tail.iter())
        .filter(|r| r.crossing == Some(Crossing::NeimarkSacker))
        .count();
    let how = match pairs {
        0 => String::new(),
        n => format!(
            ", {n} of them by a complex pair of multipliers (Neimark–Sacker: a second, \
             incommensurate frequency)"
        ),
    };
    Some(format!(
        "; the curve stopped among unstable states: all {} points judged {from} are \
         unstable{how}, so no structure follows this stretch of it. A march shows what the \
         structure does there instead: `{}`",
        tail.len(),
        march(stop.frequency_hz)
    ))
}

/// A curve (`rows`, in curve order) that ends in a stretch of unstable states: at least
/// `UNSTABLE_TAIL` points judged since its last stable one, all unstable.
pub fn in_unstable_stretch(rows: &[SweepRow]) -> bool {
    let (judged, since) = judged_since_stable(rows);
    judged.len() - since.map_or(0, |i| i + 1) >= UNSTABLE_TAIL
}

/// The frequency [Hz] of a curve's last stable point (`rows` in curve order).
pub fn last_stable_hz(rows: &[SweepRow]) -> Option<f64> {
    let (judged, since) = judged_since_stable(rows);
    since.map(|i| judged[i].frequency_hz)
}

/// The judged rows of a curve, and the position among them of the last stable one.
fn judged_since_stable(rows: &[SweepRow]) -> (Vec<&SweepRow>, Option<usize>) {
    let judged: Vec<&SweepRow> = rows.iter().filter(|r| r.stable.is_some()).collect();
    let since = judged.iter().rposition(|r| r.stable == Some(true));
    (judged, since)
}

/// The bifurcation between decided rows `a` and `b` of opposite verdicts; `turns`: the curve
/// turns between the row before a and the row after b.
fn between(a: &SweepRow, b: &SweepRow, turns: bool) -> BifurcationReport {
    let loses = a.stable == Some(true);
    let (stable, unstable) = if loses { (a, b) } else { (b, a) };
    let kind = match (unstable.crossing, stable.crossing) {
        (None, _) => BifurcationKind::Unclassified,
        (Some(_), None) if stable.multiplier.is_none() => BifurcationKind::Grazing,
        (Some(Crossing::PeriodDoubling), _) => BifurcationKind::PeriodDoubling,
        (Some(Crossing::NeimarkSacker), _) => BifurcationKind::NeimarkSacker,
        (Some(Crossing::Fold), _) if turns => BifurcationKind::Kink,
        (Some(Crossing::Fold), _) => BifurcationKind::BranchPoint,
    };
    let t = match (a.multiplier, b.multiplier) {
        (Some(ma), Some(mb)) if (mb - ma).abs() > 0.0 => ((1.0 - ma) / (mb - ma)).clamp(0.0, 1.0),
        _ => 0.5,
    };
    let frequency_hz = a.frequency_hz + t * (b.frequency_hz - a.frequency_hz);
    let argument = unstable.argument.unwrap_or(0.0);
    let new_frequency_hz = match kind {
        BifurcationKind::PeriodDoubling => Some(0.5 * frequency_hz),
        BifurcationKind::NeimarkSacker => {
            Some(argument / (2.0 * std::f64::consts::PI) * frequency_hz)
        }
        _ => None,
    };
    let near = if t < 0.5 { a } else { b };
    BifurcationReport {
        kind,
        frequency_hz,
        between: [a.index, b.index],
        loses,
        multiplier: unstable.multiplier.unwrap_or(f64::NAN),
        argument_deg: argument.to_degrees(),
        new_frequency_hz,
        amplitude: near.values.first().copied().unwrap_or(f64::NAN),
        confirmed: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(index: usize, f: f64, judged: Option<(f64, f64, Crossing)>) -> SweepRow {
        turning(index, f, judged, 1.0)
    }

    fn turning(
        index: usize,
        f: f64,
        judged: Option<(f64, f64, Crossing)>,
        tangent_frequency: f64,
    ) -> SweepRow {
        SweepRow {
            values: vec![index as f64],
            tangent_frequency,
            stable: Some(judged.is_none_or(|(m, _, _)| m < 1.0)),
            multiplier: judged.map(|(m, _, _)| m),
            argument: judged.map(|(_, a, _)| a),
            crossing: judged.map(|(_, _, c)| c),
            ..SweepRow::for_tests(index, f)
        }
    }

    /// TEST GOAL: a stop is said to lie among unstable states only where at least
    /// `UNSTABLE_TAIL` points judged since the last stable one are all unstable; unjudged
    /// rows are skipped, and the complex pairs among them are counted.
    #[test]
    fn a_stop_lies_among_unstable_states_only_after_enough_judged_unstable_points() {
        let ns = Some((1.1, 0.4, Crossing::NeimarkSacker));
        let fold = Some((1.1, 0.0, Crossing::Fold));
        let mut rows = vec![row(0, 100.0, None)];
        rows.extend((1..UNSTABLE_TAIL).map(|i| row(i, 100.0 + i as f64, ns)));
        let march = |f: f64| format!("march at {f:.4}");
        assert_eq!(unstable_tail(&rows, march), None, "one point short");
        let mut unjudged = row(UNSTABLE_TAIL, 110.0, None);
        unjudged.stable = None;
        rows.push(unjudged);
        assert_eq!(
            unstable_tail(&rows, march),
            None,
            "an unjudged row does not count"
        );
        rows.push(row(UNSTABLE_TAIL + 1, 111.0, fold));
        let said = unstable_tail(&rows, march).expect("a stretch of unstable states");
        assert!(
            said.contains(
                "all 5 points judged since its last stable point, at 100.0000 Hz (point 0)"
            ),
            "{said}"
        );
        assert!(said.contains("4 of them by a complex pair"), "{said}");
        assert!(said.contains("`march at 111.0000`"), "{said}");
        rows.push(row(UNSTABLE_TAIL + 2, 112.0, None));
        assert_eq!(unstable_tail(&rows, march), None, "a stable point ends it");
    }

    #[test]
    fn a_multiplier_through_minus_one_is_a_period_doubling_located_where_its_modulus_is_one() {
        let pi = std::f64::consts::PI;
        let rows = [
            row(0, 100.0, Some((0.9, pi, Crossing::PeriodDoubling))),
            row(1, 110.0, Some((1.1, pi, Crossing::PeriodDoubling))),
            row(2, 120.0, Some((1.3, pi, Crossing::PeriodDoubling))),
            row(3, 130.0, Some((0.7, pi, Crossing::PeriodDoubling))),
        ];
        let b = locate(&rows, &[]);
        assert_eq!(b.len(), 2);
        assert_eq!(b[0].kind, BifurcationKind::PeriodDoubling);
        assert!((b[0].frequency_hz - 105.0).abs() < 1e-9);
        assert!(b[0].loses && !b[1].loses);
        assert_eq!(b[0].between, [0, 1]);
        assert!((b[0].new_frequency_hz.unwrap_or(0.0) - 52.5).abs() < 1e-9);
        // |μ| 1.3 → 0.7 crosses 1 half way.
        assert!((b[1].frequency_hz - 125.0).abs() < 1e-9);
    }

    #[test]
    fn a_change_at_a_located_fold_is_the_folds_and_a_constant_contact_side_makes_a_grazing() {
        let rows = [
            row(0, 100.0, None),
            row(1, 110.0, Some((1.2, 0.5, Crossing::NeimarkSacker))),
            row(2, 120.0, Some((0.8, 0.5, Crossing::NeimarkSacker))),
            row(3, 130.0, Some((0.8, 0.0, Crossing::Fold))),
            row(4, 125.0, Some((1.2, 0.0, Crossing::Fold))),
        ];
        let fold = FoldReport {
            frequency_hz: 130.0,
            after: 3,
            amplitude: 3.0,
        };
        let b = locate(&rows, &[fold]);
        assert_eq!(b.len(), 2, "{b:?}");
        assert_eq!(b[0].kind, BifurcationKind::Grazing);
        assert!((b[0].frequency_hz - 105.0).abs() < 1e-9);
        assert_eq!(b[1].kind, BifurcationKind::NeimarkSacker);
        let expected = 0.5 / (2.0 * std::f64::consts::PI) * 115.0;
        assert!((b[1].new_frequency_hz.unwrap_or(0.0) - expected).abs() < 1e-9);
    }

    #[test]
    fn a_real_crossing_of_plus_one_is_a_kink_where_the_curve_turns_and_a_branch_point_elsewhere() {
        let fold = |m: f64| Some((m, 0.0, Crossing::Fold));
        let rows = [
            turning(0, 100.0, fold(0.9), 1.0),
            turning(1, 101.0, fold(1.1), 1.0),
            turning(2, 100.5, fold(0.9), -1.0),
            turning(3, 99.0, fold(0.8), -1.0),
            turning(4, 98.0, fold(0.8), -1.0),
            turning(5, 97.0, fold(1.2), -1.0),
        ];
        let b = locate(&rows, &[]);
        let kinds: Vec<_> = b.iter().map(|b| b.kind).collect();
        assert_eq!(
            kinds,
            [
                BifurcationKind::Kink,
                BifurcationKind::Kink,
                BifurcationKind::BranchPoint
            ]
        );
        assert!(b.iter().all(|b| b.new_frequency_hz.is_none()));
    }
}
