//! The pipeline YAML: every shipped scene parses; errors name the file, the line and column,
//! the field, and the fix.

use std::path::PathBuf;

use hbcontact::config::{load_pipeline, FieldName, ObstacleSpec, PlaneModelSpec};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn err(path: &str, overrides: &[&str]) -> String {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    match load_pipeline(&root().join(path), &o) {
        Ok(_) => panic!("{path} {overrides:?} must not load"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn shipped_pipelines_parse_with_their_values_and_defaults() {
    let p = load_pipeline(&root().join("pipelines/strip_wall.yaml"), &[]).unwrap();
    assert_eq!(p.name, "strip_wall");
    assert!(p.geometry.file.ends_with("geometries/strip_wall.geo") && p.geometry.file.exists());
    assert_eq!(p.geometry.parameters["gap"], 1.0e-7);
    assert_eq!(p.material.youngs_modulus, 210.0e9);
    assert_eq!(p.material.model, PlaneModelSpec::PlaneStrain);
    assert_eq!(p.material.thickness, 1.0, "default thickness");
    assert_eq!(p.harmonic_balance.harmonics, 20);
    assert_eq!(
        p.harmonic_balance.samples, None,
        "default N is chosen by the solver (16H)"
    );
    assert_eq!(p.harmonic_balance.solver.c_scale, 1.0);
    let c = p.contact.unwrap();
    assert_eq!(
        c.obstacle,
        ObstacleSpec::Curve {
            group: "wall".into()
        }
    );
    assert_eq!(p.output.directory, PathBuf::from("output/strip_wall"));
    assert_eq!(p.output.frames, 32);
    assert!(p.output.fields.contains(&FieldName::Contact));
    let h = load_pipeline(&root().join("pipelines/half_disc.yaml"), &[]).unwrap();
    match h.contact.unwrap().obstacle {
        ObstacleSpec::Line { normal, .. } => assert_eq!(normal, [0.0, 1.0]),
        o => panic!("{o:?}"),
    }
    assert_eq!(h.boundaries.prescribed.len(), 2);
    assert_eq!(
        h.boundaries.prescribed[1].signal.harmonics,
        vec![(1, [2.0e-4], [0.0])]
    );
    for name in ["quickstart", "cantilever", "blade_casing"] {
        load_pipeline(&root().join(format!("pipelines/{name}.yaml")), &[])
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn overrides_change_values_and_create_blocks() {
    let o = [
        "harmonic_balance.harmonics=7",
        "geometry.parameters.gap=1e-4",
        "damping=null",
        "contact.obstacle={circle: {center: [0, 0], radius: 2.0, body_inside: true}}",
    ];
    let o: Vec<String> = o.iter().map(|s| s.to_string()).collect();
    let p = load_pipeline(&root().join("pipelines/strip_wall.yaml"), &o).unwrap();
    assert_eq!(p.harmonic_balance.harmonics, 7);
    assert_eq!(p.geometry.parameters["gap"], 1e-4);
    assert!(p.damping.is_none());
    assert_eq!(
        p.contact.unwrap().obstacle,
        ObstacleSpec::Circle {
            center: [0.0, 0.0],
            radius: 2.0,
            body_inside: true
        }
    );
}

#[test]
fn errors_name_line_field_and_fix() {
    let e = err("tests/data/config/typo.yaml", &[]);
    assert!(
        e.contains("typo.yaml")
            && e.contains("line 11")
            && e.contains("harmonicz")
            && e.contains("did you mean `harmonics`"),
        "{e}"
    );
    let e = err("tests/data/config/bad_enum.yaml", &[]);
    assert!(
        e.contains("line 8")
            && e.contains("plane_strian")
            && e.contains("did you mean `plane_strain`"),
        "{e}"
    );
    let e = err(
        "pipelines/strip_wall.yaml",
        &["harmonic_balance.samples=20"],
    );
    assert!(
        e.contains("harmonic_balance.samples = 20") && e.contains("at least 41"),
        "{e}"
    );
    let e = err("pipelines/strip_wall.yaml", &["material.poisson_ratio=0.5"]);
    assert!(e.contains("material.poisson_ratio"), "{e}");
    let e = err(
        "pipelines/strip_wall.yaml",
        &["harmonic_balance.frequency=fast"],
    );
    assert!(
        e.contains("--set harmonic_balance.frequency=fast") && e.contains("invalid type"),
        "{e}"
    );
    let e = err(
        "pipelines/strip_wall.yaml",
        &["harmonic_balance.harmonicz=3"],
    );
    assert!(e.contains("did you mean `harmonics`"), "{e}");
    let e = err(
        "pipelines/strip_wall.yaml",
        &["geometry.file=geometries/nope.geo"],
    );
    assert!(
        e.contains("geometry.file") && e.contains("nope.geo") && e.contains("tried"),
        "{e}"
    );
    let e = err("pipelines/strip_wall.yaml", &["material"]);
    assert!(e.contains("KEY=VALUE"), "{e}");
    let e = err(
        "pipelines/strip_wall.yaml",
        &["contact.obstacle={line: {point: [0, 0], normal: [0, 0]}}"],
    );
    assert!(e.contains("normal must be a non-zero vector"), "{e}");
    let e = err(
        "pipelines/strip_wall.yaml",
        &["boundaries.loads=[{group: tip, type: traction}]"],
    );
    assert!(e.contains("static") && e.contains("harmonics"), "{e}");
    let e = err("pipelines/nope.yaml", &[]);
    assert!(e.contains("nope.yaml") && e.contains("cannot read"), "{e}");
}

/// `check` on strip_wall with overrides: its exit code and stderr.
fn check(overrides: &[&str]) -> (Option<i32>, String) {
    let mut args = vec!["check", "pipelines/strip_wall.yaml", "-q"];
    for o in overrides {
        args.push("--set");
        args.push(o);
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_hbcontact"))
        .args(&args)
        .current_dir(root())
        .output()
        .expect("the hbcontact binary runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// TEST GOAL: non-finite or absurd numbers are bad input caught by `check` (exit code 2)
/// with a message naming the field, not a "resonance" at exit 3 after meshing and solving:
/// an infinite or NaN load amplitude, `frequency: 1e300`, an infinite geometry parameter, NaN
/// damping, an infinite obstacle point.
#[test]
fn non_finite_and_absurd_numbers_are_refused_by_check_naming_the_field() {
    let cases = [
        (
            "boundaries.loads.0.harmonics.0.cos=[.inf, 0]",
            "boundaries.loads[0].harmonics (k = 1).cos[0] = inf",
        ),
        (
            "boundaries.loads.0.static=[0, .nan]",
            "boundaries.loads[0].static[1] = NaN",
        ),
        (
            "harmonic_balance.frequency=1e300",
            "harmonic_balance.frequency = 1e300 Hz is above 1e9 Hz",
        ),
        (
            "harmonic_balance.frequency=.inf",
            "harmonic_balance.frequency = inf",
        ),
        (
            "geometry.parameters.gap=.inf",
            "geometry.parameters.gap = inf",
        ),
        ("damping.alpha=.nan", "damping.alpha = NaN"),
        (
            "material.youngs_modulus=1e300",
            "material.youngs_modulus = 1e300",
        ),
        (
            "contact.obstacle={line: {point: [.inf, 0], normal: [1, 0]}}",
            "contact.obstacle.line.point[0] = inf",
        ),
    ];
    for (set, named) in cases {
        let (code, err) = check(&[set]);
        assert_eq!(code, Some(2), "{set}: {err}");
        assert!(err.contains(named), "{set}: {err}");
    }
}

/// TEST GOAL: the documented limits hold at `check` with exit code 2 and name the key:
/// harmonics ≤ 1000, k ≤ 1000, samples ≤ 1e6, frames ≤ output.max_frames (which raises it),
/// and a contact scene whose H is below a load's harmonic (H = 0 with a k = 1 load; it used to
/// pass `check` and fail at exit 3).
#[test]
fn limits_and_contact_harmonics_are_checked_naming_the_key() {
    let cases: [(&[&str], &str); 5] = [
        (
            &["harmonic_balance.harmonics=0"],
            "harmonic_balance.harmonics = 0 is below harmonic k = 1 of boundaries.loads[0]",
        ),
        (
            &["harmonic_balance.harmonics=1001"],
            "harmonic_balance.harmonics = 1001 is above the limit of 1000",
        ),
        (
            &["boundaries.loads.0.harmonics.0.k=5000"],
            "k = 5000 is above the limit of 1000",
        ),
        (
            &["harmonic_balance.samples=2000000"],
            "harmonic_balance.samples = 2000000 is above the limit",
        ),
        (
            &["output.frames=20000"],
            "output.frames = 20000 is above output.max_frames = 10000",
        ),
    ];
    for (sets, named) in cases {
        let (code, err) = check(sets);
        assert_eq!(code, Some(2), "{sets:?}: {err}");
        assert!(err.contains(named), "{sets:?}: {err}");
    }
    let o = vec![
        "output.frames=20000".to_string(),
        "output.max_frames=20000".to_string(),
    ];
    let p = load_pipeline(&root().join("pipelines/strip_wall.yaml"), &o).unwrap();
    assert_eq!(p.output.frames, 20000);
}

/// TEST GOAL: an error quotes at most an ~80-character excerpt of a bad input string (with its
/// length), not all 100 kB of it: as a name, a group name, an enum value and a --set value.
#[test]
fn errors_quote_only_an_excerpt_of_long_input() {
    let long = "a".repeat(100_000);
    for set in [
        format!("name={long}"),
        format!("output.probes=[{long}]"),
        format!("material.model={long}"),
        format!("harmonic_balance.frequency={long}"),
    ] {
        let e = err("pipelines/strip_wall.yaml", &[set.as_str()]);
        assert!(e.len() < 1000, "{} characters: {}", e.len(), &e[..300]);
        assert!(e.contains("100000 characters"), "{e}");
    }
}

/// TEST GOAL: `--set` addresses list entries by index (`boundaries.loads.0.static`), and an
/// index past the end or into a value that is not a list is an error that says how many entries
/// there are and how to replace the whole list.
#[test]
fn set_indexes_list_entries_and_says_how_to_replace_a_list() {
    let o = vec![
        "boundaries.loads.0.harmonics.0.cos=[2.0e5, 0.0]".to_string(),
        "output.probes.0=tip".to_string(),
    ];
    let p = load_pipeline(&root().join("pipelines/strip_wall.yaml"), &o).unwrap();
    assert_eq!(p.boundaries.loads[0].signal.harmonics[0].1, [2.0e5, 0.0]);
    assert_eq!(p.output.probes, vec!["tip".to_string()]);
    let e = err("pipelines/strip_wall.yaml", &["boundaries.loads.3.group=x"]);
    assert!(
        e.contains("boundaries.loads has 1 entries")
            && e.contains("--set 'boundaries.loads=[...]'"),
        "{e}"
    );
    let e = err("pipelines/strip_wall.yaml", &["harmonic_balance.0=x"]);
    assert!(
        e.contains("harmonic_balance is not a list") && e.contains("set the whole value"),
        "{e}"
    );
}

/// TEST GOAL: the sweep's output keys are read into the validated spec (`write_at` as given,
/// `save_every` default 1) and a `write_at` frequency outside the swept range is refused
/// naming the entry and the range.
#[test]
fn sweep_output_keys_are_read_and_write_at_outside_the_range_is_refused() {
    let path = root().join("pipelines/strip_sweep.yaml");
    let sets = vec!["sweep.write_at=[1200, 1650.5]".to_string()];
    let spec = load_pipeline(&path, &sets).unwrap().sweep.unwrap();
    assert_eq!(spec.write_at, vec![1200.0, 1650.5]);
    assert_eq!(spec.save_every, 1);
    let sets = vec!["sweep.save_every=0".to_string()];
    assert_eq!(
        load_pipeline(&path, &sets)
            .unwrap()
            .sweep
            .unwrap()
            .save_every,
        0
    );
    let e = err(
        "pipelines/strip_sweep.yaml",
        &["sweep.write_at=[1200, 2000]"],
    );
    assert!(
        e.contains("sweep.write_at[1] = 2000 Hz lies outside the swept range [1000, 1800]"),
        "{e}"
    );
}

/// TEST GOAL: `harmonic_balance.basis` reads `fourier` (the default) and
/// `{spline: {degree, segments}}` (degree 3 by default); a degree outside 2 … 7, too few
/// segments for the degree or for the loads' harmonics, samples that are not a multiple of
/// the segments with degree + 1 per segment (the contact quadrature), and an even number of
/// segments in a sweep with contact (an undamped Nyquist frequency) are refused naming the key
/// and the fix; a sweep without contact takes any S.
#[test]
fn time_basis_is_read_defaulted_and_its_limits_named() {
    use hbcontact::config::BasisSpec;
    let load = |overrides: &[&str]| {
        let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        load_pipeline(&root().join("pipelines/cantilever.yaml"), &o).unwrap()
    };
    assert_eq!(load(&[]).harmonic_balance.basis, BasisSpec::Fourier);
    let fourier = load(&["harmonic_balance.basis=fourier"]);
    assert_eq!(fourier.harmonic_balance.basis, BasisSpec::Fourier);
    let spline = load(&["harmonic_balance.basis={spline: {segments: 16}}"]);
    assert_eq!(
        spline.harmonic_balance.basis,
        BasisSpec::Spline {
            degree: 3,
            segments: 16
        }
    );
    let k2 = "boundaries.loads.0.harmonics=[{k: 2, cos: [0.0, 1.0], sin: [0.0, 0.0]}]";
    let sweep = "sweep={from: 5.0, to: 15.0}";
    let linear = load(&["harmonic_balance.basis={spline: {segments: 64}}", sweep]);
    assert!(linear.sweep.is_some());
    let odd = load_pipeline(
        &root().join("pipelines/strip_sweep.yaml"),
        &["harmonic_balance.basis={spline: {segments: 41}}".to_string()],
    )
    .unwrap();
    assert!(odd.sweep.is_some() && odd.contact.is_some());
    let cases: [(&str, &str, &[&str], &str); 6] = [
        (
            "cantilever",
            "{spline: {degree: 1, segments: 16}}",
            &[],
            "degree = 1 must be 2 … 7",
        ),
        (
            "cantilever",
            "{spline: {degree: 4, segments: 4}}",
            &[],
            "segments = 4 must be 5",
        ),
        (
            "cantilever",
            "{spline: {degree: 2, segments: 4}}",
            &[k2],
            "more than 4 segments",
        ),
        (
            "strip_wall",
            "{spline: {segments: 64}}",
            &["harmonic_balance.samples=1000"],
            "must be a multiple of harmonic_balance.basis.spline.segments = 64",
        ),
        (
            "strip_wall",
            "{spline: {segments: 64}}",
            &["harmonic_balance.samples=192"],
            "at least degree + 1 = 4 per segment",
        ),
        (
            "strip_sweep",
            "{spline: {segments: 64}}",
            &[],
            "needs an odd number of segments",
        ),
    ];
    for (scene, basis, extra, needle) in cases {
        let mut overrides = vec![format!("harmonic_balance.basis={basis}")];
        overrides.extend(extra.iter().map(|s| s.to_string()));
        let overrides: Vec<&str> = overrides.iter().map(|s| s.as_str()).collect();
        let e = err(&format!("pipelines/{scene}.yaml"), &overrides);
        assert!(
            e.contains(needle) && e.contains("harmonic_balance.basis"),
            "{scene} {basis}: {e}"
        );
    }
}

/// TEST GOAL: a relative `geometry.file` is looked up next to the pipeline, then in its parent
/// directory, then in the working directory: a pipeline in a folder of its own (two levels
/// below anything holding `geometries/`) that names `geometries/quickstart.geo` finds the one
/// beside the working directory (the crate root, where cargo runs the tests); a file found
/// nowhere is refused with each place tried named (issue #50).
#[test]
fn geometry_file_is_found_beside_the_pipeline_its_parent_or_the_working_directory() {
    let dir = root().join("output/test-runs/config-geometry-lookup/scene/own");
    std::fs::create_dir_all(&dir).unwrap();
    let quickstart = std::fs::read_to_string(root().join("pipelines/quickstart.yaml")).unwrap();
    assert!(quickstart.contains("file: geometries/quickstart.geo"));
    let pipeline = dir.join("quickstart.yaml");
    std::fs::write(&pipeline, &quickstart).unwrap();
    assert!(!dir.join("geometries").exists() && !dir.join("../geometries").exists());
    let p = load_pipeline(&pipeline, &[]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(p.geometry.file, PathBuf::from("geometries/quickstart.geo"));

    let e = match load_pipeline(
        &pipeline,
        &["geometry.file=geometries/nope.geo".to_string()],
    ) {
        Ok(_) => panic!("a missing geometry must not load"),
        Err(e) => e.to_string(),
    };
    let tried = format!(
        "(tried {}, {}, geometries/nope.geo)",
        dir.join("geometries/nope.geo").display(),
        dir.join("../geometries/nope.geo").display()
    );
    assert!(e.contains(&tried), "{tried} not in: {e}");
    assert!(e.contains("working directory"), "{e}");
}
