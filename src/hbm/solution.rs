//! What a harmonic-balance solve returns: the per-harmonic amplitudes of the whole field, the
//! contact multipliers, and how well complementarity holds; evaluated at any instant by
//! `field_at`, `multipliers_at` and `snapshot` (the Fourier convention is `fourier`'s).
//!
//! With a spline basis the map keys are the discrete frequencies j of the spline coefficients
//! and the amplitudes their phasors (ũ_n = Re Σ_j z_j e^{2πijn/S}, `basis`): `field_at`
//! evaluates u(t) = Re Σ_j z_j E_j(t) through the basis' rotor, and `amplitude` returns the
//! Fourier harmonic k of that spline function.

use std::collections::BTreeMap;

use faer::c64;
use schemars::JsonSchema;
use serde::Serialize;

use super::basis::TimeBasis;
use super::reduced::NewtonOutcome;
use crate::fem::DofMap;

/// Wall time per stage of the solve, in seconds.
#[derive(Clone, Debug, Default, Serialize, JsonSchema)]
pub struct Timings {
    pub factor: f64,
    pub linear_solve: f64,
    pub reduce: f64,
    pub newton: f64,
    /// The knob check's re-solves at 2N and at a second c (`KnobCheck`): the cost of knowing the
    /// answer does not hang on N or c, kept apart from the solve's own Newton.
    pub knob_check: f64,
    pub recover: f64,
}

impl std::ops::AddAssign<&Timings> for Timings {
    fn add_assign(&mut self, o: &Timings) {
        self.factor += o.factor;
        self.linear_solve += o.linear_solve;
        self.reduce += o.reduce;
        self.newton += o.newton;
        self.knob_check += o.knob_check;
        self.recover += o.recover;
    }
}

/// How far the Fourier-series λ and g miss complementarity at the samples, each relative to
/// its own scale (the peak contact force, the linear gap range).
#[derive(Clone, Debug, Default, Serialize, JsonSchema)]
pub struct Complementarity {
    /// max(0, g) / gap scale: sampled penetration.
    pub penetration: f64,
    /// max(0, λ) / force scale: sampled adhesion (pulling) force.
    pub adhesion: f64,
    /// max |λ g| / (force scale · gap scale).
    pub product: f64,
    /// The largest of the three.
    pub violation: f64,
    /// Absolute sampled penetration (length).
    pub max_penetration: f64,
    /// The peak sampled |λ| (force).
    pub force_scale: f64,
    /// The peak sampled |r|, the linear gap (length).
    pub gap_scale: f64,
}

/// The contact part of a solution.
#[derive(Clone, Debug)]
pub struct ContactSolution {
    pub harmonics: usize,
    pub samples: usize,
    pub c: f64,
    /// λ coefficients, node-major, 2H+1 per node (`fourier` layout).
    pub multipliers: Vec<f64>,
    /// Gap coefficients g = B u − g0, node-major.
    pub gaps: Vec<f64>,
    pub newton: NewtonOutcome,
    /// The harmonic ladder actually climbed (just [H] when the direct solve converged).
    pub ladder: Vec<usize>,
    /// The damping ratios ζ at the fundamental the damping continuation went through, from
    /// 5% down to the scene's own (empty when it was not needed).
    pub damping_path: Vec<f64>,
    pub complementarity: Complementarity,
    /// The N and c checks (`knobs`).
    pub knob_check: super::knobs::KnobCheck,
    /// G_k, the compliance per harmonic the state was solved with (`ReducedProblem`), for
    /// Hill's method (`hill`); `None` once a caller has no more use for it.
    pub compliance: Option<std::sync::Arc<Vec<Vec<c64>>>>,
    /// The tangential part of a frictional solve (`None`: frictionless).
    pub friction: Option<FrictionSolution>,
    /// How H was chosen within a range (`harmonic_balance.harmonics: {min, max}`); `None`
    /// at a fixed H.
    pub harmonics_chosen: Option<super::adaptive::HarmonicsChosen>,
}

/// The tangential part of a frictional contact solution (`hbm::friction`).
#[derive(Clone, Debug)]
pub struct FrictionSolution {
    /// μ per contact node.
    pub coefficients: Vec<f64>,
    /// λ_t coefficients, node-major (`fourier` layout), the tangential force on the body
    /// along t = ẑ × n.
    pub tangential: Vec<f64>,
    /// w coefficients, the tangential displacement relative to the obstacle.
    pub slips: Vec<f64>,
    /// The largest change of the multipliers from N to 2N, relative to the largest (NaN:
    /// not checked, a sweep's point after the first).
    pub samples_change: f64,
    /// Newton iterations of the frictional solve (after the frictionless one).
    pub iterations: usize,
    /// Shares of (node, sample) pairs open, stuck and slipping at the solver's samples.
    pub shares: [f64; 3],
    /// Peak over the samples of |Σ_i λ_t,i|, the total tangential force [N].
    pub peak_force: f64,
}

impl FrictionSolution {
    /// Energy each node dissipates per period, E_i = −∫ λ_t ẇ dt = −π Σ_k k (α_k b_k − β_k
    /// a_k) for λ_t = Σ α_k cos + β_k sin and w = Σ a_k cos + b_k sin (exact for the
    /// series; independent of ω).
    pub fn dissipation(&self, harmonics: usize) -> Vec<f64> {
        let m = 2 * harmonics + 1;
        (self
            .tangential
            .chunks_exact(m)
            .zip(self.slips.chunks_exact(m)))
        .map(|(l, w)| {
            -std::f64::consts::PI
                * (1..=harmonics)
                    .map(|k| k as f64 * (l[2 * k - 1] * w[2 * k] - l[2 * k] * w[2 * k - 1]))
                    .sum::<f64>()
        })
        .collect()
    }

    /// The index of the contact node that dissipates most per period, and its energy.
    pub fn most_dissipating(&self, harmonics: usize) -> Option<(usize, f64)> {
        let energies = self.dissipation(harmonics);
        (energies.into_iter().enumerate()).max_by(|a, b| a.1.total_cmp(&b.1))
    }
}

/// The detour a contact solve took where the direct one failed, in words (`None`: direct):
/// the damping continuation through the ratios `damping_path`, or the harmonic `ladder`.
/// The one wording of the warning, the run's headline and the benches.
pub fn detour(ladder: &[usize], damping_path: &[f64]) -> Option<String> {
    match (damping_path, ladder.len()) {
        ([first, .., last], _) => Some(format!(
            "continuation in the damping with the smoothing, ζ at the fundamental from {:.1}% \
             down to the scene's {:.2}% in {} steps",
            100.0 * first,
            100.0 * last,
            damping_path.len() - 1
        )),
        (_, 2..) => Some(format!("the harmonic ladder {ladder:?}")),
        _ => None,
    }
}

impl ContactSolution {
    /// The solution a converged Newton found at N = `samples` and `c`, without the knob
    /// checks (a continuation point or a re-solve from a checked solution); the spline
    /// basis' underdamped share, a measure of the solution alone, is kept.
    pub fn unchecked(
        problem: &super::ReducedProblem,
        samples: usize,
        c: f64,
        newton: NewtonOutcome,
    ) -> ContactSolution {
        let x = &newton.multipliers;
        let gaps = problem.gap(x);
        let underdamped_share = super::knobs::underdamped_share(problem, &gaps);
        ContactSolution {
            harmonics: problem.harmonics,
            samples,
            c,
            multipliers: x.clone(),
            complementarity: super::measure_complementarity(problem, x, &gaps, samples),
            gaps,
            ladder: vec![problem.harmonics],
            damping_path: Vec::new(),
            knob_check: super::knobs::KnobCheck {
                samples_initial: samples,
                samples_changes: Vec::new(),
                c_alternative: c,
                c_change: None,
                iterations: 0,
                seconds: 0.0,
                underdamped_share,
            },
            newton,
            compliance: Some(std::sync::Arc::new(problem.compliance.clone())),
            friction: None,
            harmonics_chosen: None,
        }
    }

    /// Coefficients per node, M = 2H + 1.
    pub fn coefficients(&self) -> usize {
        2 * self.harmonics + 1
    }
}

/// The tangential state of the contact nodes at one instant (friction), per node.
#[derive(Clone, Debug)]
pub struct Tangential {
    /// λ_t [N] along t = ẑ × n, the force on the body.
    pub force: Vec<f64>,
    /// ẇ [m/s], the slip velocity relative to the obstacle along t.
    pub velocity: Vec<f64>,
    pub mu: Vec<f64>,
    /// The energy dissipated per period [J].
    pub energy: Vec<f64>,
}

/// The state at one instant of the period, on all dofs.
#[derive(Clone, Debug)]
pub struct Snapshot {
    pub time: f64,
    pub displacement: Vec<f64>,
    pub velocity: Vec<f64>,
    pub acceleration: Vec<f64>,
    /// Contact multipliers λ_i (≤ 0 when pressing), one per contact node.
    pub contact_force: Option<Vec<f64>>,
}

/// A periodic steady state.
#[derive(Clone)]
pub struct Solution {
    pub omega: f64,
    /// The time basis the amplitudes refer to.
    pub basis: TimeBasis,
    /// Harmonic index (spline: discrete frequency) → complex amplitude on the free dofs.
    pub free: BTreeMap<usize, Vec<c64>>,
    /// Harmonic index → prescribed motion amplitudes.
    pub motion: BTreeMap<usize, Vec<c64>>,
    pub contact: Option<ContactSolution>,
    /// Relative residual of each harmonic's linear solve.
    pub residuals: BTreeMap<usize, f64>,
    /// "real" or "complex" factorizations.
    pub complex_arithmetic: bool,
    pub timings: Timings,
    /// Things the user should know although the solve succeeded (near resonance, …).
    pub warnings: Vec<String>,
}

impl Solution {
    pub fn harmonics(&self) -> Vec<usize> {
        self.free.keys().copied().collect()
    }

    /// The period T = 2π/ω.
    pub fn period(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.omega
    }

    /// Displacement (derivative 0), velocity (1) or acceleration (2) at time t on all dofs.
    pub fn field_at(&self, dofs: &DofMap, t: f64, derivative: u32) -> Vec<f64> {
        let mut u = vec![0.0; dofs.total()];
        let rotors = self.rotors(t, derivative);
        for (map, targets) in [(&self.free, &dofs.free), (&self.motion, &dofs.prescribed)] {
            for (&k, z) in map {
                for (i, &d) in targets.iter().enumerate() {
                    u[d] += (z[i] * rotors[k]).re;
                }
            }
        }
        u
    }

    /// `field_at` on the dofs `which` only (its values in that order): what a time history
    /// of a few nodes costs, not the whole field's.
    pub fn field_on(&self, dofs: &DofMap, which: &[usize], t: f64, derivative: u32) -> Vec<f64> {
        let mut u = vec![0.0; which.len()];
        let rotors = self.rotors(t, derivative);
        for (map, index) in [
            (&self.free, dofs.free_map()),
            (&self.motion, dofs.prescribed_map()),
        ] {
            for (&k, z) in map {
                for (u, &d) in u.iter_mut().zip(which) {
                    if let Some(i) = index[d] {
                        *u += (z[i] * rotors[k]).re;
                    }
                }
            }
        }
        u
    }

    /// The basis' rotors E_k^{(d)}(t) for every harmonic (or discrete frequency) stored.
    fn rotors(&self, t: f64, derivative: u32) -> Vec<c64> {
        let count = self
            .free
            .keys()
            .chain(self.motion.keys())
            .max()
            .map_or(0, |k| k + 1);
        self.basis.rotors(count, self.omega, t, derivative)
    }

    /// The complex amplitude of Fourier harmonic k on all dofs (for a spline basis the
    /// harmonic k content of the solution's frequency k; its aliases at k ± lS are left out).
    pub fn amplitude(&self, dofs: &DofMap, k: usize) -> Vec<c64> {
        let content = self.basis.harmonic_content(k);
        let mut z = vec![c64::new(0.0, 0.0); dofs.total()];
        for (map, targets) in [(&self.free, &dofs.free), (&self.motion, &dofs.prescribed)] {
            if let Some(zk) = map.get(&k) {
                for (i, &d) in targets.iter().enumerate() {
                    z[d] = zk[i] * content;
                }
            }
        }
        z
    }

    /// The contact multipliers λ_i(t) (≤ 0 when pressing), one per contact node; `None`
    /// without contact.
    pub fn multipliers_at(&self, t: f64) -> Option<Vec<f64>> {
        let c = self.contact.as_ref()?;
        Some(
            c.multipliers
                .chunks(c.coefficients())
                .map(|coeffs| super::sampler::evaluate(&self.basis, coeffs, self.omega, t))
                .collect(),
        )
    }

    /// With friction: the tangential state at time t per contact node (λ_t, ẇ, μ and the
    /// energy dissipated per period; friction needs the Fourier basis).
    pub fn tangential_at(&self, t: f64) -> Option<Tangential> {
        let c = self.contact.as_ref()?;
        let f = c.friction.as_ref()?;
        let at = |series: &[f64], derivative: usize| -> Vec<f64> {
            (series.chunks(c.coefficients()))
                .map(|coeffs| super::fourier::evaluate(coeffs, self.omega, t)[derivative])
                .collect()
        };
        Some(Tangential {
            force: at(&f.tangential, 0),
            velocity: at(&f.slips, 1),
            mu: f.coefficients.clone(),
            energy: f.dissipation(c.harmonics),
        })
    }

    /// Displacement, velocity, acceleration and contact multipliers at time t.
    pub fn snapshot(&self, dofs: &DofMap, t: f64) -> Snapshot {
        Snapshot {
            time: t,
            displacement: self.field_at(dofs, t, 0),
            velocity: self.field_at(dofs, t, 1),
            acceleration: self.field_at(dofs, t, 2),
            contact_force: self.multipliers_at(t),
        }
    }
}
