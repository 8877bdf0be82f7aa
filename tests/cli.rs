//! The command line as a user meets it (issue #50, "a command line that behaves like a good
//! one"): each subcommand's `--help` describes its own options and no other subcommand's, the
//! top-level help lists the exit codes, `check` offers no `--out`, and progress on a stderr
//! that is not a terminal is one line per stage and at most one progress line a second.

mod common;

use std::process::Output;

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
/// subcommand writes by default; the accuracy table is mentioned by `accuracy` alone.
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
        ("sweep", "`<output.directory>/sweep`"),
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
