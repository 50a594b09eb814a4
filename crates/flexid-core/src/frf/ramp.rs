//! The velocity ramp of a constant acceleration, removed from a periodic velocity FRF.
//!
//! A free chain driven by a torque with a small constant part (a set-point rounded to the
//! drive's resolution: 3.8e-6 N m of mean in the 1.6 kHz demo; an offset; a bias) accelerates
//! as a whole: after the transient the motor velocity is the periodic response plus a ramp
//! `a t`. Over one period the ramp is a sawtooth whose DFT falls as `1/k`, the same in every
//! period, so averaging does not remove it and the period-to-period variance does not see
//! it: a bias at the lowest lines (31 % at the first line of that demo, ripple over the
//! first dozen), which made the total inertia and the arm's body wrong by several percent.
//!
//! The ramp shows in the period means of the velocity (the DC line of each period's DFT),
//! `Y_m(0) = c + b m`; `b` is their least-squares slope over the steady periods, and the
//! ramp adds `(b/N) / (e^{-j 2 pi k/N} - 1)` to line `k` of every period (`1/N` scaling).

use num_complex::Complex64;

/// Least-squares slope per period of the period means `Y_m(0)`, `m = 0..p`, from
/// `sum_m m Y_m(0)` and the mean of the `Y_m(0)`; 0 with fewer than 2 periods.
pub(super) fn period_slope(sum_m_dc: f64, mean_dc: f64, p: usize) -> f64 {
    if p < 2 {
        return 0.0;
    }
    let pf = p as f64;
    let m_mean = 0.5 * (pf - 1.0);
    // sum (m - m_mean)^2 over m = 0..p
    let sxx = pf * (pf * pf - 1.0) / 12.0;
    (sum_m_dc - m_mean * pf * mean_dc) / sxx
}

/// What a ramp rising by `slope` per period (of `n` samples) adds to line `k >= 1` of each
/// period's DFT scaled by `1/n`: `(slope/n) / (e^{-j 2 pi k/n} - 1)`.
pub(super) fn ramp_line(slope: f64, k: usize, n: usize) -> Complex64 {
    if k == 0 || slope == 0.0 {
        return Complex64::new(0.0, 0.0);
    }
    let w = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * k as f64 / n as f64);
    (slope / n as f64) / (w - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DFT of a ramp, summed term by term.
    fn naive_line(slope: f64, k: usize, n: usize) -> Complex64 {
        (0..n)
            .map(|i| {
                let ph = -2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
                Complex64::from_polar(slope * i as f64 / n as f64, ph)
            })
            .sum::<Complex64>()
            / n as f64
    }

    #[test]
    fn ramp_line_equals_the_dft_of_a_ramp() {
        for (n, k) in [(64, 1), (64, 5), (6622, 1), (6622, 3000), (7, 3)] {
            let got = ramp_line(0.37, k, n);
            let want = naive_line(0.37, k, n);
            assert!(
                (got - want).norm() < 1e-9 * want.norm().max(1e-3),
                "{n} {k}"
            );
        }
    }

    #[test]
    fn slope_of_period_means() {
        let (c, b, p) = (2.5, -0.125, 9);
        let dc: Vec<f64> = (0..p).map(|m| c + b * m as f64).collect();
        let sum_m: f64 = dc.iter().enumerate().map(|(m, y)| m as f64 * y).sum();
        let mean = dc.iter().sum::<f64>() / p as f64;
        assert!((period_slope(sum_m, mean, p) - b).abs() < 1e-12);
        assert_eq!(period_slope(1.0, 1.0, 1), 0.0);
    }
}
