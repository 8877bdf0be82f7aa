//! Hostile or mistaken input is bounded (issue #46): valid values that would make a command
//! exhaust the machine are refused before it allocates, with exit 2 and a message naming the
//! estimate and what to change.

mod common;

use std::process::Output;

/// `hbcontact <command> <pipeline> --quiet --out <tagged dir> --set …`.
fn hbcontact(command: &str, pipeline: &str, tag: &str, sets: &[&str]) -> Output {
    let dir = common::temp_out(&format!("bounds-{tag}"));
    let directory = format!("output.directory={}", dir.display());
    let mut args = vec![command, pipeline, "--quiet", "--set", &directory];
    for s in sets {
        args.extend(["--set", s]);
    }
    common::hbcontact(&args)
}

/// Exit 2, no panic, and a message that gives the march's estimate and names `advice`.
fn assert_march_refused(output: &Output, advice: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for part in [
        "time marching refused before it started",
        "steps per period",
        "of memory",
        advice,
    ] {
        assert!(stderr.contains(part), "no `{part}` in: {stderr}");
    }
}

/// The three valid settings that crashed the time march (a 131 GB allocation, an abort, a
/// capacity overflow), each with the advice its cause calls for.
const CRASHES: [(&str, &str, &[&str], &str); 3] = [
    (
        "strip_wall-beta",
        "pipelines/strip_wall.yaml",
        &["damping.beta=0.5"],
        "Lower damping.beta",
    ),
    (
        "blade_casing-frequency",
        "pipelines/blade_casing.yaml",
        &["harmonic_balance.frequency=0.0007"],
        "higher harmonic_balance.frequency",
    ),
    (
        "soft_contact-beta-density",
        "pipelines/hard/soft_contact.yaml",
        &["damping.beta=3", "material.density=0.0078"],
        "Lower damping.beta",
    ),
];

/// TEST GOAL: each of the three settings that crashed `hbcontact transient` (strip_wall with
/// damping.beta = 0.5; blade_casing at 0.0007 Hz; the soft-contact case with β = 3 s and
/// density 0.0078) now exits 2 before marching, naming the estimated steps per period and
/// memory and the key to change.
#[test]
fn a_march_beyond_the_machine_is_refused_by_transient_naming_the_estimate() {
    for (tag, pipeline, sets, advice) in CRASHES {
        let mut sets = sets.to_vec();
        sets.push("stability.check=false");
        let output = hbcontact("transient", pipeline, tag, &sets);
        assert_march_refused(&output, advice);
    }
}

/// TEST GOAL: with `stability.method: march`, `hbcontact run` refuses the same three scenes
/// (its stability check would march) with exit 2 before it solves, saying the march is the
/// stability check's and how to skip it; `hbcontact check` reports the same refusal. With the
/// default Floquet check nothing marches and `check` passes them.
#[test]
fn a_stability_march_beyond_the_machine_is_refused_by_run_and_check() {
    for (tag, pipeline, sets, advice) in CRASHES {
        let default = hbcontact("check", pipeline, &format!("{tag}-floquet"), sets);
        let stderr = String::from_utf8_lossy(&default.stderr);
        assert!(default.status.success(), "{stderr}");
        assert!(
            !stderr.contains("stability check of `run` marches"),
            "{stderr}"
        );
        let mut sets = sets.to_vec();
        sets.push("stability.method=march");
        for command in ["run", "check"] {
            let output = hbcontact(command, pipeline, &format!("{tag}-{command}"), &sets);
            assert_march_refused(&output, advice);
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert!(stderr.contains("stability.check: false"), "{stderr}");
        }
    }
}

/// TEST GOAL: with the stability check off, `check` still passes a scene whose transient
/// march is beyond the machine, warning that `hbcontact transient` would stop.
#[test]
fn check_warns_when_only_the_transient_command_would_be_refused() {
    let (_, pipeline, sets, _) = CRASHES[0];
    let mut args = vec![
        "check",
        pipeline,
        "--set",
        "output.directory=output/test-runs/bounds-warn",
    ];
    for s in sets.iter().chain(&["stability.check=false"]) {
        args.extend(["--set", s]);
    }
    let output = common::hbcontact(&args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains("`hbcontact transient` would stop: time marching refused"),
        "{stderr}"
    );
}
