//! The 2T branches a sweep follows from the period doublings it locates
//! (`sweep.follow_period_doubling`; docs/method.md, "The 2T branch").
//!
//! Every period doubling a sweep lists is first checked on the 2T problem (`confirm`: det J_odd
//! changes sign around it). From the judged row beside a confirmed one (its unstable side
//! first), the T state is embedded in the 2T problem (`hbm::subharmonic`: half the drive
//! frequency, the loads on the even harmonics, 2H harmonics and 2N samples) and pushed along
//! the null vector φ of the odd-harmonic Newton matrix J_odd, the period doubling's Floquet
//! vector in the harmonic-balance unknowns, until a fixed-ω Newton lands on a state with an
//! odd part (`first_point`); the continuation starts there, along the push. The branch ends
//! where its odd part turns against the previous point's: it crossed the T branch there (a
//! second period doubling) onto the same orbit shifted by T.
//!
//! A branch row is a sweep row at the drive frequency 2ω₂/2π: `probe_first_harmonic` is the
//! probe's amplitude at the drive frequency (the 2T problem's harmonic 2), `subharmonic` the
//! one at half of it (harmonic 1); the stability verdict is Hill's on the 2T state (its
//! multipliers are over 2T).

use serde::{Deserialize, Serialize};

use super::bifurcations::{BifurcationKind, BifurcationReport};
use super::{Start, SweepRow};
use crate::config::{Pipeline, SweepSpec};
use crate::hbm::continuation::{self, ContinuationState, PointInfo};
use crate::hbm::hill::HillModel;
use crate::hbm::{subharmonic, ContactSolution, Solution};
use crate::linalg::norm2;
use crate::pipeline::outputs::Output;
use crate::pipeline::summary::MeshInfo;
use crate::pipeline::Model;
use crate::progress::Reporter;
use crate::{Error, Result};

/// A branch the sweep followed off its curve.
#[derive(Clone, Debug, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Branch {
    /// `period_doubling`: the 2T branch of a period doubling.
    pub kind: String,
    /// The period doubling it starts from [Hz] (`bifurcations`), and the row it left from.
    pub from_hz: f64,
    pub from_row: usize,
    /// Where its odd part changed sign: it crossed the T-periodic curve there [Hz] (a period
    /// doubling of that curve), between its last row and the next point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rejoins_hz: Option<f64>,
    /// How it ended, in words.
    pub ended: String,
    /// Its points in curve order (`frequency_hz` the drive frequency, `subharmonic` the
    /// probe's amplitude at half of it).
    pub rows: Vec<SweepRow>,
}

/// The 2T branch of every period doubling of `bifurcations` that no branch followed before it
/// rejoined the curve there; a branch that cannot start is a warning.
#[allow(clippy::too_many_arguments)]
pub fn follow_all(
    p: &Pipeline,
    spec: &SweepSpec,
    (model, mesh): (&Model, &MeshInfo),
    starts: &[Start],
    bifurcations: &[BifurcationReport],
    hill: Option<&HillModel>,
    reporter: &dyn Reporter,
) -> (Vec<Branch>, Vec<String>) {
    let (mut branches, mut warnings): (Vec<Branch>, Vec<String>) = (Vec::new(), Vec::new());
    for pd in bifurcations
        .iter()
        .filter(|b| b.kind == BifurcationKind::PeriodDoubling && b.confirmed != Some(false))
    {
        let reached = |b: &Branch| {
            b.rejoins_hz
                .is_some_and(|f| (f - pd.frequency_hz).abs() <= SAME * f)
        };
        if branches.iter().any(reached) {
            continue;
        }
        match follow(p, spec, (model, mesh), starts, pd, hill, reporter) {
            Ok(branch) => branches.push(branch),
            Err(e) => warnings.push(format!(
                "the 2T branch of the period doubling at {:.4} Hz was not followed: {e}",
                pd.frequency_hz
            )),
        }
    }
    (branches, warnings)
}

/// A period doubling within this fraction of a branch's rejoining frequency is that branch's
/// other end.
const SAME: f64 = 0.005;

/// The 2T branch from period doubling `pd`.
fn follow(
    p: &Pipeline,
    spec: &SweepSpec,
    (model, mesh): (&Model, &MeshInfo),
    starts: &[Start],
    pd: &BifurcationReport,
    hill: Option<&HillModel>,
    reporter: &dyn Reporter,
) -> Result<Branch> {
    // The unstable side first: a supercritical doubling's branch lies there.
    let sides = if pd.loses {
        [pd.between[1], pd.between[0]]
    } else {
        pd.between
    };
    let mut tried = Vec::new();
    let found = sides.iter().find_map(|&row| {
        let start = first_point(p, model, starts, row);
        start
            .map_err(|e| tried.push(format!("from row {row}: {e}")))
            .ok()
    });
    let Some(first) = found else {
        return Err(Error::NotConverged(tried.join("; ")));
    };
    let mut system = first.system;
    let mut settings = super::settings(spec, Some(first.state));
    settings.omega_start /= 2.0;
    settings.omega_end /= 2.0;
    let mut walk = Walk::new(p, (model, mesh), first.hb.harmonics);
    let outcome = continuation::sweep(
        &mut system,
        Some(&first.op),
        &first.hb,
        &settings,
        reporter,
        &mut |info: &PointInfo, solution: &Solution| walk.point(info, solution),
    );
    let ended = match (&walk.rejoins, outcome) {
        (Some(f), _) => format!("rejoins the curve at {f:.4} Hz"),
        (None, Ok(o)) => o
            .stopped
            .unwrap_or_else(|| "reached the end of the range".into()),
        (None, Err(e)) => e.to_string(),
    };
    if let Some(hill) = hill {
        walk.judge(model, hill);
    }
    Ok(Branch {
        kind: "period_doubling".into(),
        from_hz: pd.frequency_hz,
        from_row: first.row,
        rejoins_hz: walk.rejoins,
        ended,
        rows: walk.rows,
    })
}

/// Where a 2T continuation starts: its problem and first state.
struct FirstPoint {
    row: usize,
    system: crate::hbm::System,
    op: crate::contact::ContactOperator,
    hb: crate::hbm::HbSettings,
    state: ContinuationState,
}

/// Pushes along φ tried from the T state, as fractions of its ‖λ‖ (the branch between a
/// close pair of doublings is small: on the coarse strip at H = 40, 1270–1285 Hz, |μ| ≤ 1.03).
const PUSHES: [f64; 7] = [1e-4, 1e-3, 0.01, 0.03, 0.1, 0.3, 1.0];

/// The odd share below which a state is the T one (a Newton that returns to it leaves an odd
/// part of the order of its tolerance).
const ON_T: f64 = 1e-6;

/// The 2T problem at row `row`'s ω with the row's T state embedded in it, and what its
/// odd-harmonic Newton matrix says there.
struct Doubled<'s> {
    system: crate::hbm::System,
    op: crate::contact::ContactOperator,
    hb: crate::hbm::HbSettings,
    problem: crate::hbm::problem::ReducedProblem,
    x: Vec<f64>,
    contact: &'s ContactSolution,
    omega: f64,
    odd: subharmonic::OddNull,
}

fn doubled_at<'s>(
    p: &Pipeline,
    model: &Model,
    starts: &'s [Start],
    row: usize,
) -> Result<Doubled<'s>> {
    let (omega, contact) = starts
        .iter()
        .find(|(i, _, _)| *i == row)
        .and_then(|(_, w, c)| c.as_ref().map(|c| (*w, c)))
        .ok_or_else(|| Error::Model(format!("the state of row {row} was not kept")))?;
    let op = &(model.contact.as_ref())
        .ok_or_else(|| Error::Model("internal: no contact".into()))?
        .operator;
    let mut base = model.system.clone();
    base.omega = omega;
    let (system, op2) = subharmonic::doubled_period(&base, op)?;
    let hb = subharmonic::doubled_settings(&crate::hbm::HbSettings {
        harmonics: contact.harmonics,
        samples: contact.samples,
        ..crate::pipeline::hb_settings(p)
    });
    let problem = subharmonic::reduced_problem(&system, &op2, &hb)?;
    let x = subharmonic::embed(&contact.multipliers, op.nodes(), contact.harmonics);
    let odd = subharmonic::odd_null_vector(&problem, &x, hb.samples, contact.c)?;
    Ok(Doubled {
        system,
        op: op2,
        hb,
        problem,
        x,
        contact,
        omega,
        odd,
    })
}

/// Each period doubling of `bifurcations` checked on the 2T problem (`BifurcationReport::
/// confirmed`): det J_odd changes sign where a real multiplier of the harmonic-balance model
/// passes −1, so it must change sign somewhere over the rows from the one before the
/// doubling's pair to the one after it (Hill locates the doubling by |μ| between its rows;
/// the 2T problem's crossing may fall in the step on either side). Hill's model freezes the
/// compliance above 10ω at the integer harmonics, while a doubling lives at the half-integer
/// ones, which the 2T problem computes exactly. A doubling that does not check out gets a
/// warning.
pub fn confirm(
    p: &Pipeline,
    model: &Model,
    starts: &[Start],
    bifurcations: &mut [BifurcationReport],
) -> Vec<String> {
    let mut warnings = Vec::new();
    // Rows shared by the windows of neighbouring doublings are formed once.
    let mut at = std::collections::BTreeMap::new();
    for pd in bifurcations
        .iter_mut()
        .filter(|b| b.kind == BifurcationKind::PeriodDoubling)
    {
        let (first, last) = (pd.between[0].saturating_sub(1), pd.between[1] + 1);
        let signs: Vec<f64> = (first..=last)
            .filter_map(|row| {
                *(at.entry(row)).or_insert_with(|| {
                    (doubled_at(p, model, starts, row).ok()).map(|d| d.odd.det_sign)
                })
            })
            .collect();
        pd.confirmed = (signs.len() >= 2).then(|| signs.windows(2).any(|w| w[0] != w[1]));
        if pd.confirmed == Some(false) {
            warnings.push(format!(
                "the period doubling at {:.4} Hz is not confirmed by the 2T problem: the determinant of its odd-harmonic Newton matrix keeps its sign over the rows {first}–{last}, where a real multiplier of the harmonic-balance model through −1 changes it. Hill's multipliers there may depend on the modes they keep dynamic (above H = 10 most harmonics see the compliance it freezes), or the contact set jumps between the rows: check the rows by marching (stability.method: both) or sweep them at another harmonic_balance.harmonics",
                pd.frequency_hz
            ));
        }
    }
    warnings
}

/// The first 2T state at row `row`'s ω: the row's T state embedded in the 2T problem and
/// pushed along φ, J_odd's null vector, by `PUSHES` until a fixed-ω Newton lands on a state
/// with an odd part; the continuation leaves it along that odd part.
fn first_point(p: &Pipeline, model: &Model, starts: &[Start], row: usize) -> Result<FirstPoint> {
    let d = doubled_at(p, model, starts, row)?;
    let (system, op2, hb, problem, x) = (d.system, d.op, d.hb, d.problem, d.x);
    let (phi, least, c, omega) = (d.odd.vector, d.odd.least, d.contact.c, d.omega);
    let newton = crate::hbm::reduced::NewtonSettings {
        samples: hb.samples,
        c,
        tolerance: hb.tolerance,
        max_iterations: 50,
        min_iterations: 1,
        ..Default::default()
    };
    let (silent, size) = (&crate::Silent, norm2(&x));
    let landed = PUSHES.iter().find_map(|push| {
        let pushed: Vec<f64> = (x.iter().zip(&phi))
            .map(|(a, f)| a + push * size * f)
            .collect();
        let o = crate::hbm::reduced::newton(&problem, &newton, &pushed, silent);
        let odd = subharmonic::odd_share(&o.multipliers, hb.harmonics);
        (o.converged && odd > ON_T).then_some(o.multipliers)
    });
    let y = landed.ok_or_else(|| {
        Error::NotConverged(format!(
            "no 2T state at {:.4} Hz along the period doubling's Floquet vector (a fixed-ω \
             Newton from every push returns to the T state; the least eigenvalue of the \
             odd-harmonic Newton matrix is {least:.1e} of its largest entry, near zero at a \
             period doubling of the 2T problem)",
            omega / (2.0 * std::f64::consts::PI)
        ))
    })?;
    let away: Vec<f64> = y.iter().zip(&x).map(|(a, b)| a - b).collect();
    let length = norm2(&away).max(f64::MIN_POSITIVE);
    let force = (c * norm2(&problem.linear_gap)).max(f64::MIN_POSITIVE);
    let state = ContinuationState {
        index: 0,
        omega: system.omega,
        step: crate::config::SweepSpec::default().step,
        tangent: away.iter().map(|a| a / length).chain([0.0]).collect(),
        largest: norm2(&y),
        multipliers: y,
        force_scale: force,
        c,
        samples: hb.samples,
        reduced_frame: false,
        enriched_at: Vec::new(),
        harmonic_first: false,
        trail: Vec::new(),
        max_turn: None,
    };
    Ok(FirstPoint {
        row,
        system,
        op: op2,
        hb,
        state,
    })
}

/// The branch as the continuation walks it: its rows, the states to judge, and where its odd
/// part changed sign.
struct Walk<'a> {
    p: &'a Pipeline,
    model: &'a Model,
    mesh: &'a MeshInfo,
    harmonics: usize,
    rows: Vec<SweepRow>,
    states: Vec<(f64, ContactSolution)>,
    odd: Vec<f64>,
    rejoins: Option<f64>,
}

impl<'a> Walk<'a> {
    fn new(p: &'a Pipeline, (model, mesh): (&'a Model, &'a MeshInfo), h: usize) -> Self {
        Walk {
            p,
            model,
            mesh,
            harmonics: h,
            rows: Vec::new(),
            states: Vec::new(),
            odd: Vec::new(),
            rejoins: None,
        }
    }

    /// One point of the 2T continuation; ends the walk with `Error::Interrupted` where the odd part turns against the last one's.
    fn point(&mut self, info: &PointInfo, solution: &Solution) -> Result<()> {
        let Some(contact) = solution.contact.as_ref() else {
            return Ok(());
        };
        let odd = subharmonic::odd_part(&contact.multipliers, self.harmonics);
        let turned = self.odd.len() == odd.len() && crate::linalg::dot(&odd, &self.odd) < 0.0;
        // The drive frequency, twice the 2T problem's.
        let drive_hz = info.omega / std::f64::consts::PI;
        if turned {
            let last = self.rows.last().map_or(drive_hz, |r| r.frequency_hz);
            self.rejoins = Some(0.5 * (last + drive_hz));
            return Err(Error::Interrupted(
                "the 2T branch rejoined the curve".into(),
            ));
        }
        self.odd = odd;
        let summary = super::point_summary(self.p, self.model, self.mesh, solution);
        let mut row = super::row_of(self.p, &summary, info, solution);
        row.frequency_hz = drive_hz;
        let probe = super::outputs(self.p)
            .iter()
            .position(|o| *o == Output::ProbeFirstHarmonic);
        if let Some(c) = probe {
            row.values[c] = Output::ProbeHarmonic(2).value(&summary, None);
        }
        row.subharmonic = Some(Output::ProbeHarmonic(1).value(&summary, None));
        self.rows.push(row);
        self.states.push((info.omega, contact.clone()));
        Ok(())
    }

    /// Hill's verdict on every row's 2T state.
    fn judge(&mut self, model: &Model, hill: &HillModel) {
        for (row, (omega, contact)) in self.rows.iter_mut().zip(&self.states) {
            let verdict = super::judge_state(model, hill, *omega, contact);
            row.stable = verdict.stable();
            row.multiplier = verdict.multiplier;
            row.argument = verdict.argument;
            row.crossing = verdict.crossing;
        }
    }
}

/// branch_K.csv: sweep.csv's columns and the probe's amplitude at half the drive frequency.
pub fn csv(columns: &[String], b: &Branch) -> String {
    let table = super::rows_csv(columns, &b.rows);
    let mut lines = table.lines();
    let mut text = lines
        .next()
        .map_or(String::new(), |h| format!("{h},subharmonic\n"));
    for (line, r) in lines.zip(&b.rows) {
        let sub = r
            .subharmonic
            .map_or(String::new(), crate::output::tables::csv_number);
        text.push_str(&format!("{line},{sub}\n"));
    }
    text
}
