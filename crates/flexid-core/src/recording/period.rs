//! Inference of the excitation description from the torque signal alone, for recordings
//! whose sidecar does not describe the excitation.

use crate::excitation::{ExcitationInfo, ExcitationKind};
use realfft::RealFftPlanner;

/// Relative tolerance of the periodicity test: two samples one period apart are equal when
/// they differ by at most this times the peak |torque|.
pub const PERIOD_TOLERANCE: f64 = 1e-9;

/// Relative threshold for excited lines: a DFT line of one period counts as excited when its
/// amplitude exceeds this times the largest line amplitude.
pub const EXCITED_LINE_THRESHOLD: f64 = 1e-6;

/// How many of the best autocorrelation candidates are verified exactly.
const CANDIDATES: usize = 48;

/// A period found in a signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Periodicity {
    /// Period length [samples], the smallest that fits.
    pub period_samples: usize,
    /// First sample index from which `x[k + P] == x[k]` holds (within tolerance) for all
    /// later k: the length of the non-periodic lead-in [samples].
    pub periodic_from: usize,
}

/// Find the smallest period P of `x`, allowing a non-periodic lead-in (transient).
///
/// `x` is periodic with period P when `|x[k+P] - x[k]| <= PERIOD_TOLERANCE * max|x|` for
/// all k from some `k0` on, and the periodic part `x[k0..]` holds at least two periods and at
/// least half of the signal. Candidates come from the FFT-based average magnitude
/// difference `d(P) = sum_k (x[k+P] - x[k])^2` (computed from the autocorrelation in
/// O(N log N)); the best ones are verified exactly, and then their divisors, so the result is
/// the fundamental period. Returns `None` for a signal that is not periodic, constant, or too
/// short (fewer than 4 samples).
pub fn find_period(x: &[f64]) -> Option<Periodicity> {
    let n = x.len();
    if n < 4 || x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let tol = PERIOD_TOLERANCE * peak;
    if hi - lo <= tol {
        return None; // constant: no excitation
    }
    let d = difference_function(x);
    let max_p = n / 2;
    let mut cand: Vec<usize> = (1..=max_p).collect();
    let k = CANDIDATES.min(cand.len());
    if k < cand.len() {
        cand.select_nth_unstable_by(k, |&a, &b| d[a].total_cmp(&d[b]));
        cand.truncate(k);
    }
    cand.sort_by(|&a, &b| d[a].total_cmp(&d[b]).then(a.cmp(&b)));
    let best = cand.into_iter().find_map(|p| verify(x, p, tol))?;
    // The fundamental period divides every period of a long enough periodic signal.
    let q = best.period_samples;
    let fundamental = (1..q)
        .filter(|p| q % p == 0)
        .find_map(|p| verify(x, p, tol))
        .unwrap_or(best);
    Some(fundamental)
}

/// `d[P] / (energy of the overlapping parts)` for P in 0..N (index 0 unused), via FFT.
fn difference_function(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let m = (2 * n).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(m);
    let inv = planner.plan_fft_inverse(m);
    let mut buf = vec![0.0; m];
    for (b, v) in buf.iter_mut().zip(x) {
        *b = v - mean;
    }
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut buf, &mut spec).expect("fft sizes match");
    for c in spec.iter_mut() {
        *c = num_complex::Complex64::new(c.norm_sqr(), 0.0);
    }
    let mut r = inv.make_output_vec();
    inv.process(&mut spec, &mut r).expect("fft sizes match");
    let scale = 1.0 / m as f64;
    // Prefix sums of squares of the mean-removed signal.
    let mut cum = Vec::with_capacity(n + 1);
    cum.push(0.0);
    let mut s = 0.0;
    for v in x {
        s += (v - mean) * (v - mean);
        cum.push(s);
    }
    let mut d = vec![f64::INFINITY; n];
    for p in 1..n {
        let head = cum[n - p]; // sum over k < N-P of x[k]^2
        let tail = cum[n] - cum[p]; // sum over k >= P of x[k]^2
        let e = head + tail;
        let dp = (e - 2.0 * r[p] * scale).max(0.0);
        d[p] = if e > 0.0 { dp / e } else { f64::INFINITY };
    }
    d
}

/// Exact test of period `p`: scan from the end for the last mismatch.
fn verify(x: &[f64], p: usize, tol: f64) -> Option<Periodicity> {
    let n = x.len();
    if p == 0 || 2 * p > n {
        return None;
    }
    let mut k0 = 0;
    for k in (0..n - p).rev() {
        if (x[k + p] - x[k]).abs() > tol {
            k0 = k + 1;
            break;
        }
    }
    let periodic_len = n - k0;
    if periodic_len >= 2 * p && 2 * periodic_len >= n {
        // A period over which the signal is constant is no excitation.
        let seg = &x[n - p..];
        let (lo, hi) = seg
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        if hi - lo > tol {
            return Some(Periodicity {
                period_samples: p,
                periodic_from: k0,
            });
        }
    }
    None
}

/// Describe the excitation of a recording from its torque command [N m] sampled at
/// `sample_rate_hz` [Hz].
///
/// Periodic torque (see [`find_period`]) gives kind `Multisine` with `period_samples` P,
/// `transient_periods` = the number of leading P-blocks touched by the non-periodic lead-in,
/// at least 1 when more than 2 periods are recorded (the response needs one period to settle),
/// `periods` = floor(N/P) minus the transient ones, the excited lines (DC excluded) of the DFT
/// of the last complete period with amplitude above [`EXCITED_LINE_THRESHOLD`] times the
/// largest, their band [Hz], the peak |torque| [N m] over the whole signal and the RMS torque
/// [N m] over the steady-state periods. Anything else gives kind `Other` with the peak and
/// RMS over the whole signal.
pub fn infer_excitation(torque_nm: &[f64], sample_rate_hz: f64) -> ExcitationInfo {
    let peak = torque_nm.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let rms = |s: &[f64]| {
        if s.is_empty() {
            0.0
        } else {
            (s.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt()
        }
    };
    let other = ExcitationInfo {
        kind: ExcitationKind::Other,
        period_samples: 0,
        periods: 0,
        transient_periods: 0,
        excited_lines: Vec::new(),
        band_hz: None,
        peak_nm: Some(peak),
        rms_nm: Some(rms(torque_nm)),
        design: None,
        blocks: Vec::new(),
        realisations: Vec::new(),
        band_limited: false,
    };
    let Some(per) = find_period(torque_nm) else {
        return other;
    };
    let p = per.period_samples;
    let total = torque_nm.len() / p;
    let lead_in_blocks = per.periodic_from.div_ceil(p);
    let transient = lead_in_blocks.max(usize::from(total > 2));
    if transient >= total {
        return other;
    }
    let periods = total - transient;
    let last = &torque_nm[(total - 1) * p..total * p];
    let lines = excited_lines(last);
    if lines.is_empty() {
        return other;
    }
    let df = sample_rate_hz / p as f64;
    let band = [lines[0] as f64 * df, lines[lines.len() - 1] as f64 * df];
    ExcitationInfo {
        kind: ExcitationKind::Multisine,
        period_samples: p,
        periods,
        transient_periods: transient,
        band_hz: Some(band),
        excited_lines: lines,
        peak_nm: Some(peak),
        rms_nm: Some(rms(&torque_nm[transient * p..total * p])),
        design: None,
        blocks: Vec::new(),
        realisations: Vec::new(),
        band_limited: false,
    }
}

/// DFT line indices 1..=P/2 of one period whose amplitude exceeds the threshold.
fn excited_lines(period: &[f64]) -> Vec<usize> {
    let p = period.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(p);
    let mut buf = period.to_vec();
    let mut spec = fft.make_output_vec();
    fft.process(&mut buf, &mut spec).expect("fft sizes match");
    let amp: Vec<f64> = spec.iter().map(|c| c.norm()).collect();
    let max = amp.iter().skip(1).fold(0.0_f64, |m, &a| m.max(a));
    if max == 0.0 {
        return Vec::new();
    }
    (1..amp.len())
        .filter(|&k| amp[k] > EXCITED_LINE_THRESHOLD * max)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn multisine(p: usize, lines: &[usize], n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| {
                lines
                    .iter()
                    .enumerate()
                    .map(|(i, &l)| {
                        (2.0 * PI * l as f64 * (k % p) as f64 / p as f64 + i as f64 * 1.3).cos()
                    })
                    .sum::<f64>()
            })
            .collect()
    }

    #[test]
    fn finds_period_with_lead_in() {
        let p = 250;
        let mut x = multisine(p, &[1, 3, 7, 20, 41], 6 * p + 17);
        // A fade-in over the first 100 samples.
        for (k, v) in x.iter_mut().enumerate().take(100) {
            *v *= k as f64 / 100.0;
        }
        let per = find_period(&x).unwrap();
        assert_eq!(per.period_samples, p);
        assert!(per.periodic_from <= 100);
        let info = infer_excitation(&x, 1000.0);
        assert_eq!(info.kind, ExcitationKind::Multisine);
        assert_eq!(info.period_samples, p);
        assert_eq!(info.transient_periods, 1);
        assert_eq!(info.periods, 5);
        assert_eq!(info.excited_lines, vec![1, 3, 7, 20, 41]);
        assert_eq!(info.band_hz, Some([4.0, 164.0]));
    }

    #[test]
    fn fundamental_not_multiple() {
        let p = 64;
        let x = multisine(p, &[2, 5], 10 * p);
        assert_eq!(find_period(&x).unwrap().period_samples, p);
    }

    #[test]
    fn noise_and_constants_are_not_periodic() {
        let mut s = 12345_u64;
        let x: Vec<f64> = (0..5000)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        assert!(find_period(&x).is_none());
        assert_eq!(infer_excitation(&x, 1e3).kind, ExcitationKind::Other);
        assert!(find_period(&[2.0; 100]).is_none());
        assert!(find_period(&[]).is_none());
    }

    #[test]
    fn two_periods_have_no_transient() {
        let p = 100;
        let x = multisine(p, &[3], 2 * p);
        let info = infer_excitation(&x, 1e3);
        assert_eq!(info.kind, ExcitationKind::Multisine);
        assert_eq!((info.transient_periods, info.periods), (0, 2));
    }
}
