//! The 2T branch a sweep follows from a period doubling (`sweep.follow_period_doubling`),
//! against the orbit an independent time march of the same structure settles on.

mod common;

use hbcontact::config::Pipeline;
use hbcontact::pipeline::{self, RunOptions};
use hbcontact::sweep::{SweepRow, SweepSummary};

/// The preloaded rod (`pipelines/scenes/preloaded_rod.yaml`) swept 6–11 kHz, its 2T
/// branches followed.
fn rod_sweep() -> (Pipeline, SweepSummary) {
    let sets = [
        "sweep.from=6000",
        "sweep.to=11000",
        "sweep.max_points=1500",
        "sweep.follow_period_doubling=true",
    ];
    let p = common::scene("scenes/preloaded_rod", &sets);
    let options = RunOptions {
        out: Some(common::temp_out("subharmonic-rod-sweep")),
        ..Default::default()
    };
    let s = hbcontact::sweep::run(&p, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"))
        .summary;
    (p, s)
}

fn column(s: &SweepSummary, name: &str) -> usize {
    (s.columns.iter().position(|c| c == name)).unwrap_or_else(|| panic!("no column {name}"))
}

/// The row of `rows` nearest `hz` among those before the first that turns back in frequency
/// (the rising part of a branch).
fn rising_row_near(rows: &[SweepRow], hz: f64) -> &SweepRow {
    let rising = rows
        .windows(2)
        .position(|w| w[1].frequency_hz < w[0].frequency_hz)
        .map_or(rows.len(), |i| i + 1);
    rows[..rising]
        .iter()
        .min_by(|a, b| {
            (a.frequency_hz - hz)
                .abs()
                .total_cmp(&(b.frequency_hz - hz).abs())
        })
        .expect("rows")
}

/// TEST GOAL: past the period doubling of the preloaded rod's T-periodic curve at 7837 Hz
/// (H = 10), the sweep follows the 2T branch from the row beside it to where it crosses the
/// curve again (8415 Hz when measured, 2026-11-29): its subharmonic (f/2) amplitude grows
/// from near zero at its first row; at 8100 Hz it is stable (Hill's method on the 2T state),
/// and it is the orbit a time march from the unstable T state settles on (a 2T subharmonic):
/// peak-to-peak +0.3% and mean contact force +0.06% of the march's when measured (held to
/// 1.5% and 1%), where the T state is 17% off in peak-to-peak.
#[test]
fn the_2t_branch_of_a_period_doubling_is_the_orbit_time_marching_settles_on() {
    let (p, s) = rod_sweep();
    let b = s.branches.first().expect("a 2T branch");
    println!(
        "branch from {:.4} Hz (row {}): {} rows, {}",
        b.from_hz,
        b.from_row,
        b.rows.len(),
        b.ended
    );
    assert!((7825.0..7850.0).contains(&b.from_hz), "{}", b.from_hz);
    let rejoins = b.rejoins_hz.expect("the branch crosses the curve again");
    assert!((8380.0..8450.0).contains(&rejoins), "rejoins at {rejoins}");
    let subharmonics: Vec<f64> = b.rows.iter().filter_map(|r| r.subharmonic).collect();
    let largest = subharmonics.iter().copied().fold(0.0, f64::max);
    assert_eq!(subharmonics.len(), b.rows.len());
    assert!(
        subharmonics[0] < 0.3 * largest,
        "first {} of {largest}",
        subharmonics[0]
    );
    let (p2p, mean) = (
        column(&s, "probe_peak_to_peak"),
        column(&s, "mean_contact_force"),
    );
    let on_branch = rising_row_near(&b.rows, 8100.0);
    let on_curve = s
        .rows
        .iter()
        .min_by(|a, b| {
            (a.frequency_hz - 8100.0)
                .abs()
                .total_cmp(&(b.frequency_hz - 8100.0).abs())
        })
        .expect("rows");
    assert_eq!(on_branch.stable, Some(true), "{on_branch:?}");
    assert_eq!(on_curve.stable, Some(false), "{on_curve:?}");
    // The march from the unstable T state at 8100 Hz.
    let sets = [
        format!("harmonic_balance.frequency={}", on_branch.frequency_hz),
        "transient.start=harmonic_balance".into(),
        "transient.perturbation=0.01".into(),
        "transient.max_periods=600".into(),
    ];
    let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
    let t = common::scene("scenes/preloaded_rod", &sets);
    let options = RunOptions {
        out: Some(common::temp_out("subharmonic-rod-march")),
        ..Default::default()
    };
    let marched = pipeline::run_transient(&t, &options, &hbcontact::Silent)
        .unwrap_or_else(|e| panic!("{e}"))
        .summary;
    let late = &marched
        .transient
        .as_ref()
        .expect("transient details")
        .late_response;
    println!("{}", late.description);
    assert_eq!(
        late.kind,
        hbcontact::pipeline::late::LateKind::Subharmonic,
        "{}",
        late.description
    );
    let outputs = hbcontact::sweep::outputs(&p);
    let value = |name: &str| {
        let o = outputs[column(&s, name)];
        o.value(&marched, None)
    };
    let (march_p2p, march_mean) = (value("probe_peak_to_peak"), value("mean_contact_force"));
    let off = |a: f64, b: f64| (a - b) / b;
    let (branch_p2p, branch_mean) = (
        off(on_branch.values[p2p], march_p2p),
        off(on_branch.values[mean], march_mean),
    );
    let curve_p2p = off(on_curve.values[p2p], march_p2p);
    println!(
        "at {:.2} Hz against the march: 2T branch peak-to-peak {branch_p2p:+.4}, mean force {branch_mean:+.4}; the T curve's peak-to-peak {curve_p2p:+.4}",
        on_branch.frequency_hz
    );
    assert!(branch_p2p.abs() < 0.015, "{branch_p2p}");
    assert!(branch_mean.abs() < 0.01, "{branch_mean}");
    assert!(curve_p2p.abs() > 0.1, "{curve_p2p}");
}

/// TEST GOAL: every period doubling a sweep lists is checked on the 2T problem. On the coarse
/// strip swept 1150–1400 Hz at H = 40 Hill's method lists a pair at 1270.5 and 1284.7 Hz
/// (|μ| ≤ 1.029), but its multiplier there moves with the modes it keeps dynamic (0.88–1.04
/// when measured, 2026-11-29) and the determinant of the 2T problem's odd-harmonic Newton
/// matrix keeps its sign around them: both are listed as not confirmed, each with a warning
/// naming the check to make. The coarse strip's doubling at H = 10 (located at
/// 1046.5 Hz on the 1000–1800 Hz sweep, 1050.7 Hz on 1000–1100 Hz) is confirmed.
#[test]
fn a_period_doubling_hill_finds_at_h_40_on_the_coarse_strip_is_not_confirmed_by_the_2t_problem() {
    use hbcontact::sweep::bifurcations::BifurcationKind;
    let sweep = |sets: &[&str], tag: &str| {
        let p = common::scene("strip_sweep", sets);
        let options = RunOptions {
            out: Some(common::temp_out(tag)),
            ..Default::default()
        };
        hbcontact::sweep::run(&p, &options, &hbcontact::Silent)
            .unwrap_or_else(|e| panic!("{e}"))
            .summary
    };
    let doublings = |s: &SweepSummary| -> Vec<(f64, Option<bool>)> {
        (s.bifurcations.iter())
            .filter(|b| b.kind == BifurcationKind::PeriodDoubling)
            .map(|b| (b.frequency_hz, b.confirmed))
            .collect()
    };
    let coarse = "geometry.parameters.lc=0.025";
    let s = sweep(
        &[
            coarse,
            "sweep.from=1150",
            "sweep.to=1400",
            "harmonic_balance.harmonics=40",
        ],
        "subharmonic-strip-h40",
    );
    let listed = doublings(&s);
    println!("H = 40: {listed:?}");
    assert!(!listed.is_empty(), "no period doubling listed at H = 40");
    for (f, confirmed) in &listed {
        assert_eq!(*confirmed, Some(false), "{f} Hz");
        let named = format!("the period doubling at {f:.4} Hz is not confirmed");
        assert!(
            s.warnings.iter().any(|w| w.contains(&named)),
            "{:?}",
            s.warnings
        );
    }
    let s = sweep(&[coarse, "sweep.to=1100"], "subharmonic-strip-h10");
    let listed = doublings(&s);
    println!("H = 10: {listed:?}");
    assert!(
        listed
            .iter()
            .any(|(f, c)| (1040.0..1060.0).contains(f) && *c == Some(true)),
        "{listed:?}"
    );
}
