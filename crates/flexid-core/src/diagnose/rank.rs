//! Rank the candidates by how much of the gap each removes, penalised for the parameters it
//! adds (BIC: with the line variances known, chi² is -2 ln L up to a constant, so each added
//! parameter costs ln(lines); chi² differences are divided by what noise alone gives per
//! line, [`super::noise`], because the variances are estimated). A candidate is named only
//! when its improvement is significant, its defining parameter is, and it explains the gap:
//! it removes more than half of the chi² beyond the noise ([`EXPLAINS`]).

use super::effects::{EffectFit, Param};
use super::{Data, ResidualKind};
use crate::diagnose::Effect;
use serde::Serialize;

/// What "explains" means: the fraction of the nominal model's chi² beyond the noise
/// (`chi² - mean · lines`, [`super::noise::NoiseChi2::mean`]) that an effect (or the set of
/// effects) removes must exceed one half. The definition of explaining the gap (most of it),
/// not a value tuned to a benchmark: a candidate that removes less leaves more gap than it
/// explains, and the answer is then `unexplained`, with the candidates still ranked.
pub const EXPLAINS: f64 = 0.5;

/// One candidate in the ranking.
#[derive(Debug, Clone, Serialize)]
pub struct Ranked {
    pub effect: Effect,
    /// RMS log-complex gap with this effect [dB].
    pub after_rms_db: f64,
    /// chi² reduction over the nominal model minus `added * ln(lines)` (BIC); > 0: better.
    pub score: f64,
    pub chi2: f64,
    pub added_params: usize,
    pub params: Vec<Param>,
}

impl Ranked {
    /// Whether the candidate's fit reached at least the nominal model's chi² (`nominal_chi2`,
    /// the `none` entry's). Every candidate holds the nominal model (its effect at size
    /// zero), so a fit that ends above it did not converge: its parameters are where the
    /// search stopped, not an estimate, and are not to be read.
    pub fn converged(&self, nominal_chi2: f64) -> bool {
        self.chi2.is_finite() && self.chi2 <= nominal_chi2 * (1.0 + 1e-9)
    }
}

/// The nominal model's chi² in a ranking (its `none` entry), if it is there.
pub fn nominal_chi2(ranking: &[Ranked]) -> Option<f64> {
    ranking
        .iter()
        .find(|r| r.effect == Effect::None)
        .map(|r| r.chi2)
}

fn rms_db(data: &Data, e: &EffectFit) -> f64 {
    super::rms_parts(data, &e.model).0
}

/// The ranking (best first, `none` included) and the index in `fits` of the best
/// candidate that is significant (the first step of the forward selection; whether it
/// explains the gap is decided on the selected set, [`explained_fraction`]).
pub fn rank(
    data: &Data,
    nominal: &EffectFit,
    fits: &[EffectFit],
    residual: &ResidualKind,
) -> (Vec<Ranked>, Option<usize>) {
    let mut r: Vec<(Ranked, Option<usize>)> = fits
        .iter()
        .enumerate()
        .map(|(i, e)| {
            (
                Ranked {
                    effect: e.effect,
                    after_rms_db: rms_db(data, e),
                    score: score(data, nominal.chi2, e),
                    chi2: e.chi2,
                    added_params: e.added,
                    params: e.params.clone(),
                },
                Some(i),
            )
        })
        .collect();
    r.push((
        Ranked {
            effect: Effect::None,
            after_rms_db: rms_db(data, nominal),
            score: 0.0,
            chi2: nominal.chi2,
            added_params: 0,
            params: vec![],
        },
        None,
    ));
    r.sort_by(|a, b| b.0.score.total_cmp(&a.0.score));
    // the best candidate whose improvement is significant and whose own defining parameter
    // is significantly different from zero: significance before a name
    let win = r.iter().find_map(|(rk, i)| {
        let i = (*i)?;
        (residual.gap_is_real() && rk.score > 0.0 && defining_parameter_significant(&fits[i]))
            .then_some(i)
    });
    (r.into_iter().map(|x| x.0).collect(), win)
}

/// The score of `fit` against a model of chi² `chi2_before`: the chi² reduction in units of
/// the noise's mean per line, minus the BIC price `ln(lines)` of each parameter it adds
/// (> 0: the improvement is significant).
pub fn score(data: &Data, chi2_before: f64, fit: &EffectFit) -> f64 {
    let pen = (data.lines() as f64).ln();
    (chi2_before - fit.chi2) / data.noise.mean - pen * fit.added as f64
}

/// The fraction of the chi² beyond the noise (`chi2_before - mean · lines`) that a model of
/// chi² `chi2_after` removes (1: down to the noise; may exceed 1 by chance).
pub fn explained_fraction(data: &Data, chi2_before: f64, chi2_after: f64) -> f64 {
    let excess = chi2_before - data.noise.mean * data.lines() as f64;
    if excess > 0.0 {
        (chi2_before - chi2_after) / excess
    } else {
        0.0
    }
}

/// Whether an effect's defining parameter (its first: the friction torque, the gap, the
/// delay, the loop's bandwidth, the extra inertia, `m g l`, ...) is at least
/// [`super::effects::viscous::SIGNIFICANT_SIGMA`] standard deviations from zero. A
/// parameter without an uncertainty (a nonlinear fit that reports none) is not held
/// against the effect: its significance then rests on the gap reduction alone.
pub fn defining_parameter_significant(e: &EffectFit) -> bool {
    match e.params.first() {
        Some(p) if p.std.is_finite() && p.std > 0.0 => {
            p.value.abs() >= super::effects::viscous::SIGNIFICANT_SIGMA * p.std
        }
        _ => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ranked(effect: Effect, chi2: f64) -> Ranked {
        Ranked {
            effect,
            after_rms_db: 0.0,
            score: 0.0,
            chi2,
            added_params: 1,
            params: Vec::new(),
        }
    }

    /// A candidate that ended above the nominal model's chi² (or at a non-finite one) did
    /// not converge; at or below it, it did.
    #[test]
    fn a_fit_above_the_nominal_did_not_converge() {
        let ranking = vec![
            ranked(Effect::Backlash, 90.0),
            ranked(Effect::None, 100.0),
            ranked(Effect::CoulombFriction, 4.2e8),
            ranked(Effect::TimeDelay, f64::NAN),
        ];
        let n = nominal_chi2(&ranking).unwrap();
        assert_eq!(n, 100.0);
        let ok: Vec<bool> = ranking.iter().map(|r| r.converged(n)).collect();
        assert_eq!(ok, [true, true, false, false]);
        assert!(nominal_chi2(&ranking[..1]).is_none());
    }
}
