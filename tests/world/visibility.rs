//! How clearly an effect shows in a measurement, computed from what only the world knows
//! (the plant with and without it, the excitation's power, the encoder, the disturbance),
//! independently of the diagnosis; used to size each effect and to declare where a cause
//! acts.
//!
//! The reference measurement is the case's own multisine where it measures with one
//! (Schroeder, random-phase or odd random-phase; its excited lines); for a stepped sine,
//! the stepped sine itself (its spots, each block's steady periods and tone:
//! [`Reference::stepped`]); for a sweep, the full grid with the sweep's own energy per
//! line ([`Reference::energy`]; its error then measured on repeated recordings,
//! [`repeated_sigma_ln`]), the response simulated under a random-phase multisine on the
//! full grid of the case's band, at the case's two levels, `periods` steady periods of
//! the case's period. Per
//! line, the one-sigma scatter of `ln H` is
//! `s^2 = 4 (v_meas / |H|^2 + s_w^2 |H_w / H|^2) / (N P A^2)`: `v_meas` the white noise of
//! the reading per sample (`q^2 / 12` of an encoder count `q` for a position,
//! `(q f_s)^2 / 6` for the velocity reading), `s_w` the disturbance torque per sample and
//! `H_w` its path to the reading, `A` the line's amplitude, `N P` the samples averaged.
//! The **visibility** of a change `D = ln(H_with / H_without)` is
//! `sqrt(mean over the lines of both levels of |D|^2 / s^2)`: the RMS of the change in
//! units of the line noise (equal to the diagnosis's systematic gap over its noise RMS,
//! inverse-variance weighted, when the nominal model is the true one). Nonlinear plants'
//! `H` comes from noise-free simulations (two transient periods, one analysed; a stepped
//! sine's whole record, each block's last period analysed), the linear ones' from
//! [`super::analytic`].

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
    /// The case's own multisine, when it is one: its period at each level (its lines are
    /// then `lines_hz`). A nonlinear effect's size depends on the signal that drives it (a
    /// cubic spring to the ground jumped under one multisine and not under the case's
    /// Schroeder design, at the same RMS), so it is judged on the measurement the case
    /// makes where the world can.
    pub own_periods: Option<Vec<Vec<f64>>>,
    /// The case's own excitation's energy per line and level where it is no multisine (a
    /// sweep, a stepped sine: [`super::excitation::Design::line_energy`]); `None`: the
    /// reference multisine's, `N P A^2 / 4` on every line. A line without energy is not
    /// measured (infinite scatter) and not counted.
    pub energy: Option<Vec<Vec<f64>>>,
    /// The case's own stepped sine, when it measures with one: its signal and blocks per
    /// level (its spots are then `lines_hz`, one per block). A tone puts the whole RMS at
    /// one frequency, where a multisine spreads it over the grid: a nonlinear effect is
    /// driven much harder at a spot than by the reference multisine at the same RMS (a
    /// cubic spring to the ground without a steady state under the stepped sine was sized
    /// on a multisine it hardly moved), and only the spots are measured. So the world judges
    /// it on the stepped sine itself.
    pub stepped: Option<Vec<Stepped>>,
    /// The design's full grid [Hz]: where the small-signal motion is reckoned (the RMS
    /// spread evenly over it), whatever lines are judged.
    pub grid_hz: Vec<f64>,
}

/// One level of a stepped sine: the command [N m] and its blocks (one spot each).
#[derive(Debug, Clone)]
pub struct Stepped {
    pub u: Vec<f64>,
    pub blocks: Vec<flexid::excitation::SteppedBlock>,
}

impl Stepped {
    /// The DFT ratio `Y / U` at block `b`'s line over its period `p` (0-based from the
    /// block's start, settle periods included), `y` the reading differenced.
    fn ratio(&self, b: &flexid::excitation::SteppedBlock, y: &[f64], p: usize) -> Complex64 {
        let n = b.period_samples;
        let w = -2.0 * std::f64::consts::PI * b.line as f64 / n as f64;
        let (mut uf, mut yf) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
        let from = b.start + p * n;
        for j in 0..n {
            let e = Complex64::from_polar(1.0, w * j as f64);
            uf += self.u[from + j] * e;
            yf += y[from + j] * e;
        }
        yf / uf
    }
}

impl Reference {
    /// One line's amplitude [N m] at level `i` (the RMS spread evenly over the lines).
    /// Where the small-signal motion is reckoned: the judged lines, or the full grid for a
    /// stepped sine (whose spots hold the whole RMS one at a time).
    pub fn motion_lines_hz(&self) -> &[f64] {
        match self.stepped {
            Some(_) => &self.grid_hz,
            None => &self.lines_hz,
        }
    }

    pub fn line_amplitude_nm(&self, i: usize) -> f64 {
        self.levels_rms_nm[i] * (2.0 / self.lines_hz.len() as f64).sqrt()
    }

    /// The excitation's energy [N^2 m^2 x samples] the estimate averages on each line at
    /// level `i` (see [`Reference::energy`]).
    pub fn line_energy(&self, i: usize) -> Vec<f64> {
        if let Some(st) = &self.stepped {
            // each spot's steady periods, its tone's amplitude: N A^2 / 4
            return st[i]
                .blocks
                .iter()
                .map(|b| {
                    let n = (b.periods * b.period_samples) as f64;
                    n * b.amplitude_nm * b.amplitude_nm / 4.0
                })
                .collect();
        }
        match &self.energy {
            Some(e) => e[i].clone(),
            None => {
                let a = self.line_amplitude_nm(i);
                let np = (self.period_samples * self.periods) as f64;
                vec![np * a * a / 4.0; self.lines_hz.len()]
            }
        }
    }

    /// One period of the reference multisine at level `i` [N m].
    pub fn period(&self, i: usize) -> Vec<f64> {
        if let Some(p) = &self.own_periods {
            return p[i].clone();
        }
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
    (0..r.levels_rms_nm.len())
        .map(|i| {
            let energy = r.line_energy(i);
            r.lines_hz
                .iter()
                .zip(energy)
                .map(|(&f, e)| {
                    let h = analytic::position(plant, f);
                    let hw = analytic::disturbance_position(plant, f);
                    let w = 2.0 * std::f64::consts::PI * f;
                    let reading = match plant.sensor.output {
                        Output::Position => q * q / 12.0 / h.norm_sqr(),
                        Output::Velocity => (q * r.fs_hz).powi(2) / 6.0 / (w * w * h.norm_sqr()),
                    };
                    let dist = (plant.torque_noise_nm * hw.norm() / h.norm()).powi(2);
                    if e > 0.0 {
                        ((reading + dist) / e).sqrt()
                    } else {
                        f64::INFINITY
                    }
                })
                .collect()
        })
        .collect()
}

/// The scatter of `ln H` per line of one level as a recording of the case's own periodic
/// multisine shows it: the spread of the per-period responses (`reading` differenced when
/// it is a position) over `periods` steady periods after `transient` ones, as the standard
/// deviation of their mean. `sigma` is the noise model's value for the same lines: the
/// measured-to-model ratio is smoothed (median over 9 neighbouring lines, so that one
/// period's chance does not count) and multiplies the model, which keeps its shape across
/// resonances. A plant whose scatter grows with its excitation (a cubic spring to the
/// ground moved by the disturbance's drift) shows less clearly than the model says.
#[allow(clippy::too_many_arguments)]
pub fn measured_sigma_ln(
    u: &[f64],
    reading: &[f64],
    differenced: bool,
    r: &Reference,
    transient: usize,
    periods: usize,
    sigma: &[f64],
) -> Vec<f64> {
    let n = r.period_samples;
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let spectrum = |x: Vec<f64>| {
        let mut inp = x;
        let mut out = fft.make_output_vec();
        fft.process(&mut inp, &mut out)
            .expect("an FFT of the period");
        out
    };
    let bins: Vec<usize> = r
        .lines_hz
        .iter()
        .map(|&f| (f * n as f64 / r.fs_hz).round() as usize)
        .collect();
    let per_period: Vec<Vec<Complex64>> = (transient..transient + periods)
        .map(|p| {
            let y: Vec<f64> = (p * n..(p + 1) * n)
                .map(|j| {
                    if differenced {
                        reading[j] - reading[j - 1]
                    } else {
                        reading[j]
                    }
                })
                .collect();
            let (uf, yf) = (spectrum(u[p * n..(p + 1) * n].to_vec()), spectrum(y));
            bins.iter().map(|&k| yf[k] / uf[k]).collect()
        })
        .collect();
    let pf = periods as f64;
    let ratio: Vec<f64> = (0..bins.len())
        .map(|l| {
            let mean = per_period.iter().map(|h| h[l]).sum::<Complex64>() / pf;
            let var = per_period
                .iter()
                .map(|h| (h[l] - mean).norm_sqr())
                .sum::<f64>()
                / (pf - 1.0);
            (var / pf).sqrt() / mean.norm() / sigma[l]
        })
        .collect();
    smoothed(&ratio, sigma)
}

/// The spectrum of `x` by the planned real FFT `fft` (of `x`'s length).
pub fn spectrum_by(fft: &dyn realfft::RealToComplex<f64>, x: &[f64]) -> Vec<Complex64> {
    let mut input = x.to_vec();
    let mut out = fft.make_output_vec();
    fft.process(&mut input, &mut out)
        .expect("an FFT of the planned length");
    out
}

/// The model `sigma` times the measured-to-model `ratio` smoothed over 9 neighbouring
/// lines (their median: one realisation's chance does not count; the model keeps its
/// shape across resonances).
fn smoothed(ratio: &[f64], sigma: &[f64]) -> Vec<f64> {
    (0..ratio.len())
        .map(|l| {
            let (a, b) = (l.saturating_sub(4), (l + 5).min(ratio.len()));
            let mut w: Vec<f64> = ratio[a..b].to_vec();
            w.sort_by(f64::total_cmp);
            w[w.len() / 2] * sigma[l]
        })
        .collect()
}

/// `ln H` per line of a non-periodic record: the `H1` estimate over the record's bins
/// within half of `spacing_hz` of each line, `y` the reading (differenced when a position)
/// under the command `u`.
pub fn ln_h1_lines(
    u: &[f64],
    y: &[f64],
    lines_hz: &[f64],
    fs_hz: f64,
    spacing_hz: f64,
) -> Vec<Complex64> {
    let n = u.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let (uf, yf) = (spectrum_by(fft.as_ref(), u), spectrum_by(fft.as_ref(), y));
    let half = 0.5 * spacing_hz;
    lines_hz
        .iter()
        .map(|&fl| {
            let lo = ((fl - half) * n as f64 / fs_hz).ceil().max(1.0) as usize;
            let hi = (((fl + half) * n as f64 / fs_hz).floor() as usize).min(uf.len() - 1);
            let (mut num, mut den) = (Complex64::new(0.0, 0.0), 0.0);
            for j in lo..=hi {
                num += yf[j] * uf[j].conj();
                den += uf[j].norm_sqr();
            }
            (num / den).ln()
        })
        .collect()
}

/// The error of `ln H` per line of a non-periodic record (a sweep) as repeated
/// recordings show it: `runs` holds `ln H` of each (the same command, the noise drawn
/// anew, [`ln_h1_lines`]), `exact` the plant's own response without noise or
/// quantisation; their RMS deviation from it over the model `sigma`, smoothed like
/// [`measured_sigma_ln`]'s ratio, multiplies the model. Against the exact response rather
/// than the runs' mean, so that an error the runs share (a quantisation that follows the
/// same slow motion) counts. Needed where the model's white reading noise is not what
/// the encoder gives: a slow motion quantises into a sawtooth whose error sits at low
/// frequencies (a 17-bit sweep's top sixth scattered 0.02-0.08 of the model's variance).
pub fn repeated_sigma_ln(runs: &[Vec<Complex64>], exact: &[Complex64], sigma: &[f64]) -> Vec<f64> {
    let k = runs.len() as f64;
    let ratio: Vec<f64> = (0..sigma.len())
        .map(|l| {
            let ms = runs
                .iter()
                .map(|h| (h[l] - exact[l]).norm_sqr())
                .sum::<f64>()
                / k;
            ms.sqrt() / sigma[l]
        })
        .collect();
    smoothed(&ratio, sigma)
}

/// The least visibility beyond the nominal model that a diagnosis can be required to
/// see: the expected excess of chi-square over the `L` lines of both levels, `L v^2`,
/// five standard deviations (`sqrt(L)`, each line's `|D|^2 / s^2` of unit mean and
/// variance) above the noise alone: `v = (25 / L)^(1/4)`.
pub fn detectable(sigma: &[Vec<f64>]) -> f64 {
    let lines: usize = sigma.iter().flatten().filter(|s| s.is_finite()).count();
    (25.0 / lines.max(1) as f64).powf(0.25)
}

/// `sqrt(mean |D|^2 / s^2)` over every measured line (finite `s`) of every level.
pub fn visibility(delta: &[Vec<Complex64>], sigma: &[Vec<f64>]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (d, sg) in delta.iter().zip(sigma) {
        for (d, sg) in d.iter().zip(sg).filter(|(_, sg)| sg.is_finite()) {
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
/// the next two analysed; the response of the last), with the sub-steps for `peaks`, and
/// `ln(H_last / H_before)` per line and level: how far the response is from periodic. Only
/// ratios of such responses are used.
pub fn simulated_response(plant: &Plant, r: &Reference, peaks: &Peaks) -> Simulated {
    let steps = substeps(plant, r.fs_hz, peaks);
    if let Some(st) = &r.stepped {
        return stepped_response(plant, r.fs_hz, steps, st);
    }
    let n = r.period_samples;
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let spectrum = |x: &[f64]| spectrum_by(fft.as_ref(), x);
    let mut change = Vec::new();
    let response = (0..r.levels_rms_nm.len())
        .map(|i| {
            let period = r.period(i);
            let u: Vec<f64> = period.repeat(4);
            let mut sim = Sim::new(plant, r.fs_hz, steps, 0, true);
            sim.start_centred(&period);
            let y: Vec<f64> = sim.run(&u).iter().map(|s| s.position_rad).collect();
            // differenced: the drift of a free chain (a velocity offset) stays at DC
            let of_period = |p: usize| {
                let yd: Vec<f64> = (p * n..(p + 1) * n).map(|j| y[j] - y[j - 1]).collect();
                let (uf, yf) = (spectrum(&u[p * n..(p + 1) * n]), spectrum(&yd));
                r.lines_hz
                    .iter()
                    .map(|&f| {
                        let k = (f * n as f64 / r.fs_hz).round() as usize;
                        yf[k] / uf[k]
                    })
                    .collect::<Vec<Complex64>>()
            };
            let (before, last) = (of_period(2), of_period(3));
            change.push(
                last.iter()
                    .zip(&before)
                    .map(|(a, b)| (a / b).ln())
                    .collect(),
            );
            last
        })
        .collect();
    Simulated { response, change }
}

/// [`simulated_response`] on a stepped sine: the whole command of each level simulated
/// without noise (centred on the record, as it is measured), each spot's response over the
/// last steady period of its block, the change from the period before.
fn stepped_response(plant: &Plant, fs_hz: f64, steps: usize, st: &[Stepped]) -> Simulated {
    let (response, before): (Vec<Vec<Complex64>>, Vec<Vec<Complex64>>) = st
        .iter()
        .map(|s| {
            let mut sim = Sim::new(plant, fs_hz, steps, 0, true);
            sim.start_centred(&s.u);
            let pos: Vec<f64> = sim.run(&s.u).iter().map(|x| x.position_rad).collect();
            let y: Vec<f64> = (0..pos.len())
                .map(|j| pos[j] - pos[j.saturating_sub(1)])
                .collect();
            s.blocks
                .iter()
                .map(|b| {
                    let p = b.settle_periods + b.periods - 1;
                    (s.ratio(b, &y, p), s.ratio(b, &y, p - 1))
                })
                .unzip()
        })
        .unzip();
    Simulated {
        change: delta_of(&before, &response),
        response,
    }
}

/// The scatter of `ln H` per spot of one level as a recording of the case's stepped sine
/// shows it: the spread of the per-period responses over each block's steady periods (the
/// reading differenced when a position), as the standard deviation of their mean, over
/// the model's `sigma` and smoothed like [`measured_sigma_ln`]'s. A spot whose response
/// does not settle (no steady state) scatters from period to period.
pub fn measured_sigma_stepped(
    st: &Stepped,
    reading: &[f64],
    differenced: bool,
    sigma: &[f64],
) -> Vec<f64> {
    let y: Vec<f64> = (0..reading.len())
        .map(|j| {
            if differenced {
                reading[j] - reading[j.saturating_sub(1)]
            } else {
                reading[j]
            }
        })
        .collect();
    let ratio: Vec<f64> = st
        .blocks
        .iter()
        .zip(sigma)
        .map(|(b, sg)| {
            let hs: Vec<Complex64> = (b.settle_periods..b.settle_periods + b.periods)
                .map(|p| st.ratio(b, &y, p))
                .collect();
            let pf = hs.len() as f64;
            let mean = hs.iter().sum::<Complex64>() / pf;
            let var = hs.iter().map(|h| (h - mean).norm_sqr()).sum::<f64>() / (pf - 1.0).max(1.0);
            (var / pf).sqrt() / mean.norm() / sg
        })
        .collect();
    smoothed(&ratio, sigma)
}

/// A noise-free simulated response (see [`simulated_response`]).
pub struct Simulated {
    /// Per level and line.
    pub response: Vec<Vec<Complex64>>,
    /// `ln(H_last / H_before)` of the two analysed periods, per level and line.
    pub change: Vec<Vec<Complex64>>,
}

impl Simulated {
    /// Whether the response repeats from period to period within the line noise `sigma`
    /// more closely than `nominal`'s does by one line-noise RMS: a plant whose response
    /// changes from one period to the next by more than the noise (a cubic spring to the
    /// ground driven into chaos) has no steady state for a periodic FRF to measure.
    pub fn periodic_like(&self, nominal: &Simulated, sigma: &[Vec<f64>]) -> bool {
        visibility(&self.change, sigma) <= 1.0 + visibility(&nominal.change, sigma)
    }
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
    if v == f64::MAX {
        // not periodic (see `Simulated::periodic_like`): the largest periodic size found
        return a;
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

/// What a re-fitted nominal model absorbs of a change: the nominal chain's parameters
/// (log inertias, stiffnesses, dampings, and the motor's viscous friction to the ground)
/// are fitted to the with-effect response by damped Gauss-Newton on `ln H`, weighted by the
/// line noise, starting from the true nominal chain, as the diagnosis's nominal refit does;
/// what is left is what no nominal chain explains. An effect "visible beyond the nominal
/// model" shows that much against the noise after the best nominal chain has taken what it
/// can (a hardening spring's mean stiffening, a friction's mean damping, ...). A first-order
/// projection (one linear step) overstated large changes that move a resonance: a refit
/// follows them (a cubic ground spring of "visibility 145" left a reduced chi-square of 0.87).
pub struct Projector {
    nominal: Plant,
    lines_hz: Vec<f64>,
    sigma: Vec<Vec<f64>>,
    /// The nominal chain's response per line.
    h_nominal: Vec<Complex64>,
    /// The additive step of the ground damper's parameter [N m s/rad].
    b_step: f64,
    /// The additive step of the drive's delay [s] (one sample), when the refit may add a
    /// delay ([`Projector::with_delay`]).
    delay_step: Option<f64>,
    /// The additive step of a spring from the load to the ground [N m/rad] (the total
    /// inertia at the lowest line), when the refit may add one
    /// ([`Projector::with_ground_spring`]).
    spring_step: Option<f64>,
}

/// The largest change of one parameter in one refit step (log units).
const MAX_STEP: f64 = 0.25;

/// The continuation's stages (see [`Projector::residual`]).
const STAGES: usize = 8;

/// One parameter of the nominal chain.
#[derive(Debug, Clone, Copy)]
enum Param {
    Inertia(usize),
    Stiffness(usize),
    Damping(usize),
    GroundDamper,
    /// The drive's delay (from the nominal one, never below zero).
    Delay,
    /// A spring from the load to the ground (from none, never below zero).
    GroundSpring,
}

impl Projector {
    pub fn new(nominal: &Plant, r: &Reference, sigma: Vec<Vec<f64>>) -> Projector {
        let jt = nominal.total_inertia_kgm2();
        let h_nominal = r
            .lines_hz
            .iter()
            .map(|&f| analytic::position(nominal, f))
            .collect();
        Projector {
            nominal: nominal.clone(),
            lines_hz: r.lines_hz.clone(),
            sigma,
            h_nominal,
            b_step: jt * 2.0 * std::f64::consts::PI * 0.1,
            delay_step: None,
            spring_step: None,
        }
    }

    /// The refit may also add a spring from the load to the ground (the library's
    /// `gravity` at small angles): a cause outside the library that only shows as a
    /// restoring stiffness (cogging at small swings, a detent) is `gravity` to any
    /// diagnosis, and is outside the library only where it shows beyond that spring (its
    /// stiffness changing with the level, ...).
    pub fn with_ground_spring(mut self) -> Projector {
        let jt = self.nominal.total_inertia_kgm2();
        let w = 2.0 * std::f64::consts::PI * self.lines_hz.first().copied().unwrap_or(1.0);
        self.spring_step = Some(jt * w * w);
        self
    }

    /// The refit may also add a delay to the drive: what is left is what neither a
    /// nominal chain nor a library `time_delay` explains. A cause outside the library is
    /// judged so: a lag anywhere in the measured path (a filter on the position reading far
    /// above the band) that only shows as a lag is a delay to any diagnosis (the drive's
    /// torque reading is the command read back at the sample instants, so it confirms
    /// whole samples only), and the cause is outside the library only where it shows
    /// beyond that delay.
    pub fn with_delay(mut self, fs_hz: f64) -> Projector {
        self.delay_step = Some(1.0 / fs_hz);
        self
    }

    fn params(&self) -> Vec<Param> {
        let n = self.nominal.bodies();
        let mut p: Vec<Param> = (0..n).map(Param::Inertia).collect();
        for k in 0..n - 1 {
            p.push(Param::Stiffness(k));
            p.push(Param::Damping(k));
        }
        p.push(Param::GroundDamper);
        if self.delay_step.is_some() {
            p.push(Param::Delay);
        }
        if self.spring_step.is_some() {
            p.push(Param::GroundSpring);
        }
        p
    }

    /// The nominal chain moved by `x` (log steps, the ground damper additive in units of
    /// `b_step`, kept at or above zero).
    fn plant(&self, params: &[Param], x: &[f64]) -> Plant {
        let mut p = self.nominal.clone();
        for (what, &v) in params.iter().zip(x) {
            match *what {
                Param::Inertia(i) => p.inertia_kgm2[i] *= v.exp(),
                Param::Stiffness(k) => p.couplings[k].stiffness_nm_per_rad *= v.exp(),
                Param::Damping(k) => p.couplings[k].damping_nms_per_rad *= v.exp(),
                Param::GroundDamper => {
                    p.motor_viscous_nms_per_rad =
                        (p.motor_viscous_nms_per_rad + v * self.b_step).max(0.0)
                }
                Param::Delay => {
                    let step = self.delay_step.unwrap_or(0.0);
                    p.drive.delay_s = (p.drive.delay_s + v * step).max(0.0)
                }
                Param::GroundSpring => {
                    let k = (v * self.spring_step.unwrap_or(0.0)).max(0.0);
                    let body = p.bodies() - 1;
                    let g = p.gravity.get_or_insert(super::plant::Gravity {
                        body,
                        m_g_l_nm: 0.0,
                        bearing_damping_nms_per_rad: 0.0,
                    });
                    g.m_g_l_nm += k;
                }
            }
        }
        p
    }

    /// The parameters `x` of `chain` (of the nominal's bodies) relative to the nominal.
    fn x_of(&self, params: &[Param], chain: &Plant) -> Vec<f64> {
        let n = &self.nominal;
        params
            .iter()
            .map(|what| match *what {
                Param::Inertia(i) => (chain.inertia_kgm2[i] / n.inertia_kgm2[i]).ln(),
                Param::Stiffness(k) => (chain.couplings[k].stiffness_nm_per_rad
                    / n.couplings[k].stiffness_nm_per_rad)
                    .ln(),
                Param::Damping(k) => (chain.couplings[k].damping_nms_per_rad
                    / n.couplings[k].damping_nms_per_rad)
                    .ln(),
                Param::GroundDamper => {
                    (chain.motor_viscous_nms_per_rad - n.motor_viscous_nms_per_rad) / self.b_step
                }
                Param::Delay | Param::GroundSpring => 0.0,
            })
            .collect()
    }

    fn response(&self, plant: &Plant) -> Vec<Complex64> {
        self.lines_hz
            .iter()
            .map(|&f| analytic::position(plant, f))
            .collect()
    }

    /// `ln(H_target / H)` per level and line (the principal value, as the diagnosis
    /// measures a gap), and its weighted sum of squares.
    fn misfit(&self, target: &[Vec<Complex64>], h: &[Complex64]) -> (Vec<Vec<Complex64>>, f64) {
        let mut cost = 0.0;
        let r: Vec<Vec<Complex64>> = target
            .iter()
            .zip(&self.sigma)
            .map(|(t, sg)| {
                t.iter()
                    .zip(h)
                    .zip(sg)
                    .map(|((t, h), s)| {
                        let v = (t / h).ln();
                        cost += v.norm_sqr() / (s * s);
                        v
                    })
                    .collect()
            })
            .collect();
        (r, cost)
    }

    /// `delta` (`ln(H_with / H_nominal)` per level and line) less what the re-fitted
    /// nominal chain explains: `ln(H_with / H_refit)`. The refit starts from the nominal
    /// chain; where it leaves more than the line noise, it also follows the change by
    /// continuation (the targets `H_nominal exp(t delta)`, `t` = 1/8 .. 1, each refit
    /// starting from the one before), because a local search from the nominal chain can stop
    /// in another basin when a lightly damped resonance has moved by more than its width;
    /// the better of the two is kept.
    pub fn residual(&self, delta: &[Vec<Complex64>]) -> Vec<Vec<Complex64>> {
        self.residual_from(delta, &[])
    }

    /// [`Projector::residual`] with the refit also started from each of `starts` (nominal
    /// chains of the same bodies: what the cause's own physics suggests a nominal model
    /// would make of it, such as an extra body merged into the one it hangs on); the best
    /// refit is kept.
    pub fn residual_from(&self, delta: &[Vec<Complex64>], starts: &[Plant]) -> Vec<Vec<Complex64>> {
        let params = self.params();
        // the phase unwrapped along the lines, so that a fraction of the change is a
        // fraction of a moving resonance's phase turn
        let delta: Vec<Vec<Complex64>> = delta.iter().map(|d| unwrapped(d)).collect();
        let start = vec![0.0; params.len()];
        let target_of = |t: f64| -> Vec<Vec<Complex64>> {
            delta
                .iter()
                .map(|d| {
                    d.iter()
                        .zip(&self.h_nominal)
                        .map(|(d, h)| (t * d).exp() * h)
                        .collect()
                })
                .collect()
        };
        let target = target_of(1.0);
        let (_, mut direct, mut direct_cost) = self.refit(&params, &target, start.clone(), 100);
        for chain in starts {
            let (_, r, c) = self.refit(&params, &target, self.x_of(&params, chain), 100);
            if c < direct_cost {
                (direct, direct_cost) = (r, c);
            }
        }
        if visibility(&direct, &self.sigma) < detectable(&self.sigma) {
            // below what a diagnosis can see: another path cannot change the answer
            return direct;
        }
        let mut x = start;
        let mut r = Vec::new();
        let mut cost = f64::INFINITY;
        for stage in 1..=STAGES {
            let t = stage as f64 / STAGES as f64;
            let iterations = if stage == STAGES { 100 } else { 15 };
            (x, r, cost) = self.refit(&params, &target_of(t), x, iterations);
        }
        if direct_cost <= cost {
            direct
        } else {
            r
        }
    }

    /// The chain `x` refitted to `target` by damped Gauss-Newton within a trust region
    /// (at most `iterations` steps, until a step gains less than a millionth); the
    /// refitted `x`, its misfit and the misfit's weighted sum of squares.
    #[allow(clippy::needless_range_loop)]
    fn refit(
        &self,
        params: &[Param],
        target: &[Vec<Complex64>],
        mut x: Vec<f64>,
        iterations: usize,
    ) -> (Vec<f64>, Vec<Vec<Complex64>>, f64) {
        let m = params.len();
        let (mut r, mut cost) = self.misfit(target, &self.response(&self.plant(params, &x)));
        let mut lambda = 1e-3;
        for _ in 0..iterations {
            // d ln H / d x_j at x, central differences
            // forward differences from the response at x (the refit needs directions, not
            // digits)
            let eps = 1e-6;
            let here = self.response(&self.plant(params, &x));
            let columns: Vec<Vec<Complex64>> = (0..m)
                .map(|j| {
                    let mut up = x.clone();
                    up[j] += eps;
                    self.response(&self.plant(params, &up))
                        .iter()
                        .zip(&here)
                        .map(|(u, h)| (u / h).ln() / eps)
                        .collect()
                })
                .collect();
            let mut a = vec![vec![0.0; m]; m];
            let mut b = vec![0.0; m];
            for (rl, sg) in r.iter().zip(&self.sigma) {
                for l in 0..rl.len() {
                    let w = 1.0 / (sg[l] * sg[l]);
                    for j in 0..m {
                        let cj = columns[j][l];
                        b[j] += w * (cj.conj() * rl[l]).re;
                        for k in j..m {
                            a[j][k] += w * (cj.conj() * columns[k][l]).re;
                        }
                    }
                }
            }
            for j in 0..m {
                for k in 0..j {
                    a[j][k] = a[k][j];
                }
            }
            // damped steps until one lowers the misfit
            let mut improved = false;
            for _ in 0..12 {
                let mut damped = a.clone();
                for j in 0..m {
                    damped[j][j] += lambda * a[j][j].max(1e-300);
                }
                let mut step = solve_symmetric(damped, b.clone());
                // a trust region: at most a factor e^0.25 per parameter and step, so that
                // the refit follows a moving resonance instead of jumping to another basin
                let largest = step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
                if largest > MAX_STEP {
                    step.iter_mut().for_each(|s| *s *= MAX_STEP / largest);
                }
                let trial: Vec<f64> = x.iter().zip(&step).map(|(x, s)| x + s).collect();
                let (rt, ct) = self.misfit(target, &self.response(&self.plant(params, &trial)));
                if ct.is_finite() && ct < cost {
                    let gain = (cost - ct) / cost.max(1e-300);
                    x = trial;
                    r = rt;
                    cost = ct;
                    lambda = (lambda / 10.0).max(1e-9);
                    improved = gain > 1e-6;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
        (x, r, cost)
    }
}

/// `ln` values along the lines with the phase unwrapped (no jump over pi between lines).
fn unwrapped(d: &[Complex64]) -> Vec<Complex64> {
    let mut last = 0.0;
    d.iter()
        .map(|v| {
            let turns = ((v.im - last) / std::f64::consts::TAU).round();
            let im = v.im - turns * std::f64::consts::TAU;
            last = im;
            Complex64::new(v.re, im)
        })
        .collect()
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
