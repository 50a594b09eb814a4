//! A set of linear effects against an FRF that changes between levels.

use super::distortion::{self, LevelChange};
use super::effects::EffectFit;
use super::{noise, scan, Data, Effect, Level, Located, ResidualKind, Step};
use crate::Complex64;

/// How the measured FRF changes between the levels of `data`.
pub struct Changes {
    /// Every pair of levels, line by line.
    pub changes: Vec<LevelChange>,
    /// The most significant run of lines of the change ([`scan`]).
    pub change_local: Option<Located>,
    /// Significant over the whole band of a pair or on that run.
    pub changed: bool,
}

/// The change of the FRF between every two levels of `data`, over the band and on its
/// most significant run of lines (a ground spring changes the lowest lines only).
pub fn between_levels(data: &Data) -> Changes {
    fn lines_of(l: &Level) -> distortion::LevelLines<'_> {
        distortion::LevelLines {
            f: &l.f,
            h: &l.h,
            var: &l.var,
            dof: noise::dof(l.averages),
        }
    }
    let mut changes = Vec::new();
    for a in 0..data.levels.len() {
        for b in a + 1..data.levels.len() {
            changes.push(distortion::level_change(
                a,
                b,
                &lines_of(&data.levels[a]),
                &lines_of(&data.levels[b]),
            ));
        }
    }
    let change_local = scan::scan(
        &changes
            .iter()
            .map(|c| scan::Series {
                f: &c.line_hz,
                z2: &c.line_z2,
                dof: &c.line_dof,
            })
            .collect::<Vec<_>>(),
    )
    .map(|w| Located {
        pair: Some((changes[w.series].a, changes[w.series].b)),
        ..Located::from(w)
    });
    let changed =
        changes.iter().any(|c| c.significant) || change_local.is_some_and(|w| w.window.significant);
    Changes {
        changes,
        change_local,
        changed,
    }
}

/// Whether `effects` are all linear at every amplitude while the FRF changes between levels
/// beyond the noise on a localised run of lines ([`ResidualKind::change_local`]), and the
/// set acts on that run: no linear model has a change between levels, so the set describes
/// the gap there at most in part; with a note. `gravity` is linear only at small swings
/// (`m g l sin q` softens as the swing grows: a world pendulum swinging 0.28 rad at the high
/// level, within 1 % of `m g l`, showed a significant change on precise sines), so a set
/// with it is not held to this; a cogging torque fitted as gravity (its detent's stiffness
/// at small swings) is then still named gravity.
///
/// A set whose model does not differ from the nominal model on the run of lines where the
/// FRF changes ([`acts_on`]) is not refuted by that change: the change is a second thing,
/// left unexplained beside the set (a sweep whose low level leaves a mode far above the
/// set's band a few encoder counts deep changes there between levels, while an extra mode
/// at 6 Hz takes the gap from 0.28 to 0.02 dB). Nor is a set that fits every level within
/// the noise on that run ([`misfits_on`]): the change is then smaller than what the set's
/// fit can tell from the noise at either level.
pub fn linear_set_misses(
    data: &Data,
    nominal: &EffectFit,
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
    let band = [w.window.lo_hz, w.window.hi_hz];
    let set = &effects[effects.len() - 1].fit;
    if !acts_on(data, &nominal.model, &set.model, band) {
        notes.push(format!(
            "the FRF changes between levels beyond the noise ({:.2}-{:.2} Hz), where {} does not act (its model is the nominal model's there within the noise): that change is left unexplained beside it",
            band[0],
            band[1],
            names.join(" + ")
        ));
        return false;
    }
    if !misfits_on(data, &set.model, band) {
        notes.push(format!(
            "the FRF changes between levels beyond the noise ({:.2}-{:.2} Hz), but {} fits every level there within the noise: the change does not refute it",
            band[0],
            band[1],
            names.join(" + ")
        ));
        return false;
    }
    notes.push(format!(
        "{} is linear, but the FRF changes between levels beyond the noise ({:.2}-{:.2} Hz): a linear effect cannot explain that: not named",
        names.join(" + "),
        band[0],
        band[1]
    ));
    true
}

/// Whether `model` differs from `nominal` beyond the line noise on the lines of `band_hz`
/// at some level ([`beyond_noise_on`]).
pub fn acts_on(
    data: &Data,
    nominal: &[Vec<Complex64>],
    model: &[Vec<Complex64>],
    band_hz: [f64; 2],
) -> bool {
    beyond_noise_on(data, band_hz, |i, k| model[i][k] - nominal[i][k])
}

/// Whether the measurement departs from `model` beyond the line noise on the lines of
/// `band_hz` at some level ([`beyond_noise_on`]).
pub fn misfits_on(data: &Data, model: &[Vec<Complex64>], band_hz: [f64; 2]) -> bool {
    beyond_noise_on(data, band_hz, |i, k| data.levels[i].h[k] - model[i][k])
}

/// Whether `difference(level, line)` is beyond the line noise on the lines of `band_hz` at
/// some level: each line's `z² = |difference|² / var` scored as under noise alone
/// ([`scan::exp_score`]), summed over the band (Fisher's method, [`scan::ln_gamma_tail`]),
/// at the same one-sided level as every other test ([`scan::alpha`]), Bonferroni over the
/// levels. A band without lines is not.
fn beyond_noise_on(
    data: &Data,
    band_hz: [f64; 2],
    difference: impl Fn(usize, usize) -> Complex64,
) -> bool {
    let levels = data.levels.len().max(1) as f64;
    data.levels.iter().enumerate().any(|(i, l)| {
        let d = noise::dof(l.averages);
        let (mut s, mut w) = (0.0, 0usize);
        for (k, f) in l.f.iter().enumerate() {
            if *f < band_hz[0] || *f > band_hz[1] || !l.var[k].is_finite() {
                continue;
            }
            let z2 = difference(i, k).norm_sqr() / l.var[k].max(1e-300);
            s += scan::exp_score(z2, d);
            w += 1;
        }
        w > 0 && scan::ln_gamma_tail(w, s) + levels.ln() < scan::alpha().ln()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::lti::LinExt;
    use crate::diagnose::tests_support::exact_data;
    use crate::diagnose::{scan, Located};

    /// One level of 40 lines in 1-100 Hz, exactly a 1 g m² rigid body, 1 % noise per line.
    fn data() -> (Data, EffectFit) {
        let lin = LinExt::nominal(crate::model::Chain::new(vec![1e-3], vec![], vec![]).unwrap());
        let (data, lin) = exact_data(&lin, 1000.0, &[1.0, 100.0], 40);
        let nominal = EffectFit {
            effect: Effect::None,
            params: Vec::new(),
            added: 0,
            chi2: 0.0,
            model: vec![data.levels[0].h.clone()],
            lin,
        };
        (data, nominal)
    }

    /// An effect whose model is the nominal one times 1.1 (ten line sigmas) below 10 Hz.
    fn step(effect: Effect, data: &Data, nominal: &EffectFit) -> Step {
        let l = &data.levels[0];
        let model: Vec<Complex64> =
            l.f.iter()
                .zip(&nominal.model[0])
                .map(|(f, m)| if *f < 10.0 { m * 1.1 } else { *m })
                .collect();
        Step {
            effect,
            fit: EffectFit {
                effect,
                added: 1,
                model: vec![model],
                ..nominal.clone()
            },
            after_rms_db: 0.0,
            score: 0.0,
        }
    }

    fn residual(significant_change: bool, band_hz: [f64; 2]) -> ResidualKind {
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
                lo_hz: band_hz[0],
                hi_hz: band_hz[1],
                p: 1e-55,
                tests: 14048,
                significant: significant_change,
            })),
            levels: Vec::new(),
            changes: Vec::new(),
        }
    }

    /// A set of linear effects is not named where the FRF changes between levels on a
    /// significant run of lines where the set acts; a set with an amplitude-dependent
    /// effect is, and so is a linear set where the change is within the noise, and gravity
    /// (linear at small swings only).
    #[test]
    fn a_linear_set_does_not_explain_a_change_between_levels() {
        let (data, nominal) = data();
        let low = [1.0, 8.5];
        let mut notes = Vec::new();
        let delay = [step(Effect::TimeDelay, &data, &nominal)];
        let misses = |set: &[Step], r: &ResidualKind, notes: &mut Vec<String>| {
            linear_set_misses(&data, &nominal, set, r, notes)
        };
        assert!(misses(&delay, &residual(true, low), &mut notes));
        assert!(notes[0].contains("time_delay is linear"), "{notes:?}");
        assert!(!misses(&delay, &residual(false, low), &mut notes));
        let gravity = [step(Effect::Gravity, &data, &nominal)];
        assert!(!misses(&gravity, &residual(true, low), &mut notes));
        let with_friction = [
            step(Effect::TimeDelay, &data, &nominal),
            step(Effect::CoulombFriction, &data, &nominal),
        ];
        assert!(!misses(&with_friction, &residual(true, low), &mut notes));
        assert!(!misses(&[], &residual(true, low), &mut notes));
        assert_eq!(notes.len(), 1);
    }

    /// Two equal levels do not change; a level 10 % (ten line sigmas) higher on a run of
    /// lines does, on a run that starts among them.
    #[test]
    fn levels_change_where_one_is_higher_than_the_other() {
        let (mut data, _) = data();
        let mut second = data.levels[0].clone();
        data.levels.push(second.clone());
        assert!(!between_levels(&data).changed);
        for (h, f) in second.h.iter_mut().zip(&second.f) {
            if *f < 10.0 {
                *h *= 1.1;
            }
        }
        data.levels[1] = second;
        let c = between_levels(&data);
        assert!(c.changed);
        let w = c.change_local.expect("a run of lines").window;
        assert!(w.significant && w.lo_hz < 10.0, "{w:?}");
    }

    /// A change between levels far from where the set acts does not refute the set: it is
    /// left unexplained beside it, with a note.
    #[test]
    fn a_change_where_the_set_does_not_act_leaves_the_set_named() {
        let (data, nominal) = data();
        let delay = [step(Effect::TimeDelay, &data, &nominal)];
        let mut notes = Vec::new();
        assert!(!linear_set_misses(
            &data,
            &nominal,
            &delay,
            &residual(true, [40.0, 90.0]),
            &mut notes
        ));
        assert!(notes[0].contains("does not act"), "{notes:?}");
        // and the band test itself: acts below 10 Hz, not above
        let set = &delay[0].fit.model;
        assert!(acts_on(&data, &nominal.model, set, [2.0, 5.0]));
        assert!(!acts_on(&data, &nominal.model, set, [20.0, 100.0]));
        assert!(!acts_on(&data, &nominal.model, set, [200.0, 300.0]));
    }

    /// A set that acts where the FRF changes but fits every level there within the noise
    /// (the measurement is the set's model) is not refuted by the change.
    #[test]
    fn a_change_the_set_fits_within_the_noise_does_not_refute_it() {
        let (mut data, nominal) = data();
        let delay = [step(Effect::TimeDelay, &data, &nominal)];
        let mut notes = Vec::new();
        let low = residual(true, [1.0, 8.5]);
        assert!(misfits_on(&data, &delay[0].fit.model, [1.0, 8.5]));
        data.levels[0].h = delay[0].fit.model[0].clone();
        assert!(!misfits_on(&data, &delay[0].fit.model, [1.0, 8.5]));
        assert!(!linear_set_misses(
            &data, &nominal, &delay, &low, &mut notes
        ));
        assert!(notes[0].contains("fits every level"), "{notes:?}");
    }
}
