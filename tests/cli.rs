//! The command line as a user meets it (issue #50, "a command line that behaves like a good
//! one"): each subcommand's `--help` describes its own options and no other subcommand's, the
//! top-level help lists the exit codes, `check` offers no `--out`, progress on a stderr that
//! is not a terminal is one line per stage and at most one progress line a second, naming the
//! frequency, the point or the period and step, and a sweep's resume hint names its folder.

mod common;

use std::process::Output;
use std::time::Instant;

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// `hbcontact <args> --help`, which must succeed.
fn help(args: &[&str]) -> String {
    let mut all = args.to_vec();
    all.push("--help");
    let o = common::hbcontact(&all);
    assert!(o.status.success(), "{all:?}: {}", stderr(&o));
    stdout(&o)
}

/// TEST GOAL: every subcommand's help speaks of that subcommand only: no option reads
/// "(`transient`: …)" or "(for `accuracy` …)" elsewhere; `--out` names the folder that
/// subcommand writes by default; the accuracy table is mentioned by `accuracy` alone; `run`
/// and `sweep` say that `stability.check` switches their stability check off.
#[test]
fn each_subcommands_help_describes_its_own_options_only() {
    let subcommands = [
        "run",
        "transient",
        "sweep",
        "check",
        "accuracy",
        "modes",
        "compare",
        "study",
        "schema",
    ];
    for sub in subcommands {
        let text = help(&[sub]);
        for other in ["(`transient`:", "for `accuracy`", "`transient`: instead"] {
            assert!(!text.contains(other), "`{sub} --help` has {other}:\n{text}");
        }
        if sub != "accuracy" {
            assert!(
                !text.contains("accuracy table"),
                "`{sub} --help` speaks of accuracy:\n{text}"
            );
        }
    }
    let out_default = [
        ("run", "`output.directory`"),
        ("transient", "`<output.directory>-transient`"),
        ("sweep", "`<output.directory>-sweep`"),
        ("modes", "`<output.directory>-modes`"),
        ("accuracy", "`<output.directory>-accuracy`"),
    ];
    for (sub, default) in out_default {
        let text = help(&[sub]);
        let after = text
            .split("--out <DIR>")
            .nth(1)
            .unwrap_or_else(|| panic!("`{sub} --help` has no --out <DIR>:\n{text}"));
        // The option's text: up to the next option's line.
        let mut words = Vec::new();
        for (i, line) in after.lines().enumerate() {
            if i > 0 && line.trim_start().starts_with('-') {
                break;
            }
            words.extend(line.split_whitespace());
        }
        let out = words.join(" ");
        assert!(
            out.contains(&format!("instead of {default}")),
            "`{sub} --help`'s --out does not name {default}: {out}"
        );
    }
    assert!(help(&["accuracy"]).contains("accuracy table"));
    for sub in ["run", "sweep"] {
        assert!(
            help(&[sub]).contains("stability.check"),
            "`{sub} --help` does not say how to skip the stability check"
        );
    }
}

/// TEST GOAL: `hbcontact --help` lists every exit code the command can end with (the codes
/// `Error::exit_code` gives, 0 and 130), one per line.
#[test]
fn the_top_level_help_lists_the_exit_codes() {
    let text = help(&[]);
    let codes = text
        .split("Exit codes:")
        .nth(1)
        .unwrap_or_else(|| panic!("no exit codes in --help:\n{text}"));
    for code in ["0", "2", "3", "4", "5", "6", "130"] {
        assert!(
            codes
                .lines()
                .any(|l| l.trim_start().starts_with(&format!("{code} "))),
            "exit code {code} not listed:\n{codes}"
        );
    }
    let errors = [
        hbcontact::Error::Input("x".into()),
        hbcontact::Error::Model("x".into()),
        hbcontact::Error::NotConverged("x".into()),
        hbcontact::Error::io(std::path::Path::new("x"), std::io::Error::other("x")),
        hbcontact::Error::Interrupted("x".into()),
    ];
    for e in errors {
        let code = format!("{} ", e.exit_code());
        assert!(
            codes.lines().any(|l| l.trim_start().starts_with(&code)),
            "{e:?}'s exit code {code}not listed:\n{codes}"
        );
    }
}

/// TEST GOAL: `check` writes nothing, so it offers no `--out` (nor `--force`): its help lists
/// neither, and a script that passes `--out` is refused by name with exit 2 before anything
/// runs.
#[test]
fn check_offers_no_out_and_refuses_it_by_name() {
    let text = help(&["check"]);
    assert!(
        !text.contains("--out") && !text.contains("--force"),
        "{text}"
    );
    let o = common::hbcontact(&["check", "pipelines/quickstart.yaml", "--out", "somewhere"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("unexpected argument '--out'"),
        "{}",
        stderr(&o)
    );
}

/// The progress lines of stderr: indented, and not gmsh's own output.
fn progress_lines(err: &str) -> Vec<&str> {
    err.lines()
        .filter(|l| l.starts_with("  ") && !l.trim_start().starts_with("gmsh "))
        .collect()
}

/// TEST GOAL: without a terminal each stage of a run is one line with its time (`[check]
/// 0.002 s`, no bare `[check]` before it), the solve too; a stage is named bare only to head
/// the progress lines it shows; the checks made between mesh, assembly and solve are one
/// `[check]` line (issue #50: it was printed twice, then five times), and summary.json's
/// `stage_seconds` names each stage once, the checks' parts summed.
#[test]
fn each_stage_of_a_run_is_one_line_with_its_time_and_check_is_said_once() {
    let out = common::temp_out("cli-stages");
    let o = common::hbcontact(&[
        "run",
        "pipelines/quickstart.yaml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let lines: Vec<&str> = err.lines().collect();
    for stage in ["mesh", "check", "assemble", "solve", "write"] {
        let timed = lines
            .iter()
            .filter(|l| l.starts_with(&format!("[{stage}] ")) && l.ends_with(" s"))
            .count();
        assert_eq!(timed, 1, "`[{stage}] … s` {timed} times:\n{err}");
    }
    for (i, l) in lines.iter().enumerate() {
        if l.starts_with('[') && !l.ends_with(" s") {
            assert!(
                lines.get(i + 1).is_some_and(|n| n.starts_with("  ")),
                "a bare stage line `{l}` heads no progress:\n{err}"
            );
            assert_ne!(*l, "[check]", "{err}");
        }
    }
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let start = text.find("\"stage_seconds\"").expect("stage_seconds");
    let end = start + text[start..].find('}').unwrap();
    let keys: Vec<&str> = text[start..end]
        .lines()
        .skip(1)
        .filter_map(|l| l.trim().split('"').nth(1))
        .collect();
    assert!(
        keys.contains(&"check") && keys.contains(&"mesh"),
        "{keys:?}"
    );
    let unique: std::collections::BTreeSet<&&str> = keys.iter().collect();
    assert_eq!(unique.len(), keys.len(), "a stage named twice: {keys:?}");
}

/// TEST GOAL: a march whose period takes thousands of steps names the period and the step
/// within it (`periods 0/1: period 1: step K/N`, K a multiple of 1024; it used to show
/// nothing for minutes until a period ended), in fewer lines than the reports made (counted,
/// not timed: which report the throttle lets through first depends on the machine's speed),
/// the last state before the stage's time.
#[test]
fn a_long_march_names_its_period_and_step_and_its_lines_are_throttled() {
    let out = common::temp_out("cli-march-progress");
    let start = Instant::now();
    let o = common::hbcontact(&[
        "transient",
        "pipelines/quickstart.yaml",
        "--out",
        out.to_str().unwrap(),
        "--set",
        "damping.beta=0",
        "--set",
        "damping.alpha=100",
        "--set",
        "transient.max_periods=1",
        "--set",
        "output.plots=false",
    ]);
    let seconds = start.elapsed().as_secs_f64();
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    println!("{seconds:.1} s:\n{err}");
    let lines = progress_lines(&err);
    let first = lines
        .first()
        .unwrap_or_else(|| panic!("no progress:\n{err}"));
    // The first line shown: a report every 1024 steps, the first one a throttle lets through.
    let (step, steps) = first
        .strip_prefix("  periods 0/1: period 1: step ")
        .and_then(|rest| rest.split_once('/'))
        .and_then(|(k, n)| Some((k.parse::<usize>().ok()?, n.parse::<usize>().ok()?)))
        .unwrap_or_else(|| panic!("the first line `{first}` names no step"));
    assert!(
        step % 1024 == 0 && step >= 1024 && step <= steps,
        "`{first}`"
    );
    assert!(
        steps >= 2048,
        "{steps} steps a period: too few to show throttling"
    );
    let reports = steps / 1024 + 1;
    assert!(
        lines.len() < reports,
        "{} lines for {reports} reports:\n{err}",
        lines.len()
    );
    let mut seen = std::collections::BTreeSet::new();
    for l in &lines {
        assert!(seen.insert(*l), "`{l}` printed twice:\n{err}");
        assert!(l.starts_with("  periods "), "`{l}`");
    }
    let all: Vec<&str> = err.lines().collect();
    let last = all
        .iter()
        .position(|l| l.starts_with("  periods 1/1: change "));
    let timed = all
        .iter()
        .position(|l| l.starts_with("[march] ") && l.ends_with(" s"));
    assert!(
        matches!((last, timed), (Some(a), Some(b)) if a < b),
        "the march's last state is not before its time:\n{err}"
    );
}

/// TEST GOAL: a sweep stopped short without `--out` prints a resume command without `--out`
/// that names the default folder `<output.directory>-sweep`, and run by a shell as printed it
/// continues the sweep there (issue #50; `sweep_output.rs` covers the hint with `--out`).
#[test]
fn sweep_resume_hint_without_out_names_the_default_folder() {
    let base = common::temp_out("cli-resume-default");
    let directory = format!("output.directory={}", base.join("scene").display());
    let default = base.join("scene-sweep");
    let sets = [
        "geometry.parameters.lc=0.025",
        "sweep.from=1550",
        "sweep.to=1750",
        "stability.check=false",
        "output.plots=false",
        directory.as_str(),
        "sweep.max_points=4",
    ];
    let mut args = vec!["sweep", "pipelines/strip_sweep.yaml"];
    for s in &sets {
        args.extend(["--set", s]);
    }
    let o = common::hbcontact(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = common::read_json(&default.join("sweep.json"));
    let reason = json["stopped"]["reason"].as_str().unwrap().to_string();
    let command = reason
        .split('`')
        .nth(1)
        .unwrap_or_else(|| panic!("{reason}"));
    assert!(!command.contains("--out"), "{command}");
    assert!(command.ends_with(" --resume"), "{command}");
    assert!(
        reason.contains(&format!("into {}", default.display())),
        "{reason}"
    );
    assert!(stdout(&o).contains(command), "{}", stdout(&o));
    let bin = std::path::Path::new(env!("CARGO_BIN_EXE_hbcontact"))
        .parent()
        .unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let resumed = std::process::Command::new("sh")
        .args(["-c", &format!("{command} --quiet --set sweep.max_points=6")])
        .env("PATH", path)
        .current_dir(common::root())
        .output()
        .unwrap();
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    let json = common::read_json(&default.join("sweep.json"));
    assert_eq!(json["rows"].as_array().unwrap().len(), 6);
    assert_eq!(json["resumed_from"], serde_json::json!([3]));
}

/// TEST GOAL: a sweep's progress (stderr not a terminal) is at most one line a second, plus
/// one final state per task, never the same line twice, and each line during the
/// continuation names the frequency, ending with the last point's: the strip sweep's 300
/// points (a few seconds), which factor the dynamic stiffness hundreds of times, used to
/// print `factor 1/11: harmonic 0` for most of them.
#[test]
fn sweep_progress_is_at_most_a_line_a_second_and_names_the_frequency() {
    let out = common::temp_out("cli-sweep-progress");
    let start = Instant::now();
    let o = common::hbcontact(&[
        "sweep",
        "pipelines/strip_sweep.yaml",
        "--out",
        out.to_str().unwrap(),
        "--set",
        "stability.check=false",
        "--set",
        "sweep.max_points=300",
        "--set",
        "output.plots=false",
    ]);
    let seconds = start.elapsed().as_secs_f64();
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let lines = progress_lines(&err);
    println!("{seconds:.1} s:\n{err}");
    // At most one a second, plus each task's last state (factor, Newton, sweep, write).
    assert!(
        lines.len() as f64 <= seconds.ceil() + 5.0,
        "{} progress lines in {seconds:.1} s:\n{err}",
        lines.len()
    );
    let mut seen = std::collections::BTreeSet::new();
    for l in &lines {
        assert!(seen.insert(*l), "`{l}` printed twice:\n{err}");
        if l.contains("sweep ") {
            assert!(l.contains(" Hz"), "`{l}` names no frequency");
        }
    }
    let last = lines
        .iter()
        .rev()
        .find(|l| l.contains("sweep "))
        .unwrap_or_else(|| panic!("no sweep line:\n{err}"));
    let json = common::read_json(&out.join("sweep.json"));
    let rows = json["rows"].as_array().unwrap();
    let end = format!("sweep {}: ", rows.len() - 1);
    assert!(
        last.contains(&end),
        "the last sweep line `{last}` is not the last point's ({end})"
    );
}

/// TEST GOAL: a study's progress names the points as they finish and ends with the count of
/// all of them (`points 4/4: point … done (…)`), at most one line a second besides.
#[test]
fn study_progress_names_the_points_and_ends_with_all_of_them() {
    let dir = common::temp_out("cli-study-progress");
    std::fs::create_dir_all(&dir).unwrap();
    let study = dir.join("study.yaml");
    let pipeline = common::root().join("pipelines/strip_wall.yaml");
    std::fs::write(
        &study,
        format!(
            "name: progress\npipeline: {}\nset: {{geometry.parameters.lc: 0.0025, harmonic_balance.harmonics: 8}}\nparameters:\n  - {{key: geometry.parameters.gap, values: [1.0e-7, 2.0e-7], unit: m}}\n  - {{key: boundaries.loads.0.harmonics.0.cos.0, values: [1.0e5, 1.5e5], unit: Pa}}\n",
            pipeline.display()
        ),
    )
    .unwrap();
    let start = Instant::now();
    let o = common::hbcontact(&[
        "study",
        study.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    let seconds = start.elapsed().as_secs_f64();
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let points: Vec<&str> = progress_lines(&err)
        .into_iter()
        .filter(|l| l.trim_start().starts_with("points "))
        .collect();
    println!("{seconds:.1} s:\n{err}");
    let last = points
        .last()
        .unwrap_or_else(|| panic!("no points line:\n{err}"));
    assert!(
        last.trim_start().starts_with("points 4/4: point ") && last.contains(" done ("),
        "the last points line is not the whole study: {last}\n{err}"
    );
    assert!(points.len() as f64 <= seconds.ceil() + 1.0, "{err}");
}
