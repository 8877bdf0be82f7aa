//! The command line as a user meets it (issue #50, "a command line that behaves like a good
//! one"): each subcommand's `--help` describes its own options and no other subcommand's, the
//! top-level help lists the exit codes, `check` offers no `--out`, and progress on a stderr
//! that is not a terminal is one line per stage and at most one progress line a second.

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
/// 0.002 s`, no bare `[check]` before it), and a stage is named bare only to head the
/// progress lines it shows.
#[test]
fn each_stage_of_a_run_is_one_line_with_its_time() {
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
    let checks = lines.iter().filter(|l| l.starts_with("[check]")).count();
    assert!(checks >= 1, "{err}");
    for (i, l) in lines.iter().enumerate() {
        if l.starts_with('[') && !l.ends_with(" s") {
            assert!(
                lines.get(i + 1).is_some_and(|n| n.starts_with("  ")),
                "a bare stage line `{l}` heads no progress:\n{err}"
            );
            assert_ne!(*l, "[check]", "{err}");
        }
    }
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
