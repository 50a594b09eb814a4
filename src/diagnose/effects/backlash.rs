//! `backlash`: a dead zone in one coupling (resonances that move with amplitude, odd
//! harmonics), searched on each coupling; the gap is scaled by the coupling's deflection
//! at the lowest level.

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::fit_per_coupling;
use crate::diagnose::Data;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    fit_per_coupling(
        data,
        nominal,
        true,
        "backlash",
        "half_gap_rad",
        0.02,
        4.0,
        |k, g| Nl::Backlash { k, g },
    )
}
