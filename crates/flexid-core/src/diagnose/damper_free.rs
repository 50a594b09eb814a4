//! Starts of the nominal chain with viscous friction to the ground, identified on the
//! measurement with that damper taken out.
//!
//! The chain fitted without the damper can bend into a basin (a soft extra pair mimicking
//! the ground damping) that a joint fit of chain and damper, started from it, does not
//! leave. The identification takes the damper out of the measurement first
//! ([`crate::identify::ground_damper`]), so the chain it returns is a start in the right
//! basin, with the damper it saw.

use super::lti::LinExt;
use super::Data;
use crate::analysis::{analyze_estimate, Analysis, EstimatedFrf};

/// Start of the nominal `n`-body chain with viscous friction to the ground: the chain
/// identified on the highest level's measurement with its ground damper taken out, and
/// that damper. `None` when the lowest lines show no damper significantly above zero or
/// the identification fails.
pub fn start(
    data: &Data,
    n: usize,
    band: Option<[f64; 2]>,
    budget: &crate::identify::fit::FitBudget,
) -> Option<LinExt> {
    let a = identified_on_top(data, n, band, budget, |_| {})?;
    let b = a.ground_damper.as_ref()?.damping.b_nms_per_rad;
    Some(LinExt {
        motor_b: b,
        ..LinExt::nominal(a.fit?.chain)
    })
}

/// The identification of the nominal `n`-body chain ([`super::nominal_analysis`]) on the
/// highest level's measurement in `band`, after `change` (what a start takes out of it).
pub(crate) fn identified_on_top(
    data: &Data,
    n: usize,
    band: Option<[f64; 2]>,
    budget: &crate::identify::fit::FitBudget,
    change: impl FnOnce(&mut EstimatedFrf),
) -> Option<Analysis> {
    let level = &data.levels[super::top_level(data)];
    let mut est: EstimatedFrf = level.measured(band).ok()?;
    change(&mut est);
    let opts = super::nominal_analysis(n, band, budget);
    analyze_estimate(&level.rec, est, &opts).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::lti::Discrete;
    use crate::frf::{Frf, FrfKind};
    use crate::identify::ground_damper::{ground_damping, without_ground_damper};
    use crate::model::Chain;

    /// A 3-body chain with a strong damper to the ground, its sampled differenced-velocity
    /// response on a log grid: the damper is recovered from the lowest lines, and taking it
    /// out gives the free chain's response (both checked against the exact sampled models).
    #[test]
    fn the_ground_damper_is_found_and_taken_out() {
        let chain = Chain::new(
            vec![0.005, 0.012, 0.023],
            vec![2300.0, 64.0],
            vec![0.12, 0.046],
        )
        .unwrap();
        let b = 0.57;
        let fs = 4000.0;
        let f: Vec<f64> = (0..40)
            .map(|k| 1.0 * 1.2f64.powi(k))
            .filter(|&f| f < 1500.0)
            .collect();
        let with = LinExt {
            motor_b: b,
            ..LinExt::nominal(chain.clone())
        };
        let kind = FrfKind::DifferencedVelocity;
        let h_with = Discrete::new(&with, fs, 0).frf_lines(&f, kind);
        let h_free = Discrete::new(&LinExt::nominal(chain), fs, 0).frf_lines(&f, kind);
        let measured = Frf {
            freq_hz: f.clone(),
            h: h_with.clone(),
            var: h_with.iter().map(|h| 1e-6 * h.norm_sqr()).collect(),
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: fs,
        };
        let d = ground_damping(&measured, 0).unwrap();
        assert!(
            (d.b_nms_per_rad - b).abs() < 0.02 * b,
            "b {} vs {b}",
            d.b_nms_per_rad
        );
        assert!(d.b_nms_per_rad > 100.0 * d.std_nms_per_rad);
        let out = without_ground_damper(&measured, b, 0);
        for (i, (a, e)) in out.h.iter().zip(&h_free).enumerate() {
            let rel = (a - e).norm() / e.norm();
            // exact for the continuous response; the zero-order-hold chain departs from
            // it by a small multiple of (w T)^2 near its resonance and Nyquist: ample for a
            // start, and the correction matters only where b Y is not small (the low lines)
            let tol = if f[i] < 50.0 { 2e-4 } else { 1e-2 };
            assert!(rel < tol, "line {} Hz: {rel:e}", f[i]);
        }
    }

    /// A free chain has no ground damping: the estimate is zero within its scatter.
    #[test]
    fn a_free_chain_shows_no_ground_damper() {
        let chain = Chain::new(vec![0.005, 0.012], vec![2300.0], vec![0.12]).unwrap();
        let fs = 2000.0;
        let f: Vec<f64> = (2..400).map(|k| 0.5 * k as f64).collect();
        let h = Discrete::new(&LinExt::nominal(chain), fs, 0)
            .frf_lines(&f, FrfKind::DifferencedVelocity);
        let measured = Frf {
            freq_hz: f,
            var: h.iter().map(|h| 1e-4 * h.norm_sqr()).collect(),
            h,
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: fs,
        };
        let d = ground_damping(&measured, 0).unwrap();
        assert!(
            d.b_nms_per_rad.abs() < crate::identify::SIGNIFICANT_SIGMA * d.std_nms_per_rad,
            "{d:?}"
        );
    }
}
