//! `backlash`: a dead zone in one coupling (resonances that move with amplitude, odd
//! harmonics), searched on each coupling; the gap is scaled by the coupling's deflection
//! at the lowest level.

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::fit_nonlinear;
use crate::diagnose::Data;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let mut best: Option<EffectFit> = None;
    for k in 0..nominal.chain.masses().saturating_sub(1) {
        let x = data.deflection_rms(nominal, k, true);
        if !(x > 0.0) {
            continue;
        }
        let Some(mut e) = fit_nonlinear(
            data,
            nominal,
            "backlash",
            "half_gap_rad",
            0.02 * x,
            4.0 * x,
            false,
            |g| Nl::Backlash { k, g },
        ) else {
            continue;
        };
        e.params.push(EffectFit::param("coupling", k as f64, 0.0));
        if best.as_ref().is_none_or(|b| e.chi2 < b.chi2) {
            best = Some(e);
        }
    }
    best
}
