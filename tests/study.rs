//! Parameter studies (`hbcontact study`): the table does not depend on how the points were
//! run (threads, shards, Slurm), failures are recorded without stopping the rest, done points
//! are skipped on a rerun, bad parameter names are refused before anything runs, and the
//! accuracy study's errors fall along the H ladder on the strip.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    common::hbcontact(args)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn run_ok(args: &[&str]) -> Output {
    let o = run(args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    o
}

/// A study file written for the test (under the test's output directory), varying the strip.
fn strip_study(dir: &Path, body: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("study.yaml");
    let pipeline = common::root().join("pipelines/strip_wall.yaml");
    let text = format!(
        "name: test\npipeline: {}\nset: {{geometry.parameters.lc: 0.0025, harmonic_balance.harmonics: 8}}\n{body}",
        pipeline.display()
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// `hbcontact study STUDY -q --out OUT`, which must succeed.
fn run_study(study: &Path, out: &Path) {
    run_ok(&[
        "study",
        study.to_str().unwrap(),
        "-q",
        "--out",
        out.to_str().unwrap(),
    ]);
}

const GAP_GRID: &str = "parameters:\n  - {key: geometry.parameters.gap, values: [1.0e-7, 2.0e-7], unit: m}\n  - {key: boundaries.loads.0.harmonics.0.cos.0, values: [1.0e5, 1.5e5], unit: Pa}\n";

/// study.csv without the wall-time column (the one value that differs between runs).
fn table_without_times(csv: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let rows: Vec<Vec<String>> = text
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    let time = rows[0].iter().position(|c| c == "wall_time");
    rows.into_iter()
        .map(|mut r| {
            if let Some(i) = time {
                r.remove(i);
            }
            r
        })
        .collect()
}

fn column(rows: &[Vec<String>], name: &str) -> Vec<String> {
    let i = rows[0].iter().position(|c| c == name).unwrap();
    rows[1..].iter().map(|r| r[i].clone()).collect()
}

/// TEST GOAL: running the points two at a time gives the same table (parameters, outputs,
/// status, keys) as running them one after another, and both write plots and a manifest
/// (forces on their axes per metre of thickness, as the plane-strain strip's are).
#[test]
fn parallel_study_table_equals_serial_table() {
    let dir = common::temp_out("study-parallel");
    let study = strip_study(&dir, GAP_GRID);
    let study = study.to_str().unwrap();
    let (serial, parallel) = (dir.join("serial"), dir.join("parallel"));
    run_ok(&[
        "study",
        study,
        "-q",
        "--threads",
        "1",
        "--out",
        serial.to_str().unwrap(),
    ]);
    run_ok(&[
        "study",
        study,
        "-q",
        "--threads",
        "2",
        "--out",
        parallel.to_str().unwrap(),
    ]);
    let (a, b) = (
        table_without_times(&serial.join("study.csv")),
        table_without_times(&parallel.join("study.csv")),
    );
    assert_eq!(a.len(), 5, "header and 4 points: {a:?}");
    assert_eq!(a, b);
    assert!(column(&a, "status").iter().all(|s| s == "ok"), "{a:?}");
    let manifest = common::read_json(&parallel.join("manifest.json"));
    assert_eq!(manifest["points"], 4);
    assert_eq!(manifest["execution"]["threads"], 2);
    assert_eq!(manifest["execution"]["geometries"], 2, "one mesh per gap");
    for f in [
        "probe_first_harmonic_vs_gap.svg",
        "probe_first_harmonic_vs_gap.png",
        "peak_contact_force_heatmap.png",
    ] {
        assert!(parallel.join("plots").join(f).is_file(), "{f} missing");
    }
    let svg =
        std::fs::read_to_string(parallel.join("plots/probe_first_harmonic_vs_gap.svg")).unwrap();
    assert!(
        svg.contains("gap [m]") && svg.contains("cos [Pa] = ") || svg.contains(" Pa"),
        "axis label with unit and a legend naming the other parameter"
    );
    // The strip's forces are per metre of thickness (plane strain at the default 1 m).
    let svg =
        std::fs::read_to_string(parallel.join("plots/peak_contact_force_vs_gap.svg")).unwrap();
    assert!(svg.contains("peak_contact_force [N per m of thickness]"));
}

/// TEST GOAL: a point that fails (its Newton is allowed no iteration) is in the table as
/// failed with its error message and exit class `not_converged`; the other point completes;
/// the exit code (6) says some points failed.
#[test]
fn failed_point_is_recorded_and_the_others_complete() {
    let dir = common::temp_out("study-failure");
    let study = strip_study(
        &dir,
        "design: list\nparameters:\n  - {key: harmonic_balance.solver.max_iterations, values: [200, 0]}\n",
    );
    let out = dir.join("out");
    let o = run(&[
        "study",
        study.to_str().unwrap(),
        "-q",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(6), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 of 2 study points failed"),
        "{}",
        stderr(&o)
    );
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    assert!(lines[1].contains(",ok,,,"), "{csv}");
    assert!(
        lines[2].contains(",failed,not_converged,") && lines[2].contains("max_iterations = 0"),
        "{csv}"
    );
}

/// TEST GOAL: rerunning a finished study runs nothing (every point is found by its key), and
/// after one point's record is removed, exactly that point runs again.
#[test]
fn rerun_skips_points_already_done() {
    let dir = common::temp_out("study-resume");
    let study = strip_study(&dir, GAP_GRID);
    let (study, out) = (study.to_str().unwrap(), dir.join("out"));
    let out_s = out.to_str().unwrap();
    run_ok(&["study", study, "-q", "--out", out_s]);
    let first = std::fs::read_to_string(out.join("study.csv")).unwrap();
    run_ok(&["study", study, "-q", "--out", out_s]);
    let m = common::read_json(&out.join("manifest.json"));
    assert_eq!(
        (
            m["execution"]["ran"].as_u64(),
            m["execution"]["skipped"].as_u64()
        ),
        (Some(0), Some(4))
    );
    assert_eq!(
        first,
        std::fs::read_to_string(out.join("study.csv")).unwrap(),
        "the same table, times included"
    );
    let key = &m["point_keys"][2];
    std::fs::remove_file(
        out.join("points")
            .join(key.as_str().unwrap())
            .join("point.json"),
    )
    .unwrap();
    run_ok(&["study", study, "-q", "--out", out_s]);
    let m = common::read_json(&out.join("manifest.json"));
    assert_eq!(
        (
            m["execution"]["ran"].as_u64(),
            m["execution"]["skipped"].as_u64()
        ),
        (Some(1), Some(3))
    );
}

/// TEST GOAL: a study's points pay for the stability check by time marching (several times
/// their solve) only when the study tabulates it: with the default outputs every point's
/// summary says `not_checked` and has no `stability` stage; asking for `stable` and
/// `multiplier` reruns the points (their records lack the verdict) and tabulates each point's
/// verdict as its summary states it (1 stable, 0 unstable) with its multiplier.
#[test]
fn study_points_run_the_stability_check_only_when_its_outputs_ask_for_it() {
    let dir = common::temp_out("study-stability");
    let body =
        "parameters:\n  - {key: geometry.parameters.gap, values: [1.0e-7, 2.0e-7], unit: m}\n";
    let plain = strip_study(&dir, body);
    let out = dir.join("out");
    run_study(&plain, &out);
    let rows = table_without_times(&out.join("study.csv"));
    assert!(!rows[0].iter().any(|c| c == "stable"), "{:?}", rows[0]);
    for key in column(&rows, "key") {
        let s = common::read_json(&out.join("points").join(&key).join("summary.json"));
        assert_eq!(s["stability"]["verdict"], "not_checked", "{key}");
        assert!(s["stage_seconds"].get("stability").is_none(), "{key}");
    }
    let asked = strip_study(
        &dir,
        &format!("{body}outputs: [probe_first_harmonic, stable, multiplier]\n"),
    );
    run_study(&asked, &out);
    let m = common::read_json(&out.join("manifest.json"));
    assert_eq!(
        m["execution"]["ran"].as_u64(),
        Some(2),
        "the verdicts were missing"
    );
    let rows = table_without_times(&out.join("study.csv"));
    let (stable, multiplier) = (column(&rows, "stable"), column(&rows, "multiplier"));
    for (i, key) in column(&rows, "key").iter().enumerate() {
        let s = common::read_json(&out.join("points").join(key).join("summary.json"));
        let verdict = s["stability"]["verdict"].as_str().unwrap().to_string();
        let expected = match verdict.as_str() {
            "stable" => "1",
            "unstable" => "0",
            other => panic!("point {i}: verdict {other}: {}", s["stability"]["reason"]),
        };
        assert!(stable[i].parse::<f64>().unwrap() == expected.parse::<f64>().unwrap());
        let mu: f64 = multiplier[i].parse().unwrap();
        let summary_mu = s["stability"]["multiplier"].as_f64().unwrap();
        assert!(
            (mu - summary_mu).abs() <= 1e-12 * summary_mu,
            "{mu} vs {summary_mu}"
        );
        // Unstable can also mean "marching settles elsewhere" with μ̂ < 1; stable cannot grow.
        assert!(
            verdict != "stable" || mu < 1.0,
            "point {i}: μ̂ = {mu}, {verdict}"
        );
    }
}

/// TEST GOAL: two shards (`--shard 0/2`, `--shard 1/2`) then `--merge` give the table a
/// one-process run gives; a merge before the second shard ran reports the missing points
/// (exit 6) and tabulates them as `missing`.
#[test]
fn merged_shards_equal_one_run() {
    let dir = common::temp_out("study-shards");
    let study = strip_study(&dir, GAP_GRID);
    let study = study.to_str().unwrap();
    let (one, sharded) = (dir.join("one"), dir.join("sharded"));
    let s = sharded.to_str().unwrap();
    run_ok(&["study", study, "-q", "--out", one.to_str().unwrap()]);
    run_ok(&["study", study, "-q", "--shard", "0/2", "--out", s]);
    assert!(
        !sharded.join("study.csv").exists(),
        "a shard writes no table"
    );
    let early = run(&["study", study, "-q", "--merge", "--out", s]);
    assert_eq!(early.status.code(), Some(6), "{}", stderr(&early));
    let partial = table_without_times(&sharded.join("study.csv"));
    assert_eq!(
        column(&partial, "status"),
        ["ok", "missing", "ok", "missing"]
    );
    run_ok(&["study", study, "-q", "--shard", "1/2", "--out", s]);
    run_ok(&["study", study, "-q", "--merge", "--out", s]);
    assert_eq!(
        table_without_times(&one.join("study.csv")),
        table_without_times(&sharded.join("study.csv"))
    );
}

/// TEST GOAL: a parameter the .geo does not define, or a pipeline key that does not exist, is
/// refused with exit 2 before any point runs, naming the study file and suggesting the fix.
#[test]
fn unknown_parameter_names_are_rejected_with_exit_2() {
    let dir = common::temp_out("study-unknown");
    for (key, expect) in [
        ("geometry.parameters.gapp", "gap"),
        ("harmonic_balance.harmoncs", "harmoncs"),
    ] {
        let study = strip_study(
            &dir,
            &format!("parameters:\n  - {{key: {key}, values: [1, 2]}}\n"),
        );
        let out = dir.join("out");
        let o = run(&[
            "study",
            study.to_str().unwrap(),
            "-q",
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{key}: {err}");
        assert!(
            err.contains("study.yaml") && err.contains(expect),
            "{key}: {err}"
        );
        assert!(
            !out.join("points").exists()
                || std::fs::read_dir(out.join("points")).unwrap().count() == 0
        );
    }
    let study = strip_study(&dir, "parameters:\n  - {key: geometry.parameters.gap, values: [1e-7]}\noutputs: [probe_amplitude]\n");
    let o = run(&["study", study.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("outputs[0]") && stderr(&o).contains("did you mean"),
        "{}",
        stderr(&o)
    );
}

/// TEST GOAL: on the strip, the accuracy study's errors against the finest rung fall as H
/// rises (5, 10, 20 → 40) in the probe's first-harmonic amplitude and peak-to-peak range (the
/// contact forces' errors are not monotone at H = 5: a coarse series can land close by luck)
/// and in the displacement L2 over space and period (every node, the mesh being the same);
/// every rung has a wall time and a peak memory; `--tolerance` names a cheapest setting per measure; the Pareto
/// plot names the reference.
#[test]
fn accuracy_study_errors_fall_along_the_h_ladder_on_the_strip() {
    let dir = common::temp_out("study-accuracy");
    let study = strip_study(
        &dir,
        "accuracy:\n  ladders:\n    - {key: harmonic_balance.harmonics, values: [5, 10, 20, 40]}\n",
    );
    let out = dir.join("out");
    let o = run_ok(&[
        "study",
        study.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--tolerance",
        "1e-2",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("probe_first_harmonic   harmonic_balance.harmonics ="),
        "{stdout}"
    );
    let rows = table_without_times(&out.join("accuracy.csv"));
    let errors = |name: &str| -> Vec<f64> {
        column(&rows, name)
            .iter()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    for measure in [
        "error_probe_first_harmonic",
        "error_probe_peak_to_peak",
        "error_displacement_l2",
    ] {
        let e = errors(measure);
        assert!(
            e[0] > e[1] && e[1] > e[2] && e[3] == 0.0,
            "{measure}: {e:?}"
        );
    }
    let nodes = errors("displacement_l2_nodes");
    assert!(
        nodes.iter().all(|&n| n > 100.0 && n == nodes[3]),
        "same mesh on every rung: every node compared, {nodes:?}"
    );
    let memory = errors("peak_memory");
    assert!(
        memory.iter().all(|&m| m > 1.0 && m < 4096.0),
        "peak memory [MB] per rung: {memory:?}"
    );
    let text = std::fs::read_to_string(out.join("accuracy.csv")).unwrap();
    assert!(text.lines().skip(1).all(|l| l
        .split(',')
        .nth(4)
        .is_some_and(|t| t.parse::<f64>().unwrap() > 0.0)));
    let svg = std::fs::read_to_string(out.join("accuracy.svg")).unwrap();
    assert!(
        svg.contains("reference: the finest rung (harmonics = 40)"),
        "{svg}"
    );
    assert!(out.join("accuracy.png").is_file());
}

/// TEST GOAL: the Slurm path: `--slurm` writes a job array and a dependent merge job; on a
/// running cluster (.ci/run starts a one-node one) the merged table equals the one-process
/// run. Skipped, saying why, when sbatch or a controller is missing, unless
/// HBCONTACT_REQUIRE_SLURM=1.
#[test]
fn slurm_job_array_merges_into_the_one_process_table() {
    let dir = common::temp_out("study-slurm");
    let study = strip_study(&dir, GAP_GRID);
    let study = study.to_str().unwrap();
    let (one, cluster) = (dir.join("one"), dir.join("cluster"));
    let c = cluster.to_str().unwrap();
    run_ok(&[
        "study", study, "-q", "--slurm", "--shards", "3", "--time", "00:10:00", "--mem", "1G",
        "--out", c,
    ]);
    let array = std::fs::read_to_string(cluster.join("slurm/array.sbatch")).unwrap();
    assert!(
        array.contains("#SBATCH --array=0-2")
            && array.contains("--shard \"${SLURM_ARRAY_TASK_ID}/3\""),
        "{array}"
    );
    assert!(array.contains("#SBATCH --time=00:10:00") && array.contains("#SBATCH --mem=1G"));
    let submit = std::fs::read_to_string(cluster.join("slurm/submit.sh")).unwrap();
    assert!(submit.contains("--dependency=afterany:"), "{submit}");
    let cluster_up = std::process::Command::new("sinfo")
        .arg("-h")
        .output()
        .is_ok_and(|o| o.status.success() && !o.stdout.is_empty());
    if !cluster_up {
        if std::env::var("HBCONTACT_REQUIRE_SLURM").as_deref() == Ok("1") {
            panic!("no Slurm cluster answers (sinfo) but HBCONTACT_REQUIRE_SLURM=1 (.ci/run starts one)");
        }
        eprintln!("SKIPPED the cluster run: no Slurm controller answers `sinfo` (apt-get install slurm-wlm munge; .ci/run starts a one-node cluster)");
        return;
    }
    run_ok(&["study", study, "-q", "--out", one.to_str().unwrap()]);
    let submitted = std::process::Command::new("bash")
        .arg(cluster.join("slurm/submit.sh"))
        .output()
        .unwrap();
    assert!(
        submitted.status.success(),
        "{}",
        String::from_utf8_lossy(&submitted.stderr)
    );
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(300);
    while !cluster.join("manifest.json").exists() {
        assert!(
            std::time::Instant::now() < deadline,
            "the merge job did not finish in 5 minutes"
        );
        std::thread::sleep(std::time::Duration::from_millis(500));
    }
    assert_eq!(
        table_without_times(&one.join("study.csv")),
        table_without_times(&cluster.join("study.csv"))
    );
}

/// TEST GOAL: a study meshes each distinct geometry with exactly one gmsh process (the
/// element estimate and the mesh in one gmsh session), plus one `gmsh --version` per
/// hbcontact process: counted by a logging `python` in front of the venv's.
#[test]
fn each_geometry_is_meshed_by_one_gmsh_process() {
    let dir = common::temp_out("study-gmsh-processes");
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let log = dir.join("python.log");
    let _ = std::fs::remove_file(&log);
    let python = bin.join("python");
    common::write_executable(
        &python,
        &format!(
            "#!/bin/sh\necho \"$1\" >> '{}'\nexec '{}' \"$@\"\n",
            log.display(),
            common::venv_python().display()
        ),
    );
    common::copy_executable(&common::root().join(".venv/bin/gmsh"), &bin.join("gmsh"));
    let study = strip_study(
        &dir,
        "parameters:\n  - {key: geometry.parameters.gap, values: [1.0e-7, 1.5e-7, 2.0e-7]}\n",
    );
    let (out, gmsh) = (dir.join("out"), bin.join("gmsh"));
    run_ok(&[
        "study",
        study.to_str().unwrap(),
        "-q",
        "--set",
        &format!("geometry.gmsh={}", gmsh.display()),
        "--out",
        out.to_str().unwrap(),
    ]);
    let calls = std::fs::read_to_string(&log).unwrap();
    let gmsh_sessions = calls.lines().filter(|l| *l == "-c").count();
    assert_eq!(
        (gmsh_sessions, calls.lines().count()),
        (3, 4),
        "3 geometries, one gmsh session each, and one --version: {calls}"
    );
}

/// TEST GOAL: `natural_frequency_K` outputs follow Euler–Bernoulli on the slender cantilever
/// (plane strain, clamped–free): f₁ = (1.8751²/2π)·√(E'I/(ρA))/L² with E' = E/(1 − ν²) and
/// I/A = h²/12, so f₁ ∝ h/L²: doubling h doubles f₁, L → 0.8 L multiplies it by 1/0.64, and
/// f₂/f₁ = (4.6941/1.8751)² = 6.27 (reference: Blevins, Formulas for Natural Frequency and Mode
/// Shape, table 8-1). Measured: f₁ within 0.05 % of the formula, f₂/f₁ = 6.254 (the beam's
/// shear and rotary inertia lower f₂ by 0.2 %); asserted within 0.2 % and 0.5 %.
#[test]
fn natural_frequencies_follow_euler_bernoulli_as_the_cantilever_changes() {
    let dir = common::temp_out("study-natural-frequencies");
    std::fs::create_dir_all(&dir).unwrap();
    let study = dir.join("study.yaml");
    let text = format!(
        "name: test\npipeline: {}\ndesign: list\nparameters:\n  - {{key: geometry.parameters.L, values: [1.0, 1.0, 0.8]}}\n  - {{key: geometry.parameters.H, values: [0.02, 0.04, 0.02]}}\noutputs: [natural_frequency_1, natural_frequency_2, probe_first_harmonic]\n",
        common::root().join("pipelines/cantilever.yaml").display()
    );
    std::fs::write(&study, text).unwrap();
    let out = dir.join("out");
    run_study(&study, &out);
    let rows = table_without_times(&out.join("study.csv"));
    let f = |name: &str| -> Vec<f64> {
        column(&rows, name)
            .iter()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let (f1, f2) = (f("natural_frequency_1"), f("natural_frequency_2"));
    let (e, nu, rho) = (210.0e9_f64, 0.3_f64, 7800.0_f64);
    let beam = |l: f64, h: f64| {
        1.8751_f64.powi(2) / (2.0 * std::f64::consts::PI)
            * (e / (1.0 - nu * nu) * h * h / 12.0 / rho).sqrt()
            / (l * l)
    };
    for (i, (l, h)) in [(1.0, 0.02), (1.0, 0.04), (0.8, 0.02)].iter().enumerate() {
        let expected = beam(*l, *h);
        assert!(
            (f1[i] / expected - 1.0).abs() < 0.002,
            "L = {l}, h = {h}: f1 = {} Hz, Euler–Bernoulli {expected} Hz",
            f1[i]
        );
    }
    assert!((f1[1] / f1[0] / 2.0 - 1.0).abs() < 0.002, "{f1:?}");
    assert!((f1[2] / f1[0] * 0.64 - 1.0).abs() < 0.002, "{f1:?}");
    let ratio = f2[0] / f1[0];
    assert!((ratio / 6.267 - 1.0).abs() < 0.005, "f2/f1 = {ratio}");
}

/// TEST GOAL: along a mesh-size ladder the meshes differ, so the displacement L2 error is
/// summed over the nodes both meshes have (fewer than the coarse mesh's nodes, at least the
/// geometry's points), is finite and positive for the coarse rung and zero for the reference.
#[test]
fn displacement_l2_error_across_different_meshes_uses_their_shared_nodes() {
    let dir = common::temp_out("study-accuracy-meshes");
    let study = strip_study(
        &dir,
        "accuracy:\n  ladders:\n    - {key: geometry.parameters.lc, values: [0.005, 0.0025]}\n",
    );
    let out = dir.join("out");
    run_study(&study, &out);
    let rows = table_without_times(&out.join("accuracy.csv"));
    let number = |name: &str| -> Vec<f64> {
        column(&rows, name)
            .iter()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let (e, nodes, dofs) = (
        number("error_displacement_l2"),
        number("displacement_l2_nodes"),
        number("free_dofs"),
    );
    assert!(e[0] > 0.0 && e[0] < 1.0 && e[1] == 0.0, "{e:?}");
    assert!(
        nodes[0] >= 5.0 && nodes[0] < dofs[0] / 2.0 && nodes[1] > dofs[0] / 2.0,
        "shared nodes {nodes:?}, free dofs {dofs:?}"
    );
}

/// TEST GOAL: a parameter may take string values (`contact.mass: [redistributed, lumped]`):
/// in a grid with a numeric gap every point runs with its mass model (lumped and redistributed
/// give different amplitudes), the plots against the gap have a line per mass model, the
/// plots against the mass model have a categorical axis (its values as tick labels, left to
/// right in the study's order, each point drawn above its value's tick at the table's value,
/// read back from the SVG) and no heat map is drawn over a string axis; in a list, strings holding a comma or a quote (here
/// geometry files so named) are quoted in study.csv (RFC 4180), and a Latin hypercube refuses
/// values (exit 2).
#[test]
fn string_valued_parameters_vary_keys_whose_values_are_words() {
    let dir = common::temp_out("study-strings");
    let study = strip_study(
        &dir,
        "parameters:\n  - {key: geometry.parameters.gap, values: [1.0e-7, 2.0e-7], unit: m}\n  - {key: contact.mass, values: [redistributed, lumped]}\n",
    );
    let out = dir.join("grid");
    run_study(&study, &out);
    let rows = table_without_times(&out.join("study.csv"));
    assert_eq!(
        column(&rows, "contact.mass"),
        ["redistributed", "lumped", "redistributed", "lumped"]
    );
    let amplitude = column(&rows, "probe_first_harmonic");
    assert!(
        amplitude[0] != amplitude[1] && amplitude[2] != amplitude[3],
        "the mass model changes the answer: {amplitude:?}"
    );
    let svg = std::fs::read_to_string(out.join("plots/probe_first_harmonic_vs_gap.svg")).unwrap();
    assert!(svg.contains("mass = lumped") && svg.contains("mass = redistributed"));
    assert!(!out.join("plots/probe_first_harmonic_heatmap.svg").exists());
    // Against the string parameter: a categorical axis, each point above its value's tick.
    let plot = CategoricalPlot::read(&out.join("plots/probe_first_harmonic_vs_mass.svg"));
    let names: Vec<&str> = plot.ticks.iter().map(|t| t.0.as_str()).collect();
    assert_eq!(
        names,
        ["redistributed", "lumped"],
        "tick labels left to right"
    );
    // Two gaps × two mass models, in the two series' colours (the warned points' markers,
    // a third colour, sit over some of them: `study_plots_mark_the_points_whose_run_warned`).
    let series = plot
        .circles
        .iter()
        .filter(|c| c.2 == "#1F77B4" || c.2 == "#D62728")
        .count();
    assert_eq!(series, 4, "two gaps × two mass models");
    let (gaps, masses) = (
        column(&rows, "geometry.parameters.gap"),
        column(&rows, "contact.mass"),
    );
    for (colour, gap) in [("#1F77B4", "1e-7"), ("#D62728", "2e-7")] {
        for (mass, tick_x) in &plot.ticks {
            let row = (0..4)
                .find(|&i| gaps[i] == gap && &masses[i] == mass)
                .unwrap();
            let expected: f64 = amplitude[row].parse().unwrap();
            let drawn = plot
                .circles
                .iter()
                .find(|c| c.2 == colour && (c.0 - tick_x).abs() <= 1.0)
                .unwrap_or_else(|| panic!("no {colour} point above `{mass}`: {:?}", plot.circles));
            let value = plot.value_at(drawn.1);
            assert!(
                (value - expected).abs() <= 0.01 * plot.y_span,
                "gap {gap}, {mass}: drawn {value:e}, table {expected:e}"
            );
        }
    }

    // Geometry files named with a comma and with quotes: strings the CSV must quote.
    let geo = common::root().join("geometries/strip_wall.geo");
    let (one, two) = (dir.join("strip, one.geo"), dir.join("strip \"two\".geo"));
    std::fs::copy(&geo, &one).unwrap();
    std::fs::copy(&geo, &two).unwrap();
    let study = strip_study(
        &dir,
        &format!(
            "design: list\nparameters:\n  - {{key: geometry.file, values: ['{}', '{}']}}\n  - {{key: contact.mass, values: [lumped, redistributed]}}\n",
            one.display(),
            two.display()
        ),
    );
    let out = dir.join("list");
    run_study(&study, &out);
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    let quoted = |path: &Path| format!("\"{}\"", path.display().to_string().replace('"', "\"\""));
    assert!(
        lines[1].starts_with(&format!("0,{},lumped,", quoted(&one))),
        "{csv}"
    );
    assert!(
        lines[2].starts_with(&format!("1,{},redistributed,", quoted(&two))),
        "{csv}"
    );
    assert!(lines[1..].iter().all(|l| l.contains(",ok,")), "{csv}");

    let study = strip_study(
        &dir,
        "design: {latin_hypercube: {samples: 2}}\nparameters:\n  - {key: contact.mass, values: [lumped, redistributed]}\n",
    );
    let o = run(&["study", study.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("range"), "{}", stderr(&o));
}

/// TEST GOAL: the accuracy table of docs/verification.md is what the shipped study
/// (studies/strip_accuracy.yaml) computes: every rung, in order, with its first-harmonic,
/// peak-to-peak and displacement L2 errors within a factor 2 of the documented ones (the
/// references exactly 0). Reads the table from the document, so it cannot drift from the study.
#[test]
fn shipped_strip_accuracy_study_errors_are_the_documented_table() {
    let readme = std::fs::read_to_string(common::root().join("docs/verification.md")).unwrap();
    let header = "| probe 1st-harmonic error | probe peak-to-peak error | displacement L2 error |";
    let at = readme
        .find(header)
        .expect("the accuracy table of docs/verification.md");
    let table: Vec<Vec<String>> = readme[at..]
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect()
        })
        .collect();
    let out = common::temp_out("study-shipped-accuracy");
    run_ok(&[
        "study",
        "studies/strip_accuracy.yaml",
        "-q",
        "--out",
        out.to_str().unwrap(),
    ]);
    let rows = table_without_times(&out.join("accuracy.csv"));
    assert_eq!(rows.len() - 1, table.len(), "one documented row per rung");
    let columns = [
        (4, "error_probe_first_harmonic"),
        (5, "error_probe_peak_to_peak"),
        (6, "error_displacement_l2"),
    ];
    for (i, readme_row) in table.iter().enumerate() {
        assert_eq!(column(&rows, "ladder")[i], readme_row[0]);
        let value: f64 = column(&rows, "value")[i].parse().unwrap();
        assert_eq!(
            value,
            readme_row[1].parse::<f64>().unwrap(),
            "{readme_row:?}"
        );
        for (c, name) in columns {
            let measured: f64 = column(&rows, name)[i].parse().unwrap();
            let ok = match readme_row[c].as_str() {
                "(reference)" => measured == 0.0,
                written => {
                    let r = measured / written.parse::<f64>().unwrap();
                    (0.5..=2.0).contains(&r)
                }
            };
            assert!(ok, "{name} of {readme_row:?}: measured {measured}");
        }
    }
}

/// A study plot against a categorical axis, read back from its SVG: the x tick labels (text,
/// pixel x) left to right, the data markers (pixel x, pixel y, fill) and the y axis's map
/// from pixels to values (a least-squares line through its numeric tick labels).
struct CategoricalPlot {
    ticks: Vec<(String, f64)>,
    circles: Vec<(f64, f64, String)>,
    y_map: (f64, f64),
    y_span: f64,
}

impl CategoricalPlot {
    fn read(path: &Path) -> Self {
        let text = std::fs::read_to_string(path).unwrap();
        let doc = roxmltree::Document::parse(&text).expect("the plot is XML");
        let num = |n: &roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
        let (mut labels, mut y_ticks, mut circles) = (Vec::new(), Vec::new(), Vec::new());
        for n in doc.descendants().filter(|n| n.is_element()) {
            match n.tag_name().name() {
                "text" => {
                    let content = n.text().unwrap_or_default().trim().to_string();
                    match (n.attribute("text-anchor"), content.parse::<f64>()) {
                        (Some("end"), Ok(v)) => y_ticks.push((num(&n, "y"), v)),
                        (Some("middle"), Err(_)) => {
                            labels.push((content, num(&n, "x"), num(&n, "y")))
                        }
                        _ => {}
                    }
                }
                "circle" => circles.push((
                    num(&n, "cx"),
                    num(&n, "cy"),
                    n.attribute("fill").unwrap().to_string(),
                )),
                _ => {}
            }
        }
        // The x tick labels: the row of middle-anchored texts lowest but for the axis title.
        let mut rows: Vec<f64> = labels.iter().map(|l| l.2).collect();
        rows.sort_by(f64::total_cmp);
        rows.dedup();
        let tick_row = rows[rows.len() - 2];
        let mut ticks: Vec<(String, f64)> = labels
            .into_iter()
            .filter(|l| l.2 == tick_row)
            .map(|l| (l.0, l.1))
            .collect();
        ticks.sort_by(|a, b| a.1.total_cmp(&b.1));
        let n = y_ticks.len() as f64;
        let (mp, mv) = y_ticks
            .iter()
            .fold((0.0, 0.0), |(a, b), t| (a + t.0 / n, b + t.1 / n));
        let (sxy, sxx) = y_ticks.iter().fold((0.0, 0.0), |(a, b), t| {
            (a + (t.0 - mp) * (t.1 - mv), b + (t.0 - mp) * (t.0 - mp))
        });
        let slope = sxy / sxx;
        let values: Vec<f64> = y_ticks.iter().map(|t| t.1).collect();
        let y_span = values.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - values.iter().cloned().fold(f64::INFINITY, f64::min);
        CategoricalPlot {
            ticks,
            circles,
            y_map: (mv - slope * mp, slope),
            y_span,
        }
    }

    fn value_at(&self, pixel_y: f64) -> f64 {
        self.y_map.0 + self.y_map.1 * pixel_y
    }
}

/// TEST GOAL: a study does not hide what its points warned of. On the 0.5%-damped reference
/// strip, whose answer at H = 15 depends on c (1.4% at c/3, measured; the strip has two
/// periodic states there, contact_scenes.rs
/// `lightly_damped_strip_has_two_periodic_states_at_one_h`), the accuracy study over H marks
/// that rung in the status column, prints its warning under the table with a line on what
/// it means for its error (measured 2.4% in the probe's amplitude against H = 40, where
/// H = 20 has 0.73%; held within 2× each, and more than twice H = 20's), keeps it in
/// accuracy.csv's last column, marks it on the plot and, where it is the cheapest rung
/// within `--tolerance`, says so there; the H = 20 rung, which did not warn, keeps "ok" and
/// an empty column. A parameter study over the damping writes each point's warnings into
/// study.csv's last column (the 5%-damped point none) and counts them.
/// A ladder rung with an injected wall time and first-measure error.
fn rung(value: f64, seconds: f64, error: f64, warned: bool) -> hbcontact::study::accuracy::Rung {
    hbcontact::study::accuracy::Rung {
        key: "harmonic_balance.harmonics".into(),
        value,
        status: "ok".into(),
        exit_class: None,
        message: None,
        seconds,
        peak_memory: f64::NAN,
        free_dofs: 1.0,
        newton_iterations: 1.0,
        values: vec![1.0; 4],
        errors: vec![error; 5],
        l2_nodes: 0,
        warnings: if warned {
            vec!["depends on c".into()]
        } else {
            vec![]
        },
        dir: std::path::PathBuf::new(),
        is_reference: false,
    }
}

/// TEST GOAL (issue #51): the cheapest rung within a tolerance does not depend on the host's
/// load. Rungs whose wall times are within `TIME_NOISE` (1.5×) of the least are tied and the
/// first in the study's order is named, the others listed as tied; a rung more than 1.5×
/// slower is not tied; a rung beyond the tolerance never counts; `warned` follows the named
/// rung. Times are injected, so the outcome is the same on any machine.
#[test]
fn the_cheapest_rung_is_the_first_of_those_within_the_timing_noise() {
    use hbcontact::study::accuracy::AccuracyReport;
    use hbcontact::study::spec::Reference;
    let report = |rungs| AccuracyReport {
        reference: Reference::Finest,
        rungs,
    };
    let mut reference = rung(40.0, 0.9, 0.0, false);
    reference.is_reference = true;
    // H = 15 measured slower than H = 20, within the noise: H = 15 is named, and warned.
    let tied = report(vec![
        rung(15.0, 0.232, 0.024, true),
        rung(20.0, 0.197, 0.0073, false),
        reference.clone(),
    ]);
    let c = &tied.cheapest(5e-2)[0];
    assert_eq!(c.rung.as_ref().map(|r| r.1), Some(15.0));
    assert!(c.warned);
    assert_eq!(c.tied, vec!["harmonics = 20".to_string()]);
    // H = 15 more than 1.5× slower: H = 20 is named alone, not warned.
    let apart = report(vec![
        rung(15.0, 0.31, 0.024, true),
        rung(20.0, 0.2, 0.0073, false),
        reference.clone(),
    ]);
    let c = &apart.cheapest(5e-2)[0];
    assert_eq!(c.rung.as_ref().map(|r| r.1), Some(20.0));
    assert!(!c.warned && c.tied.is_empty());
    // At 1% only H = 20 is within: H = 15's lower time does not count.
    let c = &tied.cheapest(1e-2)[0];
    assert_eq!(c.rung.as_ref().map(|r| r.1), Some(20.0));
    assert!(!c.warned && c.tied.is_empty());
    // Nothing but the reference within: no rung.
    assert!(tied.cheapest(1e-3)[0].rung.is_none());
}

#[test]
fn study_and_accuracy_tables_carry_each_points_warnings() {
    let dir = common::temp_out("study-warnings");
    let strip = common::root().join("pipelines/reference_strip.yaml");
    let o = run_ok(&[
        "accuracy",
        strip.to_str().unwrap(),
        "--set",
        "damping.alpha=86",
        "--set",
        "stability.check=false",
        "--ladder",
        "harmonic_balance.harmonics=15,20,40",
        "--out",
        dir.join("accuracy").to_str().unwrap(),
        "--tolerance",
        "5e-2",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    let printed = |h: &str| {
        stdout
            .lines()
            .find(|l| l.starts_with(&format!("| harmonic_balance.harmonics | {h} |")))
            .unwrap_or_else(|| panic!("H = {h}: {stdout}"))
    };
    assert!(printed("15").ends_with("| ok, 1 warning |"), "{stdout}");
    assert!(printed("20").ends_with("| ok |"), "{stdout}");
    assert!(stdout.contains("1 of 3 rungs warned"), "{stdout}");
    // The cheapest rung within 5% is H = 15 or H = 20 (their wall times are within the host's
    // noise; which is named is held with injected times by
    // `the_cheapest_rung_is_the_first_of_those_within_the_timing_noise`), and the line says
    // it warned exactly when it is the warned H = 15.
    let cheapest = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("probe_first_harmonic "))
        .unwrap_or_else(|| panic!("{stdout}"));
    let names_warned = cheapest.contains("harmonics = 15 (");
    assert!(
        names_warned || cheapest.contains("harmonics = 20 ("),
        "{cheapest}"
    );
    assert_eq!(
        cheapest.ends_with("this rung warned (above)"),
        names_warned,
        "{cheapest}"
    );
    assert!(
        stdout.contains("harmonics = 15: the contact response changes by"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(dir.join("accuracy/accuracy.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with(",error,warnings"), "{}", lines[0]);
    let column = |name: &str| lines[0].split(',').position(|c| c == name).unwrap();
    let error = |line: &str| -> f64 {
        let field = line.split(',').nth(column("error_probe_first_harmonic"));
        field.and_then(|v| v.parse().ok()).expect("an error")
    };
    assert!(error(lines[1]) > 2.0 * error(lines[2]), "{text}");
    // The numbers of docs/verification.md, within 2×: 2.4% at H = 15, 0.73% at H = 20.
    assert!((0.012..0.048).contains(&error(lines[1])), "{text}");
    assert!((0.0037..0.0146).contains(&error(lines[2])), "{text}");
    let svg = std::fs::read_to_string(dir.join("accuracy/accuracy.svg")).unwrap();
    assert!(svg.contains("harmonics = 15: warned"), "the plot marks it");
    assert!(!svg.contains("harmonics = 20: warned"));
    assert!(
        lines[1].starts_with("harmonic_balance.harmonics,15,ok,")
            && lines[1].contains("depends on the complementarity parameter"),
        "{text}"
    );
    assert!(
        lines[2].starts_with("harmonic_balance.harmonics,20,ok,") && lines[2].ends_with(",,"),
        "{text}"
    );

    let study = dir.join("damping.yaml");
    std::fs::write(
        &study,
        format!(
            "name: damping\npipeline: {}\nset: {{harmonic_balance.harmonics: 15, stability.check: false}}\nparameters:\n  - {{key: damping.alpha, values: [857.0, 86.0]}}\n",
            strip.display()
        ),
    )
    .unwrap();
    let out = dir.join("damping");
    let o = run_ok(&[
        "study",
        study.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        stderr(&o).contains("2 ok (1 of them warned"),
        "{}",
        stderr(&o)
    );
    let text = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with(",key,warnings"), "{}", lines[0]);
    let row = |alpha: &str| {
        lines[1..]
            .iter()
            .find(|l| l.split(',').nth(1) == Some(alpha))
            .unwrap_or_else(|| panic!("alpha = {alpha}: {text}"))
    };
    assert!(row("857").ends_with(','), "{text}");
    assert!(
        row("86").contains("depends on the complementarity parameter"),
        "{text}"
    );
    let manifest = common::read_json(&out.join("manifest.json"));
    assert_eq!(manifest["warned"], 1, "{manifest}");
}

/// Two points varying the gap, with `threads` in the study file when given.
fn two_point_study(dir: &Path, threads: Option<usize>) -> PathBuf {
    let body =
        "parameters:\n  - {key: geometry.parameters.gap, values: [1.0e-7, 2.0e-7], unit: m}\n";
    let body = match threads {
        Some(t) => format!("threads: {t}\n{body}"),
        None => body.to_string(),
    };
    strip_study(dir, &body)
}

/// TEST GOAL: `study --threads 1000000` (which started that many threads) and a study file's
/// `threads: 1000` run at most one point per core: each warns "threads = N is more than the
/// C cores here: running C points at once", completes with every point ok, and its manifest
/// records C threads.
#[test]
fn threads_beyond_the_cores_are_cut_to_them_with_a_warning() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let dir = common::temp_out("study-threads");
    let warning = |n: usize| {
        format!("threads = {n} is more than the {cores} cores here: running {cores} points at once")
    };
    let from_flag = two_point_study(&dir.join("flag"), None);
    let from_file = two_point_study(&dir.join("file"), Some(1000));
    for (study, extra, n) in [
        (&from_flag, vec!["--threads", "1000000"], 1_000_000),
        (&from_file, vec![], 1000),
    ] {
        let out = study.parent().unwrap().join("out");
        let mut args = vec![
            "study",
            study.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = run_ok(&args);
        assert!(stderr(&o).contains(&warning(n)), "{}", stderr(&o));
        let rows = table_without_times(&out.join("study.csv"));
        assert!(
            column(&rows, "status").iter().all(|s| s == "ok"),
            "{rows:?}"
        );
        assert_eq!(rows.len(), 3, "{rows:?}");
        let manifest = common::read_json(&out.join("manifest.json"));
        assert_eq!(manifest["execution"]["threads"], cores);
    }
}

/// TEST GOAL: study.csv writes integers as integers: the harmonics varied (4, 8) and the
/// Newton iterations are written `4`, `8`, `7`, not `4e0`, `8e0`, `7e0`; a fraction keeps its
/// shortest exact form (the gap 1e-7), and the numbers read back to the values (issue #50).
#[test]
fn study_csv_writes_integers_as_integers() {
    let dir = common::temp_out("study-integers");
    let study = strip_study(
        &dir,
        "parameters:\n  - {key: harmonic_balance.harmonics, values: [4, 8]}\noutputs: [newton_iterations, peak_contact_force]\n",
    );
    let out = dir.join("out");
    run_study(&study, &out);
    let rows = table_without_times(&out.join("study.csv"));
    assert_eq!(column(&rows, "harmonic_balance.harmonics"), ["4", "8"]);
    for n in column(&rows, "newton_iterations") {
        assert!(
            !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()),
            "newton_iterations {n:?} is not written as an integer: {rows:?}"
        );
    }
    for f in column(&rows, "peak_contact_force") {
        assert!(f.parse::<f64>().is_ok_and(|v| v > 0.0), "{f:?}");
    }
    use hbcontact::output::tables::csv_number;
    assert_eq!(csv_number(8.0), "8");
    assert_eq!(csv_number(-3.0), "-3");
    assert_eq!(csv_number(1000.0), "1000");
    assert_eq!(csv_number(1e-7), "1e-7");
    assert_eq!(csv_number(1.5e5 + 0.25), "1.5000025e5");
    assert_eq!(csv_number(1e20), "1e20");
    assert_eq!(csv_number(f64::NAN), "");
}

/// The keys of a finished study's points, in table order (from its manifest).
fn point_keys(out: &Path) -> Vec<String> {
    let m = common::read_json(&out.join("manifest.json"));
    m["point_keys"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_str().unwrap().to_string())
        .collect()
}

/// TEST GOAL: a point record (points/<key>/point.json) read back is validated like user
/// input: a record tampered with as issue #46 found (`probe_first_harmonic = 1e308` and
/// `status: "weird"`, which went into study.csv), a record of another point (its key), an
/// unknown exit class, an output of the wrong range, or a file larger than any record makes
/// both `study` and `study --merge` fail with exit 2 naming the file, the field and the fix
/// (delete the point's folder), and write no table; restoring the record lets the merge
/// publish the table again.
#[test]
fn tampered_point_records_are_refused_naming_the_file_and_field() {
    let dir = common::temp_out("study-tampered-records");
    let study = two_point_study(&dir, None);
    let out = dir.join("out");
    run_study(&study, &out);
    let key = point_keys(&out)[1].clone();
    let record_path = out.join("points").join(&key).join("point.json");
    let original = std::fs::read_to_string(&record_path).unwrap();
    let record: serde_json::Value = serde_json::from_str(&original).unwrap();
    let edited = |pointer: &str, value: serde_json::Value| {
        let mut r = record.clone();
        *r.pointer_mut(pointer)
            .unwrap_or_else(|| panic!("{pointer}")) = value;
        serde_json::to_string_pretty(&r).unwrap()
    };
    let failed = {
        let mut r = record.clone();
        r["status"] = "failed".into();
        r["exit_class"] = "mystery".into();
        r["exit_code"] = 2.into();
        r["error"] = "oops".into();
        serde_json::to_string_pretty(&r).unwrap()
    };
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "1e308",
            edited("/outputs/probe_first_harmonic", serde_json::json!(1e308)),
            "`outputs.probe_first_harmonic` = 1e308",
        ),
        (
            "weird status",
            edited("/status", "weird".into()),
            "`status` is \"weird\"",
        ),
        (
            "another key",
            edited("/key", "0123456789abcdef".into()),
            "`key` is \"0123456789abcdef\"",
        ),
        ("unknown exit class", failed, "`exit_class` is \"mystery\""),
        (
            "contact fraction",
            edited("/outputs/contact_fraction", serde_json::json!(1.5)),
            "`outputs.contact_fraction` = 1.5e0 is not in [0, 1]",
        ),
        (
            "huge file",
            format!("{}{}", original, " ".repeat(2 << 20)),
            "larger than 1 MiB",
        ),
    ];
    let s = study.to_str().unwrap();
    let o_s = out.to_str().unwrap();
    for (name, text, field) in cases {
        std::fs::write(&record_path, &text).unwrap();
        for extra in [None, Some("--merge")] {
            let mut args = vec!["study", s, "-q", "--out", o_s];
            args.extend(extra);
            let o = run(&args);
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{name} {extra:?}: {e}");
            assert!(
                e.contains(&format!("{key}/point.json")) && e.contains(field),
                "{name} {extra:?}: the error names the file and the field: {e}"
            );
            assert!(
                e.contains(&format!(
                    "delete the folder {}",
                    out.join("points").join(&key).display()
                )),
                "{name} {extra:?}: the error says the fix: {e}"
            );
            assert!(!out.join("study.csv").exists(), "{name}: no table");
        }
    }
    std::fs::write(&record_path, &original).unwrap();
    run_ok(&["study", s, "-q", "--merge", "--out", o_s]);
    let rows = table_without_times(&out.join("study.csv"));
    assert_eq!(column(&rows, "status"), ["ok", "ok"]);
}

/// TEST GOAL: a point record cut short (its JSON unfinished, as a copy that did not finish
/// leaves it; issue #46 found it silently counted missing) is not trusted: `study` says on
/// stderr that the file is cut short and that it runs the point again, then runs exactly
/// that point (the others are skipped) and exits 0; `study --merge`, which runs nothing,
/// refuses it with exit 2 naming the file and saying how to recompute it.
#[test]
fn a_cut_short_point_record_is_run_again_by_a_study_and_refused_by_a_merge() {
    let dir = common::temp_out("study-cut-short-record");
    let study = two_point_study(&dir, None);
    let out = dir.join("out");
    run_study(&study, &out);
    let key = point_keys(&out)[0].clone();
    let record_path = out.join("points").join(&key).join("point.json");
    let original = std::fs::read(&record_path).unwrap();
    std::fs::write(&record_path, &original[..original.len() / 2]).unwrap();
    let (s, o_s) = (study.to_str().unwrap(), out.to_str().unwrap());
    let merged = run(&["study", s, "-q", "--merge", "--out", o_s]);
    let e = stderr(&merged);
    assert_eq!(merged.status.code(), Some(2), "{e}");
    assert!(
        e.contains(&format!("{key}/point.json is cut short")) && e.contains("without --merge"),
        "{e}"
    );
    let o = run_ok(&["study", s, "--out", o_s]);
    let e = stderr(&o);
    assert!(
        e.contains(&format!("{key}/point.json is cut short"))
            && e.contains("running the point again"),
        "{e}"
    );
    let m = common::read_json(&out.join("manifest.json"));
    assert_eq!(
        (
            m["execution"]["ran"].as_u64(),
            m["execution"]["skipped"].as_u64()
        ),
        (Some(1), Some(1))
    );
    let record = common::read_json(&record_path);
    assert_eq!(record["status"], "ok");
}

/// TEST GOAL: `hbcontact accuracy` without `--ladder` climbs the pipeline's harmonics H/4,
/// H/2, H, 2H when the scene has contact (the strip: H = 20 gives 5, 10, 20, 40) and element
/// order 1, 2 always (the quickstart, without contact, climbs that alone), one rung at a
/// time, into `<output.directory>-accuracy`; a ladder of one value is refused against its
/// own last rung (naming `--ladder`) and taken against a time-marching reference.
#[test]
fn accuracy_without_ladders_climbs_the_harmonics_with_contact_and_the_element_order() {
    use hbcontact::study::accuracy::{default_ladders, from_ladders};
    use hbcontact::study::spec::{Ladder, Reference};
    let strip = hbcontact::pipeline::load_pipeline(Path::new("pipelines/strip_wall.yaml"), &[])
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(strip.harmonic_balance.harmonics, 20);
    let ladders = default_ladders(&strip);
    let found: Vec<(&str, &[f64])> = ladders
        .iter()
        .map(|l| (l.key.as_str(), l.values.as_slice()))
        .collect();
    assert_eq!(
        found,
        [
            ("harmonic_balance.harmonics", &[5.0, 10.0, 20.0, 40.0][..]),
            ("geometry.order", &[1.0, 2.0][..])
        ]
    );
    let quick = hbcontact::pipeline::load_pipeline(Path::new("pipelines/quickstart.yaml"), &[])
        .unwrap_or_else(|e| panic!("{e}"));
    let ladders = default_ladders(&quick);
    assert_eq!(ladders.len(), 1);
    assert_eq!(ladders[0].key, "geometry.order");

    let set = vec!["harmonic_balance.harmonics=8".to_string()];
    let spec = from_ladders(&strip, &set, Vec::new(), Reference::Finest, None).unwrap();
    let mut expected = strip.output.directory.clone().into_os_string();
    expected.push("-accuracy");
    assert_eq!(spec.out, PathBuf::from(expected));
    assert_eq!(spec.threads, Some(1));
    assert_eq!(spec.set, set);
    assert_eq!(spec.pipeline, strip.source);
    assert_eq!(spec.accuracy.as_ref().unwrap().ladders.len(), 2);

    let one = || {
        vec![Ladder {
            key: "harmonic_balance.harmonics".into(),
            values: vec![10.0],
        }]
    };
    let e = from_ladders(&strip, &[], one(), Reference::Finest, None)
        .expect_err("one rung cannot be its own reference")
        .to_string();
    assert!(
        e.contains("--ladder harmonic_balance.harmonics") && e.contains("at least 2"),
        "{e}"
    );
    let named = Path::new("elsewhere");
    let spec = from_ladders(&strip, &[], one(), Reference::Transient, Some(named)).unwrap();
    assert_eq!(spec.out, named);
    assert_eq!(spec.point_count(), 2, "one rung and the marched reference");
}

/// TEST GOAL: a study's plots mark the points whose run warned (their legend entry
/// `table::WARNED`, one marker per such point over the curve), and only where some did: the
/// cantilever on its stop at f1 over the stop's distance (studies/cantilever_gap.yaml, every
/// point warned of the half-power band) has them; the linear bracket over its drive frequency,
/// whose runs warn of nothing, has none.
#[test]
fn study_plots_mark_the_points_whose_run_warned() {
    use hbcontact::study::table::WARNED;
    let out = common::temp_out("study-warned-marks");
    run_ok(&[
        "study",
        "studies/cantilever_gap.yaml",
        "-q",
        "--out",
        out.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let warned = text.lines().skip(1).filter(|l| !l.ends_with(',')).count();
    assert_eq!(warned, 4, "every point warned:\n{text}");
    let svg = std::fs::read_to_string(out.join("plots/probe_first_harmonic_vs_stop_distance.svg"))
        .unwrap();
    assert!(svg.contains(WARNED), "no `{WARNED}` legend");
    // One line series (no markers) and the warned points: their markers and the legend's.
    let circles = svg.matches("<circle").count();
    assert!(
        circles > warned,
        "{circles} circles for {warned} warned points"
    );

    let dir = common::temp_out("study-unwarned-marks");
    std::fs::create_dir_all(&dir).unwrap();
    let study = dir.join("study.yaml");
    let pipeline = common::root().join("pipelines/quickstart.yaml");
    let body = "parameters:\n  - {key: harmonic_balance.frequency, values: [400.0, 500.0, 600.0]}\noutputs: [probe_first_harmonic]\n";
    std::fs::write(
        &study,
        format!("name: quiet\npipeline: {}\n{body}", pipeline.display()),
    )
    .unwrap();
    let plain = dir.join("out");
    run_study(&study, &plain);
    let text = std::fs::read_to_string(plain.join("study.csv")).unwrap();
    assert!(
        text.lines().skip(1).all(|l| l.ends_with(',')),
        "no point warned:\n{text}"
    );
    let svg =
        std::fs::read_to_string(plain.join("plots/probe_first_harmonic_vs_frequency.svg")).unwrap();
    assert!(!svg.contains(WARNED), "a mark without a warning");
}
