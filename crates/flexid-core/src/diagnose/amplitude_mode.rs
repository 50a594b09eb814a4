//! An amplitude-dependent mode: where the FRF changes significantly between excitation
//! levels ([`super::ResidualKind::change_local`]) and no candidate explains the gap, the
//! modes in that band are fitted at every level by a local modal fit ([`super::modal`]) and
//! each mode's natural frequency and damping ratio are compared between the lowest and the
//! highest level against their fitted uncertainties. A frequency that falls with the level
//! is a softening stiffness, one that rises a hardening stiffness, a damping ratio that
//! changes (frequency steady) an amplitude-dependent damping. Physically grounded and
//! general: the structure's own modes, whatever model of the axis the nominal chain is.
//!
//! **The threshold is derived, not tuned.** Each of the `2 m` comparisons (frequency and
//! damping of `m` modes) is `z = (x_high - x_low) / sqrt(σ_high² + σ_low²)`, standard
//! normal when nothing changes (the two levels are independent measurements; each `σ`
//! from the fit's covariance scaled by its own excess over the noise, [`super::modal`]).
//! One of them is called significant when `|z|` passes the two-sided
//! [`SIGNIFICANT_SIGMA`] level shared by the `2 m` tests (Bonferroni): the family's
//! false-alarm rate stays at `2 Φ(-3)` = 0.27 %, checked by a Monte-Carlo in the tests.
//! The uncertainties' scale is estimated from the fits' residuals, so the quantile is
//! Student's t with the smaller fit's `2L - P` degrees of freedom ([`t_crit`]: 3.58
//! instead of 3.51 for the F-16's 6 comparisons on 172, 3.49 instead of 3.21 for a
//! world swept sine's 2 on about 40).
//!
//! **Which mode.** Among the modes inside the band of the change whose frequency or damping
//! passes, the one whose change alone (its `(f, ζ)` moved from the lowest level's to the
//! highest's, the residues kept) changes the fitted FRF most, as an RMS of the log ratio
//! over the band [dB]; a significant frequency shift names a stiffness (softening when it
//! falls), otherwise the damping.
//!
//! Nothing is named when no comparison passes (the verdict stays what it was).

use super::modal::{self, Lines, ModalFit, Mode};
use super::noise::SIGNIFICANT_SIGMA;
use super::Data;

/// What changes with the amplitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModeChange {
    /// The natural frequency falls with the level.
    SofteningStiffness,
    /// The natural frequency rises with the level.
    HardeningStiffness,
    /// The damping ratio changes with the level, the frequency does not significantly.
    AmplitudeDependentDamping,
}

impl ModeChange {
    pub const fn name(self) -> &'static str {
        match self {
            ModeChange::SofteningStiffness => "softening_stiffness",
            ModeChange::HardeningStiffness => "hardening_stiffness",
            ModeChange::AmplitudeDependentDamping => "amplitude_dependent_damping",
        }
    }
}

/// One level's local modal fit.
#[derive(Debug, Clone)]
pub struct LevelFit {
    /// Index of the recording.
    pub level: usize,
    /// RMS of its input [N m, or the recording's unit].
    pub torque_rms: f64,
    /// The fit (`None`: its modes could not be fitted: not identifiable).
    pub fit: Option<ModalFit>,
}

/// One mode followed over the levels, with its comparison between the lowest and the
/// highest level.
#[derive(Debug, Clone)]
pub struct ModeTrack {
    /// The mode at each level, in the order of [`AmplitudeMode::levels`] (`None`: not
    /// identifiable there).
    pub at: Vec<Option<Mode>>,
    /// Whether the mode is identified at each level ([`identified`]): only identified
    /// values are compared.
    pub identified: Vec<bool>,
    /// `(f_high - f_low) / sqrt(σ_high² + σ_low²)` (`None`: not identifiable).
    pub f_shift_sigmas: Option<f64>,
    /// The same for the damping ratio.
    pub zeta_shift_sigmas: Option<f64>,
    /// The FRF change this mode's shift alone makes between the two levels compared:
    /// `sum_k |H'_k - H_k|² / (var_low,k + var_high,k)` over the lowest level's lines,
    /// `H` the lowest level's modal fit and `H'` the same with this mode's frequency and
    /// damping ratio those of the highest level (`None`: not identifiable).
    pub change_z2: Option<f64>,
    /// The same change as an RMS over those lines of `|ln(H'/H)|` [dB] (1 rad of phase
    /// = 8.69 dB): how much this mode's shift alone changes the FRF, whatever the noise.
    /// The named mode is the significant one whose change is the largest: significance
    /// says whether a mode moves, this how much of the FRF's change it is (on the F-16 the
    /// 9.2 Hz mode's shift is the most significant, -17.9 sigma, the torsion mode's the
    /// largest, 5.3 dB against 2.0 dB).
    pub change_db: Option<f64>,
}

/// The named change: which mode and what.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Named {
    /// Index into [`AmplitudeMode::modes`].
    pub mode: usize,
    pub change: ModeChange,
}

/// The analysis of the modes in the band of the change between levels.
#[derive(Debug, Clone)]
pub struct AmplitudeMode {
    /// Where the FRF changes most significantly between levels [Hz].
    pub change_hz: [f64; 2],
    /// The band fitted: the change's widened by a quarter of its width each side (not
    /// below 0) [Hz].
    pub band_hz: [f64; 2],
    /// Every level's fit, by increasing input RMS.
    pub levels: Vec<LevelFit>,
    /// Positions in `levels` of the two levels compared (lowest and highest input RMS
    /// with a fit).
    pub low: usize,
    pub high: usize,
    /// The modes (those of the lowest level's fit, by frequency) over the levels.
    pub modes: Vec<ModeTrack>,
    /// Comparisons made (2 per mode) and the `|z|` one must pass.
    pub tests: usize,
    pub z_crit: f64,
    /// Degrees of freedom of the comparisons' uncertainties: the smaller of the two
    /// compared fits' `2L - P` (their covariance scale is estimated from as many
    /// residuals, so `z` follows Student's t with about as many, [`t_crit`]).
    pub dof: usize,
    /// The change named (`None`: nothing significant, or no mode in the change's band).
    pub named: Option<Named>,
}

/// `Φ⁻¹(1 - p)` for `0 < p < 0.5` (bisection on [`super::effects::backlash::erfc`], to
/// 1e-10 in `z`).
pub fn upper_quantile(p: f64) -> f64 {
    let tail = |z: f64| 0.5 * super::effects::backlash::erfc(z / std::f64::consts::SQRT_2);
    let (mut a, mut b) = (0.0, 40.0);
    for _ in 0..100 {
        let m = 0.5 * (a + b);
        if tail(m) > p {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// The `|z|` each of `tests` two-sided comparisons must pass for the family's false-alarm
/// rate to be that of one two-sided [`SIGNIFICANT_SIGMA`] test.
pub fn z_crit(tests: usize) -> f64 {
    let alpha = super::effects::backlash::erfc(SIGNIFICANT_SIGMA / std::f64::consts::SQRT_2);
    upper_quantile(alpha / (2.0 * tests.max(1) as f64))
}

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, 9 terms; relative error below 1e-13).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// `P(T > t)` for Student's t with `nu` degrees of freedom, `t >= 0` (Simpson's rule on
/// the density over `[0, t]`, 4000 intervals).
fn t_tail(t: f64, nu: f64) -> f64 {
    let c = (ln_gamma(0.5 * (nu + 1.0)) - ln_gamma(0.5 * nu)).exp()
        / (nu * std::f64::consts::PI).sqrt();
    let pdf = |x: f64| c * (1.0 + x * x / nu).powf(-0.5 * (nu + 1.0));
    let n = 4000;
    let h = t / n as f64;
    let mut s = pdf(0.0) + pdf(t);
    for i in 1..n {
        s += if i % 2 == 1 { 4.0 } else { 2.0 } * pdf(i as f64 * h);
    }
    (0.5 - s * h / 3.0).max(0.0)
}

/// The `|z|` each of `tests` two-sided comparisons must pass, as [`z_crit`], when each
/// uncertainty's scale is estimated from `dof` residuals: Student's t quantile (the
/// normal one beyond 10⁶ degrees of freedom).
pub fn t_crit(tests: usize, dof: usize) -> f64 {
    let alpha = super::effects::backlash::erfc(SIGNIFICANT_SIGMA / std::f64::consts::SQRT_2);
    let p = alpha / (2.0 * tests.max(1) as f64);
    if dof > 1_000_000 {
        return upper_quantile(p);
    }
    let nu = dof.max(1) as f64;
    // bisection on a log scale above the normal quantile (t's is larger)
    let (mut a, mut b) = (upper_quantile(p) * 0.999, 1e4_f64);
    for _ in 0..80 {
        let m = (a * b).sqrt();
        if t_tail(m, nu) > p {
            a = m;
        } else {
            b = m;
        }
    }
    (a * b).sqrt()
}

/// Whether a fitted mode is identified: its damping ratio and frequency determined within
/// their admissible ranges at [`SIGNIFICANT_SIGMA`] (`ζ ± 3σ` inside `(0, ZETA_MAX)`,
/// `f ± 3σ` inside the fitted band). A fit pressed against a bound, or a mode whose
/// damping cannot be told from zero or whose frequency can leave the band, is no estimate
/// to compare (on a noisy sweep's FRF a "mode" at the damping bound `ζ = 0.5` was one).
pub fn identified(m: &Mode, band: [f64; 2]) -> bool {
    let k = SIGNIFICANT_SIGMA;
    m.zeta - k * m.zeta_std > 0.0
        && m.zeta + k * m.zeta_std < modal::ZETA_MAX
        && m.f_hz - k * m.f_std_hz > band[0]
        && m.f_hz + k * m.f_std_hz < band[1]
}

fn shift(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<f64> {
    let ((xa, sa), (xb, sb)) = (a?, b?);
    let s = (sa * sa + sb * sb).sqrt();
    (s > 0.0 && s.is_finite()).then(|| (xb - xa) / s)
}

/// The modes of `levels` (each a receptance on its lines, with its input RMS) in
/// `change_hz` widened by a quarter of its width each side, compared between the lowest
/// and the highest level. `None` when fewer than two levels, or no mode can be fitted at the
/// lowest level or the same modes at no other.
pub fn analyse(levels: &[(usize, f64, Lines)], change_hz: [f64; 2]) -> Option<AmplitudeMode> {
    let width = change_hz[1] - change_hz[0];
    if levels.len() < 2 || width.is_nan() || width <= 0.0 {
        return None;
    }
    let band = [
        (change_hz[0] - 0.25 * width).max(0.0),
        change_hz[1] + 0.25 * width,
    ];
    let mut order: Vec<&(usize, f64, Lines)> = levels.iter().collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let lines: Vec<Lines> = order.iter().map(|l| l.2.within(band[0], band[1])).collect();
    let first = modal::fit_order(&lines[0], band[0], band[1])?;
    let starts: Vec<(f64, f64)> = first.modes.iter().map(|m| (m.f_hz, m.zeta)).collect();
    let n = starts.len();
    let mut fits: Vec<Option<ModalFit>> = vec![Some(first)];
    for l in &lines[1..] {
        // from the previous level's modes (the change is gradual), else the lowest's
        let prev: Option<Vec<(f64, f64)>> = fits
            .iter()
            .rev()
            .flatten()
            .next()
            .map(|f| f.modes.iter().map(|m| (m.f_hz, m.zeta)).collect());
        let fit = prev
            .iter()
            .chain([&starts])
            .filter_map(|s| modal::fit(l, s, band[0], band[1]))
            .filter(|f| f.modes.len() == n)
            .min_by(|a, b| a.chi2.total_cmp(&b.chi2));
        fits.push(fit);
    }
    let level_fits: Vec<LevelFit> = order
        .iter()
        .zip(fits)
        .map(|(l, fit)| LevelFit {
            level: l.0,
            torque_rms: l.1,
            fit,
        })
        .collect();
    let low = 0;
    let high = (0..level_fits.len())
        .rev()
        .find(|&i| level_fits[i].fit.is_some())
        .filter(|&i| i > low)?;
    let modes: Vec<ModeTrack> = (0..n)
        .map(|i| {
            let at: Vec<Option<Mode>> = level_fits
                .iter()
                .map(|l| l.fit.as_ref().map(|f| f.modes[i]))
                .collect();
            let ok: Vec<bool> = at
                .iter()
                .map(|m| m.is_some_and(|m| identified(&m, band)))
                .collect();
            let fz = |j: usize| at[j].filter(|_| ok[j]).map(|m| (m.f_hz, m.f_std_hz));
            let zz = |j: usize| at[j].filter(|_| ok[j]).map(|m| (m.zeta, m.zeta_std));
            let (change_z2, change_db) = match (&level_fits[low].fit, at[high]) {
                (Some(fit), Some(m)) if ok[low] && ok[high] => {
                    let mut moved = fit.modes.clone();
                    moved[i] = m;
                    let (z2, db) = change_of(fit, &moved, &lines[low], &lines[high]);
                    (Some(z2), Some(db))
                }
                _ => (None, None),
            };
            ModeTrack {
                f_shift_sigmas: shift(fz(low), fz(high)),
                zeta_shift_sigmas: shift(zz(low), zz(high)),
                identified: ok,
                change_z2,
                change_db,
                at,
            }
        })
        .collect();
    let tests = 2 * n;
    let dof = [low, high]
        .iter()
        .filter_map(|&i| level_fits[i].fit.as_ref())
        .map(|f| (2 * f.lines).saturating_sub(f.params))
        .min()
        .unwrap_or(1);
    let zc = t_crit(tests, dof);
    // among the modes inside the band where the FRF changes whose frequency or damping
    // changes significantly, the one whose change alone changes the FRF most
    let inside =
        |t: &ModeTrack| t.at[low].is_some_and(|m| m.f_hz >= change_hz[0] && m.f_hz <= change_hz[1]);
    let passes = |z: Option<f64>| z.is_some_and(|z| z.abs() > zc);
    let named = (0..n)
        .filter(|&i| inside(&modes[i]))
        .filter(|&i| passes(modes[i].f_shift_sigmas) || passes(modes[i].zeta_shift_sigmas))
        .max_by(|&a, &b| {
            let c = |i: usize| modes[i].change_db.unwrap_or(0.0);
            c(a).total_cmp(&c(b))
        })
        .map(|mode| Named {
            mode,
            change: match modes[mode].f_shift_sigmas {
                Some(z) if z.abs() > zc && z < 0.0 => ModeChange::SofteningStiffness,
                Some(z) if z.abs() > zc => ModeChange::HardeningStiffness,
                _ => ModeChange::AmplitudeDependentDamping,
            },
        });
    Some(AmplitudeMode {
        change_hz,
        band_hz: band,
        levels: level_fits,
        low,
        high,
        modes,
        tests,
        z_crit: zc,
        dof,
        named,
    })
}

/// `sum_k |H'_k - H_k|² / (var_a,k + var_b,k)` over the lines of `a` (those of `b` at the
/// same frequencies; a line `b` lacks counts with `a`'s variance alone), `H` the fit on
/// `a` and `H'` the same with `moved` modes; and the RMS of `|ln(H'/H)|` over them [dB].
fn change_of(fit: &ModalFit, moved: &[Mode], a: &Lines, b: &Lines) -> (f64, f64) {
    let (mut z2, mut ln2) = (0.0, 0.0);
    for (&f, &va) in a.f.iter().zip(&a.var) {
        let vb =
            b.f.iter()
                .position(|&g| (g - f).abs() <= 1e-9 * f.abs().max(1.0))
                .map_or(0.0, |k| b.var[k]);
        let (h1, h0) = (
            fit.response_with(moved, f),
            fit.response_with(&fit.modes, f),
        );
        z2 += (h1 - h0).norm_sqr() / (va + vb);
        let r = (h1 / h0).ln();
        if r.re.is_finite() && r.im.is_finite() {
            ln2 += r.norm_sqr();
        }
    }
    let db = super::localise::DB_PER_NEPER * (ln2 / a.f.len().max(1) as f64).sqrt();
    (z2, db)
}

/// [`analyse`] on the diagnosis's data: each level's FRF as a receptance.
pub fn of_data(data: &Data, change_hz: [f64; 2]) -> Option<AmplitudeMode> {
    let levels: Vec<(usize, f64, Lines)> = data
        .levels
        .iter()
        .enumerate()
        .filter_map(|(i, l)| {
            let lines = Lines {
                f: l.f.clone(),
                h: l.h.clone(),
                var: l.var.clone(),
            };
            modal::receptance(data.kind, data.fs, &lines).map(|r| (i, l.torque_rms, r))
        })
        .collect();
    analyse(&levels, change_hz)
}

impl AmplitudeMode {
    /// The named change in words (for the notes and the report).
    pub fn words(&self) -> String {
        let Some(nm) = self.named else {
            return format!(
                "no mode in {:.2}-{:.2} Hz changes significantly between levels (|z| <= {:.2} for the {} comparisons)",
                self.band_hz[0], self.band_hz[1], self.z_crit, self.tests
            );
        };
        let t = &self.modes[nm.mode];
        let per_level: Vec<String> = self
            .levels
            .iter()
            .zip(t.at.iter().zip(&t.identified))
            .map(|(l, (m, &ok))| match m {
                Some(m) if ok => format!(
                    "level {} ({:.4} RMS): {:.4} +- {:.4} Hz, zeta {:.4} +- {:.4}",
                    l.level, l.torque_rms, m.f_hz, m.f_std_hz, m.zeta, m.zeta_std
                ),
                _ => format!("level {}: not identifiable", l.level),
            })
            .collect();
        let z = |x: Option<f64>| x.map_or("not identifiable".to_string(), |z| format!("{z:+.1}"));
        let at = t.at[self.low].map_or("not identifiable".to_string(), |m| {
            format!("{:.3} Hz", m.f_hz)
        });
        format!(
            "{} of the mode near {at}: frequency shift {} sigma, damping shift {} sigma (significant beyond {:.2} for {} comparisons); {}",
            nm.change.name(),
            z(t.f_shift_sigmas),
            z(t.zeta_shift_sigmas),
            self.z_crit,
            self.tests,
            per_level.join("; ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn the_quantile_inverts_the_normal_tail() {
        // Φ(-3) = 1.3499e-3; Φ(-2) = 2.2750e-2
        assert!((upper_quantile(1.349_898e-3) - 3.0).abs() < 1e-4);
        assert!((upper_quantile(2.275_013e-2) - 2.0).abs() < 1e-4);
        // one test: the two-sided 3-sigma level itself
        assert!((z_crit(1) - 3.0).abs() < 1e-4);
        assert!(z_crit(6) > 3.0 && z_crit(6) < 4.0);
        // Student's t quantiles (tables): t_0.9995(10) = 4.587, t_0.999(10) = 4.144,
        // t_0.975(5) = 2.571, t_0.9995(40) = 3.551; with 10^7 dof the normal's
        let q = |p_one: f64, nu: f64| {
            let (mut a, mut b) = (0.0, 100.0);
            for _ in 0..100 {
                let m = 0.5 * (a + b);
                if t_tail(m, nu) > p_one {
                    a = m;
                } else {
                    b = m;
                }
            }
            0.5 * (a + b)
        };
        assert!((q(5e-4, 10.0) - 4.587).abs() < 2e-3);
        assert!((q(1e-3, 10.0) - 4.144).abs() < 2e-3);
        assert!((q(0.025, 5.0) - 2.571).abs() < 2e-3);
        assert!((q(5e-4, 40.0) - 3.551).abs() < 2e-3);
        assert!((t_crit(1, 10_000_000) - 3.0).abs() < 1e-4);
        // t_crit: with 40 dof and one test, the two-sided 3-sigma level (p = 1.35e-3 a side)
        assert!(t_crit(1, 40) > 3.0 && t_crit(1, 40) < q(1e-3, 40.0) + 0.2);
        assert!(t_crit(6, 170) > z_crit(6) && t_crit(6, 170) < z_crit(6) + 0.15);
    }

    /// A mode at the damping bound, one whose damping cannot be told from zero and one
    /// whose frequency can leave the band are not identified; a well-determined one is.
    #[test]
    fn a_mode_at_a_bound_is_not_identified() {
        let m = |f_hz, f_std_hz, zeta, zeta_std| Mode {
            f_hz,
            f_std_hz,
            zeta,
            zeta_std,
        };
        let band = [55.0, 157.0];
        assert!(identified(&m(100.0, 1.0, 0.05, 0.005), band));
        assert!(!identified(&m(87.0, 9.3, 0.5, 0.087), band));
        assert!(!identified(&m(100.0, 1.0, 0.05, 0.02), band));
        assert!(!identified(&m(168.0, 1.2, 0.04, 0.008), band));
        assert!(!identified(&m(154.0, 1.2, 0.04, 0.008), band));
    }

    fn level(modes: &[(f64, f64, Complex64)], sigma: f64, rng: &mut rand::rngs::StdRng) -> Lines {
        let f: Vec<f64> = (0..110).map(|k| 5.7 + 0.0488 * k as f64).collect();
        let h0 = modal::synthetic(modes, Complex64::new(1e-6, 0.0), &f);
        let n = Normal::new(0.0, sigma / std::f64::consts::SQRT_2).unwrap();
        Lines {
            h: h0
                .iter()
                .map(|h| h + Complex64::new(n.sample(rng), n.sample(rng)))
                .collect(),
            var: vec![sigma * sigma; f.len()],
            f,
        }
    }

    fn modes(f_torsion: f64, zeta_torsion: f64) -> Vec<(f64, f64, Complex64)> {
        vec![
            (6.6, 0.015, Complex64::new(0.0, -2e-3)),
            (f_torsion, zeta_torsion, Complex64::new(1e-4, -4e-3)),
            (9.2, 0.012, Complex64::new(0.0, -1.5e-3)),
        ]
    }

    /// Three levels of the same linear structure: nothing is named, in (nearly) every
    /// noise realisation (the family's false-alarm rate is 0.27 %: at most 2 of 60).
    #[test]
    fn no_change_names_nothing() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut alarms = 0;
        for _ in 0..60 {
            let levels: Vec<(usize, f64, Lines)> = (0..3)
                .map(|i| (i, 1.0 + i as f64, level(&modes(7.3, 0.02), 2e-5, &mut rng)))
                .collect();
            let a = analyse(&levels, [6.6, 9.7]).expect("analysis");
            assert_eq!(a.modes.len(), 3, "{a:?}");
            alarms += usize::from(a.named.is_some());
        }
        assert!(alarms <= 2, "{alarms} false alarms of 60");
    }

    /// A torsion mode that softens by 1 % from the lowest to the highest level is named
    /// `softening_stiffness` at 7.3 Hz; one whose damping doubles, amplitude-dependent
    /// damping; one that stiffens, hardening.
    #[test]
    fn a_shifting_mode_is_named_with_its_direction() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let cases = [
            (
                [7.3, 7.26, 7.227],
                [0.02; 3],
                ModeChange::SofteningStiffness,
            ),
            ([7.3, 7.33, 7.37], [0.02; 3], ModeChange::HardeningStiffness),
            (
                [7.3; 3],
                [0.02, 0.03, 0.04],
                ModeChange::AmplitudeDependentDamping,
            ),
        ];
        for (fs, zs, want) in cases {
            let levels: Vec<(usize, f64, Lines)> = (0..3)
                .map(|i| {
                    (
                        i,
                        1.0 + i as f64,
                        level(&modes(fs[i], zs[i]), 2e-5, &mut rng),
                    )
                })
                .collect();
            let a = analyse(&levels, [6.6, 9.7]).expect("analysis");
            let nm = a.named.unwrap_or_else(|| panic!("nothing named: {a:?}"));
            assert_eq!(nm.change, want, "{}", a.words());
            let m = a.modes[nm.mode].at[0].unwrap();
            assert!((m.f_hz - 7.3).abs() < 0.05, "{}", a.words());
            let top = a.modes[nm.mode].at[2].unwrap();
            assert!(
                (top.f_hz - fs[2]).abs() < 4.0 * top.f_std_hz,
                "{}",
                a.words()
            );
        }
    }

    /// The shift statistic of one mode under no change is standard normal: its variance
    /// over a Monte-Carlo of two noisy levels is 1 within the sampling error.
    #[test]
    fn the_shift_statistic_is_standard_normal_under_no_change() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let mut zs = Vec::new();
        for _ in 0..150 {
            let levels: Vec<(usize, f64, Lines)> = (0..2)
                .map(|i| (i, 1.0 + i as f64, level(&modes(7.3, 0.02), 2e-5, &mut rng)))
                .collect();
            let a = analyse(&levels, [6.6, 9.7]).expect("analysis");
            if let Some(z) = a.modes.get(1).and_then(|t| t.f_shift_sigmas) {
                zs.push(z);
            }
        }
        let n = zs.len() as f64;
        assert!(n >= 140.0);
        let mean = zs.iter().sum::<f64>() / n;
        let var = zs.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / (n - 1.0);
        eprintln!(
            "shift statistic under no change: mean {mean:.3}, variance {var:.3} over {n} runs"
        );
        // the sample variance of 150 normals: 1 +- 0.12 (one sigma)
        assert!((var - 1.0).abs() < 0.36, "variance {var}, mean {mean}");
        assert!(mean.abs() < 0.3, "mean {mean}");
    }
}
