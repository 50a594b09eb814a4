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
}

/// Per-line normalised squared difference `|H_meas - H_model|² / var` (E = 1 for noise).
pub fn z2(h: &[Complex64], var: &[f64], model: &[Complex64]) -> Vec<f64> {
    h.iter()
        .zip(var)
        .zip(model)
        .map(|((h, v), m)| {
            // log-complex form: robust to large gaps, equal to the linear one when small
            let l = (m / h).ln();
            let w2 = h.norm_sqr() / v.max(1e-300);
            if v.is_finite() {
                l.norm_sqr() * w2
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

/// Bands of one level: runs of lines whose 5-line running mean of `z²` exceeds 3
/// (a noise-only run does so with probability about 1e-4 per line), merged across gaps of
/// up to 3 lines, at least 3 lines long.
pub fn bands(
    level: usize,
    f: &[f64],
    h: &[Complex64],
    var: &[f64],
    model: &[Complex64],
) -> Vec<Band> {
    let z = z2(h, var, model);
    let n = z.len();
    let half = 2usize;
    let mut flag = vec![false; n];
    for i in 0..n {
        let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
        let m: f64 = z[a..b].iter().sum::<f64>() / (b - a) as f64;
        flag[i] = m > 3.0 || z[i] > 16.0;
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
            Band {
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
