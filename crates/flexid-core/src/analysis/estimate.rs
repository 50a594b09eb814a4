use super::AnalysisError;
use crate::excitation::ExcitationKind;
use crate::frf::{self, Frf, FrfKind, NonExcitedLevels};
use crate::recording::{MotionSignal, Recording};
use num_complex::Complex64;

/// Longest Welch segment [samples]: segments grow with the record (at least 16 of them,
/// half overlapping) up to this length, 8192 lines; a longer record buys more averages, not
/// finer lines (at 1 to 8 kHz that is 0.12 to 1 Hz, finer than the features a chain's
/// damping lets apart, while the fit's cost grows with the lines).
const MAX_SEGMENT: usize = 1 << 14;

/// The FRF of a recording and how it was obtained.
#[derive(Debug, Clone)]
pub struct EstimatedFrf {
    /// Torque -> motion response on the excited lines (periodic) or all Welch lines.
    pub frf: Frf,
    /// Levels at the non-excited lines (periodic excitation only).
    pub nonexcited: Option<NonExcitedLevels>,
    /// "periodic", "realisations" (several multisine realisations), "stepped", "lpm" (one
    /// sweep) or "welch_h1".
    pub method: &'static str,
    /// The motion signal used.
    pub motion: MotionSignal,
    /// Steady periods (periodic) or segments (Welch) averaged.
    pub averages: usize,
    /// How the estimate was made, in words for the report: the estimator, window,
    /// segment or period length and resolution, averages, what was removed.
    pub choices: String,
    /// Several realisations of a multisine only: the variance of `frf.h` from the noise
    /// alone, line by line (`frf.var` is the spread over realisations: noise and the
    /// stochastic nonlinear distortion), and the periods it is worth as a variance's
    /// degrees of freedom ([`frf::estimate_realisations`]). `None` for the other
    /// estimators, whose variance is the noise's.
    pub noise_var: Option<(Vec<f64>, usize)>,
}

/// The recording's excitation when it is periodic (a multisine or stepped design with a
/// period), `None` for anything else (a chirp, a trajectory, no description): the test
/// that picks the periodic estimator in [`estimate_frf`], and the trajectory path of the
/// diagnosis.
pub fn periodic_excitation(rec: &Recording) -> Option<&crate::excitation::ExcitationInfo> {
    rec.sidecar.excitation.as_ref().filter(|e| {
        e.kind != ExcitationKind::Other && e.kind != ExcitationKind::Chirp && e.period_samples > 0
    })
}

/// Whether the estimator reads a steady state of a periodic excitation (a periodic
/// multisine after its transient periods, or stepped-sine blocks after their settle
/// periods): a noise-free linear simulation's estimate is then the exact response at its
/// lines. A sweep's local polynomial and a Welch estimate are not (the window's bias at a
/// narrow resonance, the record's start and end).
pub fn reads_steady_state(rec: &Recording) -> bool {
    periodic_excitation(rec).is_some() || stepped_blocks(rec).is_some()
}

/// The description of a recording that is one swept sine (not periodic): its estimate is
/// the local polynomial method's ([`frf::estimate_lpm`]).
pub fn single_sweep(rec: &Recording) -> Option<&crate::excitation::ExcitationInfo> {
    rec.sidecar
        .excitation
        .as_ref()
        .filter(|e| e.kind == ExcitationKind::Chirp && e.period_samples == 0)
}

/// The dwell blocks of a stepped-sine recording whose description carries them.
fn stepped_blocks(rec: &Recording) -> Option<&[crate::excitation::SteppedBlock]> {
    rec.sidecar
        .excitation
        .as_ref()
        .filter(|e| e.kind == ExcitationKind::SteppedSine && e.period_samples == 0)
        .map(|e| e.blocks.as_slice())
        .filter(|b| !b.is_empty())
}

/// Estimate the torque -> motion FRF of a recording.
///
/// Position is differenced to velocity (never `j w` times the DFT of a drifting position);
/// periodic excitation uses the per-line periodic estimator with its variance, a stepped
/// sine with its blocks the same estimator block by block, a single sweep the local
/// polynomial method, anything else the Welch H1 estimator with coherence. The result is
/// limited to the excited band, or to `band_hz` when given.
pub fn estimate_frf(
    rec: &Recording,
    band_hz: Option<[f64; 2]>,
) -> Result<EstimatedFrf, AnalysisError> {
    let (motion, signal) = rec.preferred_motion().ok_or(AnalysisError::NoMotion)?;
    // an encoder's counts: their repeating error is part of each line's variance
    let quantum = match motion {
        MotionSignal::Position | MotionSignal::Velocity => frf::quantisation::grid_step(signal),
        MotionSignal::Acceleration => None,
    };
    estimate_motion(rec, motion, signal, quantum, band_hz)
}

/// [`estimate_frf`] of the response `signal` [rad, rad/s or rad/s² by `motion`] to the
/// recording's torque command (any motion columns of `rec` are not read), with the grid
/// step `quantum` of `signal` [its unit] when it lies on an encoder's counts (`None`: no
/// count error in the line variances; `h` does not depend on it). For a simulated response
/// ([`crate::diagnose::nlsim::sim_frf`]): the measurement's estimator without copying its
/// recording or searching a smooth signal for a grid.
pub fn estimate_motion(
    rec: &Recording,
    motion: MotionSignal,
    signal: &[f64],
    quantum: Option<f64>,
    band_hz: Option<[f64; 2]>,
) -> Result<EstimatedFrf, AnalysisError> {
    let fs = rec.sample_rate_hz;
    let kind = motion_frf_kind(motion);
    let y = match motion {
        MotionSignal::Position => frf::differenced_velocity(signal, fs),
        MotionSignal::Velocity | MotionSignal::Acceleration => signal.to_vec(),
    };
    let response = Response {
        y: &y,
        kind,
        quantum: quantum.map(|q| (q, signal)),
        words: motion_words(motion),
    };
    let r = estimate_response(rec, &response, band_hz)?;
    Ok(EstimatedFrf {
        frf: r.frf,
        nonexcited: r.nonexcited,
        method: r.method,
        motion,
        averages: r.averages,
        choices: r.choices,
        noise_var: r.noise_var,
    })
}

/// The kind of FRF [`estimate_motion`] takes of a motion: a position is differenced to a
/// velocity (never `j w` times the DFT of a drifting position), an acceleration is no
/// kind of motion the chain's asymptote knows.
pub fn motion_frf_kind(motion: MotionSignal) -> FrfKind {
    match motion {
        MotionSignal::Position => FrfKind::DifferencedVelocity,
        MotionSignal::Velocity => FrfKind::Velocity,
        MotionSignal::Acceleration => FrfKind::Other,
    }
}

/// The drive's torque reading against its command, `T_act / T_cmd`, on the excited lines
/// (the same estimator as [`estimate_frf`] picks, kind [`FrfKind::Other`]: nothing
/// differenced, no ramp removed); `None` when the recording has no `torque_actual_nm`.
pub fn estimate_torque_path(
    rec: &Recording,
    band_hz: Option<[f64; 2]>,
) -> Option<Result<ResponseEstimate, AnalysisError>> {
    let y = rec.torque_actual_nm.as_deref()?;
    let response = Response {
        y,
        kind: FrfKind::Other,
        quantum: None,
        words: "; the drive's torque reading (torque_actual_nm) as the response",
    };
    Some(estimate_response(rec, &response, band_hz))
}

/// A response signal to estimate against the torque command.
struct Response<'a> {
    y: &'a [f64],
    kind: FrfKind,
    /// The grid step of the signal the response comes from, and that signal: its
    /// repeating count error is part of each line's variance.
    quantum: Option<(f64, &'a [f64])>,
    /// How the response entered the estimate, a clause of the choices sentence.
    words: &'static str,
}

/// A response's estimate: [`EstimatedFrf`] without the motion signal.
#[derive(Debug, Clone)]
pub struct ResponseEstimate {
    pub frf: Frf,
    pub nonexcited: Option<NonExcitedLevels>,
    pub method: &'static str,
    pub averages: usize,
    pub choices: String,
    /// As [`EstimatedFrf::noise_var`].
    pub noise_var: Option<(Vec<f64>, usize)>,
}

/// Estimate the response `resp.y` to the torque command: the estimator chosen by the
/// recording's excitation (see [`estimate_frf`]), limited to its band or `band_hz`.
fn estimate_response(
    rec: &Recording,
    resp: &Response,
    band_hz: Option<[f64; 2]>,
) -> Result<ResponseEstimate, AnalysisError> {
    let fs = rec.sample_rate_hz;
    let (u, y, kind) = (&rec.torque_cmd_nm, resp.y, resp.kind);
    let grid_words = resp.quantum.map_or(String::new(), |(q, _)| {
        format!("; the motion lies on a grid of {q:.4e} (an encoder count), whose error, as far as it repeats from period to period, is added to each line's variance")
    });
    let periodic = periodic_excitation(rec);
    let stepped = stepped_blocks(rec);
    let mut out = if let Some(info) = periodic.filter(|e| !e.realisations.is_empty()) {
        realisations_estimate(info, u, y, fs, kind, resp.words)?
    } else if let Some(blocks) = stepped {
        let frf = frf::estimate_stepped(blocks, u, y, fs, kind, resp.quantum)?;
        let periods = blocks.iter().map(|b| b.periods).min().unwrap_or(0);
        let choices = format!(
            "FRF: stepped sine, each of the {} dwell blocks its own periodic experiment (its settle periods dropped, at least {periods} steady periods averaged, no window), one line per block, line variance from the period-to-period scatter{grid_words}{}",
            blocks.len(),
            resp.words
        );
        ResponseEstimate {
            frf,
            nonexcited: None,
            averages: periods,
            method: "stepped",
            choices,
            noise_var: None,
        }
    } else if let Some(info) = single_sweep(rec) {
        // an encoder's count error follows the sweep: not in the windows' residual
        let floor = resp.quantum.map_or(0.0, |(q, _)| q * q / 12.0);
        let count_words = resp.quantum.map_or(String::new(), |(q, _)| {
            format!("; the motion lies on a grid of {q:.4e} (an encoder count), whose error's level q^2/12 is added to each line's variance")
        });
        // the user's band first, else the sweep's own
        let mut frf =
            frf::estimate_lpm_with_floor(u, y, fs, kind, band_hz.or(info.band_hz), floor)?;
        if let Some((q, _)) = resp.quantum {
            frf::quantisation::add_sweep_tone_variance(&mut frf, q, u);
        }
        let q = frf::lpm_dof();
        let width = 2 * frf::lpm::HALF_WIDTH + 1;
        let choices = format!(
            "FRF: local polynomial method on the whole sweep ({} samples, {:.1} s, no window; {:.4} Hz DFT lines): in each window of {width} lines the response and the transient are polynomials of degree {}, one estimate per window ({:.4} Hz apart) with the noise variance from the fit's residual ({q} complex degrees of freedom){count_words}{}",
            u.len(),
            u.len() as f64 / fs,
            fs / u.len() as f64,
            frf::lpm::DEGREE,
            width as f64 * fs / u.len() as f64,
            resp.words
        );
        ResponseEstimate {
            frf,
            nonexcited: None,
            // a variance with q complex dof is that of q + 1 averages
            averages: q + 1,
            method: "lpm",
            choices,
            noise_var: None,
        }
    } else if let Some(info) = periodic {
        // nothing sized by the description before it is checked against the record
        if info.period_samples > u.len() {
            return Err(frf::FrfError::TooShort {
                needed: info.period_samples,
                got: u.len(),
                unit: "samples (one period of the sidecar's excitation)",
            }
            .into());
        }
        let repeating = resp
            .quantum
            .and_then(|(q, signal)| repeating_per_line(q, signal, info));
        let mut est =
            frf::PeriodicEstimator::from_info(info, fs, kind)?.with_quantum_spectrum(repeating);
        est.push(u, y)?;
        let frf = est.estimate()?;
        let choices = format!(
            "FRF: periodic estimator, {} steady periods of {} samples averaged ({:.4} Hz lines, no window: the excitation is periodic), line variance from the period-to-period scatter{grid_words}{}",
            est.periods_done(),
            info.period_samples,
            fs / info.period_samples as f64,
            resp.words
        );
        ResponseEstimate {
            nonexcited: est.nonexcited().ok(),
            averages: est.periods_done(),
            frf,
            method: "periodic",
            choices,
            noise_var: None,
        }
    } else {
        let n = u.len();
        let mut nperseg = 256usize;
        while nperseg * 16 <= n && nperseg < MAX_SEGMENT {
            nperseg *= 2;
        }
        if n < nperseg {
            return Err(AnalysisError::TooShort {
                samples: n,
                needed: nperseg,
            });
        }
        let mut w = frf::WelchH1::new(nperseg, nperseg / 2, frf::Window::Hann, fs)?.with_kind(kind);
        w.push(u, y)?;
        let choices = format!(
            "FRF: Welch H1 (the excitation is not periodic), {n} samples ({:.1} s) in {} Hann-windowed segments of {nperseg} samples ({:.4} Hz lines), half overlapping ({:.1} independent averages); the segment grows with the record to keep at least 16 segments, up to {MAX_SEGMENT} samples; each segment's mean removed (a velocity offset); line variance from the coherence and the averages{}",
            n as f64 / fs,
            w.segments(),
            fs / nperseg as f64,
            w.effective_averages(),
            resp.words
        );
        ResponseEstimate {
            frf: w.estimate()?,
            nonexcited: None,
            averages: w.segments(),
            method: "welch_h1",
            choices,
            noise_var: None,
        }
    };
    let band = band_hz.or_else(|| {
        rec.sidecar
            .excitation
            .as_ref()
            .and_then(|e| e.band_hz)
            .filter(|_| out.method == "welch_h1")
    });
    // the lines kept: in the band, with input (a zero or non-finite response is none)
    let keep: Vec<bool> = (0..out.frf.len())
        .map(|i| {
            let (f, h) = (out.frf.freq_hz[i], out.frf.h[i]);
            band.is_none_or(|[lo, hi]| f >= lo && f <= hi)
                && h.re.is_finite()
                && h.im.is_finite()
                && h.norm() != 0.0
        })
        .collect();
    if keep.iter().any(|k| !k) {
        let mut i = 0;
        out.frf.retain_band(|_| {
            i += 1;
            keep[i - 1]
        });
        if let Some((v, _)) = out.noise_var.as_mut() {
            let mut i = 0;
            v.retain(|_| {
                i += 1;
                keep[i - 1]
            });
        }
    }
    if out.frf.is_empty() {
        return Err(AnalysisError::NoLines);
    }
    Ok(out)
}

/// The best linear approximation over the realisations of a multisine
/// ([`frf::estimate_realisations`]).
fn realisations_estimate(
    info: &crate::excitation::ExcitationInfo,
    u: &[f64],
    y: &[f64],
    fs: f64,
    kind: FrfKind,
    words: &str,
) -> Result<ResponseEstimate, AnalysisError> {
    let e = frf::estimate_realisations(
        u,
        y,
        fs,
        info.period_samples,
        &info.realisations,
        &info.excited_lines,
        kind,
    )?;
    let r = e.realisations;
    // the noise spectrum's bins average `segments` Hann periodograms: about 2 real degrees
    // of freedom each, as many as `segments + 1` periods give a line's variance
    let noise_var = e.noise_var.map(|v| (v, e.noise_segments + 1));
    let noise_words = match &noise_var {
        Some((_, p)) => format!(
            "; the noise alone from the repeated lead-ins ({} Hann segments, worth {p} periods), for the models that reproduce the distortion",
            e.noise_segments
        ),
        None => "; no noise estimate (no repeated lead-in)".to_string(),
    };
    let choices = format!(
        "FRF: best linear approximation over {r} realisations of the multisine (one steady period of {} samples each after its lead-in, {:.4} Hz lines, no window): the mean of Y/U per line, its variance from the spread over the realisations (noise and stochastic nonlinear distortion){noise_words}{}",
        info.period_samples,
        fs / info.period_samples as f64,
        words
    );
    Ok(ResponseEstimate {
        frf: e.frf,
        nonexcited: e.nonexcited,
        method: "realisations",
        averages: r,
        choices,
        noise_var,
    })
}

/// How the motion signal entered the estimate, as a clause of the choices sentence.
fn motion_words(motion: MotionSignal) -> &'static str {
    match motion {
        MotionSignal::Position => {
            "; the position differenced to a velocity (a drift becomes an offset, which carries no line)"
        }
        MotionSignal::Velocity => "; the recorded velocity",
        MotionSignal::Acceleration => "; the recorded acceleration",
    }
}

/// A mobility-like view of an FRF whose kind the chain fit does not take: a measured
/// velocity is taken as the differenced one, an acceleration is divided by `j w`.
/// Good enough to locate resonances; not for the parameter fit.
pub(crate) fn mobility_equivalent(frf: &Frf) -> Frf {
    let mut out = frf.clone();
    if frf.kind == FrfKind::Other {
        for (i, f) in frf.freq_hz.iter().enumerate() {
            let jw = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            out.h[i] = frf.h[i] / jw;
            out.var[i] = frf.var[i] / jw.norm_sqr();
        }
    }
    out.kind = FrfKind::DifferencedVelocity;
    out
}

/// The repeating quantisation error of a periodic record on a grid of step `q`, per line
/// of a period ([`frf::quantisation_spectrum`]), placed by the speed of the periods' mean
/// at the excited lines (without those, e.g. lines to be inferred, spread evenly). Two
/// readings of how much of the error the periods share, the larger taken line by line:
/// the noise behind the counts new at every sample, taken from the whole period-to-period
/// scatter ([`frf::quantisation::noise_std_from_scatter`]), and the slow wander between
/// the periods with the noise from the fast rest ([`frf::quantisation_correlation`]). Each
/// misses what the other holds (the first calls a wander of several counts noise, the
/// second reads a wander that changes within its window as noise), and a variance too
/// small is what makes noise look like a gap.
fn repeating_per_line(
    q: f64,
    signal: &[f64],
    info: &crate::excitation::ExcitationInfo,
) -> Option<Vec<f64>> {
    use frf::quantisation_spectrum::MAX_HARMONIC;
    let n = info.period_samples.max(1);
    let start = (info.transient_periods * n).min(signal.len());
    let periods = info.periods.min((signal.len() - start) / n);
    let steady = &signal[start..];
    let c = q * q / (2.0 * std::f64::consts::PI.powi(2));
    let power = |g: &[f64]| -> f64 {
        g.iter()
            .enumerate()
            .map(|(i, g)| c / ((i + 1) * (i + 1)) as f64 * g)
            .sum()
    };
    let speed = frf::quantisation_spectrum::periodic_speed(steady, n, periods, &info.excited_lines);
    let per_line = |gains: &[f64], tail: f64| -> Vec<f64> {
        match &speed {
            Some(speed) => frf::quantisation_spectrum::shared_spectrum(q, gains, tail, speed),
            None => vec![(power(gains) + tail).max(0.0); n / 2 + 1],
        }
    };
    // noise new at every sample, from the whole scatter
    let scatter = frf::quantisation::scatter_std(steady, n, periods).unwrap_or(0.0);
    let sigma = frf::quantisation::noise_std_from_scatter(q, scatter);
    let damp = 4.0 * std::f64::consts::PI.powi(2) * (sigma / q).powi(2);
    let g: Vec<f64> = (1..=MAX_HARMONIC)
        .map(|k| (-damp * (k * k) as f64).exp())
        .collect();
    let tail = (frf::quantisation::repeating_variance(q, sigma) - power(&g)).max(0.0);
    let mut floor = per_line(&g, tail);
    // the slow wander between periods
    if let Some(offsets) =
        frf::quantisation_correlation::PeriodOffsets::measure(steady, n, periods, q)
    {
        let g = offsets.gains(offsets.noise_std());
        let tail = (power(&g) - power(&g[..MAX_HARMONIC])).max(0.0);
        let shared = per_line(&g[..MAX_HARMONIC], tail);
        for (f, s) in floor.iter_mut().zip(shared) {
            *f = f.max(s);
        }
    }
    Some(floor)
}
