//! A simulated multi-axis measurement of one pose: orthogonal random-phase multisines on
//! every axis at once (the paper's section 3), added to the torque of the position loop
//! the robot is held by, the sampled plant ([`SampledPose`]) stepped sample by sample,
//! encoder noise on the motor positions (fed back by the loop), and the FRF matrix
//! estimated from the total torques and the backward-differenced motor speeds (the direct
//! method) with its variance. The tests' and benchmarks' measurement, and the core of the
//! simulated robot drive.

use super::cost::PoseMeasurement;
use super::pose::RigidPose;
use super::sampled::{PositionLoop, SampledPose};
use super::springs::Flexibilities;
use super::ManipulatorError;
use crate::excitation::{OrthogonalMultisine, OrthogonalMultisineDesign};
use crate::frf::{MimoEstimator, MimoFrf};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// How the pose is measured.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasureOptions {
    /// Sample (drive cycle) rate [Hz].
    pub fs_hz: f64,
    /// Samples per multisine period (the line spacing is `fs / period`).
    pub period_samples: usize,
    /// Excited band [Hz].
    pub band_hz: [f64; 2],
    /// Multisine RMS per axis [N m, motor side].
    pub rms_nm: Vec<f64>,
    /// Blocks of `N` orthogonal experiments.
    pub blocks: usize,
    /// Periods per experiment left to settle, then averaged.
    pub transient_periods: usize,
    pub periods: usize,
    /// Bandwidth of the position loop [Hz].
    pub loop_bandwidth_hz: f64,
    /// Standard deviation of the encoder noise [rad, motor side].
    pub encoder_noise_rad: f64,
    /// Seed of the multisines' phases and of the noise.
    pub seed: u64,
}

impl MeasureOptions {
    /// The measurement the reference arm is identified with (`robots/flexid-arm6`): 1 Hz
    /// lines over 2 Hz to 0.3 `fs` (at most 300 Hz), one block, two settling and six
    /// averaged periods per experiment, a 2 Hz position loop, a 20-bit encoder's noise
    /// (5e-6 rad), multisines of 0.6, 0.6, 0.4 N m RMS on the main axes and 0.1, 0.1,
    /// 0.05 N m on the wrist (0.05 N m on any further axis).
    pub fn for_axes(axes: usize, fs_hz: f64, seed: u64) -> Self {
        let mut rms = vec![0.6, 0.6, 0.4, 0.1, 0.1, 0.05];
        rms.resize(axes, 0.05);
        MeasureOptions {
            fs_hz,
            period_samples: fs_hz.round() as usize,
            band_hz: [2.0, (0.3 * fs_hz).min(300.0)],
            rms_nm: rms,
            blocks: 1,
            transient_periods: 2,
            periods: 6,
            loop_bandwidth_hz: 2.0,
            encoder_noise_rad: 5e-6,
            seed,
        }
    }
}

impl MeasureOptions {
    /// The orthogonal random-phase multisines of this measurement on `axes` axes (its
    /// rate, period, band, levels, blocks and seed).
    pub fn excitation(&self, axes: usize) -> Result<OrthogonalMultisine, ManipulatorError> {
        OrthogonalMultisineDesign {
            rms_nm: self.rms_nm.clone(),
            blocks: self.blocks,
            seed: self.seed,
            ..OrthogonalMultisineDesign::new(
                axes,
                self.fs_hz,
                self.period_samples,
                self.band_hz,
                0.0,
            )
        }
        .generate()
        .map_err(|e| ManipulatorError::Measurement {
            detail: e.to_string(),
        })
    }
}

/// The pose `pose` with springs `theta` measured as `opts` says: the estimate with its
/// variance.
pub fn simulate(
    pose: &RigidPose,
    theta: &Flexibilities,
    opts: &MeasureOptions,
) -> Result<MimoFrf, ManipulatorError> {
    let mut plant = SampledPose::new(pose, theta, opts.fs_hz)?;
    let control = PositionLoop::for_pose(pose, opts.loop_bandwidth_hz);
    let excitation = opts.excitation(pose.axes())?;
    let mut estimator = MimoEstimator::from_multisine(&excitation)
        .map(|e| e.with_transient_periods(opts.transient_periods))
        .map_err(|e| ManipulatorError::Measurement {
            detail: e.to_string(),
        })?;
    let noise = Normal::new(0.0, opts.encoder_noise_rad.max(0.0)).map_err(|e| {
        ManipulatorError::Measurement {
            detail: e.to_string(),
        }
    })?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(opts.seed ^ 0x5eed_0fe5_c0de);
    for experiment in 0..excitation.experiments() {
        run_experiment(
            &mut plant,
            &control,
            &excitation,
            experiment,
            opts,
            &mut |p: &mut [f64]| p.iter_mut().for_each(|x| *x += noise.sample(&mut rng)),
            &mut estimator,
        )?;
    }
    estimator
        .estimate()
        .map_err(|e| ManipulatorError::Measurement {
            detail: e.to_string(),
        })
}

/// One experiment from rest: every period simulated, each pushed to the estimator.
fn run_experiment(
    plant: &mut SampledPose,
    control: &PositionLoop,
    excitation: &OrthogonalMultisine,
    experiment: usize,
    opts: &MeasureOptions,
    add_noise: &mut dyn FnMut(&mut [f64]),
    estimator: &mut MimoEstimator,
) -> Result<(), ManipulatorError> {
    let axes = plant.axes();
    let n = excitation.period_samples();
    let mut x = vec![0.0; plant.states()];
    let (mut meas, mut meas_prev, mut fb, mut uk) = (
        vec![0.0; axes],
        vec![0.0; axes],
        vec![0.0; axes],
        vec![0.0; axes],
    );
    let mut u = vec![vec![0.0; n]; axes];
    let mut y = vec![vec![0.0; n]; axes];
    for _ in 0..opts.transient_periods + opts.periods {
        for k in 0..n {
            plant.motor_positions(&x, &mut meas);
            add_noise(&mut meas);
            control.torque(&meas, &meas_prev, opts.fs_hz, &mut fb);
            for i in 0..axes {
                uk[i] = fb[i] + excitation.period(experiment, i)[k];
                u[i][k] = uk[i];
                y[i][k] = (meas[i] - meas_prev[i]) * opts.fs_hz;
            }
            plant.step(&mut x, &uk);
            meas_prev.copy_from_slice(&meas);
        }
        let us: Vec<&[f64]> = u.iter().map(|v| v.as_slice()).collect();
        let ys: Vec<&[f64]> = y.iter().map(|v| v.as_slice()).collect();
        estimator
            .push_period(experiment, &us, &ys)
            .map_err(|e| ManipulatorError::Measurement {
                detail: e.to_string(),
            })?;
    }
    Ok(())
}

impl PoseMeasurement {
    /// The measurement of an estimate: its lines, matrices and variances (the symmetrised
    /// estimate's variance with the two elements' correlation, for the symmetric cost).
    pub fn from_mimo(frf: &MimoFrf) -> Self {
        PoseMeasurement {
            f_hz: frf.freq_hz.clone(),
            g: frf.g.clone(),
            var: Some(frf.var.clone()),
            var_sym: Some(frf.var_sym.clone()),
        }
    }
}
