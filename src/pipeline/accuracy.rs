//! What accuracy costs: one scene run over a ladder of settings (harmonics H, samples N, mesh
//! size, element order), each compared with the most expensive rung as the reference, with
//! the wall time it took. Written as `accuracy.csv`, a Markdown table on stdout and
//! `accuracy.svg` (error against wall time, log–log).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{run, RunOptions, Summary};
use crate::config::{load_pipeline, Pipeline};
use crate::output::tables::write_csv;
use crate::progress::{Reporter, Silent};
use crate::{Error, Result};

/// One axis of the study: a pipeline key and the values to try (cheapest first).
#[derive(Clone, Debug)]
pub struct Ladder {
    pub key: String,
    pub values: Vec<String>,
}

#[derive(Clone, Debug)]
pub struct Rung {
    pub key: String,
    pub value: String,
    pub seconds: f64,
    pub probe_amplitude: f64,
    pub error: f64,
    pub complementarity: Option<f64>,
    pub newton_iterations: Option<u64>,
    pub dofs: u64,
}

/// The error measure: the first probe's larger first-harmonic amplitude, smooth in the
/// settings, unlike a peak value that follows the Gibbs ripples of a truncated series.
fn probe_amplitude(p: &Pipeline, summary: &Summary) -> f64 {
    p.output
        .probes
        .first()
        .and_then(|name| summary.probes.get(name))
        .map_or(f64::NAN, |a| a.first_harmonic())
}

fn run_one(
    path: &Path,
    overrides: &[String],
    out: PathBuf,
    reporter: &dyn Reporter,
) -> Result<(f64, f64, Summary)> {
    let p: Pipeline = load_pipeline(path, overrides)?;
    if p.output.probes.is_empty() {
        return Err(Error::Config {
            path: path.to_path_buf(),
            message:
                "output.probes: the accuracy study measures a probe's amplitude; name a probe group"
                    .into(),
        });
    }
    let options = RunOptions {
        out: Some(out),
        ..Default::default()
    };
    let summary = run(&p, &options, reporter)?.summary;
    // What the setting costs: every stage but meshing, which a study's cache makes free.
    let st = &summary.stage_seconds;
    let secs = st.total() - st.get("mesh");
    Ok((secs, probe_amplitude(&p, &summary), summary))
}

/// Run every ladder (each varying one key, the others at the pipeline's values) and compare
/// each rung with that ladder's last (most expensive) rung. The runs themselves report to
/// `Silent`; `reporter` sees one step per rung.
pub fn study(
    path: &Path,
    base: &[String],
    ladders: &[Ladder],
    out: &Path,
    reporter: &dyn Reporter,
) -> Result<Vec<Rung>> {
    let mut rungs = Vec::new();
    let total = ladders.iter().map(|l| l.values.len()).sum::<usize>() as u64;
    let mut done = 0;
    for ladder in ladders {
        let mut rows = Vec::new();
        for value in &ladder.values {
            let mut overrides = base.to_vec();
            overrides.push(format!("{}={}", ladder.key, value));
            let tag = format!(
                "{}-{}",
                ladder.key.replace('.', "_"),
                value.replace(['/', ' '], "_")
            );
            reporter.progress(
                "accuracy",
                done,
                Some(total),
                &format!("{} = {value}", ladder.key),
            );
            let row = run_one(path, &overrides, out.join("runs").join(tag), &Silent)?;
            done += 1;
            rows.push((value.clone(), row));
        }
        let Some((_, (_, a_ref, _))) = rows.last() else {
            continue;
        };
        let a_ref = *a_ref;
        for (value, (secs, a, s)) in &rows {
            let contact = s.contact.as_ref().and_then(|c| c.solver.as_ref());
            rungs.push(Rung {
                key: ladder.key.clone(),
                value: value.clone(),
                seconds: *secs,
                probe_amplitude: *a,
                error: ((a - a_ref) / a_ref).abs(),
                complementarity: contact.map(|c| c.complementarity.violation),
                newton_iterations: contact.map(|c| c.newton_iterations as u64),
                dofs: s.sizes.free_dofs as u64,
            });
        }
    }
    reporter.task_done("accuracy");
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let header: Vec<String> = [
        "ladder_value",
        "seconds",
        "probe_amplitude",
        "relative_error",
        "complementarity_violation",
        "newton_iterations",
        "free_dofs",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let rows: Vec<Vec<f64>> = rungs
        .iter()
        .map(|r| {
            vec![
                r.value.parse().unwrap_or(f64::NAN),
                r.seconds,
                r.probe_amplitude,
                r.error,
                r.complementarity.unwrap_or(f64::NAN),
                r.newton_iterations.map_or(f64::NAN, |v| v as f64),
                r.dofs as f64,
            ]
        })
        .collect();
    write_csv(&out.join("accuracy.csv"), &header, &rows)?;
    let svg = plot(&rungs);
    let tmp = out.join(format!("accuracy.svg.tmp-{}", std::process::id()));
    std::fs::write(&tmp, svg).map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, out.join("accuracy.svg"))
        .map_err(|e| Error::io(out.join("accuracy.svg"), e))?;
    Ok(rungs)
}

/// A Markdown table of the study.
pub fn table(rungs: &[Rung]) -> String {
    let mut s = String::from("| setting | value | wall time [s] | probe 1st-harmonic amplitude | error vs last rung | complementarity | Newton its | free dofs |\n|---|---|---|---|---|---|---|---|\n");
    for r in rungs {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.6e} | {:.2e} | {} | {} | {} |",
            r.key,
            r.value,
            r.seconds,
            r.probe_amplitude,
            r.error,
            r.complementarity.map_or("-".into(), |v| format!("{v:.2e}")),
            r.newton_iterations.map_or("-".into(), |v| v.to_string()),
            r.dofs
        );
    }
    s
}

/// Error against wall time, log–log, one polyline per ladder (the reference rung, error 0,
/// is left out).
pub fn plot(rungs: &[Rung]) -> String {
    let pts: Vec<&Rung> = rungs
        .iter()
        .filter(|r| r.error > 0.0 && r.seconds > 0.0)
        .collect();
    let (w, h, m) = (640.0, 420.0, 60.0);
    let lx = |v: f64| v.log10();
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for r in &pts {
        x0 = x0.min(lx(r.seconds));
        x1 = x1.max(lx(r.seconds));
        y0 = y0.min(lx(r.error));
        y1 = y1.max(lx(r.error));
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (-2.0, 1.0, -6.0, 0.0);
    }
    let (x0, x1) = (x0.floor(), x1.ceil().max(x0.floor() + 1.0));
    let (y0, y1) = (y0.floor(), y1.ceil().max(y0.floor() + 1.0));
    let px = |v: f64| m + (lx(v) - x0) / (x1 - x0) * (w - 2.0 * m);
    let py = |v: f64| h - m - (lx(v) - y0) / (y1 - y0) * (h - 2.0 * m);
    let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
    let _ = writeln!(
        s,
        "<rect x=\"{m}\" y=\"{m}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>",
        w - 2.0 * m,
        h - 2.0 * m
    );
    for d in (x0 as i32)..=(x1 as i32) {
        let x = m + (d as f64 - x0) / (x1 - x0) * (w - 2.0 * m);
        let _ = writeln!(
            s,
            "<text x=\"{x}\" y=\"{}\" text-anchor=\"middle\">1e{d}</text>",
            h - m + 16.0
        );
    }
    for d in (y0 as i32)..=(y1 as i32) {
        let y = h - m - (d as f64 - y0) / (y1 - y0) * (h - 2.0 * m);
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{y}\" text-anchor=\"end\">1e{d}</text>",
            m - 6.0
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">wall time [s]</text>",
        w / 2.0,
        h - 16.0
    );
    let _ = writeln!(s, "<text x=\"16\" y=\"{}\" transform=\"rotate(-90 16 {})\" text-anchor=\"middle\">relative error of the probe amplitude</text>", h / 2.0, h / 2.0);
    let colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"];
    let mut keys: Vec<&str> = pts.iter().map(|r| r.key.as_str()).collect();
    keys.dedup();
    for (i, key) in keys.iter().enumerate() {
        let colour = colours[i % colours.len()];
        let line: Vec<String> = pts
            .iter()
            .filter(|r| r.key == *key)
            .map(|r| format!("{:.1},{:.1}", px(r.seconds), py(r.error)))
            .collect();
        let _ = writeln!(
            s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\"/>",
            line.join(" ")
        );
        for r in pts.iter().filter(|r| r.key == *key) {
            let _ = writeln!(s, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"{colour}\"><title>{} = {}</title></circle>", px(r.seconds), py(r.error), r.key, r.value);
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" fill=\"{colour}\">{}</text>",
                px(r.seconds) + 6.0,
                py(r.error) - 6.0,
                r.value
            );
        }
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" fill=\"{colour}\">{key}</text>",
            w - m - 150.0,
            m + 18.0 + 16.0 * i as f64
        );
    }
    s.push_str("</svg>\n");
    s
}
