//! Harmonics chosen per run and per sweep point: `harmonic_balance.harmonics: {min, max}` with
//! `harmonic_balance.tolerance` (`hbm::adaptive`, `hbm::continuation` levels).

mod common;

use hbcontact::hbm::adaptive::HarmonicsChosen;
use hbcontact::pipeline::Summary;

fn chosen(s: &Summary) -> HarmonicsChosen {
    let solver = s.contact.as_ref().and_then(|c| c.solver.as_ref());
    let chosen = solver.and_then(|s| s.harmonics_chosen.clone());
    chosen.expect("a run with a range of harmonics says how it chose H")
}

fn mean_force(s: &Summary) -> f64 {
    s.contact.as_ref().expect("contact").mean_contact_force
}

/// TEST GOAL: a run with a range doubles H from `min` while the answer changes by more than
/// the tolerance from the level below; the H it stops at gives, against a fixed H = 80, the
/// probe's first harmonic and the mean contact force within that tolerance (the estimate is
/// an honest bound), and the summary reports that H. Measured on strip_wall at 3%: levels 5
/// (21.7%), 10 (12.1%), 20 (3.09%), 40 (1.20%); on its 25 mm mesh 5 (21.1%), 10 (5.57%),
/// 20 (2.07%).
#[test]
fn a_run_raises_h_until_the_change_from_the_level_below_meets_the_tolerance() {
    for mesh in [None, Some("geometry.parameters.lc=0.025")] {
        let tag = format!("range-strip-wall{}", mesh.map_or("", |_| "-coarse"));
        let mut sets = vec![
            "harmonic_balance.harmonics={min: 5, max: 80}",
            "harmonic_balance.tolerance=0.03",
            "stability.check=false",
        ];
        sets.extend(mesh);
        let s = common::run_summary("strip_wall", &sets, &tag);
        let c = chosen(&s);
        levels_double_until_the_tolerance(&c, 0.03);
        let solver = s
            .contact
            .as_ref()
            .and_then(|c| c.solver.as_ref())
            .expect("solver");
        assert_eq!(solver.harmonics, c.chosen());
        let mut fixed = vec!["harmonic_balance.harmonics=80", "stability.check=false"];
        fixed.extend(mesh);
        let reference = common::run_summary("strip_wall", &fixed, &format!("{tag}-80"));
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
        let probe = rel(
            common::first_probe_harmonic(&s),
            common::first_probe_harmonic(&reference),
        );
        let mean = rel(mean_force(&s), mean_force(&reference));
        assert!(
            probe <= 0.03 && mean <= 0.03,
            "{tag}: H = {} against H = 80: probe {probe:.2e}, mean force {mean:.2e}",
            c.chosen()
        );
    }
}

/// The levels of `c` double, each passed only where its estimate or its c-change did not
/// meet `tolerance`, and the last meets it.
fn levels_double_until_the_tolerance(c: &HarmonicsChosen, tolerance: f64) {
    let levels: Vec<usize> = c.levels.iter().map(|l| l.harmonics).collect();
    assert!(c.met && levels.len() >= 2, "{c:?}");
    for (pair, l) in levels.windows(2).zip(&c.levels) {
        assert_eq!(pair[1], 2 * pair[0], "levels double: {levels:?}");
        let c_settled = l.c_change.is_none_or(|x| x <= 1e-2);
        assert!(
            l.estimate.is_none_or(|e| e > tolerance) || !c_settled,
            "a level that met the tolerance was passed: {c:?}"
        );
    }
    let last = c.levels.last().expect("a level");
    assert!(last.estimate.is_some_and(|e| e <= tolerance), "{c:?}");
}

/// TEST GOAL: a level whose truncation estimate meets the tolerance but whose answer still
/// depends on c (the knob check's change above 1%) is not kept: the run raises H, as the
/// check advises, and warns of c only if that does not settle it. On strip_wall at H = 10 the
/// estimate is 12.2% and the c-change 4.4%; at 15% tolerance H = 20 (estimate 3.1%, c-change
/// 0.4%) is kept with no c warning.
#[test]
fn a_run_raises_h_where_the_answer_depends_on_c_instead_of_warning() {
    let sets = [
        "harmonic_balance.harmonics={min: 10, max: 40}",
        "harmonic_balance.tolerance=0.15",
        "stability.check=false",
    ];
    let s = common::run_summary("strip_wall", &sets, "range-strip-wall-c");
    let c = chosen(&s);
    let first = &c.levels[0];
    assert!(first.estimate.is_some_and(|e| e <= 0.15), "{c:?}");
    assert!(first.c_change.is_some_and(|x| x > 1e-2), "{c:?}");
    assert!(c.met && c.chosen() > 10, "{c:?}");
    assert!(
        !s.warnings.iter().any(|w| w.contains("second c")),
        "{:?}",
        s.warnings
    );
}

/// TEST GOAL: a range whose max does not meet the tolerance says so, naming the change it
/// measured and the key to raise; the run still reports H = max.
#[test]
fn a_range_too_narrow_for_the_tolerance_warns_naming_harmonics_max() {
    let sets = [
        "harmonic_balance.harmonics={min: 5, max: 10}",
        "stability.check=false",
    ];
    let s = common::run_summary("strip_wall", &sets, "range-strip-wall-narrow");
    let c = chosen(&s);
    assert!(!c.met && c.chosen() == 10, "{c:?}");
    let warning = s.warnings.iter().find(|w| w.contains("harmonics.max"));
    let warning = warning.unwrap_or_else(|| panic!("{:?}", s.warnings));
    assert!(warning.contains("from H = 5 to H = 10"), "{warning}");
}

/// TEST GOAL: what a range cannot be combined with, and malformed ranges, are refused naming
/// the key and the fix.
#[test]
fn a_range_of_harmonics_is_refused_where_it_cannot_apply_naming_the_fix() {
    let err = |name: &str, sets: &[&str]| -> String {
        let path = common::root()
            .join("pipelines")
            .join(format!("{name}.yaml"));
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        match hbcontact::pipeline::load_pipeline(&path, &sets) {
            Ok(_) => panic!("{name} {sets:?} must not load"),
            Err(e) => e.to_string(),
        }
    };
    let range = "harmonic_balance.harmonics={min: 10, max: 40}";
    let cases: [(&str, Vec<&str>, &str); 6] = [
        (
            "strip_wall",
            vec![range, "harmonic_balance.samples=640"],
            "leave samples out",
        ),
        (
            "strip_wall",
            vec![range, "harmonic_balance.basis={spline: {segments: 41}}"],
            "Fourier basis",
        ),
        (
            "strip_wall",
            vec!["harmonic_balance.harmonics={min: 40, max: 10}"],
            "use max ≥ min",
        ),
        (
            "strip_wall",
            vec!["harmonic_balance.tolerance=0.01"],
            "harmonics: {min: 20, max: 80}",
        ),
        (
            "strip_wall",
            vec!["harmonic_balance.harmonics={min: 10}"],
            "or a range",
        ),
        (
            "scenes/friction_block",
            vec![range],
            "frictionless contact only",
        ),
    ];
    for (name, sets, fix) in cases {
        let e = err(name, &sets);
        assert!(e.contains("harmonic_balance"), "{sets:?}: {e}");
        assert!(e.contains(fix), "{sets:?}: {e}");
    }
}

/// TEST GOAL: a sweep with a range chooses H per point: each row's `harmonics` lies in the
/// range and is in sweep.csv; every row below max met the tolerance (its estimate is in the
/// row); the rows at max above it are the ones the summary counts as unsettled and warns of;
/// H changes along the curve and the curve reaches its end.
#[test]
fn a_sweep_chooses_h_per_point_and_every_row_below_max_meets_the_tolerance() {
    let sets = [
        "geometry.parameters.lc=0.025",
        "harmonic_balance.harmonics={min: 5, max: 20}",
        "harmonic_balance.tolerance=0.05",
        "stability.check=false",
    ];
    let out = common::run_cli("sweep", "pipelines/strip_sweep.yaml", "range-sweep", &sets);
    let s = common::read_json(&out.join("sweep.json"));
    assert!(s["stopped"].is_null(), "{}", s["stopped"]);
    let rows = s["rows"].as_array().expect("rows");
    let (mut seen, mut unsettled) = (Vec::new(), 0);
    for r in rows {
        let h = r["harmonics"].as_u64().expect("harmonics") as usize;
        assert!((5..=20).contains(&h), "{r}");
        let estimate = r["truncation_estimate"].as_f64();
        if h < 20 {
            assert!(estimate.is_some_and(|e| e <= 0.05), "{r}");
        } else if estimate.is_none_or(|e| e > 0.05) {
            unsettled += 1;
        }
        if !seen.contains(&h) {
            seen.push(h);
        }
    }
    assert!(seen.len() >= 2, "H never changed: {seen:?}");
    let along = &s["harmonics_chosen"];
    assert_eq!(
        along["unsettled"].as_u64(),
        Some(unsettled as u64),
        "{along}"
    );
    assert!(along["changes"].as_u64().is_some_and(|c| c >= 1), "{along}");
    let warns = s["warnings"].to_string().contains("harmonics.max");
    assert_eq!(warns, unsettled > 0, "{}", s["warnings"]);
    let csv = std::fs::read_to_string(out.join("sweep.csv")).expect("sweep.csv");
    let header = csv.lines().next().expect("a header");
    assert!(
        header.contains(",harmonics,truncation_estimate,"),
        "{header}"
    );
}
