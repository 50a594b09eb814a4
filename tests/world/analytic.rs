//! The world's small-signal frequency response, computed in the frequency domain (not by
//! simulation): the bodies' positions from `(K - w^2 M + j w C) x = e_0 T` (a complex
//! tridiagonal solve; ground springs and dampers on the diagonal), times the drive's
//! transfer (delay, notch, current loop) and the sensor's (compliant shaft, position
//! low-pass).
//!
//! The nonlinear laws are linearised at rest: backlash in contact, hardening at zero
//! deflection, gravity at the hanging position, cogging in its detent; Coulomb friction,
//! the cubic ground spring, the amplifier's dead zone and the encoder's play have no
//! small-signal part.

use super::plant::{LowPass, Plant};
use super::substeps::Peaks;
use flexid::Complex64;

fn jw(f_hz: f64) -> Complex64 {
    Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz)
}

/// Positions of every body per unit torque on the motor [rad/(N m)] at `f_hz`.
pub fn body_positions(plant: &Plant, f_hz: f64) -> Vec<Complex64> {
    let s = jw(f_hz);
    let n = plant.bodies();
    let mut diag: Vec<Complex64> = plant.inertia_kgm2.iter().map(|j| s * s * *j).collect();
    let mut off = vec![Complex64::new(0.0, 0.0); n.saturating_sub(1)];
    for (k, c) in plant.couplings.iter().enumerate() {
        // every law linearised at rest, in contact
        let z = c.stiffness_nm_per_rad + s * c.damping_nms_per_rad;
        diag[k] += z;
        diag[k + 1] += z;
        off[k] = -z;
    }
    diag[0] += s * plant.motor_viscous_nms_per_rad;
    if let Some(g) = &plant.gravity {
        diag[g.body] += g.m_g_l_nm + s * g.bearing_damping_nms_per_rad;
    }
    if let Some(c) = &plant.cogging {
        diag[0] += c.amplitude_nm * c.periods_per_rev;
    }
    // Thomas algorithm for the symmetric tridiagonal system, right-hand side e_0
    let mut rhs = vec![Complex64::new(0.0, 0.0); n];
    rhs[0] = Complex64::new(1.0, 0.0);
    let mut cp = vec![Complex64::new(0.0, 0.0); n];
    let mut dp = vec![Complex64::new(0.0, 0.0); n];
    for i in 0..n {
        let sub = if i > 0 {
            off[i - 1]
        } else {
            Complex64::new(0.0, 0.0)
        };
        let den = diag[i]
            - sub
                * if i > 0 {
                    cp[i - 1]
                } else {
                    Complex64::new(0.0, 0.0)
                };
        cp[i] = if i + 1 < n {
            off[i] / den
        } else {
            Complex64::new(0.0, 0.0)
        };
        dp[i] = (rhs[i]
            - sub
                * if i > 0 {
                    dp[i - 1]
                } else {
                    Complex64::new(0.0, 0.0)
                })
            / den;
    }
    let mut x = vec![Complex64::new(0.0, 0.0); n];
    for i in (0..n).rev() {
        x[i] = dp[i]
            - if i + 1 < n {
                cp[i] * x[i + 1]
            } else {
                Complex64::new(0.0, 0.0)
            };
    }
    x
}

/// A low-pass's response at `f_hz`.
pub fn lowpass(l: &LowPass, f_hz: f64) -> Complex64 {
    let s = jw(f_hz);
    let w = 2.0 * std::f64::consts::PI * l.bandwidth_hz;
    if l.order == 1 {
        w / (s + w)
    } else {
        w * w / (s * s + 2.0 * l.damping_ratio * w * s + w * w)
    }
}

/// The drive's transfer from torque command to motor torque at `f_hz` (the dead zone
/// ignored).
pub fn drive(plant: &Plant, f_hz: f64) -> Complex64 {
    let s = jw(f_hz);
    let d = &plant.drive;
    let mut h = (-s * d.delay_s).exp();
    if let Some(n) = &d.notch {
        let w = 2.0 * std::f64::consts::PI * n.centre_hz;
        h *= (s * s + 2.0 * n.zero_damping_ratio * w * s + w * w)
            / (s * s + 2.0 * n.pole_damping_ratio * w * s + w * w);
    }
    if let Some(l) = &d.current_loop {
        h *= lowpass(l, f_hz);
    }
    h
}

/// The sensor path's transfer from the encoder's true angle to its reading at `f_hz`.
pub fn sensor(plant: &Plant, f_hz: f64) -> Complex64 {
    let s = jw(f_hz);
    let mut h = Complex64::new(1.0, 0.0);
    if let Some(r) = &plant.sensor.shaft {
        let w = 2.0 * std::f64::consts::PI * r.frequency_hz;
        let num = 2.0 * r.damping_ratio * w * s + w * w;
        h *= num / (s * s + num);
    }
    if let Some(l) = &plant.sensor.lowpass {
        h *= lowpass(l, f_hz);
    }
    h
}

/// Torque command -> measured position [rad/(N m)] at `f_hz` (continuous time).
pub fn position(plant: &Plant, f_hz: f64) -> Complex64 {
    drive(plant, f_hz) * body_positions(plant, f_hz)[0] * sensor(plant, f_hz)
}

/// Disturbance torque on the motor -> measured position [rad/(N m)] at `f_hz`.
pub fn disturbance_position(plant: &Plant, f_hz: f64) -> Complex64 {
    body_positions(plant, f_hz)[0] * sensor(plant, f_hz)
}

/// RMS of each coupling's deflection and each body's position [rad] under a multisine of
/// `rms_nm` spread evenly over `lines_hz` (small-signal response).
pub fn rms_motion(plant: &Plant, lines_hz: &[f64], rms_nm: f64) -> Peaks {
    let a2 = rms_nm * rms_nm / lines_hz.len().max(1) as f64; // mean square per line
    let n = plant.bodies();
    let mut defl = vec![0.0; n.saturating_sub(1)];
    let mut pos = vec![0.0; n];
    for &f in lines_hz {
        let d = drive(plant, f);
        let x = body_positions(plant, f);
        for i in 0..n {
            pos[i] += (d * x[i]).norm_sqr() * a2;
        }
        for k in 0..n.saturating_sub(1) {
            defl[k] += (d * (x[k + 1] - x[k])).norm_sqr() * a2;
        }
    }
    Peaks {
        deflection_rad: defl.into_iter().map(f64::sqrt).collect(),
        position_rad: pos.into_iter().map(f64::sqrt).collect(),
    }
}

/// RMS motor velocity [rad/s] under a multisine of `rms_nm` spread over `lines_hz`.
pub fn rms_velocity(plant: &Plant, lines_hz: &[f64], rms_nm: f64) -> f64 {
    let a2 = rms_nm * rms_nm / lines_hz.len().max(1) as f64;
    lines_hz
        .iter()
        .map(|&f| (jw(f) * position(plant, f)).norm_sqr() * a2)
        .sum::<f64>()
        .sqrt()
}

/// The exact response of the sampled measurement to a held (ZOH) command, torque command
/// -> differenced measured position `(p[k] - p[k-1]) f_s` at `f_hz`, by the alias sum
/// `H_d = (1 - e^{-j w T})^2 / T^2 * sum_k H(j w_k) / (j w_k)`, `w_k = w + k w_s`,
/// truncated at `|k| <= terms` (the terms fall as `1/k^3`). For checking the simulator.
pub fn sampled_differenced(plant: &Plant, fs_hz: f64, f_hz: f64, terms: i64) -> Complex64 {
    let ts = 1.0 / fs_hz;
    let mut sum = Complex64::new(0.0, 0.0);
    for k in -terms..=terms {
        let fk = f_hz + k as f64 * fs_hz;
        sum += position(plant, fk) / jw(fk);
    }
    let hold = Complex64::new(1.0, 0.0) - (-jw(f_hz) * ts).exp();
    hold * hold / (ts * ts) * sum
}

/// The exact response of the sampled velocity reading (the motor's velocity at the sample
/// instants) to a held command at `f_hz`: `(1 - e^{-j w T}) / T * sum_k H(j w_k)` (terms
/// falling as `1/k^2`). For checking the simulator.
pub fn sampled_velocity(plant: &Plant, fs_hz: f64, f_hz: f64, terms: i64) -> Complex64 {
    let ts = 1.0 / fs_hz;
    let mut sum = Complex64::new(0.0, 0.0);
    for k in -terms..=terms {
        let fk = f_hz + k as f64 * fs_hz;
        sum += position(plant, fk);
    }
    (Complex64::new(1.0, 0.0) - (-jw(f_hz) * ts).exp()) / ts * sum
}

/// The exact sampled response of what `plant`'s recording holds (differenced position, or
/// the velocity reading) at `f_hz`.
pub fn sampled_reading(plant: &Plant, fs_hz: f64, f_hz: f64, terms: i64) -> Complex64 {
    match plant.sensor.output {
        super::plant::Output::Position => sampled_differenced(plant, fs_hz, f_hz, terms),
        super::plant::Output::Velocity => sampled_velocity(plant, fs_hz, f_hz, terms),
    }
}
