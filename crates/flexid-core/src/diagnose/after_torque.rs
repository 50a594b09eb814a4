//! A lag the drive's torque reading places after the torque: out of the library.
//!
//! The library's lags act in the torque path: a drive delay (`time_delay`) and a current
//! loop (`current_loop`). A candidate whose lag the torque reading contradicts is dropped
//! ([`super::torque_path::drop_contradicted`]): the reading is the command read back, so a
//! current loop it does not show is not in the torque path. Its fit is kept here as
//! evidence. A low-pass in the position measurement (an encoder or velocity filter, left
//! in the drive) has the FRF of a current loop, while the reading shows none; the drive
//! delay, whose part of a sample the reading cannot show, then takes the lag's phase and
//! is named although the magnitude's roll-off is left over.
//!
//! So, after the selection: when a dropped fit explains the gap better than the named set
//! by more than the BIC price of the parameters it has beyond the set's (the ranking's
//! significance) and takes more than half of what the set leaves beyond the noise
//! ([`super::rank::EXPLAINS`], the forward selection's rule for a further effect), the
//! better description of the gap is a lag after the torque: the verdict is `unexplained`,
//! with that evidence, instead of the set. Without the second condition, clean data make
//! any small imperfection of a true delay's fit "significant": a low-pass took 2 % of
//! what a world's true 0.74-sample delay left, far beyond its BIC price.

use super::effects::EffectFit;
use super::rank;
use super::{Data, Step};

/// The note on a dropped fit that explains the gap better than the named set (see the
/// module's documentation); `None` when none does.
pub fn better_than_named(data: &Data, named: &[Step], dropped: &[EffectFit]) -> Option<String> {
    let last = named.last()?;
    let per_line = data.noise.mean;
    let pen = (data.lines() as f64).ln();
    let set_params: usize = named.iter().map(|s| s.fit.added).sum();
    let left = last.fit.chi2 - per_line * data.lines() as f64;
    dropped
        .iter()
        .filter(|d| {
            let extra = d.added.saturating_sub(set_params) as f64;
            let score = (last.fit.chi2 - d.chi2) / per_line - pen * extra;
            score > 0.0
                && left > 0.0
                && (last.fit.chi2 - d.chi2) > rank::EXPLAINS * left
                && rank::defining_parameter_significant(d)
        })
        .min_by(|a, b| a.chi2.total_cmp(&b.chi2))
        .map(|d| {
            let names: Vec<&str> = named.iter().map(|s| s.effect.name()).collect();
            let claim = match d.lin.current_loop {
                Some(lp) => format!(
                    "a low-pass (order {}, {:.1} Hz)",
                    lp.order, lp.bandwidth_hz
                ),
                None => format!("a delay of {:.2} samples", d.lin.delay_s * data.fs),
            };
            let note = format!(
                "{claim} explains the gap better than {} (chi2 {:.4e} -> {:.4e}, {:.0} % of what it leaves beyond the noise), but the drive's torque reading does not show it: it acts after the torque, in the position measurement (an encoder or velocity filter) or the mechanics, outside the library: unexplained",
                names.join(" + "),
                last.fit.chi2,
                d.chi2,
                100.0 * (last.fit.chi2 - d.chi2) / left
            );
            note
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::{current_loop, delay};
    use crate::diagnose::lti::{LinExt, Loop};
    use crate::diagnose::tests_support::exact_data;
    use crate::diagnose::Effect;
    use crate::model::Chain;

    /// A 2-body axis (antiresonance 209 Hz, resonance 284 Hz) with viscous friction to the
    /// ground, at 4 kHz.
    fn axis() -> LinExt {
        LinExt {
            motor_b: 1.718e-3,
            ..LinExt::nominal(
                Chain::new(vec![4.705e-4, 4.023e-4], vec![692.8], vec![6.55e-3]).unwrap(),
            )
        }
    }

    /// The delay named first, as the ranking would, and the current loop's fit kept aside
    /// as if the reading had dropped it; what the rule makes of them.
    fn judged(truth: &LinExt) -> Option<String> {
        let (data, _) = exact_data(truth, 4000.0, &[0.5, 1600.0], 60);
        let nominal = axis();
        let delay = delay::fit(&data, &nominal).expect("a delay fit");
        let lowpass = current_loop::fit(&data, &nominal).expect("a loop fit");
        let named = [Step {
            effect: Effect::TimeDelay,
            after_rms_db: 0.0,
            score: 0.0,
            fit: delay,
        }];
        better_than_named(&data, &named, std::slice::from_ref(&lowpass))
    }

    /// A second-order low-pass at 900 Hz (the position reading's filter; on the FRF it is
    /// the same as a current loop) is a delay's phase and more: the low-pass explains what
    /// the delay leaves, so the delay is not named. A true delay of 0.6 samples leaves
    /// nothing beyond the noise for the low-pass to take.
    #[test]
    fn a_low_pass_the_reading_does_not_show_outdoes_the_delay_a_true_delay_stays() {
        let mut filtered = axis();
        filtered.current_loop = Some(Loop {
            order: 2,
            bandwidth_hz: 900.0,
            zeta: std::f64::consts::FRAC_1_SQRT_2,
        });
        let note = judged(&filtered).expect("the low-pass outdoes the delay");
        assert!(note.contains("a low-pass (order 2"), "{note}");
        assert!(note.contains("outside the library"), "{note}");
        let mut delayed = axis();
        delayed.delay_s = 0.6 / 4000.0;
        assert_eq!(judged(&delayed), None);
    }
}
