//! A set of linear effects against an FRF that changes between levels.

use super::{Effect, ResidualKind, Step};

/// Whether `effects` are all linear at every amplitude while the FRF changes between levels
/// beyond the noise on a localised run of lines ([`ResidualKind::change_local`]): no
/// linear model has a change between levels, so the set describes the gap at most in part;
/// with a note. `gravity` is linear only at small swings (`m g l sin q` softens as the
/// swing grows: a world pendulum swinging 0.28 rad at the high level, within 1 % of `m g l`,
/// showed a significant change on precise sines), so a set with it is not held to this;
/// a cogging torque fitted as gravity (its detent's stiffness at small swings) is then
/// still named gravity.
pub fn linear_set_misses(
    effects: &[Step],
    residual: &ResidualKind,
    notes: &mut Vec<String>,
) -> bool {
    let Some(w) = residual.change_local.filter(|w| w.window.significant) else {
        return false;
    };
    let linear_at_any_amplitude = |e: Effect| e.is_linear() && e != Effect::Gravity;
    if effects.is_empty() || !effects.iter().all(|s| linear_at_any_amplitude(s.effect)) {
        return false;
    }
    let names: Vec<&str> = effects.iter().map(|s| s.effect.name()).collect();
    notes.push(format!(
        "{} is linear, but the FRF changes between levels beyond the noise ({:.2}-{:.2} Hz): a linear effect cannot explain that: not named",
        names.join(" + "),
        w.window.lo_hz,
        w.window.hi_hz
    ));
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::EffectFit;
    use crate::diagnose::lti::LinExt;
    use crate::diagnose::{scan, Located};

    fn step(effect: Effect) -> Step {
        let lin = LinExt::nominal(crate::model::Chain::new(vec![1e-3], vec![], vec![]).unwrap());
        Step {
            effect,
            fit: EffectFit {
                effect,
                params: Vec::new(),
                added: 1,
                chi2: 0.0,
                model: Vec::new(),
                lin,
            },
            after_rms_db: 0.0,
            score: 0.0,
        }
    }

    fn residual(significant_change: bool) -> ResidualKind {
        ResidualKind {
            reduced_chi2: 10.0,
            within_noise: false,
            changed: significant_change,
            nonlinear: false,
            linear_model_error: false,
            local: None,
            change_local: Some(Located::from(scan::Window {
                series: 0,
                start: 0,
                lines: 16,
                lo_hz: 1.0,
                hi_hz: 8.5,
                p: 1e-55,
                tests: 14048,
                significant: significant_change,
            })),
            levels: Vec::new(),
            changes: Vec::new(),
        }
    }

    /// A set of linear effects is not named where the FRF changes between levels on a
    /// significant run of lines; a set with an amplitude-dependent effect is, and so is a
    /// linear set where the change is within the noise, and gravity (linear at small swings
    /// only).
    #[test]
    fn a_linear_set_does_not_explain_a_change_between_levels() {
        let mut notes = Vec::new();
        let delay = [step(Effect::TimeDelay)];
        assert!(linear_set_misses(&delay, &residual(true), &mut notes));
        assert!(notes[0].contains("time_delay is linear"), "{notes:?}");
        assert!(!linear_set_misses(&delay, &residual(false), &mut notes));
        let gravity = [step(Effect::Gravity)];
        assert!(!linear_set_misses(&gravity, &residual(true), &mut notes));
        let with_friction = [step(Effect::TimeDelay), step(Effect::CoulombFriction)];
        assert!(!linear_set_misses(
            &with_friction,
            &residual(true),
            &mut notes
        ));
        assert!(!linear_set_misses(&[], &residual(true), &mut notes));
        assert_eq!(notes.len(), 1);
    }
}
