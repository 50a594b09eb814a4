//! What a residual is: noise (within the variance), nonlinear distortion (energy at the
//! non-excited detection lines; the FRF changing with the excitation amplitude) or linear
//! model error (significant, the same at every amplitude).

use crate::frf::NonExcitedLevels;
use num_complex::Complex64;
use serde::Serialize;

/// Distortion seen in one recording.
#[derive(Debug, Clone, Serialize)]
pub struct LevelDistortion {
    pub level: usize,
    /// RMS command torque [N m].
    pub torque_rms_nm: f64,
    /// Mean level at the non-excited lines over its noise variance [dB]; about 0 dB
    /// for a linear system, `None` without non-excited lines.
    pub detection_excess_db: Option<f64>,
    /// Fraction of the non-excited lines more than 10 dB above their noise.
    pub detection_lines_hit: Option<f64>,
    /// Where the distortion is [Hz]: the lowest and highest non-excited line more than
    /// 10 dB above its noise (`None` without such a line).
    pub distortion_hz: Option<[f64; 2]>,
    /// Several realisations of a multisine: the median over the lines of the FRF's spread
    /// over the realisations against its noise alone [dB] (the stochastic nonlinear
    /// distortion; about 0 dB for a linear system), [`realisation_excess_db`]. `None` for
    /// one realisation.
    pub realisation_excess_db: Option<f64>,
}

/// The stochastic nonlinear distortion of several realisations: the median over the lines
/// of `spread_var / noise_var` in dB (both variances of the mean FRF; the ratio of two
/// variance estimates, about 1 under noise alone, its median over many lines very close
/// to 1). `None` without lines.
pub fn realisation_excess_db(spread_var: &[f64], noise_var: &[f64]) -> Option<f64> {
    let mut r: Vec<f64> = spread_var
        .iter()
        .zip(noise_var)
        .filter(|(s, n)| s.is_finite() && n.is_finite() && **n > 0.0)
        .map(|(s, n)| s / n)
        .collect();
    if r.is_empty() {
        return None;
    }
    r.sort_by(f64::total_cmp);
    Some(10.0 * r[r.len() / 2].max(f64::MIN_POSITIVE).log10())
}

/// Change of the FRF between two recordings (amplitude levels).
#[derive(Debug, Clone, Serialize)]
pub struct LevelChange {
    pub a: usize,
    pub b: usize,
    /// Mean `|H_a - H_b|² / (var_a + var_b)` over the common lines (1 = noise).
    pub mean_z2: f64,
    /// RMS of `20 log10 |H_a / H_b|` [dB] over the common lines.
    pub rms_db: f64,
    /// Significant at the 1e-6 level (mean z² of n exponential draws); the residual's
    /// judgement adds the localised scan of [`LevelChange::line_z2`]
    /// ([`super::scan`]).
    pub significant: bool,
    /// The common lines [Hz], their `z²` and the `d` of each one's `F(2, d)` under noise
    /// alone (Welch-Satterthwaite from the two variances' own `d`), for the scan.
    #[serde(skip)]
    pub line_hz: Vec<f64>,
    #[serde(skip)]
    pub line_z2: Vec<f64>,
    #[serde(skip)]
    pub line_dof: Vec<f64>,
}

pub fn level_distortion(
    level: usize,
    torque_rms: f64,
    ne: Option<&NonExcitedLevels>,
) -> LevelDistortion {
    let (mut ex, mut hit, mut at) = (None, None, None);
    if let Some(ne) = ne {
        let pairs: Vec<(f64, f64)> = ne
            .mean_power_y
            .iter()
            .zip(&ne.noise_var_y)
            .filter(|(p, v)| p.is_finite() && v.is_finite() && **v > 0.0)
            .map(|(p, v)| (*p, *v))
            .collect();
        if !pairs.is_empty() {
            let p: f64 = pairs.iter().map(|x| x.0).sum();
            let v: f64 = pairs.iter().map(|x| x.1).sum();
            ex = Some(10.0 * (p / v).log10());
            hit = Some(
                pairs.iter().filter(|(p, v)| *p > 10.0 * v).count() as f64 / pairs.len() as f64,
            );
            let hot: Vec<f64> = ne
                .freq_hz
                .iter()
                .zip(ne.mean_power_y.iter().zip(&ne.noise_var_y))
                .filter(|(_, (p, v))| v.is_finite() && **v > 0.0 && **p > 10.0 * **v)
                .map(|(f, _)| *f)
                .collect();
            if let (Some(lo), Some(hi)) = (hot.first(), hot.last()) {
                at = Some([*lo, *hi]);
            }
        }
    }
    LevelDistortion {
        level,
        torque_rms_nm: torque_rms,
        detection_excess_db: ex,
        detection_lines_hit: hit,
        distortion_hz: at,
        realisation_excess_db: None,
    }
}

/// One level's lines for [`level_change`]: frequencies [Hz], FRF, variances and the `d`
/// of the variances (`2(P - 1)`, [`super::noise::dof`]).
pub struct LevelLines<'a> {
    pub f: &'a [f64],
    pub h: &'a [Complex64],
    pub var: &'a [f64],
    pub dof: f64,
}

/// FRF change between two levels on their common lines (matched by frequency).
pub fn level_change(a: usize, b: usize, la: &LevelLines, lb: &LevelLines) -> LevelChange {
    let (fa, ha, va) = (la.f, la.h, la.var);
    let (fb, hb, vb) = (lb.f, lb.h, lb.var);
    let (mut line_hz, mut line_z2, mut line_dof) = (Vec::new(), Vec::new(), Vec::new());
    let (mut sz, mut sdb, mut n) = (0.0, 0.0, 0usize);
    let mut j = 0;
    for i in 0..fa.len() {
        while j < fb.len() && fb[j] < fa[i] * (1.0 - 1e-9) {
            j += 1;
        }
        if j < fb.len() && (fb[j] - fa[i]).abs() <= 1e-9 * fa[i].abs().max(1.0) {
            let v = va[i] + vb[j];
            if v.is_finite() && v > 0.0 {
                let z2 = (ha[i] - hb[j]).norm_sqr() / v;
                sz += z2;
                line_hz.push(fa[i]);
                line_z2.push(z2);
                line_dof.push(v * v / (va[i] * va[i] / la.dof + vb[j] * vb[j] / lb.dof));
                let db = 20.0 * (ha[i].norm() / hb[j].norm()).log10();
                sdb += db * db;
                n += 1;
            }
        }
    }
    let nn = n.max(1) as f64;
    let mean = sz / nn;
    // mean of n Exp(1): sd 1/sqrt(n); 1e-6 one-sided about 5 sd (and a floor for few lines)
    let thr = 1.0 + (5.0 / nn.sqrt()).max(0.5);
    LevelChange {
        a,
        b,
        mean_z2: mean,
        rms_db: (sdb / nn).sqrt(),
        significant: n > 0 && mean > thr,
        line_hz,
        line_z2,
        line_dof,
    }
}
