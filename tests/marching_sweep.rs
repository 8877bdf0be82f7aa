//! The folded frequency-response curve against brute-force sweeps by time marching: what a
//! structure swept slowly up and down in frequency does, marched period by period from the
//! state the last frequency ended in (`transient.start: previous`), with nothing of the
//! harmonic-balance code in the loop (docs/method.md, sections 12, 14 and 15).
//!
//! The scene: the strip of pipelines/strip_sweep.yaml (5% damping, gap 10 µm) on the coarse
//! mesh lc = 0.025, from 1550 to 1720 Hz. Harmonic balance (H = 40) runs on the marching's
//! own discrete model (diagonal mass), so the two differ only in the time discretization.

mod common;

use std::path::{Path, PathBuf};

use hbcontact::config::Pipeline;
use hbcontact::hbm::continuation::{sweep, PointInfo};
use hbcontact::hbm::{solve_from, ContactSolution, Solution};
use hbcontact::pipeline::end_state::{self, Marched};
use hbcontact::pipeline::stability::marching_start;
use hbcontact::pipeline::{self, Model, Purpose, RunOptions, Stages};
use hbcontact::Silent;

const STEP_HZ: f64 = 10.0;
const MIDDLE_HZ: f64 = 1640.0;
/// The marching's time step, as a fraction of the stable one: the impacts' timing errs at
/// first order in it, 1.78% in amplitude at 0.8 (the default) and 0.27% at this.
const COURANT: f64 = 0.2;

fn scene(extra: &[&str]) -> Pipeline {
    let mut all = vec![
        "geometry.parameters.lc=0.025",
        "harmonic_balance.harmonics=40",
        "transient.periodic_tolerance=1e-6",
        "sweep.from=1550",
        "sweep.to=1720",
    ];
    all.extend_from_slice(extra);
    common::scene("strip_sweep", &all)
}

/// The marching model and the mesh file it was built from.
fn marching_model(p: &Pipeline, out: &Path) -> (Model, PathBuf) {
    let mut stages = Stages::new(p, &Silent);
    let (mesh, info) =
        pipeline::stages::mesh(p, out, &mut stages).unwrap_or_else(|e| panic!("{e}"));
    let model = pipeline::build(p, mesh, Purpose::Transient).unwrap_or_else(|e| panic!("{e}"));
    (model, info.msh)
}

/// The probe's first-harmonic amplitude of a harmonic-balance state.
fn amplitude(model: &Model, s: &Solution) -> f64 {
    common::hb_probe_amplitudes(model, s, 40)["probe"].first_harmonic_x
}

/// The continuation on the marching model: every point's (Hz, amplitude), the folds' point
/// indices and Hz, and the states within 6 Hz of `MIDDLE_HZ` by index.
struct Curve {
    points: Vec<(f64, f64)>,
    states: Vec<ContactSolution>,
    folds: Vec<(usize, f64)>,
    near_middle: Vec<(usize, f64, Solution)>,
}

fn continuation(p: &Pipeline, model: &Model) -> Curve {
    let spec = p.sweep.as_ref().expect("a sweep block");
    let settings = hbcontact::sweep::settings(spec, None);
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut system = model.system.clone();
    let contact = model.contact.as_ref().map(|c| &c.operator);
    let (mut points, mut states, mut near_middle) = (Vec::new(), Vec::new(), Vec::new());
    let mut on_point = |info: &PointInfo, s: &Solution| {
        let hz = info.omega / two_pi;
        points.push((hz, amplitude(model, s)));
        states.push(s.contact.clone().expect("a contact state"));
        if (hz - MIDDLE_HZ).abs() < 6.0 {
            near_middle.push((info.index, hz, s.clone()));
        }
        Ok(())
    };
    let hb = pipeline::hb_settings(p);
    let outcome = sweep(&mut system, contact, &hb, &settings, &Silent, &mut on_point)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(outcome.stopped.is_none(), "{:?}", outcome.stopped);
    let folds = outcome
        .folds
        .iter()
        .map(|f| (f.after, f.omega / two_pi))
        .collect();
    Curve {
        points,
        states,
        folds,
        near_middle,
    }
}

/// March at `hz` into `dir`, from rest or from the end state already there.
fn march(hz: f64, dir: &Path, previous: bool, courant: f64) -> (f64, bool) {
    let frequency = format!("harmonic_balance.frequency={hz}");
    let courant = format!("transient.courant={courant}");
    let start = format!(
        "transient.start={}",
        if previous { "previous" } else { "rest" }
    );
    let p = scene(&[&frequency, &start, &courant]);
    let options = RunOptions {
        out: Some(dir.to_path_buf()),
        write: hbcontact::pipeline::WriteLevel::Summary,
        ..Default::default()
    };
    let s = pipeline::run_transient(&p, &options, &Silent)
        .unwrap_or_else(|e| panic!("{hz} Hz: {e}"))
        .summary;
    let converged = s.transient.as_ref().is_some_and(|t| t.converged);
    (s.probes["probe"].first_harmonic_x, converged)
}

/// A brute-force sweep over `hz`: the first from rest, each next from the last end state.
fn brute_force(hz: &[f64], tag: &str, courant: f64) -> Vec<(f64, f64)> {
    let dir = common::temp_out(tag);
    hz.iter()
        .enumerate()
        .map(|(i, &f)| {
            let (a, converged) = march(f, &dir, i > 0, courant);
            assert!(converged, "{f} Hz did not become periodic");
            (f, a)
        })
        .collect()
}

/// The harmonic-balance amplitude at exactly `hz` on the branch of the continuation points
/// `range`: Newton at `hz` from the state of the branch's point nearest in frequency.
fn on_branch(
    p: &Pipeline,
    model: &Model,
    curve: &Curve,
    range: std::ops::RangeInclusive<usize>,
    hz: f64,
) -> f64 {
    let nearest = range
        .min_by(|&i, &j| {
            (curve.points[i].0 - hz)
                .abs()
                .total_cmp(&(curve.points[j].0 - hz).abs())
        })
        .expect("a branch");
    let mut system = model.system.clone();
    system.omega = 2.0 * std::f64::consts::PI * hz;
    let op = &model.contact.as_ref().expect("contact").operator;
    let s = solve_from(
        &system,
        op,
        &pipeline::hb_settings(p),
        &curve.states[nearest],
        &Silent,
    )
    .unwrap_or_else(|e| panic!("{hz} Hz: {e}"));
    amplitude(model, &s)
}

/// Where a brute-force sweep jumps: the pair of successive frequencies whose amplitudes
/// differ by more than 30%.
fn jump(sweep: &[(f64, f64)]) -> (f64, f64) {
    let w = sweep
        .windows(2)
        .find(|w| (w[1].1 - w[0].1).abs() > 0.3 * w[0].1.min(w[1].1))
        .expect("the brute-force sweep jumps");
    (w[0].0, w[1].0)
}

/// TEST GOAL: the fold test. Continuation passes both folds of the stiffened
/// resonance (the upper, smooth one where it turns back, and the lower one where the middle
/// branch grazes onto the non-contacting branch); brute-force sweeps by time marching, each
/// frequency started from the last end state, jump within one frequency step of them (the
/// up-sweep falls off the upper branch between the two frequencies that bracket the upper
/// fold, the down-sweep climbs onto it between those bracketing the grazing fold); and their
/// amplitudes lie on the stable branches, against harmonic balance (H = 40) solved at the same
/// frequency on the same branch: within 0.5% on the contacting branch (measured 0.27%; the
/// issue asks 1%) and 2e-5 on the open branch (measured 8.9e-6), with the marching at Courant
/// 0.2. At the default 0.8 the up-sweep differs by 1.78%, more than 3× as much (the impacts'
/// timing errs at first order in the time step: 0.55% at 0.4), so the difference is the
/// marching's. Then stability: marching started from the
/// harmonic-balance states at 1640 Hz, perturbed by ±2%, stays on the upper and lower branch
/// (ends within 1.6e-6 of the brute-force amplitude; measured up to 5.0e-7) and leaves the middle
/// branch for one of the stable ones (+2% to the upper, −2% to the lower). Reference: time marching (src/transient, independent of the
/// harmonic-balance code) on the same discrete model.
#[test]
fn brute_force_marching_sweeps_jump_at_the_folds_and_follow_the_stable_branches() {
    let p = scene(&[]);
    let (model, msh) = marching_model(&p, &common::temp_out("marching-sweep-hb"));
    let curve = continuation(&p, &model);
    let upper = *curve
        .folds
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("folds");
    let graze = *curve.folds.last().expect("folds");
    println!("folds {:?}", curve.folds);
    assert!(
        graze.0 > upper.0 && graze.1 < upper.1 - 50.0,
        "{:?}",
        curve.folds
    );

    let up_hz: Vec<f64> = (0..=15).map(|i| 1550.0 + STEP_HZ * i as f64).collect();
    let down_hz: Vec<f64> = (0..=14).map(|i| 1700.0 - STEP_HZ * i as f64).collect();
    let up = brute_force(&up_hz, "marching-sweep-up", COURANT);
    let down = brute_force(&down_hz, "marching-sweep-down", COURANT);
    println!("up {up:?}\ndown {down:?}");
    let (a, b) = jump(&up);
    assert!(
        a <= upper.1 && upper.1 <= b,
        "up-sweep jumps {a}–{b}, fold {}",
        upper.1
    );
    let (c, d) = jump(&down);
    assert!(
        d <= graze.1 && graze.1 <= c,
        "down-sweep jumps {c}–{d}, fold {}",
        graze.1
    );

    // Amplitudes against harmonic balance at the same frequency on the same branch; the
    // up-sweep again at the default step, to show which side the difference comes from.
    let (contacting, open) = (0..=upper.0, graze.0 + 1..=curve.points.len() - 1);
    let hb_contacting: Vec<(f64, f64)> = up_hz
        .iter()
        .filter(|&&f| f <= a)
        .map(|&f| (f, on_branch(&p, &model, &curve, contacting.clone(), f)))
        .collect();
    let default_step = brute_force(&up_hz[..hb_contacting.len()], "marching-sweep-up-0.8", 0.8);
    let worst_against = |marched: &[(f64, f64)]| {
        let hb = |f: f64| hb_contacting.iter().find(|x| x.0 == f).expect("solved").1;
        marched
            .iter()
            .filter(|(f, _)| *f <= a)
            .map(|&(f, m)| (m - hb(f)).abs() / m)
            .fold(0.0, f64::max)
    };
    let stable: Vec<(f64, f64)> = up
        .iter()
        .chain(down.iter().filter(|(f, _)| *f <= d))
        .copied()
        .collect();
    let (worst, worst_default) = (worst_against(&stable), worst_against(&default_step));
    let worst_open = down
        .iter()
        .filter(|(f, _)| *f >= c)
        .map(|&(f, m)| (m - on_branch(&p, &model, &curve, open.clone(), f)).abs() / m)
        .fold(0.0, f64::max);
    println!("harmonic balance on the contacting branch {hb_contacting:?}");
    println!(
        "contacting branch: worst {worst:.2e} (at Courant 0.8: {worst_default:.2e}); open branch: worst {worst_open:.2e}"
    );
    assert!(worst < 5e-3 && worst_open < 2e-5, "{worst} {worst_open}");
    assert!(worst_default > 3.0 * worst, "{worst_default} {worst}");

    // Stability: from each branch's state near 1640 Hz, perturbed.
    let at = |f: f64, sweep: &[(f64, f64)]| sweep.iter().find(|x| x.0 == f).expect("swept").1;
    let (on_upper, on_lower) = (at(MIDDLE_HZ, &up), at(MIDDLE_HZ, &down));
    let branch_of = |index: usize| match index {
        i if i <= upper.0 => 0,
        i if i <= graze.0 => 1,
        _ => 2,
    };
    for branch in 0..3 {
        let (_, hz, state) = curve
            .near_middle
            .iter()
            .filter(|(i, _, _)| branch_of(*i) == branch)
            .min_by(|x, y| (x.1 - MIDDLE_HZ).abs().total_cmp(&(y.1 - MIDDLE_HZ).abs()))
            .expect("a state near 1640 Hz on each branch");
        let start = amplitude(&model, state);
        for perturbation in [0.02, -0.02] {
            let dir = common::temp_out(&format!("marching-sweep-start-{branch}-{perturbation}"));
            std::fs::create_dir_all(&dir).unwrap();
            let initial = marching_start(state, &model.system.dofs, perturbation);
            end_state::save(&dir, *hz, &msh, &initial, Marched::default())
                .unwrap_or_else(|e| panic!("{e}"));
            let (end, converged) = march(MIDDLE_HZ, &dir, true, COURANT);
            let (e_up, e_low) = (
                (end - on_upper).abs() / on_upper,
                (end - on_lower).abs() / on_lower,
            );
            println!(
                "branch {branch} ({hz:.2} Hz, HB {start:.4e}) {perturbation:+}: ends {end:.4e} \
                 ({e_up:.1e} from the upper, {e_low:.1e} from the lower)"
            );
            assert!(converged);
            match branch {
                0 => assert!(e_up < 1.6e-6, "{e_up}"),
                2 => assert!(e_low < 1.6e-6, "{e_low}"),
                _ => {
                    assert!(e_up.min(e_low) < 1.6e-6, "{e_up} {e_low}");
                    assert!((end - start).abs() > 0.1 * start, "{end} {start}");
                }
            }
        }
    }
}
