//! Excited DFT lines of one period of a periodic excitation.

use realfft::RealFftPlanner;

/// Mean of the whole periods `first..` of `x` (period length `period`): one period with the
/// noise of a measured signal reduced. Returns `x[..period]` when `x` holds a single period.
/// `None` when `x` is shorter than `(first + 1) * period` and not exactly one period long.
pub fn mean_period(x: &[f64], period: usize, first: usize) -> Option<Vec<f64>> {
    if period == 0 {
        return None;
    }
    if x.len() == period {
        return Some(x.to_vec());
    }
    let n = x.len() / period;
    if n <= first {
        return None;
    }
    let mut mean = vec![0.0; period];
    for p in first..n {
        for (m, v) in mean.iter_mut().zip(&x[p * period..(p + 1) * period]) {
            *m += v;
        }
    }
    let count = (n - first) as f64;
    mean.iter_mut().for_each(|m| *m /= count);
    Some(mean)
}

/// DFT line indices `k` in `1..=period/2` (DC excluded) whose amplitude exceeds
/// `rel_threshold` times the largest one. Line `k` is at `k * fs / period` Hz.
///
/// For a designed (noise-free) period a threshold of `1e-6` is right; a measured signal
/// needs one above its noise floor relative to the excited lines (e.g. `1e-2`).
pub fn excited_lines(one_period: &[f64], rel_threshold: f64) -> Vec<usize> {
    let n = one_period.len();
    if n < 2 {
        return Vec::new();
    }
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut input = one_period.to_vec();
    let mut spectrum = fft.make_output_vec();
    if fft.process(&mut input, &mut spectrum).is_err() {
        return Vec::new();
    }
    let amp: Vec<f64> = spectrum.iter().map(|c| c.norm()).collect();
    let max = amp.iter().skip(1).cloned().fold(0.0, f64::max);
    if max <= 0.0 || !max.is_finite() {
        return Vec::new();
    }
    (1..amp.len())
        .filter(|&k| amp[k] > rel_threshold * max)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_lines_of_a_synthetic_multisine() {
        let n = 1000;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                [3usize, 7, 11]
                    .iter()
                    .map(|&k| (2.0 * std::f64::consts::PI * k as f64 * t + k as f64).cos())
                    .sum::<f64>()
                    + 5.0
            })
            .collect();
        assert_eq!(excited_lines(&x, 1e-6), vec![3, 7, 11]);
        let two: Vec<f64> = x.iter().chain(&x).cloned().collect();
        let m = mean_period(&two, n, 1).unwrap();
        assert_eq!(excited_lines(&m, 1e-6), vec![3, 7, 11]);
        assert!(mean_period(&two, n, 2).is_none());
    }
}
