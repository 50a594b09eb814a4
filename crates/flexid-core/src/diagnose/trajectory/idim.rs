//! The inverse dynamic identification model, least squares (IDIM-LS): the rigid body
//! `tau = M qdd + Fv qd + Fc sign(qd) + offset` written as one linear equation per sample,
//! `F(tau)[k] = [F(qdd), F(qd), F(sign qd), 1][k] theta`, solved for `theta`.
//!
//! Units are the recording's: the force column `torque_cmd_nm` [N m], the position
//! `position_rad` [rad]; `M` [kg m² = N m s²/rad], `Fv` [N m s/rad], `Fc` and the offset
//! [N m]. A prismatic axis whose columns hold N and m reads kg, N s/m and N.

use super::butterworth::Butterworth;
use super::differences::{central_acceleration, central_velocity};

/// A column of the observation matrix, named after the parameter it multiplies (with
/// that parameter's unit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    /// `qdd` [rad/s²] -> the inertia `M` [kg m²].
    Inertia,
    /// `qd` [rad/s] -> viscous friction `Fv` [N m s/rad].
    Viscous,
    /// `sign(qd)` -> Coulomb friction `Fc` [N m].
    Coulomb,
    /// `1` -> the force offset [N m].
    Offset,
}

impl Column {
    /// The parameter's name on the wire (its unit in the name).
    pub const fn name(self) -> &'static str {
        match self {
            Column::Inertia => "inertia_kgm2",
            Column::Viscous => "viscous_nms_per_rad",
            Column::Coulomb => "coulomb_nm",
            Column::Offset => "offset_nm",
        }
    }
}

/// The rigid body without friction, with viscous friction, with Coulomb and viscous
/// friction (the IDIM model).
pub const RIGID: [Column; 2] = [Column::Inertia, Column::Offset];
pub const RIGID_VISCOUS: [Column; 3] = [Column::Inertia, Column::Viscous, Column::Offset];
pub const RIGID_FRICTION: [Column; 4] = [
    Column::Inertia,
    Column::Viscous,
    Column::Coulomb,
    Column::Offset,
];

/// How the samples are processed (the same for an estimation and a cross-test record).
#[derive(Debug, Clone, PartialEq)]
pub struct Processing {
    /// The zero-phase low-pass of the position, the force and the sign column.
    pub filter: Butterworth,
    /// One sample kept in `decimation`.
    pub decimation: usize,
    /// Samples dropped at each end (the filter's memory).
    pub edge_samples: usize,
    /// A sample is used only where `|qd|` exceeds this [rad/s]: below it the sign of the
    /// velocity estimate is not trusted (see [`velocity_noise_rad_s`]).
    pub velocity_threshold_rad_s: f64,
    /// ... nor within this many samples of such a sample: the zero-phase filter spreads
    /// each sample's force over its impulse response ([`Processing::spread_samples`]), so
    /// a filtered sample next to a reversal or a standstill mixes in forces that
    /// `Fc sign(qd)` does not describe.
    pub spread_samples: usize,
}

impl Processing {
    /// The half-width [samples] of the zero-phase impulse response that holds 99 % of its
    /// absolute sum: the span a filtered sample draws on.
    pub fn spread_samples(filter: &Butterworth) -> usize {
        let m = filter.memory_samples();
        let mut x = vec![0.0; 4 * m + 1];
        x[2 * m] = 1.0;
        let h = filter.filtfilt(&x);
        let total: f64 = h.iter().map(|v| v.abs()).sum();
        let mut inside = h[2 * m].abs();
        for w in 1..2 * m {
            if inside >= 0.99 * total {
                return w - 1;
            }
            inside += h[2 * m - w].abs() + h[2 * m + w].abs();
        }
        2 * m
    }
}

/// The decimated equations: the filtered force and the observation matrix's columns.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Samples {
    /// `F(tau)` [N m].
    pub tau_nm: Vec<f64>,
    /// `qdd` [rad/s²] of the filtered position.
    pub qdd_rad_s2: Vec<f64>,
    /// `qd` [rad/s] of the filtered position.
    pub qd_rad_s: Vec<f64>,
    /// `F(sign(qd))` (parallel filtering of the Coulomb column).
    pub sign: Vec<f64>,
    /// Decimated samples inside the edges, before the velocity test.
    pub candidates: usize,
    /// The record's sample index of each equation.
    pub index: Vec<usize>,
}

impl Samples {
    pub fn len(&self) -> usize {
        self.tau_nm.len()
    }
    pub fn is_empty(&self) -> bool {
        self.tau_nm.is_empty()
    }
    fn column(&self, c: Column) -> Vec<f64> {
        match c {
            Column::Inertia => self.qdd_rad_s2.clone(),
            Column::Viscous => self.qd_rad_s.clone(),
            Column::Coulomb => self.sign.clone(),
            Column::Offset => vec![1.0; self.len()],
        }
    }
}

/// The force that the central second difference at sample `k` sees. A command is held
/// over its sample (zero-order hold), `io_delay` whole samples after it was recorded (the
/// recording's `io_delay_samples`): the body is driven by `tau[j - d]` over
/// `[t_j, t_(j+1))`, and for a body driven so `q[k+1] - 2 q[k] + q[k-1]` is exactly
/// `dt²/M` times the mean of the forces over `[t_(k-1), t_k)` and `[t_k, t_(k+1))`, that
/// is `(tau[k-1-d] + tau[k-d]) / 2`. Regressing `tau[k]` instead would shift the force by
/// half a sample against the acceleration (a bias of about `M <qdd²>/<qd²> dt/2` on `Fv`).
/// The first samples repeat the first force.
pub fn held_force(tau_nm: &[f64], io_delay: usize) -> Vec<f64> {
    let at = |j: isize| tau_nm[j.clamp(0, tau_nm.len() as isize - 1) as usize];
    (0..tau_nm.len() as isize)
        .map(|k| {
            let d = io_delay as isize;
            0.5 * (at(k - 1 - d) + at(k - d))
        })
        .collect()
}

/// Zero-order-hold alignment, zero-phase low-pass, central differences, parallel
/// filtering, decimation and the velocity test: the equations of one record (`io_delay`:
/// its whole-sample delay of the force, see [`held_force`]).
pub fn equations(q_rad: &[f64], tau_nm: &[f64], io_delay: usize, p: &Processing) -> Samples {
    let fs = p.filter.sample_rate_hz;
    let qf = p.filter.filtfilt(q_rad);
    let qd = central_velocity(&qf, fs);
    let qdd = central_acceleration(&qf, fs);
    let tau = p.filter.filtfilt(&held_force(tau_nm, io_delay));
    let sign: Vec<f64> = qd.iter().map(|v| v.signum()).collect();
    let sign = p.filter.filtfilt(&sign);
    let n = q_rad.len();
    let trusted = trusted_sign(&qd, p.velocity_threshold_rad_s, p.spread_samples);
    let mut s = Samples::default();
    let mut k = p.edge_samples;
    while k + p.edge_samples < n {
        s.candidates += 1;
        if trusted[k] {
            s.tau_nm.push(tau[k]);
            s.qdd_rad_s2.push(qdd[k]);
            s.qd_rad_s.push(qd[k]);
            s.sign.push(sign[k]);
            s.index.push(k);
        }
        k += p.decimation.max(1);
    }
    s
}

/// Where the sign of the velocity is trusted: `|qd| > threshold` at every sample within
/// `spread` samples.
pub fn trusted_sign(qd: &[f64], threshold: f64, spread: usize) -> Vec<bool> {
    let n = qd.len();
    let mut ok = vec![true; n];
    for (k, v) in qd.iter().enumerate() {
        if v.abs() <= threshold {
            let lo = k.saturating_sub(spread);
            let hi = (k + spread + 1).min(n);
            ok[lo..hi].iter_mut().for_each(|o| *o = false);
        }
    }
    ok
}

/// A least-squares fit of some columns.
#[derive(Debug, Clone, PartialEq)]
pub struct LsFit {
    pub columns: Vec<Column>,
    /// The parameters, in the order of `columns`.
    pub theta: Vec<f64>,
    /// Their standard deviations: `sqrt(diag(sigma² (X^T X)^-1))`, `sigma² = rss/(N - p)`.
    pub std: Vec<f64>,
    /// Residual sum of squares [(N m)²].
    pub rss: f64,
    pub samples: usize,
    /// Condition number of the observation matrix `X` (largest over smallest singular value).
    pub condition: f64,
    /// Relative force error `||y - X theta|| / ||y||` (Janot et al. 2019, eq. 11).
    pub relative_error: f64,
}

impl LsFit {
    /// The value and standard deviation of `c`, if fitted.
    pub fn param(&self, c: Column) -> Option<(f64, f64)> {
        let i = self.columns.iter().position(|&x| x == c)?;
        Some((self.theta[i], self.std[i]))
    }
    /// The value of `c`, 0 where not fitted.
    pub fn value(&self, c: Column) -> f64 {
        self.param(c).map_or(0.0, |p| p.0)
    }
}

/// Least squares by singular value decomposition, `X = U S V^T`, `theta = V S^-1 U^T y`,
/// `(X^T X)^-1 = V S^-2 V^T`. `None` when there are no more samples than columns or `X`
/// is rank-deficient (a singular value below `1e-12` of the largest: a column the
/// trajectory does not excite).
pub fn least_squares(s: &Samples, columns: &[Column]) -> Option<LsFit> {
    let (n, p) = (s.len(), columns.len());
    if n <= p || p == 0 {
        return None;
    }
    let cols: Vec<Vec<f64>> = columns.iter().map(|&c| s.column(c)).collect();
    let x = nalgebra::DMatrix::from_fn(n, p, |i, j| cols[j][i]);
    let y = nalgebra::DVector::from_column_slice(&s.tau_nm);
    let svd = x.clone().svd(true, true);
    let sv = &svd.singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let rank_ok = smin > 1e-12 * smax && smax.is_finite();
    if !rank_ok {
        return None;
    }
    let u = svd.u.as_ref()?;
    let vt = svd.v_t.as_ref()?;
    let uty = u.transpose() * &y;
    let theta = vt.transpose() * nalgebra::DVector::from_fn(p, |i, _| uty[i] / sv[i]);
    let r = &y - &x * &theta;
    let rss = r.norm_squared();
    let sigma2 = rss / (n - p) as f64;
    let std = (0..p)
        .map(|j| {
            let d: f64 = (0..p).map(|i| (vt[(i, j)] / sv[i]).powi(2)).sum();
            (sigma2 * d).sqrt()
        })
        .collect();
    let ynorm = y.norm();
    Some(LsFit {
        columns: columns.to_vec(),
        theta: theta.iter().copied().collect(),
        std,
        rss,
        samples: n,
        condition: smax / smin,
        relative_error: if ynorm > 0.0 {
            rss.sqrt() / ynorm
        } else {
            f64::NAN
        },
    })
}

/// The force a fit predicts for each equation [N m].
pub fn predicted_nm(s: &Samples, fit: &LsFit) -> Vec<f64> {
    (0..s.len())
        .map(|k| {
            fit.columns
                .iter()
                .zip(&fit.theta)
                .map(|(&c, th)| {
                    th * match c {
                        Column::Inertia => s.qdd_rad_s2[k],
                        Column::Viscous => s.qd_rad_s[k],
                        Column::Coulomb => s.sign[k],
                        Column::Offset => 1.0,
                    }
                })
                .sum()
        })
        .collect()
}

/// The residual sum of squares and the relative error of parameters `fit` on other
/// equations (a cross-test).
pub fn prediction_error(s: &Samples, fit: &LsFit) -> (f64, f64) {
    let pred = predicted_nm(s, fit);
    let rss: f64 = s
        .tau_nm
        .iter()
        .zip(&pred)
        .map(|(y, p)| (y - p).powi(2))
        .sum();
    let yy: f64 = s.tau_nm.iter().map(|y| y * y).sum();
    (
        rss,
        if yy > 0.0 {
            (rss / yy).sqrt()
        } else {
            f64::NAN
        },
    )
}

/// The noise gains of the processing: the sums of squares of the impulse responses of
/// the zero-phase filter `h`, of `D1 h` [1/s] and of `D2 h` [1/s²], and the cross sum
/// `D1 h · D2 h`. White noise of variance `s²` per sample leaves `s² · gain` in the
/// processed signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseGains {
    pub filter: f64,
    pub velocity: f64,
    pub acceleration: f64,
    pub cross: f64,
}

pub fn noise_gains(filter: &Butterworth) -> NoiseGains {
    let m = filter.memory_samples();
    let n = 4 * m + 1;
    let mut x = vec![0.0; n];
    x[2 * m] = 1.0;
    let h = filter.filtfilt(&x);
    let fs = filter.sample_rate_hz;
    let g1 = central_velocity(&h, fs);
    let g2 = central_acceleration(&h, fs);
    let inner = 1..n - 1;
    NoiseGains {
        filter: h.iter().map(|v| v * v).sum(),
        velocity: g1[inner.clone()].iter().map(|v| v * v).sum(),
        acceleration: g2[inner.clone()].iter().map(|v| v * v).sum(),
        cross: g1[inner.clone()]
            .iter()
            .zip(&g2[inner])
            .map(|(a, b)| a * b)
            .sum(),
    }
}

/// The velocity estimate's noise [rad/s]: white position noise of one-sided PSD
/// `floor` [rad²/Hz] (variance `floor · fs/2` per sample) through the filter and the
/// central difference.
pub fn velocity_noise_rad_s(floor: f64, fs: f64, g: &NoiseGains) -> f64 {
    (floor * 0.5 * fs * g.velocity).sqrt()
}

/// The residual the noise floors alone leave in a sample of the processed equation
/// [N m]: the force's white noise through the filter, and the position's through
/// `M D2 + Fv D1` (what the regressors carry into the fitted force).
pub fn residual_noise_nm(
    force_floor: f64,
    position_floor: f64,
    fs: f64,
    g: &NoiseGains,
    inertia: f64,
    viscous: f64,
) -> f64 {
    let half = 0.5 * fs;
    let pos = inertia * inertia * g.acceleration
        + viscous * viscous * g.velocity
        + 2.0 * inertia * viscous * g.cross;
    (force_floor * half * g.filter + position_floor * half * pos.max(0.0)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(n: usize, theta: [f64; 4]) -> Samples {
        // a deterministic, well-excited set of equations with a small pseudo-noise
        let mut s = Samples::default();
        for k in 0..n {
            let t = k as f64 * 0.01;
            let qdd = (1.3 * t).sin() * 5.0;
            let qd = (0.7 * t).cos() * 2.0;
            let sg = qd.signum();
            let e = (((k * 7919) % 101) as f64 / 101.0 - 0.5) * 0.01;
            s.tau_nm
                .push(theta[0] * qdd + theta[1] * qd + theta[2] * sg + theta[3] + e);
            s.qdd_rad_s2.push(qdd);
            s.qd_rad_s.push(qd);
            s.sign.push(sg);
        }
        s.candidates = n;
        s
    }

    #[test]
    fn least_squares_recovers_the_parameters_and_its_sigmas_are_the_formula() {
        let s = samples(3000, [2.0, 0.5, 0.3, -0.1]);
        let fit = least_squares(&s, &RIGID_FRICTION).unwrap();
        for (got, want) in fit.theta.iter().zip([2.0, 0.5, 0.3, -0.1]) {
            assert!((got - want).abs() < 1e-3, "{got} vs {want}");
        }
        // the naive reference: normal equations and an explicit inverse
        let x = nalgebra::DMatrix::from_fn(s.len(), 4, |i, j| match j {
            0 => s.qdd_rad_s2[i],
            1 => s.qd_rad_s[i],
            2 => s.sign[i],
            _ => 1.0,
        });
        let y = nalgebra::DVector::from_column_slice(&s.tau_nm);
        let xtx = x.transpose() * &x;
        let inv = xtx.clone().try_inverse().unwrap();
        let th = &inv * x.transpose() * &y;
        let r = &y - &x * &th;
        let s2 = r.norm_squared() / (s.len() - 4) as f64;
        for j in 0..4 {
            assert!((th[j] - fit.theta[j]).abs() < 1e-9);
            let sd = (s2 * inv[(j, j)]).sqrt();
            assert!(
                (sd / fit.std[j] - 1.0).abs() < 1e-6,
                "{sd} vs {}",
                fit.std[j]
            );
        }
        let e = xtx.symmetric_eigenvalues();
        let cond = (e.max() / e.min()).sqrt();
        assert!((cond / fit.condition - 1.0).abs() < 1e-6);
        assert!((fit.relative_error - r.norm() / y.norm()).abs() < 1e-12);
        let (rss, rel) = prediction_error(&s, &fit);
        assert!((rss / fit.rss - 1.0).abs() < 1e-9 && (rel - fit.relative_error).abs() < 1e-12);
    }

    /// A double integrator under a held force: the central second difference equals the
    /// held force's two-sample mean over M, to rounding (the naive reference: exact
    /// integration of piecewise-constant accelerations).
    #[test]
    fn held_force_matches_the_zero_order_hold() {
        let (m, dt, d) = (2.5, 1e-3, 1usize);
        let tau: Vec<f64> = (0..200).map(|k| ((k * 37) % 17) as f64 - 8.0).collect();
        let (mut q, mut v) = (vec![0.0; 200], 0.0);
        for k in 1..200 {
            // over [t_(k-1), t_k) the force recorded at k-1-d acts
            let a = if k > d { tau[k - 1 - d] / m } else { 0.0 };
            q[k] = q[k - 1] + v * dt + 0.5 * a * dt * dt;
            v += a * dt;
        }
        let qdd = central_acceleration(&q, 1.0 / dt);
        let held = held_force(&tau, d);
        for k in (d + 2)..199 {
            assert!(
                (qdd[k] * m - held[k]).abs() < 1e-6,
                "{k}: {} vs {}",
                qdd[k] * m,
                held[k]
            );
        }
    }

    #[test]
    fn rank_deficient_or_too_few_samples_give_none() {
        let mut s = samples(100, [1.0, 0.0, 0.0, 0.0]);
        s.qd_rad_s.iter_mut().for_each(|v| *v = 1.0); // equal to the offset column
        assert!(least_squares(&s, &[Column::Viscous, Column::Offset]).is_none());
        let s = samples(3, [1.0, 0.0, 0.0, 0.0]);
        assert!(least_squares(&s, &RIGID_FRICTION).is_none());
    }

    #[test]
    fn noise_gains_match_simulated_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let f = Butterworth::low_pass(4, 60.0, 1000.0).unwrap();
        let g = noise_gains(&f);
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let x: Vec<f64> = (0..200_000).map(|_| normal.sample(&mut rng)).collect();
        let y = f.filtfilt(&x);
        let v = central_velocity(&y, 1000.0);
        let a = central_acceleration(&y, 1000.0);
        let var = |z: &[f64]| {
            z[1000..z.len() - 1000].iter().map(|v| v * v).sum::<f64>() / (z.len() - 2000) as f64
        };
        assert!((var(&y) / g.filter - 1.0).abs() < 0.03);
        assert!((var(&v) / g.velocity - 1.0).abs() < 0.03);
        assert!((var(&a) / g.acceleration - 1.0).abs() < 0.03);
    }
}
