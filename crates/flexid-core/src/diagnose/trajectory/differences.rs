//! Velocity and acceleration of a (filtered) position by central differences: no lag, and
//! exact for a quadratic. The end samples use one-sided differences; the identification
//! never uses them (they lie inside the filter's edge, which it trims).

/// `qd[k] = (q[k+1] - q[k-1]) / (2 dt)` [position unit/s], `dt = 1/sample_rate_hz`.
pub fn central_velocity(q: &[f64], sample_rate_hz: f64) -> Vec<f64> {
    let n = q.len();
    if n < 2 {
        return vec![0.0; n];
    }
    let fs = sample_rate_hz;
    (0..n)
        .map(|k| match k {
            0 => (q[1] - q[0]) * fs,
            k if k == n - 1 => (q[n - 1] - q[n - 2]) * fs,
            k => 0.5 * (q[k + 1] - q[k - 1]) * fs,
        })
        .collect()
}

/// `qdd[k] = (q[k+1] - 2 q[k] + q[k-1]) / dt²` [position unit/s²].
pub fn central_acceleration(q: &[f64], sample_rate_hz: f64) -> Vec<f64> {
    let n = q.len();
    if n < 3 {
        return vec![0.0; n];
    }
    let fs2 = sample_rate_hz * sample_rate_hz;
    let inner = |k: usize| (q[k + 1] - 2.0 * q[k] + q[k - 1]) * fs2;
    (0..n)
        .map(|k| match k {
            0 => inner(1),
            k if k == n - 1 => inner(n - 2),
            k => inner(k),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn exact_on_a_quadratic() {
        let fs = 250.0;
        let q: Vec<f64> = (0..50)
            .map(|k| {
                let t = k as f64 / fs;
                0.3 - 1.2 * t + 4.5 * t * t
            })
            .collect();
        let v = central_velocity(&q, fs);
        let a = central_acceleration(&q, fs);
        for k in 1..49 {
            let t = k as f64 / fs;
            assert!((v[k] - (-1.2 + 9.0 * t)).abs() < 1e-9, "{k}: {}", v[k]);
            assert!((a[k] - 9.0).abs() < 1e-6, "{k}: {}", a[k]);
        }
    }

    /// Against the naive reference, the analytic derivatives of a sine: the central
    /// difference's known response `sin(w dt)/dt` and `(2 sin(w dt/2)/dt)²`.
    #[test]
    fn sine_against_analytic_derivatives() {
        let (fs, f) = (1000.0, 13.0);
        let w = 2.0 * PI * f;
        let q: Vec<f64> = (0..2000).map(|k| (w * k as f64 / fs).sin()).collect();
        let v = central_velocity(&q, fs);
        let a = central_acceleration(&q, fs);
        let dt = 1.0 / fs;
        let gv = (w * dt).sin() / dt;
        let ga = (2.0 * (0.5 * w * dt).sin() / dt).powi(2);
        for k in 1..1999 {
            let t = k as f64 * dt;
            assert!((v[k] - gv * (w * t).cos()).abs() < 1e-9);
            assert!((a[k] + ga * (w * t).sin()).abs() < 1e-6);
            // and close to the true derivatives (relative error (w dt)²/6 and /12)
            assert!((v[k] - w * (w * t).cos()).abs() < 0.003 * w);
            assert!((a[k] + w * w * (w * t).sin()).abs() < 0.002 * w * w);
        }
        assert!(central_velocity(&[], fs).is_empty());
        assert_eq!(central_acceleration(&[1.0, 2.0], fs), vec![0.0, 0.0]);
    }
}
