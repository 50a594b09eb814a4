//! `hardening_stiffness`: a coupling whose stiffness rises with deflection,
//! `c x (1 + (x/x_ref)²)`, searched on each coupling; `x_ref` is scaled by the coupling's
//! deflection at the highest level.

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::fit_per_coupling;
use crate::diagnose::Data;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    fit_per_coupling(
        data,
        nominal,
        false,
        "hardening_stiffness",
        "x_ref_rad",
        0.3,
        100.0,
        |k, xref| Nl::Hardening { k, xref },
    )
}
