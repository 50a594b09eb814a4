//! Recordings whose response is an acceleration (accelerometers: the F-16 ground vibration
//! test) as position recordings: the acceleration divided by `(j w)²` line by line over the
//! whole record, so that the nominal chain's identification, the simulated candidates and
//! the estimator see a position like any other recording. Below the lowest excited line the
//! division only amplifies noise and drift (`1/w²`); those lines are set to zero and said
//! so in the recording's source.

use crate::recording::{MotionSignal, Recording};
use num_complex::Complex64;
use realfft::RealFftPlanner;

/// `rec` with its acceleration replaced by the position it integrates to (the recording
/// itself when its response is not an acceleration).
pub fn as_position(rec: &Recording) -> Recording {
    let Some((MotionSignal::Acceleration, a)) = rec.preferred_motion() else {
        return rec.clone();
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
            let w = 2.0 * std::f64::consts::PI * f;
            // 1/(j w)² = -1/w²
            *x *= -1.0 / (w * w);
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
    out.position_rad = Some(pos);
    let note = format!(
        "position from the acceleration divided by (j w)^2 over the whole record; lines below {lowest_hz:.4} Hz (the lowest excited) set to zero"
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
    }

    fn out_position(rec: &Recording, p: &[f64]) -> Recording {
        Recording {
            acceleration_rad_s2: None,
            position_rad: Some(p.to_vec()),
            ..rec.clone()
        }
    }
}
