//! Interruptions (SIGTERM, as a scheduler or `kill` sends it; Ctrl-C's SIGINT takes the same
//! path) keep the work and name the stage (issue #46, item 4): an interrupted `transient`
//! writes the whole periods it marched as a partial result, marked in its summary, and exits
//! with 130; an interruption that ends the process at once names the stage that was running,
//! says gmsh was stopped only when it ran, and what was kept; the unfinished output of an
//! interrupted write is gone once the next run into the same folder starts.
//!
//! Each test spawns the binary with stderr piped (progress then comes as plain lines, at
//! most one a second, each stage announced before its first), waits for the line that shows
//! the stage under way (the write: for its first frame file, since 10 000 frames can be
//! written before the first progress line is due), and sends SIGTERM.

mod common;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::Duration;

/// The longest any of these runs may take once signalled before the test gives up on it (a
/// guard against a hang, not a measurement).
const GUARD: Duration = Duration::from_secs(600);

/// `hbcontact args…` from the project root, stdout discarded, stderr as a channel of lines.
fn spawn(args: &[&str]) -> (Child, Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hbcontact"))
        .args(args)
        .current_dir(common::root())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the hbcontact binary runs");
    let stderr = child.stderr.take().expect("stderr is piped");
    let (send, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if send.send(line).is_err() {
                break;
            }
        }
    });
    (child, lines)
}

/// Read stderr until a line holds `marker` (returning what was read), or panic when the
/// process ends first.
fn wait_for(lines: &Receiver<String>, marker: &str) -> String {
    let mut seen = String::new();
    loop {
        match lines.recv_timeout(GUARD) {
            Ok(line) => {
                seen.push_str(&line);
                seen.push('\n');
                if line.contains(marker) {
                    return seen;
                }
            }
            Err(e) => panic!("no line with {marker:?} ({e}); stderr so far:\n{seen}"),
        }
    }
}

/// Wait until `file` exists (the child is then under way in the stage that writes it), or
/// panic when the child ends first. Polled, so that the signal never waits on a progress line:
/// those come at most once a second, and a fast write can end before its first.
fn wait_for_file(child: &mut Child, file: &Path) {
    let start = std::time::Instant::now();
    while !file.exists() {
        if let Ok(Some(status)) = child.try_wait() {
            panic!(
                "the run ended ({status}) before {} was written",
                file.display()
            );
        }
        assert!(start.elapsed() < GUARD, "{} never appeared", file.display());
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// SIGTERM to `child`, then its exit code and the rest of its stderr.
fn terminate(mut child: Child, lines: &Receiver<String>) -> (Option<i32>, String) {
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success());
    let mut rest = String::new();
    while let Ok(line) = lines.recv_timeout(GUARD) {
        rest.push_str(&line);
        rest.push('\n');
    }
    let code = child.wait().expect("the child is waited for").code();
    (code, rest)
}

/// The `<name>.partial-<pid>` folders beside `out`.
fn partials(out: &Path) -> Vec<String> {
    let name = out.file_name().unwrap().to_string_lossy().to_string();
    let Ok(entries) = std::fs::read_dir(out.parent().unwrap()) else {
        return Vec::new();
    };
    entries
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(&format!("{name}.partial-")))
        .collect()
}

/// TEST GOAL: SIGTERM while `hbcontact transient` marches (the 0.5%-damped strip, its
/// periodicity tolerance out of reach so that only the signal ends it) stops the march and
/// writes the whole periods marched as a partial result: exit 130; the message names the
/// `march` stage and the folder, and does not claim gmsh was stopped; summary.json's
/// `transient.stopped` says `interrupted` with the periods (those of `transient.periods`, at
/// least the one the progress line showed) and the steps into the next (fewer than a
/// period's), and a warning says the result is partial; the frames, probes.csv and
/// end_state.json are written (the end state of the last whole period, finite), no partial
/// folder is left, and `transient.start: previous` marches on from that end state.
#[test]
fn an_interrupted_transient_writes_the_periods_it_marched_marked_partial() {
    let out = common::temp_out("interrupt-transient");
    let out_arg = out.to_str().unwrap();
    let sets = [
        "geometry.parameters.lc=0.025",
        "transient.periodic_tolerance=1e-30",
        "transient.max_periods=1000000",
        "output.plots=false",
    ];
    let mut args = vec![
        "transient",
        "pipelines/strip_sweep_light.yaml",
        "--out",
        out_arg,
    ];
    for s in &sets {
        args.extend(["--set", s]);
    }
    let (child, lines) = spawn(&args);
    let before = wait_for(&lines, "periods ");
    let (code, stderr) = terminate(child, &lines);
    println!("{before}{stderr}");
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted during the `march` stage"),
        "{stderr}"
    );
    assert!(!stderr.contains("gmsh"), "gmsh was not running: {stderr}");
    assert!(
        stderr.contains(&format!("the partial result is in {out_arg}")),
        "{stderr}"
    );
    let summary = common::read_json(&out.join("summary.json"));
    let t = &summary["transient"];
    let stopped = &t["stopped"];
    assert_eq!(stopped["class"], "interrupted", "{t}");
    let periods = t["periods"].as_u64().unwrap();
    assert_eq!(stopped["periods"].as_u64(), Some(periods));
    assert!(periods >= 1, "{t}");
    assert!(
        stopped["steps_into_period"].as_u64().unwrap() < t["steps_per_period"].as_u64().unwrap()
    );
    assert_eq!(t["converged"], false);
    let warnings = summary["warnings"].to_string();
    assert!(
        warnings.contains("a partial result: interrupted"),
        "{warnings}"
    );
    for file in [
        "series.pvd",
        "frame_0000.vtu",
        "probes.csv",
        "end_state.json",
    ] {
        assert!(out.join(file).is_file(), "{file}");
    }
    let end = common::read_json(&out.join("end_state.json"));
    assert_eq!(end["periods"].as_u64(), Some(periods));
    let finite = |k: &str| {
        end[k]
            .as_array()
            .unwrap()
            .iter()
            .all(|v| v.as_f64().is_some())
    };
    assert!(finite("displacement") && finite("velocity"));
    let probe = summary["probes"]["probe"]["first_harmonic_x"]
        .as_f64()
        .unwrap();
    assert!(probe.is_finite() && probe > 0.0, "{probe}");
    assert!(partials(&out).is_empty(), "{:?}", partials(&out));
    // The partial result is a state to march on from.
    let mut again = args.clone();
    again.extend([
        "--set",
        "transient.start=previous",
        "--set",
        "transient.max_periods=2",
        "--quiet",
    ]);
    let o = common::hbcontact(&again);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let summary = common::read_json(&out.join("summary.json"));
    assert_eq!(summary["transient"]["start"], "previous");
    assert!(summary["transient"].get("stopped").is_none());
}

/// TEST GOAL: SIGTERM while `hbcontact run` writes its frames ends it at once with exit 130 and
/// a message that names the `write` stage, says nothing was written, that the earlier output
/// is as it was and that the unfinished `.partial-<pid>` folder goes with the next run, and
/// does not claim gmsh was stopped; the earlier output's files are untouched, and the next
/// run into the folder removes that partial folder (saying so) and leaves none.
#[test]
fn an_interrupted_write_names_its_stage_and_its_partial_folder_goes_with_the_next_run() {
    let out = common::temp_out("interrupt-write");
    let out_arg = out.to_str().unwrap();
    let run = |frames: &str| {
        vec![
            "run".to_string(),
            "pipelines/strip_sweep_light.yaml".into(),
            "--out".into(),
            out_arg.into(),
            "--set".into(),
            "stability.check=false".into(),
            "--set".into(),
            "output.plots=false".into(),
            "--set".into(),
            "output.fields=[displacement]".into(),
            "--set".into(),
            format!("output.frames={frames}"),
        ]
    };
    let first = run("8");
    let first: Vec<&str> = first.iter().map(String::as_str).collect();
    let o = common::hbcontact(&first);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let earlier = std::fs::read(out.join("summary.json")).unwrap();
    // 10 000 frames take seconds to write; the signal comes after the first.
    let long = run("10000");
    let long: Vec<&str> = long.iter().map(String::as_str).collect();
    let (mut child, lines) = spawn(&long);
    let pid = child.id();
    let partial = format!("{out_arg}.partial-{pid}");
    wait_for_file(&mut child, &Path::new(&partial).join("frame_0000.vtu"));
    let (code, stderr) = terminate(child, &lines);
    println!("{stderr}");
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted during the `write` stage")
            && stderr.contains(&format!("nothing written: {out_arg} is as it was"))
            && stderr.contains(&format!(
                "the unfinished {partial} is removed by the next run into it"
            )),
        "{stderr}"
    );
    assert!(!stderr.contains("gmsh"), "gmsh was not running: {stderr}");
    assert_eq!(std::fs::read(out.join("summary.json")).unwrap(), earlier);
    assert!(out.join("frame_0007.vtu").is_file() && !out.join("frame_0008.vtu").exists());
    assert!(
        Path::new(&partial).is_dir(),
        "the killed write left {partial}"
    );
    let o = common::hbcontact(&first);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "removed {partial}, the partial output of a run (pid {pid})"
        )),
        "{stderr}"
    );
    assert!(partials(&out).is_empty(), "{:?}", partials(&out));
}

/// TEST GOAL: SIGTERM while gmsh meshes (a stand-in gmsh that reads, then hangs) ends the run
/// at once with exit 130, and the message names the `mesh` stage, says gmsh was stopped and
/// that nothing was written.
#[test]
fn an_interruption_while_meshing_names_the_mesh_stage_and_stops_gmsh() {
    let out = common::temp_out("interrupt-mesh");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    let fake = out.with_file_name("interrupt-mesh-gmsh.sh");
    common::write_executable(
        &fake,
        "#!/bin/sh\nif [ \"$1\" = --version ]; then echo 4.15.2; exit 0; fi\n\
         echo \"Info    : Reading the geometry...\"\nexec sleep 600\n",
    );
    let gmsh = format!("geometry.gmsh={}", fake.display());
    let (child, lines) = spawn(&[
        "run",
        "pipelines/strip_sweep_light.yaml",
        "--out",
        out.to_str().unwrap(),
        "--set",
        &gmsh,
        "--set",
        "geometry.parameters.lc=0.0312345",
    ]);
    let before = wait_for(&lines, "Reading the geometry");
    let (code, stderr) = terminate(child, &lines);
    println!("{before}{stderr}");
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted during the `mesh` stage")
            && stderr.contains("; gmsh stopped: nothing written"),
        "{stderr}"
    );
    assert!(!out.exists() && partials(&out).is_empty());
}
