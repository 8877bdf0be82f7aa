//! No user file is ever lost (issue #46): every subcommand that writes a folder refuses a
//! folder it did not write (exit 2, naming the folder and `--force`), `--force` moves such a
//! folder aside whole, a run replaces its own previous output, and look-alike partial folders
//! without the tool's marker survive (src/output/staging.rs).

mod common;

use std::path::{Path, PathBuf};

/// A user's folder: a file and a subfolder with a file, no marker.
fn user_folder(dir: &Path) {
    std::fs::create_dir_all(dir.join("chapter")).unwrap();
    std::fs::write(dir.join("thesis.txt"), b"thesis").unwrap();
    std::fs::write(dir.join("chapter/figure.csv"), b"1,2").unwrap();
}

fn intact(dir: &Path) -> bool {
    std::fs::read(dir.join("thesis.txt")).is_ok_and(|b| b == b"thesis")
        && std::fs::read(dir.join("chapter/figure.csv")).is_ok_and(|b| b == b"1,2")
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A short, coarse sweep of the strip against its wall.
const SHORT_SWEEP: [&str; 8] = [
    "--set",
    "geometry.parameters.lc=0.025",
    "--set",
    "stability.check=false",
    "--set",
    "sweep.from=1550",
    "--set",
    "sweep.to=1560",
];

const QUICK: [&str; 4] = [
    "--set",
    "geometry.mesh_size=0.01",
    "--set",
    "stability.check=false",
];

/// TEST GOAL: `run`, `transient`, `modes` and `sweep` pointed at a user's folder (by `--out`)
/// refuse with exit 2 naming the folder and `--force`, and leave every file and subfolder
/// in it; `study` and `compare` write beside the user's files without touching them; the
/// same folder named by `output.directory` is refused too.
#[test]
fn a_users_folder_survives_every_subcommand_pointed_at_it() {
    let root = common::temp_out("ownership-user");
    let user = root.join("userdata");
    user_folder(&user);
    let out = user.to_str().unwrap();
    let strip = SHORT_SWEEP;
    let with = |cmd: &'static str, pipeline: &'static str, sets: &[&'static str]| {
        [&[cmd, pipeline, "--out", out][..], sets].concat()
    };
    let cases: Vec<Vec<&str>> = vec![
        with("run", "pipelines/quickstart.yaml", &QUICK),
        with("transient", "pipelines/quickstart.yaml", &QUICK),
        with("modes", "pipelines/quickstart.yaml", &QUICK),
        with("sweep", "pipelines/strip_sweep.yaml", &strip),
    ];
    for args in &cases {
        let o = common::hbcontact(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(out) && e.contains("--force") && e.contains("thesis.txt"),
            "{args:?}: {e}"
        );
        assert!(intact(&user), "{args:?} touched the user's folder");
    }
    let directory = format!("output.directory={out}");
    let o = common::hbcontact(
        &[
            &["run", "pipelines/quickstart.yaml", "--set", &directory][..],
            &QUICK,
        ]
        .concat(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(intact(&user));

    // compare writes its three entries beside the user's files.
    let hb = root.join("hb");
    let tr = root.join("tr");
    for (cmd, dir) in [("run", &hb), ("transient", &tr)] {
        let o = common::hbcontact(&[
            cmd,
            "pipelines/strip_wall.yaml",
            "-q",
            "--out",
            dir.to_str().unwrap(),
            "--set",
            "geometry.parameters.lc=0.025",
            "--set",
            "stability.check=false",
        ]);
        assert!(o.status.success(), "{cmd}: {}", stderr(&o));
    }
    let o = common::hbcontact(&[
        "compare",
        hb.to_str().unwrap(),
        tr.to_str().unwrap(),
        "--out",
        out,
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(intact(&user) && user.join("compare.json").exists());
    // A user's own compare.json in a folder without the marker is refused.
    let other = root.join("other");
    user_folder(&other);
    std::fs::write(other.join("compare.json"), b"mine").unwrap();
    let o = common::hbcontact(&[
        "compare",
        hb.to_str().unwrap(),
        tr.to_str().unwrap(),
        "--out",
        other.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read(other.join("compare.json")).unwrap(), b"mine");

    // A study writes its entries beside the user's files; one whose table is the user's own
    // (study.csv, no marker) is refused.
    let study = root.join("tiny.yaml");
    std::fs::write(
        &study,
        format!(
            "name: tiny\npipeline: {}\nset: {{geometry.mesh_size: 0.01}}\nparameters:\n  - {{key: harmonic_balance.frequency, values: [400.0, 500.0]}}\noutputs: [probe_first_harmonic]\n",
            common::root().join("pipelines/quickstart.yaml").display()
        ),
    )
    .unwrap();
    let o = common::hbcontact(&["study", study.to_str().unwrap(), "--out", out, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(intact(&user) && user.join("study.csv").exists());
    std::fs::write(other.join("study.csv"), b"mine").unwrap();
    let o = common::hbcontact(&[
        "study",
        study.to_str().unwrap(),
        "--out",
        other.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read(other.join("study.csv")).unwrap(), b"mine");
    assert!(intact(&other));
}

fn moved_aside(parent: &Path, name: &str) -> Vec<PathBuf> {
    std::fs::read_dir(parent)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with(&format!("{name}.moved-")))
        })
        .collect()
}

/// TEST GOAL: `--force` moves a user's folder aside whole (to `<name>.moved-<time>`) and
/// writes the results in its place; a second run replaces its own output without `--force`;
/// a file the user adds to that output makes the next run refuse; a sweep's output nested in
/// a run's folder survives the next run; a look-alike `<name>.partial-<dead pid>` folder
/// without the marker, and another target's, survive.
#[test]
fn force_moves_a_users_folder_aside_and_runs_replace_only_their_own() {
    let root = common::temp_out("ownership-force");
    let user = root.join("userdata");
    user_folder(&user);
    let dead = 4_194_400; // above Linux's largest pid_max (2^22)
    let lookalikes = [
        root.join(format!("userdata.partial-{dead}")),
        root.join(format!("notes.partial-{dead}")),
    ];
    for d in &lookalikes {
        std::fs::create_dir_all(d).unwrap();
        std::fs::write(d.join("keep.txt"), b"keep").unwrap();
    }
    let out = user.to_str().unwrap();
    let run = |extra: &[&str]| {
        common::hbcontact(
            &[
                &["run", "pipelines/quickstart.yaml", "-q", "--out", out][..],
                &QUICK,
                extra,
            ]
            .concat(),
        )
    };
    let o = run(&["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let moved = moved_aside(&root, "userdata");
    assert_eq!(moved.len(), 1, "{moved:?}");
    assert!(intact(&moved[0]));
    assert!(user.join("summary.json").exists());
    for d in &lookalikes {
        assert!(d.join("keep.txt").exists(), "{} was removed", d.display());
    }
    // Ours: replaced without --force, nothing moved aside.
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(moved_aside(&root, "userdata").len(), 1);
    // A sweep's output nested in the run's folder survives the next run.
    let nested = user.join("sweep");
    let o = common::hbcontact(
        &[
            &[
                "sweep",
                "pipelines/strip_sweep.yaml",
                "-q",
                "--out",
                nested.to_str().unwrap(),
            ][..],
            &SHORT_SWEEP,
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        nested.join("sweep.csv").exists(),
        "the nested sweep was lost"
    );
    // A file the user adds to our output: refused, kept.
    std::fs::write(user.join("notes.md"), b"mine").unwrap();
    let o = run(&[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("notes.md"), "{}", stderr(&o));
    assert_eq!(std::fs::read(user.join("notes.md")).unwrap(), b"mine");
}
