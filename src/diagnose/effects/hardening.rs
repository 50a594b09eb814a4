//! `hardening_stiffness`: a coupling whose stiffness rises with deflection,
//! `c x (1 + (x/x_ref)²)`, searched on each coupling; `x_ref` is scaled by the coupling's
//! deflection at the highest level.

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::fit_nonlinear;
use crate::diagnose::Data;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let mut best: Option<EffectFit> = None;
    for k in 0..nominal.chain.masses().saturating_sub(1) {
        let x = data.deflection_rms(nominal, k, false);
        if !(x > 0.0) {
            continue;
        }
        let Some(mut e) = fit_nonlinear(
            data,
            nominal,
            "hardening_stiffness",
            "x_ref_rad",
            0.3 * x,
            100.0 * x,
            false,
            |xref| Nl::Hardening { k, xref },
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
