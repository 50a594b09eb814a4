//! A better nominal model found by a candidate: an effect whose own parameter is not
//! significant, fitted with its extension, can have led the chain out of a basin the
//! nominal fit stayed in (gravity's restoring stiffness opens a path the chain alone does
//! not take). Its chain, the extension removed, is then the nominal model, fitted better.

use super::effects::{self, EffectFit, Lin};
use super::lti::LinExt;
use super::{rank, Data, Effect};

/// The best candidate fit whose defining parameter is not significant
/// ([`rank::defining_parameter_significant`]), with its extension removed (gravity's
/// restoring stiffness, the loop, the delay; the motor's damper kept) and refitted on the
/// nominal chain: when its chi² is lower than the nominal model's by more than one
/// parameter's BIC price (`ln(lines)` in units of the noise per line), the better nominal
/// model, the effect it came from and its chi².
pub fn better_nominal(
    data: &Data,
    nominal: &EffectFit,
    fits: &[EffectFit],
) -> Option<(LinExt, Effect, f64)> {
    let n = nominal.lin.chain.masses();
    let price = (data.lines().max(2) as f64).ln() * data.noise.mean;
    let mut best: Option<(LinExt, Effect, f64)> = None;
    for f in fits {
        let linear = matches!(
            f.effect,
            Effect::Gravity | Effect::TimeDelay | Effect::CurrentLoop
        );
        if !linear
            || f.lin.chain.masses() != n
            || rank::defining_parameter_significant(f)
            || f.chi2 >= nominal.chi2 - price
        {
            continue;
        }
        let mut s = f.lin.clone();
        s.ground_k = 0.0;
        s.current_loop = None;
        s.delay_s = 0.0;
        let kind = if s.motor_b > 0.0 {
            Lin::Viscous
        } else {
            Lin::None
        };
        let refit = effects::fit_linear(data, &data.targets, kind, &s, 40)
            .map(|r| r.0)
            .unwrap_or(s);
        let c = data.chi2_of(&refit);
        if c < nominal.chi2 - price && best.as_ref().is_none_or(|b| c < b.2) {
            best = Some((refit, f.effect, c));
        }
    }
    best
}

/// `lin` without the motor's damper, its chain refitted (the start of the damper's
/// decision, which compares the nominal model with and without it).
pub fn refit_without_damper(data: &Data, lin: &LinExt) -> LinExt {
    let mut s = lin.clone();
    s.motor_b = 0.0;
    effects::fit_linear(data, &data.targets, Lin::None, &s, 40)
        .map(|r| r.0)
        .unwrap_or(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::Param;
    use crate::diagnose::tests_support::exact_data;
    use crate::model::Chain;

    fn truth() -> LinExt {
        let mut l = LinExt::nominal(
            Chain::new(vec![2e-3, 5e-3, 1e-3], vec![300.0, 80.0], vec![0.02, 0.01]).unwrap(),
        );
        l.motor_b = 0.02;
        l
    }

    /// A nominal fit stuck away from the truth, a gravity fit at the truth whose `m g l`
    /// is not significant (as big as its uncertainty) and one whose `m g l` is.
    fn setup() -> (Data, EffectFit, EffectFit, EffectFit) {
        let (data, t) = exact_data(&truth(), 2000.0, &[2.0, 400.0], 120);
        let mut stuck = t.clone();
        stuck.chain.stiffness_nm_per_rad[1] *= 1.3;
        let nominal = effects::finish_linear(&data, Effect::None, stuck, vec![], 0);
        let mut g = t.clone();
        g.ground_k = 1e-6;
        let param = |std: f64| {
            vec![
                Param {
                    name: "m_g_l_nm".into(),
                    value: 1e-6,
                    std,
                },
                Param {
                    name: "damping_nms_per_rad".into(),
                    value: 0.02,
                    std: 1e-4,
                },
            ]
        };
        let insignificant =
            effects::finish_linear(&data, Effect::Gravity, g.clone(), param(1e-6), 2);
        let significant = effects::finish_linear(&data, Effect::Gravity, g, param(1e-8), 2);
        (data, nominal, insignificant, significant)
    }

    #[test]
    fn an_insignificant_candidate_that_fits_better_is_the_nominal_model() {
        let (data, nominal, insignificant, _) = setup();
        assert!(insignificant.chi2 < 1e-3 * nominal.chi2);
        let (better, from, chi2) =
            better_nominal(&data, &nominal, std::slice::from_ref(&insignificant)).unwrap();
        assert_eq!(from, Effect::Gravity);
        assert_eq!(better.ground_k, 0.0);
        assert!(chi2 < 1e-3 * nominal.chi2, "{chi2} vs {}", nominal.chi2);
        let k = better.chain.stiffness_nm_per_rad[1];
        assert!((k / 80.0 - 1.0).abs() < 1e-3, "{k}");
        // the damper is kept; the start of the damper's decision has none
        assert!((better.motor_b / 0.02 - 1.0).abs() < 1e-3);
        let without = refit_without_damper(&data, &better);
        assert_eq!(without.motor_b, 0.0);
    }

    #[test]
    fn a_significant_effect_or_a_worse_fit_leaves_the_nominal_model() {
        let (data, nominal, insignificant, significant) = setup();
        assert!(better_nominal(&data, &nominal, &[significant]).is_none());
        // the candidate no better than the nominal model: nothing to take
        let same = effects::finish_linear(
            &data,
            Effect::Gravity,
            nominal.lin.clone(),
            insignificant.params.clone(),
            2,
        );
        assert!(better_nominal(&data, &nominal, &[same]).is_none());
    }
}
