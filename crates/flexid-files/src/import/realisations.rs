//! Realisations of a multisine in one record, found by the periodicity of the input: a
//! generator that plays each realisation from a point `L` samples before its period's start
//! leaves a stretch where `x[n] = x[n + P]` (the lead-in and the period's last `L`
//! samples). Each such stretch of at least [`MIN_RUN`] samples is one realisation: its
//! steady period starts where the stretch ends, its lead-in is the stretch.
//!
//! Used by the `silverbox` preset (10 realisations of an odd random-phase multisine, each
//! with its own lead-in, between zero-input gaps).

use flexid_core::excitation::Realisation;
use realfft::RealFftPlanner;

/// Shortest repeated stretch taken for a realisation's lead-in [samples]: a chance run of
/// agreeing samples between two unrelated stretches of a multisine (each agreeing with a
/// probability of about 6 % at [`AGREE`]) is never this long.
pub const MIN_RUN: usize = 32;
/// Two samples one period apart agree when they differ by less than this fraction of the
/// input's RMS: a generator's repeated samples differ by its measurement noise (the
/// Silverbox: 0.6 % of the RMS), two unrelated samples of a multisine by about 1.4 RMS.
pub const AGREE: f64 = 0.1;
/// A run ends at the first of this many consecutive disagreeing samples (one chance
/// agreement does not lengthen a lead-in, one noisy sample does not cut it).
const END_RUN: usize = 3;

/// The realisations of period `period` in `x` (mean removed by the caller): `(lead-in
/// start, steady start)` per realisation, in order; the steady period `steady .. steady +
/// period` lies inside `x`.
pub fn find(x: &[f64], period: usize) -> Vec<(usize, usize)> {
    if period == 0 || x.len() < period + MIN_RUN {
        return Vec::new();
    }
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    if !(rms > 0.0 && rms.is_finite()) {
        return Vec::new();
    }
    let tol = AGREE * rms;
    let agree = |n: usize| (x[n] - x[n + period]).abs() < tol;
    let last = x.len() - period;
    let mut out = Vec::new();
    let mut n = 0;
    while n < last {
        if !agree(n) {
            n += 1;
            continue;
        }
        let a = n;
        // to the first of END_RUN consecutive disagreements
        let mut b = n;
        while b < last && (b..(b + END_RUN).min(last)).any(agree) {
            b += 1;
        }
        // an idle stretch (zero input at both ends) agrees too: not a lead-in
        let power = x[a..b].iter().map(|v| v * v).sum::<f64>() / (b - a).max(1) as f64;
        if b - a >= MIN_RUN && power.sqrt() > AGREE * rms && b + period <= x.len() {
            out.push((a, b));
            n = b + period;
        } else {
            n = b.max(a + 1);
        }
    }
    out
}

/// The excited lines of a flat multisine design played in several realisations: lines
/// (1 to `period/2`) whose amplitude, in every realisation's steady period, is at least
/// half the median amplitude of the lines above a hundredth of the largest. A designed
/// flat multisine has its lines at its median level (the generator's filter bends it by
/// less than half at the band's edge); a disturbance that leaks over neighbouring lines
/// (mains hum not synchronous with the period) reaches a fraction of it.
pub fn flat_lines(x: &[f64], period: usize, steady_starts: &[usize]) -> Vec<usize> {
    if period < 2 || steady_starts.is_empty() {
        return Vec::new();
    }
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(period);
    let mut keep: Option<Vec<bool>> = None;
    for &s in steady_starts {
        let Some(seg) = x.get(s..s + period) else {
            return Vec::new();
        };
        let mut buf = seg.to_vec();
        let mut spec = fft.make_output_vec();
        if fft.process(&mut buf, &mut spec).is_err() {
            return Vec::new();
        }
        let amp: Vec<f64> = spec.iter().map(|c| c.norm()).collect();
        let max = amp.iter().skip(1).cloned().fold(0.0, f64::max);
        let mut above: Vec<f64> = amp
            .iter()
            .skip(1)
            .copied()
            .filter(|a| *a > 1e-2 * max)
            .collect();
        if above.is_empty() {
            return Vec::new();
        }
        above.sort_by(f64::total_cmp);
        let median = above[above.len() / 2];
        let here: Vec<bool> = (0..amp.len())
            .map(|k| k > 0 && amp[k] >= 0.5 * median)
            .collect();
        keep = Some(match keep {
            None => here,
            Some(k) => k.iter().zip(&here).map(|(a, b)| *a && *b).collect(),
        });
    }
    keep.map(|k| (1..k.len()).filter(|&i| k[i]).collect())
        .unwrap_or_default()
}

/// The realisations as the sidecar describes them, relative to row `from` of the cut
/// record.
pub fn described(found: &[(usize, usize)], from: usize) -> Vec<Realisation> {
    found
        .iter()
        .map(|&(a, b)| Realisation {
            start: b - from,
            lead_in: b - a,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three realisations of a flat odd multisine (other phases each), each the period's
    /// last `lead` samples, the period and a zero gap, with a hum not synchronous with
    /// the period: found exactly, the odd lines and no hum line.
    #[test]
    fn realisations_and_their_lines_are_found() {
        let (p, lead, gap) = (512usize, 60usize, 37usize);
        let lines: Vec<usize> = (1..100).filter(|k| k % 2 == 1).collect();
        let mut x = vec![0.0; 50];
        let mut expect = Vec::new();
        let mut seed = 1u64;
        for r in 0..3 {
            let ph: Vec<f64> = lines
                .iter()
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (seed >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU
                })
                .collect();
            let period: Vec<f64> = (0..p)
                .map(|n| {
                    lines
                        .iter()
                        .zip(&ph)
                        .map(|(&k, f)| {
                            (std::f64::consts::TAU * (k * n) as f64 / p as f64 + f).cos()
                        })
                        .sum::<f64>()
                })
                .collect();
            let a = x.len();
            x.extend_from_slice(&period[p - lead..]);
            expect.push((a, a + lead));
            x.extend_from_slice(&period);
            x.extend(std::iter::repeat_n(0.0, gap + 10 * r));
        }
        let hum: Vec<f64> = (0..x.len())
            .map(|n| 0.3 * (std::f64::consts::TAU * 50.3 * n as f64 / p as f64).cos())
            .collect();
        let with_hum: Vec<f64> = x.iter().zip(&hum).map(|(a, b)| a + b).collect();
        let found = find(&x, p);
        assert_eq!(found, expect);
        let starts: Vec<usize> = found.iter().map(|f| f.1).collect();
        assert_eq!(flat_lines(&with_hum, p, &starts), lines);
        let d = described(&found, 50);
        assert_eq!(
            d[0],
            Realisation {
                start: lead,
                lead_in: lead
            }
        );
        // nothing in noise-free silence or a constant
        assert!(find(&[0.0; 2000], p).is_empty());
        assert!(find(&[1.0; 10], p).is_empty());
    }
}
