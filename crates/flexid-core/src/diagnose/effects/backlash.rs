//! `backlash`: a dead zone in one coupling (resonances that move with amplitude, odd
//! harmonics), searched on each coupling. Its describing function ([`contact_fraction`])
//! turns the per-level linear fits into a start for the true stiffness and the gap, which
//! the simulation then refines ([`fit_spring`]).

use super::EffectFit;
use crate::diagnose::lti::LinExt;
use crate::diagnose::nlsim::Nl;
use crate::diagnose::search::{fit_spring, Spring};
use crate::diagnose::Data;
use crate::diagnose::Effect;

/// `erfc(x)` (Numerical Recipes' Chebyshev fit, relative error below 1.2e-7).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Equivalent stiffness of a spring with a dead zone of half-width `gap_rad`, as a
/// fraction of its stiffness in contact, under a Gaussian deflection of RMS
/// `defl_rms_rad` (statistical linearisation: the mean slope, the probability of contact
/// `erfc(g/(σ√2))`).
pub fn contact_fraction(gap_rad: f64, defl_rms_rad: f64) -> f64 {
    erfc(gap_rad / (defl_rms_rad * std::f64::consts::SQRT_2))
}

/// Backlash as the per-level fits see it; the gap searched in 0.001-4x the gear's RMS
/// deflection at the high level when the describing function gives no start (a sine
/// sweep's deflection away from the resonance is the RMS divided by about the resonance's
/// peak factor, which reaches hundreds: a gap that small already shows there, while the
/// Gaussian describing function sees none); the polish
/// starts again from 1.2x and 1.4x the simplex's gap along the valley (the simplex stops at
/// 0.6-0.8x the true gap on the cases it misses), paid for by a shorter simplex (30 + 16
/// evaluations instead of hardening's 40 + 24).
pub const SPRING: Spring = Spring {
    equivalent: contact_fraction,
    damping_follows: true,
    high_level_chain: true,
    range: (0.001, 4.0),
    valley_starts: &[1.2, 1.4],
    refine_evals: [30, 16],
    small_signal_scan: false,
};

/// Identify backlash on the data, from the nominal chain.
pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    fit_spring(
        data,
        nominal,
        Effect::Backlash,
        "half_gap_rad",
        &SPRING,
        |k, g| Nl::Backlash { k, g },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::search::describing_solution;

    /// erfc against the naive reference: the midpoint rule on `2/√π e^(-t²)` from x to 6.
    #[test]
    fn erfc_matches_the_integral() {
        for x in [-1.5, -0.3, 0.0, 0.2, 0.7, 1.4, 2.5] {
            let n = 200_000;
            let h = (6.0 - x) / n as f64;
            let s: f64 = (0..n)
                .map(|i| {
                    let t = x + (i as f64 + 0.5) * h;
                    (-t * t).exp()
                })
                .sum::<f64>()
                * h
                * 2.0
                / std::f64::consts::PI.sqrt();
            assert!(
                (erfc(x) - s).abs() < 1e-6 * s.max(1e-3),
                "{x}: {} vs {s}",
                erfc(x)
            );
        }
    }

    /// The describing-function solution inverts the equivalent stiffness: stiffnesses
    /// generated from a known gap give the gap back; a stiffness falling with the level
    /// has no backlash solution.
    #[test]
    fn describing_solution_gives_the_gap_back() {
        let (c, g) = (2.5e4, 3e-5);
        let (s_lo, s_hi) = (2.5e-5, 1.1e-4);
        let got = describing_solution(
            contact_fraction,
            c * contact_fraction(g, s_lo),
            s_lo,
            c * contact_fraction(g, s_hi),
            s_hi,
        )
        .unwrap();
        assert!((got / g - 1.0).abs() < 1e-6, "{got}");
        assert!(describing_solution(contact_fraction, 2e4, s_lo, 1.9e4, s_hi).is_none());
    }
}
