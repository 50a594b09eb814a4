//! Where the model and the measurement part: per-line significance of the difference
//! against the measurement's own variance (over periods), grouped into bands.

use num_complex::Complex64;
use serde::Serialize;

/// `20/ln 10`: dB per neper.
pub const DB_PER_NEPER: f64 = 8.685889638065035;

/// A band where the difference is statistically significant.
#[derive(Debug, Clone, Serialize)]
pub struct Band {
    /// Which recording (0-based, in the order given).
    pub level: usize,
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// Lines in the band.
    pub lines: usize,
    /// RMS of `20 log10 |H_meas / H_model|` over the band [dB].
    pub excess_db: f64,
    /// RMS of the phase difference over the band [deg].
    pub excess_deg: f64,
    /// Mean `|H_meas - H_model|² / var` over the band (1 = noise).
    pub mean_z2: f64,
    /// Magnitude difference significant (mean |dB| over 3 one-sigma dB units of the band).
    pub magnitude_significant: bool,
    /// Phase difference significant (same test on the phase).
    pub phase_significant: bool,
    /// Where the difference is largest (the line of the largest 5-line mean `z²`) [Hz].
    pub peak_hz: f64,
    /// The core of the band [Hz]: the lines around the peak where the error is at least half
    /// its largest (5-line mean `z²` at least a quarter of the peak's; the full width at half
    /// maximum of the error's amplitude). Narrow where the cause is local, even when the
    /// measurement is so clean that its far tails are significant over the whole band.
    pub core_lo_hz: f64,
    pub core_hi_hz: f64,
    /// What the difference looks like (evidence for a cause the candidates do not cover).
    pub shape: Shape,
}

/// The shape of the measured/model ratio over a band: the evidence an `unexplained` gap
/// comes with, so that the technician knows where to look.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// The measurement dips below the model inside the band and comes back (a notch
    /// filter, an unmodelled anti-resonance).
    Dip,
    /// The measurement rises above the model inside the band and comes back (an
    /// unmodelled resonance, a resonance in a sensor mount).
    Peak,
    /// The measurement falls away from the model towards the top of the band, with phase
    /// lag (a low-pass in the torque path or in the measured signal).
    RollOff,
    /// Phase lag growing with frequency, magnitude matched (a delay).
    PhaseLag,
    /// None of these.
    Broad,
}

impl Shape {
    /// In words, for reports.
    pub fn words(self) -> &'static str {
        match self {
            Shape::Dip => "notch-like dip",
            Shape::Peak => "peak-like excess",
            Shape::RollOff => "roll-off towards high frequency (a low-pass)",
            Shape::PhaseLag => "phase lag growing with frequency (delay-like)",
            Shape::Broad => "broad mismatch",
        }
    }
}

/// The shape of `ratio_db` and `ratio_deg` (measured over model, per line of a band), each
/// feature judged against the band's one-sigma `sig_db` of a line: a dip or peak is an
/// interior extremum at least 3 sigma beyond both ends; a roll-off falls by 3 sigma from
/// the low end to the high end with the phase lagging; a phase lag grows by 3 sigma with
/// the magnitude within 3 sigma.
fn shape(ratio_db: &[f64], ratio_deg: &[f64], sig_db: f64) -> Shape {
    let n = ratio_db.len();
    if n < 3 {
        return Shape::Broad;
    }
    let s = 3.0 * sig_db.max(1e-12);
    let sig_deg = (sig_db / DB_PER_NEPER).to_degrees();
    // ends: the mean of the outer fifth (at least one line) on each side
    let k = (n / 5).max(1);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (lo, hi) = (mean(&ratio_db[..k]), mean(&ratio_db[n - k..]));
    let (imin, &vmin) = ratio_db
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    let (imax, &vmax) = ratio_db
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    let interior = |i: usize| i >= k && i < n - k;
    let dip = interior(imin) && vmin < lo.min(hi) - s;
    let peak = interior(imax) && vmax > lo.max(hi) + s;
    let (plo, phi) = (mean(&ratio_deg[..k]), mean(&ratio_deg[n - k..]));
    match (dip, peak) {
        (true, false) => return Shape::Dip,
        (false, true) => return Shape::Peak,
        (true, true) => {
            // the larger excursion names it
            return if lo.min(hi) - vmin > vmax - lo.max(hi) {
                Shape::Dip
            } else {
                Shape::Peak
            };
        }
        _ => {}
    }
    if hi < lo - s && phi < plo - 3.0 * sig_deg {
        Shape::RollOff
    } else if phi < plo - 3.0 * sig_deg && (hi - lo).abs() <= s {
        Shape::PhaseLag
    } else {
        Shape::Broad
    }
}

/// Per-line normalised squared difference `|H_meas - H_model|² / var` (E = 1 for noise).
///
/// The linear form, not the log-complex one `|ln(H_model/H_meas)|² |H_meas|²/var`: the two
/// agree where the line's relative error is small, but where it is not (high frequencies,
/// small torque: `|H|²/var` of a few) the logarithm of a noisy value is far from Gaussian
/// and its weight uses the noisy `|H_meas|`, so that noise alone gave band means of 5-8 at
/// an F(2, 8) line whose mean is 1.33 (a world case without effect at 4 kHz).
pub fn z2(h: &[Complex64], var: &[f64], model: &[Complex64]) -> Vec<f64> {
    h.iter()
        .zip(var)
        .zip(model)
        .map(|((h, v), m)| {
            if v.is_finite() {
                (m - h).norm_sqr() / v.max(1e-300)
            } else {
                0.0
            }
        })
        .collect()
}

/// RMS of the log-complex gap `|ln(H_meas/H_model)|` in dB (magnitude and phase together:
/// one radian of phase counts as 8.69 dB) over the lines `idx` (all when empty).
pub fn gap_rms_db(h: &[Complex64], model: &[Complex64]) -> f64 {
    if h.is_empty() {
        return 0.0;
    }
    let s: f64 = h
        .iter()
        .zip(model)
        .map(|(h, m)| (h / m).ln().norm_sqr())
        .sum();
    DB_PER_NEPER * (s / h.len() as f64).sqrt()
}

/// Bands of one level: runs of lines whose 5-line running mean of `z²` exceeds three
/// times what noise gives per line, or one line beyond the level noise exceeds with
/// probability 1e-6 (both from `F(2, 2(P-1))` of `averages` = P, [`super::noise`]), merged
/// across gaps of up to 3 lines, at least 3 lines long.
pub fn bands(
    level: usize,
    f: &[f64],
    h: &[Complex64],
    var: &[f64],
    model: &[Complex64],
    averages: usize,
) -> Vec<Band> {
    let z = z2(h, var, model);
    let n = z.len();
    let half = 2usize;
    let line_mean = super::noise::line_mean(averages).min(3.0);
    let one_line = super::noise::quantile(averages, 1e-6);
    let mut flag = vec![false; n];
    let mut smooth = vec![0.0; n];
    for i in 0..n {
        let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
        let m: f64 = z[a..b].iter().sum::<f64>() / (b - a) as f64;
        smooth[i] = m;
        flag[i] = m > 3.0 * line_mean || z[i] > one_line;
    }
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut i = 0;
    while i < n {
        if flag[i] {
            let s = i;
            while i < n && flag[i] {
                i += 1;
            }
            match runs.last_mut() {
                Some(last) if s - last.1 <= 3 => last.1 = i,
                _ => runs.push((s, i)),
            }
        } else {
            i += 1;
        }
    }
    runs.into_iter()
        .filter(|(a, b)| b - a >= 3)
        .map(|(a, b)| {
            let k = (b - a) as f64;
            let (mut sdb, mut sdeg, mut sz, mut sab_db, mut sab_deg, mut ssig) =
                (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for i in a..b {
                let l = (h[i] / model[i]).ln();
                let (db, deg) = (DB_PER_NEPER * l.re, l.im.to_degrees());
                sdb += db * db;
                sdeg += deg * deg;
                sab_db += db.abs();
                sab_deg += deg.abs();
                sz += z[i];
                // one-sigma of ln|H| (and of arg H) from the complex variance
                ssig += (var[i] / h[i].norm_sqr() / 2.0).sqrt();
            }
            let sig = ssig / k;
            let ratio: Vec<Complex64> = (a..b).map(|i| (h[i] / model[i]).ln()).collect();
            let rdb: Vec<f64> = ratio.iter().map(|l| DB_PER_NEPER * l.re).collect();
            let rdeg: Vec<f64> = ratio.iter().map(|l| l.im.to_degrees()).collect();
            let ipk = (a..b)
                .max_by(|&x, &y| smooth[x].total_cmp(&smooth[y]))
                .unwrap_or(a);
            let (mut ca, mut cb) = (ipk, ipk);
            while ca > a && smooth[ca - 1] >= 0.25 * smooth[ipk] {
                ca -= 1;
            }
            while cb + 1 < b && smooth[cb + 1] >= 0.25 * smooth[ipk] {
                cb += 1;
            }
            Band {
                peak_hz: f[ipk],
                core_lo_hz: f[ca],
                core_hi_hz: f[cb],
                shape: shape(&rdb, &rdeg, DB_PER_NEPER * sig),
                level,
                lo_hz: f[a],
                hi_hz: f[b - 1],
                lines: b - a,
                excess_db: (sdb / k).sqrt(),
                excess_deg: (sdeg / k).sqrt(),
                mean_z2: sz / k,
                magnitude_significant: sab_db / k > 3.0 * DB_PER_NEPER * sig / k.sqrt(),
                phase_significant: (sab_deg / k).to_radians() > 3.0 * sig / k.sqrt(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A measurement equal to the model times `factor(f)`, with a 0.1 % one-sigma line
    /// variance, on 200 lines from 10 to 500 Hz; its bands against the model.
    fn bands_of(factor: impl Fn(f64) -> Complex64) -> Vec<Band> {
        let f: Vec<f64> = (0..200).map(|i| 10.0 + 490.0 * i as f64 / 199.0).collect();
        let model: Vec<Complex64> = f.iter().map(|&f| Complex64::new(1.0, f / 100.0)).collect();
        let h: Vec<Complex64> = f.iter().zip(&model).map(|(&f, m)| m * factor(f)).collect();
        let var: Vec<f64> = h.iter().map(|h| 1e-6 * h.norm_sqr()).collect();
        bands(0, &f, &h, &var, &model, 8)
    }

    /// A second-order section `(s² + 2 zn w s + w²)/(s² + 2 zd w s + w²)` at `f0` [Hz].
    fn notch(f: f64, f0: f64, zn: f64, zd: f64) -> Complex64 {
        let s = Complex64::new(0.0, f / f0);
        (s * s + 2.0 * zn * s + 1.0) / (s * s + 2.0 * zd * s + 1.0)
    }

    #[test]
    fn a_notch_filter_gives_a_narrow_dip_at_its_frequency() {
        let b = bands_of(|f| notch(f, 200.0, 0.02, 0.2));
        assert_eq!(b.len(), 1, "{b:?}");
        assert_eq!(b[0].shape, Shape::Dip, "{b:?}");
        assert!((b[0].peak_hz - 200.0).abs() < 10.0, "{b:?}");
        // a clean measurement shows the pole's far tails over the whole band; its core is
        // the notch
        assert!(b[0].core_lo_hz > 150.0 && b[0].core_hi_hz < 260.0, "{b:?}");
    }

    #[test]
    fn an_extra_resonance_gives_a_peak() {
        let b = bands_of(|f| notch(f, 150.0, 0.2, 0.02));
        assert_eq!(b.len(), 1, "{b:?}");
        assert_eq!(b[0].shape, Shape::Peak, "{b:?}");
        assert!((b[0].peak_hz - 150.0).abs() < 10.0, "{b:?}");
    }

    #[test]
    fn a_low_pass_rolls_off_and_a_delay_lags() {
        let lp = bands_of(|f| 1.0 / Complex64::new(1.0, f / 250.0));
        assert!(!lp.is_empty());
        assert_eq!(lp.last().unwrap().shape, Shape::RollOff, "{lp:?}");
        let delay =
            bands_of(|f| Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f * 2e-4));
        assert!(!delay.is_empty());
        assert_eq!(delay.last().unwrap().shape, Shape::PhaseLag, "{delay:?}");
    }

    #[test]
    fn noise_alone_gives_no_band() {
        // the exact model: no band (z² = 0)
        assert!(bands_of(|_| Complex64::new(1.0, 0.0)).is_empty());
    }
}
