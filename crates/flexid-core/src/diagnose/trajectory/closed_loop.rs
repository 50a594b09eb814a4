//! Test only: a rigid body with Coulomb and viscous friction and a force offset, tracking a
//! bang-bang trajectory under the EMPS control law (a position loop around a velocity
//! loop, `tau = kv (kp (q_ref - q_meas) - qd_meas)`), integrated on fine sub-steps with
//! stiction; the command held over each sample (zero-order hold), the encoder quantised,
//! the recorded force noisy.

use crate::excitation::{ExcitationInfo, ExcitationKind};
use crate::recording::{Recording, Sidecar};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// The plant's true parameters (a prismatic axis: kg, N s/m, N).
#[derive(Debug, Clone, Copy)]
pub struct Plant {
    pub mass: f64,
    pub viscous: f64,
    pub coulomb: f64,
    pub offset: f64,
    /// A restoring spring to the ground [N/m] (not in the identified model: 0 unless a
    /// test wants a gap the model cannot explain).
    pub spring: f64,
}

/// The experiment.
#[derive(Debug, Clone)]
pub struct Setup {
    pub sample_rate_hz: f64,
    pub substeps: usize,
    /// Position loop gain [1/s] and velocity loop gain [N s/m].
    pub kp: f64,
    pub kv: f64,
    /// Encoder increment [m].
    pub encoder_m: f64,
    /// Standard deviation of the noise on the recorded force [N].
    pub force_noise_n: f64,
    /// Bang-bang moves: acceleration [m/s²] and the cruise speeds [m/s] cycled through
    /// (not multiples of an encoder increment per sample: the quantisation error of such
    /// a cruise is constant, not noise).
    pub accel: f64,
    pub speeds: Vec<f64>,
    /// Distance of one move [m] and the dwell between moves [s].
    pub stroke: f64,
    pub dwell_s: f64,
    pub duration_s: f64,
    pub seed: u64,
}

impl Default for Setup {
    fn default() -> Self {
        Setup {
            sample_rate_hz: 1000.0,
            substeps: 20,
            kp: 160.0,
            kv: 8500.0,
            encoder_m: 1e-6,
            force_noise_n: 1.0,
            accel: 3.0,
            speeds: vec![0.0537, 0.1213, 0.1987, 0.0861, 0.1579],
            stroke: 0.1173,
            dwell_s: 0.15,
            duration_s: 24.0,
            seed: 1,
        }
    }
}

/// The reference acceleration [m/s²] at every sub-step: moves of `stroke` back and forth,
/// accelerating at `accel` to the move's speed, cruising, braking, then dwelling.
fn reference_acceleration(s: &Setup, steps: usize, h: f64) -> Vec<f64> {
    let mut a = Vec::with_capacity(steps);
    let mut dir = 1.0;
    let mut i = 0;
    while a.len() < steps {
        let v = s.speeds[i % s.speeds.len()];
        i += 1;
        let t_acc = v / s.accel;
        let cruise = (s.stroke - v * t_acc).max(0.0) / v;
        let phases = [
            (t_acc, dir * s.accel),
            (cruise, 0.0),
            (t_acc, -dir * s.accel),
            (s.dwell_s, 0.0),
        ];
        for (dur, acc) in phases {
            let n = (dur / h).round() as usize;
            a.extend(std::iter::repeat_n(acc, n));
        }
        dir = -dir;
    }
    a.truncate(steps);
    a
}

/// The recording: `torque_cmd_nm` holds the recorded force [N] and `position_rad` the
/// encoder position [m]; not periodic.
pub fn simulate(p: &Plant, s: &Setup) -> Recording {
    let fs = s.sample_rate_hz;
    let dt = 1.0 / fs;
    let h = dt / s.substeps as f64;
    let n = (s.duration_s * fs) as usize;
    let acc_ref = reference_acceleration(s, n * s.substeps, h);
    let mut rng = rand::rngs::StdRng::seed_from_u64(s.seed);
    let noise = Normal::new(0.0, s.force_noise_n.max(1e-300)).unwrap();
    let (mut q, mut v) = (0.0f64, 0.0f64);
    let (mut qr, mut vr) = (0.0f64, 0.0f64);
    let mut q_prev_meas = 0.0;
    let mut qf_prev = 0.0;
    let mut time = Vec::with_capacity(n);
    let mut tau_rec = Vec::with_capacity(n);
    let mut pos = Vec::with_capacity(n);
    for k in 0..n {
        // the measurement and the command at t_k
        let q_meas = (q / s.encoder_m).round() * s.encoder_m;
        let qf = 0.5 * (q_meas + q_prev_meas);
        let qd_meas = if k == 0 { 0.0 } else { (qf - qf_prev) / dt };
        q_prev_meas = q_meas;
        qf_prev = qf;
        let cmd = s.kv * (s.kp * (qr - q_meas) - qd_meas);
        time.push(k as f64 * dt);
        pos.push(q_meas);
        tau_rec.push(cmd + s.force_noise_n * noise.sample(&mut rng));
        // the command held over the sample
        for j in 0..s.substeps {
            let ar = acc_ref[k * s.substeps + j];
            qr += vr * h + 0.5 * ar * h * h;
            vr += ar * h;
            let drive = cmd - p.offset - p.spring * q;
            if v == 0.0 && drive.abs() <= p.coulomb {
                continue; // stuck: static friction holds the drive
            }
            let dir = if v != 0.0 { v.signum() } else { drive.signum() };
            let a = (drive - p.viscous * v - p.coulomb * dir) / p.mass;
            let v_new = v + a * h;
            if v != 0.0 && v_new * v < 0.0 {
                // reversal inside the sub-step: stop at zero (stiction decides next)
                let t0 = -v / a;
                q += v * t0 + 0.5 * a * t0 * t0;
                v = 0.0;
            } else {
                q += v * h + 0.5 * a * h * h;
                v = v_new;
            }
        }
    }
    let peak = tau_rec.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    Recording {
        time_s: time,
        torque_cmd_nm: tau_rec,
        position_rad: Some(pos),
        sample_rate_hz: fs,
        sidecar: Sidecar {
            sample_rate_hz: Some(fs),
            excitation: Some(ExcitationInfo {
                kind: ExcitationKind::Other,
                period_samples: 0,
                periods: 0,
                transient_periods: 0,
                excited_lines: Vec::new(),
                band_hz: None,
                peak_nm: Some(peak),
                rms_nm: None,
                design: None,
                blocks: Vec::new(),
                realisations: Vec::new(),
                band_limited: false,
            }),
            source: Some("closed-loop simulation of a prismatic axis (test)".into()),
            ..Sidecar::default()
        },
        ..Recording::default()
    }
}
