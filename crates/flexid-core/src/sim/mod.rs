//! Simulated recordings of a chain, for tests, benchmarks and the embedded demo.
//!
//! The plant advances exactly under zero-order hold (matrix exponential of the chain's state
//! space), the position is sampled at each sample instant before the torque of that sample
//! is applied, and then the measurement imperfections are added:
//! * velocity noise: white noise on the differenced velocity, i.e. a random walk on the
//!   position (what a free, slightly disturbed axis looks like through its encoder);
//! * torque noise: a white disturbance torque on the motor (process noise);
//! * encoder quantisation to a number of counts per revolution;
//! * a constant velocity offset (drift), as used to keep friction out of a measurement.

use crate::model::{Chain, ModelError, StateSpace};
use crate::recording::{Recording, Sidecar};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Measurement and plant imperfections for [`simulate_position`].
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// Sample rate [Hz].
    pub sample_rate_hz: f64,
    /// Whole samples between a torque command and its application.
    pub delay_samples: u32,
    /// Standard deviation of white noise on the differenced velocity, relative to the RMS of
    /// the noise-free differenced velocity about its mean [-] (0.02 = 2 %).
    pub velocity_noise_rel: f64,
    /// RMS of a white disturbance torque on the motor [N m].
    pub torque_noise_nm: f64,
    /// Encoder resolution [counts/rev]; `None` for an ideal encoder.
    pub encoder_counts_per_rev: Option<u64>,
    /// Initial velocity of the whole chain [rad/s] (a drift superposed on the response).
    pub initial_velocity_rad_s: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            sample_rate_hz: 2000.0,
            delay_samples: 0,
            velocity_noise_rel: 0.0,
            torque_noise_nm: 0.0,
            encoder_counts_per_rev: None,
            initial_velocity_rad_s: 0.0,
            seed: 1,
        }
    }
}

/// Motor position [rad] sampled at `k / fs` for the torque sequence `torque_nm` [N m]
/// (held over each sample interval).
pub fn simulate_position(
    chain: &Chain,
    torque_nm: &[f64],
    opts: &SimOptions,
) -> Result<Vec<f64>, ModelError> {
    chain.validate()?;
    if !(opts.sample_rate_hz.is_finite() && opts.sample_rate_hz > 0.0) {
        return Err(ModelError::SampleRate {
            fs_hz: opts.sample_rate_hz,
        });
    }
    let n = chain.masses();
    let ts = 1.0 / opts.sample_rate_hz;
    let d = StateSpace::of(chain).discretize(ts);
    let m = 2 * n;
    let mut rng = rand::rngs::StdRng::seed_from_u64(opts.seed);
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let mut x = vec![0.0; m];
    for v in x[n..].iter_mut() {
        *v = opts.initial_velocity_rad_s;
    }
    let mut next = vec![0.0; m];
    let delay = opts.delay_samples as usize;
    let mut pos = Vec::with_capacity(torque_nm.len());
    for k in 0..torque_nm.len() {
        pos.push(x[0]);
        let mut u = if k >= delay {
            torque_nm[k - delay]
        } else {
            0.0
        };
        if opts.torque_noise_nm > 0.0 {
            u += opts.torque_noise_nm * unit.sample(&mut rng);
        }
        for (i, nx) in next.iter_mut().enumerate() {
            let mut acc = d.bd[i] * u;
            for (j, xj) in x.iter().enumerate() {
                acc += d.ad[(i, j)] * xj;
            }
            *nx = acc;
        }
        std::mem::swap(&mut x, &mut next);
    }
    add_velocity_noise(
        &mut pos,
        opts.velocity_noise_rel,
        opts.sample_rate_hz,
        &mut rng,
    );
    if let Some(counts) = opts.encoder_counts_per_rev {
        quantise(&mut pos, counts);
    }
    Ok(pos)
}

/// Add white noise of standard deviation `rel` times the RMS (about its mean) of the
/// differenced velocity of `pos` [rad] sampled at `fs_hz` [Hz] to that velocity, i.e. a
/// random walk on the position (the first sample untouched). No-op for `rel <= 0`.
pub fn add_velocity_noise<R: rand::Rng>(pos: &mut [f64], rel: f64, fs_hz: f64, rng: &mut R) {
    if !(rel > 0.0 && pos.len() > 1) {
        return;
    }
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let fs = fs_hz;
    let ts = 1.0 / fs;
    let mean_v = (pos[pos.len() - 1] - pos[0]) * fs / (pos.len() - 1) as f64;
    let rms_v = (pos
        .windows(2)
        .map(|w| ((w[1] - w[0]) * fs - mean_v).powi(2))
        .sum::<f64>()
        / (pos.len() - 1) as f64)
        .sqrt();
    let sigma_step = rel * rms_v * ts;
    let mut walk = 0.0;
    for p in pos.iter_mut().skip(1) {
        walk += sigma_step * unit.sample(rng);
        *p += walk;
    }
}

/// Round positions [rad] to an encoder of `counts` counts per revolution (0 = no-op).
pub fn quantise(pos: &mut [f64], counts: u64) {
    if counts == 0 {
        return;
    }
    let q = 2.0 * std::f64::consts::PI / counts as f64;
    for p in pos.iter_mut() {
        *p = (*p / q).round() * q;
    }
}

/// A complete [`Recording`] of `chain` driven by `torque_nm`, with the given sidecar (its
/// `sample_rate_hz` and `io_delay_samples` are set from `opts`).
pub fn simulate_recording(
    chain: &Chain,
    torque_nm: &[f64],
    opts: &SimOptions,
    mut sidecar: Sidecar,
) -> Result<Recording, ModelError> {
    let position = simulate_position(chain, torque_nm, opts)?;
    let fs = opts.sample_rate_hz;
    sidecar.sample_rate_hz = Some(fs);
    sidecar.io_delay_samples = Some(opts.delay_samples);
    Ok(Recording {
        time_s: (0..torque_nm.len()).map(|k| k as f64 / fs).collect(),
        torque_cmd_nm: torque_nm.to_vec(),
        position_rad: Some(position),
        velocity_rad_s: None,
        acceleration_rad_s2: None,
        torque_actual_nm: None,
        sample_rate_hz: fs,
        sidecar,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SampledChain;
    use num_complex::Complex64;
    use std::f64::consts::PI;

    fn chain() -> Chain {
        Chain::new(vec![2e-3, 4e-3, 9e-3], vec![600.0, 9000.0], vec![0.05, 0.3]).unwrap()
    }

    /// Steady-state response to a periodic multisine: DFT of the last period of the
    /// differenced position over that of the torque equals `SampledChain::frf`.
    #[test]
    fn simulation_matches_the_sampled_frf() {
        let fs = 1000.0;
        let p = 1000;
        let lines = [3usize, 17, 40, 81, 150, 333, 470];
        let period: Vec<f64> = (0..p)
            .map(|k| {
                lines
                    .iter()
                    .map(|&l| (2.0 * PI * (l * k) as f64 / p as f64 + l as f64).cos())
                    .sum()
            })
            .collect();
        let torque: Vec<f64> = (0..8).flat_map(|_| period.iter().copied()).collect();
        for delay in [0u32, 1] {
            let opts = SimOptions {
                sample_rate_hz: fs,
                delay_samples: delay,
                initial_velocity_rad_s: 3.0,
                ..Default::default()
            };
            let pos = simulate_position(&chain(), &torque, &opts).unwrap();
            let sc = SampledChain::new(&chain(), fs, delay).unwrap();
            let last = torque.len() - p;
            for &l in &lines {
                let (mut u, mut v) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
                for k in 0..p {
                    let w = Complex64::from_polar(1.0, -2.0 * PI * (l * k) as f64 / p as f64);
                    u += torque[last + k] * w;
                    v += (pos[last + k] - pos[last + k - 1]) * fs * w;
                }
                let h = v / u;
                let m = sc.frf(l as f64 * fs / p as f64);
                // lightly damped modes decay slowly; 7 periods of settling leave ~1e-4
                assert!(
                    (h - m).norm() < 2e-3 * m.norm(),
                    "line {l}, delay {delay}: {h} vs {m}"
                );
            }
        }
    }

    #[test]
    fn velocity_noise_has_the_requested_size() {
        let fs = 2000.0;
        let torque: Vec<f64> = (0..20000).map(|k| (k as f64 * 0.05).sin()).collect();
        let opts = SimOptions {
            velocity_noise_rel: 0.02,
            ..Default::default()
        };
        let noisy = simulate_position(&chain(), &torque, &opts).unwrap();
        let clean = simulate_position(&chain(), &torque, &SimOptions::default()).unwrap();
        let dv = |p: &[f64]| -> Vec<f64> { p.windows(2).map(|w| (w[1] - w[0]) * fs).collect() };
        let (vn, vc) = (dv(&noisy), dv(&clean));
        // RMS about the mean: a drift does not count as signal
        let rms = |x: &[f64]| {
            let m = x.iter().sum::<f64>() / x.len() as f64;
            (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
        };
        let diff: Vec<f64> = vn.iter().zip(&vc).map(|(a, b)| a - b).collect();
        let ratio = rms(&diff) / rms(&vc);
        assert!((ratio - 0.02).abs() < 0.002, "noise/signal = {ratio}");
        assert_eq!(
            noisy,
            simulate_position(&chain(), &torque, &opts).unwrap(),
            "seeded"
        );
    }

    #[test]
    fn encoder_quantisation_rounds_to_counts() {
        let torque: Vec<f64> = (0..4000).map(|k| (k as f64 * 0.05).sin()).collect();
        let opts = SimOptions {
            encoder_counts_per_rev: Some(4096),
            ..Default::default()
        };
        let pos = simulate_position(&chain(), &torque, &opts).unwrap();
        let clean = simulate_position(&chain(), &torque, &SimOptions::default()).unwrap();
        let q = 2.0 * PI / 4096.0;
        assert!(pos.iter().all(|p| ((p / q) - (p / q).round()).abs() < 1e-6));
        assert!(pos
            .iter()
            .zip(&clean)
            .all(|(a, b)| (a - b).abs() <= q / 2.0 + 1e-12));
        assert!(pos
            .iter()
            .zip(&clean)
            .any(|(a, b)| (a - b).abs() > q / 10.0));
    }
}
