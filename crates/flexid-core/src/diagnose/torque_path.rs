//! The drive's torque path as its own torque reading shows it: `D = T_act / T_cmd`.
//!
//! A CiA 402 drive reports the torque it produces (0x6077, from the measured phase
//! currents), sampled at the same instants as the position. Whatever lies between the
//! command and the motor's torque (the current loop, a filter on the torque reference, a
//! dead zone) is in `D`; whatever lies after the torque (the mechanics, a filter on the
//! measured position, the encoder's mounting) is not. So `D` says on which side of the
//! torque a lag sits, which the torque -> position FRF alone cannot: a low-pass on the
//! measured position multiplies that FRF exactly as a current loop does.
//!
//! The model of `D` (derived here, checked in the tests against a fine-step simulation):
//! the command `u[j]` is held over `[jT + tau, (j+1)T + tau)` (zero-order hold after a delay
//! `tau = (m + phi) T`, `0 <= phi < 1`), passes a current loop `(A, B, C)` and is read at
//! `kT`, just before the new command can act. Over one sample the loop sees `u[k-m-1]`
//! for `phi T`, then `u[k-m]`:
//!
//! `x[k+1] = Phi x[k] + Gamma_a u[k-m-1] + Gamma_b u[k-m]`, `y[k] = C x[k]`,
//!
//! `Phi = e^(AT)`, `Gamma_a = e^(A(1-phi)T) int_0^(phi T) e^(As) ds B`,
//! `Gamma_b = int_0^((1-phi)T) e^(As) ds B`, so
//! `D(z) = C (zI - Phi)^-1 (Gamma_a z^(-m-1) + Gamma_b z^(-m))`. Without a loop the
//! reading is the command in effect just before `kT`, `u[k-1-m]`: `D = z^-(m+1)`, whatever
//! `phi` is (a delay of part of a sample does not show in a sampled staircase).
//!
//! Each model carries a real gain (the torque reading's scale, e.g. a rated torque entered
//! slightly wrong), fitted in closed form. Whole samples of delay are a convention of the
//! drive (when it samples the current against when it takes the set-point), so they are
//! free too: the torque reading is evidence on the loop, not on the delay.

use super::effects::EffectFit;
use super::lti::{zoh, Loop};
use super::noise::{self, NoiseChi2};
use super::simplex;
use crate::analysis::estimate_torque_path;
use crate::recording::Recording;
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::f64::consts::PI;

/// Whole samples of delay tried around a model's own [`WHOLE_SAMPLES_FREE`], and up to
/// which the static model's delay is searched: a drive that reports its current more than
/// this many cycles late is not a drive whose loop can be judged from its reading.
pub const WHOLE_SAMPLES_FREE: i32 = 4;

/// One level's torque reading against its command, on the excited lines.
#[derive(Debug, Clone)]
pub struct TorqueLevel {
    pub f: Vec<f64>,
    pub d: Vec<Complex64>,
    pub var: Vec<f64>,
    pub averages: usize,
}

/// A model of the torque path fitted to the reading.
#[derive(Debug, Clone, PartialEq)]
pub struct PathFit {
    /// The current loop (none: the reading is the command, delayed).
    pub lp: Option<Loop>,
    /// Delay of the command before the loop [s] (whole samples included).
    pub delay_s: f64,
    /// Scale of the reading [1].
    pub gain: f64,
    /// `sum |D - gain D_model|^2 / var` over all lines of all levels.
    pub chi2: f64,
}

/// What the torque reading says about the torque path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// The command, delayed and scaled, within the noise: no loop, no filter.
    Clean,
    /// A current loop, significant beyond the noise and explaining the reading.
    Loop,
    /// Something neither explains (a notch, a dead zone, ...).
    Departs,
}

/// The torque reading of every level, the two fits and what they say.
#[derive(Debug, Clone)]
pub struct TorquePath {
    pub levels: Vec<TorqueLevel>,
    pub fs: f64,
    pub noise: NoiseChi2,
    /// The best pure delay (no loop).
    pub clean: PathFit,
    /// The best current loop (order 1 or 2, the one the BIC prefers).
    pub with_loop: PathFit,
    pub shape: Shape,
    /// The chain identified with the loop the reading shows divided out of the motion's
    /// measurement ([`super::loop_free::start`]), with that loop: a start of the
    /// current-loop candidate in the basin of the chain behind the loop (set by the
    /// diagnosis; `None` when the reading shows no loop).
    pub loop_free: Option<super::lti::LinExt>,
}

impl TorquePath {
    /// The torque reading of each recording (`None` when one has none, or its estimate
    /// fails: the torque path is evidence, never a requirement).
    pub fn measure(recs: &[Recording], band_hz: Option<[f64; 2]>) -> Option<TorquePath> {
        let fs = recs.first()?.sample_rate_hz;
        let mut levels = Vec::with_capacity(recs.len());
        for r in recs {
            let e = estimate_torque_path(r, band_hz)?.ok()?;
            let keep = e.frf.usable_lines();
            if keep.is_empty() {
                return None;
            }
            levels.push(TorqueLevel {
                f: keep.iter().map(|&k| e.frf.freq_hz[k]).collect(),
                d: keep.iter().map(|&k| e.frf.h[k]).collect(),
                var: keep.iter().map(|&k| e.frf.var[k]).collect(),
                averages: e.averages,
            });
        }
        Some(Self::from_levels(levels, fs))
    }

    /// Fit the clean and the loop models to measured levels and decide the shape.
    pub fn from_levels(levels: Vec<TorqueLevel>, fs: f64) -> TorquePath {
        let noise = noise::reduced_chi2(
            &levels
                .iter()
                .map(|l| (l.f.len(), l.averages))
                .collect::<Vec<_>>(),
        );
        let mut tp = TorquePath {
            loop_free: None,
            levels,
            fs,
            noise,
            clean: PathFit {
                lp: None,
                delay_s: 0.0,
                gain: 1.0,
                chi2: f64::INFINITY,
            },
            with_loop: PathFit {
                lp: None,
                delay_s: 0.0,
                gain: 1.0,
                chi2: f64::INFINITY,
            },
            shape: Shape::Departs,
        };
        tp.clean = tp.fit_clean();
        tp.with_loop = tp.fit_loop();
        tp.shape = if tp.within_noise(tp.clean.chi2) {
            Shape::Clean
        } else if tp.loop_score() > 0.0 && tp.within_noise(tp.with_loop.chi2) {
            Shape::Loop
        } else {
            Shape::Departs
        };
        tp
    }

    pub fn lines(&self) -> usize {
        self.levels.iter().map(|l| l.f.len()).sum()
    }

    /// Whether a chi² over all lines is within the noise (as [`super::Data::within_noise`]).
    pub fn within_noise(&self, chi2: f64) -> bool {
        chi2 < self.noise.threshold * self.lines() as f64
    }

    /// The loop's chi² reduction over the clean model in units of the noise's mean, minus
    /// the BIC price of its parameters (bandwidth, the part of a sample of delay, and the
    /// damping for order 2): > 0 when the reading shows a loop.
    pub fn loop_score(&self) -> f64 {
        let k = match self.with_loop.lp {
            Some(Loop { order: 2, .. }) => 3.0,
            Some(_) => 2.0,
            None => return f64::NEG_INFINITY,
        };
        let n = (2 * self.lines()) as f64;
        (self.clean.chi2 - self.with_loop.chi2) / self.noise.mean - k * n.ln()
    }

    /// Whole samples of delay the reading shows beyond the recording's `io_delay` (the
    /// reading at `kT` is `u[k - 1 - io_delay - m]`), where it is clean; `None` otherwise
    /// (or when the reading is earlier than the recording says, which is no delay).
    pub fn whole_samples_beyond(&self, io_delay: u32) -> Option<u32> {
        if self.shape != Shape::Clean {
            return None;
        }
        let m = (self.clean.delay_s * self.fs).round() as i64 - io_delay as i64;
        u32::try_from(m).ok()
    }

    /// Whether a candidate's claim about the torque path contradicts the reading, where
    /// the reading is understood (its shape [`Shape::Clean`] or [`Shape::Loop`]; a reading
    /// that departs from both says nothing against anyone):
    /// - a current loop the reading would show beyond the noise, when the reading is the
    ///   delayed command within the noise;
    /// - a delay of `delay_s` beyond the recording's `io_delay` whole samples, when the
    ///   reading is clean and shows another number of whole samples: the command read back
    ///   at `kT` is `u[k - 1 - m]` with `m = floor(io_delay + delay_s / T)`, so the reading's
    ///   `m` must lie within the candidate's delay +- [`noise::SIGNIFICANT_SIGMA`] standard
    ///   deviations (the torque and the position are read at the same instant, so a
    ///   latency of the readings is in both and is no contradiction).
    ///
    /// Candidates without a loop or a delay make no claim about the torque path.
    ///
    /// `expected_chi2` is what noise alone gives the candidate's fit (the line noise times
    /// its lines): where the fit ends above it, its model misses more than the noise and
    /// its delay carries that misfit too (a delay fitted on top of another effect whose
    /// parameters are held: 0.83 +- 0.05 samples where the truth is 1.02), so the delay's
    /// standard deviation is scaled by `sqrt(chi2 / expected_chi2)` (the Birge ratio)
    /// before the whole samples are compared.
    ///
    /// Where the reading shows a current loop ([`Shape::Loop`]), the loop's continuous
    /// output is sampled, so a part of a sample of delay before it shows too: a candidate's
    /// delay (on the reading's loop, or on its own where it has one) contradicts the
    /// reading when no delay within its reach (as above) brings the reading's model within
    /// the noise (a lag fitted as a delay that the torque path does not carry is after the
    /// torque: in the position measurement or the mechanics).
    pub fn contradicts(&self, fit: &EffectFit, io_delay: u32, expected_chi2: f64) -> bool {
        match self.shape {
            Shape::Clean => self.clean_contradicts(fit, io_delay, expected_chi2),
            Shape::Loop => self.loop_contradicts(fit, io_delay, expected_chi2),
            Shape::Departs => false,
        }
    }

    /// How far a candidate's delay may be from its value: [`noise::SIGNIFICANT_SIGMA`] of
    /// its standard deviation scaled by the fit's Birge ratio (infinite without one).
    fn delay_reach(fit: &EffectFit, expected_chi2: f64) -> f64 {
        let sd = fit
            .params
            .iter()
            .find(|p| p.name == "delay_s")
            .map_or(0.0, |p| {
                if p.std.is_finite() {
                    p.std
                } else {
                    f64::INFINITY
                }
            });
        let birge = if expected_chi2 > 0.0 {
            (fit.chi2 / expected_chi2).max(1.0).sqrt()
        } else {
            1.0
        };
        noise::SIGNIFICANT_SIGMA * sd * birge
    }

    /// [`TorquePath::contradicts`] where the reading shows a loop.
    fn loop_contradicts(&self, fit: &EffectFit, io_delay: u32, expected_chi2: f64) -> bool {
        let lin = &fit.lin;
        if lin.delay_s <= 0.0 {
            return false;
        }
        let Some(lp) = lin.current_loop.or(self.with_loop.lp) else {
            return false;
        };
        let reach = Self::delay_reach(fit, expected_chi2);
        if !reach.is_finite() {
            return false;
        }
        let ts = 1.0 / self.fs;
        let tau = io_delay as f64 * ts + lin.delay_s;
        let (lo, hi) = ((tau - reach).max(0.0), tau + reach);
        let best = [lo, tau, hi, self.with_loop.delay_s.clamp(lo, hi)]
            .into_iter()
            .map(|t| self.chi2_gain(Some(&lp), t).0)
            .fold(f64::INFINITY, f64::min);
        !self.within_noise(best)
    }

    /// [`TorquePath::contradicts`] where the reading is clean.
    fn clean_contradicts(&self, fit: &EffectFit, io_delay: u32, expected_chi2: f64) -> bool {
        let lin = &fit.lin;
        let ts = 1.0 / self.fs;
        if let Some(lp) = &lin.current_loop {
            // the loop after the whole samples the reading shows and the candidate's part
            // of a sample: a loop far above the band reads back as the command itself
            let part = (lin.delay_s.max(0.0) / ts).fract() * ts;
            let (chi2, _) = self.chi2_gain(Some(lp), self.clean.delay_s + part);
            if !self.within_noise(chi2) {
                return true;
            }
        }
        if lin.delay_s <= 0.0 {
            return false;
        }
        let reach = Self::delay_reach(fit, expected_chi2);
        // the candidate's whole samples, from its delay's lowest to its highest plausible value
        let lo = ((lin.delay_s - reach).max(0.0) / ts + io_delay as f64 + 1e-9).floor();
        let hi = ((lin.delay_s + reach) / ts + io_delay as f64 + 1e-9).floor();
        let m = (self.clean.delay_s / ts).round();
        m < lo || m > hi
    }

    /// chi² and the closed-form gain of one model (`Re sum conj(M) D / var / sum |M|² / var`).
    fn chi2_gain(&self, lp: Option<&Loop>, delay_s: f64) -> (f64, f64) {
        let model = Sampled::new(lp, delay_s, self.fs);
        let (mut num, mut den) = (0.0, 0.0);
        let mut m_all: Vec<Vec<Complex64>> = Vec::with_capacity(self.levels.len());
        for l in &self.levels {
            let m: Vec<Complex64> = l.f.iter().map(|&f| model.at(f)).collect();
            for ((d, v), mk) in l.d.iter().zip(&l.var).zip(&m) {
                num += (mk.conj() * d).re / v;
                den += mk.norm_sqr() / v;
            }
            m_all.push(m);
        }
        let g = if den > 0.0 { num / den } else { 1.0 };
        let chi2 = self
            .levels
            .iter()
            .zip(&m_all)
            .map(|(l, m)| {
                l.d.iter()
                    .zip(&l.var)
                    .zip(m)
                    .map(|((d, v), mk)| (d - g * mk).norm_sqr() / v)
                    .sum::<f64>()
            })
            .sum::<f64>();
        (
            if chi2.is_finite() {
                chi2
            } else {
                f64::INFINITY
            },
            g,
        )
    }

    /// The best pure delay: whole samples 0 to [`WHOLE_SAMPLES_FREE`] (a part of a
    /// sample does not show without a loop).
    fn fit_clean(&self) -> PathFit {
        let ts = 1.0 / self.fs;
        (0..=WHOLE_SAMPLES_FREE)
            .map(|m| {
                let (chi2, gain) = self.chi2_gain(None, m as f64 * ts);
                PathFit {
                    lp: None,
                    delay_s: m as f64 * ts,
                    gain,
                    chi2,
                }
            })
            .min_by(|a, b| a.chi2.total_cmp(&b.chi2))
            .expect("at least one delay")
    }

    /// The best current loop: order 1 on a grid of bandwidths (from a tenth of the lowest
    /// line to ten times the sample rate) and delays (whole samples and quarters), polished
    /// by a simplex; then order 2 from it at three dampings. The order the BIC prefers.
    fn fit_loop(&self) -> PathFit {
        let ts = 1.0 / self.fs;
        let f_lo = self
            .levels
            .iter()
            .filter_map(|l| l.f.first().copied())
            .fold(f64::INFINITY, f64::min)
            .max(1e-3);
        let (b_lo, b_hi) = ((0.1 * f_lo).ln(), (10.0 * self.fs).ln());
        let cost1 = |x: &[f64]| {
            let lp = loop1(x[0].exp());
            self.chi2_gain(Some(&lp), x[1].max(0.0) * ts).0
        };
        let mut best = (vec![0.0, 0.0], f64::INFINITY);
        for i in 0..24 {
            let lb = b_lo + (b_hi - b_lo) * i as f64 / 23.0;
            for q in 0..(4 * WHOLE_SAMPLES_FREE + 1) {
                let x = vec![lb, 0.25 * q as f64];
                let c = cost1(&x);
                if c < best.1 {
                    best = (x, c);
                }
            }
        }
        let s1 = simplex::minimise(&best.0, &[0.2, 0.2], 200, cost1);
        let first = self.path_fit(Some(loop1(s1.x[0].exp())), s1.x[1].max(0.0) * ts);
        let cost2 = |x: &[f64]| {
            let lp = loop2(x[0].exp(), x[1].exp());
            self.chi2_gain(Some(&lp), x[2].max(0.0) * ts).0
        };
        let second = [0.4f64, 0.7, 1.0]
            .iter()
            .map(|z| simplex::minimise(&[s1.x[0], z.ln(), s1.x[1]], &[0.2, 0.3, 0.2], 300, cost2))
            .min_by(|a, b| a.f.total_cmp(&b.f))
            .map(|s| {
                self.path_fit(
                    Some(loop2(s.x[0].exp(), s.x[1].exp())),
                    s.x[2].max(0.0) * ts,
                )
            })
            .expect("three starts");
        // one parameter more for order 2: its BIC price in units of the noise's mean
        let price = (2 * self.lines()) as f64;
        if first.chi2 - second.chi2 > self.noise.mean * price.ln() {
            second
        } else {
            first
        }
    }

    fn path_fit(&self, lp: Option<Loop>, delay_s: f64) -> PathFit {
        let (chi2, gain) = self.chi2_gain(lp.as_ref(), delay_s);
        PathFit {
            lp,
            delay_s,
            gain,
            chi2,
        }
    }

    /// One line for the notes.
    pub fn describe(&self) -> String {
        let lines = self.lines() as f64;
        match self.shape {
            Shape::Clean => format!(
                "torque path: the drive's torque reading is its command of {:.0} sample(s) before, scaled {:.4}, within the noise (reduced chi2 {:.3}, threshold {:.3}): no current loop or filter acts between command and torque",
                self.clean.delay_s * self.fs + 1.0,
                self.clean.gain,
                self.clean.chi2 / lines,
                self.noise.threshold
            ),
            Shape::Loop => {
                let lp = self.with_loop.lp.expect("a loop fit");
                format!(
                    "torque path: the drive's torque reading shows a current loop of order {} at {:.1} Hz (delay {:.2} samples; reduced chi2 {:.3} against {:.3} without it, threshold {:.3})",
                    lp.order,
                    lp.bandwidth_hz,
                    self.with_loop.delay_s * self.fs,
                    self.with_loop.chi2 / lines,
                    self.clean.chi2 / lines,
                    self.noise.threshold
                )
            }
            Shape::Departs => format!(
                "torque path: the drive's torque reading departs from its command in a way neither a delay (reduced chi2 {:.3}) nor a current loop ({:.3}) explains (threshold {:.3}): something acts between command and torque (a filter on the torque reference, a dead zone, ...)",
                self.clean.chi2 / lines,
                self.with_loop.chi2 / lines,
                self.noise.threshold
            ),
        }
    }
}

/// Drop the candidates whose torque path the reading contradicts ([`TorquePath::contradicts`],
/// `expected_chi2` what noise alone gives their fits), with a note for each; returns the
/// dropped fits (evidence of a lag after the torque, [`super::after_torque`]).
pub fn drop_contradicted(
    tp: &TorquePath,
    io_delay: u32,
    expected_chi2: f64,
    fits: &mut Vec<EffectFit>,
    notes: &mut Vec<String>,
) -> Vec<EffectFit> {
    let (bad, good): (Vec<EffectFit>, Vec<EffectFit>) = std::mem::take(fits)
        .into_iter()
        .partition(|f| tp.contradicts(f, io_delay, expected_chi2));
    *fits = good;
    for f in &bad {
        let claim = match f.lin.current_loop {
            Some(lp) => format!(
                "current loop (order {}, {:.1} Hz)",
                lp.order, lp.bandwidth_hz
            ),
            None => format!(
                "delay of {:.2} samples beyond the recording's {io_delay}",
                f.lin.delay_s * tp.fs
            ),
        };
        notes.push(format!(
            "{}: its {claim} is not in the drive's torque reading, which is the command of {:.0} sample(s) before within the noise: not a candidate (the lag is after the torque: in the position measurement or the mechanics)",
            f.effect,
            tp.clean.delay_s * tp.fs + 1.0,
        ));
    }
    bad
}

fn loop1(bw_hz: f64) -> Loop {
    Loop {
        order: 1,
        bandwidth_hz: bw_hz,
        zeta: 1.0,
    }
}

fn loop2(bw_hz: f64, zeta: f64) -> Loop {
    Loop {
        order: 2,
        bandwidth_hz: bw_hz,
        zeta,
    }
}

/// The sampled torque path of the module's model, ready to evaluate on any line.
pub struct Sampled {
    /// Whole samples of delay `m`.
    m: i32,
    /// `Phi`, `Gamma_a`, `Gamma_b`, `C` of a loop with one or two states (none: static).
    lp: Option<(DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>)>,
    ts: f64,
}

impl Sampled {
    pub fn new(lp: Option<&Loop>, delay_s: f64, fs: f64) -> Sampled {
        let ts = 1.0 / fs;
        let total = delay_s.max(0.0) / ts;
        let mut m = total.floor();
        let mut phi = total - m;
        if phi > 1.0 - 1e-9 {
            m += 1.0;
            phi = 0.0;
        }
        let lp = lp.map(|l| {
            let (a, b, c) = continuous(l);
            let (ad, _) = zoh(&a, &b, ts);
            let (ea, ia) = zoh(&a, &b, (1.0 - phi) * ts);
            let (_, ip) = zoh(&a, &b, phi * ts);
            (ad, ea * ip, ia, c)
        });
        Sampled {
            m: m as i32,
            lp,
            ts,
        }
    }

    /// `D` at `f_hz`.
    pub fn at(&self, f_hz: f64) -> Complex64 {
        let z = Complex64::from_polar(1.0, 2.0 * PI * f_hz * self.ts);
        let zi = 1.0 / z;
        let zm = zi.powi(self.m);
        let Some((phi, ga, gb, c)) = &self.lp else {
            return zm * zi;
        };
        // (zI - Phi) x = Gamma_a z^(-m-1) + Gamma_b z^(-m), one or two states, on the stack
        let g = |i: usize| ga[(i, 0)] * zm * zi + gb[(i, 0)] * zm;
        if phi.nrows() == 1 {
            return c[(0, 0)] * g(0) / (z - phi[(0, 0)]);
        }
        // 2 x 2 by Cramer's rule
        let (a, b) = (z - phi[(0, 0)], -phi[(0, 1)]);
        let (cc, d) = (-phi[(1, 0)], z - phi[(1, 1)]);
        let det = a * d - b * cc;
        let x0 = (g(0) * d - b * g(1)) / det;
        let x1 = (a * g(1) - cc * g(0)) / det;
        c[(0, 0)] * x0 + c[(0, 1)] * x1
    }
}

/// `(A, B, C)` of a loop: order 1 `1/(1 + s/wc)`, order 2 `wc²/(s² + 2 zeta wc s + wc²)`.
fn continuous(l: &Loop) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let wc = 2.0 * PI * l.bandwidth_hz;
    if l.order == 1 {
        (
            DMatrix::from_element(1, 1, -wc),
            DMatrix::from_element(1, 1, wc),
            DMatrix::from_element(1, 1, 1.0),
        )
    } else {
        (
            DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wc * wc, -2.0 * l.zeta * wc]),
            DMatrix::from_row_slice(2, 1, &[0.0, wc * wc]),
            DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::lti::LinExt;

    /// Fine-step reference: the command held over each sample after the delay, through the
    /// loop by RK4 at `sub` steps per sample, read just before each sample instant; the
    /// response to a sine at line `k` of `n` samples, after settling, by a DFT of one period.
    fn simulated(lp: Option<&Loop>, delay_s: f64, fs: f64, n: usize, k: usize) -> Complex64 {
        let ts = 1.0 / fs;
        let sub = 400usize;
        let h = ts / sub as f64;
        let periods = 6;
        let u: Vec<f64> = (0..n * periods)
            .map(|i| (2.0 * PI * k as f64 * i as f64 / n as f64).cos())
            .collect();
        let cmd = |t: f64| -> f64 {
            // the command in effect at t: u[j] on [jT + delay, (j+1)T + delay)
            let j = ((t - delay_s) / ts).floor();
            if j < 0.0 {
                0.0
            } else {
                u[(j as usize).min(u.len() - 1)]
            }
        };
        let (a, b, c) = lp.map(continuous).unwrap_or_else(|| {
            (
                DMatrix::zeros(1, 1),
                DMatrix::zeros(1, 1),
                DMatrix::zeros(1, 1),
            )
        });
        let ns = a.nrows();
        let mut x = nalgebra::DVector::<f64>::zeros(ns);
        let mut y = Vec::with_capacity(u.len());
        let f = |x: &nalgebra::DVector<f64>, uu: f64| &a * x + &b * uu;
        for i in 0..u.len() {
            let t0 = i as f64 * ts;
            // the reading at kT, just before: the static path reads the command at kT-
            y.push(if lp.is_some() {
                (&c * &x)[0]
            } else {
                cmd(t0 - 1e-9 * ts)
            });
            for s in 0..sub {
                let t = t0 + s as f64 * h;
                // the command is constant within a sub-step when the delay's fraction
                // falls on a sub-step boundary (the tests choose such delays)
                let uu = cmd(t + 0.5 * h);
                let k1 = f(&x, uu);
                let k2 = f(&(&x + &k1 * (0.5 * h)), uu);
                let k3 = f(&(&x + &k2 * (0.5 * h)), uu);
                let k4 = f(&(&x + &k3 * h), uu);
                x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
            }
        }
        let last = &y[(periods - 1) * n..];
        let dft = |s: &[f64]| -> Complex64 {
            s.iter()
                .enumerate()
                .map(|(i, v)| v * Complex64::from_polar(1.0, -2.0 * PI * (k * i) as f64 / n as f64))
                .sum()
        };
        let uu = &u[(periods - 1) * n..];
        dft(last) / dft(uu)
    }

    #[test]
    fn the_sampled_model_matches_a_fine_step_simulation() {
        let fs = 1000.0;
        let n = 64;
        for lp in [
            None,
            Some(loop1(180.0)),
            Some(loop2(260.0, 0.6)),
            Some(loop1(2500.0)),
        ] {
            for delay_samples in [0.0, 0.25, 1.0, 1.75] {
                let m = Sampled::new(lp.as_ref(), delay_samples / fs, fs);
                for k in [1usize, 7, 20, 31] {
                    let want = simulated(lp.as_ref(), delay_samples / fs, fs, n, k);
                    let got = m.at(k as f64 * fs / n as f64);
                    assert!(
                        (got - want).norm() < 1e-6 * want.norm().max(1e-3),
                        "{lp:?} delay {delay_samples} line {k}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// Levels of `D` from a model, with relative noise `rel` (deterministic pseudo-noise).
    fn levels_of(
        lp: Option<&Loop>,
        delay_s: f64,
        gain: f64,
        fs: f64,
        rel: f64,
    ) -> Vec<TorqueLevel> {
        let m = Sampled::new(lp, delay_s, fs);
        let mut state = 7u64;
        // Box-Muller from the crate's test generator
        let mut normal = || {
            let (u1, u2) = (
                crate::frf::test_rng::lcg(&mut state).max(1e-300),
                crate::frf::test_rng::lcg(&mut state),
            );
            (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
        };
        let f: Vec<f64> = (1..200).map(|i| i as f64 * 2.0).collect();
        let d = f
            .iter()
            .map(|&fk| {
                let e = Complex64::new(normal(), normal()) * (rel / 2f64.sqrt());
                gain * m.at(fk) * (1.0 + e)
            })
            .collect::<Vec<_>>();
        let var = d.iter().map(|v| (rel * v.norm()).powi(2)).collect();
        vec![TorqueLevel {
            f,
            d,
            var,
            averages: 8,
        }]
    }

    /// A candidate's fit with a torque path: `lp`, and `delay_s` +- `sd`.
    fn candidate(lp: Option<Loop>, delay_s: f64, sd: f64) -> EffectFit {
        let mut lin =
            LinExt::nominal(crate::model::Chain::new(vec![1e-3], vec![], vec![]).unwrap());
        lin.current_loop = lp;
        lin.delay_s = delay_s;
        EffectFit {
            effect: super::super::Effect::TimeDelay,
            params: vec![EffectFit::param("delay_s", delay_s, sd)],
            added: 1,
            chi2: 0.0,
            model: Vec::new(),
            lin,
        }
    }

    #[test]
    fn a_clean_reading_is_clean_and_contradicts_a_loop() {
        let fs = 1000.0;
        // the command of one sample before (no delay beyond the reading's instant)
        let tp = TorquePath::from_levels(levels_of(None, 0.0, 0.98, fs, 1e-3), fs);
        assert_eq!(tp.shape, Shape::Clean, "{}", tp.describe());
        assert!((tp.clean.gain - 0.98).abs() < 1e-3);
        assert_eq!(tp.clean.delay_s, 0.0);
        assert!(!tp.contradicts(&candidate(None, 0.0, 0.0), 0, 0.0));
        assert!(tp.contradicts(&candidate(Some(loop1(300.0)), 0.0, 0.0), 0, 0.0));
        // a loop far above the band is the command itself
        assert!(!tp.contradicts(&candidate(Some(loop1(1e9)), 0.0, 0.0), 0, 0.0));
        // a part of a sample does not show; whole samples do, within the candidate's reach
        assert!(!tp.contradicts(&candidate(None, 0.6 / fs, 0.01 / fs), 0, 0.0));
        assert!(tp.contradicts(&candidate(None, 2.7 / fs, 0.01 / fs), 0, 0.0));
        assert!(!tp.contradicts(&candidate(None, 1.02 / fs, 0.01 / fs), 0, 0.0));
        assert!(tp.contradicts(&candidate(None, 1.1 / fs, 0.01 / fs), 0, 0.0));
        // the recording's own whole-sample delay counts
        assert!(tp.contradicts(&candidate(None, 0.6 / fs, 0.01 / fs), 1, 0.0));
    }

    /// A delay fitted on top of another effect, biased by that effect's held parameters
    /// (0.83 +- 0.05 samples where the reading shows one whole sample): contradicted when
    /// its fit is within the noise, admitted when the fit's chi² is ten times what noise
    /// gives (its reach scaled by the Birge ratio sqrt(10)).
    #[test]
    fn a_delay_whose_fit_misses_more_than_the_noise_reaches_further() {
        let fs = 1000.0;
        let tp = TorquePath::from_levels(levels_of(None, 1.02 / fs, 1.0, fs, 1e-3), fs);
        assert_eq!(tp.shape, Shape::Clean, "{}", tp.describe());
        let mut c = candidate(None, 0.83 / fs, 0.05 / fs);
        c.chi2 = 1000.0;
        assert!(tp.contradicts(&c, 0, 1000.0));
        c.chi2 = 10_000.0;
        assert!(!tp.contradicts(&c, 0, 1000.0));
        // an expected chi² unknown (0): no scaling
        assert!(tp.contradicts(&c, 0, 0.0));
    }

    #[test]
    fn a_reading_delayed_by_whole_samples_admits_the_delay_that_shows_them() {
        let fs = 1000.0;
        let tp = TorquePath::from_levels(levels_of(None, 2.3 / fs, 1.0, fs, 1e-3), fs);
        assert_eq!(tp.shape, Shape::Clean, "{}", tp.describe());
        assert!(!tp.contradicts(&candidate(None, 2.3 / fs, 0.02 / fs), 0, 0.0));
        assert!(tp.contradicts(&candidate(None, 0.4 / fs, 0.02 / fs), 0, 0.0));
        assert!(!tp.contradicts(&candidate(None, 0.4 / fs, 0.02 / fs), 2, 0.0));
    }

    #[test]
    fn a_loop_is_found_and_a_candidate_with_it_is_admitted() {
        let fs = 1000.0;
        let truth = loop2(220.0, 0.7);
        let tp = TorquePath::from_levels(levels_of(Some(&truth), 0.4 / fs, 1.0, fs, 1e-3), fs);
        assert_eq!(tp.shape, Shape::Loop, "{}", tp.describe());
        let lp = tp.with_loop.lp.unwrap();
        assert_eq!(lp.order, 2);
        assert!((lp.bandwidth_hz / 220.0 - 1.0).abs() < 0.02, "{lp:?}");
        assert!(!tp.contradicts(&candidate(Some(truth), 0.4 / fs, 0.0), 0, 0.0));
        // a delay alone, on the loop as read: the part of a sample shows behind a loop
        assert!(!tp.contradicts(&candidate(None, 0.4 / fs, 0.02 / fs), 0, 0.0));
        assert!(tp.contradicts(&candidate(None, 0.15 / fs, 0.02 / fs), 0, 0.0));
        assert!(tp.contradicts(&candidate(None, 2.7 / fs, 0.02 / fs), 0, 0.0));
        // ... unless the candidate's own uncertainty reaches the reading's delay
        assert!(!tp.contradicts(&candidate(None, 0.15 / fs, 0.1 / fs), 0, 0.0));
        // whole samples of the recording's io_delay count as part of the delay
        assert!(tp.contradicts(&candidate(None, 0.4 / fs, 0.02 / fs), 1, 0.0));
    }

    #[test]
    fn a_notch_departs() {
        let fs = 1000.0;
        let mut lv = levels_of(None, 1.0 / fs, 1.0, fs, 1e-3);
        let l = &mut lv[0];
        for (fk, d) in l.f.iter().zip(l.d.iter_mut()) {
            let s = Complex64::new(0.0, fk / 150.0);
            *d *= (s * s + 0.02 * s + 1.0) / (s * s + 0.4 * s + 1.0);
        }
        let tp = TorquePath::from_levels(lv, fs);
        assert_eq!(tp.shape, Shape::Departs, "{}", tp.describe());
    }
}
