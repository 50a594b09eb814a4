//! How clearly an effect shows in a measurement, computed from what only the world knows
//! (the plant with and without it, the excitation's power, the encoder, the disturbance),
//! independently of the diagnosis; used to size each effect and to declare where a cause
//! acts.
//!
//! The reference measurement is a random-phase multisine on the full grid of the case's
//! band, at the case's two levels, `periods` steady periods of the case's period. Per
//! line, the one-sigma scatter of `ln H` is
//! `s^2 = 4 (v_meas / |H|^2 + s_w^2 |H_w / H|^2) / (N P A^2)`: `v_meas` the white noise of
//! the reading per sample (`q^2 / 12` of an encoder count `q` for a position,
//! `(q f_s)^2 / 6` for the velocity reading), `s_w` the disturbance torque per sample and
//! `H_w` its path to the reading, `A` the line's amplitude, `N P` the samples averaged.
//! The **visibility** of a change `D = ln(H_with / H_without)` is
//! `sqrt(mean over the lines of both levels of |D|^2 / s^2)`: the RMS of the change in
//! units of the line noise (equal to the diagnosis's systematic gap over its noise RMS,
//! inverse-variance weighted, when the nominal model is the true one). Nonlinear plants'
//! `H` comes from noise-free simulations (two transient periods, one analysed),
//! the linear ones' from [`super::analytic`].

use super::analytic;
use super::plant::{Output, Plant};
use super::simulator::Sim;
use super::substeps::{substeps, Peaks};
use flexid::excitation::{AmplitudeShape, MultisineDesign, PhaseDesign};
use flexid::Complex64;
use realfft::RealFftPlanner;

/// The reference measurement of a case.
#[derive(Debug, Clone)]
pub struct Reference {
    pub fs_hz: f64,
    /// The full grid of the band [Hz], `k fs / N`.
    pub lines_hz: Vec<f64>,
    pub period_samples: usize,
    /// Steady periods averaged.
    pub periods: usize,
    pub levels_rms_nm: Vec<f64>,
    pub phase_seed: u64,
}

impl Reference {
    /// One line's amplitude [N m] at level `i` (the RMS spread evenly over the lines).
    pub fn line_amplitude_nm(&self, i: usize) -> f64 {
        self.levels_rms_nm[i] * (2.0 / self.lines_hz.len() as f64).sqrt()
    }

    /// One period of the reference multisine at level `i` [N m].
    pub fn period(&self, i: usize) -> Vec<f64> {
        let mut d = MultisineDesign::new(
            self.fs_hz,
            self.period_samples,
            [self.lines_hz[0], *self.lines_hz.last().unwrap()],
            100.0 * self.levels_rms_nm[i],
            self.levels_rms_nm[i],
        );
        d.phases = PhaseDesign::Random {
            seed: self.phase_seed,
        };
        d.amplitude = AmplitudeShape::Flat;
        d.generate().expect("a valid reference multisine").period
    }
}

/// The one-sigma scatter of `ln H` per line and level for `plant`'s measurement.
pub fn sigma_ln(plant: &Plant, r: &Reference) -> Vec<Vec<f64>> {
    let q = plant.sensor.count_rad();
    let np = (r.period_samples * r.periods) as f64;
    (0..r.levels_rms_nm.len())
        .map(|i| {
            let a = r.line_amplitude_nm(i);
            r.lines_hz
                .iter()
                .map(|&f| {
                    let h = analytic::position(plant, f);
                    let hw = analytic::disturbance_position(plant, f);
                    let w = 2.0 * std::f64::consts::PI * f;
                    let reading = match plant.sensor.output {
                        Output::Position => q * q / 12.0 / h.norm_sqr(),
                        Output::Velocity => (q * r.fs_hz).powi(2) / 6.0 / (w * w * h.norm_sqr()),
                    };
                    let dist = (plant.torque_noise_nm * hw.norm() / h.norm()).powi(2);
                    (4.0 * (reading + dist) / (np * a * a)).sqrt()
                })
                .collect()
        })
        .collect()
}

/// `sqrt(mean |D|^2 / s^2)` over every line of every level.
pub fn visibility(delta: &[Vec<Complex64>], sigma: &[Vec<f64>]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (d, sg) in delta.iter().zip(sigma) {
        for (d, sg) in d.iter().zip(sg) {
            s += d.norm_sqr() / (sg * sg);
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// `ln(H_with / H_without)` per level from the small-signal responses (the same at
/// every level).
pub fn delta_linear(without: &Plant, with: &Plant, r: &Reference) -> Vec<Vec<Complex64>> {
    let d: Vec<Complex64> = r
        .lines_hz
        .iter()
        .map(|&f| (analytic::position(with, f) / analytic::position(without, f)).ln())
        .collect();
    vec![d; r.levels_rms_nm.len()]
}

/// The response per line and level of `plant` (torque command -> differenced measured
/// position), simulated without noise on the reference multisine (two transient periods,
/// the third analysed), with the sub-steps for `peaks`. Only ratios of such responses are
/// used.
pub fn simulated_response(plant: &Plant, r: &Reference, peaks: &Peaks) -> Vec<Vec<Complex64>> {
    let n = r.period_samples;
    let steps = substeps(plant, r.fs_hz, peaks);
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let spectrum = |x: &[f64]| {
        let mut inp = x.to_vec();
        let mut out = fft.make_output_vec();
        fft.process(&mut inp, &mut out)
            .expect("an FFT of the period");
        out
    };
    (0..r.levels_rms_nm.len())
        .map(|i| {
            let period = r.period(i);
            let u: Vec<f64> = period.repeat(3);
            let mut sim = Sim::new(plant, r.fs_hz, steps, 0, true);
            sim.start_centred(&period);
            let y: Vec<f64> = sim.run(&u).iter().map(|s| s.position_rad).collect();
            // differenced: the drift of a free chain (a velocity offset) stays at DC
            let yd: Vec<f64> = (2 * n..3 * n).map(|j| y[j] - y[j - 1]).collect();
            let (uf, yf) = (spectrum(&u[2 * n..]), spectrum(&yd));
            r.lines_hz
                .iter()
                .map(|&f| {
                    let k = (f * n as f64 / r.fs_hz).round() as usize;
                    yf[k] / uf[k]
                })
                .collect()
        })
        .collect()
}

/// `ln(H_with / H_without)` from two simulated responses.
pub fn delta_of(without: &[Vec<Complex64>], with: &[Vec<Complex64>]) -> Vec<Vec<Complex64>> {
    without
        .iter()
        .zip(with)
        .map(|(a, b)| a.iter().zip(b).map(|(a, b)| (b / a).ln()).collect())
        .collect()
}

/// The size in `[lo, hi]` whose visibility is `target` (within 10 %), searched from
/// `start` in log-log steps; the bound when the target lies beyond it. Returns the size
/// and its visibility.
pub fn size_for(
    target: f64,
    lo: f64,
    hi: f64,
    start: f64,
    mut vis: impl FnMut(f64) -> f64,
) -> (f64, f64) {
    let close = |v: f64| (v / target).ln().abs() < 1.1f64.ln();
    let mut s = start.clamp(lo, hi);
    let mut v = vis(s);
    if close(v) {
        return (s, v);
    }
    // bracket: a below the target, b above it
    type Point = Option<(f64, f64)>;
    let (mut a, mut b): (Point, Point) = (None, None);
    for _ in 0..30 {
        if v < target {
            a = Some((s, v));
        } else {
            b = Some((s, v));
        }
        if let (Some(_), Some(_)) = (a, b) {
            break;
        }
        let next = if v < target { s * 4.0 } else { s / 4.0 };
        let bounded = next.clamp(lo, hi);
        if bounded == s {
            return (s, v);
        }
        s = bounded;
        v = vis(s);
        if close(v) {
            return (s, v);
        }
    }
    let (Some(mut a), Some(mut b)) = (a, b) else {
        return (s, v);
    };
    for _ in 0..12 {
        // interpolate ln v linearly in ln s, kept inside the bracket
        let (la, lb) = (a.0.ln(), b.0.ln());
        let (va, vb) = (a.1.max(1e-12).ln(), b.1.max(1e-12).ln());
        let t = ((target.ln() - va) / (vb - va)).clamp(0.1, 0.9);
        s = (la + t * (lb - la)).exp();
        v = vis(s);
        if close(v) {
            break;
        }
        if v < target {
            a = (s, v);
        } else {
            b = (s, v);
        }
    }
    (s, v)
}

/// Where a change acts on the FRF: the lines whose `|D|` (largest over the levels,
/// averaged over 5 neighbouring lines) reaches a tenth of its largest value, from the first
/// to the last [Hz]; `None` when nothing changes.
pub fn acting_band(delta: &[Vec<Complex64>], lines_hz: &[f64]) -> Option<[f64; 2]> {
    let m: Vec<f64> = (0..lines_hz.len())
        .map(|k| delta.iter().map(|d| d[k].norm()).fold(0.0, f64::max))
        .collect();
    let n = m.len();
    let smooth: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(2), (k + 3).min(n));
            m[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect();
    let top = smooth.iter().copied().fold(0.0, f64::max);
    if top <= 0.0 {
        return None;
    }
    let first = smooth.iter().position(|v| *v >= 0.1 * top)?;
    let last = smooth.iter().rposition(|v| *v >= 0.1 * top)?;
    Some([lines_hz[first], lines_hz[last]])
}

/// What a re-fitted nominal model absorbs of a change, to first order: the change's
/// weighted least-squares projection on the derivatives of `ln H` with respect to the
/// nominal chain's parameters (log inertias, stiffnesses, dampings, and the motor's
/// viscous friction to the ground) is removed, leaving what no nominal chain explains.
/// An effect "visible beyond the nominal model" shows that much against the noise after
/// the best nominal chain has taken what it can (a hardening spring's mean stiffening, a
/// friction's mean damping, ...).
pub struct Projector {
    /// Per parameter, per line: `d ln H / d p`.
    columns: Vec<Vec<Complex64>>,
    sigma: Vec<Vec<f64>>,
}

impl Projector {
    pub fn new(nominal: &Plant, r: &Reference, sigma: Vec<Vec<f64>>) -> Projector {
        let n = nominal.bodies();
        let jt = nominal.total_inertia_kgm2();
        let b_step = jt * 2.0 * std::f64::consts::PI * 0.1;
        let mut columns = Vec::new();
        // (which parameter, log or additive step)
        let mut params: Vec<(usize, usize, bool)> = Vec::new();
        for i in 0..n {
            params.push((0, i, true));
        }
        for k in 0..n - 1 {
            params.push((1, k, true));
            params.push((2, k, true));
        }
        params.push((3, 0, false));
        for (what, i, log) in params {
            let eps = 1e-6;
            let shifted = |sign: f64| {
                let mut p = nominal.clone();
                let v = match what {
                    0 => &mut p.inertia_kgm2[i],
                    1 => &mut p.couplings[i].stiffness_nm_per_rad,
                    2 => &mut p.couplings[i].damping_nms_per_rad,
                    _ => &mut p.motor_viscous_nms_per_rad,
                };
                if log {
                    *v *= (sign * eps).exp();
                } else {
                    *v += sign * eps * b_step;
                }
                p
            };
            let (up, down) = (shifted(1.0), shifted(-1.0));
            columns.push(
                r.lines_hz
                    .iter()
                    .map(|&f| {
                        (analytic::position(&up, f) / analytic::position(&down, f)).ln()
                            / (2.0 * eps)
                    })
                    .collect(),
            );
        }
        Projector { columns, sigma }
    }

    /// `delta` less its weighted projection on the nominal parameters' derivatives.
    #[allow(clippy::needless_range_loop)]
    pub fn residual(&self, delta: &[Vec<Complex64>]) -> Vec<Vec<Complex64>> {
        let m = self.columns.len();
        let mut a = vec![vec![0.0; m]; m];
        let mut b = vec![0.0; m];
        for (d, sg) in delta.iter().zip(&self.sigma) {
            for l in 0..d.len() {
                let w = 1.0 / (sg[l] * sg[l]);
                for j in 0..m {
                    let cj = self.columns[j][l];
                    b[j] += w * (cj.conj() * d[l]).re;
                    for k in j..m {
                        a[j][k] += w * (cj.conj() * self.columns[k][l]).re;
                    }
                }
            }
        }
        for j in 0..m {
            for k in 0..j {
                a[j][k] = a[k][j];
            }
        }
        let x = solve_symmetric(a, b);
        delta
            .iter()
            .map(|d| {
                d.iter()
                    .enumerate()
                    .map(|(l, v)| v - (0..m).map(|j| self.columns[j][l] * x[j]).sum::<Complex64>())
                    .collect()
            })
            .collect()
    }
}

/// Solve `A x = b` for a symmetric positive semi-definite `A` (Gaussian elimination with
/// a small ridge; a direction without information gets no weight).
#[allow(clippy::needless_range_loop)]
fn solve_symmetric(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let m = b.len();
    let scale = (0..m).map(|i| a[i][i]).fold(0.0, f64::max).max(1e-300);
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += 1e-12 * scale;
    }
    for c in 0..m {
        let p = (c..m)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        b.swap(c, p);
        let piv = a[c][c];
        if piv.abs() < 1e-300 {
            continue;
        }
        for r in c + 1..m {
            let f = a[r][c] / piv;
            for k in c..m {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; m];
    for c in (0..m).rev() {
        let s: f64 = (c + 1..m).map(|k| a[c][k] * x[k]).sum();
        x[c] = if a[c][c].abs() < 1e-300 {
            0.0
        } else {
            (b[c] - s) / a[c][c]
        };
    }
    x
}
