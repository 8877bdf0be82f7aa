//! The time basis of harmonic balance (the note's equation (3), u(t) = Σ_m φ_m(t) ũ_m): the
//! Fourier series of `fourier`, or uniform periodic B-splines, and what the rest of the solver
//! needs from either: the per-frequency symbols of the Gram matrices, the load projection, and
//! the evaluation of a stored solution at any instant (docs/method.md §16).
//!
//! Glossary (T = 2π/ω the period):
//! - p the spline degree (≥ 2, so the basis is C¹ as the note asks), S the number of uniform
//!   segments, h = T/S, x = t/h the time in segments;
//! - B(x) the cardinal B-spline of degree p on [0, p+1]; φ_m(t) = Σ_l B(t/h − m + lS), m = 0..S−1
//!   (periodized; a partition of unity);
//! - Gram matrices (10)–(12): L_K = T⁻¹∫φᵀφ, L_D = T⁻¹∫φᵀφ̇, L_M = −T⁻¹∫φ̇ᵀφ̇ (row = test
//!   function, column = coefficient). On a uniform periodic grid each is circulant,
//!   L[m, m+d] = r_d (indices mod S), built from the unit-spacing integrals
//!   a_d = ∫B(y)B(y−d)dy, b_d = ∫B(y)B'(y−d)dy, c_d = ∫B'(y)B'(y−d)dy (d = −p..p), so
//!   L_K = a/S, L_D = b/T, L_M = −(S/T²) c, all by Gauss–Legendre quadrature exact for
//!   degree 2p;
//! - discrete frequency j = 0..⌊S/2⌋, θ_j = 2πj/S: the circulants' eigenvectors are
//!   e^{iθ_j n}, with eigenvalues â_j = S⁻¹Σ a_d e^{iθd}, b̂_j = T⁻¹Σ b_d e^{iθd} (imaginary),
//!   ĉ_j = −(S/T²)Σ c_d e^{iθd};
//! - the symbols s_j = b̂_j/â_j = iσ_j and q_j = ĉ_j/â_j: Z_j = K + s_j D + q_j M is the
//!   dynamic stiffness of frequency j (Fourier: s_k = ikω, q_k = −(kω)², exactly);
//!   σ_j → jω and q_j → −(jω)² as S grows (the error is O((jωh)^{2p}));
//! - phasor convention (the same as `fourier`'s): the real coefficients are
//!   ũ_n = Re Σ_j z_j e^{iθ_j n}, so u(t) = Re Σ_j z_j E_j(t) with the *rotor*
//!   E_j(t) = Σ_n φ_n(t) e^{iθ_j n} (Fourier: E_k(t) = e^{ikωt});
//! - load factor γ_k = β_k/â_k with β_k = T⁻¹∫φ_0(t) e^{ikωt}dt = S⁻¹((e^{iθ_k} − 1)/(iθ_k))^{p+1}:
//!   the Galerkin projection of Re(F e^{ikωt}) onto the splines has phasor γ_k F at frequency
//!   j = k (for 2k < S), so Z_k z_k = γ_k F; γ_k E_k(t) is the L² projection of e^{ikωt}.

use std::f64::consts::PI;

use faer::c64;

/// The per-frequency symbols of a basis: s = i·`damping`, q = `mass`, so that
/// Z = K + s D + q M, and their rates ∂σ/∂ω, ∂q/∂ω at fixed basis (a sweep's R_ω).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Symbols {
    pub damping: f64,
    pub mass: f64,
    pub damping_rate: f64,
    pub mass_rate: f64,
}

/// The time basis a solve uses.
#[derive(Clone, Debug, Default)]
pub enum TimeBasis {
    /// Harmonics 0..H (`fourier`).
    #[default]
    Fourier,
    /// Uniform periodic B-splines.
    Spline(SplineBasis),
}

impl TimeBasis {
    /// The symbols of frequency k at the angular frequency ω (Fourier: the exact derivative
    /// of e^{ikωt}, s = ikω and q = −(kω)², in the arithmetic `System` always used).
    pub fn symbols(&self, k: usize, omega: f64) -> Symbols {
        match self {
            TimeBasis::Fourier => {
                let (kf, kw) = (k as f64, k as f64 * omega);
                Symbols {
                    damping: kw,
                    mass: -(kw * kw),
                    damping_rate: kf,
                    mass_rate: -2.0 * kf * kf * omega,
                }
            }
            TimeBasis::Spline(s) => s.symbols(k, omega),
        }
    }

    /// γ_k, the factor the Galerkin projection puts on a load of harmonic k (`None`: 1).
    pub fn load_factor(&self, k: usize) -> Option<c64> {
        match self {
            TimeBasis::Fourier => None,
            TimeBasis::Spline(s) => Some(s.load_factor(k)),
        }
    }

    /// E_k^{(d)}(t): the d-th time derivative at t of the function whose frequency-k phasor is
    /// 1, so a stored phasor z contributes Re(z · rotor).
    pub fn rotor(&self, k: usize, omega: f64, t: f64, derivative: u32) -> c64 {
        match self {
            TimeBasis::Fourier => super::fourier::rotor(k, omega, t, derivative),
            TimeBasis::Spline(s) => s.rotor(k, omega, t, derivative),
        }
    }

    /// E_k^{(d)}(t) for k = 0..`count` (see `rotor`).
    pub fn rotors(&self, count: usize, omega: f64, t: f64, derivative: u32) -> Vec<c64> {
        match self {
            TimeBasis::Fourier => (0..count)
                .map(|k| super::fourier::rotor(k, omega, t, derivative))
                .collect(),
            TimeBasis::Spline(s) => s.rotors(count, omega, t, derivative),
        }
    }

    /// T⁻¹∫E_k(t) e^{−ikωt}dt: the Fourier harmonic k of the function whose frequency-k phasor
    /// is 1 (1 for Fourier; S·conj(β_k) for splines, whose other content sits at k ± lS).
    pub fn harmonic_content(&self, k: usize) -> c64 {
        match self {
            TimeBasis::Fourier => c64::new(1.0, 0.0),
            TimeBasis::Spline(s) => s.beta(k).conj() * s.segments as f64,
        }
    }

    /// The key that refines the basis in time (what to raise when the answer is too coarse
    /// in time: more harmonics, or more spline segments).
    pub fn refine_key(&self) -> &'static str {
        match self {
            TimeBasis::Fourier => "harmonic_balance.harmonics",
            TimeBasis::Spline(_) => "harmonic_balance.basis.spline.segments",
        }
    }

    /// For messages and summaries: `fourier` or `spline (degree p, S segments)`.
    pub fn describe(&self) -> String {
        match self {
            TimeBasis::Fourier => "fourier".into(),
            TimeBasis::Spline(s) => {
                format!("spline (degree {}, {} segments)", s.degree, s.segments)
            }
        }
    }
}

/// Uniform periodic B-splines of degree p on S segments, with their Gram matrices' symbols.
#[derive(Clone, Debug)]
pub struct SplineBasis {
    pub degree: usize,
    pub segments: usize,
    /// a_d, b_d, c_d for d = 0..=p (a, c symmetric, b antisymmetric in d).
    integrals: [Vec<f64>; 3],
    /// Per frequency j = 0..=S/2: σ_j/ω and q_j/ω² (dimensionless).
    sigma: Vec<f64>,
    q: Vec<f64>,
}

impl SplineBasis {
    /// Requires degree ≥ 1 and segments ≥ 1 (the config checks the user-facing bounds).
    pub fn new(degree: usize, segments: usize) -> Self {
        let integrals = unit_integrals(degree);
        let mut basis = SplineBasis {
            degree,
            segments,
            integrals,
            sigma: Vec::new(),
            q: Vec::new(),
        };
        let (sigma, q) = (0..=segments / 2).map(|j| basis.unit_symbols(j)).unzip();
        basis.sigma = sigma;
        basis.q = q;
        basis
    }

    /// The number of distinct discrete frequencies, ⌊S/2⌋ + 1.
    pub fn frequencies(&self) -> usize {
        self.segments / 2 + 1
    }

    /// σ_j / (jω): how much of the exact damping symbol jω frequency j keeps (1 at j = 0). The
    /// Galerkin derivative's symbol is odd in θ = 2πj/S, so it falls to 0 at the Nyquist
    /// frequency: cubic splines keep 0.9994 at j = S/4, 0.956 at 3S/8, 0.35 at 0.475 S.
    pub fn damping_ratio(&self, j: usize) -> f64 {
        match j {
            0 => 1.0,
            _ => self.sigma[self.fold(j)] / self.fold(j) as f64,
        }
    }

    /// The circulant symbol Σ_{d=−p..p} r_d e^{iθd} of unit integrals r (0 = a, 1 = b, 2 = c).
    fn circulant_symbol(&self, which: usize, j: usize) -> c64 {
        let theta = 2.0 * PI * j as f64 / self.segments as f64;
        let r = &self.integrals[which];
        let odd = which == 1;
        let mut sum = c64::new(r[0], 0.0);
        for (d, &v) in r.iter().enumerate().skip(1) {
            let (sin, cos) = (theta * d as f64).sin_cos();
            sum += if odd {
                c64::new(0.0, 2.0 * v * sin)
            } else {
                c64::new(2.0 * v * cos, 0.0)
            };
        }
        sum
    }

    /// The eigenvalues (â_j, b̂_j, ĉ_j) of L_K, L_D, L_M at frequency j for period T.
    pub fn eigenvalues(&self, j: usize, period: f64) -> (f64, c64, f64) {
        let s = self.segments as f64;
        let a = self.circulant_symbol(0, j).re / s;
        let b = self.circulant_symbol(1, j) / period;
        let c = -s / (period * period) * self.circulant_symbol(2, j).re;
        (a, b, c)
    }

    /// (σ_j, q_j) at ω = 1 (T = 2π); j = 0 and the Nyquist frequency are exactly (0, ·) and
    /// j = 0 exactly (0, 0): the constant is in the space and its derivatives vanish.
    fn unit_symbols(&self, j: usize) -> (f64, f64) {
        if j == 0 {
            return (0.0, 0.0);
        }
        let (a, b, c) = self.eigenvalues(j, 2.0 * PI);
        let nyquist = 2 * j == self.segments;
        (if nyquist { 0.0 } else { b.im / a }, c / a)
    }

    /// The symbols of frequency k (taken mod S and folded to 0..=S/2) at ω.
    pub fn symbols(&self, k: usize, omega: f64) -> Symbols {
        let j = self.fold(k);
        let (sigma, q) = (self.sigma[j], self.q[j]);
        Symbols {
            damping: sigma * omega,
            mass: q * omega * omega,
            damping_rate: sigma,
            mass_rate: 2.0 * q * omega,
        }
    }

    /// The frequency 0..=S/2 that k aliases to.
    fn fold(&self, k: usize) -> usize {
        let j = k % self.segments;
        j.min(self.segments - j)
    }

    /// β_k = T⁻¹∫φ_0(t) e^{ikωt}dt = S⁻¹((e^{iθ} − 1)/(iθ))^{p+1}, θ = 2πk/S (the Fourier
    /// transform of the cardinal B-spline).
    pub fn beta(&self, k: usize) -> c64 {
        let s = self.segments as f64;
        let theta = 2.0 * PI * k as f64 / s;
        let one = if theta == 0.0 {
            c64::new(1.0, 0.0)
        } else {
            (c64::from_polar(1.0, theta) - 1.0) / c64::new(0.0, theta)
        };
        one.powu(self.degree as u32 + 1) / s
    }

    /// γ_k = β_k/â_k (k < S/2).
    pub fn load_factor(&self, k: usize) -> c64 {
        let (a, _, _) = self.eigenvalues(k, 2.0 * PI);
        self.beta(k) / a
    }

    /// Where t falls: (segment i, local coordinate u ∈ [0, 1)).
    fn locate(&self, omega: f64, t: f64) -> (usize, f64) {
        let x = (t * omega / (2.0 * PI)).rem_euclid(1.0) * self.segments as f64;
        let i = (x.floor() as usize).min(self.segments - 1);
        (i, (x - i as f64).clamp(0.0, 1.0))
    }

    /// E_k^{(d)}(t) = (S/T)^d Σ_{r=0..p} B^{(d)}(u + r) e^{iθ_k(i − r)}.
    pub fn rotor(&self, k: usize, omega: f64, t: f64, derivative: u32) -> c64 {
        let (i, u) = self.locate(omega, t);
        let theta = 2.0 * PI * k as f64 / self.segments as f64;
        let scale = (self.segments as f64 * omega / (2.0 * PI)).powi(derivative as i32);
        let mut sum = c64::new(0.0, 0.0);
        for r in 0..=self.degree {
            let value = cardinal(self.degree, derivative as usize, u + r as f64);
            sum += c64::from_polar(value, theta * (i as f64 - r as f64));
        }
        sum * scale
    }

    /// E_k^{(d)}(t) for k = 0..`count`, the p + 1 B-spline values computed once (what
    /// evaluating a whole series at t needs).
    pub fn rotors(&self, count: usize, omega: f64, t: f64, derivative: u32) -> Vec<c64> {
        let (i, u) = self.locate(omega, t);
        let scale = (self.segments as f64 * omega / (2.0 * PI)).powi(derivative as i32);
        let values: Vec<f64> = (0..=self.degree)
            .map(|r| cardinal(self.degree, derivative as usize, u + r as f64) * scale)
            .collect();
        let s = self.segments as i64;
        (0..count)
            .map(|k| {
                values
                    .iter()
                    .enumerate()
                    .map(|(r, &b)| {
                        let n = ((k as i64) * (i as i64 - r as i64)).rem_euclid(s);
                        c64::from_polar(b, 2.0 * PI * n as f64 / s as f64)
                    })
                    .sum()
            })
            .collect()
    }

    /// φ_m^{(d)}(t) for period T = 2π/ω.
    pub fn value(&self, m: usize, omega: f64, t: f64, derivative: u32) -> f64 {
        let (i, u) = self.locate(omega, t);
        let scale = (self.segments as f64 * omega / (2.0 * PI)).powi(derivative as i32);
        let s = self.segments;
        (0..=self.degree)
            .filter(|&r| (i as i64 - r as i64).rem_euclid(s as i64) as usize == m)
            .map(|r| cardinal(self.degree, derivative as usize, u + r as f64))
            .sum::<f64>()
            * scale
    }

    /// The dense Gram matrices [L_K, L_D, L_M] (S × S, row-major) for period T, assembled
    /// from the circulant rows (for checks and dense fallbacks).
    pub fn gram_matrices(&self, period: f64) -> [Vec<f64>; 3] {
        let s = self.segments;
        let sf = s as f64;
        let scales = [1.0 / sf, 1.0 / period, -sf / (period * period)];
        let mut out = [vec![0.0; s * s], vec![0.0; s * s], vec![0.0; s * s]];
        for (which, matrix) in out.iter_mut().enumerate() {
            let r = &self.integrals[which];
            for m in 0..s {
                for d in -(self.degree as i64)..=self.degree as i64 {
                    let sign = if which == 1 && d < 0 { -1.0 } else { 1.0 };
                    let n = (m as i64 + d).rem_euclid(s as i64) as usize;
                    matrix[m * s + n] += sign * r[d.unsigned_abs() as usize] * scales[which];
                }
            }
        }
        out
    }
}

/// Time samples for the contact terms (22)–(23) with a spline basis: `per_segment`
/// Gauss–Legendre points in each segment (≥ p + 1, so the quadrature of φᵀφ is exact and
/// Q P = I), sample (i, g) at t = (i + u_g) h, n = i·per_segment + g; P (coefficients →
/// samples) and Q = L_K⁻¹ Pᵀ W (samples → coefficients), W_n = w_g/S the weights of T⁻¹∫.
/// In DFT coordinates over the segments both act per frequency j: the samples of the
/// coefficients e^{iθ_j n} are e^{iθ_j i} P̂_j,g with P̂_j,g = Σ_r B(u_g + r) e^{−iθ_j r}, and
/// the projection is Q̂_j y = (S â_j)⁻¹ Σ_g conj(P̂_j,g) w_g y_g.
#[derive(Clone, Debug)]
pub struct SplineSampler {
    pub basis: SplineBasis,
    rule: Vec<(f64, f64)>,
}

impl SplineSampler {
    pub fn new(basis: &SplineBasis, per_segment: usize) -> Self {
        SplineSampler {
            basis: basis.clone(),
            rule: gauss_legendre(per_segment.max(basis.degree + 1)),
        }
    }

    /// N = S · points per segment.
    pub fn samples(&self) -> usize {
        self.basis.segments * self.rule.len()
    }

    /// The Gauss points u_g of one segment, in [0, 1].
    pub fn points(&self) -> Vec<f64> {
        self.rule.iter().map(|&(u, _)| u).collect()
    }

    /// The quadrature weights w_g of one segment's points (summing to 1).
    pub fn weights(&self) -> Vec<f64> {
        self.rule.iter().map(|&(_, w)| w).collect()
    }

    /// The sample instants as fractions of the period.
    pub fn phases(&self) -> Vec<f64> {
        let s = self.basis.segments as f64;
        (0..self.basis.segments)
            .flat_map(|i| self.rule.iter().map(move |&(u, _)| (i as f64 + u) / s))
            .collect()
    }

    /// P̂_j (one entry per point of a segment).
    pub fn sample_symbol(&self, j: usize) -> Vec<c64> {
        let theta = 2.0 * PI * j as f64 / self.basis.segments as f64;
        let p = self.basis.degree;
        self.rule
            .iter()
            .map(|&(u, _)| {
                (0..=p)
                    .map(|r| c64::from_polar(cardinal(p, 0, u + r as f64), -theta * r as f64))
                    .sum()
            })
            .collect()
    }

    /// P: samples of Re Σ_j z_j E_j(t) from the phasors z_j, j = 0..=S/2.
    pub fn to_samples(&self, phasors: &[c64], out: &mut [f64]) {
        let (s, r) = (self.basis.segments, self.rule.len());
        out.iter_mut().for_each(|v| *v = 0.0);
        for (j, &z) in phasors.iter().enumerate() {
            let theta = 2.0 * PI * j as f64 / s as f64;
            let symbol = self.sample_symbol(j);
            for i in 0..s {
                let zi = z * c64::from_polar(1.0, theta * i as f64);
                for (g, ps) in symbol.iter().enumerate() {
                    out[i * r + g] += (zi * ps).re;
                }
            }
        }
    }

    /// Q: the phasors z_j (j = 0..=S/2) of the projection of the samples.
    pub fn to_phasors(&self, samples: &[f64], out: &mut [c64]) {
        let (s, r) = (self.basis.segments, self.rule.len());
        for (j, o) in out.iter_mut().enumerate() {
            let theta = 2.0 * PI * j as f64 / s as f64;
            let symbol = self.sample_symbol(j);
            let mut y = c64::new(0.0, 0.0);
            for i in 0..s {
                let turn = c64::from_polar(1.0, -theta * i as f64);
                for (g, ps) in symbol.iter().enumerate() {
                    y += ps.conj() * (self.rule[g].1 * samples[i * r + g]) * turn;
                }
            }
            let (a, _, _) = self.basis.eigenvalues(j, 2.0 * PI);
            let weight = if j == 0 || 2 * j == s { 1.0 } else { 2.0 };
            *o = y * (weight / (s as f64 * s as f64 * a));
        }
    }

    /// Dense P (N × S, row-major): φ_m at the samples.
    pub fn p_matrix(&self) -> Vec<f64> {
        let s = self.basis.segments;
        let phases = self.phases();
        let mut p = vec![0.0; phases.len() * s];
        for (n, &x) in phases.iter().enumerate() {
            for m in 0..s {
                p[n * s + m] = self.basis.value(m, 1.0, 2.0 * PI * x, 0);
            }
        }
        p
    }

    /// Dense Q = L_K⁻¹ Pᵀ W (S × N, row-major); L_K⁻¹ is the circulant with entries
    /// S⁻¹ Σ_j cos(θ_j (m − l)) / â_j.
    pub fn q_matrix(&self) -> Vec<f64> {
        let s = self.basis.segments;
        let n = self.samples();
        let inverse_row: Vec<f64> = (0..s)
            .map(|d| {
                (0..s)
                    .map(|j| {
                        let (a, _, _) = self.basis.eigenvalues(j, 2.0 * PI);
                        (2.0 * PI * (j * d) as f64 / s as f64).cos() / a
                    })
                    .sum::<f64>()
                    / s as f64
            })
            .collect();
        let p = self.p_matrix();
        let weights: Vec<f64> = (0..n)
            .map(|k| self.rule[k % self.rule.len()].1 / s as f64)
            .collect();
        let mut q = vec![0.0; s * n];
        for m in 0..s {
            for l in 0..s {
                let inv = inverse_row[(l + s - m) % s];
                for k in 0..n {
                    q[m * n + k] += inv * p[k * s + l] * weights[k];
                }
            }
        }
        q
    }
}

/// a_d, b_d, c_d (d = 0..=p) of the cardinal B-spline by Gauss–Legendre on each unit
/// interval of its support, p + 1 points (exact for the degree-2p products).
fn unit_integrals(p: usize) -> [Vec<f64>; 3] {
    let rule = gauss_legendre(p + 1);
    let mut out = [vec![0.0; p + 1], vec![0.0; p + 1], vec![0.0; p + 1]];
    let shifts = (0..=p).flat_map(|d| (0..=p).map(move |cell| (d, cell)));
    for (d, cell) in shifts {
        for &(u, w) in &rule {
            let y = cell as f64 + u;
            let (b, db) = (cardinal(p, 0, y), cardinal(p, 1, y));
            let (bs, dbs) = (cardinal(p, 0, y - d as f64), cardinal(p, 1, y - d as f64));
            out[0][d] += w * b * bs;
            out[1][d] += w * b * dbs;
            out[2][d] += w * db * dbs;
        }
    }
    out
}

/// The d-th derivative of the cardinal B-spline of degree p at x (support [0, p+1)):
/// B_p^{(d)}(x) = Σ_l (−1)^l C(d, l) B_{p−d}(x − l), B_p(x) = (x B_{p−1}(x) + (p+1−x) B_{p−1}(x−1))/p.
pub fn cardinal(p: usize, derivative: usize, x: f64) -> f64 {
    if derivative > p {
        return 0.0;
    }
    if derivative > 0 {
        let mut sum = 0.0;
        let mut binomial = 1.0;
        for l in 0..=derivative {
            let sign = if l % 2 == 0 { 1.0 } else { -1.0 };
            sum += sign * binomial * cardinal(p - derivative, 0, x - l as f64);
            binomial = binomial * (derivative - l) as f64 / (l + 1) as f64;
        }
        return sum;
    }
    if !(0.0..(p + 1) as f64).contains(&x) {
        return 0.0;
    }
    if p == 0 {
        return 1.0;
    }
    let pf = p as f64;
    (x * cardinal(p - 1, 0, x) + (pf + 1.0 - x) * cardinal(p - 1, 0, x - 1.0)) / pf
}

/// The n-point Gauss–Legendre rule on [0, 1]: (point, weight), weights summing to 1.
/// Newton on the Legendre polynomial from Chebyshev guesses (converges to round-off).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut rule = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut derivative = 1.0;
        for _ in 0..100 {
            let (p, dp) = legendre(n, x);
            derivative = dp;
            let step = p / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * derivative * derivative);
        rule.push((0.5 * (1.0 - x), 0.5 * w));
    }
    rule.sort_by(|a, b| a.0.total_cmp(&b.0));
    rule
}

/// P_n(x) and P_n'(x) by the three-term recurrence.
fn legendre(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, dp)
}
