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
