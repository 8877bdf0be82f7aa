//! The user scenes of `pipelines/scenes/` (issue #45): contact problems engineers of the
//! field study, each swept from 0.7 to 1.5 times the natural frequency its drive excites, at
//! the H that `hbcontact accuracy --ladder harmonic_balance.harmonics=5,10,20,40
//! --tolerance 1e-2` recommends at a touching frequency (the largest of the cheapest rungs
//! for the probe's first harmonic, its peak-to-peak and the mean contact force).
//!
//! Each test sweeps its scene end to end as shipped (stability check included) and holds the
//! physics a user reads off the curve against closed forms it did not come from:
//! - f1 of the scene's `modes` against Euler–Bernoulli beam or elementary bar theory,
//!   f = (λ²/2π)(h/L²)√(E/12ρ) (λ = 1.8751 clamped–free, 4.7300 clamped–clamped) and
//!   f = c/4L, c = √(E/ρ) (plane stress) or √(E/(ρ(1 − ν²))) (plane strain);
//! - contact only stiffens: the resonance peak (largest probe amplitude) lies above f1 and
//!   below the frequency of the stop held closed all period, f_c (clamped–pinned tip:
//!   (3.9266/1.8751)² f1; clamped–clamped pinned at mid-span: the clamped–pinned half,
//!   4 (3.9266/4.7300)² f1; a bar held at both ends: 2 f1), and a one-sided stop (the
//!   impact oscillator, zero gap) stays below the bilinear frequency 2 f1 f_c / (f1 + f_c);
//! - a hardening resonance bends over: the curve has a fold above f1;
//! - the body reaches the stop (peak amplitude above the gap at the probe) and the stop holds
//!   it below the free resonance (a linear run with the stop out of reach);
//! - off resonance, at both ends of the sweep, the body does not touch (contact fraction 0);
//! - the preloaded contact: closed all period at 0.7 f1 with the mean force of the static
//!   bar, F_s (L − d/2)/L, and never open all period.
//!
//! The lightly damped strip's curve stops among states no structure follows: it is held to
//! the sweep from both ends (`sweep::other_end`) and to a march between them.
//!
//! Symbols: f1 first natural frequency of the driven motion [Hz]; h beam depth, L length [m];
//! E Young's modulus [Pa], ρ density [kg/m³], ν Poisson's ratio; F_s static drive force [N];
//! d length of the driven stretch [m].

mod common;

use std::f64::consts::PI;
use std::path::PathBuf;

use hbcontact::config::{load_pipeline, Pipeline};
use hbcontact::hbm::continuation::Corrector;
use hbcontact::pipeline::late::LateKind;
use hbcontact::pipeline::{self, RunOptions};
use hbcontact::sweep::{self, SweepRow, SweepSummary};
use hbcontact::Silent;

const STEEL_E: f64 = 210.0e9;
const STEEL_RHO: f64 = 7800.0;

/// Column indices of `SweepRow::values` (`sweep::outputs`; a frictional sweep adds three
/// columns after these).
const AMPLITUDE: usize = 0;
const PEAK_FORCE: usize = 2;
const MEAN_FORCE: usize = 3;
const CONTACT_FRACTION: usize = 4;

fn scene(name: &str, overrides: &[&str]) -> Pipeline {
    let path = common::root()
        .join("pipelines/scenes")
        .join(format!("{name}.yaml"));
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    load_pipeline(&path, &overrides).unwrap_or_else(|e| panic!("{e}"))
}

fn out(tag: &str) -> Option<PathBuf> {
    Some(common::temp_out(&format!("scenes-{tag}")))
}

/// The frequency [Hz] of the `nth` (1-based) mode whose effective mass along `axis` (0 = x,
/// 1 = y) is at least a tenth of the mass free to move that way: the modes a drive along
/// `axis` excites.
fn driven_mode(name: &str, axis: usize, nth: usize) -> f64 {
    let p = scene(name, &[]);
    let options = RunOptions {
        out: out(&format!("{name}-modes")),
        ..Default::default()
    };
    let m = pipeline::modes(&p, &options, 8, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let driven: Vec<f64> = m
        .summary
        .modes
        .iter()
        .filter(|m| [m.mass_fraction_x, m.mass_fraction_y][axis] > 0.1)
        .map(|m| m.frequency_hz)
        .collect();
    *driven
        .get(nth - 1)
        .expect("the driven mode among the lowest 8")
}

/// The probe's first-harmonic amplitude of a linear run at `hz` with `far` moving the stop
/// out of reach: the free resonance the stop limits.
fn free_amplitude(name: &str, far: &str, hz: f64) -> f64 {
    let f = format!("harmonic_balance.frequency={hz}");
    let p = scene(name, &[far, &f, "stability.check=false"]);
    let options = RunOptions {
        out: out(&format!("{name}-free")),
        write: hbcontact::pipeline::WriteLevel::Summary,
        ..Default::default()
    };
    let r = pipeline::run(&p, &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let contact = r.summary.contact.as_ref().expect("a contact scene");
    assert_eq!(contact.peak_contact_force, 0.0, "{far} keeps the stop away");
    common::first_probe_harmonic(&r.summary)
}

/// Sweep the scene as shipped and require that it reaches its end with exit 0.
fn sweep_to_the_end(name: &str) -> SweepSummary {
    sweep_with_to_the_end(name, &[])
}

/// `sweep_to_the_end` with `overrides`.
fn sweep_with_to_the_end(name: &str, overrides: &[&str]) -> SweepSummary {
    let p = scene(name, overrides);
    let options = RunOptions {
        out: out(name),
        ..Default::default()
    };
    let r = sweep::run(&p, &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let s = r.summary;
    let folds: Vec<f64> = s.folds.iter().map(|f| f.frequency_hz).collect();
    println!(
        "{name}: {} points, folds {folds:?}, {:.1} s",
        s.points,
        s.stage_seconds.total()
    );
    assert!(
        r.failure.is_none(),
        "{name}: {:?}",
        r.failure.map(|e| e.to_string())
    );
    assert!(
        s.stopped.is_none(),
        "{name}: {:?}",
        s.stopped.map(|x| x.reason)
    );
    let last = s.rows.last().expect("rows").frequency_hz;
    assert!(
        (last - s.to_hz).abs() < 1e-6 * s.to_hz,
        "{last} against {}",
        s.to_hz
    );
    s
}

fn peak(s: &SweepSummary) -> &SweepRow {
    s.rows
        .iter()
        .max_by(|a, b| a.values[AMPLITUDE].total_cmp(&b.values[AMPLITUDE]))
        .expect("rows")
}

/// Euler–Bernoulli bending frequency of a beam of depth h and length l, eigenvalue `lambda`.
fn beam_frequency(lambda: f64, h: f64, l: f64) -> f64 {
    lambda * lambda / (2.0 * PI) * h / (l * l) * (STEEL_E / (12.0 * STEEL_RHO)).sqrt()
}

fn bilinear(f1: f64, fc: f64) -> f64 {
    2.0 * f1 * fc / (f1 + fc)
}

/// The claims every impacting scene shares: the swept range is 0.7–1.5 f1, neither end
/// touches, the peak lies in (f1, `upper`) with an amplitude between the gap and the free
/// resonance, and a fold lies above f1 (the resonance bends over).
fn assert_stiffened_resonance(s: &SweepSummary, f1: f64, upper: f64, gap: f64, free: f64) {
    assert!(
        (s.from_hz / f1 - 0.7).abs() < 2e-3,
        "from {} for f1 {f1}",
        s.from_hz
    );
    assert!(
        (s.to_hz / f1 - 1.5).abs() < 2e-3,
        "to {} for f1 {f1}",
        s.to_hz
    );
    for end in [s.rows.first().unwrap(), s.rows.last().unwrap()] {
        assert_eq!(end.values[CONTACT_FRACTION], 0.0, "{} Hz", end.frequency_hz);
    }
    let top = peak(s);
    let (f, a) = (top.frequency_hz, top.values[AMPLITUDE]);
    println!("peak {f:.2} Hz = {:.4} f1 (bound {:.4} f1), amplitude {a:.3e} m (gap {gap:.1e}, free {free:.3e})", f / f1, upper / f1);
    assert!(
        f > f1 && f < upper,
        "peak at {f} Hz outside ({f1}, {upper})"
    );
    assert!(
        a > gap && a < free,
        "peak amplitude {a} not in ({gap}, {free})"
    );
    assert!(top.values[PEAK_FORCE] > 0.0);
    assert!(
        s.folds.iter().any(|x| x.frequency_hz > f1),
        "no fold above f1: {:?}",
        s.folds
    );
}

/// TEST GOAL: a steel cantilever (200 × 10 mm, 0.5% damping) whose tip swings onto a stop
/// 0.5 mm below it (about a quarter of its free resonant amplitude, 1.8 mm) bends its
/// resonance over to a fold above f1 (measured 232.1 Hz = 1.043 f1, H = 20), below the
/// bilinear bound 1.628 f1; linear triangles, 3 through the depth, put f1 6% above
/// Euler–Bernoulli (222.5 against 209.6 Hz).
#[test]
fn a_cantilever_on_a_one_sided_stop_bends_its_resonance_over_above_f1() {
    let name = "cantilever_stop";
    let f1 = driven_mode(name, 1, 1);
    let eb = beam_frequency(1.8751, 0.01, 0.2);
    assert!(f1 > eb && f1 < 1.08 * eb, "{f1} against {eb}");
    let free = free_amplitude(name, "geometry.parameters.gap=0.05", f1);
    let s = sweep_to_the_end(name);
    let fc = (3.9266f64 / 1.8751).powi(2) * f1;
    assert_stiffened_resonance(&s, f1, bilinear(f1, fc), 5e-4, free);
}

/// TEST GOAL: the cantilever on its stop in quadratic elements (2 through the depth): f1
/// within 0.5% of Euler–Bernoulli, and the same stiffened resonance as the linear mesh (the
/// default steps run back onto the curve at 216.72 Hz in a tangle of kinks; swept again with
/// a turn limit of 60° per step, it reaches the end).
#[test]
fn a_quadratic_cantilever_on_a_one_sided_stop_bends_its_resonance_over_above_f1() {
    let name = "cantilever_stop_p2";
    let f1 = driven_mode(name, 1, 1);
    let eb = beam_frequency(1.8751, 0.01, 0.2);
    assert!((f1 - eb).abs() < 5e-3 * eb, "{f1} against {eb}");
    let free = free_amplitude(name, "geometry.parameters.gap=0.05", f1);
    let s = sweep_to_the_end(name);
    let fc = (3.9266f64 / 1.8751).powi(2) * f1;
    assert_stiffened_resonance(&s, f1, bilinear(f1, fc), 5e-4, free);
}

/// The stuck frequency of the clamped–clamped beam pinned at mid-span: each half is a
/// clamped–pinned beam of length L/2.
fn clamped_pinned_at_midspan(f1: f64) -> f64 {
    4.0 * (3.9266f64 / 4.7300).powi(2) * f1
}

/// TEST GOAL: a clamped–clamped steel beam (400 × 10 mm, 1% damping) with stops 0.2 mm above
/// and below mid-span (0.46 mm free amplitude) hardens: its resonance folds above f1
/// (measured 382.0 Hz = 1.083 f1), below the frequency of the beam pinned at mid-span.
#[test]
fn a_clamped_beam_between_two_stops_hardens_and_folds_above_f1() {
    let name = "clamped_stops";
    let f1 = driven_mode(name, 1, 1);
    let eb = beam_frequency(4.7300, 0.01, 0.4);
    assert!(f1 > eb && f1 < 1.08 * eb, "{f1} against {eb}");
    let free = free_amplitude(name, "geometry.parameters.gap=0.05", f1);
    let s = sweep_to_the_end(name);
    assert_stiffened_resonance(&s, f1, clamped_pinned_at_midspan(f1), 2e-4, free);
}

/// TEST GOAL: the clamped beam between its stops in quadratic elements: f1 within 0.5% of
/// Euler–Bernoulli (332.2 against 333.1 Hz) and the same hardening fold (measured
/// 360.5 Hz = 1.085 f1, the law on the corners with mortar-weighted gaps).
#[test]
fn a_quadratic_clamped_beam_between_two_stops_hardens_and_folds_above_f1() {
    let name = "clamped_stops_p2";
    let f1 = driven_mode(name, 1, 1);
    let eb = beam_frequency(4.7300, 0.01, 0.4);
    assert!((f1 - eb).abs() < 5e-3 * eb, "{f1} against {eb}");
    let free = free_amplitude(name, "geometry.parameters.gap=0.05", f1);
    let s = sweep_to_the_end(name);
    assert_stiffened_resonance(&s, f1, clamped_pinned_at_midspan(f1), 2e-4, free);
}

/// TEST GOAL: a steel blade (100 × 10 × 2 mm, 0.5% damping in modes 1 and 2) whose tip
/// corners rub a concentric casing when it swings in its first bending mode: the resonance
/// folds above f1, and the rub holds the tip's swing below its free resonance.
#[test]
fn a_blade_rubbing_its_casing_in_its_first_mode_folds_above_f1() {
    let name = "blade_mode1";
    let f1 = driven_mode(name, 0, 1);
    let eb = beam_frequency(1.8751, 0.01, 0.1);
    assert!(f1 > eb && f1 < 1.05 * eb, "{f1} against {eb}");
    let free = free_amplitude(name, "geometry.parameters.clearance=0.01", f1);
    let s = sweep_to_the_end(name);
    // The swing the rub allows is larger than the corner clearance; no stuck state bounds it
    // (the corner slides along the casing), so the bound is the second bending mode.
    let f2 = driven_mode(name, 0, 2);
    assert_stiffened_resonance(&s, f1, f2, 0.0, free);
}

/// TEST GOAL: the same blade driven around its second bending mode (0.7–1.5 f2) with a load
/// 20 times the first scene's: the rub stiffens the second mode's resonance too.
#[test]
fn a_blade_rubbing_its_casing_in_its_second_mode_folds_above_f2() {
    let name = "blade_mode2";
    let f2 = driven_mode(name, 0, 2);
    let eb = beam_frequency(1.8751, 0.01, 0.1) * (4.6941f64 / 1.8751).powi(2);
    // Shear and rotary inertia lower the second mode of a 10:1 blade below Euler–Bernoulli.
    assert!(f2 < eb && f2 > 0.95 * eb, "{f2} against {eb}");
    let free = free_amplitude(name, "geometry.parameters.clearance=0.01", f2);
    let s = sweep_to_the_end(name);
    assert_stiffened_resonance(&s, f2, 1.5 * f2, 0.0, free);
}

/// TEST GOAL: the second-mode blade's default steps, at its recommended H = 10, cross a kink
/// of the sampled law onto a sheet of solutions that ends at 5381.28 Hz; the sweep says so and
/// sweeps again from its start with a turn limit of 60° per step, which reaches the end with
/// folds within 1.5 Hz of those H = 20 finds without it (5379.6 and 5229.2 Hz). Half the
/// default gap change per step (0.05) reaches the end at the first try; a sweep that sets its
/// own turn limit is not swept again, and stopped among unstable states it is swept from the
/// other end instead, to the start, with the same folds.
#[test]
fn the_second_mode_blade_stopped_at_a_kink_is_swept_again_with_a_turn_limit_to_its_end() {
    let name = "blade_mode2";
    let s = sweep_to_the_end(name);
    let again = s.swept_again.as_ref().expect("swept again");
    assert!(again.kept && again.max_turn == 60.0, "{again:?}");
    assert!((again.first_stop_hz - 5381.28).abs() < 0.5, "{again:?}");
    assert!(again.first_reason.contains("no next point"), "{again:?}");
    let folds: Vec<f64> = s.folds.iter().map(|f| f.frequency_hz).collect();
    for h20 in [5379.6, 5229.2] {
        assert!(
            folds.iter().any(|f| (f - h20).abs() < 1.5),
            "{folds:?} against {h20} Hz"
        );
    }
    let halved = sweep_with_to_the_end(name, &["sweep.max_change=0.05"]);
    assert!(halved.swept_again.is_none());
    let limited = sweep::run(
        &scene(name, &["sweep.max_turn=170"]),
        &RunOptions {
            out: out("blade_mode2-limited"),
            ..Default::default()
        },
        &Silent,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(limited.summary.swept_again.is_none());
    let failure = limited.failure.map(|e| e.to_string());
    assert!(failure.is_none(), "{failure:?}");
    let stop = limited.summary.stopped.expect("the limited curve stops");
    assert!(stop.reason.contains("no next point"), "{}", stop.reason);
    assert_eq!(stop.class, "unstable_stretch");
    // Its stop lies among unstable states, so it is swept from the other end, to the start.
    let other = limited
        .summary
        .from_the_end
        .expect("swept from the other end");
    assert!(other.stopped.is_none(), "{:?}", other.stopped);
    for h20 in [5379.6, 5229.2] {
        let near = |f: &sweep::FoldReport| (f.frequency_hz - h20).abs() < 1.5;
        assert!(
            other.folds.iter().any(near),
            "{:?} against {h20} Hz",
            other.folds
        );
    }
}

/// TEST GOAL: a curve that runs back along a sliver of the sampled law (a thin sheet of its
/// solutions that leaves the curve and turns back along it) is led round it from where the
/// sliver left (`hbm::continuation::sliver`): the first-mode blade swept from 602 Hz instead
/// of 602.9 Hz, and swept down from 1291.9 Hz, each go round one and reach their end (they
/// stopped at 916.6 Hz without it), with the upper fold (the highest) and the lower one
/// within 0.1 Hz of the shipped sweep's, 916.81 and 871.54 Hz.
#[test]
fn a_curve_running_back_along_a_sliver_of_the_sampled_law_is_led_round_it_to_its_end() {
    let down = [
        "sweep.from=1291.9",
        "sweep.to=602.9",
        "harmonic_balance.frequency=1291.9",
    ];
    for (tag, sets) in [("up", &["sweep.from=602"][..]), ("down", &down[..])] {
        let options = RunOptions {
            out: out(&format!("blade_mode1-sliver-{tag}")),
            ..Default::default()
        };
        let r = sweep::run(&scene("blade_mode1", sets), &options, &Silent);
        let r = r.unwrap_or_else(|e| panic!("{e}"));
        let failure = r.failure.map(|e| e.to_string());
        assert!(
            failure.is_none() && r.summary.stopped.is_none(),
            "{tag}: {failure:?}"
        );
        assert!(r.summary.slivers >= 1, "{tag}: no sliver gone round");
        let folds = folds_of(&r.summary);
        let upper = folds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let lower = folds.iter().copied().fold(f64::INFINITY, f64::min);
        println!("{tag}: {} points, folds {folds:?}", r.summary.points);
        assert!(
            (upper - 916.81).abs() < 0.1 && (lower - 871.54).abs() < 0.1,
            "{folds:?}"
        );
    }
}

/// TEST GOAL: a curve that stops twice elsewhere than among unstable states (the default
/// steps, then the 60° turn limit) is swept a third time from its start with the contact
/// law's samples doubled: the first-mode blade from 610 Hz meets a dead end of its upper fold
/// at 80 samples both times, and at 160 reaches the end, its upper and lower folds within
/// 0.1 Hz of the shipped sweep's (916.81, 871.54 Hz).
#[test]
fn a_curve_stopped_twice_at_a_dead_end_of_the_sampled_law_is_swept_with_twice_the_samples_to_its_end(
) {
    let options = RunOptions {
        out: out("blade_mode1-finer"),
        ..Default::default()
    };
    let p = scene("blade_mode1", &["sweep.from=610"]);
    let r = sweep::run(&p, &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let failure = r.failure.map(|e| e.to_string());
    assert!(
        failure.is_none() && r.summary.stopped.is_none(),
        "{failure:?}"
    );
    let again = r.summary.swept_again.as_ref().expect("swept again");
    assert!(!again.kept && again.finer_kept, "{again:?}");
    assert_eq!(again.finer_samples, Some(160));
    let folds = folds_of(&r.summary);
    let upper = folds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lower = folds.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        (upper - 916.81).abs() < 0.1 && (lower - 871.54).abs() < 0.1,
        "{folds:?}"
    );
}

/// f = c/4L of a plane-stress steel bar of length `l`.
fn bar_frequency(l: f64) -> f64 {
    (STEEL_E / STEEL_RHO).sqrt() / (4.0 * l)
}

/// TEST GOAL: the classic vibro-impact bar: a clamped steel rod (500 × 20 mm, 1% damping)
/// whose free end strikes a rigid wall 20 µm away (about 40% of its free end amplitude)
/// under axial drive: f1 = c/4L within 0.5%, and the resonance folds above f1 below the
/// bilinear bound 4/3 f1 of a rod held at both ends half the period (measured 2722.6 Hz =
/// 1.049 f1).
#[test]
fn the_vibro_impact_bar_folds_between_f1_and_the_bilinear_four_thirds() {
    assert_vibro_impact_bar("vibro_impact_bar");
}

/// The vibro-impact bar `name`: f1 = c/4L within 0.5%, swept end to end, its resonance
/// stiffened between f1 and the bilinear bound, its amplitude between the gap and the free one.
fn assert_vibro_impact_bar(name: &str) {
    let f1 = driven_mode(name, 0, 1);
    let c4l = bar_frequency(0.5);
    assert!((f1 - c4l).abs() < 5e-3 * c4l, "{f1} against {c4l}");
    let free = free_amplitude(name, "geometry.parameters.gap=0.01", f1);
    let s = sweep_to_the_end(name);
    // The probe sits at mid-length, where the first axial mode moves sin(π/4) of the tip.
    let gap_at_probe = 2e-5 * (PI / 4.0).sin();
    assert_stiffened_resonance(&s, f1, bilinear(f1, 2.0 * f1), gap_at_probe, free);
}

/// TEST GOAL: the vibro-impact bar in quadratic elements (one through the depth): the same
/// fold (measured 2719.4 Hz, the law on the corners with mortar-weighted gaps, against
/// 2722.6 Hz on linear triangles).
#[test]
fn a_quadratic_vibro_impact_bar_folds_between_f1_and_the_bilinear_four_thirds() {
    assert_vibro_impact_bar("vibro_impact_bar_p2");
}

/// TEST GOAL: an aluminium rod (300 × 20 mm) pressed onto a rigid seat by a static axial
/// force of 240 N, driven by 0.95 of it: at 0.7 f1 the contact is closed all period with the
/// mean force of the static bar, F_s (L − d/2)/L = 228 N; toward resonance it opens part of
/// the period, and never all of it (a contact open all period could not carry the static
/// force); the resonance of the partly open rod lies between f1 and 2 f1 (held at both ends).
#[test]
fn a_preloaded_rod_opens_part_of_the_period_only_near_its_resonance() {
    let name = "preloaded_rod";
    let f1 = driven_mode(name, 0, 1);
    let c4l = (70.0e9f64 / 2700.0).sqrt() / (4.0 * 0.3);
    assert!((f1 - c4l).abs() < 5e-3 * c4l, "{f1} against {c4l}");
    let s = sweep_to_the_end(name);
    let first = &s.rows[0];
    let static_share = 2.0e5 * (2.0 * 0.03 * 0.02) * (0.3 - 0.015) / 0.3;
    let mean = first.values[MEAN_FORCE];
    assert!(
        (mean - static_share).abs() < 0.02 * static_share,
        "{mean} against {static_share}"
    );
    assert!(first.values[CONTACT_FRACTION] > 0.99, "{:?}", first.values);
    for r in &s.rows {
        assert!(
            r.values[PEAK_FORCE] > 0.0,
            "open all period at {} Hz",
            r.frequency_hz
        );
        assert!(
            r.values[MEAN_FORCE] > 0.98 * static_share,
            "{} Hz",
            r.frequency_hz
        );
    }
    let partly_open = s
        .rows
        .iter()
        .filter(|r| r.values[CONTACT_FRACTION] > 0.05 && r.values[CONTACT_FRACTION] < 0.95)
        .count();
    assert!(partly_open > 0);
    let top = peak(&s);
    assert!(
        top.frequency_hz > f1 && top.frequency_hz < 2.0 * f1,
        "{}",
        top.frequency_hz
    );
}

/// TEST GOAL: the reference strip (1 m × 0.1 m, plane strain) at 0.5% damping with the wall
/// 0.1 mm from its end, swept 0.7–1.5 f1 at the recommended H = 40 (f1 = c/4L): its curve
/// loses stability where it grazes the wall and stops among unstable states; swept from the
/// other end, the open branch comes down to a fold where it touches the wall, stable, and
/// stops among unstable states too. The sweep ends with exit 0, naming the stretch neither
/// curve traced, which holds f1 (measured 1357.95–1390.86 Hz); a march there, which knows
/// nothing of harmonic balance, is not T-periodic. The curve is written from both ends, the
/// second with a resume command for its own folder.
#[test]
fn the_lightly_damped_strip_is_swept_from_both_ends_around_a_stretch_it_does_not_follow() {
    let name = "strip_light";
    let f1 = driven_mode(name, 0, 1);
    let c4l = (STEEL_E / (STEEL_RHO * (1.0 - 0.09))).sqrt() / 4.0;
    assert!((f1 - c4l).abs() < 5e-3 * c4l, "{f1} against {c4l}");
    let options = RunOptions {
        out: out(name),
        ..Default::default()
    };
    let r = sweep::run(&scene(name, &[]), &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let failure = r.failure.map(|e| e.to_string());
    assert!(failure.is_none(), "{failure:?}");
    let s = r.summary;
    let stop = s.stopped.as_ref().expect("the curve from the start stops");
    assert_eq!(stop.class, "unstable_stretch", "{}", stop.reason);
    let other = s.from_the_end.as_ref().expect("swept from the other end");
    assert!(
        other.settles && other.from_hz == s.to_hz,
        "{:?}",
        s.warnings
    );
    let [lo, hi] = other.untraced_hz.expect("a stretch neither traced");
    println!(
        "untraced {lo:.2}–{hi:.2} Hz = {:.4}–{:.4} f1; {} + {} points; {:.1} s",
        lo / f1,
        hi / f1,
        s.points,
        other.points,
        s.stage_seconds.total()
    );
    assert!(
        0.97 * f1 < lo && lo < f1 && f1 < hi && hi < 1.05 * f1,
        "{lo}–{hi} Hz, f1 {f1}"
    );
    // The open branch from the end comes down, stable, to where it touches the wall.
    let last_stable = (other.rows.iter().rev()).find(|r| r.stable == Some(true));
    let last_stable = last_stable.expect("stable states from the end");
    assert!(
        (last_stable.frequency_hz - hi).abs() < 1e-9 * hi,
        "{}",
        last_stable.frequency_hz
    );
    assert!(
        last_stable.values[CONTACT_FRACTION] > 0.0,
        "it touches there"
    );
    assert!(other
        .folds
        .iter()
        .any(|f| (f.frequency_hz - hi).abs() < 1e-9 * hi));
    for end in [s.rows.first(), other.rows.first()] {
        assert_eq!(
            end.map(|r| r.values[CONTACT_FRACTION]),
            Some(0.0),
            "open at the ends"
        );
    }
    // Its resume command continues it where it is written, not where it was staged.
    let resume = format!("--out {} --resume", r.dir.join("from_the_end").display());
    let stop = other.stopped.as_ref().map_or("", |s| s.reason.as_str());
    assert!(stop.contains(&resume), "{stop}");
    let written = std::fs::read_to_string(r.dir.join("from_the_end/sweep.csv"));
    let written = written.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(written.lines().count(), other.points + 1);
    let mid = 0.5 * (lo + hi);
    let march = format!("--set harmonic_balance.frequency={mid:.4}`");
    assert!(
        s.warnings.iter().any(|w| w.contains(&march)),
        "{:?}",
        s.warnings
    );
    let at = format!("harmonic_balance.frequency={mid}");
    let late = common::marched_late_response(&scene(name, &[&at]), "strip_light-between");
    assert_ne!(late.kind, LateKind::Periodic, "{}", late.description);
}

/// TEST GOAL: a curve that stops among unstable states says so: the 0.5%-damped strip at
/// H = 20 runs back onto its curve at 1344.87 Hz, swept again it stops too, and its stop
/// names the stretch (every point judged since the last stable one, before 1336 Hz, is
/// unstable) and the march that shows what the structure does; that march, which knows
/// nothing of harmonic balance, at the stop frequency is not T-periodic.
#[test]
fn a_sweep_that_stops_among_unstable_states_names_them_and_a_march_there_is_not_periodic() {
    let p = scene("strip_light", &["harmonic_balance.harmonics=20"]);
    let options = RunOptions {
        out: out("strip_light-h20"),
        ..Default::default()
    };
    let r = sweep::run(&p, &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let stop = r.summary.stopped.expect("the H = 20 curve stops");
    println!("{}", stop.reason);
    let tail = stop
        .reason
        .split("the curve stopped among unstable states: all ")
        .nth(1);
    let tail = tail.unwrap_or_else(|| panic!("no unstable stretch named: {}", stop.reason));
    let since: f64 = (tail.split("last stable point, at ").nth(1))
        .and_then(|t| t.split(' ').next())
        .and_then(|f| f.parse().ok())
        .unwrap_or_else(|| panic!("no last stable point: {tail}"));
    assert!(since < 1336.0 && since > 1300.0, "{since}");
    let march = format!(
        "`hbcontact transient {} --set harmonic_balance.harmonics=20 --set \
         harmonic_balance.frequency={:.4}`",
        p.source.display(),
        stop.frequency_hz
    );
    assert!(stop.reason.contains(&march), "{}", stop.reason);
    let at = format!("harmonic_balance.frequency={}", stop.frequency_hz);
    let late = common::marched_late_response(&scene("strip_light", &[&at]), "strip_light-march");
    assert_ne!(late.kind, LateKind::Periodic, "{}", late.description);
}

/// TEST GOAL: a curve swept again with the turn limit saves the limit in its state: the
/// second-mode blade, stopped by `max_points` on its second sweep, resumes with the limit to
/// the end, and its rows are those of the uninterrupted sweep bit for bit.
#[test]
fn a_curve_swept_again_resumes_with_its_turn_limit_to_the_uninterrupted_one() {
    let name = "blade_mode2";
    let whole = sweep_to_the_end(name);
    let options = RunOptions {
        out: out("blade_mode2-resumed"),
        ..Default::default()
    };
    let cut = sweep::run(&scene(name, &["sweep.max_points=60"]), &options, &Silent)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(cut.summary.swept_again.as_ref().is_some_and(|a| a.kept));
    let state = cut.summary.resume.as_ref().expect("a resume state");
    assert_eq!(state.max_turn, Some(60.0));
    assert_eq!(cut.summary.points, 60);
    let resumed =
        sweep::resume(&scene(name, &[]), &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    assert!(resumed.failure.is_none(), "{:?}", resumed.failure);
    let rows = |s: &SweepSummary| -> Vec<(f64, f64)> {
        (s.rows.iter())
            .map(|r| (r.frequency_hz, r.values[AMPLITUDE]))
            .collect()
    };
    assert_eq!(rows(&resumed.summary), rows(&whole));
}

/// TEST GOAL: where the sweep swept again stops too (the blade with steps that cannot be
/// halved, `min_step` = `step`), the first curve is kept and its stop names both; neither
/// staging folder is left beside the output.
#[test]
fn a_curve_that_stops_when_swept_again_too_keeps_the_first_and_names_both_stops() {
    let name = "blade_mode2";
    let folder = out("blade_mode2-unhalved").expect("a folder");
    let options = RunOptions {
        out: Some(folder.clone()),
        ..Default::default()
    };
    let r = sweep::run(&scene(name, &["sweep.min_step=0.01"]), &options, &Silent)
        .unwrap_or_else(|e| panic!("{e}"));
    let again = r.summary.swept_again.as_ref().expect("swept again");
    assert!(!again.kept, "{again:?}");
    assert_eq!(again.first_points, r.summary.points);
    let why = r.failure.map(|e| e.to_string()).unwrap_or_default();
    assert!(why.contains("no next point"), "{why}");
    assert!(
        why.contains("swept again from its start with sweep.max_turn = 60°, it stopped too"),
        "{why}"
    );
    assert!(folder.join("sweep.json").is_file());
    let name = folder
        .file_name()
        .expect("a name")
        .to_string_lossy()
        .into_owned();
    let parent = folder.parent().expect("a parent");
    let left: Vec<String> = (std::fs::read_dir(parent).expect("the parent").flatten())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&format!("{name}.partial-")))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// TEST GOAL: a curve that turns round and leaves the range through its start does not claim
/// the end: the cantilever swept down from 229 Hz, inside its folded region, starts on the
/// open branch, turns at the lower fold (226.32 Hz) onto the middle branch and climbs back
/// past 229 Hz; the curve stops there saying so, without the resume hint a resume could not
/// use. Its stop lies among unstable states (the middle branch), so the sweep goes the other
/// way itself: from 200 Hz the curve reaches 229 Hz, and the sweep ends with exit 0.
#[test]
fn a_curve_that_runs_back_out_through_its_start_stops_saying_so_and_is_swept_the_other_way() {
    let p = scene(
        "cantilever_stop",
        &[
            "sweep.from=229",
            "sweep.to=200",
            "harmonic_balance.frequency=229",
        ],
    );
    let options = RunOptions {
        out: out("cantilever_stop-back-out"),
        ..Default::default()
    };
    let r = sweep::run(&p, &options, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let failure = r.failure.map(|e| e.to_string());
    assert!(failure.is_none(), "{failure:?}");
    let folds = folds_of(&r.summary);
    let other = r.summary.from_the_end.expect("swept the other way");
    assert!(
        other.settles && other.stopped.is_none(),
        "{:?}",
        other.stopped
    );
    let end = other.rows.last().map_or(0.0, |r| r.frequency_hz);
    assert!(
        other.from_hz == 200.0 && (end - 229.0).abs() < 1e-9,
        "{end}"
    );
    let stopped = r.summary.stopped.expect("a stop in sweep.json");
    let failure = &stopped.reason;
    assert_eq!(stopped.class, "unstable_stretch");
    assert!(
        stopped.reason.contains("back through its start"),
        "{failure}"
    );
    assert!(
        stopped.reason.contains("sweep.from = 200.0000"),
        "{failure}"
    );
    assert!(!stopped.reason.contains("--resume"), "{failure}");
    assert!(stopped.frequency_hz > 229.0, "{}", stopped.frequency_hz);
    assert!(folds.iter().any(|f| (f - 226.32).abs() < 0.1), "{folds:?}");
}

/// The folds [Hz] of `s`, in curve order.
fn folds_of(s: &SweepSummary) -> Vec<f64> {
    s.folds.iter().map(|f| f.frequency_hz).collect()
}

/// TEST GOAL: swept down, a hardening resonance reaches the lower fold along the open branch,
/// where the linear response reaches the stop and the open branch ends: the contacting branch
/// leaves that corner back in ω (corrector `open_corner`), and the curve finds the folds the
/// upward sweep finds, each within 0.1 Hz, on the cantilever and on the clamped beam between
/// its stops.
#[test]
fn a_sweep_down_leaves_the_open_branch_at_the_lower_fold_and_finds_the_upward_folds() {
    for name in ["cantilever_stop", "clamped_stops"] {
        let up = sweep_to_the_end(name);
        let (from, to) = (
            format!("sweep.from={}", up.to_hz),
            format!("sweep.to={}", up.from_hz),
        );
        let start = format!("harmonic_balance.frequency={}", up.to_hz);
        let down = sweep_with_to_the_end(name, &[&from, &to, &start]);
        assert!(down.swept_again.is_none(), "{name}");
        let corner = (down.rows.iter()).position(|r| r.corrector == Corrector::OpenCorner);
        assert!(corner.is_some(), "{name}: no open_corner row");
        let (u, d) = (folds_of(&up), folds_of(&down));
        assert_eq!(u.len(), d.len(), "{name}: {u:?} against {d:?}");
        for f in &d {
            assert!(
                u.iter().any(|g| (f - g).abs() < 0.1),
                "{name}: {f} Hz against {u:?}"
            );
        }
    }
}
