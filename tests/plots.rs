//! The plots the tool draws (`plots/` of a run, `compare`'s overlays) are valid SVG and PNG
//! with labelled axes and legends, and show the data the run reports: each SVG is read back as
//! XML, its tick labels give the pixel → value map, and its series' drawn extremes are compared
//! with summary.json (within 1% of the axis range: the SVG's coordinates are whole pixels).

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::svg::{check_plot, FIRST, SECOND};
use hbcontact::mesh::{Edge, Mesh2d};
use hbcontact::pipeline::{self, RunOptions};

fn run_ok(args: &[&str]) {
    let out = common::hbcontact(args);
    assert!(
        out.status.success(),
        "hbcontact {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn read_csv(path: &Path) -> BTreeMap<String, Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut cols: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for line in lines {
        for (h, v) in header.iter().zip(line.split(',')) {
            cols.entry(h.to_string())
                .or_default()
                .push(v.parse().unwrap());
        }
    }
    cols
}

fn number(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

const LC: &str = "geometry.parameters.lc=0.0025";

/// TEST GOAL: a harmonic-balance run of the strip against the wall draws, in `plots/`, the
/// probe displacement, the total contact force and the contact pressure at the peak, each as
/// an SVG that parses as XML with its axis labels (with units) and legend texts, and a
/// 720 × 480 PNG; and the plots show the run's values: the drawn law force peaks at the
/// summary's `peak_contact_force`, the dashed raw series dips to −(force_series_tension_ratio
/// × peak_contact_force_series) (the truncation ripple), u_x spans twice the summary's half
/// peak-to-peak, and the pressure profile's nodes are the kept contact nodes along the 10 mm
/// tip (arc length 0 to H = 0.01 m), their forces summing to the peak force, drawn at their
/// pressures. The `plots` stage is timed in the summary.
#[test]
fn run_plots_are_valid_svg_and_png_and_draw_the_summary_values() {
    let out = common::temp_out("plots-hb");
    run_ok(&[
        "run",
        "pipelines/strip_wall.yaml",
        "--quiet",
        "--set",
        LC,
        "--out",
        out.to_str().unwrap(),
    ]);
    let s = common::read_json(&out.join("summary.json"));
    let c = &s["contact"];
    let plots = out.join("plots");
    println!("plots stage: {} s", s["stage_seconds"]["plots"]);
    assert!(number(&s["stage_seconds"]["plots"]) > 0.0);

    let probe = check_plot(
        &plots.join("probe_probe"),
        &[
            "displacement [m]",
            "t/T [-], period T = 2e-4 s",
            "u_x",
            "u_y",
        ],
    );
    let (max, min) = probe.y_extremes(FIRST);
    let half = number(&s["probes"]["probe"]["half_peak_to_peak_x"]);
    probe.assert_close("probe u_x peak-to-peak", max - min, 2.0 * half);

    let force = check_plot(
        &plots.join("contact_force"),
        &[
            "total contact force [N per m of thickness]",
            "t/T [-]",
            "contact law max(0, c g - λ)",
            "Fourier series of λ",
        ],
    );
    let (peak, low) = force.y_extremes(FIRST);
    force.assert_close("law force peak", peak, number(&c["peak_contact_force"]));
    force.assert_close("law force minimum", low, 0.0);
    // The dashes may skip an extreme: every dash point lies on the raw series of contact.csv,
    // and the ripple below zero shows.
    let history = read_csv(&out.join("contact.csv"));
    let period = number(&s["period_s"]);
    let times: Vec<f64> = history["time"].iter().map(|t| t / period).collect();
    force.assert_on_curve("law", FIRST, &times, &history["total_force"]);
    force.assert_on_curve("series", SECOND, &times, &history["total_force_series"]);
    let (_, series_low) = force.y_extremes(SECOND);
    let series = number(&c["peak_contact_force_series"]);
    let tension = number(&c["force_series_tension_ratio"]) * series;
    println!(
        "series: lowest drawn {series_low:.4e} N, lowest sampled {:.4e} N",
        -tension
    );
    assert!(
        series_low < -0.25 * tension,
        "the ripple below zero is drawn"
    );

    let pressure = check_plot(
        &plots.join("contact_pressure"),
        &[
            "contact pressure [Pa]",
            "arc length along tip [m]",
            "contact law",
        ],
    );
    let rows = read_csv(&plots.join("contact_pressure.csv"));
    let kept = s["contact_setup"]["kept"].as_u64().unwrap() as usize;
    let arc = &rows["arc_length"];
    assert_eq!(arc.len(), kept);
    assert!(arc.windows(2).all(|w| w[1] > w[0]), "sorted along the tip");
    assert!(
        arc[0].abs() < 1e-12 && (arc[kept - 1] - 0.01).abs() < 1e-9,
        "{arc:?}"
    );
    let total: f64 = rows["force"].iter().sum();
    let peak_force = number(&c["peak_contact_force"]);
    assert!(
        (total - peak_force).abs() <= 1e-9 * peak_force,
        "{total} vs {peak_force}"
    );
    let drawn = pressure.series(FIRST);
    assert_eq!(drawn.len(), kept, "one point per contact node");
    for ((x, p), (s_i, p_i)) in drawn.iter().zip(arc.iter().zip(&rows["pressure"])) {
        assert!(
            (x - s_i).abs() <= 0.01 * 0.01,
            "arc length {x} drawn for {s_i}"
        );
        pressure.assert_close("node pressure", *p, *p_i);
    }
}

/// TEST GOAL: time marching draws the same plots over its last period, its force plot at
/// every time step (peaking at the summary's every-step peak) with the output frames as
/// markers; and `hbcontact compare` writes the overlays (probe u_x and u_y, total contact
/// force, opening of the node with the largest force) as SVG and PNG into `plots/` of its
/// output directory, each curve drawn at its own solver's values: the force overlay peaks at
/// each summary's peak, the probe overlay spans each side's half peak-to-peak.
#[test]
fn transient_plots_and_compare_overlays_show_both_solvers() {
    let base = common::temp_out("plots-compare");
    let (hb, tm, cmp) = (base.join("hb"), base.join("tm"), base.join("cmp"));
    for (mode, dir) in [("run", &hb), ("transient", &tm)] {
        run_ok(&[
            mode,
            "pipelines/strip_wall.yaml",
            "--quiet",
            "--set",
            LC,
            "--out",
            dir.to_str().unwrap(),
        ]);
    }
    let (s_hb, s_tm) = (
        common::read_json(&hb.join("summary.json")),
        common::read_json(&tm.join("summary.json")),
    );
    let peak = |s: &serde_json::Value| number(&s["contact"]["peak_contact_force"]);

    let force = check_plot(
        &tm.join("plots/contact_force"),
        &[
            "total contact force [N per m of thickness]",
            "contact law, every time step",
            "contact law, output frames",
        ],
    );
    force.assert_close("every-step peak", force.y_extremes(FIRST).0, peak(&s_tm));
    let frames = number(&s_tm["frames"]) as usize;
    let markers = force.circles.iter().filter(|c| c.0 == SECOND).count();
    assert_eq!(markers, frames + 1, "the frames, closed over the period");
    check_plot(&tm.join("plots/probe_probe"), &["displacement [m]", "u_x"]);
    check_plot(
        &tm.join("plots/contact_pressure"),
        &["contact pressure [Pa]"],
    );

    run_ok(&[
        "compare",
        hb.to_str().unwrap(),
        tm.to_str().unwrap(),
        "--quiet",
        "--out",
        cmp.to_str().unwrap(),
    ]);
    let plots = cmp.join("plots");
    let legend = ["harmonic balance", "time marching", "t/T [-]"];
    let total = check_plot(&plots.join("compare_total_force"), &legend);
    total.assert_close("HB peak", total.y_extremes(FIRST).0, peak(&s_hb));
    total.assert_close("TM peak", total.y_extremes(SECOND).0, peak(&s_tm));
    let ux = check_plot(&plots.join("compare_probe_ux"), &legend);
    ux.assert_texts(&plots.join("compare_probe_ux.svg"), &["probe u_x [m]"]);
    for (colour, s) in [(FIRST, &s_hb), (SECOND, &s_tm)] {
        let (max, min) = ux.y_extremes(colour);
        let half = number(&s["probes"]["probe"]["half_peak_to_peak_x"]);
        ux.assert_close("probe u_x peak-to-peak", max - min, 2.0 * half);
    }
    check_plot(&plots.join("compare_probe_uy"), &legend);
    let opening: Vec<_> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with("compare_node") && n.ends_with("_opening.svg"))
        .collect();
    assert_eq!(opening.len(), 1, "{opening:?}");
    let stem = plots.join(opening[0].trim_end_matches(".svg"));
    let svg = check_plot(&stem, &["harmonic balance", "(largest force) [m]"]);
    assert!(
        svg.y_extremes(FIRST).0 > 0.0,
        "the node opens during the period"
    );
}

/// TEST GOAL: plots cost nothing where they are not wanted: `output.plots: false` writes no
/// `plots/` (and times no `plots` stage), a summary-only run (a study point) writes none,
/// and a scene without contact draws its probes only.
#[test]
fn plots_are_skipped_when_switched_off_or_summary_only_and_contact_plots_need_contact() {
    let base = common::temp_out("plots-off");
    let (on, off, summary_only) = (base.join("on"), base.join("off"), base.join("summary"));
    run_ok(&[
        "run",
        "pipelines/quickstart.yaml",
        "--quiet",
        "--out",
        on.to_str().unwrap(),
    ]);
    let names: Vec<String> = std::fs::read_dir(on.join("plots"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(sorted, ["probe_probe.png", "probe_probe.svg"]);

    run_ok(&[
        "run",
        "pipelines/quickstart.yaml",
        "--quiet",
        "--set",
        "output.plots=false",
        "--out",
        off.to_str().unwrap(),
    ]);
    assert!(off.join("summary.json").is_file() && !off.join("plots").exists());
    let s = common::read_json(&off.join("summary.json"));
    assert!(s["stage_seconds"]["plots"].is_null());

    let p = common::scene("quickstart", &[]);
    let options = RunOptions {
        out: Some(summary_only.clone()),
        write: hbcontact::pipeline::WriteLevel::Summary,
        ..Default::default()
    };
    pipeline::run(&p, &options, &hbcontact::Silent).unwrap_or_else(|e| panic!("{e}"));
    assert!(summary_only.join("summary.json").is_file());
    assert!(!summary_only.join("plots").exists());
}

/// TEST GOAL: the pressure plot's abscissa: `arc_lengths` measures along the boundary's edges
/// from the end with the smallest x, through a 3-node edge's middle node, whatever the edges'
/// order and direction; a node off the boundary gets NaN. Here an L-shaped curve
/// (0,0) → (3,0) → (3,4) with the edges listed backwards and a 3-node edge: s = 0, 1.5, 3, 7.
#[test]
fn arc_lengths_run_along_the_boundary_from_its_leftmost_end() {
    let mut mesh = Mesh2d {
        nodes: vec![[3.0, 4.0], [3.0, 0.0], [0.0, 0.0], [1.5, 0.0], [9.0, 9.0]],
        ..Default::default()
    };
    mesh.edge_groups.insert(
        "b".into(),
        vec![
            Edge { nodes: vec![0, 1] },
            Edge {
                nodes: vec![1, 2, 3],
            },
        ],
    );
    let s = hbcontact::contact::geometry::arc_lengths(&mesh, "b", &[2, 3, 1, 0, 4]);
    assert_eq!(&s[..4], &[0.0, 1.5, 3.0, 7.0]);
    assert!(s[4].is_nan());
}

/// TEST GOAL: the probe plot's title names the probe group once: quickstart's group is called
/// `probe`, and its plot is titled "probe: mean displacement over one period", not
/// "probe probe: …" (issue #50).
#[test]
fn the_probe_plot_title_names_its_group_once() {
    let out = common::temp_out("plots-probe-title");
    run_ok(&[
        "run",
        "pipelines/quickstart.yaml",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    let svg = check_plot(&out.join("plots/probe_probe"), &[]);
    let titles: Vec<&String> = svg
        .texts
        .iter()
        .filter(|t| t.contains("mean displacement"))
        .collect();
    assert_eq!(
        titles,
        ["probe: mean displacement over one period"],
        "{:?}",
        svg.texts
    );
    assert!(
        svg.texts.iter().all(|t| !t.contains("probe probe")),
        "{:?}",
        svg.texts
    );
}

/// TEST GOAL: force axes say what the model's forces are for: per metre of thickness at the
/// default thickness of 1 m (the plane-strain strip above: "[N per m of thickness]"), newtons
/// of the body at a given thickness (the friction block, plane stress, 10 mm: "[N]", on its
/// contact force and friction loop plots).
#[test]
fn force_axes_name_the_thickness_the_forces_are_for() {
    let out = common::run_cli(
        "run",
        "pipelines/scenes/friction_block.yaml",
        "plots-force-unit",
        &[],
    );
    let plots = out.join("plots");
    check_plot(&plots.join("contact_force"), &["total contact force [N]"]);
    check_plot(
        &plots.join("friction_loop"),
        &["tangential force λ_t on the body [N]"],
    );
    let svg = std::fs::read_to_string(plots.join("contact_force.svg")).unwrap();
    assert!(!svg.contains("per m of thickness"));
}
