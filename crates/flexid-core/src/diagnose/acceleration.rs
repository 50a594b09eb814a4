//! Recordings whose response is an acceleration (accelerometers: the F-16 ground vibration
//! test) or a velocity alone (the drive's velocity estimate) as position recordings: the
//! response divided by `(j w)²` or `j w` line by line over the whole record, so that the
//! nominal chain's identification, the simulated candidates and the estimator see a
//! position like any other recording. Below the lowest excited line the division only
//! amplifies noise and drift; those lines are set to zero and said so in the recording's
//! source.

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
            let jw = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            *x /= jw.powi(order);
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
        "position from the {} divided by (j w){} over the whole record; lines below {lowest_hz:.4} Hz (the lowest excited) set to zero",
        if order == 2 { "acceleration" } else { "velocity" },
        if order == 2 { "^2" } else { "" }
    );
    out.sidecar.source = Some(match &rec.sidecar.source {
        Some(s) => format!("{s}; {note}"),
        None => note,
    });
    out
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
        // a velocity alone integrates once: v = dx/dt
        let vel = |t: f64| {
            lines
                .iter()
                .map(|&(k, amp, ph)| {
                    let w = 2.0 * std::f64::consts::PI * k as f64 * fs / n as f64;
                    w * amp * (w * t + ph).cos()
                })
                .sum::<f64>()
        };
        let v_rec = Recording {
            acceleration_rad_s2: None,
            velocity_rad_s: Some(t.iter().map(|&t| vel(t)).collect()),
            ..rec.clone()
        };
        let out = as_position(&v_rec);
        let err = t
            .iter()
            .zip(out.position_rad.as_ref().unwrap())
            .map(|(&t, p)| (x(t) - p).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "velocity: max error {err}");
        assert!(out.velocity_rad_s.is_none());
    }

    fn out_position(rec: &Recording, p: &[f64]) -> Recording {
        Recording {
            acceleration_rad_s2: None,
            position_rad: Some(p.to_vec()),
            ..rec.clone()
        }
    }
}
