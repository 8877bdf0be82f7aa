//! The plots a run draws into `plots/` of its output directory, SVG and PNG each, through
//! `output::plot` (`compare` draws its overlays with the same axes and styles).
//!
//! Per run, over the one period it writes (harmonic balance: the steady period at the
//! history's N samples; time marching: the last marched period):
//! - `probe_<group>`: the mean displacement u_x(t), u_y(t) [m] of each probe group;
//! - `contact_force` (contact scenes): the total pressing force of the contact law
//!   F(t) = Σ_i F_i(t), F_i = max(0, c g_i − λ_i) [N] (≥ 0, what `contact.csv` holds), and
//!   dashed the raw Fourier series −Σ_i λ_i(t) (harmonic balance: where it dips below zero
//!   is the truncation ripple); time marching: F at every step, and at the output frames;
//! - `contact_pressure` (contact scenes): p_i = F_i / (L_i × thickness) [Pa] against the arc
//!   length s_i along the contact boundary [m] (`contact::geometry::arc_lengths`), at the
//!   history instant of the largest total force (time marching: the output frame of the
//!   largest total force; per-node forces are kept only at the frames), its values also in
//!   `contact_pressure.csv`;
//! - `friction_loop` (frictional harmonic balance): the tangential force λ_t(t) against the
//!   tangential displacement w(t) at the contact node that dissipates most, whose enclosed
//!   area is its energy per period.
//!
//! Glossary: t/T time over the period T = 1/f; λ_i the contact multipliers (≤ 0 pressing);
//! g_i the normal gap (> 0 penetrating); L_i the tributary boundary length of node i.
//! Every curve is closed over the period: its first sample is repeated at t/T = 1.

use std::path::{Path, PathBuf};

use super::late::LateSignals;
use super::model::Model;
use super::report::{nodal_pressure, Sampled};
use crate::contact::geometry::arc_lengths;
use crate::output::plot::{tick, Axis, Figure, Style};
use crate::output::tables::write_csv;
use crate::transient::characterize::amplitude_spectrum;
use crate::{Error, Result};

/// Histories with at least this many points are drawn as plain curves, shorter ones with a
/// marker at every sample (the time-marching frames).
const DENSE: usize = 64;

pub(super) fn style(points: usize) -> Style {
    if points >= DENSE {
        Style::Curve
    } else {
        Style::Line
    }
}

pub(super) fn time_axis(period: f64) -> Axis {
    Axis::linear(format!("t/T [-], period T = {} s", tick(period)))
}

/// (t/T, v) points closed over the period.
pub(super) fn over_period(times: &[f64], values: &[f64], period: f64) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = times
        .iter()
        .zip(values)
        .map(|(&t, &v)| (t / period, v))
        .collect();
    if let Some(&(t0, v0)) = pts.first() {
        pts.push((t0 + 1.0, v0));
    }
    pts
}

/// Draw the run's plots into `dir` (created); returns the files written. `boundary` is the
/// contact boundary group (contact scenes).
pub fn write_run_plots(
    dir: &Path,
    model: &Model,
    sampled: &Sampled,
    boundaries: &[&str],
    period: f64,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut figures = probe_figures(model, sampled, period);
    if let Some(c) = &model.contact {
        if !sampled.history.contact.is_empty() {
            let unit = model.material.force_unit();
            figures.push(("contact_force".into(), force_figure(sampled, period, unit)));
            let mut offset = 0;
            for (j, (pair, boundary)) in c.pairs.iter().zip(boundaries).enumerate() {
                let rows = offset..offset + pair.nodes.len();
                offset = rows.end;
                let (fig, rows) = pressure_figure(model, sampled, boundary, rows, period);
                let header = ["node", "arc_length", "pressure", "force", "opening"];
                let header: Vec<String> = header.iter().map(|h| h.to_string()).collect();
                let stem = match boundaries.len() {
                    1 => "contact_pressure".to_string(),
                    _ => format!("contact_pressure_{j}_{}", file_safe(boundary)),
                };
                write_csv(&dir.join(format!("{stem}.csv")), &header, &rows)?;
                figures.push((stem, fig));
            }
        }
    }
    if let Some(l) = &sampled.friction_loop {
        let unit = model.material.force_unit();
        figures.push(("friction_loop".into(), friction_loop_figure(l, unit)));
    }
    let mut files = Vec::new();
    for (stem, fig) in figures {
        fig.save(&dir.join(&stem))?;
        files.extend(["svg", "png"].map(|ext| dir.join(format!("{stem}.{ext}"))));
    }
    Ok(files)
}

/// The hysteresis loop λ_t(w) of the contact node that dissipates most (closed over the
/// period); its area is the energy the node dissipates per period.
fn friction_loop_figure(l: &super::report::FrictionLoop, unit: &str) -> Figure {
    let mut points: Vec<(f64, f64)> = l
        .slip
        .iter()
        .copied()
        .zip(l.force.iter().copied())
        .collect();
    if let Some(&first) = points.first() {
        points.push(first);
    }
    let title = format!(
        "friction loop of contact node {}: {} J per period",
        l.node,
        tick(l.energy)
    );
    let x = Axis::linear("tangential displacement w relative to the obstacle [m]");
    let y = Axis::linear(format!("tangential force λ_t on the body [{unit}]"));
    Figure::new(title, x, y).add(format!("node {}", l.node), points, style(l.slip.len()))
}

/// The probe plot's title: the group named once ("probe: …" for a group called `probe`,
/// "probe tip: …" for a group `tip`).
fn probe_title(name: &str) -> String {
    format!("{}: mean displacement over one period", probe_label(name))
}

/// A probe group in words, named once: "probe" for a group called `probe`, "probe tip" for a
/// group `tip` (plots and the run's headline).
pub fn probe_label(name: &str) -> String {
    if name.to_lowercase().contains("probe") {
        name.to_string()
    } else {
        format!("probe {name}")
    }
}

/// `probe_<group>`: each probe group's mean u_x and u_y over the period.
fn probe_figures(model: &Model, sampled: &Sampled, period: f64) -> Vec<(String, Figure)> {
    let h = &sampled.history;
    model
        .probes
        .iter()
        .zip(&h.probe_means)
        .map(|((name, _), [x, y])| {
            let s = style(h.times.len());
            let fig = Figure::new(
                probe_title(name),
                time_axis(period),
                Axis::linear("displacement [m]"),
            )
            .add("u_x", over_period(&h.times, x, period), s)
            .add("u_y", over_period(&h.times, y, period), s);
            (format!("probe_{name}"), fig)
        })
        .collect()
}

/// `contact_force`: the law's total force and (dashed) the raw series, or for time marching
/// the force at every step and at the frames.
fn force_figure(sampled: &Sampled, period: f64, unit: &str) -> Figure {
    let h = &sampled.history;
    let fig = Figure::new(
        "total contact force over one period",
        time_axis(period),
        Axis::linear(format!("total contact force [{unit}]")),
    );
    let law = over_period(&h.times, &h.total_force(), period);
    match &sampled.steps {
        Some(steps) => fig
            .curve(
                "contact law, every time step",
                over_period(&steps.times, &steps.total_force, period),
            )
            .scatter("contact law, output frames", law),
        None => fig.curve("contact law max(0, c g - λ)", law).dashed(
            "Fourier series of λ",
            over_period(&h.times, &h.total_force_series(), period),
        ),
    }
}

/// A group name as a file-name part: letters, digits, `-` and `_` kept, the rest `_`.
fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `contact_pressure`: the pressure along one pair's boundary (its contact rows `pair`) at
/// the instant of the largest total force, and its rows (node, s, p, F, opening) sorted by
/// arc length.
fn pressure_figure(
    model: &Model,
    sampled: &Sampled,
    boundary: &str,
    pair: std::ops::Range<usize>,
    period: f64,
) -> (Figure, Vec<Vec<f64>>) {
    let h = &sampled.history;
    let totals = h.total_force();
    let peak = (0..totals.len())
        .max_by(|&a, &b| totals[a].total_cmp(&totals[b]))
        .unwrap_or(0);
    let state = &h.contact[peak];
    let nodes = model
        .contact
        .as_ref()
        .map_or(&[][..], |c| &c.set.nodes[pair.clone()]);
    let s = arc_lengths(&model.mesh, boundary, nodes);
    let mut rows: Vec<Vec<f64>> = nodes
        .iter()
        .zip(pair)
        .enumerate()
        .map(|(j, (&n, i))| {
            let f = state.force[i];
            vec![
                n as f64,
                s[j],
                nodal_pressure(model, i, f),
                f,
                -state.gap[i],
            ]
        })
        .collect();
    rows.sort_by(|a, b| a[1].total_cmp(&b[1]));
    let instant = if sampled.steps.is_some() {
        "the output frame of largest total force"
    } else {
        "the largest total force"
    };
    let fig = Figure::new(
        format!(
            "contact pressure at t/T = {:.3}, {instant} ({:.4e} N)",
            h.times[peak] / period,
            totals[peak]
        ),
        Axis::linear(format!("arc length along {boundary} [m]")),
        Axis::linear("contact pressure [Pa]"),
    )
    .line("contact law", rows.iter().map(|r| (r[1], r[2])).collect())
    .from_zero();
    (fig, rows)
}

/// The late response of a march (`late::LateSignals`, the last whole periods as window
/// means): `spectrum`, the probes' amplitude spectra A(ν) [m] against ν = frequency/f (Hann
/// window, resolution f/L, lines up to 10 f or the record's Nyquist frequency; log axis down
/// to 10⁻⁶ of the largest line); `late_response`, the probes' u over the L periods against
/// t/T; `late_contact_force` (contact scenes), the total contact force over them. Returns
/// the files written into `dir` (created).
pub fn write_late_plots(
    dir: &Path,
    signals: &LateSignals,
    (f, unit): (f64, &str),
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let periods = signals.periods;
    let mut figures = vec![("spectrum", late_spectrum(signals, f))];
    let t_axis = || {
        Axis::linear(format!(
            "t/T [-] from the start of the march, T = {} s",
            tick(1.0 / f)
        ))
    };
    let over = |v: &[f64]| -> Vec<(f64, f64)> {
        signals
            .times
            .iter()
            .zip(v)
            .map(|(&t, &y)| (t * f, y))
            .collect()
    };
    let mut history = Figure::new(
        format!(
            "probes over the last {periods} periods (means over T/{})",
            signals.samples_per_period
        ),
        t_axis(),
        Axis::linear("displacement [m]"),
    );
    for (label, v) in signals.probes() {
        history = history.curve(label, over(v));
    }
    figures.push(("late_response", history));
    let force = signals
        .labels
        .iter()
        .zip(&signals.values)
        .find(|((_, u), _)| *u == "N");
    if let Some(((label, _), v)) = force {
        let fig = Figure::new(
            format!(
                "total contact force over the last {periods} periods (means over T/{})",
                signals.samples_per_period
            ),
            t_axis(),
            Axis::linear(format!("total contact force [{unit}]")),
        )
        .curve(label.as_str(), over(v));
        figures.push(("late_contact_force", fig));
    }
    let mut files = Vec::new();
    for (stem, fig) in figures {
        fig.save(&dir.join(stem))?;
        files.extend(["svg", "png"].map(|ext| dir.join(format!("{stem}.{ext}"))));
    }
    Ok(files)
}

/// `spectrum`: each probe signal's amplitude spectrum, log amplitude.
fn late_spectrum(signals: &LateSignals, f: f64) -> Figure {
    let periods = signals.periods.max(1);
    let spectra: Vec<(&str, Vec<(f64, f64)>)> = signals
        .probes()
        .map(|(label, v)| (label, amplitude_spectrum(v, periods)))
        .collect();
    let largest = spectra
        .iter()
        .flat_map(|(_, s)| s.iter().skip(1).map(|p| p.1))
        .fold(0.0f64, f64::max);
    let floor = 1e-6 * largest;
    let mut fig = Figure::new(
        format!(
            "probe spectrum over the last {periods} periods (resolution f/{periods}, f = {} Hz)",
            tick(f)
        ),
        Axis::linear("frequency / drive frequency f [-]"),
        Axis::log("amplitude [m]"),
    );
    for (label, s) in spectra {
        let points = s
            .into_iter()
            .skip(1)
            .take_while(|p| p.0 <= 10.0)
            .map(|(nu, a)| (nu, a.max(floor)))
            .collect();
        fig = fig.curve(label, points);
    }
    fig
}
