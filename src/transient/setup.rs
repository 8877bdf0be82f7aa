//! From the discrete model (the harmonic-balance `System`, a diagonal mass, the contact
//! operator) to a time-marching problem on the free dofs, and back from free-dof states to
//! all dofs: the set-up every caller of `run_to_periodic` needs, in one place.

use faer::c64;

use super::{ContactRows, Coriolis, TransientProblem};
use crate::contact::ContactOperator;
use crate::hbm::{fourier, System};
use crate::{Error, Result};

/// A force history f(t) on the free dofs.
type Force<'a> = Box<dyn Fn(f64, &mut [f64]) + Sync + 'a>;

/// The model as time marching sees it.
pub struct Marching<'a> {
    system: &'a System,
    contact: Option<&'a ContactOperator>,
    /// Diagonal mass on the free dofs (zero on massless contact dofs).
    pub mass: Vec<f64>,
    /// Free dofs recorded at every step of the last period.
    pub probes: Vec<usize>,
    force: Force<'a>,
}

impl<'a> Marching<'a> {
    /// `mass_diagonal` on all dofs; `probe_nodes` whose x and y dofs are recorded (held dofs
    /// are skipped).
    pub fn new(
        system: &'a System,
        mass_diagonal: &[f64],
        contact: Option<&'a ContactOperator>,
        probe_nodes: &[usize],
    ) -> Result<Self> {
        let dofs = &system.dofs;
        let moving = system
            .inputs
            .values()
            .any(|i| i.motion.iter().any(|z| z.norm() != 0.0));
        if contact.is_some_and(|c| c.b_prescribed.nnz() > 0) && moving {
            return Err(Error::Model(
                "transient mode does not support prescribed motion on contact nodes; hold them \
                 with boundaries.fixed or move the prescribed group"
                    .into(),
            ));
        }
        if contact.is_some_and(|c| c.tangential.as_ref().is_some_and(|t| !t.motion.is_empty())) {
            return Err(Error::Model(
                "time marching with friction against a moving obstacle is not modelled (its \
                 tangential motion); harmonic balance (`hbcontact run`) takes it"
                    .into(),
            ));
        }
        let loads: Vec<(usize, Vec<c64>)> =
            system.inputs.keys().map(|&k| (k, system.load(k))).collect();
        let omega = system.omega;
        let force = move |t: f64, f: &mut [f64]| {
            f.iter_mut().for_each(|v| *v = 0.0);
            for (k, z) in &loads {
                let rot = fourier::rotor(*k, omega, t, 0);
                for (fi, zi) in f.iter_mut().zip(z) {
                    *fi += (zi * rot).re;
                }
            }
        };
        Ok(Marching {
            system,
            contact,
            mass: dofs.free.iter().map(|&d| mass_diagonal[d]).collect(),
            probes: probe_nodes
                .iter()
                .flat_map(|&n| [2 * n, 2 * n + 1])
                .filter_map(|d| dofs.free_index(d))
                .collect(),
            force: Box::new(force),
        })
    }

    /// The period T = 2π/ω.
    pub fn period(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.system.omega
    }

    /// The problem `run_to_periodic` marches.
    pub fn problem(&self) -> TransientProblem<'_> {
        TransientProblem {
            stiffness: &self.system.k_ff,
            mass: &self.mass,
            rayleigh: self.system.rayleigh,
            force: &*self.force,
            contact: self.contact.map(|c| ContactRows {
                b: &c.b_free,
                g0: &c.g0,
                gap_harmonics: &c.gap_harmonics,
                omega: self.system.omega,
                friction: c
                    .tangential
                    .as_ref()
                    .map(|t| (&t.b_free, &t.coefficients[..])),
            }),
            period: self.period(),
            probes: self.probes.clone(),
            initial: None,
            coriolis: self.system.gyroscopic.as_ref().map(|g| Coriolis {
                speed: g.speed,
                pairs: self.node_pairs(),
            }),
            decided: None,
        }
    }

    /// The (x, y) free-dof pairs of the nodes whose two dofs are free.
    fn node_pairs(&self) -> Vec<(usize, usize)> {
        let dofs = &self.system.dofs;
        (0..dofs.free.iter().map(|d| d / 2 + 1).max().unwrap_or(0))
            .filter_map(|n| Some((dofs.free_index(2 * n)?, dofs.free_index(2 * n + 1)?)))
            .collect()
    }

    /// A free-dof state (derivative 0, 1, 2 of u) at time t on all dofs, with the
    /// prescribed motion.
    pub fn to_global(&self, free: &[f64], t: f64, derivative: u32) -> Vec<f64> {
        let dofs = &self.system.dofs;
        let mut u = dofs.scatter_free(free);
        for (&k, input) in &self.system.inputs {
            let f = fourier::rotor(k, self.system.omega, t, derivative);
            for (i, &d) in dofs.prescribed.iter().enumerate() {
                u[d] += (input.motion[i] * f).re;
            }
        }
        u
    }
}
