//! Recordings whose response is an acceleration (accelerometers: the F-16 ground vibration
//! test) or a velocity alone (the drive's velocity estimate) as position recordings, so
//! that the nominal chain's identification, the simulated candidates and the estimator see
//! a position like any other recording:
//!
//! * acceleration: divided by `(j w)²` line by line over the whole record (an
//!   accelerometer's band-limited signal of a continuously excited structure);
//! * velocity: integrated by the trapezoidal rule, line by line `V T (1 + z⁻¹) /
//!   (2 (1 - z⁻¹))`. The drive's velocity is the motor's velocity at the sample instant
//!   under a torque held over each sample: the rigid body's velocity is then piecewise
//!   linear, the trapezoid integrates it exactly, and the backward difference of the
//!   position it gives is the differenced position the chain models describe (`V (1 +
//!   z⁻¹)/2`). Dividing by `j w` instead, exact for a band-limited signal, leaves the
//!   differenced response `sinc(θ/2)/cos(θ/2)` too large (`θ = ω T`): 5 dB at 0.35 `f_s`,
//!   which the diagnosis took for a current loop. (A drive whose "velocity" is itself a
//!   backward difference of its position would appear half a sample late; record the
//!   position where the drive has it.)
//!
//! Below the lowest excited line the division only amplifies noise and drift; those lines
//! are set to zero and said so in the recording's source.

use crate::recording::{MotionSignal, Recording};
use num_complex::Complex64;
use realfft::RealFftPlanner;

/// `rec` with its acceleration or velocity replaced by the position it integrates to (the
/// recording itself when it has a position).
pub fn as_position(rec: &Recording) -> Recording {
    let (order, a) = match rec.preferred_motion() {
        Some((MotionSignal::Acceleration, a)) => (2, a),
        Some((MotionSignal::Velocity, v)) => (1, v),
        _ => return rec.clone(),
    };
    let n = a.len();
    if n < 4 {
        return rec.clone();
    }
    let fs = rec.sample_rate_hz;
    let lowest_hz = rec
        .sidecar
        .excitation
        .as_ref()
        .and_then(|e| e.band_hz.map(|b| b[0]))
        .filter(|f| *f > 0.0)
        .unwrap_or(fs / n as f64);
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n);
    let inv = planner.plan_fft_inverse(n);
    let mut buf = a.to_vec();
    let mut spec = fwd.make_output_vec();
    if fwd.process(&mut buf, &mut spec).is_err() {
        return rec.clone();
    }
    let df = fs / n as f64;
    for (k, x) in spec.iter_mut().enumerate() {
        let f = k as f64 * df;
        // half a line below the lowest excited one still passes it
        if f < lowest_hz - 0.5 * df {
            *x = Complex64::new(0.0, 0.0);
        } else {
            *x = integrator(order, f, fs).map_or(Complex64::new(0.0, 0.0), |g| *x / g);
        }
    }
    // the inverse of a real signal's spectrum: the Nyquist line must be real
    if n % 2 == 0 {
        if let Some(last) = spec.last_mut() {
            last.im = 0.0;
        }
    }
    let mut pos = inv.make_output_vec();
    if inv.process(&mut spec, &mut pos).is_err() {
        return rec.clone();
    }
    for p in &mut pos {
        *p /= n as f64;
    }
    let mut out = rec.clone();
    out.acceleration_rad_s2 = None;
    out.velocity_rad_s = None;
    out.position_rad = Some(pos);
    let note = format!(
        "position from the {} over the whole record; lines below {lowest_hz:.4} Hz (the lowest excited) set to zero",
        if order == 2 {
            "acceleration divided by (j w)^2"
        } else {
            "velocity integrated by the trapezoidal rule (a sampled instantaneous velocity under a held torque)"
        },
    );
    out.sidecar.source = Some(match &rec.sidecar.source {
        Some(s) => format!("{s}; {note}"),
        None => note,
    });
    out
}

/// The response of the integration at `f_hz` that turns the signal into a position:
/// `(j w)²` for an acceleration, the trapezoidal rule's `(2/T)(1 - z⁻¹)/(1 + z⁻¹) = j (2/T)
/// tan(w T / 2)` for a velocity (`None` at Nyquist, where it is infinite: that line of the
/// position is zero).
fn integrator(order: i32, f_hz: f64, fs_hz: f64) -> Option<Complex64> {
    let w = 2.0 * std::f64::consts::PI * f_hz;
    if order == 2 {
        return Some(Complex64::new(0.0, w).powi(2));
    }
    let half = w / (2.0 * fs_hz);
    (half.cos().abs() > 1e-12).then(|| Complex64::new(0.0, 2.0 * fs_hz * half.tan()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::Sidecar;

    #[test]
    fn a_periodic_acceleration_integrates_to_its_position() {
        // x = sum of sines on whole lines of the record: a = -w² x exactly
        let (fs, n) = (400.0, 4096usize);
        let lines = [(20usize, 1.0, 0.3), (57, 0.2, -1.0), (301, 0.01, 2.0)];
        let x = |t: f64| {
            lines
                .iter()
                .map(|&(k, amp, ph)| {
                    let w = 2.0 * std::f64::consts::PI * k as f64 * fs / n as f64;
                    amp * (w * t + ph).sin()
                })
                .sum::<f64>()
        };
        let acc = |t: f64| {
            lines
                .iter()
                .map(|&(k, amp, ph)| {
                    let w = 2.0 * std::f64::consts::PI * k as f64 * fs / n as f64;
                    -w * w * amp * (w * t + ph).sin()
                })
                .sum::<f64>()
        };
        let t: Vec<f64> = (0..n).map(|i| i as f64 / fs).collect();
        let rec = Recording {
            torque_cmd_nm: vec![0.0; n],
            position_rad: None,
            velocity_rad_s: None,
            acceleration_rad_s2: Some(t.iter().map(|&t| acc(t)).collect()),
            torque_actual_nm: None,
            sample_rate_hz: fs,
            sidecar: Sidecar::default(),
            time_s: t.clone(),
        };
        let out = as_position(&rec);
        let p = out.position_rad.as_ref().unwrap();
        let err = t
            .iter()
            .zip(p)
            .map(|(&t, p)| (x(t) - p).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "max error {err}");
        assert!(out.acceleration_rad_s2.is_none());
        assert!(out.sidecar.source.unwrap().contains("(j w)^2"));
        // a position recording is left alone
        let same = as_position(&out_position(&rec, p));
        assert_eq!(same.position_rad.as_deref(), Some(&p[..]));
    }

    /// A rigid body (1e-3 kg m²) under a periodic torque held over each sample: its
    /// velocity read at the sample instants, integrated, differenced, is the differenced
    /// exact position to round-off, at every line up to Nyquist (the exact position by
    /// integrating the piecewise-constant acceleration twice, an independent computation).
    #[test]
    fn an_instantaneous_velocity_integrates_to_the_sampled_position() {
        let (fs, n, j) = (1000.0, 2000usize, 1e-3);
        let t_s = 1.0 / fs;
        // a zero-mean periodic torque: odd lines with phases from a simple sequence
        let torque: Vec<f64> = (0..n)
            .map(|k| {
                (1..400)
                    .step_by(2)
                    .map(|l| {
                        let ph = (l * l) as f64 * 0.7;
                        (2.0 * std::f64::consts::PI * (l * k) as f64 / n as f64 + ph).sin()
                    })
                    .sum::<f64>()
                    * 0.05
            })
            .collect();
        // exact velocity and position at the instants (two periods: the first settles the
        // mean velocity so that the second is periodic)
        let mut v = 0.0;
        let mut p = 0.0;
        let mut vel = Vec::new();
        let mut pos = Vec::new();
        for pass in 0..2 {
            if pass == 1 {
                // remove the mean velocity of the first pass: periodic in the second
                let mean = vel.iter().sum::<f64>() / n as f64;
                v -= mean;
                vel.clear();
                pos.clear();
            }
            for &u in &torque {
                vel.push(v);
                pos.push(p);
                let a = u / j;
                p += v * t_s + 0.5 * a * t_s * t_s;
                v += a * t_s;
            }
        }
        let rec = Recording {
            torque_cmd_nm: torque.clone(),
            position_rad: None,
            velocity_rad_s: Some(vel),
            acceleration_rad_s2: None,
            torque_actual_nm: None,
            sample_rate_hz: fs,
            sidecar: Sidecar::default(),
            time_s: (0..n).map(|k| k as f64 * t_s).collect(),
        };
        let out = as_position(&rec);
        let got = out.position_rad.as_ref().unwrap();
        assert!(out.sidecar.source.unwrap().contains("trapezoidal"));
        let diff = |x: &[f64]| -> Vec<f64> { (1..x.len()).map(|k| x[k] - x[k - 1]).collect() };
        let (dg, dp) = (diff(got), diff(&pos));
        let scale = dp.iter().map(|x| x.abs()).fold(0.0, f64::max);
        let err = dg
            .iter()
            .zip(&dp)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9 * scale, "max error {err} of {scale}");
    }

    fn out_position(rec: &Recording, p: &[f64]) -> Recording {
        Recording {
            acceleration_rad_s2: None,
            position_rad: Some(p.to_vec()),
            ..rec.clone()
        }
    }
}
