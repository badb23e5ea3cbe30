//! The actuation delay line: which logged commands a delayed actuator applies over a sample.
//!
//! A controller computes `τ_cmd,k` at `t_k = t_0 + k T` and holds it over the sample. An
//! actuation delay `d = (m + r) T` (whole samples `m ≥ 0`, fraction `0 ≤ r < 1`) applies over
//! sample `k`
//!
//! ```text
//! τ_delayed,k = (1 − r) τ_cmd,k−m + r τ_cmd,k−m−1
//! ```
//!
//! (the fractional part interpolates between the two commands the delayed hold straddles), and
//! before the first sample the first command. The simulator
//! ([`simulate`](crate::simulate::simulate)), the k-step prediction and the torque-residual fit
//! of the diagnosis all form the delayed command here, so that they agree to the last bit,
//! also at exact multiples of the sample period.

/// A delay split into whole samples and a fraction of a sample (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DelayLine {
    /// Whole samples `m`.
    whole: usize,
    /// Fraction of a sample `r`, in `[0, 1)`.
    frac: f64,
}

impl DelayLine {
    /// The delay line of `delay` seconds for commands every `period` seconds. A ratio
    /// `delay / period` within 1e-9 of an integer is that integer, so that a delay written as
    /// a multiple of the period delays by whole samples despite the rounding of the division
    /// (`0.0175 / 0.0025` is 7.000000000000001 in floating point). A delay that is zero, negative, NaN, or
    /// a period that is not positive, is no delay.
    pub fn new(delay: f64, period: f64) -> DelayLine {
        let ratio = delay / period;
        if !(ratio > 0.0) || !(period > 0.0) {
            return DelayLine { whole: 0, frac: 0.0 };
        }
        if ratio.is_infinite() {
            return DelayLine { whole: usize::MAX, frac: 0.0 };
        }
        let ratio = if (ratio - ratio.round()).abs() < 1e-9 { ratio.round() } else { ratio };
        let whole = ratio.floor();
        DelayLine { whole: whole as usize, frac: ratio - whole }
    }

    /// Whole samples `m` of the delay.
    pub fn whole(&self) -> usize {
        self.whole
    }

    /// Fraction `r` of a sample, in `[0, 1)`.
    pub fn frac(&self) -> f64 {
        self.frac
    }

    /// Whether the line delays nothing (`m = 0`, `r = 0`): the command is applied as computed.
    pub fn is_zero(&self) -> bool {
        self.whole == 0 && self.frac == 0.0
    }

    /// The two samples whose commands are applied over sample `k` and their weights:
    /// `[(k − m, 1 − r), (k − m − 1, r)]`, samples before the first one clamped to it.
    pub fn taps(&self, k: usize) -> [(usize, f64); 2] {
        [(k.saturating_sub(self.whole), 1.0 - self.frac), (k.saturating_sub(self.whole.saturating_add(1)), self.frac)]
    }

    /// The delayed command over sample `k` from `command(i)`, the command of sample `i`:
    /// `(1 − r) τ_{k−m} + r τ_{k−m−1}` (see [`DelayLine::taps`]).
    #[inline]
    pub fn delayed(&self, k: usize, command: impl Fn(usize) -> f64) -> f64 {
        let [(newer, a), (older, b)] = self.taps(k);
        a * command(newer) + b * command(older)
    }

    /// [`DelayLine::delayed`] for every joint: `command(i)` is the row of sample `i`, `out` the
    /// delayed row (overwritten; its length is the number of joints). Never allocates.
    ///
    /// # Panics
    /// If a row is shorter than `out`.
    #[inline]
    pub fn delayed_row<'a>(&self, k: usize, command: impl Fn(usize) -> &'a [f64], out: &mut [f64]) {
        let [(newer, a), (older, b)] = self.taps(k);
        let (x, y) = (command(newer), command(older));
        for (j, o) in out.iter_mut().enumerate() {
            *o = a * x[j] + b * y[j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_multiples_of_the_period_delay_by_whole_samples() {
        // 0.0175 / 0.0025 = 7.000000000000001 and 0.035 / 0.0025 = 14.000000000000002 in
        // floating point
        for (delay, period, m) in [(0.0025, 0.0025, 1usize), (0.0075, 0.0025, 3), (0.0175, 0.0025, 7), (0.035, 0.0025, 14), (0.014, 0.002, 7)] {
            let line = DelayLine::new(delay, period);
            assert_eq!((line.whole(), line.frac()), (m, 0.0), "{delay} / {period}");
        }
    }

    #[test]
    fn fractional_delay_interpolates_between_the_straddled_commands() {
        let line = DelayLine::new(1.25 * 0.002, 0.002);
        assert_eq!(line.whole(), 1);
        assert!((line.frac() - 0.25).abs() < 1e-12);
        let tau = |i: usize| 10.0 * i as f64;
        // over sample 5: 0.75 τ_4 + 0.25 τ_3
        assert!((line.delayed(5, tau) - (0.75 * 40.0 + 0.25 * 30.0)).abs() < 1e-12);
    }

    #[test]
    fn before_the_first_sample_the_first_command_is_held() {
        let line = DelayLine::new(2.5, 1.0);
        let tau = |i: usize| if i == 0 { 7.0 } else { 100.0 + i as f64 };
        for k in 0..=2 {
            assert_eq!(line.delayed(k, tau), 7.0, "sample {k}");
        }
        // over sample 3: 0.5 τ_1 + 0.5 τ_0
        assert_eq!(line.delayed(3, tau), 0.5 * 101.0 + 0.5 * 7.0);
        let huge = DelayLine::new(1e9, 0.001);
        assert_eq!(huge.delayed(10_000, tau), 7.0);
    }

    #[test]
    fn no_delay_applies_the_command_as_computed() {
        for d in [0.0, -1.0, f64::NAN] {
            let line = DelayLine::new(d, 0.002);
            assert!(line.is_zero());
            assert_eq!(line.delayed(4, |i| i as f64), 4.0);
        }
    }
}
