//! Several contact pairs in one scene (`contact.pairs`): each pair a boundary against its own
//! obstacle, their rows stacked in one B. Checked against the same contact written as one
//! pair, against the product's time marching of the same two-pair model, and in `check`.

mod common;

use std::path::Path;

use common::{hbcontact, json_number as number, read_json, run_cli as run};

const PAIRS: &str = "tests/data/two_strips_wall_pairs.yaml";
const ONE_PAIR: &str = "contact={boundary: tip, obstacle: {curve: wall}, search_distance: 0.001}";

/// The rows of a CSV file after its header, as numbers, sorted.
fn rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    rows.sort_by(|a, b| a[0].total_cmp(&b[0]));
    rows
}

fn assert_close(a: &[Vec<f64>], b: &[Vec<f64>], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (ra, rb) in a.iter().zip(b) {
        for (x, y) in ra.iter().zip(rb) {
            assert!(
                (x - y).abs() <= 1e-9 * (1.0 + y.abs()),
                "{what}: {ra:?} vs {rb:?}"
            );
        }
    }
}

/// TEST GOAL: the strip's tip face against a wall split in two segments, written as two
/// contact pairs (tests/data/two_strips_wall_pairs.yaml: 2 nodes face the upper segment, 3
/// the lower), is the same contact as the face against the whole wall as one pair: the probe,
/// the contact force history and the pressure along the face agree to 1e-9 (the same rows of
/// B in another order), and the two pairs' pressure tables together are the one pair's.
#[test]
fn a_face_split_between_two_pairs_equals_the_face_against_the_whole_wall() {
    let two = run("run", PAIRS, "pairs-two", &[]);
    let one = run("run", PAIRS, "pairs-one", &[ONE_PAIR]);
    let (s2, s1) = (
        read_json(&two.join("summary.json")),
        read_json(&one.join("summary.json")),
    );
    for pointer in [
        "/contact/mean_contact_force",
        "/contact/peak_contact_force",
        "/probes/probe/harmonics_x/0",
    ] {
        let (a, b) = (number(&s2, pointer), number(&s1, pointer));
        println!("{pointer}: two pairs {a:.12e}, one pair {b:.12e}");
        assert!((a - b).abs() <= 1e-9 * b.abs(), "{pointer}: {a} vs {b}");
    }
    let history = |d: &Path| {
        let text = std::fs::read_to_string(d.join("contact.csv")).unwrap();
        let header: Vec<String> = text
            .lines()
            .next()
            .unwrap()
            .split(',')
            .map(String::from)
            .collect();
        let col = header.iter().position(|h| h == "total_force").unwrap();
        rows(&d.join("contact.csv"))
            .iter()
            .map(|r| vec![r[0], r[col]])
            .collect::<Vec<_>>()
    };
    assert_close(&history(&two), &history(&one), "contact.csv total force");
    let mut split = rows(&two.join("plots/contact_pressure_0_tip.csv"));
    split.extend(rows(&two.join("plots/contact_pressure_1_tip.csv")));
    split.sort_by(|a, b| a[0].total_cmp(&b[0]));
    // Columns node, arc length, pressure, force, opening.
    assert_close(
        &split,
        &rows(&one.join("plots/contact_pressure.csv")),
        "pressure tables",
    );
    assert_eq!(split.len(), 5);
}

/// TEST GOAL: harmonic balance (H = 20) on the two-pair scene agrees with the product's time
/// marching of the same two-pair model: the probe's first harmonic (measured −0.12%) and the
/// mean contact force (+0.04%) within 1%.
#[test]
fn two_contact_pairs_agree_with_the_marching_of_the_same_model() {
    let hb = read_json(&run("run", PAIRS, "pairs-hb", &[]).join("summary.json"));
    let tm = read_json(&run("transient", PAIRS, "pairs-tm", &[]).join("summary.json"));
    common::assert_agrees_with_marching(
        &hb,
        &tm,
        &["/probes/probe/harmonics_x/0", "/contact/mean_contact_force"],
        1e-2,
    );
}

/// TEST GOAL: `check` reports each pair by its key: its nodes, those dropped and its smallest
/// gap, in words and in `--json` (`contact_pairs`), the totals over the pairs beside them.
#[test]
fn check_reports_each_contact_pair() {
    let r = hbcontact(&["check", PAIRS]);
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for needle in [
        "contact.pairs[0] `tip`: 2 of 5 boundary nodes face the obstacle",
        "contact.pairs[1] `tip`: 3 of 5 boundary nodes face the obstacle",
        "dropped: 3 off the obstacle, 0 beyond the search distance",
        "smallest initial gap 1.000e-7 m",
    ] {
        assert!(text.contains(needle), "{needle}: {text}");
    }
    let r = hbcontact(&["check", PAIRS, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["contact_nodes"], 5);
    assert_eq!(v["contact_pairs"][1]["key"], "contact.pairs[1]");
    assert_eq!(v["contact_pairs"][1]["nodes"], 3);
}

/// TEST GOAL: a contact block that mixes one pair's keys with `pairs`, an empty `pairs`, and a
/// pair whose obstacle moves at a harmonic above H are refused (exit 2) naming the key.
#[test]
fn contact_pairs_that_cannot_be_meant_are_refused_naming_the_key() {
    let cases = [
        (
            "contact={boundary: tip, obstacle: {curve: wall}, pairs: [{boundary: tip, obstacle: {curve: wall}}]}",
            "not both",
        ),
        ("contact={pairs: []}", "contact.pairs is empty"),
        (
            "contact={pairs: [{boundary: tip, obstacle: {curve: wall_low}}, {boundary: tip, obstacle: {line: {point: [0.2, 0.0], normal: [-1.0, 0.0]}}, motion: {harmonics: [{k: 30, cos: [1.0e-8, 0.0]}]}}]}",
            "contact.pairs[1].motion",
        ),
    ];
    for (set, needle) in cases {
        let r = hbcontact(&["check", PAIRS, "--set", set]);
        let err = String::from_utf8_lossy(&r.stderr);
        println!("{err}");
        assert_eq!(r.status.code(), Some(2), "{err}");
        assert!(err.contains(needle), "{needle}: {err}");
    }
}
