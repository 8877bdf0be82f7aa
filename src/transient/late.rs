//! The late response of a march: the last `PERIODS_KEPT` whole periods of every probe dof and
//! of the total contact force, at `WINDOWS` instants a period, and the peak and mean contact
//! force of each period from every step. What `characterize` reads to say what the structure
//! does when it does not settle into a T-periodic state; bounded memory whatever the march's
//! length.
//!
//! Formulas and glossary:
//! - N the steps a period, R = min(`WINDOWS`, N) the samples a period, Δt = T/N;
//! - window j of a period (0 ≤ j < R) holds the steps i with ⌊jN/R⌋ ≤ i < ⌊(j+1)N/R⌋ (every
//!   window one step at least, lengths differing by one at most);
//! - y_j = (1/n_j) Σ_{i ∈ window j} y(iΔt), the window mean of a signal y: a box filter of
//!   width ≈ T/R before sampling at T/R, so content far above the sampling rate R/T is damped
//!   (an impact's ringing) instead of folded onto low frequencies; below R/(4T) the filter's
//!   gain differs from 1 by less than 11%, at the drive's first ten harmonics (R = 128) by
//!   less than 1%;
//! - F(t) = −Σ_a λ_a(t) the total contact force (≥ 0 pressing), λ of a step the multipliers
//!   that step computed (they act at its end); per period F_peak = max over its N steps,
//!   F_mean = (1/N) Σ over them (the numbers `contact_steps.csv` gives for the last period).
//!
//! Only whole periods are kept: an interrupted period is dropped. The march's own numbers
//! are untouched (the record only reads them).

use std::collections::VecDeque;

/// Whole periods kept: the spectrum's resolution is 1/(`PERIODS_KEPT` T) = f/64, fine enough
/// to tell a Neimark–Sacker frequency a few percent from f/2 from a period doubling.
pub const PERIODS_KEPT: usize = 64;

/// Samples (window means) a period, at most.
pub const WINDOWS: usize = 128;

/// `LateRecord::runaway`: the periods looked at, the least growth a period and the least
/// growth over the record that mark a march gaining energy.
pub const RUNAWAY_PERIODS: usize = 16;
pub const RUNAWAY_RATE: f64 = 1.05;
pub const RUNAWAY_SPAN: f64 = 10.0;

/// One recorded period.
#[derive(Clone, Debug, Default)]
pub struct PeriodRecord {
    /// Per probe dof: the R window means of u.
    pub probes: Vec<Vec<f64>>,
    /// The R window means of the total contact force F [N].
    pub force: Vec<f64>,
    /// The largest F over the period's steps [N].
    pub peak_force: f64,
    /// The mean F over the period's steps [N].
    pub mean_force: f64,
}

/// The last periods of a march (see the header).
#[derive(Clone, Debug)]
pub struct LateRecord {
    /// R, samples a period.
    pub samples_per_period: usize,
    /// T [s].
    pub period: f64,
    /// The recorded periods, oldest first (at most `PERIODS_KEPT`).
    pub periods: VecDeque<PeriodRecord>,
    /// The number (1, 2, …) of the last recorded period among all marched (0: none).
    pub last_period: usize,
    steps: usize,
    current: PeriodRecord,
    /// The window being summed, its end step, its sums (probe dofs, then F) and count.
    window: usize,
    window_end: usize,
    sums: Vec<f64>,
    count: usize,
    force_sum: f64,
}

impl LateRecord {
    /// A record of `probes` probe dofs for a march of `steps` steps a period of `period` s.
    pub fn new(probes: usize, steps: usize, period: f64) -> Self {
        let r = WINDOWS.min(steps.max(1));
        LateRecord {
            samples_per_period: r,
            period,
            periods: VecDeque::with_capacity(PERIODS_KEPT),
            last_period: 0,
            steps: steps.max(1),
            current: PeriodRecord::empty(probes, r),
            window: 0,
            window_end: window_end(0, steps.max(1), r),
            sums: vec![0.0; probes + 1],
            count: 0,
            force_sum: 0.0,
        }
    }

    /// Book step `step` of the period under way (in order): u at it on the probe dofs
    /// (`probe_values`), and the multipliers the step computed.
    pub fn record(&mut self, step: usize, probe_values: impl Iterator<Item = f64>, lambda: &[f64]) {
        let force = -lambda.iter().sum::<f64>();
        let probes = self.sums.len() - 1;
        for (sum, u) in self.sums.iter_mut().zip(probe_values) {
            *sum += u;
        }
        self.sums[probes] += force;
        self.count += 1;
        self.current.peak_force = if step == 0 {
            force
        } else {
            self.current.peak_force.max(force)
        };
        self.force_sum += force;
        if step + 1 >= self.window_end {
            let n = self.count.max(1) as f64;
            for (p, sum) in self.current.probes.iter_mut().zip(&self.sums) {
                p[self.window] = sum / n;
            }
            self.current.force[self.window] = self.sums[probes] / n;
            self.sums.iter_mut().for_each(|s| *s = 0.0);
            self.count = 0;
            self.window += 1;
            self.window_end = window_end(self.window, self.steps, self.samples_per_period);
        }
    }

    /// Close the period under way: it becomes the newest recorded one.
    pub fn end_period(&mut self) {
        let (probes, r) = (self.current.probes.len(), self.samples_per_period);
        let mut done = std::mem::replace(&mut self.current, PeriodRecord::empty(probes, r));
        done.mean_force = self.force_sum / self.steps as f64;
        if self.periods.len() == PERIODS_KEPT {
            self.periods.pop_front();
        }
        self.periods.push_back(done);
        self.last_period += 1;
        self.force_sum = 0.0;
        self.window = 0;
        self.window_end = window_end(0, self.steps, r);
    }

    /// Probe dof `d`'s samples over the recorded periods, oldest first.
    pub fn probe(&self, d: usize) -> Vec<f64> {
        self.periods
            .iter()
            .flat_map(|p| p.probes[d].iter().copied())
            .collect()
    }

    /// The total contact force's samples over the recorded periods, oldest first.
    pub fn force(&self) -> Vec<f64> {
        self.periods
            .iter()
            .flat_map(|p| p.force.iter().copied())
            .collect()
    }

    /// A march that gains energy the scene does not supply: the per-period peak contact force
    /// grows geometrically over the last `RUNAWAY_PERIODS` recorded (at least `RUNAWAY_RATE`
    /// a period on average, all but a quarter of the steps up) and ends at least
    /// `RUNAWAY_SPAN` times the record's smallest peak. Returns (the factor a period, the
    /// span); `None` otherwise (a departure from an unstable start saturates within a few
    /// dozen periods and ends flat).
    pub fn runaway(&self) -> Option<(f64, f64)> {
        let peaks: Vec<f64> = self.periods.iter().map(|p| p.peak_force).collect();
        let n = RUNAWAY_PERIODS;
        if peaks.len() < n + 1 || !peaks.iter().all(|p| p.is_finite()) {
            return None;
        }
        let last = &peaks[peaks.len() - n - 1..];
        let (first, end) = (last[0], last[n]);
        let smallest = peaks.iter().copied().fold(f64::INFINITY, f64::min);
        if !(first > 0.0 && smallest > 0.0) {
            return None;
        }
        let rate = (end / first).powf(1.0 / n as f64);
        let ups = last.windows(2).filter(|w| w[1] > w[0]).count();
        let span = end / smallest;
        (rate >= RUNAWAY_RATE && 4 * ups >= 3 * n && span >= RUNAWAY_SPAN).then_some((rate, span))
    }

    /// The sample times over the recorded periods [s], from the start of the march.
    pub fn times(&self) -> Vec<f64> {
        let first = self.last_period - self.periods.len();
        let r = self.samples_per_period;
        let (n, dt) = (self.steps, self.period / self.steps as f64);
        (0..self.periods.len() * r)
            .map(|k| {
                let (period, j) = (first + k / r, k % r);
                let (a, b) = (j * n / r, (j + 1) * n / r);
                // The window's centre: the mean of its steps' times.
                period as f64 * self.period + 0.5 * (a + b - 1) as f64 * dt
            })
            .collect()
    }
}

impl PeriodRecord {
    fn empty(probes: usize, r: usize) -> Self {
        PeriodRecord {
            probes: vec![vec![0.0; r]; probes],
            force: vec![0.0; r],
            peak_force: 0.0,
            mean_force: 0.0,
        }
    }
}

/// ⌊(j+1)N/R⌋, the step window j ends before.
fn window_end(j: usize, steps: usize, r: usize) -> usize {
    (j + 1) * steps / r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: the record keeps the last `PERIODS_KEPT` whole periods; a window's sample is
    /// the mean of its steps (a ramp u = step gives the window's mid step), the force's peak
    /// and mean per period are those of its steps, and the times are the windows' centres.
    #[test]
    fn the_record_keeps_the_last_whole_periods_as_window_means() {
        let steps = 300;
        let mut late = LateRecord::new(1, steps, 1.0);
        assert_eq!(late.samples_per_period, WINDOWS);
        for period in 0..PERIODS_KEPT + 3 {
            for step in 0..steps {
                let lambda = [-(period as f64) - step as f64 / steps as f64];
                late.record(step, std::iter::once(step as f64), &lambda);
            }
            late.end_period();
        }
        assert_eq!(late.periods.len(), PERIODS_KEPT);
        assert_eq!(late.last_period, PERIODS_KEPT + 3);
        let last = late.periods.back().unwrap();
        let p = (PERIODS_KEPT + 2) as f64;
        assert!((last.peak_force - (p + (steps - 1) as f64 / steps as f64)).abs() < 1e-12);
        assert!((last.mean_force - (p + 0.5 * (steps - 1) as f64 / steps as f64)).abs() < 1e-12);
        let times = late.times();
        for (j, &u) in last.probes[0].iter().enumerate() {
            let (a, b) = (j * steps / WINDOWS, (j + 1) * steps / WINDOWS);
            assert!(
                (u - 0.5 * (a + b - 1) as f64).abs() < 1e-12,
                "window {j}: {u}"
            );
            let t = times[(PERIODS_KEPT - 1) * WINDOWS + j];
            assert!((t - (p + u / steps as f64)).abs() < 1e-12, "{t}");
        }
    }
}
