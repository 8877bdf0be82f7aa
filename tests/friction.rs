//! Coulomb friction at the contact nodes (`contact.friction`, `hbm::friction`), checked
//! against closed forms and its own limits: Jenkins' hysteresis loop of a block driven
//! across a rigid floor, the frictionless state as μ → 0, the bonded base as μ → ∞.

mod common;

use hbcontact::config::load_pipeline;
use hbcontact::pipeline::{self, summary::FrictionSummary, Summary};

use common::{root, run_summary, temp_out};

fn friction(s: &Summary) -> &FrictionSummary {
    let contact = s.contact.as_ref().expect("a contact summary");
    contact.friction.as_ref().expect("a friction summary")
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// TEST GOAL: a block pressed onto a rigid floor by a static normal force N and driven
/// along it by a harmonic displacement a of its top, quasi-statically, behaves as Jenkins'
/// element (a spring k_t in series with a Coulomb slider): its tangential force saturates
/// at μN and the energy it dissipates per period, the hysteresis loop's area, is
/// 4μN(a − a_s), a_s = μN/k_t. k_t is the block's own shear stiffness, measured by the same
/// code with the base stuck (μ = 10 and ten times the preload, so that no corner lifts:
/// every sample sticks, the force is k_t a). On two
/// meshes (10 and 20 cells along the base, 4 through), H = 20: measured 300.000 N = μN
/// and the area +0.47% and +0.22% from Jenkins' (the base's corners slip first).
#[test]
fn a_block_driven_across_a_floor_saturates_at_mu_n_and_dissipates_jenkins_loop_area() {
    let (mu, a) = (0.3, 1.0e-7);
    for nx in ["10", "20"] {
        let mesh = format!("geometry.parameters.nx={nx}");
        let stuck = run_summary(
            "scenes/friction_block",
            &[
                &mesh,
                "contact.friction.coefficient=10",
                "boundaries.prescribed.0.static=-5e-7",
            ],
            &format!("friction-block-stuck-{nx}"),
        );
        let stuck_friction = friction(&stuck);
        assert!(stuck_friction.stick_share > 0.999, "{stuck_friction:?}");
        let k_t = stuck_friction.peak_tangential_force / a;
        let s = run_summary(
            "scenes/friction_block",
            &[&mesh],
            &format!("friction-block-{nx}"),
        );
        let f = friction(&s);
        let n = s
            .contact
            .as_ref()
            .map(|c| c.mean_contact_force)
            .unwrap_or(0.0);
        let a_s = mu * n / k_t;
        let jenkins = 4.0 * mu * n * (a - a_s);
        println!(
            "nx = {nx}: N = {n:.6e} N, k_t = {k_t:.6e} N/m, peak |Σλ_t| = {:.6e} N (μN {:.6e}), \
             loop area {:.6e} J, Jenkins {jenkins:.6e} J ({:+.3}%), stuck {:.1}%",
            f.peak_tangential_force,
            mu * n,
            f.dissipated_energy_per_period,
            100.0 * (f.dissipated_energy_per_period / jenkins - 1.0),
            100.0 * f.stick_share,
        );
        assert!(relative(f.peak_tangential_force, mu * n) < 1e-6);
        assert!(relative(f.dissipated_energy_per_period, jenkins) < 1e-2);
        assert!(f.stick_share > 0.2 && f.slip_share > 0.5, "{f:?}");
        assert!(f.samples_change.is_some_and(|c| c < 1e-3), "{f:?}");
    }
}

/// TEST GOAL: μ → 0 gives the frictionless state: the cantilever of
/// pipelines/scenes/cantilever_stop.yaml near its resonance, hitting its stop part of the
/// period, with μ = 1e-9 agrees with the frictionless run in its probe amplitude and contact
/// force to 1e-7 (and dissipates nothing measurable), while μ = 0.3 moves both and
/// dissipates energy; that state moves by 2.2e-3 from N to 2N samples, past the knob check's
/// 1e-3, and the run warns, naming harmonic_balance.samples, which, raised, silences it.
#[test]
fn a_vanishing_friction_coefficient_gives_the_frictionless_state() {
    let at = "harmonic_balance.frequency=225";
    let plain = run_summary("scenes/cantilever_stop", &[at], "friction-none");
    let tiny = run_summary(
        "scenes/cantilever_stop",
        &[at, "contact.friction.coefficient=1e-9"],
        "friction-tiny",
    );
    let real = run_summary(
        "scenes/cantilever_stop",
        &[at, "contact.friction.coefficient=0.3"],
        "friction-real",
    );
    let probe = |s: &Summary| common::first_probe_harmonic(s);
    let peak = |s: &Summary| s.contact.as_ref().map_or(0.0, |c| c.peak_contact_force);
    let (dp, df) = (
        relative(probe(&tiny), probe(&plain)),
        relative(peak(&tiny), peak(&plain)),
    );
    println!(
        "μ = 1e-9: probe {dp:.2e}, peak force {df:.2e} from frictionless; μ = 0.3: {:.2e}, {:.2e}, {:.4e} J per period",
        relative(probe(&real), probe(&plain)),
        relative(peak(&real), peak(&plain)),
        friction(&real).dissipated_energy_per_period
    );
    assert!(peak(&plain) > 0.0, "the cantilever touches its stop");
    assert!(dp < 1e-7 && df < 1e-7);
    assert!(friction(&tiny).dissipated_energy_per_period.abs() < 1e-12);
    assert!(friction(&real).dissipated_energy_per_period > 1e-7);
    // The frictional re-solve at 2N moved that state by 2.2e-3: the run says so, and the
    // advice holds (at N = 1280 it moves by 3.4e-5 and the warning goes).
    let knob = "the frictional state still changes by";
    assert!(
        real.warnings.iter().any(|w| w.contains(knob)),
        "{:?}",
        real.warnings
    );
    let more = run_summary(
        "scenes/cantilever_stop",
        &[
            at,
            "contact.friction.coefficient=0.3",
            "harmonic_balance.samples=1280",
        ],
        "friction-real-2n",
    );
    assert!(
        !more.warnings.iter().any(|w| w.contains(knob)),
        "{:?}",
        more.warnings
    );
    assert!(friction(&more).samples_change.is_some_and(|c| c < 1e-3));
    assert!(relative(peak(&real), peak(&plain)) > 1e-4);
}

/// TEST GOAL: μ → ∞ gives the bonded base: the friction block pressed ten times harder
/// (every base node closed all period) with μ = 10 sticks at every sample, and its stresses
/// and contact forces equal those of the same block with its base held in x
/// (tests/data/friction_block_bonded.yaml) to 1e-9.
#[test]
fn a_huge_friction_coefficient_gives_the_bonded_base() {
    let preload = "boundaries.prescribed.0.static=-5e-7";
    let stuck = run_summary(
        "scenes/friction_block",
        &[preload, "contact.friction.coefficient=10"],
        "friction-bonded-limit",
    );
    let path = root().join("tests/data/friction_block_bonded.yaml");
    let p = load_pipeline(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
    let options = pipeline::RunOptions {
        out: Some(temp_out("friction-bonded")),
        write: pipeline::WriteLevel::Summary,
        ..Default::default()
    };
    let bonded = pipeline::run(&p, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"))
        .summary;
    assert_eq!(friction(&stuck).stick_share, 1.0);
    let pairs = [
        ("max von Mises", stuck.max_von_mises, bonded.max_von_mises),
        (
            "peak contact force",
            stuck.contact.as_ref().map(|c| c.peak_contact_force),
            bonded.contact.as_ref().map(|c| c.peak_contact_force),
        ),
    ];
    for (what, a, b) in pairs {
        let (a, b) = (a.unwrap_or(f64::NAN), b.unwrap_or(f64::NAN));
        println!("{what}: μ = 10 {a:.9e}, bonded {b:.9e}");
        assert!(relative(a, b) < 1e-9, "{what}: {a:e} vs {b:e}");
    }
}

/// TEST GOAL: a friction coefficient outside [0, 10] (or not a number) is refused with
/// the key named.
#[test]
fn a_friction_coefficient_out_of_range_is_refused_naming_the_key() {
    let path = root().join("pipelines/scenes/friction_block.yaml");
    for bad in ["-0.1", "11", ".nan"] {
        let set = vec![format!("contact.friction.coefficient={bad}")];
        let e = load_pipeline(&path, &set).expect_err("refused");
        assert!(
            e.to_string().contains("contact.friction.coefficient"),
            "{bad}: {e}"
        );
    }
}

/// TEST GOAL: harmonic balance agrees with the independent time marching (explicit central
/// differences on the diagonal mass, the step's frictional contact by projected
/// Gauss–Seidel) on a scene with stick, slip and separation in one period: the friction
/// damper of pipelines/scenes/friction_damper.yaml at μ = 0.1, whose end face slides along
/// its wall and lifts a corner. At H = 40 the probe amplitude is within 1% and the energy
/// friction dissipates per period within 2% of the marched one (measured −0.13% and −0.17%;
/// at H = 20 −0.46% and −2.0%, at H = 60 −0.05% and −0.08%). The marched frames carry the
/// tangential fields too (read by meshio): within the cone to round-off, stuck pairs at rest
/// and slipping ones against their force, and the nodes' energies sum to the marched
/// summary's.
#[test]
fn harmonic_balance_of_a_friction_damper_agrees_with_time_marching() {
    let sets = [
        "contact.friction.coefficient=0.1",
        "harmonic_balance.harmonics=40",
    ];
    let hb = common::run_cli(
        "run",
        "pipelines/scenes/friction_damper.yaml",
        "friction-damper-hb",
        &sets,
    );
    let tm = common::run_cli(
        "transient",
        "pipelines/scenes/friction_damper.yaml",
        "friction-damper-tm",
        &sets,
    );
    let hb = common::read_json(&hb.join("summary.json"));
    let tm_dir = tm;
    let tm = common::read_json(&tm_dir.join("summary.json"));
    common::assert_agrees_with_marching(&hb, &tm, &["/probes/probe/first_harmonic_y"], 1e-2);
    common::assert_agrees_with_marching(
        &hb,
        &tm,
        &["/contact/friction/dissipated_energy_per_period"],
        2e-2,
    );
    // The marched frames carry the tangential fields too: within the cone (to round-off),
    // some node slipping and some sticking, and the nodes' energies sum to the summary's.
    let v = frame_friction(&tm_dir, 0.1);
    let energy = common::json_number(&tm, "/contact/friction/dissipated_energy_per_period");
    assert!(v[0] >= 1.0 && v[1] >= 1.0 && v[2] < 1e-9, "{v:?}");
    // Stuck pairs do not move, slipping ones dissipate (measured 0 and 0).
    assert!(v[4] < 1e-9 && v[5] <= 1e-9, "{v:?}");
    assert!(
        ((v[3] - energy) / energy).abs() < 1e-9,
        "{} vs {energy}",
        v[3]
    );
    let slip = common::json_number(&hb, "/contact/friction/slip_share");
    let stick = common::json_number(&hb, "/contact/friction/stick_share");
    let open = common::json_number(&hb, "/contact/friction/open_share");
    assert!(
        slip > 0.1 && stick > 0.005 && open > 0.1,
        "{slip} {stick} {open}"
    );
}

/// TEST GOAL: the shipped study over the friction coefficient (studies/friction_damper_mu.yaml)
/// tabulates friction's outputs and shows what a friction damper does at a fixed drive: the
/// beam's amplitude falls as μ rises (measured 2.05e-4 m at μ = 0.02 to 3.1e-7 m at 0.3, where
/// the end face sticks), while the energy dissipated per period rises and then falls, with
/// its largest value inside the range (2.8e-2 J at μ = 0.05).
#[test]
fn a_study_over_the_friction_coefficient_finds_the_dampers_optimum_inside_its_range() {
    let rows: Vec<(f64, f64)> = study_columns(
        "studies/friction_damper_mu.yaml",
        "friction-study",
        &["probe_first_harmonic", "dissipated_energy"],
    )
    .into_iter()
    .map(|r| (r[0], r[1]))
    .collect();
    println!("{rows:?}");
    assert!(
        rows.windows(2).all(|w| w[1].0 < w[0].0),
        "amplitude falls with μ"
    );
    let best = (0..rows.len())
        .max_by(|&a, &b| rows[a].1.total_cmp(&rows[b].1))
        .expect("rows");
    assert!(best > 0 && best + 1 < rows.len(), "optimum inside: {best}");
}

/// The columns `names` of a study's study.csv, row by row, after `hbcontact study`.
fn study_columns(study: &str, tag: &str, names: &[&str]) -> Vec<Vec<f64>> {
    let out = common::temp_out(tag);
    let out_arg = out.display().to_string();
    let r = common::hbcontact(&["study", study, "--out", &out_arg]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = std::fs::read_to_string(out.join("study.csv")).expect("study.csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let columns: Vec<usize> = (names.iter())
        .map(|name| header.iter().position(|h| h == name).expect(name))
        .collect();
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            columns
                .iter()
                .map(|&c| f[c].parse().expect("a number"))
                .collect()
        })
        .collect()
}

/// TEST GOAL: the normal preload is a study parameter like any other key: the shipped study
/// over the friction block's preload (studies/friction_block_preload.yaml, 0.5 to 3 kN)
/// follows Jenkins' 4μN(a − μN/k_t) within 1% while the block slides (measured +0.45% to
/// −0.19% up to 2.5 kN, k_t measured as in the test above), and its largest energy is at the
/// preload nearest Jenkins' optimum a k_t/(2μ) (1.6 kN; 1.5 kN in the study). At 3 kN the
/// stick displacement μN/k_t is 93% of the drive: the base no longer slides as one, the
/// tangential force stays below μN (891 of 900 N) and the continuum's microslip dissipates
/// 11% more than the single slider.
#[test]
fn a_study_over_the_normal_preload_follows_jenkins_and_peaks_at_its_optimum() {
    let (mu, a) = (0.3, 1.0e-7);
    let stuck = run_summary(
        "scenes/friction_block",
        &[
            "contact.friction.coefficient=10",
            "boundaries.prescribed.0.static=-5e-7",
        ],
        "friction-block-preload-stuck",
    );
    let k_t = friction(&stuck).peak_tangential_force / a;
    let rows = study_columns(
        "studies/friction_block_preload.yaml",
        "friction-block-preload",
        &[
            "mean_contact_force",
            "dissipated_energy",
            "peak_tangential_force",
        ],
    );
    let jenkins = |n: f64| 4.0 * mu * n * (a - mu * n / k_t);
    for r in &rows {
        let (n, e) = (r[0], r[1]);
        println!(
            "N = {n:.1} N: {e:.6e} J, Jenkins {:.6e} J ({:+.2}%), peak λ_t {:.1} N",
            jenkins(n),
            100.0 * (e / jenkins(n) - 1.0),
            r[2]
        );
        if mu * n / k_t < 0.8 * a {
            assert!(relative(e, jenkins(n)) < 1e-2, "N = {n}");
            assert!(relative(r[2], mu * n) < 1e-6, "N = {n}");
        } else {
            assert!(e > jenkins(n) && r[2] < mu * n, "N = {n}: microslip");
        }
    }
    let optimum = a * k_t / (2.0 * mu);
    let best = (rows.iter())
        .max_by(|p, q| p[1].total_cmp(&q[1]))
        .expect("rows");
    let nearest = (rows.iter())
        .min_by(|p, q| (p[0] - optimum).abs().total_cmp(&(q[0] - optimum).abs()))
        .expect("rows");
    assert_eq!(best[0], nearest[0], "the optimum {optimum:.0} N");
}

/// TEST GOAL: a frictional run's frames carry the tangential force and the slip status at
/// the contact nodes, read back by meshio (an independent reader): the tangential force's
/// series is within the cone μ × the law force everywhere to the series' truncation (the
/// excess at most 5% of the peak tangential force; measured 3.0% at H = 20, where a node
/// about to open rings), and some node slips in some frame and some sticks; the run draws
/// the hysteresis loop of the node that dissipates most (plots/friction_loop.svg). The
/// nodes' `contact_friction_energy` sums to the summary's energy per period.
#[test]
fn frictional_frames_carry_tangential_force_and_slip_within_the_cone() {
    let out = common::run_cli(
        "run",
        "pipelines/scenes/friction_damper.yaml",
        "friction-frames",
        &["contact.friction.coefficient=0.1"],
    );
    let v = frame_friction(&out, 0.1);
    let summary = common::read_json(&out.join("summary.json"));
    let energy = common::json_number(&summary, "/contact/friction/dissipated_energy_per_period");
    assert!(
        ((v[3] - energy) / energy).abs() < 1e-9,
        "{} vs {energy}",
        v[3]
    );
    assert!(v[0] >= 1.0 && v[1] >= 1.0 && v[2] < 0.05, "{v:?}");
    // No slipping pair puts energy in: λ_t ẇ ≤ 0 to the series' truncation (measured 0).
    assert!(v[5] < 0.05, "{v:?}");
    let svg = std::fs::read_to_string(out.join("plots/friction_loop.svg")).expect("the loop");
    assert!(svg.contains("friction loop of contact node") && svg.contains("<polyline"));
}

/// The rows of a sweep's sweep.json: frequency [Hz] and each column's value (NaN for null).
fn sweep_rows(out: &std::path::Path) -> Vec<(f64, std::collections::BTreeMap<String, f64>)> {
    let json = common::read_json(&out.join("sweep.json"));
    assert!(
        json["stopped"].is_null(),
        "the sweep ends: {}",
        json["stopped"]
    );
    let columns: Vec<String> = (json["columns"].as_array().expect("columns").iter())
        .map(|c| c.as_str().unwrap_or_default().to_string())
        .collect();
    (json["rows"].as_array().expect("rows").iter())
        .map(|r| {
            let values = r["values"].as_array().expect("values");
            let named = (columns.iter().zip(values))
                .map(|(c, v)| (c.clone(), v.as_f64().unwrap_or(f64::NAN)))
                .collect();
            (common::json_number(r, "/frequency_hz"), named)
        })
        .collect()
}

/// TEST GOAL: a frictional sweep follows the law along the curve: the friction block swept
/// from 50 to 400 Hz (all far below its first mode, so quasi-static) dissipates at every row
/// the energy of the single run at 100 Hz, the run checked against Jenkins' loop above (to
/// 1e-4; measured 9e-6 over the 24 rows), its tangential force saturated at μN; the
/// summary says why the rows' stability is empty (a frictional state's is not judged).
#[test]
fn a_frictional_sweep_of_the_block_dissipates_the_single_runs_energy_at_every_frequency() {
    let mesh = "geometry.parameters.nx=10";
    let run = run_summary("scenes/friction_block", &[mesh], "friction-block-sweep-run");
    let energy = friction(&run).dissipated_energy_per_period;
    let n = run.contact.as_ref().map_or(0.0, |c| c.mean_contact_force);
    let out = common::run_cli(
        "sweep",
        "pipelines/scenes/friction_block.yaml",
        "friction-block-sweep",
        &[mesh],
    );
    let rows = sweep_rows(&out);
    let worst = rows.iter().fold(0.0f64, |a, (_, r)| {
        a.max(relative(r["dissipated_energy"], energy))
    });
    println!(
        "{} rows, energy {energy:.6e} J, largest deviation {worst:.2e}",
        rows.len()
    );
    assert!(rows.len() > 5 && worst < 1e-4);
    for (f, r) in &rows {
        assert!(
            relative(r["peak_tangential_force"], 0.3 * n) < 1e-6,
            "{f} Hz: {r:?}"
        );
        assert!(r["slip_share"] > 0.5, "{f} Hz: {r:?}");
    }
    // The stable column is empty, and the summary says why.
    let warnings = common::read_json(&out.join("sweep.json"))["warnings"].to_string();
    assert!(
        warnings.contains(&format!(
            "the stability of {} points is undecided",
            rows.len()
        )) && warnings.contains("frictional state"),
        "{warnings}"
    );
}

/// TEST GOAL: a frictional sweep passes a resonance with impacts: the cantilever of
/// pipelines/scenes/cantilever_stop.yaml with μ = 0.3 on its stop, swept from 155.8 to
/// 333.8 Hz, reaches the end through its folds; it dissipates nothing where the stop is not
/// touched and a positive energy where it is; rows in contact below the lowest fold (where
/// the state is unique; between the folds a single run at 226.5 Hz finds a state 11% below
/// the sweep's) are the single run's state at their frequency (probe amplitude to 1e-6;
/// measured 2e-16).
#[test]
fn a_frictional_sweep_through_an_impacting_resonance_matches_single_runs() {
    let mu = "contact.friction.coefficient=0.3";
    let out = common::run_cli(
        "sweep",
        "pipelines/scenes/cantilever_stop.yaml",
        "friction-stop-sweep",
        &[mu, "stability.check=false"],
    );
    let rows = sweep_rows(&out);
    let touching = rows.iter().filter(|(_, r)| r["contact_fraction"] > 0.0);
    assert!(touching.clone().count() > 5, "the stop is touched");
    for (f, r) in &rows {
        let e = r["dissipated_energy"];
        match r["contact_fraction"] > 0.0 {
            true => assert!(e > -1e-12, "{f} Hz dissipates: {e}"),
            false => assert!(e.abs() < 1e-15, "{f} Hz is open: {e}"),
        }
    }
    assert!(touching.clone().any(|(_, r)| r["dissipated_energy"] > 1e-6));
    let json = common::read_json(&out.join("sweep.json"));
    let row = |f: f64| rows.iter().find(|(g, _)| *g == f).map(|(_, r)| r.clone());
    let amplitude = |f: f64| row(f).map_or(f64::NAN, |r| r["probe_first_harmonic"]);
    let in_contact = |f: &f64| row(*f).is_some_and(|r| r["contact_fraction"] > 0.0);
    // Below the lowest fold the state is unique: the first and last rows in contact there.
    let folds = json["folds"].as_array().expect("folds").iter();
    let lowest = folds.fold(f64::INFINITY, |a, f| {
        a.min(common::json_number(f, "/frequency_hz"))
    });
    let graph: Vec<f64> = (rows.iter().map(|(f, _)| *f))
        .filter(|f| *f < lowest - 0.5)
        .filter(in_contact)
        .collect();
    let picked = [graph.first(), graph.last()].map(|f| f.copied().unwrap_or(f64::NAN));
    assert!(
        picked[0] < picked[1],
        "two graph rows in contact: {graph:?}"
    );
    for f in picked {
        let at = format!("harmonic_balance.frequency={f}");
        let tag = format!("friction-stop-at-{f:.0}");
        let s = run_summary("scenes/cantilever_stop", &[&at, mu], &tag);
        let d = relative(amplitude(f), common::first_probe_harmonic(&s));
        println!("{f:.3} Hz: sweep {:.6e} m, run {d:.2e} off", amplitude(f));
        assert!(d < 1e-6, "{f} Hz: {d:e}");
    }
}

/// TEST GOAL: the stability of a frictional state is judged by time marching where asked
/// (`stability.method: march`), and left undecided with a warning naming that key by the
/// default Floquet method, which forms no multipliers for it: the friction damper at μ = 0.1
/// and 300 Hz, marched from its own state perturbed, stays (measured: 24 periods, the change
/// decaying by 0.55 a period, 1.9% from the harmonic-balance orbit at H = 20).
#[test]
fn a_frictional_state_is_judged_stable_by_marching_and_undecided_by_floquet() {
    let mu = "contact.friction.coefficient=0.1";
    let marched = run_summary(
        "scenes/friction_damper",
        &[mu, "stability.method=march"],
        "friction-stability-march",
    );
    let verdict = marched.stability.as_ref().expect("a verdict");
    println!("{verdict:?}");
    assert_eq!(verdict.stable(), Some(true), "{verdict:?}");
    assert_eq!(
        verdict.method,
        hbcontact::pipeline::stability::Method::Marching
    );
    let floquet = run_summary(
        "scenes/friction_damper",
        &[mu],
        "friction-stability-floquet",
    );
    let verdict = floquet.stability.as_ref().expect("a verdict");
    assert_eq!(verdict.stable(), None, "{verdict:?}");
    assert!(
        floquet
            .warnings
            .iter()
            .any(|w| w.contains("stability.method: march")),
        "{:?}",
        floquet.warnings
    );
}

/// TEST GOAL: a friction-damped structure swept through its first resonance does what a
/// friction damper does: the rod of pipelines/scenes/friction_rod.yaml, driven axially with a
/// stop pressed onto its underside near the tip, at three preloads (interference 20, 50 and
/// 100 µm: 3.8, 9.4 and 18.7 N) peaks lower and at a higher frequency each time (measured
/// 4.91e-7 m at 6493 Hz, 9.65e-8 m at 6513 Hz, 9.39e-8 m at 7081 Hz, the last the resonance
/// of the rod held at its pad, stuck all period). At the two slipping preloads' peaks the
/// harmonic balance at H = 40 agrees with the time marching of the same model, the pad
/// sticking, slipping and lifting in one period: probe amplitude within 1% and dissipated
/// energy within 2% (measured +0.04% and +0.09% at 20 µm, +0.06% and +0.12% at 50 µm; at
/// 50 µm H = 20 is +1.1% and +1.4%, H = 10 +11%; on the 50 µm curve's flanks, 6300 and
/// 6800 Hz, +0.08%/+0.03% and −0.05%/+0.02%, measured once: four marches from rest cost
/// minutes).
#[test]
fn a_friction_damped_rod_peaks_lower_and_higher_with_more_preload_and_agrees_with_marching() {
    let scene = "pipelines/scenes/friction_rod.yaml";
    let mut peaks = Vec::new();
    for gap in ["-2e-5", "-5e-5", "-1e-4"] {
        let set = format!("geometry.parameters.gap={gap}");
        let tag = format!("friction-rod-sweep{gap}");
        let out = common::run_cli("sweep", scene, &tag, &[&set, "stability.check=false"]);
        let rows = sweep_rows(&out);
        let (f, peak) = (rows.iter())
            .max_by(|a, b| a.1["probe_first_harmonic"].total_cmp(&b.1["probe_first_harmonic"]))
            .expect("rows");
        println!(
            "gap {gap}: peak {:.4e} m at {f:.1} Hz, N = {:.2} N, slip share {:.3}",
            peak["probe_first_harmonic"], peak["mean_contact_force"], peak["slip_share"]
        );
        peaks.push((set, *f, peak["probe_first_harmonic"], peak["slip_share"]));
    }
    for w in peaks.windows(2) {
        assert!(w[1].2 < w[0].2, "the peak falls: {:?}", peaks);
        assert!(w[1].1 > w[0].1, "and moves up: {:?}", peaks);
    }
    for (set, f, _, slip) in &peaks[..2] {
        assert!(*slip > 0.05, "slipping at the peak: {slip}");
        let sets = [
            set.as_str(),
            &format!("harmonic_balance.frequency={f}"),
            "harmonic_balance.harmonics=40",
            "stability.check=false",
        ];
        let hb = common::run_cli("run", scene, &format!("friction-rod-hb{f:.0}"), &sets);
        let tm = common::run_cli("transient", scene, &format!("friction-rod-tm{f:.0}"), &sets);
        let hb = common::read_json(&hb.join("summary.json"));
        let tm = common::read_json(&tm.join("summary.json"));
        common::assert_agrees_with_marching(&hb, &tm, &["/probes/probe/first_harmonic_x"], 1e-2);
        let energy = "/contact/friction/dissipated_energy_per_period";
        common::assert_agrees_with_marching(&hb, &tm, &[energy], 2e-2);
    }
}

/// TEST GOAL: a frictional sweep's points are judged by time marching where asked: the
/// friction rod swept over 6000–6400 Hz with `stability.method: both` (a frictional state has
/// no Floquet multipliers, so marching alone judges) gives its first and last rows a verdict
/// and a marched multiplier (measured stable, |μ| 0.97 and 0.99), and no undecided warning;
/// with the Floquet default the rows stay empty and sweep.json says why (the block's test
/// above).
#[test]
fn a_frictional_sweeps_points_are_judged_by_marching_where_asked() {
    let out = common::run_cli(
        "sweep",
        "pipelines/scenes/friction_rod.yaml",
        "friction-rod-sweep-march",
        &[
            "sweep.to=6400",
            "stability.method=both",
            "stability.every=1000",
        ],
    );
    let json = common::read_json(&out.join("sweep.json"));
    let rows = json["rows"].as_array().expect("rows");
    for row in [rows.first(), rows.last()].map(|r| r.expect("a row")) {
        println!(
            "{} Hz: {} {}",
            row["frequency_hz"], row["stable"], row["multiplier"]
        );
        assert_eq!(row["stable"], serde_json::Value::Bool(true), "{row}");
        assert!(common::json_number(row, "/multiplier") < 1.0, "{row}");
    }
    assert!(
        !json["warnings"].to_string().contains("undecided"),
        "{}",
        json["warnings"]
    );
}

/// Over a run's frames (read by meshio, an independent reader): how many (node, frame) pairs
/// slip and stick, the largest excess of |λ_t| over μ × the contact force relative to the
/// peak |λ_t|, the first frame's sum of `contact_friction_energy`, the largest slip speed of
/// a stuck pair relative to the largest of all, and the largest power λ_t ẇ a slipping pair
/// puts in (slip dissipates: λ_t ẇ ≤ 0) relative to peak |λ_t| × peak |ẇ|.
fn frame_friction(out: &std::path::Path, mu: f64) -> Vec<f64> {
    let script = r#"
import glob, sys, meshio
mu = float(sys.argv[2])
slip = stick = 0
excess = peak = 0.0
speed = stuck_speed = power = 0.0
m0 = meshio.read(sys.argv[1] + '/frame_0000.vtu')
total = float(m0.point_data['contact_friction_energy'].sum())
for f in sorted(glob.glob(sys.argv[1] + '/frame_*.vtu')):
    m = meshio.read(f)
    keys = ('contact_tangential_force', 'contact_force', 'contact_slip', 'contact_slip_velocity')
    t, n, s, v = (m.point_data[k] for k in keys)
    for ti, ni, si, vi in zip(t, n, s, v):
        if si >= 0:
            excess = max(excess, abs(ti) - mu * ni)
        peak = max(peak, abs(ti))
        speed = max(speed, abs(vi))
        if si == 0:
            stuck_speed = max(stuck_speed, abs(vi))
        if si == 1:
            power = max(power, ti * vi)
        slip += si == 1
        stick += si == 0
print(slip, stick, excess / peak, total, stuck_speed / speed, power / (peak * speed))
"#;
    let r = std::process::Command::new(common::venv_python())
        .args(["-c", script, &out.display().to_string(), &mu.to_string()])
        .output()
        .expect("python runs");
    let text = String::from_utf8_lossy(&r.stdout);
    println!("{text}{}", String::from_utf8_lossy(&r.stderr));
    let v: Vec<f64> = (text.split_whitespace())
        .filter_map(|w| w.parse().ok())
        .collect();
    assert_eq!(v.len(), 6, "{text}");
    v
}

/// TEST GOAL: friction between two elastic bodies (the pair structure: node-to-segment rows,
/// the target side gets the reaction) agrees with the time marching of the same model: two
/// clamped strips, their free end faces pressed together by static tractions and driven
/// along each other by opposite transverse ones (tests/data/two_strips_friction.yaml, μ = 0.3,
/// slipping most of the period), H = 20. Both strips' probe amplitudes within 1% and the
/// dissipated energy within 2%, on matching face meshes (measured −0.05% and −0.07%) and on
/// B's finer, non-matching one (lcB 1.75 mm against 2.5 mm: −0.56% and −0.71%).
#[test]
fn friction_between_two_elastic_bodies_agrees_with_time_marching() {
    let scene = "tests/data/two_strips_friction.yaml";
    for (tag, set) in [
        ("matching", "geometry.parameters.lcB=-1"),
        ("finer-b", "geometry.parameters.lcB=0.00175"),
    ] {
        let hb_sets = [set, "stability.check=false"];
        let hb = common::run_cli("run", scene, &format!("friction-pair-hb-{tag}"), &hb_sets);
        let tm = common::run_cli(
            "transient",
            scene,
            &format!("friction-pair-tm-{tag}"),
            &[set],
        );
        let hb = common::read_json(&hb.join("summary.json"));
        let tm = common::read_json(&tm.join("summary.json"));
        let probes = [
            "/probes/probe/first_harmonic_y",
            "/probes/probe_b/first_harmonic_y",
        ];
        common::assert_agrees_with_marching(&hb, &tm, &probes, 1e-2);
        let energy = "/contact/friction/dissipated_energy_per_period";
        common::assert_agrees_with_marching(&hb, &tm, &[energy], 2e-2);
        assert!(common::json_number(&hb, "/contact/friction/slip_share") > 0.5);
    }
}
