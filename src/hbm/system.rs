//! The discrete linear system per harmonic: Dirichlet elimination, the dynamic stiffness
//! Z_k = K + s_k (D + G) + q_k M with D = αM + βK and G the gyroscopic (Coriolis) matrix of a
//! rotating frame, G = 2Ω M⊗J (J = [[0, −1], [1, 0]] per node pair, skew: Gᵀ = −G), its
//! factorizations (one symbolic analysis shared by every harmonic), and the harmonic loads,
//! including those that prescribed motion induces.
//!
//! A frame whose speed follows ω (Ω = τω, `Spin`) is built at Ω_ref = τω_ref: K holds
//! K₀ − Ω_ref²M, G holds 2Ω_ref M⊗J and harmonic 0's load the centrifugal force Ω_ref² M(x − c).
//! At another ω the stiffness is K + s M with s = Ω_ref² − Ω², so its Rayleigh damping
//! αM + β(K + sM) moves α by βs; G scales by Ω/Ω_ref; the load gains (Ω² − Ω_ref²) M(x − c).
//! Every harmonic is then Z_k = a K + b M + c G with (`System::coefficients`)
//! a = 1 + iσ_kβ, b = q_k + s + iσ_k(α + βs), c = iσ_k Ω/Ω_ref (s = 0, Ω = Ω_ref otherwise).
//!
//! The symbols s_k = iσ_k, q_k come from the time basis (`basis::TimeBasis::symbols`, their one
//! home): Fourier gives s_k = ikω, q_k = −k²ω² (Z_k = K − k²ω²M + ikωD); a spline basis gives
//! its per-discrete-frequency symbols, and scales loads and prescribed motion by its
//! projection factor γ_k.

use std::collections::BTreeMap;
use std::sync::{Arc, OnceLock};

use faer::c64;

use super::basis::{Symbols, TimeBasis};
use crate::fem::DofMap;
use crate::linalg::schur::{SchurPlan, PIVOT_TOLERANCE};
use crate::linalg::{complex_columns, Csc, Factor, LuPattern, SparseLu, Triplets};
use crate::{Error, Result};

/// Complex amplitudes of one harmonic: x(t) = Re(X e^{ikωt}), X = a − i b for a cos + b sin.
#[derive(Clone, Debug)]
pub struct HarmonicInput {
    /// Nodal forces on the free dofs.
    pub force: Vec<c64>,
    /// Motion of the prescribed dofs.
    pub motion: Vec<c64>,
}

/// K, M (and D) split into free–free and free–prescribed blocks, on one shared pattern.
#[derive(Clone)]
pub struct System {
    pub dofs: DofMap,
    pub omega: f64,
    pub rayleigh: Option<(f64, f64)>,
    pub k_ff: Csc,
    pub m_ff: Csc,
    pub k_fp: Csc,
    pub m_fp: Csc,
    /// The Coriolis matrix G on the free dofs (on K's pattern) and its free–prescribed block,
    /// with the frame's speed Ω: `None` without a Coriolis force. G makes Z_k non-symmetric,
    /// so it is factored by LU only and the pencil of K and M (`pencil`) no longer holds.
    pub gyroscopic: Option<Gyroscopic>,
    /// A rotating frame whose speed follows ω (`None`: a fixed speed, or none).
    pub spin: Option<Spin>,
    /// Harmonic index → load and prescribed motion (only the harmonics the scene excites).
    pub inputs: BTreeMap<usize, HarmonicInput>,
    /// The time basis (Fourier unless `with_basis` says otherwise).
    pub basis: TimeBasis,
    /// The symbolic LU analysis (on first use: a scene whose LDLᵀ passes its checks needs it
    /// only for the resonance check).
    pattern: OnceLock<std::result::Result<LuPattern, String>>,
    /// The Schur-complement plan of G_k = B Z_k⁻¹ Bᵀ and the B it was built for (`None`
    /// plan: B does not allow it), shared by every harmonic and frequency.
    schur: OnceLock<(Csc, Option<Arc<SchurPlan>>)>,
    /// The plan of a plain LDLᵀ (no contact rows kept).
    plain: OnceLock<Arc<SchurPlan>>,
    /// Row sums of |K_ff| and |M_ff| (for ‖Z_k‖∞).
    row_sums: OnceLock<(Vec<f64>, Vec<f64>)>,
}

/// The Coriolis blocks of a rotating frame.
#[derive(Clone)]
pub struct Gyroscopic {
    /// Ω [rad/s] about +z.
    pub speed: f64,
    pub g_ff: Csc,
    pub g_fp: Csc,
}

/// A rotating frame turning τ times per period (Ω = τω), whose matrices were built at
/// Ω_ref = `reference`.
#[derive(Clone, Debug)]
pub struct Spin {
    /// τ, turns per period.
    pub turns: f64,
    /// Ω_ref [rad/s], the speed K, G and the loads were built at.
    pub reference: f64,
    /// Whether K holds the spin softening −Ω_ref²M.
    pub softening: bool,
    /// M(x − c) on the free dofs, the centrifugal force per Ω² (`None`: not simulated).
    pub centrifugal: Option<Vec<c64>>,
}

impl Spin {
    /// Ω at ω.
    pub fn speed(&self, omega: f64) -> f64 {
        self.turns * omega
    }

    /// The stiffness shift s = Ω_ref² − Ω² at ω and ds/dω (zero without spin softening).
    pub(crate) fn shift(&self, omega: f64) -> (f64, f64) {
        match self.softening {
            true => (
                self.reference.powi(2) - self.speed(omega).powi(2),
                -2.0 * self.turns * self.turns * omega,
            ),
            false => (0.0, 0.0),
        }
    }

    /// Ω² − Ω_ref², by which the centrifugal load M(x − c) grows from its built value, at ω,
    /// and its derivative in ω, 2τΩ.
    fn growth(&self, omega: f64) -> (f64, f64) {
        let speed = self.speed(omega);
        (
            speed.powi(2) - self.reference.powi(2),
            2.0 * self.turns * speed,
        )
    }

    /// Ω/Ω_ref at ω and its derivative in ω (G's scale).
    fn scale(&self, omega: f64) -> (f64, f64) {
        (
            self.speed(omega) / self.reference,
            self.turns / self.reference,
        )
    }
}

/// Z_k = a K + b M + c G (G at its reference speed), or the coefficients' rates in ω.
#[derive(Clone, Copy, Debug)]
pub struct Coefficients {
    pub a: c64,
    pub b: c64,
    pub c: c64,
}

/// A right-hand side and its solution.
type Checked = (Vec<c64>, Vec<c64>);

/// Which factorization `System::factor_with` computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FactorPath {
    /// The LDLᵀ where its estimated cost is below the LU's, else the LU.
    Auto,
    /// The LDLᵀ whenever it factors and passes its checks, else the LU.
    Ldlt,
    /// faer's pivoting sparse LU.
    Lu,
}

/// How to factor Z_k: the path and the LDLᵀ's pivot threshold (|d| > this × its column).
#[derive(Clone, Copy, Debug)]
pub struct FactorOptions {
    pub path: FactorPath,
    pub pivot_tolerance: f64,
}

impl Default for FactorOptions {
    fn default() -> Self {
        FactorOptions {
            path: FactorPath::Auto,
            pivot_tolerance: PIVOT_TOLERANCE,
        }
    }
}

impl System {
    pub fn new(
        dofs: DofMap,
        stiffness: &Triplets,
        mass: &Triplets,
        rayleigh: Option<(f64, f64)>,
        omega: f64,
        inputs: BTreeMap<usize, HarmonicInput>,
        gyroscopic: Option<(f64, &Triplets)>,
    ) -> Result<Self> {
        let (nf, np) = (dofs.free.len(), dofs.prescribed.len());
        if nf == 0 {
            return Err(Error::Model(
                "every degree of freedom is held: nothing to solve (check boundaries.fixed)".into(),
            ));
        }
        let k = stiffness.block(dofs.free_map(), dofs.free_map(), nf, nf);
        let m = mass.block(dofs.free_map(), dofs.free_map(), nf, nf);
        let g = gyroscopic.map(|(_, g)| g.block(dofs.free_map(), dofs.free_map(), nf, nf));
        let blocks: Vec<&Csc> = [&k, &m].into_iter().chain(g.as_ref()).collect();
        let mut common = Csc::on_common_pattern(&blocks).into_iter();
        let (k_ff, m_ff) = match (common.next(), common.next()) {
            (Some(k), Some(m)) => (k, m),
            _ => return Err(Error::Model("internal: common pattern".into())),
        };
        let gyroscopic = match (gyroscopic, common.next()) {
            (Some((speed, g)), Some(g_ff)) => Some(Gyroscopic {
                speed,
                g_ff,
                g_fp: g.block(dofs.free_map(), dofs.prescribed_map(), nf, np),
            }),
            _ => None,
        };
        let k_fp = stiffness.block(dofs.free_map(), dofs.prescribed_map(), nf, np);
        let m_fp = mass.block(dofs.free_map(), dofs.prescribed_map(), nf, np);
        Ok(System {
            dofs,
            omega,
            rayleigh,
            k_ff,
            m_ff,
            k_fp,
            m_fp,
            gyroscopic,
            spin: None,
            inputs,
            basis: TimeBasis::Fourier,
            pattern: OnceLock::new(),
            schur: OnceLock::new(),
            plain: OnceLock::new(),
            row_sums: OnceLock::new(),
        })
    }

    /// The same system with a speed that follows ω.
    pub fn with_spin(mut self, spin: Option<Spin>) -> Self {
        self.spin = spin;
        self
    }

    /// The same system as a fixed-speed model at ω (`omega` set; a following speed's
    /// matrices and centrifugal load rebuilt at Ω(ω)), for the consumers that take K, G and
    /// the loads as they stand (time marching).
    pub fn at_frequency(&self, omega: f64) -> System {
        let mut out = self.clone();
        out.omega = omega;
        let Some(spin) = out.spin.take() else {
            return out;
        };
        let (s, _) = spin.shift(omega);
        out.k_ff = self.combination(1.0, s);
        out.k_fp = out.k_fp.plus_scaled(&out.m_fp, s);
        if let Some(g) = out.gyroscopic.as_mut() {
            let (scale, _) = spin.scale(omega);
            g.speed *= scale;
            g.g_ff.values.iter_mut().for_each(|v| *v *= scale);
            g.g_fp.values.iter_mut().for_each(|v| *v *= scale);
        }
        if let (Some(unit), Some(input)) = (&spin.centrifugal, out.inputs.get_mut(&0)) {
            let (grow, _) = spin.growth(omega);
            input
                .force
                .iter_mut()
                .zip(unit)
                .for_each(|(f, u)| *f += u * grow);
        }
        // The caches stand on K's values (row sums) or only its pattern (kept).
        out.row_sums = OnceLock::new();
        out
    }

    /// The same system on another time basis.
    pub fn with_basis(mut self, basis: TimeBasis) -> Self {
        self.basis = basis;
        self
    }

    /// The same system with its damping D scaled by `scale` (the damping continuation's
    /// heavier-damped scenes). The symbolic analyses, which do not depend on D, are shared.
    pub fn with_damping_scaled(&self, scale: f64) -> System {
        System {
            rayleigh: self.rayleigh.map(|(a, b)| (a * scale, b * scale)),
            ..self.clone()
        }
    }

    /// s_k = i·damping and q_k = mass of harmonic (or discrete frequency) k at this ω.
    pub fn symbols(&self, k: usize) -> Symbols {
        self.basis.symbols(k, self.omega)
    }

    /// Z_k = a K + b M: (a, b) = (1 + iσ_kβ, q_k + s + iσ_k(α + βs)) at this ω (Rayleigh
    /// damping keeps every harmonic in the pencil of K and M; a reduced model of it serves
    /// them all). Without the Coriolis matrix (c = 0) this is all of Z_k.
    pub fn pencil(&self, k: usize) -> (c64, c64) {
        self.pencil_at(k, self.omega)
    }

    /// ∂(a, b)/∂ω of `pencil`.
    pub fn pencil_rate(&self, k: usize) -> (c64, c64) {
        let r = self.coefficient_rates(k, self.omega);
        (r.a, r.b)
    }

    /// `pencil` at another ω.
    pub fn pencil_at(&self, k: usize, omega: f64) -> (c64, c64) {
        let c = self.coefficients(k, omega);
        (c.a, c.b)
    }

    /// (a, b, c) of Z_k = a K + b M + c G at ω (the module header's formulas).
    pub fn coefficients(&self, k: usize, omega: f64) -> Coefficients {
        let sym = self.basis.symbols(k, omega);
        let (alpha_s, beta) = self.damping_shifted(&sym, omega);
        let (s, _) = self.shift(omega);
        let (g, _) = self.spin.as_ref().map_or((1.0, 0.0), |sp| sp.scale(omega));
        Coefficients {
            a: c64::new(1.0, sym.damping * beta),
            b: c64::new(sym.mass + s, sym.damping * alpha_s),
            c: c64::new(0.0, sym.damping * g),
        }
    }

    /// ∂(a, b, c)/∂ω of `coefficients`.
    pub fn coefficient_rates(&self, k: usize, omega: f64) -> Coefficients {
        let sym = self.basis.symbols(k, omega);
        let (alpha_s, beta) = self.damping_shifted(&sym, omega);
        let (_, ds) = self.shift(omega);
        let (g, dg) = self.spin.as_ref().map_or((1.0, 0.0), |sp| sp.scale(omega));
        let damping = sym.damping_rate * alpha_s + sym.damping * beta * ds;
        Coefficients {
            a: c64::new(0.0, sym.damping_rate * beta),
            b: c64::new(sym.mass_rate + ds, damping),
            c: c64::new(0.0, sym.damping_rate * g + sym.damping * dg),
        }
    }

    /// (a K + b M)⁻¹ x for real columns `x`: the plain LDLᵀ, or the LU where it fails.
    pub fn pencil_solve(&self, (a, b): (c64, c64), x: &[Vec<f64>]) -> Result<Vec<Vec<c64>>> {
        let re = self.combination(a.re, b.re);
        let im = (a.im != 0.0 || b.im != 0.0).then(|| self.combination(a.im, b.im).values);
        let ldlt = self
            .ldlt_plan(None)
            .and_then(|p| p.factor(&re.values, im.as_deref(), PIVOT_TOLERANCE).ok());
        let factor = match ldlt {
            Some(f) => Factor::Ldlt(f),
            None => self.lu(&re, im.as_deref())?,
        };
        Ok(factor.solve_many(&complex_columns(x)))
    }

    /// ca K + cb M on the pattern K and M share.
    fn combination(&self, ca: f64, cb: f64) -> Csc {
        let mut out = self.k_ff.clone();
        for (v, m) in out.values.iter_mut().zip(&self.m_ff.values) {
            *v = ca * *v + cb * m;
        }
        out
    }

    /// The spin's stiffness shift s and ds/dω at ω (zero without a following speed).
    fn shift(&self, omega: f64) -> (f64, f64) {
        self.spin.as_ref().map_or((0.0, 0.0), |sp| sp.shift(omega))
    }

    /// (α + βs, β) where the damping term acts, else zero: the Rayleigh damping of the
    /// stiffness K + sM at ω.
    fn damping_shifted(&self, sym: &Symbols, omega: f64) -> (f64, f64) {
        let (alpha, beta) = self.damping_at(sym);
        (alpha + beta * self.shift(omega).0, beta)
    }

    /// (α, β) where the damping term acts (s_k ≠ 0), else zero.
    fn damping_at(&self, sym: &Symbols) -> (f64, f64) {
        self.rayleigh
            .filter(|_| sym.damping != 0.0)
            .unwrap_or((0.0, 0.0))
    }

    /// The symbolic analysis of the free-dof pattern (K, M and every Z_k share it).
    pub fn lu_pattern(&self) -> Result<&LuPattern> {
        let analysed = self
            .pattern
            .get_or_init(|| LuPattern::analyse(&self.k_ff).map_err(|e| e.to_string()));
        analysed.as_ref().map_err(|e| Error::Model(e.clone()))
    }

    pub fn free_count(&self) -> usize {
        self.dofs.free.len()
    }

    /// Z_k as (real part, imaginary part on the same pattern); `None` imaginary when undamped
    /// or s_k = 0.
    pub fn dynamic_stiffness(&self, k: usize) -> (Csc, Option<Vec<f64>>) {
        let c = self.coefficients(k, self.omega);
        let sym = self.symbols(k);
        let re = self.combination(c.a.re, c.b.re);
        // σ(βK + α_s M) entry by entry (α_s = α + βs).
        let (alpha, beta) = self.damping_shifted(&sym, self.omega);
        let mut im: Option<Vec<f64>> = self.rayleigh.filter(|_| sym.damping != 0.0).map(|_| {
            self.k_ff
                .values
                .iter()
                .zip(&self.m_ff.values)
                .map(|(kv, mv)| sym.damping * (beta * kv + alpha * mv))
                .collect()
        });
        if let Some(g) = self.gyroscopic.as_ref().filter(|_| c.c.im != 0.0) {
            let im = im.get_or_insert_with(|| vec![0.0; g.g_ff.values.len()]);
            for (v, gv) in im.iter_mut().zip(&g.g_ff.values) {
                *v += c.c.im * gv;
            }
        }
        (re, im)
    }

    /// Factor Z_k once for everything harmonic k needs (docs/method.md §4–§5): the load
    /// solve, the recovery solves and, for a contact B, G_k = B Z_k⁻¹ Bᵀ (`Factor::compliance`).
    /// The complex symmetric LDLᵀ with B's normals kept last where its estimated cost is below
    /// that of an LU with n_c blocked solves, else faer's LU (real when the scene has no
    /// damping or k = 0).
    pub fn factor(&self, k: usize, b: Option<&Csc>) -> Result<Factor> {
        self.factor_with(k, b, &FactorOptions::default())
    }

    /// `factor` on a chosen path. The LDLᵀ is checked after factoring: one solve's backward
    /// error below 1e-12 and, with B, G_k y against B Z_k⁻¹ Bᵀ y refined once, within 1e-11
    /// of its largest entry; a vanishing pivot or a failed check falls back to the LU.
    pub fn factor_with(
        &self,
        k: usize,
        b: Option<&Csc>,
        options: &FactorOptions,
    ) -> Result<Factor> {
        let plan = match options.path {
            // The LDLᵀ needs a symmetric Z_k; the Coriolis matrix is skew.
            _ if self.gyroscopic.is_some() => None,
            FactorPath::Lu => None,
            FactorPath::Auto => self.ldlt_plan(b).filter(|p| p.preferred()),
            FactorPath::Ldlt => self.ldlt_plan(b),
        };
        let (re, im) = self.dynamic_stiffness(k);
        if let Some(plan) = plan {
            if let Ok(f) = plan.factor(&re.values, im.as_deref(), options.pivot_tolerance) {
                let mut f = Factor::Ldlt(f);
                if let Some(checked) = self.factor_is_accurate(k, b, &f) {
                    if let Factor::Ldlt(ldlt) = &mut f {
                        ldlt.checked = Some(checked);
                    }
                    return Ok(f);
                }
            }
        }
        self.lu(&re, im.as_deref())
    }

    /// faer's pivoting LU of the matrix with real part `re` and imaginary part `im` on its
    /// pattern (real when `None`).
    fn lu(&self, re: &Csc, im: Option<&[f64]>) -> Result<Factor> {
        let lu = match im {
            Some(im) => SparseLu::factor_complex(self.lu_pattern()?, re, im)?,
            None => SparseLu::factor_real(self.lu_pattern()?, re)?,
        };
        Ok(Factor::Lu(Box::new(lu)))
    }

    /// The LDLᵀ plan: with B's normals kept (`None` when B does not allow it), or plain.
    fn ldlt_plan(&self, b: Option<&Csc>) -> Option<Arc<SchurPlan>> {
        match b {
            Some(b) => self.schur_plan(b),
            None => {
                Some(Arc::clone(self.plain.get_or_init(|| {
                    Arc::new(SchurPlan::without_contact(&self.k_ff))
                })))
            }
        }
    }

    /// The safety net of a pivot-free factorization (one pass over the factor for both
    /// solves): a solve's normwise backward error below 1e-12, and G_k y against
    /// B Z_k⁻¹ Bᵀ y refined once, within 1e-11 of its largest entry. The Newton works with
    /// G and the recovery (24) with the solves, so a G that lost accuracy (a pivot-free
    /// elimination of a slender body pressed flat) would leave a gap of that error times λ.
    /// The solves checked are the load's (where there is one) and Bᵀy's; without either, an
    /// arbitrary right-hand side's. On success, the load and its solution (an empty pair for
    /// an unloaded harmonic, whose linear response is zero and not solved for).
    fn factor_is_accurate(&self, k: usize, b: Option<&Csc>, f: &Factor) -> Option<Checked> {
        let n = self.free_count();
        let b = b.filter(|b| b.nrows > 0);
        let load = self.load(k);
        let loaded = load.iter().any(|z| z.norm() != 0.0);
        let mut rhs = Vec::new();
        if loaded {
            rhs.push(load);
        } else if b.is_none() {
            rhs.push(
                (0..n)
                    .map(|i| c64::new(1.0 + (i % 5) as f64, (i % 3) as f64 - 1.0))
                    .collect(),
            );
        }
        let nc = b.map_or(0, |b| b.nrows);
        let y: Vec<c64> = (0..nc)
            .map(|j| c64::new(1.0 + (j % 7) as f64 / 7.0, (j % 3) as f64 / 3.0))
            .collect();
        if let Some(b) = b {
            rhs.push(b.mul_transpose_complex(&y));
        }
        let x = f.solve_many(&rhs);
        let mut residuals = Vec::with_capacity(rhs.len());
        for (xi, bi) in x.iter().zip(&rhs) {
            let r = self.residual(k, xi, bi);
            if !(backward_error(self, k, &r, xi, bi) < 1e-12) {
                return None;
            }
            residuals.push(r);
        }
        let checked = Some(match loaded {
            true => (rhs[0].clone(), x[0].clone()),
            false => (Vec::new(), Vec::new()),
        });
        let (Some(b), Some(r), Some(x)) = (b, residuals.last(), x.last()) else {
            return checked;
        };
        // B x refined once: B (x + Z_k⁻¹ r).
        let g = f.compliance(b);
        let direct: Vec<c64> = b
            .mul_complex(x)
            .iter()
            .zip(f.contact_rows_of_solve(b, r))
            .map(|(bx, bd)| bx + bd)
            .collect();
        let scale = direct.iter().fold(0.0f64, |m, z| m.max(z.norm()));
        let agrees = (0..nc).all(|i| {
            let gy: c64 = (0..nc).map(|j| g[i * nc + j] * y[j]).sum();
            (gy - direct[i]).norm() <= 1e-11 * scale
        });
        checked.filter(|_| agrees)
    }

    /// Free the factor memory the LDLᵀ plans keep for reuse (`SchurPlan::release_spare_panels`):
    /// after a single solve, so that the stages after it do not hold it.
    pub fn release_factor_memory(&self) {
        let built = self.schur.get().and_then(|(_, p)| p.as_ref());
        for plan in built.into_iter().chain(self.plain.get()) {
            plan.release_spare_panels();
        }
    }

    /// The Schur plan for this B (built once; a different B gets its own, not kept).
    pub fn schur_plan(&self, b: &Csc) -> Option<Arc<SchurPlan>> {
        let (built_for, plan) = self
            .schur
            .get_or_init(|| (b.clone(), SchurPlan::new(&self.k_ff, b).map(Arc::new)));
        if built_for == b {
            plan.clone()
        } else {
            SchurPlan::new(&self.k_ff, b).map(Arc::new)
        }
    }

    /// r = b − Z_k x.
    pub fn residual(&self, k: usize, x: &[c64], b: &[c64]) -> Vec<c64> {
        let zx = self.apply(k, x);
        b.iter().zip(&zx).map(|(b, a)| b - a).collect()
    }

    /// Z_k x = a K x + b M x, (a, b) = `pencil(k)`, for a complex vector (residual checks),
    /// in one pass over the pattern K and M share: both are symmetric, so row j of each is
    /// its column j, and each entry of x is read where it is needed (no scattered adds).
    pub fn apply(&self, k: usize, x: &[c64]) -> Vec<c64> {
        let (a, b) = self.pencil(k);
        let (kk, mm) = (&self.k_ff, &self.m_ff);
        let zero = c64::new(0.0, 0.0);
        let mut out: Vec<c64> = (0..kk.ncols)
            .map(|j| {
                let range = kk.col_ptr[j]..kk.col_ptr[j + 1];
                let rows = &kk.row_idx[range.clone()];
                let (kv, mv) = (&kk.values[range.clone()], &mm.values[range]);
                let (mut kx, mut mx) = (zero, zero);
                for ((&r, &kp), &mp) in rows.iter().zip(kv).zip(mv) {
                    kx += x[r] * kp;
                    mx += x[r] * mp;
                }
                a * kx + b * mx
            })
            .collect();
        // G is not symmetric: its own product, not the column gather above.
        if let Some(g) = &self.gyroscopic {
            let s = self.coefficients(k, self.omega).c;
            let gx = g.g_ff.mul_complex(x);
            for (o, v) in out.iter_mut().zip(gx) {
                *o += s * v;
            }
        }
        out
    }

    /// ∂Z_k/∂ω x + ∂Z_k,fp/∂ω u_p with ∂Z_k/∂ω = (∂q_k/∂ω) M + i(∂σ_k/∂ω)(αM + βK + G) (Fourier:
    /// −2k²ω M + ik(αM + βK)): how the dynamic stiffness of harmonic k acting on the state
    /// changes with ω (the sweep's R_ω).
    pub fn omega_derivative(&self, k: usize, x: &[c64], motion: &[c64]) -> Vec<c64> {
        let mut out = self.pencil_rate_times(k, true, x);
        if let Some(fp) = self.input_rate(k, motion) {
            for (o, v) in out.iter_mut().zip(fp) {
                *o += v;
            }
        }
        out
    }

    /// The inputs' part of `omega_derivative`, ∂Z_k,fp/∂ω u_p − ∂f_k/∂ω (the prescribed
    /// motion, and the centrifugal force of a speed that follows ω); `None` when neither
    /// moves with ω.
    pub fn input_rate(&self, k: usize, motion: &[c64]) -> Option<Vec<c64>> {
        let moves = motion.iter().any(|z| z.norm() > 0.0);
        let mut out = moves.then(|| self.pencil_rate_times(k, false, motion));
        if let Some((unit, (_, rate))) = self.centrifugal(k) {
            let gamma = self.basis.load_factor(0).unwrap_or(c64::new(1.0, 0.0));
            let rate = rate * gamma;
            let out = out.get_or_insert_with(|| vec![c64::new(0.0, 0.0); unit.len()]);
            out.iter_mut().zip(unit).for_each(|(o, u)| *o -= u * rate);
        }
        out
    }

    /// Harmonic k's centrifugal load per Ω², M(x − c), and `Spin::growth` at this ω, where a
    /// following speed moves it (harmonic 0 only).
    fn centrifugal(&self, k: usize) -> Option<(&[c64], (f64, f64))> {
        let spin = self.spin.as_ref().filter(|_| k == 0)?;
        let unit = spin.centrifugal.as_deref()?;
        Some((unit, spin.growth(self.omega)))
    }

    /// (a' K + b' M + c' G) x with the free–free blocks (`free`) or the free–prescribed
    /// ones, (a', b', c') = `coefficient_rates`.
    fn pencil_rate_times(&self, k: usize, free: bool, x: &[c64]) -> Vec<c64> {
        let (kk, mm) = match free {
            true => (&self.k_ff, &self.m_ff),
            false => (&self.k_fp, &self.m_fp),
        };
        let r = self.coefficient_rates(k, self.omega);
        let sym = self.symbols(k);
        let (alpha, beta) = self.damping_shifted(&sym, self.omega);
        // r.b = (q_k' + s') + i(σ_k'α_s + σ_kβs'): the σ_kβs' term (zero without a following
        // speed) apart, so the products keep the order they had before it.
        let extra = c64::new(0.0, sym.damping * beta * self.shift(self.omega).1);
        let (kx, mx) = (kk.mul_complex(x), mm.mul_complex(x));
        let mut out: Vec<c64> = kx
            .iter()
            .zip(&mx)
            .map(|(&kv, &mv)| {
                let v = mv * r.b.re + c64::new(0.0, sym.damping_rate) * (kv * beta + mv * alpha);
                v + extra * mv
            })
            .collect();
        if let Some(g) = &self.gyroscopic {
            let block = if free { &g.g_ff } else { &g.g_fp };
            for (o, v) in out.iter_mut().zip(block.mul_complex(x)) {
                *o += r.c * v;
            }
        }
        out
    }

    /// The right-hand side of harmonic k: f_k − Z_k,fp u_p,k, times the basis' load factor γ_k
    /// (splines: the Galerkin projection of the load; `motion` is scaled alike).
    pub fn load(&self, k: usize) -> Vec<c64> {
        let nf = self.free_count();
        let Some(input) = self.inputs.get(&k) else {
            return vec![c64::new(0.0, 0.0); nf];
        };
        let mut rhs = input.force.clone();
        if let Some((unit, (grow, _))) = self.centrifugal(k) {
            rhs.iter_mut().zip(unit).for_each(|(r, u)| *r += u * grow);
        }
        if input.motion.iter().any(|z| z.norm() > 0.0) {
            let c = self.coefficients(k, self.omega);
            let sym = self.symbols(k);
            let (alpha, beta) = self.damping_shifted(&sym, self.omega);
            let u = &input.motion;
            let (re, im): (Vec<f64>, Vec<f64>) = u.iter().map(|z| (z.re, z.im)).unzip();
            let (kr, ki) = (self.k_fp.mul_vec(&re), self.k_fp.mul_vec(&im));
            let (mr, mi) = (self.m_fp.mul_vec(&re), self.m_fp.mul_vec(&im));
            let q = c.b.re;
            for i in 0..nf {
                let real = c64::new(kr[i] + q * mr[i], ki[i] + q * mi[i]);
                let damp = c64::new(beta * kr[i] + alpha * mr[i], beta * ki[i] + alpha * mi[i]);
                rhs[i] -= real + c64::new(0.0, sym.damping) * damp;
            }
            if let Some(g) = &self.gyroscopic {
                let gu = g.g_fp.mul_complex(u);
                for (r, v) in rhs.iter_mut().zip(gu) {
                    *r -= c.c * v;
                }
            }
        }
        if let Some(gamma) = self.basis.load_factor(k) {
            rhs.iter_mut().for_each(|v| *v *= gamma);
        }
        rhs
    }

    /// An upper bound of ‖Z_k‖∞ from the row sums of |K| and |M| (summed once).
    pub fn norm_inf(&self, k: usize) -> f64 {
        let c = self.coefficients(k, self.omega);
        let (rk, rm) = self.row_sums.get_or_init(|| {
            let n = self.k_ff.nrows;
            let (mut rk, mut rm) = (vec![0.0; n], vec![0.0; n]);
            for j in 0..self.k_ff.ncols {
                for p in self.k_ff.col_ptr[j]..self.k_ff.col_ptr[j + 1] {
                    rk[self.k_ff.row_idx[p]] += self.k_ff.values[p].abs();
                    rm[self.m_ff.row_idx[p]] += self.m_ff.values[p].abs();
                }
            }
            (rk, rm)
        });
        // |G| has M's row sums times 2|Ω_ref| (G = 2Ω_ref M⊗J).
        let gyro = self
            .gyroscopic
            .as_ref()
            .map_or(0.0, |g| 2.0 * g.speed.abs());
        let l1 = |z: c64| z.re.abs() + z.im.abs();
        let (ca, cm) = (l1(c.a), l1(c.b) + c.c.im.abs() * gyro);
        rk.iter()
            .zip(rm)
            .map(|(rk, rm)| rk * ca + rm * cm)
            .fold(0.0, f64::max)
    }

    /// Prescribed motion amplitudes of harmonic k (zero when not excited), in the basis'
    /// phasors (times γ_k for splines).
    pub fn motion(&self, k: usize) -> Vec<c64> {
        let mut motion = self
            .inputs
            .get(&k)
            .map(|i| i.motion.clone())
            .unwrap_or_else(|| vec![c64::new(0.0, 0.0); self.dofs.prescribed.len()]);
        if let Some(gamma) = self.basis.load_factor(k) {
            motion.iter_mut().for_each(|v| *v *= gamma);
        }
        motion
    }
}

/// Normwise backward error ‖Z x − b‖∞ / (‖Z‖∞ ‖x‖∞ + ‖b‖∞) (Higham, Accuracy and Stability
/// of Numerical Algorithms, §7.1): what a backward-stable LU guarantees to be at round-off,
/// however ill-conditioned Z is (a residual relative to ‖b‖ alone is not, for slender parts
/// on fine meshes).
pub fn relative_residual(system: &System, k: usize, x: &[c64], b: &[c64]) -> f64 {
    backward_error(system, k, &system.residual(k, x, b), x, b)
}

/// ‖r‖∞ / (‖Z_k‖∞ ‖x‖∞ + ‖b‖∞) for the residual r = b − Z_k x already formed.
pub fn backward_error(system: &System, k: usize, r: &[c64], x: &[c64], b: &[c64]) -> f64 {
    let r = r.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let bn = b.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let xn = x.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let den = system.norm_inf(k) * xn + bn;
    if den > 0.0 {
        r / den
    } else {
        r
    }
}

/// ‖K‖∞ ‖x‖∞ / ‖b‖∞: how far the solution exceeds what the load alone explains; enormous
/// values mean a (numerically) singular matrix.
pub fn amplification(system: &System, x: &[c64], b: &[c64]) -> f64 {
    let bn = b.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let xn = x.iter().map(|z| z.norm()).fold(0.0, f64::max);
    if bn > 0.0 {
        system.norm_inf(0) * xn / bn
    } else {
        0.0
    }
}
