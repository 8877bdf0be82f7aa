//! Reduced frames: the factorization-free frames of a sweep (docs/method.md, "Reduced
//! frames"). With Rayleigh damping every harmonic at every ω is Z_k(ω) = a K + b M
//! (`System::pencil`), so one reduced model of the pencil (K, M) (`linalg::modal`) gives G_k,
//! the linear gaps and the recovery at any ω of the sweep for the cost of products with
//! r-vectors, where an exact frame factors H + 1 sparse matrices.
//!
//! Glossary and formulas:
//! - W the start block: B's rows and the real and imaginary parts of the loads' parts
//!   (forces; K_fp u_p and M_fp u_p for prescribed motion), one column each;
//! - σ_j ≥ 0 the real shifts: 0, and −q_k at `SHIFTS_PER_HARMONIC` frequencies spread over
//!   the range for every harmonic k ≥ 1; the space is span{(K − σ_j M)⁻¹ W}, grown later by
//!   the exact solves of W at frames where a point failed its check (`enrich_from`);
//! - the check of a kept point: the backward error ‖f_k + Bᵀλ_k − Z_k u_k‖∞ /
//!   (‖Z_k‖∞ ‖u_k‖∞ + ‖f_k + Bᵀλ_k‖∞) of its recovered field, for every harmonic, below
//!   `BACKWARD_TOLERANCE` (`point_backward_error`), the test a factorization's solve passes.
//!
//! The projection interpolates the exact solves at the shifts and is only as good as its
//! space in between, so nothing is trusted unchecked: the caller replaces a point that fails
//! by an exact one and enriches the model there.

use std::sync::Arc;

use faer::c64;
use rayon::prelude::*;

use super::System;
use crate::linalg::modal::{ModalBasis, ModalFactor, ModalSpace};
use crate::linalg::{complex_columns, Csc, Factor};
use crate::Result;

/// The backward error a reduced solve must stay below: the one a factorization's solve is
/// held to (`check_solve`).
pub const BACKWARD_TOLERANCE: f64 = 1e-10;
/// Frequencies over the range at which each harmonic's real shift is placed.
pub const SHIFTS_PER_HARMONIC: usize = 3;

/// A reduced model of Z_k(ω)⁻¹ for ω in a range.
pub struct ReducedModel {
    basis: Arc<ModalBasis>,
    start: Vec<Vec<f64>>,
    space: ModalSpace,
    /// The shifts the space was built from.
    pub shifts: Vec<f64>,
}

impl ReducedModel {
    /// The model for ω in `omegas` and harmonics 0..=`harmonics`: real shifts σ = −q_k at
    /// `frequencies` frequencies spread evenly over the range (one: its start) for every
    /// harmonic k ≥ 1, and σ = 0.
    pub fn build(
        system: &System,
        b: &Csc,
        omegas: (f64, f64),
        frequencies: usize,
        harmonics: usize,
    ) -> Result<ReducedModel> {
        let start = start_block(system, b, harmonics);
        let spread = (0..frequencies).map(|i| {
            let t = i as f64 / frequencies.saturating_sub(1).max(1) as f64;
            omegas.0 + (omegas.1 - omegas.0) * t
        });
        let mut shifts = vec![0.0];
        for w in spread {
            shifts.extend((1..=harmonics).map(|k| -system.pencil_at(k, w).1.re));
        }
        let solves: Vec<Vec<Vec<c64>>> = shifts
            .par_iter()
            .map(|&s| system.pencil_solve((c64::new(1.0, 0.0), c64::new(-s, 0.0)), &start))
            .collect::<Result<_>>()?;
        let mut columns = Vec::new();
        for x in solves {
            push_parts(&mut columns, x);
        }
        let mut space = ModalSpace::default();
        space.extend(&system.k_ff, &system.m_ff, columns);
        Ok(ReducedModel {
            basis: Arc::new(ModalBasis::new(&space, b)?),
            start,
            space,
            shifts,
        })
    }

    /// r, the dimension of the reduced space.
    pub fn dim(&self) -> usize {
        self.basis.dim()
    }

    /// Add the real and imaginary parts of exact solutions (an exact frame's solves) to the
    /// space.
    pub fn enrich(&mut self, system: &System, b: &Csc, solutions: &[Vec<c64>]) -> Result<()> {
        let mut columns = Vec::new();
        push_parts(&mut columns, solutions.to_vec());
        self.space.extend(&system.k_ff, &system.m_ff, columns);
        self.basis = Arc::new(ModalBasis::new(&self.space, b)?);
        Ok(())
    }

    /// Add the exact solves of the start block with an exact frame's factorizations.
    pub fn enrich_from(
        &mut self,
        system: &System,
        b: &Csc,
        factors: &std::collections::BTreeMap<usize, Factor>,
    ) -> Result<()> {
        let rhs = self.start_columns();
        let solutions: Vec<Vec<c64>> = factors
            .par_iter()
            .flat_map_iter(|(_, f)| f.solve_many(&rhs))
            .collect();
        self.enrich(system, b, &solutions)
    }

    /// The reduced solve of Z_k at the system's ω, made with harmonic k's `load`
    /// (`system.load(k)`; `None`: singular on the space).
    pub fn factor(&self, system: &System, k: usize, load: &[c64]) -> Option<ModalFactor> {
        let (a, b) = system.pencil(k);
        self.basis.at(a, b, load)
    }

    /// The start block's columns, complex (the right-hand sides an exact frame solves to
    /// enrich the model).
    pub fn start_columns(&self) -> Vec<Vec<c64>> {
        complex_columns(&self.start)
    }
}

/// W: B's rows and the loads' real and imaginary parts (forces, and K_fp u_p, M_fp u_p for
/// prescribed motion) of the harmonics up to `harmonics`.
fn start_block(system: &System, b: &Csc, harmonics: usize) -> Vec<Vec<f64>> {
    let mut out = b.dense_rows();
    for (_, input) in system.inputs.range(..=harmonics) {
        let mut loads = vec![input.force.clone()];
        if input.motion.iter().any(|z| z.norm() > 0.0) {
            loads.push(system.k_fp.mul_complex(&input.motion));
            loads.push(system.m_fp.mul_complex(&input.motion));
        }
        push_parts(&mut out, loads);
    }
    // A speed that follows ω moves harmonic 0's load along M(x − c).
    if let Some(unit) = system.spin.as_ref().and_then(|s| s.centrifugal.clone()) {
        push_parts(&mut out, vec![unit]);
    }
    out
}

/// The real and imaginary parts of `vectors` that are not zero, as columns.
fn push_parts(columns: &mut Vec<Vec<f64>>, vectors: Vec<Vec<c64>>) {
    for x in vectors {
        for part in [|z: &c64| z.re, |z: &c64| z.im] {
            let v: Vec<f64> = x.iter().map(part).collect();
            if v.iter().any(|x| *x != 0.0) {
                columns.push(v);
            }
        }
    }
}

/// The largest backward error, over the harmonics, of the field a point's multipliers
/// `x` (node-major, `m` coefficients per node) recover with the frame's solves:
/// u_k = z_k + Z_k⁻¹ Bᵀ λ_k against Z_k u_k = f_k + Bᵀ λ_k.
pub(super) fn point_backward_error(
    system: &System,
    op: &crate::contact::ContactOperator,
    linear: &super::LinearResponse,
    x: &[f64],
    m: usize,
) -> f64 {
    linear
        .factors
        .par_iter()
        .map(|(&k, f)| {
            let lam = super::fourier::node_phasors(x, m, k);
            let (mut u, mut rhs) = (linear.free[&k].clone(), system.load(k));
            if let Some((force, dz)) = super::contact_part(op, f, &lam) {
                u.iter_mut().zip(dz).for_each(|(a, b)| *a += b);
                rhs.iter_mut().zip(force).for_each(|(a, b)| *a += b);
            }
            let r = system.residual(k, &u, &rhs);
            super::system::backward_error(system, k, &r, &u, &rhs)
        })
        .reduce(|| 0.0, f64::max)
}
