//! The speed goals of issue 8 against what this build measures, in one run:
//! - the reference strip at H = 20 and 40: solve time against the numpy prototype's 0.42 s and
//!   3.7 s (goal ≥ 10× faster) and the Newton's share of the run (goal < 30%);
//! - Newton iterations of the 0.5%-damped strip against the 5%-damped one, H = 5…80 (goal
//!   within 3×);
//! - the half-disc refined at the contact: the reduction G_k = B Z_k⁻¹ Bᵀ against the
//!   factorizations (goal ≤), by the Schur complement and by the blocked solve;
//! - time per factorization against its flop count (the floor);
//! - the product G v of a GMRES iteration, as the Newton does it against a dot product per row;
//! - a pressed contact patch (the half-disc) at H = 10…80, where the harmonic-block
//!   preconditioner serves the steps the node blocks stall on;
//! - the cost of Coulomb friction against the frictionless solve of the same scene (the
//!   friction block and the friction damper, H = 20 and 40), and of a frictional sweep
//!   (the block, the cantilever on its stop).
//!
//! `cargo bench --bench goals [-- strip | damping | paths | reduction | floor | whole | products | patch | friction]`
//! (default: all). Times
//! come from one run on a shared machine: the ratios within a table are what to compare.

use std::path::{Path, PathBuf};
use std::time::Instant;

use hbcontact::config::{load_pipeline, Pipeline};
use hbcontact::hbm::system::{FactorOptions, FactorPath};
use hbcontact::hbm::System;
use hbcontact::linalg::schur::{SchurPlan, BLOCKED_SOLVE_WEIGHT, SCHUR_SLOWDOWN};
use hbcontact::linalg::{Csc, Factor};
use hbcontact::pipeline::{self, Purpose, RunOptions, Stage, Stages, Summary};
use hbcontact::Silent;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn pipeline_with(file: &str, sets: &[String]) -> Option<Pipeline> {
    match load_pipeline(&root().join(file), sets) {
        Ok(p) => Some(p),
        Err(e) => {
            eprintln!("{file}: {e}");
            None
        }
    }
}

/// The system and contact operator of a pipeline (mesh from the cache under `work`).
fn model(p: &Pipeline, work: &Path) -> Option<pipeline::Model> {
    let mut stages = Stages::new(p, &Silent);
    let built = pipeline::stages::mesh(p, &work.join("model"), &mut stages)
        .and_then(|(mesh, _)| pipeline::build(p, mesh, Purpose::HarmonicBalance));
    match built {
        Ok(m) => Some(m),
        Err(e) => {
            eprintln!("{e}");
            None
        }
    }
}

fn seconds<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let out = f();
    (out, t.elapsed().as_secs_f64())
}

fn max_difference(a: &[faer::c64], b: &[faer::c64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, z| m.max(z.norm()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).norm()))
        / scale
}

/// One factorization of Z_k on a forced path, with G_k for `b` (the LDLᵀ's own; the LU's by
/// blocked solves): (factor, seconds to factor, seconds for G, G).
fn factor_and_g(
    system: &System,
    k: usize,
    b: &Csc,
    path: FactorPath,
) -> Option<(Factor, f64, f64, Vec<faer::c64>)> {
    let options = FactorOptions {
        path,
        ..Default::default()
    };
    let (f, t_factor) = seconds(|| system.factor_with(k, Some(b), &options));
    let f = f.ok()?;
    let (g, t_g) = seconds(|| f.compliance(b));
    Some((f, t_factor, t_g, g))
}

/// Reduction against factorization on the half-disc refined at the contact: the LDLᵀ (one
/// elimination gives the factor and G_k) against faer's LU plus n_c blocked solves.
fn reduction() {
    println!("\n## One factorization per harmonic with G_k = B Z_k⁻¹ Bᵀ (half_disc, search_distance 0.05)");
    println!(
        "{:>10} {:>6} {:>7} {:>3} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9} {:>10} {:>6}",
        "lc_contact",
        "nodes",
        "dofs",
        "H",
        "LDLt s",
        "LU s",
        "LU G s",
        "LDLt/LU",
        "est. ratio",
        "plan s",
        "|ΔG|/|G|",
        "ldlt"
    );
    let work = root().join("output/bench-goals");
    for (lc, h, all) in [
        (0.004, 5, true),
        (0.002, 5, true),
        (0.001, 5, true),
        (0.0005, 5, false),
        (0.0005, 10, false),
    ] {
        let sets = vec![
            format!("geometry.parameters.lc_contact={lc}"),
            "contact.search_distance=0.05".to_string(),
            format!("harmonic_balance.harmonics={h}"),
        ];
        let Some(p) = pipeline_with("pipelines/half_disc.yaml", &sets) else {
            return;
        };
        let Some(m) = model(&p, &work) else { return };
        let Some(contact) = &m.contact else { return };
        let b = &contact.operator.b_free;
        let system: &System = &m.system;
        let (plan, t_plan) = seconds(|| system.schur_plan(b));
        let Some(plan) = plan else {
            eprintln!("no Schur plan for this B");
            return;
        };
        let (mut t_ldlt, mut t_lu, mut t_lu_g, mut diff, mut ldlt) = (0.0, 0.0, 0.0, 0.0f64, 0);
        for k in 0..=h {
            let Some((f, tf, tg, g)) = factor_and_g(system, k, b, FactorPath::Ldlt) else {
                return;
            };
            t_ldlt += tf + tg;
            ldlt += f.is_ldlt() as usize;
            drop(f);
            // The LU path on the finest meshes only at k = 1 (its G takes minutes), scaled.
            if all || k == 1 {
                let Some((_, tf, tg, reference)) = factor_and_g(system, k, b, FactorPath::Lu)
                else {
                    return;
                };
                let scale = if all { 1.0 } else { (h + 1) as f64 };
                t_lu += tf * scale;
                t_lu_g += tg * scale;
                diff = diff.max(max_difference(&g, &reference));
            }
        }
        println!(
            "{lc:>10} {:>6} {:>7} {h:>3} {t_ldlt:>10.2} {:>10} {:>10} {:>10.3} {:>10.3} {t_plan:>9.2} {diff:>10.1e} {ldlt:>3}/{}",
            b.nrows,
            system.free_count(),
            format!("{t_lu:.2}{}", if all { "" } else { "*" }),
            format!("{t_lu_g:.2}{}", if all { "" } else { "*" }),
            t_ldlt / (t_lu + t_lu_g),
            plan.schur_cost / plan.solve_cost(),
            h + 1,
        );
    }
    println!("(LDLt s = factor and G by the kept LDLᵀ, all harmonics, checks included; LU s = faer's LU, LU G s = its n_c blocked solves; * timed at k = 1 and scaled by H + 1; est. ratio = estimated mul-adds of the LDLᵀ over the LU path's; ldlt = harmonics that kept the LDLᵀ after its checks)");
}

/// The path choice on the shipped scenes: the estimate against both paths' measured times,
/// and the two constants of the estimate they imply (SCHUR_SLOWDOWN, BLOCKED_SOLVE_WEIGHT).
fn paths() {
    println!("\n## Factorization path per shipped scene (its own H; all harmonics; with G where there is contact)");
    println!(
        "{:>16} {:>6} {:>7} {:>3} {:>10} {:>9} {:>9} {:>9} {:>12} {:>9} {:>9} {:>7}",
        "scene",
        "nodes",
        "dofs",
        "H",
        "est. ratio",
        "LDLt s",
        "LU s",
        "LU G s",
        "meas. ratio",
        "slowdown",
        "G weight",
        "chosen"
    );
    let work = root().join("output/bench-goals");
    for scene in [
        "strip_wall",
        "reference_strip",
        "blade_casing",
        "half_disc",
        "quickstart",
        "cantilever",
    ] {
        let file = format!("pipelines/{scene}.yaml");
        let Some(p) = pipeline_with(&file, &[]) else {
            return;
        };
        let Some(m) = model(&p, &work) else { return };
        let empty = Csc::from_entries(0, m.system.free_count(), &[]);
        let b = m.contact.as_ref().map_or(&empty, |c| &c.operator.b_free);
        let plan = if b.nrows > 0 {
            m.system.schur_plan(b)
        } else {
            Some(std::sync::Arc::new(SchurPlan::without_contact(
                &m.system.k_ff,
            )))
        };
        let Some(plan) = plan else { continue };
        let h = if b.nrows > 0 {
            p.harmonic_balance.harmonics
        } else {
            1
        };
        let (mut t_ldlt, mut t_lu, mut t_g) = (0.0, 0.0, 0.0);
        for _ in 0..2 {
            let (mut a, mut c, mut g) = (0.0, 0.0, 0.0);
            for k in 0..=h {
                let k = if b.nrows > 0 { k } else { 1 };
                let Some((_, tf, tg, _)) = factor_and_g(&m.system, k, b, FactorPath::Ldlt) else {
                    return;
                };
                a += tf + tg;
                let Some((_, tf, tg, _)) = factor_and_g(&m.system, k, b, FactorPath::Lu) else {
                    return;
                };
                c += tf;
                g += tg;
            }
            (t_ldlt, t_lu, t_g) = (a, c, g);
        }
        let est = plan.schur_cost / plan.solve_cost();
        let lu_rate = t_lu / plan.lu_cost;
        let weight = if plan.blocked_cost > 0.0 {
            format!("{:.2}", t_g / plan.blocked_cost / lu_rate)
        } else {
            "-".into()
        };
        println!(
            "{scene:>16} {:>6} {:>7} {h:>3} {est:>10.3} {t_ldlt:>9.3} {t_lu:>9.3} {t_g:>9.3} {:>12.3} {:>9.2} {weight:>9} {:>7}",
            b.nrows,
            m.system.free_count(),
            t_ldlt / (t_lu + t_g),
            t_ldlt / plan.schur_cost / lu_rate,
            if plan.preferred() { "LDLt" } else { "LU" },
        );
    }
    println!("(second of two rounds; meas. ratio = LDLt / (LU + LU G); slowdown = time per estimated mul-add of the LDLᵀ over the LU factorization's, G weight = that of the LU's blocked solves for G over its factorization's: the estimate uses SCHUR_SLOWDOWN = {SCHUR_SLOWDOWN}, BLOCKED_SOLVE_WEIGHT = {BLOCKED_SOLVE_WEIGHT})");
}

/// The whole 601-contact-node half-disc run at H = 10 (goal < 30 s), per stage, without the
/// stability check by time marching.
fn whole() {
    println!("\n## Half-disc, 601 contact nodes, H = 10: the whole run (goal < 30 s)");
    let sets = vec![
        "geometry.parameters.lc_contact=0.0005".to_string(),
        "contact.search_distance=0.05".to_string(),
        "harmonic_balance.harmonics=10".to_string(),
        // The stability check (time marching, up to 60 s per march) is issue 10's cost.
        "stability.check=false".to_string(),
    ];
    let _ = run("pipelines/half_disc.yaml", &sets, "half-disc-601-warm");
    let Some((s, wall)) = run("pipelines/half_disc.yaml", &sets, "half-disc-601") else {
        return;
    };
    let st = &s.stage_seconds;
    println!(
        "{:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6}",
        "run s", "mesh", "factor", "reduce", "newton", "recover", "write", "iters"
    );
    println!(
        "{wall:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>6}",
        st.get(Stage::Mesh),
        st.get(Stage::Factor),
        st.get(Stage::Reduce),
        st.get(Stage::Newton),
        st.get(Stage::Recover),
        st.get(Stage::Write),
        iterations(&s),
    );
    println!("(second of two runs, mesh cached, without the stability check; factor includes G_k where the LDLᵀ was chosen)");
}

/// The half-disc pressed onto its wall (63 contact nodes of a Hertz patch, rocked at 50 Hz) at
/// H = 10…80: iterations and stage times. Before the harmonic-block preconditioner H = 40 and
/// 60 stopped with exit 4 after 35 and 91 s.
fn patch() {
    println!("\n## A pressed contact patch (half_disc.yaml, 63 contact nodes) against H");
    println!(
        "{:>4} {:>6} {:>8} {:>8} {:>8} {:>8} {:>14} {:>14}",
        "H", "iters", "factor", "newton", "knobs", "run s", "peak N", "mean N"
    );
    for h in [10, 20, 40, 60, 80] {
        let sets = vec![
            format!("harmonic_balance.harmonics={h}"),
            "stability.check=false".to_string(),
        ];
        let Some((s, wall)) = run("pipelines/half_disc.yaml", &sets, &format!("patch-h{h}")) else {
            println!("{h:>4} failed");
            continue;
        };
        let st = &s.stage_seconds;
        let c = s.contact.as_ref();
        println!(
            "{h:>4} {:>6} {:>8.3} {:>8.3} {:>8.3} {wall:>8.2} {:>14.6e} {:>14.6e}",
            iterations(&s),
            st.get(Stage::Factor),
            st.get(Stage::Newton),
            st.get(Stage::KnobCheck),
            c.map_or(f64::NAN, |c| c.peak_contact_force),
            c.map_or(f64::NAN, |c| c.mean_contact_force),
        );
    }
}

/// Run a pipeline by harmonic balance (plots off) into `work/<tag>`; its summary and wall time.
fn run(file: &str, sets: &[String], tag: &str) -> Option<(Summary, f64)> {
    let mut sets = sets.to_vec();
    sets.push("output.plots=false".into());
    let p = pipeline_with(file, &sets)?;
    let options = RunOptions {
        out: Some(root().join("output/bench-goals").join(tag)),
        ..Default::default()
    };
    let (result, secs) = seconds(|| pipeline::run(&p, &options, &Silent));
    match result {
        Ok(r) => Some((r.summary, secs)),
        Err(e) => {
            eprintln!("{file} {sets:?}: {e}");
            None
        }
    }
}

/// The solve stages (assembly to recovery: no meshing, resonance or stability checks, or
/// writing) of a run; the knob check is part of the solve, apart from its Newton.
const SOLVE_STAGES: [Stage; 7] = [
    Stage::Assemble,
    Stage::Factor,
    Stage::LinearSolve,
    Stage::Reduce,
    Stage::Newton,
    Stage::KnobCheck,
    Stage::Recover,
];

/// The knob check's second c and the change there ("c/3 0.68%", "3c 0.45%", or "none" where
/// neither re-solve converged).
fn c_check(s: &Summary) -> String {
    let Some(solve) = s.contact.as_ref().and_then(|c| c.solver.as_ref()) else {
        return "-".into();
    };
    let k = &solve.knob_check;
    let at = hbcontact::hbm::knobs::c_label(k.c_alternative / solve.c);
    k.c_change.map_or("none".into(), |change| {
        format!("{at} {:.2}%", 100.0 * change)
    })
}

/// How the contact solve converged: directly, or its detour (`ContactSolve::detour`).
fn route(s: &Summary) -> String {
    let solve = s.contact.as_ref().and_then(|c| c.solver.as_ref());
    match solve.map(|solve| solve.detour()) {
        None => "-".into(),
        Some(None) => "direct".into(),
        Some(Some(detour)) => detour,
    }
}

fn iterations(s: &Summary) -> usize {
    s.contact
        .as_ref()
        .and_then(|c| c.solver.as_ref())
        .map_or(0, |c| c.newton_iterations)
}

/// Runs of the reference strip per H: the median solve (of `STRIP_RUNS`, by solve time) is
/// the one reported, so that one stall of the shared machine does not make the table.
const STRIP_RUNS: usize = 5;

/// The reference strip at H = 20 and 40 against the numpy prototype.
fn strip() {
    println!("\n## Reference strip (pipelines/reference_strip.yaml): solve time against the numpy prototype");
    println!(
        "{:>3} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>10} {:>8} {:>12} {:>14} {:>6}",
        "H",
        "assemble",
        "factor",
        "newton",
        "knobs",
        "recover",
        "solve s",
        "prototype",
        "speed-up",
        "goal",
        "newton/solve",
        "(+knobs)/solve",
        "iters"
    );
    let _ = run(
        "pipelines/reference_strip.yaml",
        &["harmonic_balance.harmonics=1".into()],
        "warm",
    );
    for (h, prototype) in [(20usize, 0.42), (40, 3.7)] {
        let mut runs: Vec<(f64, Summary)> = (0..STRIP_RUNS)
            .filter_map(|_| {
                run(
                    "pipelines/reference_strip.yaml",
                    &[format!("harmonic_balance.harmonics={h}")],
                    &format!("strip-h{h}"),
                )
            })
            .map(|(s, _)| {
                let solve: f64 = SOLVE_STAGES.iter().map(|&k| s.stage_seconds.get(k)).sum();
                (solve, s)
            })
            .collect();
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let Some((solve, s)) = runs.get(runs.len() / 2) else {
            continue;
        };
        let st = &s.stage_seconds;
        let fastest = runs.first().map_or(f64::NAN, |r| r.0);
        let slowest = runs.last().map_or(f64::NAN, |r| r.0);
        println!(
            "{h:>3} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {solve:>9.3} {prototype:>10.2} {:>9.1}× {:>8} {:>11.0}% {:>13.0}% {:>6}   (solve {fastest:.3}–{slowest:.3} s over {} runs)",
            st.get(Stage::Assemble),
            st.get(Stage::Factor),
            st.get(Stage::Newton),
            st.get(Stage::KnobCheck),
            st.get(Stage::Recover),
            prototype / solve,
            "≥ 10×",
            100.0 * st.get(Stage::Newton) / solve,
            100.0 * (st.get(Stage::Newton) + st.get(Stage::KnobCheck)) / solve,
            iterations(s),
            runs.len(),
        );
    }
    println!("(median of {STRIP_RUNS} runs by solve time; solve = assemble + factor + linear_solve + reduce + newton + knob_check + recover; goal: newton < 30% of the run; knobs = the re-solves at 2N and c/3 that check the answer does not hang on them)");
}

/// Newton iterations of the 0.5%-damped strip against the 5%-damped one, at every H from 5
/// to 80 in steps of 5 (the goal is "every H"; the counts are not smooth in H), and how many
/// H miss the goal.
fn damping() {
    println!("\n## Light damping: Newton iterations, reference strip, alpha = 86 (0.5%) against 857 (5%)");
    println!(
        "{:>3} {:>8} {:>10} {:>8} {:>10} {:>7} {:>8} {:>14} {:>10} {:>10}  0.5% route",
        "H",
        "5% its",
        "5% s",
        "0.5% its",
        "0.5% s",
        "ratio",
        "goal",
        "0.5% c check",
        "5% mean",
        "0.5% mean"
    );
    let (mut missed, mut missed_direct, mut worst_direct) = (Vec::new(), Vec::new(), 0.0f64);
    for h in (5usize..=80).step_by(5) {
        let mut row = Vec::new();
        for alpha in [857.0, 86.0] {
            // Iterations only: the stability march (hundreds of periods at 0.5%) is skipped.
            let sets = vec![
                format!("harmonic_balance.harmonics={h}"),
                format!("damping.alpha={alpha}"),
                "stability.check=false".to_string(),
            ];
            row.push(run(
                "pipelines/reference_strip.yaml",
                &sets,
                &format!("damp-{alpha}-h{h}"),
            ));
        }
        let checked = row[1].as_ref().map_or("-".into(), |(s, _)| c_check(s));
        let how = row[1].as_ref().map_or("-".into(), |(s, _)| route(s));
        let cell = |r: &Option<(Summary, f64)>| match r {
            Some((s, t)) => (
                format!("{}", iterations(s)),
                format!("{t:.2}"),
                iterations(s) as f64,
            ),
            None => ("failed".into(), "-".into(), f64::NAN),
        };
        let (a, b) = (cell(&row[0]), cell(&row[1]));
        let mean = |r: &Option<(Summary, f64)>| {
            r.as_ref()
                .and_then(|(s, _)| s.contact.as_ref())
                .map_or("-".into(), |c| format!("{:.0}", c.mean_contact_force))
        };
        let failed = a.2.is_nan() || b.2.is_nan();
        if failed || b.2 > 3.0 * a.2 {
            missed.push(h);
        }
        if how == "direct" {
            worst_direct = worst_direct.max(b.2 / a.2);
            if b.2 > 3.0 * a.2 {
                missed_direct.push(h);
            }
        }
        println!(
            "{h:>3} {:>8} {:>10} {:>8} {:>10} {:>7.2} {:>8} {:>14} {:>10} {:>10}  {}",
            a.0,
            a.1,
            b.0,
            b.1,
            b.2 / a.2,
            "≤ 3",
            checked,
            mean(&row[0]),
            mean(&row[1]),
            how
        );
    }
    println!("(s = the whole run's wall time; c check = the knob check's second c and the answer's change there; mean = the mean contact force [N], which tells the periodic states apart)");
    println!("goal missed at H = {missed:?}");
    // The goal against the physics: where the smoothing path from the open state reaches a
    // state, and where it folds (the strip has several periodic states near this resonance,
    // contact_scenes.rs::lightly_damped_strip_has_two_periodic_states_at_one_h).
    println!(
        "where the 0.5% solve was direct (its smoothing path from the open state reached a state): largest ratio {worst_direct:.2}, missed at H = {missed_direct:?}; every other H folded and went through the continuation in the damping (docs/method.md §7)"
    );
}

/// Mul-adds of a sparse LU of `a`'s pattern in an AMD order (faer's estimate).
fn lu_mul_adds(a: &hbcontact::linalg::Csc) -> f64 {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::amd;
    let n = a.ncols;
    let (mut perm, mut perm_inv) = (vec![0usize; n], vec![0usize; n]);
    let pattern =
        faer::sparse::SymbolicSparseColMatRef::new_checked(n, n, &a.col_ptr, None, &a.row_idx);
    let mut buf = MemBuffer::new(amd::order_maybe_unsorted_scratch::<usize>(n, a.nnz()));
    amd::order_maybe_unsorted(
        &mut perm,
        &mut perm_inv,
        pattern,
        amd::Control::default(),
        MemStack::new(&mut buf),
    )
    .map_or(f64::NAN, |f| f.n_mult_subs_lu + f.n_div)
}

/// Achieved real flop rate of a dense complex matrix product (the rate a factorization's
/// dense kernels can reach on this machine, now).
fn dense_rate(n: usize) -> f64 {
    let a = faer::Mat::<faer::c64>::from_fn(n, n, |i, j| faer::c64::new((i + j) as f64, 1.0));
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let (_, t) = seconds(|| &a * &a);
        best = best.min(t);
    }
    8.0 * (n as f64).powi(3) / best
}

/// Best of ten (large: three) wall times of factoring Z_1 on a forced path (with G for `b`).
fn best_factor(system: &System, k: usize, b: &Csc, path: FactorPath) -> Option<(f64, bool)> {
    let mut best = (f64::INFINITY, false);
    let rounds = if system.free_count() < 10_000 { 10 } else { 3 };
    for _ in 0..rounds {
        let (f, tf, tg, _) = factor_and_g(system, k, b, path)?;
        best = (best.0.min(tf + tg), f.is_ldlt());
    }
    Some(best)
}

/// Time per factorization against its flop count: faer's LU, and the kept LDLᵀ (with G).
fn floor() {
    println!(
        "\n## Factorization floor: time per complex factorization of Z_1 against its flop count"
    );
    let rate = dense_rate(384);
    println!(
        "dense complex matrix product here, now: {:.2} Gflop/s",
        rate * 1e-9
    );
    println!(
        "{:>28} {:>7} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8}",
        "scene",
        "dofs",
        "LU Mflop",
        "LDLt Mf",
        "LU ms",
        "LDLt ms",
        "LU/LDLt",
        "LU floor",
        "LDLt fl",
        "LU t/fl",
        "LDLt t/fl"
    );
    let work = root().join("output/bench-goals");
    let scenes: [(&str, Vec<String>); 2] = [
        ("pipelines/reference_strip.yaml", vec![]),
        (
            "pipelines/half_disc.yaml",
            vec![
                "geometry.parameters.lc_contact=0.0005".into(),
                "contact.search_distance=0.05".into(),
            ],
        ),
    ];
    for (file, sets) in scenes {
        let Some(p) = pipeline_with(file, &sets) else {
            return;
        };
        let Some(m) = model(&p, &work) else { return };
        let Some(contact) = &m.contact else { return };
        let b = &contact.operator.b_free;
        let Some(plan) = m.system.schur_plan(b) else {
            return;
        };
        // Complex: 4 real multiplications and 4 additions per complex mul-add.
        let lu_flops = 8.0 * lu_mul_adds(&m.system.k_ff);
        let ldlt_flops = 8.0 * plan.schur_cost;
        let (Some((t_lu, _)), Some((t_ldlt, kept))) = (
            best_factor(&m.system, 1, b, FactorPath::Lu),
            best_factor(&m.system, 1, b, FactorPath::Ldlt),
        ) else {
            return;
        };
        // The LDLᵀ alone (no checks), best of three.
        let (re, im) = m.system.dynamic_stiffness(1);
        let mut bare = f64::INFINITY;
        for _ in 0..10 {
            let t = seconds(|| plan.factor(&re.values, im.as_deref(), 1e-14)).1;
            bare = bare.min(t);
        }
        let f = plan.factor(&re.values, im.as_deref(), 1e-14).ok();
        let rhs = vec![faer::c64::new(1.0, 0.5); m.system.free_count()];
        let mut t_solve = f64::INFINITY;
        if let Some(f) = &f {
            for _ in 0..20 {
                t_solve = t_solve.min(seconds(|| f.solve(&rhs)).1);
            }
        }
        // Z_1 carries the load (two solves checked); Z_2 does not (one).
        let unloaded = best_factor(&m.system, 2, b, FactorPath::Ldlt).map_or(f64::NAN, |t| t.0);
        println!(
            "{:>28} LDLt without its checks: {:.2} ms; of unloaded Z_2 with its checks {:.2} ms; one solve {:.3} ms; {} fronts, widest {}, {} L entries",
            "",
            bare * 1e3,
            unloaded * 1e3,
            t_solve * 1e3,
            plan.fronts().0,
            plan.fronts().1,
            plan.factor_entries,
        );
        println!(
            "{:>28} {:>7} {:>9.1} {:>9.1} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>8.1} {:>8.1}{}",
            format!(
                "{}{}",
                p.name,
                if sets.is_empty() { "" } else { " (601 nodes)" }
            ),
            m.system.free_count(),
            lu_flops * 1e-6,
            ldlt_flops * 1e-6,
            t_lu * 1e3,
            t_ldlt * 1e3,
            t_lu / t_ldlt,
            lu_flops / rate * 1e3,
            ldlt_flops / rate * 1e3,
            t_lu / (lu_flops / rate),
            t_ldlt / (ldlt_flops / rate),
            if kept { "" } else { " (LDLt fell back to LU)" },
        );
    }
    println!("(best of ten, three at 601 nodes; LU = faer's numeric LU alone, flops its AMD estimate on the pattern of Z_k; LDLt = the kept LDLᵀ with the contact normals last, including G_k = S⁻¹ and its checks, flops from its plan; floor = flops at the dense product's rate)");
}

/// One product G v (all harmonics) by `ReducedProblem::compliance_product` (faer's complex
/// matrix–vector product per harmonic) against a dot product per row of G_k, at the contact
/// node counts of the strip, the half-disc and the refined half-disc (synthetic G_k: the
/// time does not depend on the values).
fn products() {
    use faer::c64;
    use hbcontact::hbm::fourier::{phasor, set_phasor};
    use hbcontact::hbm::problem::ReducedProblem;
    println!("\n## The product G v of a GMRES iteration: faer's matrix–vector product against a dot per row");
    println!(
        "{:>6} {:>4} {:>14} {:>14} {:>7}",
        "nodes", "H", "faer µs", "row dots µs", "ratio"
    );
    for (nc, h) in [(9usize, 40usize), (63, 5), (151, 5), (601, 10)] {
        let m = 2 * h + 1;
        let entry = |k: usize, i: usize, j: usize| {
            let d = (i as f64 - j as f64).abs();
            c64::new(1.0 / (1.0 + d + k as f64), 0.1 / (1.0 + d))
        };
        let problem = ReducedProblem::from_compliance(nc, h, entry);
        let x: Vec<f64> = (0..nc * m).map(|r| (r as f64 * 0.37).sin()).collect();
        let (mut fast, mut slow) = (vec![0.0; nc * m], vec![0.0; nc * m]);
        let mut scratch = Vec::new();
        let reps = (2e8 as usize / (nc * nc * (h + 1))).clamp(10, 100_000);
        let best = |f: &mut dyn FnMut()| {
            (0..5)
                .map(|_| seconds(|| (0..reps).for_each(|_| f())).1 / reps as f64)
                .fold(f64::INFINITY, f64::min)
        };
        let t_fast = best(&mut || problem.compliance_product(&x, &mut fast, &mut scratch));
        let mut lam = vec![c64::new(0.0, 0.0); nc];
        let t_slow = best(&mut || {
            slow.fill(0.0);
            for (k, gk) in problem.compliance.iter().enumerate() {
                for (j, l) in lam.iter_mut().enumerate() {
                    *l = phasor(&x[j * m..(j + 1) * m], k);
                }
                for i in 0..nc {
                    let y = hbcontact::linalg::dot(&gk[i * nc..(i + 1) * nc], &lam);
                    set_phasor(&mut slow[i * m..(i + 1) * m], k, y);
                }
            }
        });
        let differ = fast
            .iter()
            .zip(&slow)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        println!(
            "{nc:>6} {h:>4} {:>14.2} {:>14.2} {:>6.2}× (max difference {differ:.1e})",
            t_fast * 1e6,
            t_slow * 1e6,
            t_slow / t_fast
        );
    }
    println!(
        "(best of five batches; faer on both cores from 2¹⁶ entries of G_k, i.e. at 601 nodes)"
    );
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let want = |s: &str| args.is_empty() || args.iter().any(|a| a == s);
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("load average at start: {}", load.trim());
    if want("strip") {
        strip();
    }
    if want("damping") {
        damping();
    }
    if want("paths") {
        paths();
    }
    if want("reduction") {
        reduction();
    }
    if want("floor") {
        floor();
    }
    if want("whole") {
        whole();
    }
    if want("products") {
        products();
    }
    if want("patch") {
        patch();
    }
    if want("friction") {
        friction();
    }
}

/// Friction's cost: each scene at μ and frictionless, the Newton stage and the whole run,
/// and the ratio (one run each, on this machine now).
fn friction() {
    println!("\n# Coulomb friction against the frictionless solve of the same scene");
    println!("scene, H | Newton frictionless [s] | Newton with μ [s] | ratio | run frictionless [s] | run with μ [s] | ratio | energy per period [J]");
    let scenes = [
        ("pipelines/scenes/friction_block.yaml", "0.3"),
        ("pipelines/scenes/friction_damper.yaml", "0.1"),
    ];
    for (file, mu) in scenes {
        for h in [20, 40] {
            let base = vec![format!("harmonic_balance.harmonics={h}")];
            let mut with = base.clone();
            with.push(format!("contact.friction.coefficient={mu}"));
            let mut without = base;
            without.push("contact.friction.coefficient=0".into());
            let (Some((a, ta)), Some((b, tb))) = (
                run(file, &without, "friction-off"),
                run(file, &with, "friction-on"),
            ) else {
                continue;
            };
            let newton = |s: &Summary| s.stage_seconds.get(Stage::Newton);
            let energy = b.contact.as_ref().and_then(|c| c.friction.as_ref());
            println!(
                "{file} μ = {mu}, H = {h} | {:.3} | {:.3} | {:.1} | {ta:.3} | {tb:.3} | {:.1} | {:.4e}",
                newton(&a),
                newton(&b),
                newton(&b) / newton(&a).max(1e-6),
                tb / ta,
                energy.map_or(f64::NAN, |f| f.dissipated_energy_per_period),
            );
        }
    }
    println!("\n# Sweeps with and without friction (the scene's own range; no stability check)");
    println!("scene | points frictionless | seconds | points with μ | seconds | ratio per point");
    let sweeps = [
        ("pipelines/scenes/friction_block.yaml", "0.3"),
        ("pipelines/scenes/cantilever_stop.yaml", "0.3"),
    ];
    for (file, mu) in sweeps {
        let sweep = |mu: &str| {
            let sets = [
                format!("contact.friction.coefficient={mu}"),
                "stability.check=false".into(),
                "output.plots=false".into(),
            ];
            let p = pipeline_with(file, &sets)?;
            let options = RunOptions {
                out: Some(
                    root()
                        .join("output/bench-goals")
                        .join(format!("sweep-{mu}")),
                ),
                ..Default::default()
            };
            let (result, secs) = seconds(|| hbcontact::sweep::run(&p, &options, &Silent));
            result.ok().map(|r| (r.summary.points, secs))
        };
        let (Some((na, ta)), Some((nb, tb))) = (sweep("0"), sweep(mu)) else {
            continue;
        };
        println!(
            "{file} μ = {mu} | {na} | {ta:.2} | {nb} | {tb:.2} | {:.1}",
            (tb / nb as f64) / (ta / na as f64)
        );
    }
}
