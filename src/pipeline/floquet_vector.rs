//! The Floquet vector of an unstable harmonic-balance state as a series for ParaView: how the
//! perturbation that grows away from the state moves the structure.
//!
//! Formulas and glossary (`hbm::hill`): a perturbation grows as Re(e^{st} p(t)), s the leading
//! Floquet exponent (μ = e^{sT}) and p(t) = Σ_j φ_j q̃_j(t) T-periodic, from its real Fourier
//! coefficients p_c (c = 0, cos kωt, sin kωt). The frames show its shape without the growth,
//! u(t) = Re(e^{i Im(s) t} p(t)), at `FRAMES` instants over two drive periods (a period
//! doubling's motion, Im s = ω/2, repeats after 2T with u(t + T) = −u(t)), scaled so that the
//! largest nodal |u| over the frames is 1 (the scale of a linear perturbation is free). Held
//! dofs carry 0.

use std::path::Path;

use faer::c64;

use super::Model;
use crate::hbm::fourier::{cos_index, sin_index};
use crate::hbm::hill::FloquetVector;
use crate::output::{write_pvd, write_vtu, Field};
use crate::Result;

/// Frames over the two periods drawn.
pub const FRAMES: usize = 32;

/// The series file `write` names.
pub const FILE: &str = "floquet.pvd";

/// Write `floquet.pvd` and `floquet_XXXX.vtu` (point field `floquet_vector`) into `dir` for
/// `vector`, of a state at ω [rad/s]; returns the series' file name.
pub fn write(dir: &Path, model: &Model, vector: &FloquetVector, omega: f64) -> Result<String> {
    let period = 2.0 * std::f64::consts::PI / omega;
    let times: Vec<f64> = (0..FRAMES)
        .map(|j| 2.0 * period * j as f64 / FRAMES as f64)
        .collect();
    let coefficients = vector.coefficients();
    let frames: Vec<Vec<f64>> = times
        .iter()
        .map(|&t| shape_at(model, (vector, &coefficients), omega, t))
        .collect();
    let largest = (frames.iter().flat_map(|u| u.chunks(2)))
        .map(|c| c[0].hypot(c[1]))
        .fold(0.0f64, f64::max);
    let scale = if largest > 0.0 { 1.0 / largest } else { 1.0 };
    let mut entries = Vec::with_capacity(FRAMES);
    for (j, (u, t)) in frames.iter().zip(&times).enumerate() {
        let file = format!("floquet_{j:04}.vtu");
        let field = Field {
            name: "floquet_vector".into(),
            components: 3,
            values: u
                .chunks(2)
                .flat_map(|c| [scale * c[0], scale * c[1], 0.0])
                .collect(),
        };
        write_vtu(&dir.join(&file), &model.mesh, &[field], &[])?;
        entries.push((*t, file));
    }
    write_pvd(&dir.join(FILE), &entries)?;
    Ok(FILE.to_string())
}

/// Re(e^{i Im(s) t} p(t)) on every mesh dof (x, y per node; held dofs 0), p's coefficients
/// given (`FloquetVector::coefficients`).
pub fn shape_at(
    model: &Model,
    (vector, coefficients): (&FloquetVector, &[Vec<c64>]),
    omega: f64,
    t: f64,
) -> Vec<f64> {
    let dofs = &model.system.dofs;
    let rotation = c64::new(0.0, vector.exponent.im * t).exp();
    let mut weights = vec![c64::new(1.0, 0.0); 2 * vector.harmonics + 1];
    for k in 1..=vector.harmonics {
        let phase = k as f64 * omega * t;
        weights[cos_index(k)] = c64::new(phase.cos(), 0.0);
        weights[sin_index(k)] = c64::new(phase.sin(), 0.0);
    }
    let mut u = vec![0.0; 2 * model.mesh.nodes.len()];
    for (i, &d) in dofs.free.iter().enumerate() {
        let p: c64 = (coefficients.iter().zip(&weights))
            .map(|(field, w)| field[i] * *w)
            .sum();
        u[d] = (rotation * p).re;
    }
    u
}
