//! Periodic multisine in torque units [N m] with peak and RMS limits.

use rand::{rngs::StdRng, SeedableRng};
use serde::{Deserialize, Serialize};

use super::lines::{band_lines, odd_random_lines};
use super::phases::{random_phases, schroeder_phases};
use super::stats::{check_limit, crest_factor, peak_abs, rms, scale_to_limits};
use super::synth::LineSynth;
use super::{ExcitationError, ExcitationInfo, ExcitationKind};

/// Relative amplitude of the excited lines, before scaling to the torque limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AmplitudeShape {
    /// Equal amplitude on every excited line.
    Flat,
    /// Amplitude proportional to `f^exponent` (f in Hz of the line); e.g. `exponent = 1`
    /// compensates a plant falling as 1/f.
    PowerLaw {
        /// The exponent (finite; negative values emphasise low frequencies).
        exponent: f64,
    },
    /// One relative amplitude per candidate line of the design (finite, >= 0, not all zero),
    /// increasing in frequency: every line in band for Schroeder / Random, the excited odd
    /// lines for OddRandom. Lines given 0 are left out of [`Multisine::excited_lines`].
    Custom(Vec<f64>),
}

/// Choice of excited lines and their phases.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseDesign {
    /// All lines in band, Schroeder phases (low crest factor, deterministic).
    Schroeder,
    /// All lines in band, independent uniform random phases.
    Random {
        /// Seed of the phase generator (same seed, same signal).
        seed: u64,
    },
    /// Odd random-phase design with detection lines: only odd lines in band are candidates
    /// (even lines stay empty and reveal even nonlinearities); in each group of `group`
    /// consecutive odd lines one, drawn at random, is left out as a detection line (reveals
    /// odd nonlinearities). A trailing partial group is fully excited. Random phases.
    OddRandom {
        /// Seed of the line selection and phase generator.
        seed: u64,
        /// Odd lines per group (>= 2), typically 3 or 4.
        group: usize,
    },
}

impl PhaseDesign {
    /// Design name written to [`ExcitationInfo::design`].
    pub fn name(&self) -> &'static str {
        match self {
            PhaseDesign::Schroeder => "schroeder",
            PhaseDesign::Random { .. } => "random_phase",
            PhaseDesign::OddRandom { .. } => "odd_random_phase",
        }
    }
}

/// Design of a periodic multisine `x[n] = sum_j A_j cos(2 pi k_j n / N + phi_j)` [N m],
/// `N = period_samples`, line `k` at `k * sample_rate_hz / N` Hz.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MultisineDesign {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// Samples per period `N` (>= 4); sets the line spacing `fs / N`.
    pub period_samples: usize,
    /// Excited band `[lo, hi]` \[Hz\], inclusive; DC and the Nyquist line are never excited.
    pub band_hz: [f64; 2],
    /// Relative amplitude shape over the excited lines.
    pub amplitude: AmplitudeShape,
    /// Line selection and phases.
    pub phases: PhaseDesign,
    /// Largest allowed |torque| [N m] (> 0).
    pub peak_limit_nm: f64,
    /// Largest allowed RMS torque [N m] (> 0).
    pub rms_limit_nm: f64,
    /// Crest-factor reduction iterations (clip and re-impose amplitudes); 0 disables it.
    pub crest_iterations: usize,
}

impl MultisineDesign {
    /// Flat Schroeder multisine without crest-factor iterations; adjust the public fields
    /// for other designs.
    pub fn new(
        sample_rate_hz: f64,
        period_samples: usize,
        band_hz: [f64; 2],
        peak_limit_nm: f64,
        rms_limit_nm: f64,
    ) -> Self {
        Self {
            sample_rate_hz,
            period_samples,
            band_hz,
            amplitude: AmplitudeShape::Flat,
            phases: PhaseDesign::Schroeder,
            peak_limit_nm,
            rms_limit_nm,
            crest_iterations: 0,
        }
    }

    /// Line spacing `fs / N` \[Hz\].
    pub fn line_spacing_hz(&self) -> f64 {
        self.sample_rate_hz / self.period_samples as f64
    }

    /// Generates one period, scaled so that `peak <= peak_limit_nm` and
    /// `rms <= rms_limit_nm` with the binding limit met (up to rounding).
    pub fn generate(&self) -> Result<Multisine, ExcitationError> {
        check_limit("peak", self.peak_limit_nm)?;
        check_limit("rms", self.rms_limit_nm)?;
        let candidates = band_lines(self.sample_rate_hz, self.period_samples, self.band_hz)?;
        let df = self.line_spacing_hz();

        let (excited, detection, mut rng) = match self.phases {
            PhaseDesign::Schroeder => (candidates, Vec::new(), None),
            PhaseDesign::Random { seed } => {
                (candidates, Vec::new(), Some(StdRng::seed_from_u64(seed)))
            }
            PhaseDesign::OddRandom { seed, group } => {
                if group < 2 {
                    return Err(ExcitationError::InvalidGroup { group });
                }
                let mut rng = StdRng::seed_from_u64(seed);
                let (exc, det) = odd_random_lines(&candidates, group, &mut rng);
                if exc.is_empty() {
                    return Err(ExcitationError::NoLineInBand {
                        lo_hz: self.band_hz[0],
                        hi_hz: self.band_hz[1],
                        spacing_hz: df,
                    });
                }
                (exc, det, Some(rng))
            }
        };

        let amps = relative_amplitudes(&self.amplitude, &excited)?;
        // Lines given zero amplitude are not excited.
        let (excited, amps): (Vec<usize>, Vec<f64>) = excited
            .iter()
            .zip(&amps)
            .filter(|(_, &a)| a > 0.0)
            .map(|(&k, &a)| (k, a))
            .unzip();
        let phases = match rng.as_mut() {
            None => schroeder_phases(&excited, &amps),
            Some(r) => random_phases(excited.len(), r),
        };

        let n = self.period_samples;
        let mut synth = LineSynth::new(n, &excited, &amps);
        let mut period = vec![0.0; n];
        synth.synthesize(&phases, &mut period)?;
        synth.reduce_crest(&mut period, self.crest_iterations)?;
        let gain = scale_to_limits(&mut period, self.peak_limit_nm, Some(self.rms_limit_nm));
        let mut work = period.clone();
        let phases_rad = synth.line_phases(&mut work)?;

        Ok(Multisine {
            sample_rate_hz: self.sample_rate_hz,
            amplitudes_nm: amps.iter().map(|a| a * gain).collect(),
            phases_rad,
            period,
            excited_lines: excited,
            detection_lines: detection,
            design: self.phases.name().to_string(),
        })
    }
}

/// Relative amplitudes per excited line for a shape; validates custom lists and exponents.
fn relative_amplitudes(
    shape: &AmplitudeShape,
    lines: &[usize],
) -> Result<Vec<f64>, ExcitationError> {
    match shape {
        AmplitudeShape::Flat => Ok(vec![1.0; lines.len()]),
        AmplitudeShape::PowerLaw { exponent } => {
            if !exponent.is_finite() {
                return Err(ExcitationError::InvalidExponent {
                    exponent: *exponent,
                });
            }
            // f = k * spacing: the common factor cancels; relative to the first line.
            let k0 = lines[0] as f64;
            let amps: Vec<f64> = lines
                .iter()
                .map(|&k| (k as f64 / k0).powf(*exponent))
                .collect();
            check_amplitudes(&amps)?;
            Ok(amps)
        }
        AmplitudeShape::Custom(a) => {
            if a.len() != lines.len() {
                return Err(ExcitationError::AmplitudeLengthMismatch {
                    expected: lines.len(),
                    got: a.len(),
                });
            }
            check_amplitudes(a)?;
            // Normalise to max 1 so squares cannot overflow.
            let top = a.iter().cloned().fold(0.0, f64::max);
            Ok(a.iter().map(|v| v / top).collect())
        }
    }
}

fn check_amplitudes(a: &[f64]) -> Result<(), ExcitationError> {
    if let Some((index, &value)) = a
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
    {
        return Err(ExcitationError::InvalidAmplitude { index, value });
    }
    if a.iter().all(|&v| v == 0.0) {
        return Err(ExcitationError::InvalidAmplitude {
            index: 0,
            value: 0.0,
        });
    }
    Ok(())
}

/// One period of a generated multisine [N m] and its line spectrum.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Multisine {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// One period [N m]; `period.len()` is the period length `N` in samples.
    pub period: Vec<f64>,
    /// Excited DFT lines of the period (increasing); line `k` is at `k * fs / N` Hz.
    pub excited_lines: Vec<usize>,
    /// Odd detection lines left out by [`PhaseDesign::OddRandom`] (increasing); empty for
    /// the other designs.
    pub detection_lines: Vec<usize>,
    /// Cosine amplitude `A_j` [N m] per excited line (same order as `excited_lines`).
    pub amplitudes_nm: Vec<f64>,
    /// Cosine phase `phi_j` \[rad\] per excited line, in `(-pi, pi]`.
    pub phases_rad: Vec<f64>,
    /// Design name, e.g. `"schroeder"`, `"random_phase"`, `"odd_random_phase"`.
    pub design: String,
}

impl Multisine {
    /// Samples per period `N`.
    pub fn period_samples(&self) -> usize {
        self.period.len()
    }

    /// Line spacing `fs / N` \[Hz\].
    pub fn line_spacing_hz(&self) -> f64 {
        self.sample_rate_hz / self.period.len() as f64
    }

    /// Frequencies \[Hz\] of the excited lines.
    pub fn excited_frequencies_hz(&self) -> Vec<f64> {
        let df = self.line_spacing_hz();
        self.excited_lines.iter().map(|&k| k as f64 * df).collect()
    }

    /// Crest factor `peak / rms` of the period (dimensionless).
    pub fn crest_factor(&self) -> f64 {
        crest_factor(&self.period)
    }

    /// Peak |torque| [N m].
    pub fn peak_nm(&self) -> f64 {
        peak_abs(&self.period)
    }

    /// RMS torque [N m] (over one period, hence over any whole number of periods).
    pub fn rms_nm(&self) -> f64 {
        rms(&self.period)
    }

    /// The period repeated `total_periods` times (transient periods included) [N m].
    pub fn repeat(&self, total_periods: usize) -> Vec<f64> {
        self.period.repeat(total_periods)
    }

    /// Description of a recording of `transient_periods + periods` repetitions, the first
    /// `transient_periods` to be discarded.
    pub fn info(&self, periods: usize, transient_periods: usize) -> ExcitationInfo {
        let band_hz = super::lines::band_of(&self.excited_lines, self.line_spacing_hz());
        ExcitationInfo {
            kind: ExcitationKind::Multisine,
            period_samples: self.period.len(),
            periods,
            transient_periods,
            excited_lines: self.excited_lines.clone(),
            band_hz,
            peak_nm: Some(self.peak_nm()),
            rms_nm: Some(self.rms_nm()),
            design: Some(self.design.clone()),
            blocks: Vec::new(),
            realisations: Vec::new(),
            band_limited: false,
        }
    }
}

#[cfg(test)]
#[path = "multisine_tests.rs"]
mod tests;
