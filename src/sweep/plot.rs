//! The sweep's plots, SVG and PNG through `output::plot`:
//! - `sweep`: the probe's first-harmonic amplitude |û_1| [m] against the frequency f [Hz];
//! - `sweep_force` (contact scenes): the peak total contact force max_t Σ_i F_i(t) [N]
//!   against f.
//!
//! Both follow the rows in curve order (through the folds, so f runs back on a branch):
//! solid where the point is stable or unchecked (`stable` None), dashed where it is unstable
//! (a dashed piece starts at the last stable point, so the curve has no gap). Every fold is a
//! black triangle labelled `fold K: f Hz` on the curve; every bifurcation
//! (`sweep::bifurcations`) a glyph of its kind where it was located, labelled `PD f Hz`
//! (period doubling, disc), `NS f Hz` (Neimark–Sacker, square), `BP f Hz` (branch point,
//! diamond), `G f Hz` (grazing, ring), `S f Hz` (judged by marching, ring), kinks an unlabelled
//! cross. Labels are placed where they overlap no other (`output::plot`). A contact sweep's
//! `sweep` also draws the probe's linear response with the contact open (dashed grey, up to
//! twice the curve's peak; `sweep::reference`) and, where the probe sits on the contact, its
//! gap as a horizontal line. Rows a warning names (`WARNED`) are marked. The 2T branches of
//! `sweep.follow_period_doubling` are drawn in a second colour, solid and dashed alike.

use std::path::Path;

use super::bifurcations::{BifurcationKind, BifurcationReport};
use super::{FoldReport, SweepRow, SweepSummary};
use crate::output::plot::{Axis, Figure, Shape, Style};
use crate::Result;

/// Draw `sweep` and, with a contact force column holding values, `sweep_force` into `dir`
/// (its forces in `force_unit`, `Material::force_unit`).
pub fn write_plots(dir: &Path, s: &SweepSummary, force_unit: &str) -> Result<()> {
    let column = |name: &str| s.columns.iter().position(|c| c == name);
    let force_label = format!("peak contact force [{force_unit}]");
    let figures = [
        (
            "sweep",
            column("probe_first_harmonic"),
            "probe first-harmonic amplitude [m]",
            "probe first-harmonic amplitude against frequency",
        ),
        (
            "sweep_force",
            column("peak_contact_force"),
            force_label.as_str(),
            "peak total contact force against frequency",
        ),
    ];
    for (stem, column, y_label, title) in figures {
        let Some(c) = column else { continue };
        if !s.rows.iter().any(|r| r.values[c].is_finite()) {
            continue;
        }
        let title = format!("{}: {title} ({})", s.name, s.resolution());
        let mut figure = response_figure(&title, y_label, &s.rows, c, &s.folds);
        if stem == "sweep" {
            figure = with_reference(figure, s, c);
        }
        figure = with_branches(figure, s, c);
        figure = with_other_end(figure, s, c);
        let warned: Vec<(f64, f64)> = (s.rows.iter())
            .filter(|r| s.warned(r))
            .map(|r| (r.frequency_hz, r.values[c]))
            .collect();
        if !warned.is_empty() {
            figure = figure.scatter(WARNED, warned).colour(3);
        }
        with_bifurcations(figure, &s.rows, c, &s.bifurcations).save(&dir.join(stem))?;
    }
    Ok(())
}

/// Column `c` of the rows against frequency, in stable (solid) and unstable (dashed) pieces
/// of one colour, with the folds marked.
fn response_figure(
    title: &str,
    y_label: &str,
    rows: &[SweepRow],
    c: usize,
    folds: &[FoldReport],
) -> Figure {
    let mut fig = Figure::new(title, Axis::linear("frequency [Hz]"), Axis::linear(y_label));
    let checked = rows.iter().any(|r| r.stable.is_some());
    let (mut solid_labelled, mut dashed_labelled) = (false, false);
    for (unstable, points) in pieces(rows, c) {
        let (style, label) = if unstable {
            let l = if dashed_labelled { "" } else { "unstable" };
            dashed_labelled = true;
            (Style::Dashed, l)
        } else {
            let l = match (solid_labelled, checked) {
                (true, _) => "",
                (false, true) => "stable",
                (false, false) => "response (stability not checked)",
            };
            solid_labelled = true;
            (Style::Curve, l)
        };
        fig = fig.add(label, points, style).colour(0);
    }
    for (k, f) in folds.iter().enumerate() {
        if let Some(r) = rows.iter().find(|r| r.index == f.after) {
            let label = format!("fold {}: {:.1} Hz", k + 1, r.frequency_hz);
            fig = fig.mark(label, (r.frequency_hz, r.values[c]));
        }
    }
    fig
}

/// The bifurcations marked on column `c`'s curve, at their located frequency (the column
/// interpolated between their two rows).
fn with_bifurcations(
    mut fig: Figure,
    rows: &[SweepRow],
    c: usize,
    bifurcations: &[BifurcationReport],
) -> Figure {
    for b in bifurcations {
        let row = |i: usize| rows.iter().find(|r| r.index == i);
        let (Some(a), Some(z)) = (row(b.between[0]), row(b.between[1])) else {
            continue;
        };
        let span = z.frequency_hz - a.frequency_hz;
        let t = if span.abs() > 0.0 {
            (b.frequency_hz - a.frequency_hz) / span
        } else {
            0.5
        };
        let y = a.values[c] + t * (z.values[c] - a.values[c]);
        let shape = match b.kind {
            BifurcationKind::PeriodDoubling => Shape::Disc,
            BifurcationKind::NeimarkSacker => Shape::Square,
            BifurcationKind::BranchPoint => Shape::Diamond,
            BifurcationKind::Grazing | BifurcationKind::Unclassified => Shape::Ring,
            BifurcationKind::Kink => Shape::Cross,
        };
        let label = match b.kind {
            BifurcationKind::Kink => String::new(),
            k => format!("{} {:.1} Hz", k.tag(), b.frequency_hz),
        };
        fig = fig.mark_as(label, (b.frequency_hz, y), shape);
    }
    fig
}

/// The linear reference, dashed grey, clipped above `REFERENCE_CLIP` times the curve's peak
/// (a lightly damped linear peak would flatten the curve), and the probe's gap as a
/// horizontal line across the band.
fn with_reference(mut fig: Figure, s: &SweepSummary, c: usize) -> Figure {
    let peak = s.rows.iter().map(|r| r.values[c]).fold(0.0, f64::max);
    if let Some(r) = &s.linear_reference {
        let cap = REFERENCE_CLIP * peak;
        let mut label = "linear, contact open";
        let mut piece = Vec::new();
        let points = r.frequency_hz.iter().zip(&r.probe_first_harmonic);
        for (f, a) in points.map(|(f, a)| (*f, a.filter(|a| *a <= cap))) {
            match a {
                Some(a) => piece.push((f, a)),
                None if piece.len() > 1 => {
                    fig = fig.dashed(label, std::mem::take(&mut piece)).grey();
                    label = "";
                }
                None => piece.clear(),
            }
        }
        if piece.len() > 1 {
            fig = fig.dashed(label, piece).grey();
        }
    }
    if let (Some(g), Some(first), Some(last)) = (s.probe_gap, s.rows.first(), s.rows.last()) {
        let (lo, hi) = (
            first.frequency_hz.min(s.from_hz),
            last.frequency_hz.max(s.to_hz),
        );
        let label = format!("gap at the probe: {} m", crate::output::plot::tick(g));
        fig = fig.dashed(label, vec![(lo, g), (hi, g)]).colour(2);
    }
    fig
}

/// The 2T branches (`sweep::branch`) in a colour of their own, solid where stable and dashed
/// where not, like the curve; at the drive frequency, so they meet it at the period doublings.
fn with_branches(mut fig: Figure, s: &SweepSummary, c: usize) -> Figure {
    for b in &s.branches {
        let label = format!("2T branch from PD {:.1} Hz", b.from_hz);
        fig = with_curve(fig, (&b.rows, c), label, 1);
    }
    fig
}

/// Column `c` of `rows` in colour `colour`, solid where stable and dashed where not, labelled
/// once.
fn with_curve(
    mut fig: Figure,
    (rows, c): (&[SweepRow], usize),
    mut label: String,
    colour: usize,
) -> Figure {
    for (unstable, points) in pieces(rows, c) {
        let style = if unstable {
            Style::Dashed
        } else {
            Style::Curve
        };
        fig = fig
            .add(std::mem::take(&mut label), points, style)
            .colour(colour);
    }
    fig
}

/// The curve swept from the other end of the range (`other_end`) in a colour of its own,
/// solid where stable and dashed where not, its folds marked.
fn with_other_end(mut fig: Figure, s: &SweepSummary, c: usize) -> Figure {
    let Some(other) = &s.from_the_end else {
        return fig;
    };
    let label = format!("swept from {:.1} Hz", other.from_hz);
    fig = with_curve(fig, (&other.rows, c), label, 4);
    for f in &other.folds {
        if let Some(r) = other.rows.iter().find(|r| r.index == f.after) {
            let label = format!("fold: {:.1} Hz", r.frequency_hz);
            fig = fig.mark(label, (r.frequency_hz, r.values[c]));
        }
    }
    fig
}

/// The legend of the rows a warning of sweep.json names (a spline curve's rows whose
/// vibration lies in the basis' underdamped frequencies).
pub const WARNED: &str = "warned (sweep.json says of what)";

/// The linear reference is drawn up to this multiple of the curve's peak.
const REFERENCE_CLIP: f64 = 2.0;

/// Runs of consecutive rows of one kind (unstable or not) as (unstable, points); an unstable
/// run begins with the point before it and a stable run after an unstable one begins with
/// that run's last point, so the pieces join.
fn pieces(rows: &[SweepRow], c: usize) -> Vec<(bool, Vec<(f64, f64)>)> {
    let mut out: Vec<(bool, Vec<(f64, f64)>)> = Vec::new();
    let mut last: Option<(f64, f64)> = None;
    for r in rows {
        let p = (r.frequency_hz, r.values[c]);
        let unstable = r.stable == Some(false);
        match out.last_mut() {
            Some((kind, points)) if *kind == unstable => points.push(p),
            _ => {
                let mut points: Vec<(f64, f64)> = last.into_iter().collect();
                points.push(p);
                out.push((unstable, points));
            }
        }
        last = Some(p);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hbm::continuation::Corrector;

    fn row(index: usize, stable: Option<bool>) -> SweepRow {
        SweepRow {
            values: vec![index as f64],
            corrector: Corrector::FixedFrequency,
            stable,
            ..SweepRow::for_tests(index, 100.0 + index as f64)
        }
    }

    /// TEST GOAL: a curve with an unstable stretch is drawn as solid, dashed, solid pieces
    /// that join (each piece starts at the previous piece's last point), labelled once each
    /// ("stable", "unstable"), all in one colour; unchecked points count as solid.
    #[test]
    fn unstable_points_are_a_dashed_piece_joined_to_the_solid_ones() {
        let stability = [None, Some(true), Some(false), Some(false), Some(true), None];
        let rows: Vec<SweepRow> = (0..6).map(|i| row(i, stability[i])).collect();
        let ys = |points: &[(f64, f64)]| -> Vec<f64> { points.iter().map(|p| p.1).collect() };
        let p = pieces(&rows, 0);
        assert_eq!(p.len(), 3);
        assert_eq!((p[0].0, ys(&p[0].1)), (false, vec![0.0, 1.0]));
        assert_eq!((p[1].0, ys(&p[1].1)), (true, vec![1.0, 2.0, 3.0]));
        assert_eq!((p[2].0, ys(&p[2].1)), (false, vec![3.0, 4.0, 5.0]));
        let fig = response_figure("t", "y [m]", &rows, 0, &[]);
        let styles: Vec<(Style, &str, Option<usize>)> = fig
            .series
            .iter()
            .map(|s| (s.style, s.label.as_str(), s.colour))
            .collect();
        assert_eq!(
            styles,
            vec![
                (Style::Curve, "stable", Some(0)),
                (Style::Dashed, "unstable", Some(0)),
                (Style::Curve, "", Some(0)),
            ]
        );
        assert!(fig.svg().unwrap().contains("unstable"));
    }
}
