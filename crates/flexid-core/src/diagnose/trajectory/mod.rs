//! The time-domain path of the diagnosis, for non-periodic (trajectory) recordings of a
//! rigid axis, often measured in closed loop: the inverse dynamic identification model
//! with least squares (IDIM-LS; Gautier 1997, Janot, Gautier & Brunot 2019) of a rigid
//! body with Coulomb and viscous friction and a force offset,
//! `tau = M qdd + Fv qd + Fc sign(qd) + offset`.
//!
//! The steps, each a function:
//!
//! 1. [`spectrum::cutoff`]: the cut-off frequency `fc` [Hz] **from the data**: where the
//!    position's power spectrum (of its first difference, divided by the difference's
//!    response) meets its white-noise floor (the median PSD over `[fs/4, 0.45 fs]`),
//!    i.e. the first frequency at which the spectrum smoothed over a third of an octave
//!    is at most twice the floor (motion power equal to noise power). Below it the
//!    position holds motion, above it noise that the second difference amplifies as `f²`.
//!    (The IDIM rule of thumb, `fc >= 5` times the closed loop's highest natural
//!    frequency, needs the loop's bandwidth, which a recording without the reference
//!    position does not show; the noise-floor rule needs nothing but the position.)
//! 2. Zero-order hold ([`idim::held_force`]): a command acts over its sample, after the
//!    recording's `io_delay_samples`; the central second difference at `k` sees the mean
//!    of the forces of samples `k-1` and `k`, so that mean is the equation's force.
//! 3. [`butterworth::Butterworth`]: a 4th-order Butterworth low-pass at `fc`, run
//!    forward and backward (zero phase, `|H|²`), on the position.
//! 4. [`differences`]: velocity and acceleration by central differences of the filtered
//!    position.
//! 5. Parallel filtering: the same zero-phase low-pass on the force and on the Coulomb
//!    column `sign(qd)`, so that every term of the equation passes the filter once.
//! 6. Decimation: one sample in `floor(fs / (2 fc))` (the filtered equations hold nothing
//!    above `fc`: consecutive samples closer than that carry no new information and
//!    would make the least-squares standard deviations too small); `memory` samples are
//!    dropped at each end (the filter's transient).
//! 7. The sign test: a sample is used only where `|qd|` exceeds 3 standard deviations of
//!    the velocity estimate's noise (the position's floor through the filter and the
//!    difference): below that `sign(qd)` is a guess, and near standstill the friction is
//!    pre-sliding or stiction, which `Fc sign(qd)` does not describe. Such samples are
//!    left out, not given `sign(0) = 0`, and so are those within the span of the
//!    zero-phase filter's impulse response (99 % of its absolute sum) around them, whose
//!    filtered force mixes in the standstill's.
//! 8. [`idim::least_squares`] via the SVD: the parameters, `sigma² (X^T X)^-1` with
//!    `sigma² = RSS/(N - p)`, the condition number of `X`, the relative force error
//!    `||y - X theta|| / ||y||`.
//!
//! Three nested models are fitted: the rigid body (`M`, offset), with viscous friction,
//! and with Coulomb and viscous friction. What is named is decided in
//! [`diagnosis`].
//!
//! Units: the recording's. The force column is `torque_cmd_nm` [N m] and the position
//! `position_rad` [rad], so `M` is in kg m², `Fv` in N m s/rad, `Fc` and the offset in
//! N m. A prismatic axis whose columns hold N and m reads kg, N s/m and N.

pub mod butterworth;
pub mod diagnosis;
pub mod differences;
pub mod idim;
pub mod spectrum;

#[cfg(test)]
mod closed_loop;
#[cfg(test)]
mod tests;

use crate::diagnose::effects::viscous::SIGNIFICANT_SIGMA;
use butterworth::Butterworth;
use idim::{LsFit, Processing, Samples};

/// The Butterworth order (forward-backward: 8 poles of attenuation, no phase), as in the
/// IDIM literature.
pub const ORDER: usize = 4;

/// Samples a record needs at least (for the noise floor's spectrum).
pub const MIN_SAMPLES: usize = 1024;

/// Errors of the trajectory path.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    #[error("the trajectory path needs a position column (position_rad)")]
    NoPosition,
    #[error("{samples} samples; the trajectory path needs at least {needed}")]
    TooShort { samples: usize, needed: usize },
    #[error("{column} is not finite at row {row}")]
    NotFinite { column: &'static str, row: usize },
    #[error("the sample rate {0} Hz is not positive and finite")]
    Rate(f64),
    #[error("no noise floor: the position or the force is constant")]
    NoFloor,
    #[error("the position does not rise above its noise floor: cut-off {cutoff_hz:.3} Hz at a Welch resolution of {resolution_hz:.3} Hz (is the axis moving?)")]
    NoMotion { cutoff_hz: f64, resolution_hz: f64 },
    #[error("only {used} of {candidates} decimated samples move fast enough for the velocity's sign to be trusted (|qd| > {threshold_rad_s:.3e} rad/s); need {needed}")]
    TooFewSamples {
        used: usize,
        candidates: usize,
        threshold_rad_s: f64,
        needed: usize,
    },
    #[error("the observation matrix of the {0} model is rank-deficient: the trajectory does not excite its parameters separately")]
    Degenerate(&'static str),
    #[error("the fitted inertia is {0:.4e}, not positive: the force and position columns have opposite sign conventions")]
    NegativeInertia(f64),
    #[error("the cross-test recording's sample rate {got} Hz differs from the estimation recording's {want} Hz")]
    CrossRate { got: f64, want: f64 },
}

/// Which of the three nested models is kept (the model "with friction").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kept {
    Rigid,
    RigidViscous,
    RigidFriction,
}

/// A record the parameters were applied to without refitting (cross-test validation).
#[derive(Debug, Clone, PartialEq)]
pub struct CrossTest {
    /// Index of the recording (in the order given; 0 is the estimation record).
    pub recording: usize,
    pub samples: usize,
    /// `||y - X theta|| / ||y||` with the kept model's parameters.
    pub relative_error: f64,
}

/// The identification of one trajectory record, and what it means.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryFit {
    pub cutoff: spectrum::Cutoff,
    pub processing: Processing,
    /// Samples in the record.
    pub samples_total: usize,
    /// Decimated samples inside the edges.
    pub candidates: usize,
    /// Of those, used (sign of the velocity trusted).
    pub used: usize,
    /// Noise of the velocity estimate [rad/s] (the sign test is 3 of it).
    pub velocity_noise_rad_s: f64,
    /// The residual the noise floors alone predict per sample [N m].
    pub noise_rms_nm: f64,
    /// `||F(tau)||` over the used samples [N m].
    pub force_norm_nm: f64,
    /// The rigid body: inertia and offset.
    pub rigid: LsFit,
    /// With viscous friction.
    pub rigid_viscous: LsFit,
    /// With Coulomb and viscous friction (the IDIM model).
    pub rigid_friction: LsFit,
    /// `Fv / sigma(Fv)` in the viscous model, and its BIC score over the rigid body
    /// (`N ln(RSS_rigid / RSS_viscous) - ln N`).
    pub viscous_sigmas: f64,
    pub viscous_score: f64,
    pub viscous_significant: bool,
    /// `Fc / sigma(Fc)` in the full model, and its BIC score over the viscous model.
    pub coulomb_sigmas: f64,
    pub coulomb_score: f64,
    /// Coulomb friction named: at least 3 sigma from zero and a positive BIC score.
    pub coulomb_named: bool,
    /// The model with the friction that is kept.
    pub kept: Kept,
    /// `(RSS / N) / noise²` below which a model's residual is noise: `1 + 3 sqrt(2/N)`
    /// (the reduced chi² of N independent Gaussian residuals, mean 1, sigma `sqrt(2/N)`).
    pub within_noise_threshold: f64,
    pub cross_tests: Vec<CrossTest>,
    /// The equations used, for a plot.
    pub trace: Trace,
}

/// The filtered force and the two models' forces at the samples used (for a plot).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    pub time_s: Vec<f64>,
    /// `F(tau)` [N m].
    pub force_nm: Vec<f64>,
    /// The rigid body without friction [N m].
    pub rigid_nm: Vec<f64>,
    /// The model kept [N m].
    pub kept_nm: Vec<f64>,
}

impl TrajectoryFit {
    /// The kept model's fit.
    pub fn kept_fit(&self) -> &LsFit {
        match self.kept {
            Kept::Rigid => &self.rigid,
            Kept::RigidViscous => &self.rigid_viscous,
            Kept::RigidFriction => &self.rigid_friction,
        }
    }

    /// `(RSS / N) / noise²` of a model (1: the residual is the predicted noise).
    pub fn reduced_chi2(&self, fit: &LsFit) -> f64 {
        fit.rss / fit.samples as f64 / self.noise_rms_nm.powi(2)
    }

    /// Whether a model's residual is within the noise the floors predict.
    pub fn within_noise(&self, fit: &LsFit) -> bool {
        self.reduced_chi2(fit) < self.within_noise_threshold
    }
}

/// The position and force of a recording, checked.
fn columns(rec: &crate::recording::Recording) -> Result<(&[f64], &[f64]), TrajectoryError> {
    let q = rec
        .position_rad
        .as_deref()
        .ok_or(TrajectoryError::NoPosition)?;
    let tau = rec.torque_cmd_nm.as_slice();
    let n = q.len().min(tau.len());
    if n < MIN_SAMPLES {
        return Err(TrajectoryError::TooShort {
            samples: n,
            needed: MIN_SAMPLES,
        });
    }
    for (column, v) in [("position_rad", q), ("torque_cmd_nm", tau)] {
        if let Some(row) = v.iter().position(|x| !x.is_finite()) {
            return Err(TrajectoryError::NotFinite { column, row });
        }
    }
    let fs = rec.sample_rate_hz;
    if !(fs.is_finite() && fs > 0.0) {
        return Err(TrajectoryError::Rate(fs));
    }
    Ok((&q[..n], &tau[..n]))
}

/// The recording's whole-sample delay of the force beyond the hold (0 when not said).
fn io_delay(rec: &crate::recording::Recording) -> usize {
    rec.sidecar.io_delay_samples.unwrap_or(0) as usize
}

/// The processing of a record: the cut-off from its spectra, the filter, the decimation,
/// the edges and the velocity test.
fn processing(
    q: &[f64],
    tau: &[f64],
    fs: f64,
) -> Result<(spectrum::Cutoff, Processing, f64, idim::NoiseGains), TrajectoryError> {
    let cut = spectrum::cutoff(q, tau, fs).ok_or(TrajectoryError::NoFloor)?;
    let no_motion = TrajectoryError::NoMotion {
        cutoff_hz: cut.cutoff_hz,
        resolution_hz: cut.resolution_hz,
    };
    if cut.cutoff_hz < 4.0 * cut.resolution_hz {
        return Err(no_motion);
    }
    let filter = Butterworth::low_pass(ORDER, cut.cutoff_hz, fs).ok_or(no_motion)?;
    let gains = idim::noise_gains(&filter);
    let v_noise = idim::velocity_noise_rad_s(cut.position_floor_rad2_per_hz, fs, &gains);
    let p = Processing {
        spread_samples: Processing::spread_samples(&filter),
        decimation: ((fs / (2.0 * cut.cutoff_hz)).floor() as usize).max(1),
        edge_samples: filter.memory_samples(),
        velocity_threshold_rad_s: SIGNIFICANT_SIGMA * v_noise,
        filter,
    };
    Ok((cut, p, v_noise, gains))
}

/// `N ln(RSS_without / RSS_with) - added ln N`: the BIC score of the larger model (> 0:
/// the residual fell by more than the price of the parameters added; the noise variance
/// is unknown and estimated by each model's own residual).
pub fn bic_score(without: &LsFit, with: &LsFit, added: usize) -> f64 {
    let n = with.samples as f64;
    n * (without.rss / with.rss).ln() - added as f64 * n.ln()
}

/// Identify the rigid body with friction on a recording (its position and force).
pub fn identify(rec: &crate::recording::Recording) -> Result<TrajectoryFit, TrajectoryError> {
    let (q, tau) = columns(rec)?;
    let fs = rec.sample_rate_hz;
    let (cut, p, v_noise, gains) = processing(q, tau, fs)?;
    let s: Samples = idim::equations(q, tau, io_delay(rec), &p);
    let needed = 10 * idim::RIGID_FRICTION.len();
    if s.len() < needed {
        return Err(TrajectoryError::TooFewSamples {
            used: s.len(),
            candidates: s.candidates,
            threshold_rad_s: p.velocity_threshold_rad_s,
            needed,
        });
    }
    let fit = |cols: &[idim::Column], name| {
        idim::least_squares(&s, cols).ok_or(TrajectoryError::Degenerate(name))
    };
    let rigid = fit(&idim::RIGID, "rigid-body")?;
    let rigid_viscous = fit(&idim::RIGID_VISCOUS, "viscous-friction")?;
    let rigid_friction = fit(&idim::RIGID_FRICTION, "Coulomb-and-viscous-friction")?;
    let m = rigid_friction.value(idim::Column::Inertia);
    if m <= 0.0 {
        return Err(TrajectoryError::NegativeInertia(m));
    }
    let ratio = |f: &LsFit, c| f.param(c).map_or(0.0, |(v, sd)| (v / sd).abs());
    let viscous_sigmas = ratio(&rigid_viscous, idim::Column::Viscous);
    let viscous_score = bic_score(&rigid, &rigid_viscous, 1);
    let coulomb_sigmas = ratio(&rigid_friction, idim::Column::Coulomb);
    let coulomb_score = bic_score(&rigid_viscous, &rigid_friction, 1);
    let viscous_significant = viscous_sigmas >= SIGNIFICANT_SIGMA && viscous_score > 0.0;
    let coulomb_named = coulomb_sigmas >= SIGNIFICANT_SIGMA && coulomb_score > 0.0;
    let kept = if coulomb_named {
        Kept::RigidFriction
    } else if viscous_significant {
        Kept::RigidViscous
    } else {
        Kept::Rigid
    };
    let noise_rms_nm = idim::residual_noise_nm(
        cut.force_floor_nm2_per_hz,
        cut.position_floor_rad2_per_hz,
        fs,
        &gains,
        m,
        rigid_friction.value(idim::Column::Viscous),
    );
    let n = s.len() as f64;
    let trace = Trace {
        time_s: s.index.iter().map(|&k| k as f64 / fs).collect(),
        force_nm: s.tau_nm.clone(),
        rigid_nm: idim::predicted_nm(&s, &rigid),
        kept_nm: idim::predicted_nm(
            &s,
            match kept {
                Kept::Rigid => &rigid,
                Kept::RigidViscous => &rigid_viscous,
                Kept::RigidFriction => &rigid_friction,
            },
        ),
    };
    Ok(TrajectoryFit {
        trace,
        samples_total: q.len(),
        candidates: s.candidates,
        used: s.len(),
        velocity_noise_rad_s: v_noise,
        noise_rms_nm,
        force_norm_nm: s.tau_nm.iter().map(|v| v * v).sum::<f64>().sqrt(),
        rigid,
        rigid_viscous,
        rigid_friction,
        viscous_sigmas,
        viscous_score,
        viscous_significant,
        coulomb_sigmas,
        coulomb_score,
        coulomb_named,
        kept,
        within_noise_threshold: 1.0 + SIGNIFICANT_SIGMA * (2.0 / n).sqrt(),
        cross_tests: Vec::new(),
        cutoff: cut,
        processing: p,
    })
}

/// The kept model's parameters applied to another record, processed the same way (the
/// estimation record's cut-off, decimation, edges and velocity test): the cross-test
/// validation of the IDIM literature.
pub fn cross_test(
    fit: &TrajectoryFit,
    rec: &crate::recording::Recording,
    recording: usize,
) -> Result<CrossTest, TrajectoryError> {
    let (q, tau) = columns(rec)?;
    let want = fit.processing.filter.sample_rate_hz;
    if (rec.sample_rate_hz - want).abs() > 1e-9 * want {
        return Err(TrajectoryError::CrossRate {
            got: rec.sample_rate_hz,
            want,
        });
    }
    let s = idim::equations(q, tau, io_delay(rec), &fit.processing);
    let (_, relative_error) = idim::prediction_error(&s, fit.kept_fit());
    Ok(CrossTest {
        recording,
        samples: s.len(),
        relative_error,
    })
}
