//! Foreign input is data, not code (issue #46): a `.geo` that would run a program, write a
//! file or read one outside its folder is refused before gmsh starts (exit 2, file:line), so
//! its side effect never happens; `--trust-geometry` lets one's own geometry through; a
//! study may not choose the gmsh program; `check` says which gmsh it runs.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

/// A folder with `scene.geo` (tests/data/short_wall.geo with `statement` after its first
/// line, so the statement is on line 4) and `scene.yaml` naming it.
fn scene(tag: &str, statement: &str) -> PathBuf {
    let dir = common::temp_out(&format!("geometry-guard-{tag}"));
    let sub = dir.join("scene");
    std::fs::create_dir_all(&sub).unwrap();
    let base = std::fs::read_to_string(common::root().join("tests/data/short_wall.geo")).unwrap();
    let mut lines: Vec<&str> = base.lines().collect();
    lines.insert(3, statement);
    std::fs::write(sub.join("scene.geo"), lines.join("\n")).unwrap();
    std::fs::write(
        sub.join("scene.yaml"),
        "name: scene\ngeometry: {file: scene.geo}\nmaterial: {youngs_modulus: 210.0e9, poisson_ratio: 0.3, density: 7800.0, model: plane_strain}\nboundaries: {fixed: [right]}\nharmonic_balance: {frequency: 100.0, harmonics: 1}\n",
    )
    .unwrap();
    sub
}

fn check(dir: &Path, extra: &[&str]) -> Output {
    let yaml = dir.join("scene.yaml");
    let directory = format!("output.directory={}", dir.join("out").display());
    let mut args = vec!["check", yaml.to_str().unwrap(), "--set", &directory];
    args.extend(extra);
    common::hbcontact(&args)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// TEST GOAL: each statement that runs a program (SystemCall, NonBlockingSystemCall, Shell,
/// OnelabRun), writes a file (Printf > file, Printf >> file, Save, Print, DeleteFile) or
/// reads one outside the geometry's folder (Include "../…", an absolute Merge) is refused by
/// `check` with exit 2 naming scene.geo:4, and the file it would create does not exist.
#[test]
fn a_geo_that_runs_programs_or_writes_files_is_refused_before_gmsh_runs() {
    let marker =
        |tag: &str| common::root().join(format!("output/test-runs/geometry-guard-{tag}-made"));
    let cases: Vec<(&str, String)> = vec![
        ("systemcall", "SystemCall \"touch {m}\";".into()),
        ("nonblocking", "NonBlockingSystemCall \"touch {m}\";".into()),
        ("shell", "Shell \"touch {m}\";".into()),
        ("onelab", "OnelabRun(\"x\", \"touch {m}\");".into()),
        ("printf", "Printf(\"%g\", lc) > \"{m}\";".into()),
        ("printf-append", "Printf(\"%g\", lc) >> \"{m}\";".into()),
        ("save", "Save \"{m}\";".into()),
        ("print", "Print \"{m}\";".into()),
        ("deletefile", "DeleteFile \"{m}\";".into()),
        ("include", "Include \"../../other/{m}.geo\";".into()),
        ("merge", "Merge \"/etc/hostname\";".into()),
    ];
    for (tag, statement) in cases {
        let m = marker(tag);
        let _ = std::fs::remove_file(&m);
        let dir = scene(tag, &statement.replace("{m}", &m.to_string_lossy()));
        let o = check(&dir, &[]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{tag}: {e}");
        assert!(e.contains("scene.geo:4:"), "{tag}: {e}");
        assert!(e.contains("--trust-geometry"), "{tag}: {e}");
        assert!(!m.exists(), "{tag}: {} was made", m.display());
    }
}

/// TEST GOAL: with `--trust-geometry` the same SystemCall runs (its file is made): the flag
/// is what lets a geometry run a program, nothing in a file can.
#[test]
fn trust_geometry_lets_ones_own_geometry_run_its_statements() {
    let m = common::root().join("output/test-runs/geometry-guard-trusted-made");
    let _ = std::fs::remove_file(&m);
    let dir = scene("trusted", &format!("SystemCall \"touch {}\";", m.display()));
    let o = check(&dir, &["--trust-geometry"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(m.exists());
}

/// TEST GOAL: comments and strings that mention the refused statements, options named like
/// them, `Printf` to the terminal and an `Include` inside the folder pass the scan: `check`
/// succeeds and prints the gmsh it runs.
#[test]
fn mentions_of_refused_statements_pass() {
    let dir = scene(
        "mentions",
        "// SystemCall \"id > f\"; is refused\n/* Shell \"x\"; */ Printf(\"SystemCall > %g\", lc);\nPrint.Width = 100;\nInclude \"part.geo\";",
    );
    std::fs::write(dir.join("part.geo"), "// nothing but a comment\n").unwrap();
    let o = check(&dir, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("gmsh: "), "{stdout}");
}

/// TEST GOAL: every shipped geometry (geometries/*.geo, geometries/scenes/*.geo and the test
/// geometries) passes the scan.
#[test]
fn the_shipped_geometries_pass_the_scan() {
    for dir in ["geometries", "geometries/scenes", "tests/data"] {
        for entry in std::fs::read_dir(common::root().join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "geo") {
                let scanned = hbcontact::mesh::guard::check_geometry(&path, false);
                assert!(scanned.is_ok(), "{}: {scanned:?}", path.display());
            }
        }
    }
}

/// TEST GOAL: a study may not set or vary `geometry.gmsh` (it names the program run): its
/// `set` and a parameter naming it are refused with exit 2 naming the key.
#[test]
fn a_study_may_not_choose_the_gmsh_program() {
    let dir = common::temp_out("geometry-guard-study");
    std::fs::create_dir_all(&dir).unwrap();
    let pipeline = common::root().join("pipelines/strip_wall.yaml");
    for (tag, body) in [
        ("set", "set: {geometry.gmsh: /bin/sh}\nparameters:\n  - {key: geometry.parameters.gap, values: [1.0e-7]}\n"),
        ("parameter", "parameters:\n  - {key: geometry.gmsh, values: [/bin/sh, /bin/true]}\n"),
    ] {
        let study = dir.join(format!("{tag}.yaml"));
        let text = format!("name: s\npipeline: {}\n{body}", pipeline.display());
        std::fs::write(&study, text).unwrap();
        let out = dir.join(format!("{tag}-out"));
        let o = common::hbcontact(&["study", study.to_str().unwrap(), "-q", "--out", out.to_str().unwrap()]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{tag}: {e}");
        assert!(e.contains("`geometry.gmsh` names a program"), "{tag}: {e}");
    }
}

/// TEST GOAL: `study` and `accuracy` mesh their points' `.geo` under the same guard: without
/// `--trust-geometry` a point whose geometry runs a program fails and the program never runs;
/// with it (issue #46: `accuracy` took the flag and dropped it, `study` had none) the
/// geometry runs as written.
#[test]
fn study_and_accuracy_take_trust_geometry_for_their_points() {
    for command in ["study", "accuracy"] {
        let m = common::root().join(format!("output/test-runs/geometry-guard-{command}-made"));
        let _ = std::fs::remove_file(&m);
        let dir = scene(
            &format!("{command}-points"),
            &format!("SystemCall \"touch {}\";", m.display()),
        );
        let study = dir.join("study.yaml");
        std::fs::write(
            &study,
            "name: s\npipeline: scene.yaml\nparameters:\n  - {key: material.youngs_modulus, values: [2.1e11]}\n",
        )
        .unwrap();
        let target = match command {
            "study" => study,
            _ => dir.join("scene.yaml"),
        };
        for trusted in [false, true] {
            let out = dir.join(format!("out-{trusted}"));
            let mut args = vec![
                command,
                target.to_str().unwrap(),
                "-q",
                "--out",
                out.to_str().unwrap(),
            ];
            if trusted {
                args.push("--trust-geometry");
            }
            if command == "accuracy" {
                // An accuracy study measures a probe's amplitude.
                args.extend([
                    "--set",
                    "output.probes=[body]",
                    "--set",
                    "boundaries.loads=[{group: body, type: force, harmonics: [{k: 1, cos: [1.0e3, 0.0]}]}]",
                ]);
            }
            let o = common::hbcontact(&args);
            let e = stderr(&o);
            assert_eq!(m.exists(), trusted, "{command}, trusted {trusted}: {e}");
            if trusted {
                assert!(o.status.success(), "{command}: {e}");
            } else {
                assert!(!o.status.success(), "{command}: {e}");
            }
        }
    }
}
