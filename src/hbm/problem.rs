//! The contact problem reduced to the contact nodes' multipliers λ: the compliance
//! G_k = B Z_k⁻¹ Bᵀ of each harmonic (or a spline basis' discrete frequency) k and the linear
//! gap r, so that the gap is g = G λ + r (docs/method.md (23)). The Newton that solves it
//! lives in `reduced`, its step in `step`.
//!
//! Glossary: nc contact nodes, H the highest harmonic, M = 2H + 1 real coefficients per node
//! in `fourier`'s layout, unknowns node-major (x[i·M + m] is coefficient m of node i).

use faer::c64;

use super::basis::TimeBasis;
use super::fourier::{harmonic_of, phasor, set_phasor};
use super::sampler::ContactSampler;

/// G (per harmonic, complex, nc × nc row-major) and r (node-major coefficients).
#[derive(Clone, Debug)]
pub struct ReducedProblem {
    pub nodes: usize,
    pub harmonics: usize,
    /// `compliance[k][i * nodes + j]` = (B Z_k⁻¹ Bᵀ)_ij.
    pub compliance: Vec<Vec<c64>>,
    /// Linear gap coefficients r = B z_lin − g0 δ_k0 (node-major, 2H+1 per node).
    pub linear_gap: Vec<f64>,
    /// The time basis whose frequencies 0..H the coefficients are phasors of (splines:
    /// H = ⌊S/2⌋ for the full space, fewer on a ladder rung).
    pub basis: TimeBasis,
}

impl ReducedProblem {
    pub fn coefficients(&self) -> usize {
        2 * self.harmonics + 1
    }

    /// A Fourier problem with G_k[i, j] = `entry(k, i, j)` and no linear gap (for tests and
    /// benchmarks of the products with G).
    pub fn from_compliance(
        nodes: usize,
        harmonics: usize,
        entry: impl Fn(usize, usize, usize) -> c64,
    ) -> ReducedProblem {
        ReducedProblem {
            nodes,
            harmonics,
            compliance: (0..=harmonics)
                .map(|k| {
                    (0..nodes * nodes)
                        .map(|r| entry(k, r / nodes, r % nodes))
                        .collect()
                })
                .collect(),
            linear_gap: vec![0.0; nodes * (2 * harmonics + 1)],
            basis: TimeBasis::Fourier,
        }
    }

    /// The contact sampler of this problem's basis and frequencies at N = `samples`.
    pub fn sampler(&self, samples: usize) -> ContactSampler {
        ContactSampler::new(&self.basis, self.harmonics, samples)
    }

    /// The same problem keeping harmonics 0..=h only.
    pub fn truncate(&self, h: usize) -> ReducedProblem {
        let (m_old, m_new) = (self.coefficients(), 2 * h + 1);
        let mut r = vec![0.0; self.nodes * m_new];
        for i in 0..self.nodes {
            r[i * m_new..(i + 1) * m_new]
                .copy_from_slice(&self.linear_gap[i * m_old..i * m_old + m_new]);
        }
        ReducedProblem {
            nodes: self.nodes,
            harmonics: h,
            compliance: self.compliance[..=h].to_vec(),
            linear_gap: r,
            basis: self.basis.clone(),
        }
    }

    /// g = G x + r.
    pub fn gap(&self, x: &[f64]) -> Vec<f64> {
        let mut g = Vec::new();
        self.gap_into(x, &mut g, &mut Vec::new());
        g
    }

    /// `gap` into `g`, with `compliance_product`'s `scratch`.
    pub fn gap_into(&self, x: &[f64], g: &mut Vec<f64>, scratch: &mut Vec<c64>) {
        g.resize(self.linear_gap.len(), 0.0);
        self.compliance_product(x, g, scratch);
        for (gi, ri) in g.iter_mut().zip(&self.linear_gap) {
            *gi += ri;
        }
    }

    /// out = G x (the gap without its linear part), harmonic by harmonic: y_k = G_k λ_k by
    /// faer's complex matrix–vector product (its SIMD kernels: 1.5× a dot product per row at
    /// n_c = 9, 2.3–2.5× at 63–151 nodes, `cargo bench --bench goals -- products`), with
    /// faer's global parallelism (both cores for a run, one inside a study's parallel points)
    /// from 2¹⁶ entries, where one harmonic's product takes tens of µs (most of a GMRES
    /// iteration on the 601-node half-disc).
    /// `scratch` holds one harmonic's phasors of x and of y (resized to 2 n_c), so a caller in
    /// a loop allocates it once.
    pub fn compliance_product(&self, x: &[f64], out: &mut [f64], scratch: &mut Vec<c64>) {
        use faer::linalg::matmul::matmul;
        use faer::{Accum, MatMut, MatRef, Par};
        let (nc, m) = (self.nodes, self.coefficients());
        out.fill(0.0);
        scratch.resize(2 * nc, c64::new(0.0, 0.0));
        let (lam, y) = scratch.split_at_mut(nc);
        let par = if nc * nc >= 1 << 16 {
            faer::get_global_parallelism()
        } else {
            Par::Seq
        };
        for (k, gk) in self.compliance.iter().enumerate() {
            for (j, l) in lam.iter_mut().enumerate() {
                *l = phasor(&x[j * m..(j + 1) * m], k);
            }
            matmul(
                MatMut::from_column_major_slice_mut(y, nc, 1),
                Accum::Replace,
                MatRef::from_row_major_slice(gk, nc, nc),
                MatRef::from_column_major_slice(lam, nc, 1),
                c64::new(1.0, 0.0),
                par,
            );
            for (i, yi) in y.iter().enumerate() {
                set_phasor(&mut out[i * m..(i + 1) * m], k, *yi);
            }
        }
    }

    /// Real-form entry of G between coefficient `a` of node i and coefficient `b` of node j
    /// (zero unless both belong to the same harmonic).
    pub(super) fn real_entry(&self, i: usize, a: usize, j: usize, b: usize) -> f64 {
        let (ka, kb) = (harmonic_of(a), harmonic_of(b));
        if ka != kb {
            return 0.0;
        }
        let gij = self.compliance[ka][i * self.nodes + j];
        if ka == 0 {
            return gij.re;
        }
        match (a % 2 == 1, b % 2 == 1) {
            (true, true) | (false, false) => gij.re,
            (true, false) => gij.im,
            (false, true) => -gij.im,
        }
    }
}
