//! What the command line adds to the library: its reporter and how results are shown.

/// `println!` through `print_line`: a closed stdout (`hbcontact schema summary | head -c1`)
/// ends nothing and panics nothing. Defined before the modules so that they see it.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cli::print_line(format_args!($($arg)*))
    };
}

pub mod interrupt;
pub mod reporter;
pub mod study;

/// Write one line to the locked stdout. A reader that went away (BrokenPipe: `| head`) is
/// not an error of ours: the line is dropped and the command ends normally, its exit code
/// being that of its work; any other write error is said once on stderr.
pub fn print_line(args: std::fmt::Arguments) {
    use std::io::Write as _;
    use std::sync::atomic::{AtomicBool, Ordering};
    static WARNED: AtomicBool = AtomicBool::new(false);
    let mut out = std::io::stdout().lock();
    let result = out.write_fmt(args).and_then(|_| out.write_all(b"\n"));
    if let Err(e) = result {
        if e.kind() != std::io::ErrorKind::BrokenPipe && !WARNED.swap(true, Ordering::Relaxed) {
            eprintln!("warning: writing to stdout: {e}");
        }
    }
}

use hbcontact::hbm::IterationLog;
use hbcontact::pipeline::compare::Comparison;
use hbcontact::pipeline::summary::{RunMode, Summary};
use hbcontact::pipeline::{CheckReport, ModesResult, RunResult};

/// After a run: warnings, the contact Newton's log, where the results went and what was
/// simulated (stderr), then the headline (stdout).
/// The end of `hbcontact sweep`: points, folds, where it stopped, wall time.
pub fn show_sweep(result: &hbcontact::sweep::SweepResult) {
    let s = &result.summary;
    outln!(
        "{}: {} points from {:.4} Hz toward {:.4} Hz ({})",
        s.name,
        s.points,
        s.from_hz,
        s.to_hz,
        s.resolution()
    );
    for f in &s.folds {
        outln!(
            "  fold at {:.4} Hz (after point {}), probe first harmonic {:.4e} m",
            f.frequency_hz,
            f.after,
            f.amplitude
        );
    }
    show_bifurcations(&s.bifurcations);
    show_ending(s);
    for (k, b) in s.branches.iter().enumerate() {
        show_branch(k + 1, b);
    }
    if let Some(other) = &s.from_the_end {
        show_other_end(other);
    }
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    let r = &s.reduced_frames;
    if r.dimension > 0 {
        outln!(
            "  frames from a reduced model of dimension {} ({} frames; points re-solved on factored frames: {}; largest backward error {:.1e})",
            r.dimension,
            r.frames,
            r.replaced,
            r.largest_error
        );
    }
    outln!("  wall time: {:.3} s", s.stage_seconds.total());
    outln!(
        "  wrote {}/: sweep.csv, sweep.json, plots, {} frames in frames.pvd, {} point folders",
        result.dir.display(),
        s.frames.len(),
        s.written.len()
    );
}

/// How a sweep's curve ended: swept again, slivers gone round, stopped or at its end.
fn show_ending(s: &hbcontact::sweep::SweepSummary) {
    if let Some(a) = &s.swept_again {
        let kept = if a.kept {
            "this curve"
        } else {
            "the first curve is kept"
        };
        outln!(
            "  swept again from its start with sweep.max_turn = {}° ({kept}): the default steps had stopped at {:.4} Hz after {} points",
            a.max_turn,
            a.first_stop_hz,
            a.first_points
        );
        if let Some(n) = a.finer_samples {
            let kept = if a.finer_kept {
                "this curve"
            } else {
                "the first curve is kept"
            };
            outln!("  stopped again, and swept a third time with harmonic_balance.samples = {n} ({kept})");
        }
    }
    if s.slivers > 0 {
        outln!(
            "  led round {} sliver(s) of the sampled contact law, where the curve ran back along itself",
            s.slivers
        );
    }
    match &s.stopped {
        Some(stop) => outln!(
            "  stopped at {:.4} Hz (point {}, {}): {}",
            stop.frequency_hz,
            stop.point,
            stop.class,
            stop.reason
        ),
        None => outln!("  reached {:.4} Hz", s.to_hz),
    }
}

/// The curve swept from the other end: its points, folds and where it ended.
fn show_other_end(o: &hbcontact::sweep::other_end::FromTheEnd) {
    let folds: Vec<String> = (o.folds.iter())
        .map(|f| format!("{:.4} Hz", f.frequency_hz))
        .collect();
    let ended = match &o.stopped {
        Some(stop) => format!("stopped at {:.4} Hz ({})", stop.frequency_hz, stop.class),
        None => format!("reached {:.4} Hz", o.to_hz),
    };
    outln!(
        "  swept from the other end ({}/): {} points from {:.4} Hz, folds at [{}], {ended}",
        o.folder,
        o.points,
        o.from_hz,
        folds.join(", ")
    );
    if let Some([lo, hi]) = o.untraced_hz {
        outln!("  not traced: {lo:.4}–{hi:.4} Hz, between two stretches of unstable states");
    }
}

/// A 2T branch in one line: where it starts and ends, its largest subharmonic, its stable
/// stretch.
fn show_branch(k: usize, b: &hbcontact::sweep::branch::Branch) {
    let (lo, hi) = (b.rows.iter()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
        (lo.min(r.frequency_hz), hi.max(r.frequency_hz))
    });
    let sub = (b.rows.iter())
        .filter_map(|r| r.subharmonic)
        .fold(0.0, f64::max);
    let stable = b.rows.iter().filter(|r| r.stable == Some(true)).count();
    outln!(
        "  2T branch {k} (branch_{k}.csv) from the period doubling at {:.4} Hz: {} points over {lo:.4}–{hi:.4} Hz, {stable} stable; largest subharmonic (f/2) amplitude {sub:.4e} m; {}",
        b.from_hz,
        b.rows.len(),
        b.ended
    );
}

/// The bifurcations of a sweep, one line each; the kinks in one line.
fn show_bifurcations(list: &[hbcontact::sweep::bifurcations::BifurcationReport]) {
    use hbcontact::sweep::bifurcations::BifurcationKind;
    let (kinks, others): (Vec<_>, Vec<_>) =
        list.iter().partition(|b| b.kind == BifurcationKind::Kink);
    for b in others {
        let checked = match b.confirmed {
            Some(true) => " (confirmed by the 2T problem)",
            Some(false) => " (NOT confirmed by the 2T problem: see the warning)",
            None => "",
        };
        let motion = b.new_frequency_hz.map_or(String::new(), |f| {
            format!(", a motion at {f:.4} Hz{checked}")
        });
        outln!(
            "  {} at {:.4} Hz (between points {} and {}): stability {}, |μ| = {:.4} at {:.1}°{motion}",
            b.kind.describe(),
            b.frequency_hz,
            b.between[0],
            b.between[1],
            if b.loses { "lost" } else { "regained" },
            b.multiplier,
            b.argument_deg
        );
    }
    if !kinks.is_empty() {
        let at: Vec<String> = kinks
            .iter()
            .map(|b| format!("{:.2}", b.frequency_hz))
            .collect();
        outln!(
            "  {} changes of stability where the curve turns within a step (kinks of the sampled contact law) at {} Hz",
            kinks.len(),
            at.join(", ")
        );
    }
}

pub fn show_run(result: &RunResult) {
    let s = &result.summary;
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(solve) = s.contact.as_ref().and_then(|c| c.solver.as_ref()) {
        show_newton_log(&solve.newton_log);
    }
    eprintln!("wrote {}", result.dir.display());
    eprintln!("simulated: {}", s.effects.describe());
    show_headline(s);
}

/// The headline: what an engineer looks at first, from the typed summary.
fn show_headline(s: &Summary) {
    let h = s.headline();
    let mode = match s.mode {
        RunMode::HarmonicBalance => "harmonic balance",
        RunMode::Transient => "time marching",
    };
    outln!("{}: {mode}", s.name);
    if let Some(stability) = &h.stability {
        outln!("  {stability}");
    }
    if let Some(late) = &h.late_response {
        outln!("  {late}");
    }
    if let Some((name, a)) = &h.probe {
        outln!(
            "  {}: first harmonic x {:.4e} m, y {:.4e} m; half peak-to-peak x {:.4e} m, y {:.4e} m",
            crate::pipeline::plots::probe_label(name),
            a.first_harmonic_x,
            a.first_harmonic_y,
            a.half_peak_to_peak_x,
            a.half_peak_to_peak_y
        );
    }
    if let (Some(peak), Some(mean)) = (h.peak_contact_force, h.mean_contact_force) {
        let change = h
            .peak_change_from_half_h
            .map(|c| format!(" ({:+.1}% from H/2 to H)", 100.0 * c))
            .unwrap_or_default();
        outln!("  contact force: peak {peak:.4e} N{change}, mean {mean:.4e} N");
    }
    if let Some((energy, stick, slip)) = h.friction {
        outln!(
            "  friction: {energy:.4e} J dissipated per period; samples stuck {:.1}%, slipping {:.1}%",
            100.0 * stick,
            100.0 * slip
        );
    }
    if let Some(vm) = h.max_von_mises {
        outln!("  max von Mises: {vm:.4e} Pa");
    }
    for r in s.resonance.iter().flat_map(|r| &r.harmonics) {
        if let Some(m) = r.nearest_modes.first() {
            outln!(
                "  harmonic {} ({:.4} Hz): nearest natural frequency {:.4} Hz ({:+.2}%, ζ = {:.3}%)",
                r.k,
                r.frequency_hz,
                m.frequency_hz,
                100.0 * m.detuning,
                100.0 * m.damping_ratio
            );
        }
    }
    if let Some(chosen) = &h.harmonics_chosen {
        outln!("  harmonics: {chosen}");
    }
    if let Some(n) = h.newton_iterations {
        match &h.contact_detour {
            Some(detour) => outln!("  Newton iterations: {n}, through {detour}"),
            None => outln!("  Newton iterations: {n}"),
        }
    }
    outln!("  wall time: {:.3} s", h.wall_seconds);
    outln!("  warnings: {}", h.warnings);
}

/// `modes`: the table of frequencies, damping ratios and effective masses (stdout).
pub fn show_modes(result: &ModesResult) {
    let s = &result.summary;
    outln!(
        "{}: {} modes, supports held, contact open; mass free to move x {:.4e} kg, y {:.4e} kg",
        s.name,
        s.modes.len(),
        s.free_mass_x,
        s.free_mass_y
    );
    outln!(
        "{:>5} {:>14} {:>9} {:>12} {:>12} {:>8} {:>8}",
        "mode",
        "frequency [Hz]",
        "ζ [%]",
        "m_eff,x [kg]",
        "m_eff,y [kg]",
        "Σx [%]",
        "Σy [%]"
    );
    for m in &s.modes {
        outln!(
            "{:>5} {:>14.6} {:>9.4} {:>12.4e} {:>12.4e} {:>8.2} {:>8.2}",
            m.mode,
            m.frequency_hz,
            100.0 * m.damping_ratio,
            m.effective_mass_x,
            m.effective_mass_y,
            100.0 * m.cumulative_fraction_x,
            100.0 * m.cumulative_fraction_y
        );
    }
    eprintln!("wrote {} (modes.pvd, modes.json)", result.dir.display());
}

/// `compare`: one line per compared quantity (stdout).
pub fn show_compare(c: &Comparison) {
    outln!(
        "{:<40} {:>4} {:>13} {:>13} {:>10} {:>9}",
        "quantity",
        "unit",
        "HB",
        "transient",
        "rel. diff",
        "phase [°]"
    );
    for d in &c.differences {
        let rel = d
            .relative
            .map(|r| format!("{:+.3e}", r))
            .unwrap_or_else(|| "-".into());
        let phase = d
            .phase_difference_deg
            .map(|p| format!("{p:+.2}"))
            .unwrap_or_default();
        outln!(
            "{:<40} {:>4} {:>13.5e} {:>13.5e} {:>10} {:>9}",
            d.quantity,
            d.unit,
            d.harmonic_balance,
            d.transient,
            rel,
            phase
        );
    }
    for n in &c.notes {
        eprintln!("note: {n}");
    }
}

/// The contact Newton's log: each Newton step numbered as the summary counts them, and the
/// start of each Newton run (a smoothing level, the exact law, a retry) as a line of its
/// own; the first 30 lines and the last 5.
fn show_newton_log(log: &[IterationLog]) {
    let mut steps = 0;
    for (i, l) in log.iter().enumerate() {
        let start = l.step == 0.0;
        steps += usize::from(!start);
        if i < 30 || i + 5 >= log.len() {
            let (what, step) = if start {
                ("    run start:    ".to_string(), String::new())
            } else {
                (
                    format!("    iteration {steps:>3}:"),
                    format!(", step {}", l.step),
                )
            };
            eprintln!(
                "{what} residual {:.3e}, active samples {:>5}{step}",
                l.residual, l.active_samples
            );
        } else if i == 30 {
            eprintln!("    …");
        }
    }
}

/// `check`'s findings: the mesh, its groups and the contact candidates.
/// One pair's lines of `check` (scenes with several pairs).
fn show_pair_check(p: &crate::pipeline::PairCheck) {
    outln!(
        "{} `{}`: {} of {} boundary nodes face the obstacle",
        p.key,
        p.boundary,
        p.nodes,
        p.candidates
    );
    let [off, far] = p.dropped;
    outln!("  dropped: {off} off the obstacle, {far} beyond the search distance");
    outln!("  smallest initial gap {:.3e} m", p.smallest_gap);
    if let Some((group, nodes)) = &p.target {
        outln!("  against `{group}` of another body: {nodes} of its nodes take the reaction");
    }
    if p.penetrated_nodes > 0 {
        let (n, depth) = (p.penetrated_nodes, p.deepest_penetration);
        outln!("  {n} start inside it, the deepest by {depth:.3e} m");
    }
}

pub fn show_check(report: &CheckReport) {
    let m = &report.mesh;
    outln!(
        "mesh: {} nodes, {} cells, order {}, shortest edge {:.3e} m ({})",
        m.nodes,
        m.cells,
        m.order,
        m.min_edge_length,
        if m.cache_hit { "cached" } else { "meshed" }
    );
    if let Some(gmsh) = &report.gmsh {
        outln!("gmsh: {gmsh} ({})", m.gmsh_version);
    }
    outln!("groups:");
    for (name, g) in &report.groups {
        outln!(
            "  {name:<16} {:>7} nodes {:>7} edges {:>7} cells",
            g.nodes,
            g.edges,
            g.cells
        );
    }
    if report.contact_pairs.len() > 1 {
        for pair in &report.contact_pairs {
            show_pair_check(pair);
        }
        return;
    }
    if let (Some(kept), Some(candidates)) = (report.contact_nodes, report.contact_candidates) {
        outln!("contact: {kept} of {candidates} boundary nodes face the obstacle");
        if let Some([off, far]) = report.contact_dropped {
            outln!("  dropped: {off} off the obstacle, {far} beyond contact.search_distance");
        }
        if let Some(gap) = report.smallest_gap {
            outln!("  smallest initial gap {gap:.3e} m");
        }
        if let Some((group, nodes)) = &report.target {
            outln!("  against `{group}` of another body: {nodes} of its nodes take the reaction");
        }
        if let (Some(n), Some(depth)) = (report.penetrated_nodes, report.deepest_penetration) {
            if n > 0 {
                outln!("  {n} start inside it, the deepest by {depth:.3e} m");
            }
        }
    }
}
