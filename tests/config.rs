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
