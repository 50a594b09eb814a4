//! Validation of plotted responses and the curves derived from them (dB, unwrapped phase,
//! uncertainty bands), independent of the drawing library.

use super::error::PlotError;
use flexid_core::frf::Frf;

/// Lower clamp of the magnitude band relative to |H|: the band's lower edge is drawn at most
/// 40 dB below the curve (|H| - 2 sigma can be zero or negative).
pub const BAND_FLOOR_RELATIVE: f64 = 1e-2;

/// Largest drawn phase half-width [deg] of the uncertainty band.
pub const PHASE_BAND_MAX_DEG: f64 = 180.0;

/// Curves of one response, ready to draw.
#[derive(Debug, Clone)]
pub(crate) struct Curves {
    pub freq_hz: Vec<f64>,
    pub mag_db: Vec<f64>,
    pub phase_deg: Vec<f64>,
    /// Band edges [dB] (measured only), `None` on lines without a usable estimate.
    pub mag_band: Vec<Option<(f64, f64)>>,
    /// Band half-width [deg] (measured only).
    pub phase_band: Vec<Option<f64>>,
    /// Lines with a usable estimate (finite variance); models: all lines.
    pub usable: Vec<bool>,
    pub coherence: Option<Vec<f64>>,
}

fn check_freq(what: &str, f: &[f64]) -> Result<(), PlotError> {
    for (i, &v) in f.iter().enumerate() {
        if !(v.is_finite() && v > 0.0) || (i > 0 && v <= f[i - 1]) {
            return Err(PlotError::InvalidFrequency {
                what: what.to_string(),
                index: i,
                freq_hz: v,
            });
        }
    }
    Ok(())
}

fn check_len(
    what: &str,
    field: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), PlotError> {
    if expected != got {
        return Err(PlotError::LengthMismatch {
            what: what.to_string(),
            field,
            expected,
            got,
        });
    }
    Ok(())
}

fn check_h(what: &str, frf: &Frf) -> Result<(), PlotError> {
    for (i, h) in frf.h.iter().enumerate() {
        if !(h.re.is_finite() && h.im.is_finite()) || h.norm() == 0.0 {
            return Err(PlotError::InvalidResponse {
                what: what.to_string(),
                index: i,
                freq_hz: frf.freq_hz[i],
            });
        }
    }
    Ok(())
}

/// Validate the measured response and derive its curves with a `sigmas`-sigma band.
///
/// Band on the magnitude: |H| ± k sqrt(var), the lower edge clamped at
/// [`BAND_FLOOR_RELATIVE`] |H|; on the phase: ± k sqrt(var)/|H| rad (at most
/// [`PHASE_BAND_MAX_DEG`]). Lines with `var = +inf` are gaps.
pub(crate) fn measured_curves(frf: &Frf, sigmas: f64) -> Result<Curves, PlotError> {
    let what = "measured";
    let n = frf.freq_hz.len();
    if n == 0 {
        return Err(PlotError::Empty {
            what: what.into(),
            reason: "no lines".into(),
        });
    }
    check_len(what, "h", n, frf.h.len())?;
    check_len(what, "var", n, frf.var.len())?;
    check_freq(what, &frf.freq_hz)?;
    check_h(what, frf)?;
    for (i, &v) in frf.var.iter().enumerate() {
        if v.is_nan() || v <= 0.0 {
            return Err(PlotError::InvalidVariance {
                index: i,
                freq_hz: frf.freq_hz[i],
                var: v,
            });
        }
    }
    let coherence = match &frf.coherence {
        None => None,
        Some(c) => {
            check_len(what, "coherence", n, c.len())?;
            for (i, &v) in c.iter().enumerate() {
                if !(-1e-9..=1.0 + 1e-9).contains(&v) {
                    return Err(PlotError::InvalidCoherence { index: i, value: v });
                }
            }
            Some(c.iter().map(|v| v.clamp(0.0, 1.0)).collect())
        }
    };
    let usable: Vec<bool> = frf.var.iter().map(|v| v.is_finite()).collect();
    if !usable.iter().any(|&u| u) {
        return Err(PlotError::Empty {
            what: what.into(),
            reason: "no line has a finite variance".into(),
        });
    }
    let mut mag_band = Vec::with_capacity(n);
    let mut phase_band = Vec::with_capacity(n);
    #[allow(clippy::needless_range_loop)] // indexes four parallel vectors
    for i in 0..n {
        if !usable[i] {
            mag_band.push(None);
            phase_band.push(None);
            continue;
        }
        let m = frf.h[i].norm();
        let s = sigmas * frf.var[i].sqrt();
        let lo = (m - s).max(BAND_FLOOR_RELATIVE * m);
        mag_band.push(Some((20.0 * lo.log10(), 20.0 * (m + s).log10())));
        phase_band.push(Some((s / m).to_degrees().min(PHASE_BAND_MAX_DEG)));
    }
    Ok(Curves {
        freq_hz: frf.freq_hz.clone(),
        mag_db: frf.magnitude_db(),
        phase_deg: frf.phase_deg_unwrapped(),
        mag_band,
        phase_band,
        usable,
        coherence,
    })
}

/// Validate a model response and derive its curves; its phase is shifted by a multiple of
/// 360 degrees to lie closest to `reference` (the measured curves) where they overlap.
pub(crate) fn model_curves(
    frf: &Frf,
    label: &str,
    reference: &Curves,
) -> Result<Curves, PlotError> {
    let n = frf.freq_hz.len();
    if n == 0 {
        return Err(PlotError::Empty {
            what: label.into(),
            reason: "no lines".into(),
        });
    }
    check_len(label, "h", n, frf.h.len())?;
    check_freq(label, &frf.freq_hz)?;
    check_h(label, frf)?;
    let mut phase = frf.phase_deg_unwrapped();
    // Align at the first model line inside the measured range.
    let lo = reference.freq_hz[0];
    let hi = reference.freq_hz[reference.freq_hz.len() - 1];
    if let Some(i) = frf.freq_hz.iter().position(|&f| f >= lo && f <= hi) {
        let r = interp_log(&reference.freq_hz, &reference.phase_deg, frf.freq_hz[i]);
        let shift = ((r - phase[i]) / 360.0).round() * 360.0;
        phase.iter_mut().for_each(|p| *p += shift);
    }
    Ok(Curves {
        freq_hz: frf.freq_hz.clone(),
        mag_db: frf.magnitude_db(),
        phase_deg: phase,
        mag_band: vec![None; n],
        phase_band: vec![None; n],
        usable: vec![true; n],
        coherence: None,
    })
}

/// Linear interpolation of `y` over log frequency at `f` (clamped to the ends).
pub(crate) fn interp_log(freq: &[f64], y: &[f64], f: f64) -> f64 {
    let j = freq.partition_point(|&x| x < f);
    if j == 0 {
        return y[0];
    }
    if j >= freq.len() {
        return y[freq.len() - 1];
    }
    let (f0, f1) = (freq[j - 1].ln(), freq[j].ln());
    let t = (f.ln() - f0) / (f1 - f0);
    y[j - 1] + t * (y[j] - y[j - 1])
}

/// Runs of consecutive usable lines, as index ranges.
pub(crate) fn runs(usable: &[bool]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, &u) in usable.iter().enumerate() {
        match (u, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push(s..i);
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push(s..usable.len());
    }
    out
}

/// Tick steps for magnitude axes [dB].
pub(crate) const DB_STEPS: [f64; 12] = [
    0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0,
];
/// Tick steps for phase axes [deg].
pub(crate) const DEG_STEPS: [f64; 10] = [
    5.0, 15.0, 30.0, 45.0, 90.0, 180.0, 360.0, 720.0, 1440.0, 2880.0,
];

/// Ticks covering `[lo, hi]` with the smallest step from `steps` giving at most `max_ticks`
/// ticks. Returns `(lo', hi', ticks)` with the range widened to whole steps.
pub(crate) fn nice_ticks(
    lo: f64,
    hi: f64,
    max_ticks: usize,
    steps: &[f64],
) -> (f64, f64, Vec<f64>) {
    let (lo, hi) = if hi - lo < 1e-9 {
        (lo - steps[0], hi + steps[0])
    } else {
        (lo, hi)
    };
    let step = steps
        .iter()
        .copied()
        .find(|s| (((hi / s).ceil() - (lo / s).floor()) as usize) < max_ticks)
        .unwrap_or(steps[steps.len() - 1]);
    let a = (lo / step).floor() * step;
    let b = (hi / step).ceil() * step;
    let count = ((b - a) / step).round() as usize;
    let ticks = (0..=count).map(|k| a + k as f64 * step).collect();
    (a, b, ticks)
}

/// Decade (and, for short spans, 2x and 5x) tick frequencies inside `[lo, hi]` [Hz], and the
/// minor grid frequencies (1..9 x 10^k) not among them.
pub(crate) fn log_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    let e0 = lo.log10().floor() as i32;
    let e1 = hi.log10().ceil() as i32;
    let inside = |v: f64| v >= lo * (1.0 - 1e-12) && v <= hi * (1.0 + 1e-12);
    let at = |m: f64, e: i32| m * 10f64.powi(e);
    let decades: Vec<f64> = (e0..=e1)
        .map(|e| at(1.0, e))
        .filter(|&v| inside(v))
        .collect();
    let major: Vec<f64> = if decades.len() >= 2 {
        decades
    } else {
        (e0..=e1)
            .flat_map(|e| [1.0, 2.0, 5.0].map(|m| at(m, e)))
            .filter(|&v| inside(v))
            .collect()
    };
    let minor = (e0..=e1)
        .flat_map(|e| (1..10).map(move |m| at(m as f64, e)))
        .filter(|&v| inside(v) && !major.iter().any(|&t| (t / v - 1.0).abs() < 1e-9))
        .collect();
    (major, minor)
}

/// Text of a frequency tick, e.g. `0.5`, `10`, `1000`.
pub(crate) fn freq_label(v: f64) -> String {
    let decimals = (-v.log10().floor()).max(0.0) as usize;
    format!("{v:.decimals$}")
}

/// Text of a marker frequency: 3 significant digits at least, 1 decimal from 10 Hz to 1 kHz
/// (e.g. `52.9 Hz`).
pub(crate) fn marker_freq_text(f: f64) -> String {
    if f >= 1000.0 {
        format!("{f:.0} Hz")
    } else if f >= 10.0 {
        format!("{f:.1} Hz")
    } else {
        let d = (2.0 - f.log10().floor()).max(1.0) as usize;
        format!("{f:.d$} Hz")
    }
}
