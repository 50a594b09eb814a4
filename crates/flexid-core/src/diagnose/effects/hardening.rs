//! `hardening_stiffness`: a coupling whose stiffness rises with deflection,
//! `c x (1 + (x/x_ref)²)`, searched on each coupling. Its describing function
//! ([`stiffening`]) turns the per-level linear fits into a start for the small-signal
//! stiffness and `x_ref`, which the simulation then refines ([`fit_spring`]).

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::{fit_spring, Spring};
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

/// Identify a hardening spring on the data, from the nominal chain.
pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    fit_spring(
        data,
        nominal,
        Effect::HardeningStiffness,
        "x_ref_rad",
        &SPRING,
        |k, xref| Nl::Hardening { k, xref },
    )
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
