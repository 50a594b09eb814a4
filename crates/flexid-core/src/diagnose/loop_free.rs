//! A start of the current-loop candidate: the chain identified on the measurement with the
//! loop the drive's torque reading shows divided out.
//!
//! The nominal chain has no loop, so it bends to mimic one (a motor coupling damped 200x
//! too little on a world stepped sine, dev A 50601), and the loop's fit started from it
//! stays in that basin: there a delay and the loop left the same reduced chi-square of
//! 1600, where the true chain and loop leave 0.8. The loop acts on the command before the
//! mechanics, so dividing the motion's FRF by the loop's response gives the mechanics
//! alone, which the identification's own starts then fit (as [`super::damper_free`] does
//! for the ground damper).

use super::lti::{LinExt, Loop};
use super::torque_path::Shape;
use super::Data;
use num_complex::Complex64;

/// The continuous response of `lp` at `f_hz`: `1/(1 + s/wc)` or
/// `wc^2/(s^2 + 2 zeta wc s + wc^2)`.
pub fn response(lp: &Loop, f_hz: f64) -> Complex64 {
    let s = Complex64::new(0.0, f_hz / lp.bandwidth_hz);
    let one = Complex64::new(1.0, 0.0);
    if lp.order < 2 {
        one / (one + s)
    } else {
        one / (s * s + 2.0 * lp.zeta * s + one)
    }
}

/// The chain behind the loop the torque reading shows, with that loop and the ground damper
/// the identification saw: identified on the highest level's measurement divided by the
/// loop's response (its variance likewise). `None` where the reading shows no loop or the
/// identification fails.
pub fn start(
    data: &Data,
    n: usize,
    band: Option<[f64; 2]>,
    budget: &crate::identify::fit::FitBudget,
) -> Option<LinExt> {
    let lp = data
        .torque
        .as_ref()
        .filter(|tp| tp.shape == Shape::Loop)?
        .with_loop
        .lp?;
    let a = super::damper_free::identified_on_top(data, n, band, budget, |est| {
        for k in 0..est.frf.freq_hz.len() {
            let g = response(&lp, est.frf.freq_hz[k]);
            est.frf.h[k] /= g;
            est.frf.var[k] /= g.norm_sqr();
        }
    })?;
    let b = a
        .ground_damper
        .as_ref()
        .map_or(0.0, |g| g.damping.b_nms_per_rad);
    Some(LinExt {
        motor_b: b,
        current_loop: Some(lp),
        ..LinExt::nominal(a.fit?.chain)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The loop's response: unit gain at DC, -3 dB and -45 degrees at the corner of a first
    /// order, -90 degrees at the natural frequency of a second order with gain 1/(2 zeta).
    #[test]
    fn the_loop_response_has_its_corner_where_it_should() {
        let first = Loop {
            order: 1,
            bandwidth_hz: 500.0,
            zeta: 0.7,
        };
        assert!((response(&first, 0.0) - Complex64::new(1.0, 0.0)).norm() < 1e-12);
        let c = response(&first, 500.0);
        assert!((c.norm_sqr() - 0.5).abs() < 1e-12);
        assert!((c.arg() + std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        let second = Loop {
            order: 2,
            bandwidth_hz: 800.0,
            zeta: 0.3,
        };
        let r = response(&second, 800.0);
        assert!((r.arg() + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((r.norm() - 1.0 / 0.6).abs() < 1e-12);
    }
}
