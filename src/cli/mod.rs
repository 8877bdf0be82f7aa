//! What the command line adds to the library: its reporter and how results are shown.

pub mod reporter;
pub mod study;

use hbcontact::hbm::IterationLog;
use hbcontact::pipeline::{CheckReport, RunResult};

/// After a run: warnings, the contact Newton's log, where the results went and what was
/// simulated.
pub fn show_run(result: &RunResult) {
    let s = &result.summary;
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(solve) = s.contact.as_ref().and_then(|c| c.solver.as_ref()) {
        show_newton_log(&solve.newton_log);
    }
    eprintln!("wrote {}", result.dir.display());
    if let Ok(effects) = serde_json::to_string(&s.effects) {
        eprintln!("simulated: {effects}");
    }
}

/// The contact Newton's log, one line per iteration (long logs are elided in the middle).
fn show_newton_log(log: &[IterationLog]) {
    for (i, l) in log.iter().enumerate() {
        if i < 30 || i + 5 >= log.len() {
            eprintln!(
                "    iteration {i:>3}: residual {:.3e}, active samples {:>5}, step {}",
                l.residual, l.active_samples, l.step
            );
        } else if i == 30 {
            eprintln!("    …");
        }
    }
}

/// `check`'s findings: the mesh, its groups and the contact candidates.
pub fn show_check(report: &CheckReport) {
    let m = &report.mesh;
    println!(
        "mesh: {} nodes, {} cells, order {}, shortest edge {:.3e} m ({})",
        m.nodes,
        m.cells,
        m.order,
        m.min_edge_length,
        if m.cache_hit { "cached" } else { "meshed" }
    );
    println!("groups:");
    for (name, g) in &report.groups {
        println!(
            "  {name:<16} {:>7} nodes {:>7} edges {:>7} cells",
            g.nodes, g.edges, g.cells
        );
    }
    if let (Some(kept), Some(candidates)) = (report.contact_nodes, report.contact_candidates) {
        println!("contact: {kept} of {candidates} boundary nodes face the obstacle");
    }
}
