//! How the command line shows a study: counts, timings, where the table went, and for accuracy
//! studies the Markdown table and the cheapest settings meeting `--tolerance`.

use hbcontact::study::accuracy::AccuracyReport;
use hbcontact::study::StudyReport;

pub fn show_study(report: &StudyReport) {
    if let Some(e) = &report.execution {
        eprintln!(
            "ran {} points ({} done before, skipped) on {} threads; meshing {} geometries took {:.2} s, the points {:.2} s",
            e.ran, e.skipped, e.threads, e.geometries, e.meshing_seconds, e.points_seconds
        );
    }
    match &report.table {
        Some(table) => eprintln!(
            "{} points: {} ok{}, {} failed, {} missing; wrote {} (plots and manifest.json beside it)",
            report.points,
            report.ok,
            warned(report.warned),
            report.failed,
            report.missing,
            table.display()
        ),
        None => eprintln!(
            "shard done ({} points); join the shards with --merge",
            report.points
        ),
    }
}

/// " (3 of them warned: see the table's warnings column)", or nothing.
fn warned(n: usize) -> String {
    match n {
        0 => String::new(),
        _ => format!(" ({n} of them warned: see the table's warnings column)"),
    }
}

/// "; as cheap within the timing noise: harmonics = 20", or nothing: rungs whose wall times
/// are within `TIME_NOISE` of each other are not ranked by them (the earliest in the study's
/// order is named).
fn tied_note(tied: &[String]) -> String {
    match tied {
        [] => String::new(),
        _ => format!(
            "; as cheap within the timing noise (×{}): {}",
            hbcontact::study::accuracy::TIME_NOISE,
            tied.join(", ")
        ),
    }
}

/// The accuracy table on stdout.
pub fn show_accuracy(report: &AccuracyReport) {
    outln!("errors against {}", report.reference_name());
    outln!("{}", report.markdown());
    for note in report.warning_notes() {
        outln!("{note}");
    }
}

/// The cheapest rung meeting the tolerance, per measure.
pub fn show_tolerance(report: &AccuracyReport, tolerance: f64) {
    outln!("cheapest setting with relative error ≤ {tolerance:e}:");
    for c in report.cheapest(tolerance) {
        match c.rung {
            Some((key, value, error, secs, memory)) => outln!(
                "  {:<22} {key} = {value} (error {error:.2e}, {secs:.3} s, {}){}{}",
                c.measure,
                if memory.is_finite() {
                    format!("peak memory {memory:.0} MB")
                } else {
                    "peak memory not measured".into()
                },
                tied_note(&c.tied),
                if c.warned {
                    "; this rung warned (above)"
                } else {
                    ""
                }
            ),
            None => outln!("  {:<22} no rung meets it", c.measure),
        }
    }
}
