//! The pipeline YAML: every shipped scene parses; errors name the file, the line and column,
//! the field, and the fix.

use std::path::PathBuf;

use hbcontact::config::{FieldName, ObstacleSpec, PlaneModelSpec};
use hbcontact::pipeline::load_pipeline;

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
        c.pairs[0].obstacle,
        ObstacleSpec::Curve {
            group: "wall".into()
        }
    );
    assert_eq!(p.output.directory, PathBuf::from("output/strip_wall"));
    assert_eq!(p.output.frames, 32);
    assert!(p.output.fields.contains(&FieldName::Contact));
    let h = load_pipeline(&root().join("pipelines/half_disc.yaml"), &[]).unwrap();
    match h.contact.unwrap().pairs.remove(0).obstacle {
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
        p.contact.unwrap().pairs.remove(0).obstacle,
        ObstacleSpec::Circle {
            center: [0.0, 0.0],
            radius: 2.0,
            body_inside: true,
            lobes: None
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

/// The pipeline every bound is tried on: a sweep with contact, damping and loads.
const BOUNDS_BASE: &str = "pipelines/strip_sweep.yaml";

/// Overrides that give a key a place to live in `BOUNDS_BASE` (a list entry, an obstacle or
/// basis variant, a start to perturb), applied to every key under the prefix.
const BOUNDS_SETUP: &[(&str, &[&str])] = &[
    (
        "boundaries.prescribed",
        &["boundaries.prescribed=[{group: drive, component: x, static: 0.0, harmonics: [{k: 1, cos: 0.0, sin: 0.0}]}]"],
    ),
    ("boundaries.loads.static", &["boundaries.loads.0.static=[0.0, 0.0]"]),
    (
        "contact.obstacle.line",
        &["contact.obstacle={line: {point: [0.0, 0.0], normal: [-1.0, 0.0]}}"],
    ),
    (
        "contact.obstacle.circle",
        &["contact.obstacle={circle: {center: [0.0, 0.0], radius: 1.0}}"],
    ),
    (
        "harmonic_balance.basis.spline",
        &["harmonic_balance.basis={spline: {degree: 3, segments: 33}}"],
    ),
    ("sweep.write_at", &["sweep.write_at=[1500.0]"]),
    (
        "harmonic_balance.tolerance",
        &["harmonic_balance.harmonics={min: 10, max: 40}"],
    ),
    (
        "harmonic_balance.harmonics.",
        &["harmonic_balance.harmonics={min: 10, max: 40}"],
    ),
    ("contact.friction", &["contact.friction={coefficient: 0.0}"]),
    ("boundaries.rotation", &["boundaries.rotation={speed: 1.0}"]),
    (
        "boundaries.rotation.turns_per_period",
        &["boundaries.rotation={turns_per_period: 1.0}"],
    ),
    (
        "contact.obstacle.circle.lobes",
        &["contact.obstacle={circle: {center: [0.0, 0.0], radius: 1.0, lobes: {count: 1, amplitude: 0.0}}}"],
    ),
    (
        "contact.motion",
        &["contact.motion={static: [0.0, 0.0], harmonics: [{k: 1, cos: [0.0, 0.0], sin: [0.0, 0.0]}]}"],
    ),
    ("transient.perturbation", &["transient.start=harmonic_balance"]),
    (
        "contact.pairs",
        &["contact={pairs: [{boundary: tip, obstacle: {curve: wall}, search_distance: 1.0, motion: {static: [0.0, 0.0], harmonics: [{k: 1, cos: [0.0, 0.0], sin: [0.0, 0.0]}]}}]}"],
    ),
    (
        "contact.pairs.obstacle.line",
        &["contact.pairs.0.obstacle={line: {point: [0.0, 0.0], normal: [-1.0, 0.0]}}"],
    ),
    (
        "contact.pairs.obstacle.circle",
        &["contact.pairs.0.obstacle={circle: {center: [0.0, 0.0], radius: 1.0}}"],
    ),
    (
        "contact.pairs.obstacle.circle.lobes",
        &["contact.pairs.0.obstacle={circle: {center: [0.0, 0.0], radius: 1.0, lobes: {count: 1, amplitude: 0.0}}}"],
    ),
];

/// Other keys a value just inside a bound needs to be valid as a whole (a step of 1 needs a
/// max_step of 1, 100000 spline segments are even and a sweep with contact takes odd ones).
/// They apply to the value inside only: the one outside is tried on the base alone.
const BOUNDS_INSIDE_COMPANIONS: &[(&str, &[&str])] = &[
    ("sweep.step", &["sweep.max_step=1.0", "sweep.min_step=1e-9"]),
    ("output.max_frames", &["output.frames=1"]),
    // Just under 0.5 is only allowed in plane stress (plane strain stops at 0.4999995).
    ("material.poisson_ratio", &["material.model=plane_stress"]),
    ("harmonic_balance.basis.spline.segments", &["sweep=null"]),
    (
        "boundaries.loads.harmonics.k",
        &["harmonic_balance.harmonics=1000"],
    ),
    (
        "boundaries.prescribed.harmonics.k",
        &["harmonic_balance.harmonics=1000"],
    ),
    (
        "contact.motion.harmonics.k",
        &["harmonic_balance.harmonics=1000"],
    ),
    (
        "contact.obstacle.circle.lobes.count",
        &["harmonic_balance.harmonics=1000"],
    ),
    (
        "contact.pairs.motion.harmonics.k",
        &["harmonic_balance.harmonics=1000"],
    ),
    (
        "contact.pairs.obstacle.circle.lobes.count",
        &["harmonic_balance.harmonics=1000"],
    ),
];

/// Bounds stated relative to other keys (the doc comment's phrase, from its operator) and the
/// overrides that break each.
const BOUNDS_RELATIONAL: &[(&str, &str, &[&str])] = &[
    (
        "harmonic_balance.harmonics.max",
        "≥ min",
        &["harmonic_balance.harmonics.max=5"],
    ),
    (
        "harmonic_balance.harmonics",
        "≥ every harmonic",
        &["harmonic_balance.harmonics=0"],
    ),
    (
        "harmonic_balance.samples",
        "> 2·harmonics",
        &["harmonic_balance.samples=20"],
    ),
    (
        "harmonic_balance.basis.spline.segments",
        "≥ degree + 1",
        &["harmonic_balance.basis.spline.segments=3"],
    ),
    (
        "harmonic_balance.basis.spline.segments",
        "> 2 × the highest harmonic",
        &[
            "harmonic_balance.basis.spline.degree=2",
            "harmonic_balance.basis.spline.segments=3",
            "boundaries.loads.0.harmonics.0.k=2",
        ],
    ),
    ("sweep.to", "≠ from", &["sweep.to=1000.0"]),
    ("sweep.max_step", "≥ step", &["sweep.max_step=0.005"]),
    (
        "boundaries.loads.harmonics.k",
        "at most once",
        &["boundaries.loads.0.harmonics=[{k: 1}, {k: 1}]"],
    ),
    (
        "boundaries.prescribed.harmonics.k",
        "at most once",
        &["boundaries.prescribed.0.harmonics=[{k: 1}, {k: 1}]"],
    ),
    (
        "contact.motion.harmonics.k",
        "at most once",
        &["contact.motion.harmonics=[{k: 1}, {k: 1}]"],
    ),
    (
        "contact.pairs.motion.harmonics.k",
        "at most once",
        &["contact.pairs.0.motion.harmonics=[{k: 1}, {k: 1}]"],
    ),
];

/// A numeric leaf of the pipeline schema: its key (`a.b.c`), its `--set` path (list entries as
/// `.0`), whether it is an integer, its description and the schema's own range.
struct NumericKey {
    key: String,
    set_path: String,
    integer: bool,
    description: String,
    minimum: Option<f64>,
    maximum: Option<f64>,
}

/// Every numeric key of the schema, following `$ref`, `allOf`/`anyOf`/`oneOf` and `items`;
/// maps with free keys (`geometry.parameters`) are skipped (their values are only finite).
fn numeric_keys(
    schema: &serde_json::Value,
    definitions: &serde_json::Value,
    key: &str,
    set_path: &str,
    description: Option<&str>,
    out: &mut Vec<NumericKey>,
) {
    use serde_json::Value;
    let Some(object) = schema.as_object() else {
        return;
    };
    let description = object
        .get("description")
        .and_then(Value::as_str)
        .or(description);
    if let Some(reference) = object.get("$ref").and_then(Value::as_str) {
        let name = reference.rsplit('/').next().unwrap_or_default();
        let target = definitions
            .get(name)
            .unwrap_or_else(|| panic!("unresolved $ref {reference}"));
        numeric_keys(target, definitions, key, set_path, description, out);
    }
    for combinator in ["allOf", "anyOf", "oneOf"] {
        for sub in object
            .get(combinator)
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            numeric_keys(sub, definitions, key, set_path, description, out);
        }
    }
    if let Some(items) = object.get("items") {
        numeric_keys(
            items,
            definitions,
            key,
            &format!("{set_path}.0"),
            description,
            out,
        );
    }
    if let Some(properties) = object.get("properties").and_then(Value::as_object) {
        for (name, sub) in properties {
            let join = |prefix: &str| {
                if prefix.is_empty() {
                    name.clone()
                } else {
                    format!("{prefix}.{name}")
                }
            };
            numeric_keys(sub, definitions, &join(key), &join(set_path), None, out);
        }
    }
    let types: Vec<&str> = match object.get("type") {
        Some(Value::String(t)) => vec![t.as_str()],
        Some(Value::Array(ts)) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    let integer = types.contains(&"integer");
    if (integer || types.contains(&"number")) && !out.iter().any(|k| k.set_path == set_path) {
        out.push(NumericKey {
            key: key.to_string(),
            set_path: set_path.to_string(),
            integer,
            description: description.unwrap_or_default().to_string(),
            minimum: object.get("minimum").and_then(Value::as_f64),
            maximum: object.get("maximum").and_then(Value::as_f64),
        });
    }
}

/// A bound a doc comment states: the limit and whether it is allowed.
#[derive(Clone, Copy, Debug)]
enum Bound {
    Lower(f64, bool),
    Upper(f64, bool),
}

/// The number at the start of `text` if what follows it ends the bound (`> 0,`, `≥ 1 and`,
/// `at most 1e9 (…)`), not if it starts an expression (`> 2·harmonics`, `> 2 × …`).
fn leading_number(text: &str) -> Option<(f64, usize)> {
    let end = text
        .find(|c: char| !(c.is_ascii_digit() || "eE+-.".contains(c)))
        .unwrap_or(text.len());
    // A full stop after the number ends the sentence.
    let end = text[..end].trim_end_matches('.').len();
    let value: f64 = text[..end].parse().ok()?;
    let rest = text[end..].trim_start();
    let ends = rest.is_empty()
        || rest.starts_with([',', ';', ')', ':', '.', '('])
        || rest.starts_with("and ");
    ends.then_some((value, end))
}

/// The bounds stated before `Default:` in a description, and the phrases, from their operator
/// on, that compare with something other than a number (`≥ step`, `≠ from`).
fn stated_bounds(description: &str) -> (Vec<Bound>, Vec<String>) {
    let text = description.split_whitespace().collect::<Vec<_>>().join(" ");
    let text = text.replace('−', "-");
    let text = text.split("Default:").next().unwrap_or_default();
    // Code spans (`points/at_<f>Hz/`) are names, not bounds.
    let mut text: String = text
        .split('`')
        .enumerate()
        .map(|(i, part)| if i % 2 == 0 { part } else { "code" })
        .collect::<Vec<_>>()
        .join("");
    let mut bounds = Vec::new();
    let blank = |text: &mut String, start: usize, end: usize| {
        text.replace_range(start..end, &" ".repeat(end - start));
    };
    // Intervals `in (a, b]`.
    while let Some(start) = text.find("in (").or_else(|| text.find("in [")) {
        let open = text.as_bytes()[start + 3];
        let body_end = text[start..]
            .find([')', ']'])
            .map(|i| start + i)
            .unwrap_or_else(|| panic!("an unclosed interval in {description:?}"));
        let close = text.as_bytes()[body_end];
        let (a, b) = text[start + 4..body_end]
            .split_once(',')
            .unwrap_or_else(|| panic!("an interval without a comma in {description:?}"));
        let (a, b): (f64, f64) = match (a.trim().parse(), b.trim().parse()) {
            (Ok(a), Ok(b)) => (a, b),
            _ => panic!("an interval of non-numbers in {description:?}"),
        };
        bounds.push(Bound::Lower(a, open == b'['));
        bounds.push(Bound::Upper(b, close == b']'));
        blank(&mut text, start, body_end + 1);
    }
    // `|·| ≤ x`.
    while let Some(start) = text.find("|·| ≤ ") {
        let after = start + "|·| ≤ ".len();
        let (x, len) = leading_number(&text[after..])
            .unwrap_or_else(|| panic!("|·| ≤ without a number in {description:?}"));
        bounds.push(Bound::Lower(-x, true));
        bounds.push(Bound::Upper(x, true));
        blank(&mut text, start, after + len);
    }
    // Integer ranges `2 … 7`.
    while let Some(mid) = text.find(" … ") {
        let start = text[..mid].rfind(' ').map_or(0, |i| i + 1);
        let after = mid + " … ".len();
        let a: f64 = text[start..mid]
            .parse()
            .unwrap_or_else(|_| panic!("a range of non-numbers in {description:?}"));
        let (b, len) = leading_number(&text[after..])
            .unwrap_or_else(|| panic!("a range of non-numbers in {description:?}"));
        bounds.push(Bound::Lower(a, true));
        bounds.push(Bound::Upper(b, true));
        blank(&mut text, start, after + len);
    }
    // Comparisons.
    let mut relational = Vec::new();
    let operators = ["≥", ">", "≤", "<", "≠", "at least", "at most"];
    let mut at = 0;
    while let Some((start, op)) = operators
        .iter()
        .filter_map(|op| text[at..].find(op).map(|i| (at + i, *op)))
        .min_by_key(|(i, _)| *i)
    {
        let after = start + op.len();
        let number = leading_number(text[after..].trim_start()).map(|(x, len)| {
            (
                x,
                after + (text[after..].len() - text[after..].trim_start().len()) + len,
            )
        });
        match (op, number) {
            ("≥" | "at least", Some((x, end))) => {
                bounds.push(Bound::Lower(x, true));
                at = end;
            }
            (">", Some((x, end))) => {
                bounds.push(Bound::Lower(x, false));
                at = end;
            }
            ("≤" | "at most", Some((x, end))) => {
                bounds.push(Bound::Upper(x, true));
                at = end;
            }
            ("<", Some((x, end))) => {
                bounds.push(Bound::Upper(x, false));
                at = end;
            }
            _ => {
                relational.push(text[start..].to_string());
                at = after;
            }
        }
    }
    (bounds, relational)
}

/// A value as `--set` writes it: an integer, or a float in exponent form.
fn yaml_number(x: f64, integer: bool) -> String {
    if integer {
        format!("{}", x as i64)
    } else {
        format!("{x:e}")
    }
}

/// The value just outside a bound and the one at or just inside it.
fn outside_and_inside(bound: Bound, integer: bool) -> (f64, f64) {
    let step = if integer {
        1.0
    } else if bound_value(bound) == 0.0 {
        1e-9
    } else {
        1e-6 * bound_value(bound).abs()
    };
    match bound {
        Bound::Lower(x, true) => (x - step, x),
        Bound::Lower(x, false) => (x, x + step),
        Bound::Upper(x, true) => (x + step, x),
        Bound::Upper(x, false) => (x, x - step),
    }
}

fn bound_value(bound: Bound) -> f64 {
    match bound {
        Bound::Lower(x, _) | Bound::Upper(x, _) => x,
    }
}

/// `load_pipeline` of `BOUNDS_BASE` with the key's setup and `sets`.
fn load_with(key: &str, sets: &[String]) -> Result<hbcontact::config::Pipeline, String> {
    let mut overrides: Vec<String> = BOUNDS_SETUP
        .iter()
        .filter(|(prefix, _)| key.starts_with(prefix))
        .flat_map(|(_, s)| s.iter().map(|s| s.to_string()))
        .collect();
    overrides.extend(sets.iter().cloned());
    load_pipeline(&root().join(BOUNDS_BASE), &overrides).map_err(|e| e.to_string())
}

/// The message with list indices and harmonic labels taken out, so that
/// `boundaries.loads[0].harmonics (k = 1).cos[0]` reads `boundaries.loads.harmonics.cos`.
fn without_indices(message: &str) -> String {
    let mut out = String::new();
    let mut rest = message;
    while !rest.is_empty() {
        if let Some(tail) = rest.strip_prefix('[') {
            if let Some(close) = tail.find(']') {
                if tail[..close].chars().all(|c| c.is_ascii_digit()) && close > 0 {
                    rest = &tail[close + 1..];
                    continue;
                }
            }
        }
        if let Some(tail) = rest.strip_prefix(" (k = ") {
            if let Some(close) = tail.find(')') {
                if tail[..close].chars().all(|c| c.is_ascii_digit()) {
                    rest = &tail[close + 1..];
                    continue;
                }
            }
        }
        let c = rest.chars().next().unwrap_or_default();
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    out
}

/// Refused, in a message that names the pipeline file and the key.
fn assert_refused_naming(key: &str, sets: &[String], claim: &str) {
    match load_with(key, sets) {
        Ok(_) => panic!("{key}: {sets:?} is accepted, but {claim}"),
        Err(message) => {
            assert!(
                message.contains("strip_sweep.yaml") && without_indices(&message).contains(key),
                "{key}: {sets:?} ({claim}) is refused, but the message does not name the file and the key: {message}"
            );
        }
    }
}

/// TEST GOAL: every numeric key holds the bounds its documentation states (issue #46). The
/// pipeline schema is walked; for every number or integer key, each bound its description
/// states before `Default:` (`> 0`, `≥ 1`, `in (0, 1e-2]`, `in [1e-3, 1e3]`, `|·| ≤ 1`,
/// `2 … 7`, `at most 1e9`) and the schema's own `minimum`/`maximum` are tried: a value just
/// outside is refused naming the file and the key, the value at or just inside is accepted.
/// Bounds relative to other keys (`≥ step`, `≠ from`) are tried from a table, which must match
/// the descriptions exactly; and every floating key refuses ±inf, NaN and ±1e31. Before, an
/// infinite `geometry.max_aspect_ratio`, `sweep.from = 1e29`, `stability.every = 0`,
/// `solver.tolerance = 1e29` and `solver.c_scale = 1e29` were all taken.
#[test]
fn every_numeric_key_holds_the_bounds_its_documentation_states() {
    let schema = hbcontact::config::pipeline_schema();
    let definitions = schema
        .get("definitions")
        .cloned()
        .unwrap_or(serde_json::Value::Null);
    let mut keys = Vec::new();
    numeric_keys(&schema, &definitions, "", "", None, &mut keys);
    let names: Vec<&str> = keys.iter().map(|k| k.key.as_str()).collect();
    for expected in [
        "geometry.max_aspect_ratio",
        "harmonic_balance.solver.c_scale",
        "harmonic_balance.basis.spline.degree",
        "contact.obstacle.circle.radius",
        "boundaries.loads.harmonics.k",
        "sweep.write_at",
        "stability.every",
    ] {
        assert!(
            names.contains(&expected),
            "the walk missed {expected}: {names:?}"
        );
    }
    let mut relational_used = vec![false; BOUNDS_RELATIONAL.len()];
    let mut tried = 0;
    for k in &keys {
        let (mut bounds, relational) = stated_bounds(&k.description);
        if k.integer {
            // An unsigned type's `minimum: 0` is the type's, not a documented bound.
            bounds.extend(
                k.minimum
                    .filter(|&m| m > 0.0)
                    .map(|m| Bound::Lower(m, true)),
            );
            bounds.extend(k.maximum.map(|m| Bound::Upper(m, true)));
        }
        for bound in bounds {
            let (outside, inside) = outside_and_inside(bound, k.integer);
            if k.integer && outside < 0.0 {
                continue; // an unsigned type refuses it before any check
            }
            let set = |x: f64| format!("{}={}", k.set_path, yaml_number(x, k.integer));
            assert_refused_naming(
                &k.key,
                &[set(outside)],
                &format!("the doc states {bound:?}"),
            );
            let mut sets: Vec<String> = BOUNDS_INSIDE_COMPANIONS
                .iter()
                .filter(|(key, _)| *key == k.key)
                .flat_map(|(_, s)| s.iter().map(|s| s.to_string()))
                .collect();
            sets.push(set(inside));
            if let Err(e) = load_with(&k.key, &sets) {
                panic!("{}: {sets:?} is within {bound:?} but refused: {e}", k.key);
            }
            tried += 1;
        }
        for phrase in relational {
            let Some(i) = BOUNDS_RELATIONAL
                .iter()
                .position(|(key, start, _)| *key == k.key && phrase.starts_with(start))
            else {
                panic!(
                    "{}: the description states {phrase:?}, which is neither a number nor in BOUNDS_RELATIONAL",
                    k.key
                );
            };
            relational_used[i] = true;
            let sets: Vec<String> = BOUNDS_RELATIONAL[i]
                .2
                .iter()
                .map(|s| s.to_string())
                .collect();
            assert_refused_naming(&k.key, &sets, &format!("the doc states {phrase:?}"));
            tried += 1;
        }
        if !k.integer {
            for bad in [".inf", "-.inf", ".nan", "1e31", "-1e31"] {
                let sets = [format!("{}={bad}", k.set_path)];
                assert_refused_naming(&k.key, &sets, "numbers are finite and at most 1e30");
            }
        }
    }
    for (used, (key, phrase, _)) in relational_used.iter().zip(BOUNDS_RELATIONAL) {
        assert!(
            used,
            "BOUNDS_RELATIONAL names {key} {phrase:?}, which no description states"
        );
    }
    eprintln!("{tried} bounds tried on {} numeric keys", keys.len());
    assert!(tried >= 50, "only {tried} bounds tried");
}

/// TEST GOAL: the documented bounds that were not enforced are refused by `check` with exit
/// code 2, naming the file and the key: an infinite `geometry.max_aspect_ratio`, a sweep from
/// 1e29 Hz, `stability.every = 0`, a contact tolerance of 1e29 (it stopped after one Newton
/// iteration, 7% off) and `c_scale = 1e29` (contact force 0).
#[test]
fn documented_bounds_that_ran_before_are_refused_by_check() {
    let cases: [(&str, &str); 6] = [
        (
            "geometry.max_aspect_ratio=.inf",
            "geometry.max_aspect_ratio = inf must be a finite number of at least 1",
        ),
        (
            "sweep={from: 1e29, to: 1800.0}",
            "sweep.from = 1e29 Hz is above 1e9 Hz",
        ),
        ("stability.every=0", "stability.every = 0: give at least 1"),
        (
            "harmonic_balance.solver.tolerance=1e29",
            "harmonic_balance.solver.tolerance = 1e29 is above 1e-2",
        ),
        (
            "harmonic_balance.solver.c_scale=1e29",
            "harmonic_balance.solver.c_scale = 1e29 must lie in [1e-3, 1e3]",
        ),
        (
            "harmonic_balance.solver.tolerance=0.011",
            "harmonic_balance.solver.tolerance = 0.011 is above 1e-2",
        ),
    ];
    for (set, named) in cases {
        let (code, err) = check(&[set]);
        assert_eq!(code, Some(2), "{set}: {err}");
        assert!(
            err.contains(named) && err.contains("strip_wall.yaml"),
            "{set}: {err}"
        );
    }
}

/// TEST GOAL: a pipeline or study file is refused before the YAML parser sees it when it is
/// larger than 4 MiB or nests deeper than 64 (issue #46: a 200 kB pipeline of 100 000 nested
/// `[` kept `check` busy for over a minute): exit 2 from `check` and `study`, naming the file,
/// the line and the limit (the limit's message, so the parser never ran; no wall time is
/// asserted); flow (`[[[`), block (`- - -`) and
/// indented nesting are all counted, and the shipped pipelines and studies pass.
#[test]
fn huge_or_deeply_nested_yaml_is_refused_before_parsing() {
    let dir = root().join("output/test-runs/config-yaml-limits");
    std::fs::create_dir_all(&dir).unwrap();
    let flow = format!(
        "name: x\ngeometry: {}{}\n",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    let block = format!("name: x\ngeometry:\n  {}x\n", "- ".repeat(100_000));
    let mut indented = String::from("name: x\n");
    for d in 0..100 {
        indented.push_str(&format!("{}k{d}:\n", " ".repeat(d)));
    }
    let huge = format!("name: x\n# {}\n", "x".repeat(5 << 20));
    for (tag, text, named) in [
        (
            "flow",
            &flow,
            "line 2: the YAML nests 65 collections deep, beyond the limit of 64",
        ),
        ("block", &block, "line 3: the YAML nests"),
        ("indented", &indented, "line 66: the YAML nests"),
        ("huge", &huge, "larger than 4 MiB"),
    ] {
        for command in ["check", "study"] {
            let file = dir.join(format!("{tag}-{command}.yaml"));
            std::fs::write(&file, text).unwrap();
            let out = std::process::Command::new(env!("CARGO_BIN_EXE_hbcontact"))
                .args([command, file.to_str().unwrap(), "-q"])
                .current_dir(root())
                .output()
                .expect("the hbcontact binary runs");
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{tag} {command}: {err}");
            assert!(
                err.contains(&format!("{tag}-{command}.yaml")) && err.contains(named),
                "{tag} {command}: {err}"
            );
        }
    }
    for dir in ["pipelines", "pipelines/hard", "pipelines/scenes", "studies"] {
        for entry in std::fs::read_dir(root().join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "yaml") {
                let text = std::fs::read_to_string(&path).unwrap();
                let checked = hbcontact::config::limits::check_yaml(&text, "pipeline");
                assert!(checked.is_ok(), "{}: {checked:?}", path.display());
            }
        }
    }
}
