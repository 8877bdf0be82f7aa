//! What an explicit march will cost, estimated before it allocates anything, and refused when
//! the machine cannot pay it.
//!
//! The central-difference step with stiffness damping (the marching's `time_step`):
//!
//!   ξ = β ω_max / 2,   Δt = C (2/ω_max) (√(1 + ξ²) − ξ)   (≈ 2C / (β ω_max²) once ξ ≫ 1),
//!   N = s ⌈T / (Δt s)⌉ steps per period,   N P steps at most,
//!   bytes ≈ 8 [N (p + 1) + s (3n + c) + 14n + 2 nnz(K) + 3z² + cz + 2c²].
//!
//! Glossary: ω_max the largest natural frequency of M⁻¹K (rad/s, power iteration, +5%);
//! β the stiffness-proportional damping (`damping.beta`, s); C the Courant factor
//! (`transient.courant`); T the period (s); s the samples per period (`output.frames`);
//! P the most periods marched (`transient.max_periods`, `stability.max_periods`); n the
//! free dofs, c the contact rows, z the massless dofs, p the probe dofs. The N (p + 1)
//! term is the last period's probe and contact-force histories, s (3n + c) its sampled
//! states, the rest the march's state (with the end state of its last whole period), K's
//! product and the contact condensation.
//!
//! A march is refused (`Error::Input`, exit 2) when N > `MAX_STEPS_PER_PERIOD`,
//! N P > `MAX_STEPS` or the bytes exceed half the memory the kernel reports available
//! (`MemAvailable` of /proc/meminfo; `FALLBACK_MEMORY` where it cannot be read).

use super::TransientSettings;
use crate::{Error, Result};

/// The most steps a period may take (10⁷: a period's probe histories stay below 100 MB per
/// probe dof, and one period at a microsecond a step takes ten seconds).
pub const MAX_STEPS_PER_PERIOD: f64 = 1e7;

/// The most steps a march may take over all its periods (10¹⁰: hours at a microsecond a
/// step).
pub const MAX_STEPS: f64 = 1e10;

/// The memory assumed available where /proc/meminfo cannot be read (4 GiB).
pub const FALLBACK_MEMORY: f64 = 4.0 * 1024.0 * 1024.0 * 1024.0;

/// The sizes of a march that its memory grows with.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sizes {
    /// Free dofs.
    pub free: usize,
    /// Contact rows.
    pub contact_rows: usize,
    /// Massless (condensed) dofs.
    pub massless: usize,
    /// Probe dofs recorded at every step of the last period.
    pub probes: usize,
    /// Stored entries of K.
    pub stiffness_entries: usize,
}

/// The estimate of one march.
#[derive(Clone, Debug)]
pub struct Estimate {
    pub omega_max: f64,
    pub beta: f64,
    pub courant: f64,
    pub period: f64,
    /// The stable step before it is fitted to the period.
    pub dt: f64,
    pub samples: usize,
    pub max_periods: usize,
    /// N (a float: it may exceed any integer).
    pub steps_per_period: f64,
    /// N P.
    pub steps: f64,
    pub bytes: f64,
    /// The part of `bytes` the sampled states take, 8 s (3n + c).
    pub sampled_bytes: f64,
}

/// The limits a march is held to.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    pub steps_per_period: f64,
    pub steps: f64,
    pub bytes: f64,
    /// Whether `bytes` came from /proc/meminfo.
    pub measured: bool,
}

impl Limits {
    /// The fixed step caps and half the memory this machine has available now.
    pub fn of_machine() -> Self {
        let available = available_memory();
        Limits {
            steps_per_period: MAX_STEPS_PER_PERIOD,
            steps: MAX_STEPS,
            bytes: available.unwrap_or(FALLBACK_MEMORY) / 2.0,
            measured: available.is_some(),
        }
    }
}

/// `MemAvailable` of /proc/meminfo in bytes (`None` where it cannot be read).
pub fn available_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_available(&text)
}

/// The `MemAvailable:  N kB` line of a /proc/meminfo text, in bytes.
fn parse_mem_available(text: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_whitespace().skip(1);
    let kb: f64 = words.next()?.parse().ok()?;
    (words.next() == Some("kB") && kb.is_finite()).then_some(kb * 1024.0)
}

impl Estimate {
    /// The estimate for a march with ω_max, β and the period of `settings`' samples.
    pub fn new(
        omega_max: f64,
        beta: f64,
        period: f64,
        settings: &TransientSettings,
        sizes: Sizes,
    ) -> Self {
        let xi = beta * omega_max / 2.0;
        // √(1 + ξ²) − ξ without the cancellation that makes it 0 for a large ξ.
        let dt = settings.courant * (2.0 / omega_max) / ((1.0 + xi * xi).sqrt() + xi);
        let s = settings.samples_per_period.max(1);
        let steps_per_period = ((period / dt) / s as f64).ceil().max(1.0) * s as f64;
        let f = |v: usize| v as f64;
        let Sizes {
            free: n,
            contact_rows: c,
            massless: z,
            probes: p,
            stiffness_entries: k,
        } = sizes;
        let words = steps_per_period * (f(p) + 1.0)
            + f(s) * (3.0 * f(n) + f(c))
            + 14.0 * f(n)
            + 2.0 * f(k)
            + 3.0 * f(z) * f(z)
            + f(c) * f(z)
            + 2.0 * f(c) * f(c);
        Estimate {
            omega_max,
            beta,
            courant: settings.courant,
            period,
            dt,
            samples: s,
            max_periods: settings.max_periods,
            steps_per_period,
            steps: steps_per_period * f(settings.max_periods.max(1)),
            bytes: 8.0 * words,
            sampled_bytes: 8.0 * f(s) * (3.0 * f(n) + f(c)),
        }
    }

    /// (steps per period, steps per sample) when within `limits`, else the refusal naming the
    /// estimate and what to change.
    pub fn admit(&self, limits: &Limits) -> Result<(usize, usize)> {
        let finite = self.steps_per_period.is_finite() && self.bytes.is_finite();
        let over = !finite
            || self.steps_per_period > limits.steps_per_period
            || self.steps > limits.steps
            || self.bytes > limits.bytes;
        if over {
            return Err(Error::Input(self.refusal(limits)));
        }
        let steps = self.steps_per_period as usize;
        Ok((steps, steps / self.samples))
    }

    /// The refusal: the estimate, the limits and the change that would bring it within them.
    fn refusal(&self, limits: &Limits) -> String {
        let memory = if limits.measured {
            "half the memory available"
        } else {
            "/proc/meminfo unreadable: a fixed cap"
        };
        format!(
            "time marching refused before it started: it would take an estimated {} steps per period \
             (Δt = {:.2e} s, the stable explicit step for ω_max = {:.2e} rad/s with transient.courant = {} and \
             damping.beta = {:e} s; period {:.3e} s), up to {} steps over at most {} periods, and about {} of memory; \
             the limits are {:.0e} steps per period, {:.0e} steps and {} ({memory}). {}",
            count(self.steps_per_period),
            self.dt,
            self.omega_max,
            self.courant,
            self.beta,
            self.period,
            count(self.steps),
            self.max_periods.max(1),
            human_bytes(self.bytes),
            limits.steps_per_period,
            limits.steps,
            human_bytes(limits.bytes),
            self.advice(limits)
        )
    }

    /// What to change, the cause first.
    fn advice(&self, limits: &Limits) -> String {
        let xi = self.beta * self.omega_max / 2.0;
        let mut advice = Vec::new();
        if xi > 1.0 {
            advice.push(format!(
                "lower damping.beta: β ω_max = {:.1e} > 2 shortens the explicit step to about 2·courant/(β ω_max²)",
                2.0 * xi
            ));
        } else {
            advice.push(
                "the step follows the smallest element and the period the frequency: a coarser \
                 mesh or a higher harmonic_balance.frequency take fewer steps"
                    .to_string(),
            );
        }
        if self.steps > limits.steps && self.steps_per_period <= limits.steps_per_period {
            advice.push(
                "march fewer periods (transient.max_periods; stability.max_periods for the stability check of `run`)"
                    .into(),
            );
        }
        if self.bytes > limits.bytes && self.sampled_bytes > 0.5 * self.bytes {
            advice.push("write fewer samples per period (output.frames)".into());
        }
        let text = advice.join("; or ");
        let mut chars = text.chars();
        chars
            .next()
            .map_or(String::new(), |c| c.to_uppercase().chain(chars).collect())
    }
}

/// A count as "1.64e10" ("more than 1e308" beyond any float).
fn count(n: f64) -> String {
    if n.is_finite() {
        format!("{n:.2e}")
    } else {
        "more than 1e308".into()
    }
}

/// Bytes with three significant digits in decimal units: "131 GB", "4.25 MB".
pub fn human_bytes(bytes: f64) -> String {
    const UNITS: [&str; 6] = ["B", "kB", "MB", "GB", "TB", "PB"];
    if !bytes.is_finite() {
        return "more than 1e308 B".into();
    }
    let mut value = bytes;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < UNITS.len() {
        value /= 1000.0;
        unit += 1;
    }
    let decimals = if value >= 100.0 {
        0
    } else if value >= 10.0 {
        1
    } else {
        2
    };
    format!("{value:.decimals$} {}", UNITS[unit])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(samples: usize, max_periods: usize) -> TransientSettings {
        TransientSettings {
            courant: 0.8,
            periodic_tolerance: 1e-7,
            max_periods,
            samples_per_period: samples,
        }
    }

    /// TEST GOAL: /proc/meminfo's MemAvailable line is read in kB and turned into bytes; a
    /// text without it, or with a unit other than kB, gives nothing (the fixed cap applies).
    #[test]
    fn mem_available_is_read_in_kilobytes_and_anything_else_is_refused() {
        let text = "MemTotal:  24683656 kB\nMemAvailable:   1000 kB\n";
        assert_eq!(parse_mem_available(text), Some(1_024_000.0));
        assert_eq!(parse_mem_available("MemTotal: 5 kB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: 5 MB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: x kB\n"), None);
    }

    /// TEST GOAL: without damping the estimate is C·2/ω_max per step, fitted up to a whole
    /// number of samples, and it is admitted; a β with β ω_max = 2·10⁸ (the order of the
    /// strip_wall crash of damping.beta = 0.5) is refused naming damping.beta, and so is a
    /// step count beyond every integer (6·10²³ steps).
    #[test]
    fn the_estimate_follows_the_stable_step_and_a_huge_beta_is_refused_naming_it() {
        let limits = Limits {
            steps_per_period: MAX_STEPS_PER_PERIOD,
            steps: MAX_STEPS,
            bytes: 1e9,
            measured: true,
        };
        let sizes = Sizes {
            free: 100,
            probes: 2,
            ..Sizes::default()
        };
        let e = Estimate::new(1e6, 0.0, 1e-3, &settings(10, 100), sizes);
        assert!((e.dt - 1.6e-6).abs() < 1e-18);
        assert_eq!(e.steps_per_period, 630.0);
        assert_eq!(e.admit(&limits).ok(), Some((630, 63)));
        let e = Estimate::new(4e8, 0.5, 2e-4, &settings(32, 2000), sizes);
        let message = e
            .admit(&limits)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(message.contains("Lower damping.beta"), "{message}");
        assert!(message.contains("steps per period"), "{message}");
        let e = Estimate::new(1e9, 1e6, 1.0, &settings(32, 2000), sizes);
        assert!(e.steps_per_period > usize::MAX as f64);
        assert!(e.admit(&limits).is_err());
    }

    /// TEST GOAL: a march within the step caps but over the memory limit is refused, and a
    /// march whose sampled states fill the memory is told to lower output.frames.
    #[test]
    fn memory_over_the_limit_is_refused_and_sampled_states_name_output_frames() {
        let limits = Limits {
            steps_per_period: MAX_STEPS_PER_PERIOD,
            steps: MAX_STEPS,
            bytes: 1e8,
            measured: false,
        };
        let sizes = Sizes {
            free: 1_000_000,
            ..Sizes::default()
        };
        let e = Estimate::new(1e6, 0.0, 1e-3, &settings(10_000, 10), sizes);
        let message = e
            .admit(&limits)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(message.contains("output.frames"), "{message}");
        assert!(message.contains("a fixed cap"), "{message}");
    }

    /// TEST GOAL: byte counts print in decimal units with three significant digits (the
    /// largest unit takes any more).
    #[test]
    fn bytes_print_in_decimal_units() {
        assert_eq!(human_bytes(131e9), "131 GB");
        assert_eq!(human_bytes(4.25e6), "4.25 MB");
        assert_eq!(human_bytes(12.0), "12.0 B");
        assert_eq!(human_bytes(2.5e18), "2500 PB");
    }
}
