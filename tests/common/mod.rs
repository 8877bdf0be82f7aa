//! Shared helpers of the integration tests: the project root, the venv's Python, running the
//! `hbcontact` binary, solving a scene through the library.
#![allow(dead_code)]

pub mod svg;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hbcontact::config::Pipeline;
use hbcontact::hbm::{self, HbSettings, Solution};
use hbcontact::pipeline::load_pipeline;
use hbcontact::pipeline::{self, Model, Purpose, Stages};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The venv's Python (made by `make venv`); tests fail without it, as CI must have it.
pub fn venv_python() -> PathBuf {
    let p = root().join(".venv/bin/python");
    assert!(
        p.exists(),
        "{} is missing: run `make venv` (make test does it)",
        p.display()
    );
    p
}

/// Make `to` an executable copy of `from` without this process ever holding a write handle
/// to `to`: a test thread that forks meanwhile would inherit the handle, and exec of `to`
/// would fail with "Text file busy" (ETXTBSY, rust-lang/rust#114554). `cp`, another
/// process, writes it.
pub fn copy_executable(from: &Path, to: &Path) {
    let status = Command::new("cp").arg(from).arg(to).status().unwrap();
    assert!(status.success(), "cp {} {}", from.display(), to.display());
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(to, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// An executable script `path` with `text` (written beside it as `<path>.txt` first, then
/// `copy_executable`).
pub fn write_executable(path: &Path, text: &str) {
    let source = path.with_extension("txt");
    std::fs::write(&source, text).unwrap();
    copy_executable(&source, path);
}

pub fn hbcontact(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hbcontact"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("the hbcontact binary runs")
}

pub fn scene(name: &str, overrides: &[&str]) -> Pipeline {
    let path = root().join("pipelines").join(format!("{name}.yaml"));
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    match load_pipeline(&path, &overrides) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// Mesh and build a scene's model (meshes cached under output/.mesh-cache).
pub fn model(p: &Pipeline, purpose: Purpose) -> Model {
    let out = root().join("output").join("test-scenes").join(&p.name);
    let mut stages = Stages::new(p, &hbcontact::Silent);
    let (mesh, _) = pipeline::stages::mesh(p, &out, &mut stages).unwrap_or_else(|e| panic!("{e}"));
    pipeline::build(p, mesh, purpose).unwrap_or_else(|e| panic!("{e}"))
}

pub fn settings(p: &Pipeline) -> HbSettings {
    pipeline::hb_settings(p)
}

pub fn solve(model: &Model, p: &Pipeline) -> hbcontact::Result<Solution> {
    hbm::solve(
        &model.system,
        model.contact.as_ref().map(|c| &c.operator),
        &settings(p),
        &hbcontact::Silent,
    )
}

pub fn temp_out(tag: &str) -> PathBuf {
    let dir = root().join("output").join("test-runs").join(tag);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Whether pvbatch and xvfb-run are installed; a missing one panics when
/// HBCONTACT_REQUIRE_PARAVIEW=1 (as .ci/run sets) and is a printed skip otherwise.
pub fn paraview_available() -> bool {
    let have = |cmd: &str| {
        Command::new("sh")
            .arg("-c")
            .arg(format!("command -v {cmd}"))
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    };
    if have("pvbatch") && have("xvfb-run") {
        return true;
    }
    if std::env::var("HBCONTACT_REQUIRE_PARAVIEW").as_deref() == Ok("1") {
        panic!(
            "pvbatch or xvfb-run missing but HBCONTACT_REQUIRE_PARAVIEW=1 (.ci/run installs them)"
        );
    }
    eprintln!(
        "SKIPPED: pvbatch/xvfb-run not installed (apt-get install paraview xvfb; .ci/run does)"
    );
    false
}

/// tests/scripts/paraview_check.py under `xvfb-run -a pvbatch` with `args` and `env`, up to
/// `attempts` times a little apart (`pvbatch_script`); the last attempt's output.
pub fn render_with_paraview(
    args: &[&std::ffi::OsStr],
    env: &[(&str, &str)],
    attempts: u64,
) -> Output {
    let script = root().join("tests/scripts/paraview_check.py");
    pvbatch_script(&script, args, env, attempts)
}

/// The pvbatch script `script` under `xvfb-run -a` (a 24-bit screen) with `args` and `env`,
/// up to `attempts` times a little apart (xvfb-run -a can race for a display with other runs'
/// X servers on a busy machine); the last attempt's output.
pub fn pvbatch_script(
    script: &Path,
    args: &[&std::ffi::OsStr],
    env: &[(&str, &str)],
    attempts: u64,
) -> Output {
    let mut last = None;
    for attempt in 0..attempts {
        if attempt > 0 {
            let pause = 500 * attempt + u64::from(std::process::id() % 500);
            std::thread::sleep(std::time::Duration::from_millis(pause));
        }
        let o = Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1280x1024x24", "pvbatch"])
            .envs(env.iter().copied())
            .arg(script)
            .args(args)
            .output()
            .expect("xvfb-run runs");
        let ok = o.status.success();
        last = Some(o);
        if ok {
            break;
        }
    }
    last.expect("at least one attempt")
}

/// The first probe's first-harmonic amplitude in a run's summary.
pub fn first_probe_harmonic(s: &pipeline::Summary) -> f64 {
    s.probes.values().next().expect("a probe").first_harmonic()
}

/// `hbcontact run` of a shipped scene through the library, summary only, into
/// output/test-runs/`tag`.
pub fn run_summary(name: &str, overrides: &[&str], tag: &str) -> pipeline::Summary {
    let p = scene(name, overrides);
    let options = pipeline::RunOptions {
        out: Some(temp_out(tag)),
        write: hbcontact::pipeline::WriteLevel::Summary,
        ..Default::default()
    };
    pipeline::run(&p, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{tag}: {e}"))
        .summary
}

/// The probes' amplitudes of a harmonic-balance state, from the displacements at 64
/// instants of its period (what a run's summary computes from its history), up to harmonic
/// `harmonics`.
pub fn hb_probe_amplitudes(
    model: &Model,
    solution: &Solution,
    harmonics: usize,
) -> std::collections::BTreeMap<String, pipeline::summary::ProbeAmplitudes> {
    let sampled = pipeline::report::Sampled::harmonic_balance_history(model, solution, 1, 64);
    pipeline::summary::probe_amplitudes(model, &sampled.history.probe_means, harmonics)
}

/// The monodromy of ÿ + α ẏ + k(t) y = 0, k piecewise constant over `segments` (stiffness,
/// duration), by classical Runge–Kutta with `steps` steps per segment: independent of
/// `hbm::floquet::transition` and `hbm::hill`.
pub fn rk4_monodromy(alpha: f64, segments: &[(f64, f64)], steps: usize) -> [[f64; 2]; 2] {
    let column = |mut y: f64, mut v: f64| {
        for &(k, tau) in segments {
            let h = tau / steps as f64;
            let f = |y: f64, v: f64| (v, -alpha * v - k * y);
            for _ in 0..steps {
                let (a1, b1) = f(y, v);
                let (a2, b2) = f(y + 0.5 * h * a1, v + 0.5 * h * b1);
                let (a3, b3) = f(y + 0.5 * h * a2, v + 0.5 * h * b2);
                let (a4, b4) = f(y + h * a3, v + h * b3);
                y += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
                v += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
            }
        }
        (y, v)
    };
    let ((y0, v0), (y1, v1)) = (column(1.0, 0.0), column(0.0, 1.0));
    [[y0, y1], [v0, v1]]
}

/// `hbcontact COMMAND PIPELINE --out output/test-runs/TAG --set S…`, asserted to exit 0: the
/// output folder.
pub fn run_cli(command: &str, pipeline: &str, tag: &str, sets: &[&str]) -> PathBuf {
    let out = temp_out(tag);
    let out_arg = out.display().to_string();
    let mut args = vec![command, pipeline, "--out", &out_arg];
    for s in sets {
        args.extend(["--set", s]);
    }
    let r = hbcontact(&args);
    assert!(
        r.status.success(),
        "{tag}: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    out
}

/// The number at `pointer` of a JSON document.
pub fn json_number(v: &serde_json::Value, pointer: &str) -> f64 {
    v.pointer(pointer)
        .and_then(serde_json::Value::as_f64)
        .unwrap_or_else(|| panic!("no number at {pointer}: {v}"))
}

/// Each of `pointers` in a harmonic-balance summary within `tolerance` (relative) of the
/// time-marching one, printed.
pub fn assert_agrees_with_marching(
    hb: &serde_json::Value,
    tm: &serde_json::Value,
    pointers: &[&str],
    tolerance: f64,
) {
    for pointer in pointers {
        let (a, b) = (json_number(hb, pointer), json_number(tm, pointer));
        let error = (a - b) / b;
        println!(
            "{pointer}: harmonic balance {a:.6e}, time marching {b:.6e} ({:+.3}%)",
            100.0 * error
        );
        assert!(error.abs() < tolerance, "{pointer}: {a:e} vs {b:e}");
    }
}

/// The late response of `p` marched from rest by `hbcontact transient` (its output under the
/// temporary folder `tag`), its description printed.
pub fn marched_late_response(p: &Pipeline, tag: &str) -> hbcontact::pipeline::late::LateResponse {
    let options = pipeline::RunOptions {
        out: Some(temp_out(tag)),
        ..Default::default()
    };
    let run =
        pipeline::run_transient(p, &options, &hbcontact::Silent).unwrap_or_else(|e| panic!("{e}"));
    let late = run
        .summary
        .transient
        .expect("transient details")
        .late_response;
    println!("{}", late.description);
    late
}
