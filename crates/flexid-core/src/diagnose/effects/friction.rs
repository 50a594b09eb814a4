//! `coulomb_friction`: Coulomb (with stiction) and viscous friction on the motor; its
//! signature is a low-frequency magnitude that depends on the amplitude.

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::fit_nonlinear;
use crate::diagnose::Data;
use crate::diagnose::Effect;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let u = data.torque_rms_min();
    fit_nonlinear(
        data,
        nominal,
        Effect::CoulombFriction,
        "coulomb_nm",
        0.01 * u,
        2.0 * u,
        true,
        |tc| Nl::Friction { tc },
        |_| 0.0,
    )
}
