//! `hardening_stiffness`: a stiffness that rises with deflection, in either of two places:
//!
//! * a coupling, `c x (1 + (x/x_ref)²)`, searched on each coupling. Its describing
//!   function ([`stiffening`]) turns the per-level linear fits into a start for the
//!   small-signal stiffness and `x_ref`, which the simulation then refines
//!   ([`fit_spring`]);
//! * a cubic spring from the load to the ground, `-k3 q³` (a Duffing oscillator, as in the
//!   Silverbox), [`fit_ground`]: one parameter searched by simulation over the range where
//!   its equivalent stiffness `3 k3 σ²` (Gaussian load position of RMS `σ` at the highest
//!   level) lies between 1 % and 100 times `J_t ω_min²`, the stiffness that would put a
//!   ground resonance at the lowest excited line: below it the spring is invisible in the
//!   band, above it the nominal free chain would not have fitted the low lines at all.
//!   With a spring to the ground in the nominal model (`--ground-spring`), between a
//!   thousandth of that spring and all of it (the linear spring, fitted with the chain,
//!   gives the rest back).
//!
//! The better of the two (lower chi²) is the candidate; its parameters say which.

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::{simulate, Nl};
use crate::diagnose::search::{fit_nonlinear, fit_spring, Spring};
use crate::diagnose::Data;
use crate::diagnose::Effect;

/// Equivalent stiffness of `c x (1 + (x/x_ref)²)` as a multiple of `c` under a Gaussian
/// deflection of RMS `defl_rms_rad` (statistical linearisation: the mean slope
/// `1 + 3 σ²/x_ref²`).
pub fn stiffening(x_ref_rad: f64, defl_rms_rad: f64) -> f64 {
    1.0 + 3.0 * (defl_rms_rad / x_ref_rad).powi(2)
}

/// Hardening as the per-level fits see it, started from the low level's chain (the least
/// stiffened); `x_ref` searched in 1.2-400x the coupling's RMS deflection there (about
/// 0.3-100x at the high level) when the describing function gives no start; no valley
/// starts, so the simplex keeps the budget backlash gives to them.
pub const SPRING: Spring = Spring {
    equivalent: stiffening,
    damping_follows: false,
    high_level_chain: false,
    range: (1.2, 400.0),
    valley_starts: &[],
    refine_evals: [40, 24],
};

/// Identify a hardening spring on the data, from the nominal chain: in a coupling or to
/// the ground, whichever fits better.
pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let coupling = fit_spring(
        data,
        nominal,
        Effect::HardeningStiffness,
        crate::diagnose::search::HARDENING_PARAM,
        &SPRING,
        |k, xref| Nl::Hardening { k, xref },
    );
    let ground = fit_ground(data, nominal);
    [coupling, ground]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.chi2.total_cmp(&b.chi2))
}

/// Equivalent stiffness of `k3 q³` under a Gaussian position of RMS `sigma_rad`
/// (statistical linearisation: the mean slope `3 k3 σ²`) [N m/rad].
pub fn ground_equivalent(k3: f64, sigma_rad: f64) -> f64 {
    3.0 * k3 * sigma_rad * sigma_rad
}

/// A cubic spring from the load to the ground (see the module's documentation), on top of
/// whatever the nominal model already ties to the ground; `None` when the nominal chain
/// does not move under the recorded torque (no range to search) or no fit is found.
pub fn fit_ground(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let top = (0..data.levels.len()).max_by(|&a, &b| {
        data.levels[a]
            .torque_rms
            .total_cmp(&data.levels[b].torque_rms)
    })?;
    // the load's motion at the highest level as the nominal chain moves it (the motor's
    // position stands for it: the ground spring matters at the lowest lines, where the
    // chain moves as one body)
    let u = &data.levels[top].rec.torque_cmd_nm;
    let pos = simulate(nominal, Nl::GroundCubic { k3: 0.0 }, u, data.fs, 1).pos;
    let mean = pos.iter().sum::<f64>() / pos.len().max(1) as f64;
    let sigma =
        (pos.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / pos.len().max(1) as f64).sqrt();
    if !(sigma > 0.0 && sigma.is_finite()) {
        return None;
    }
    let k3_of = |k_eq: f64| k_eq / ground_equivalent(1.0, sigma);
    let (lo, hi) = if nominal.ground_spring && nominal.ground_k > 0.0 {
        // a nominal spring to the ground was fitted to the measurement, the cubic spring's
        // equivalent stiffness included: it is a part of that stiffness, from a thousandth
        // (a 0.05 % shift of the ground resonance) to all of it
        (k3_of(1e-3 * nominal.ground_k), k3_of(nominal.ground_k))
    } else {
        let k_ref =
            nominal.chain.total_inertia() * (2.0 * std::f64::consts::PI * data.f_min()).powi(2);
        (k3_of(1e-2 * k_ref), k3_of(1e2 * k_ref))
    };
    // with a linear spring to the ground in the nominal model, the cubic one's equivalent
    // stiffness is taken from it at each trial k3 (the level's linearised stiffness kept)
    let grounded = nominal.ground_spring;
    let mut e = fit_nonlinear(
        data,
        nominal,
        Effect::HardeningStiffness,
        "ground_k3_nm_per_rad3",
        lo,
        hi,
        false,
        |k3| Nl::GroundCubic { k3 },
        |k3| {
            if grounded {
                ground_equivalent(k3, sigma)
            } else {
                0.0
            }
        },
    )?;
    e.params.push(EffectFit::param("to_ground", 1.0, 0.0));
    Some(e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::search::describing_solution;

    /// The describing-function solution gives `x_ref` back from generated equivalent
    /// stiffnesses (naive reference: the closed form `q = (r-1)/(s_hi² - r s_lo²)`,
    /// `x_ref = √(3/q)`); a stiffness falling with the level has none.
    #[test]
    fn describing_solution_gives_x_ref_back() {
        let (c, xr) = (171.0, 2e-3);
        let (s_lo, s_hi) = (2e-4, 8e-4);
        let (c_lo, c_hi) = (c * stiffening(xr, s_lo), c * stiffening(xr, s_hi));
        let got = describing_solution(stiffening, c_lo, s_lo, c_hi, s_hi).unwrap();
        let r = c_hi / c_lo;
        let closed = (3.0 * (s_hi * s_hi - r * s_lo * s_lo) / (r - 1.0)).sqrt();
        assert!((got / xr - 1.0).abs() < 1e-6, "{got}");
        assert!((got / closed - 1.0).abs() < 1e-6, "{got} vs {closed}");
        assert!(describing_solution(stiffening, 180.0, s_lo, 170.0, s_hi).is_none());
    }
}
