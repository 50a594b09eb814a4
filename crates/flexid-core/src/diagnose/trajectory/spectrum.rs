//! The cut-off frequency from the data: where the position's spectrum meets its noise
//! floor. Also the force's noise floor, for the noise the residual must be compared with.
//!
//! The position is differenced once before its spectrum is taken (a bang-bang trajectory
//! spans many decades of power below a few hertz; the difference removes the range that
//! window leakage would spread over the noise floor), and the difference's spectrum is
//! divided by the difference's own response `4 sin²(pi f/fs)`: the result is the
//! position's power spectral density, on which white noise (encoder quantisation,
//! `delta²/12` per sample) is flat.

use crate::frf::Window;
use realfft::RealFftPlanner;

/// Welch power spectral density, one-sided [unit²/Hz].
#[derive(Debug, Clone, PartialEq)]
pub struct Psd {
    pub f_hz: Vec<f64>,
    pub psd: Vec<f64>,
    /// Segments averaged.
    pub segments: usize,
}

/// Welch's estimate with periodic Hann segments, half overlapping, each segment's mean
/// removed; the segment is the largest power of two within an eighth of the record
/// (so at least 15 half-overlapping segments), from 64 to 4096 samples. `None` below 512
/// samples or for a non-positive rate.
pub fn welch_psd(x: &[f64], sample_rate_hz: f64) -> Option<Psd> {
    let n = x.len();
    if n < 512 || !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return None;
    }
    let mut seg = 64usize;
    while seg * 2 <= n / 8 && seg < 4096 {
        seg *= 2;
    }
    let w = Window::Hann.coefficients(seg);
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(seg);
    let mut buf = fft.make_input_vec();
    let mut spec = fft.make_output_vec();
    let mut acc = vec![0.0; seg / 2 + 1];
    let mut segments = 0;
    let mut start = 0;
    while start + seg <= n {
        let part = &x[start..start + seg];
        let mean = part.iter().sum::<f64>() / seg as f64;
        for ((b, v), wi) in buf.iter_mut().zip(part).zip(&w) {
            *b = (v - mean) * wi;
        }
        fft.process(&mut buf, &mut spec).ok()?;
        for (a, c) in acc.iter_mut().zip(&spec) {
            *a += c.norm_sqr();
        }
        segments += 1;
        start += seg / 2;
    }
    let scale = 1.0 / (sample_rate_hz * w2 * segments as f64);
    let last = seg / 2;
    let psd = acc
        .iter()
        .enumerate()
        .map(|(k, a)| a * scale * if k == 0 || k == last { 1.0 } else { 2.0 })
        .collect();
    let f_hz = (0..=last)
        .map(|k| k as f64 * sample_rate_hz / seg as f64)
        .collect();
    Some(Psd {
        f_hz,
        psd,
        segments,
    })
}

/// Where white noise is measured: the top of the band, `[fs/4, 0.45 fs]`, where an
/// encoder's quantisation or a sensor's noise is above any motion a servo axis makes
/// (the lines next to the Nyquist frequency, often shaped by an anti-aliasing filter,
/// are left out).
pub const FLOOR_BAND: [f64; 2] = [0.25, 0.45];

/// The total power that means "signal as large as noise": twice the noise floor.
pub const SIGNAL_EQUALS_NOISE: f64 = 2.0;

/// The data-derived cut-off and noise floors.
#[derive(Debug, Clone, PartialEq)]
pub struct Cutoff {
    /// The cut-off [Hz]: the lowest frequency at which the position's spectrum,
    /// smoothed over a third of an octave, falls to twice its noise floor.
    pub cutoff_hz: f64,
    /// White position noise as a one-sided PSD [rad²/Hz] (the recording's position unit).
    pub position_floor_rad2_per_hz: f64,
    /// White force noise as a one-sided PSD [(N m)²/Hz] (the recording's torque unit).
    pub force_floor_nm2_per_hz: f64,
    /// `[lo, hi]` [Hz] where the floors are measured.
    pub floor_band_hz: [f64; 2],
    /// True when the spectrum stays above twice the floor up to the floor band: the cut-off
    /// is then the band's lower edge.
    pub capped: bool,
    /// Welch line spacing [Hz].
    pub resolution_hz: f64,
}

/// The median of `v` (NaN when empty).
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The median of the PSD over the floor band.
fn floor_level(p: &Psd, fs: f64) -> f64 {
    let [lo, hi] = [FLOOR_BAND[0] * fs, FLOOR_BAND[1] * fs];
    median(
        p.f_hz
            .iter()
            .zip(&p.psd)
            .filter(|(f, _)| **f >= lo && **f <= hi)
            .map(|(_, v)| *v)
            .collect(),
    )
}

/// The cut-off from the position `q` and the noise floors of `q` and of the force `tau`
/// (both sampled at `sample_rate_hz`). `None` when a record is too short for a spectrum
/// or a floor is not positive (a position that never changes, a constant force).
///
/// The rule: the filter passes the band where the position holds more motion than noise.
/// Below the frequency where the position's spectrum meets its noise floor, filtering
/// would remove motion (and bias the acceleration); above it, the filter would pass noise
/// that the differentiation amplifies (as `f²` for the acceleration). The noise floor is
/// the median position PSD over [`FLOOR_BAND`]; the spectrum is smoothed by a running
/// median over a third of an octave (lines of mains hum or of a periodic trajectory do not
/// move the crossing); the crossing is the first frequency from below at which the
/// smoothed spectrum is at most [`SIGNAL_EQUALS_NOISE`] times the floor.
pub fn cutoff(q: &[f64], tau: &[f64], sample_rate_hz: f64) -> Option<Cutoff> {
    let fs = sample_rate_hz;
    let dq: Vec<f64> = q.windows(2).map(|w| w[1] - w[0]).collect();
    let pd = welch_psd(&dq, fs)?;
    let pt = welch_psd(tau, fs)?;
    // the position's PSD: the difference's divided by 4 sin²(pi f / fs)
    let pq: Vec<f64> = pd
        .f_hz
        .iter()
        .zip(&pd.psd)
        .map(|(f, p)| {
            let s = (std::f64::consts::PI * f / fs).sin();
            if s > 0.0 {
                p / (4.0 * s * s)
            } else {
                f64::NAN
            }
        })
        .collect();
    let pos = Psd {
        f_hz: pd.f_hz.clone(),
        psd: pq,
        segments: pd.segments,
    };
    let floor_q = floor_level(&pos, fs);
    let floor_t = floor_level(&pt, fs);
    if !(floor_q > 0.0 && floor_q.is_finite() && floor_t > 0.0 && floor_t.is_finite()) {
        return None;
    }
    let band = [FLOOR_BAND[0] * fs, FLOOR_BAND[1] * fs];
    let third = 2f64.powf(1.0 / 6.0);
    let mut crossing = None;
    for (k, &f) in pos.f_hz.iter().enumerate().skip(1) {
        if f >= band[0] {
            break;
        }
        let smooth = median(
            pos.f_hz
                .iter()
                .zip(&pos.psd)
                .skip(1)
                .filter(|(g, _)| **g >= f / third && **g <= f * third)
                .map(|(_, v)| *v)
                .collect(),
        );
        if smooth <= SIGNAL_EQUALS_NOISE * floor_q {
            crossing = Some(k);
            break;
        }
    }
    let (cutoff_hz, capped) = match crossing {
        Some(k) => (pos.f_hz[k], false),
        None => (band[0], true),
    };
    Some(Cutoff {
        cutoff_hz,
        position_floor_rad2_per_hz: floor_q,
        force_floor_nm2_per_hz: floor_t,
        floor_band_hz: band,
        capped,
        resolution_hz: pos.f_hz[1],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn white_noise_psd_is_its_variance_over_half_the_rate() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let n = Normal::new(0.0, 0.5).unwrap();
        let x: Vec<f64> = (0..40_000).map(|_| n.sample(&mut rng)).collect();
        let p = welch_psd(&x, 2000.0).unwrap();
        // one-sided: 2 sigma² / fs
        let want = 2.0 * 0.25 / 2000.0;
        let mean = p.psd[10..p.psd.len() - 10].iter().sum::<f64>() / (p.psd.len() - 20) as f64;
        assert!((mean / want - 1.0).abs() < 0.03, "{mean} vs {want}");
        assert!(welch_psd(&x[..100], 2000.0).is_none());
    }

    /// A position whose spectrum is known: a sum of sines with amplitudes falling as
    /// `f^-3` plus white noise of known variance. The floor is the noise's PSD and the
    /// cut-off where the lines' smoothed PSD meets it.
    #[test]
    fn cutoff_where_the_motion_meets_a_known_noise_floor() {
        let fs = 1000.0;
        let n = 30_000;
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let sigma = 1e-4;
        let noise = Normal::new(0.0, sigma).unwrap();
        // lines every 0.25 Hz (denser than the Welch resolution, ~0.5 Hz) up to 200 Hz,
        // amplitude a(f) = c f^-3: line power a²/2 per 0.25 Hz, so PSD(f) = 2 a(f)²
        let c = 2.0;
        let spacing = 0.25;
        let lines: Vec<f64> = (4..800).map(|i| spacing * i as f64 + 0.01).collect();
        let q: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / fs;
                lines
                    .iter()
                    .enumerate()
                    .map(|(i, f)| {
                        c * f.powi(-3) * (2.0 * std::f64::consts::PI * f * t + 2.4 * i as f64).sin()
                    })
                    .sum::<f64>()
                    + noise.sample(&mut rng)
            })
            .collect();
        let tau: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
        let cut = cutoff(&q, &tau, fs).unwrap();
        let floor = 2.0 * sigma * sigma / fs;
        assert!(
            (cut.position_floor_rad2_per_hz / floor - 1.0).abs() < 0.1,
            "{} vs {floor}",
            cut.position_floor_rad2_per_hz
        );
        assert!((cut.force_floor_nm2_per_hz / floor - 1.0).abs() < 0.1);
        // where c² f^-6 / (2 spacing) = floor (signal as large as noise)
        let want = (c * c / (2.0 * spacing * floor)).powf(1.0 / 6.0);
        assert!(!cut.capped);
        assert!(
            (cut.cutoff_hz / want - 1.0).abs() < 0.1,
            "{} vs {want}",
            cut.cutoff_hz
        );
    }

    #[test]
    fn no_noise_floor_no_cutoff() {
        let q = vec![1.0; 5000];
        let tau: Vec<f64> = (0..5000).map(|k| (k as f64).sin()).collect();
        assert!(cutoff(&q, &tau, 1000.0).is_none());
    }
}
