//! Several effects at once: forward selection. The first effect is the best significant
//! candidate of the ranking; each next one is fitted on top of the ones before and kept
//! while it is significant given them (its chi² reduction over the step before beats the
//! BIC price of the parameters it adds, and its defining parameter is at least 3 sigma from
//! zero) and explains the gap that remains (more than half of the chi² beyond the noise
//! left after the step before, [`super::rank::EXPLAINS`]: with clean data any imperfection
//! of the first effect's model is "significant", and a further candidate that takes a
//! little of it is not a further effect). The set is named only when it explains the gap.
//!
//! "On top of" is exact for the linear extensions (the next fit starts from the chain and
//! extensions of the step before and keeps them): an amplitude-dependent effect found
//! before is divided out of the measurement ([`divided_out`]): the next fit sees
//! `H_meas · H_lin / H_sim` of the step before, whose chi² equals the chi² of the combined
//! model `H_next · H_sim / H_lin` on the measurement (the log-complex residual and the
//! weights are unchanged by the division).

use super::effects::{model_on, EffectFit};
use super::lti::LinExt;
use super::{Data, Effect, Step};
use num_complex::Complex64;

/// Most effects named at once (the first and two more).
pub const MAX_EFFECTS: usize = 3;

/// How many of the best linear candidates of step 2 are backfitted with an
/// amplitude-dependent first effect (each costs one more fit of that effect).
pub const BACKFITTED: usize = 2;

/// The measurement with the part of `fit` that its linear model does not carry divided out
/// (`r = H_fit / H_lin(fit.lin)` per line: the simulated amplitude-dependent effect), and
/// `r`; `None` when `fit` is linear (nothing to divide).
pub fn divided_out(data: &Data, fit: &EffectFit) -> Option<(Data, Vec<Vec<Complex64>>)> {
    let lin = model_on(&fit.lin, data.fs, data.kind, &data.full_targets);
    let r: Vec<Vec<Complex64>> = fit
        .model
        .iter()
        .zip(&lin)
        .map(|(m, l)| m.iter().zip(l).map(|(m, l)| m / l).collect())
        .collect();
    let linear = r
        .iter()
        .flatten()
        .all(|x| (x - Complex64::new(1.0, 0.0)).norm() < 1e-9);
    if linear {
        return None;
    }
    let mut d = data.clone();
    for (i, l) in d.levels.iter_mut().enumerate() {
        for (k, h) in l.h.iter_mut().enumerate() {
            let ri = r[i][k];
            *h /= ri;
            l.var[k] /= ri.norm_sqr();
        }
    }
    // the weights |h|/sigma are unchanged; the targets' h follow the levels
    for targets in [&mut d.targets, &mut d.full_targets] {
        for (i, t) in targets.iter_mut().enumerate() {
            for (j, &k) in t.idx.iter().enumerate() {
                t.h[j] = d.levels[i].h[k];
            }
        }
    }
    Some((d, r))
}

/// A fit made on a divided-out measurement as a model of the original one: its FRF times
/// the divided part (its chi² is already the original's).
fn multiplied(mut fit: EffectFit, r: &[Vec<Complex64>]) -> EffectFit {
    for (m, r) in fit.model.iter_mut().zip(r) {
        for (m, r) in m.iter_mut().zip(r) {
            *m *= r;
        }
    }
    fit
}

/// Forward selection from `first` (the ranking's best significant candidate). `next`
/// fits the candidates on a measurement (original or divided out) on top of the linear
/// model given, leaving out the effects given; it returns the fits (their `added` counts
/// only their own parameters). Returns the steps, first included, and a note per step
/// tried.
///
/// Backfitting: where the first effect is amplitude-dependent and a linear one is tried
/// next, the first effect's fit was made without the linear one and has taken up part of
/// its signature (a hardening fitted without the current loop); `backfit(lin, effect)`
/// refits `effect` on the original measurement on top of `lin` (the chain with the linear
/// effect), whose chi² is the pair's. The [`BACKFITTED`] best linear candidates are
/// backfitted and keep the better of the two fits.
pub fn forward(
    data: &Data,
    nominal_chi2: f64,
    first: EffectFit,
    mut next: impl FnMut(&Data, &LinExt, &[Effect]) -> Vec<EffectFit>,
    mut backfit: impl FnMut(&LinExt, Effect) -> Option<EffectFit>,
) -> (Vec<Step>, Vec<String>) {
    let rms = |f: &EffectFit| super::rms_parts(data, &f.model).0;
    let mut notes = Vec::new();
    let mut steps = vec![Step {
        effect: first.effect,
        after_rms_db: rms(&first),
        score: super::rank::score(data, nominal_chi2, &first),
        fit: first,
    }];
    while steps.len() < MAX_EFFECTS {
        let last = &steps.last().unwrap().fit;
        if data.within_noise(last.chi2) {
            break;
        }
        let named: Vec<Effect> = steps.iter().map(|s| s.effect).collect();
        let fits = match divided_out(data, last) {
            Some((d, r)) => next(&d, &last.lin, &named)
                .into_iter()
                .map(|f| multiplied(f, &r))
                .collect::<Vec<_>>(),
            None => next(data, &last.lin, &named),
        };
        let score_of = |f: &EffectFit| super::rank::score(data, last.chi2, f);
        let mut scored: Vec<(f64, EffectFit)> = fits
            .into_iter()
            .filter(|f| !named.contains(&f.effect) && f.chi2.is_finite())
            .map(|f| (score_of(&f), f))
            .collect();
        if let [only] = named[..] {
            if !only.is_linear() {
                let step = steps.len() + 1;
                backfit_linear(&mut scored, only, step, &score_of, &mut backfit, &mut notes);
            }
        }
        let tried: Vec<String> = scored
            .iter()
            .map(|(s, f)| format!("{} chi2 {:.4e} (score {s:.1})", f.effect, f.chi2))
            .collect();
        notes.push(format!(
            "forward selection, step {}: candidates on top of {}: {}",
            steps.len() + 1,
            named
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(" + "),
            if tried.is_empty() {
                "none fitted".to_string()
            } else {
                tried.join(", ")
            }
        ));
        // the best of the significant ones (a better-scoring candidate whose own parameter
        // is not significant does not hide one that is); else the best, to report
        let significant_fit = |score: f64, fit: &EffectFit| {
            score > 0.0 && super::rank::defining_parameter_significant(fit)
        };
        let any_significant = scored.iter().any(|(s, f)| significant_fit(*s, f));
        let best = scored
            .into_iter()
            .filter(|(s, f)| !any_significant || significant_fit(*s, f))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((score, fit)) = best else { break };
        let significant = significant_fit(score, &fit);
        let explains = super::rank::explained_fraction(data, last.chi2, fit.chi2);
        let added = significant && explains > super::rank::EXPLAINS;
        notes.push(format!(
            "forward selection, step {}: best next effect {} (score {score:.1}, chi2 {:.4e} -> {:.4e}, {:.0} % of the remaining gap): {}",
            steps.len() + 1,
            fit.effect,
            last.chi2,
            fit.chi2,
            100.0 * explains,
            match (significant, added) {
                (_, true) => "significant, explains the remaining gap: added",
                (true, false) => "significant but explains too little of the remaining gap: the selection stops",
                _ => "not significant: the selection stops",
            }
        ));
        if !added {
            break;
        }
        steps.push(Step {
            effect: fit.effect,
            after_rms_db: rms(&fit),
            score,
            fit,
        });
    }
    (steps, notes)
}

/// Backfitting at step `step` (see [`forward`]): the first effect `first` (amplitude-dependent)
/// refitted on top of each of the [`BACKFITTED`] best-scoring linear candidates of
/// `scored`; a candidate whose pair fits better takes the refit's model, chain and score.
fn backfit_linear(
    scored: &mut [(f64, EffectFit)],
    first: Effect,
    step: usize,
    score_of: &impl Fn(&EffectFit) -> f64,
    backfit: &mut impl FnMut(&LinExt, Effect) -> Option<EffectFit>,
    notes: &mut Vec<String>,
) {
    let mut linear: Vec<usize> = (0..scored.len())
        .filter(|&i| scored[i].1.effect.is_linear() && scored[i].0 > 0.0)
        .collect();
    linear.sort_by(|&a, &b| scored[b].0.total_cmp(&scored[a].0));
    for &i in linear.iter().take(BACKFITTED) {
        let (score, f) = &mut scored[i];
        let Some(b) = backfit(&f.lin, first).filter(|b| b.chi2 < f.chi2) else {
            continue;
        };
        let params: Vec<String> = b
            .params
            .iter()
            .map(|p| format!("{} = {:.4e}", p.name, p.value))
            .collect();
        notes.push(format!(
            "forward selection, step {step}: {first} refitted with {} (backfitting): chi2 {:.4e} -> {:.4e}; {}",
            f.effect,
            f.chi2,
            b.chi2,
            params.join(", ")
        ));
        f.chi2 = b.chi2;
        f.model = b.model;
        f.lin = b.lin;
        *score = score_of(f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::lti::LinExt;
    use crate::model::Chain;

    /// A 2-mass measurement generated from a linear model with a delay (the lines exact,
    /// one percent variance), and a candidate "effect" that multiplies the model by a fixed
    /// factor (standing in for a simulated amplitude-dependent one).
    fn setup() -> (Data, LinExt) {
        let chain = Chain::new(vec![1e-3, 2e-3], vec![400.0], vec![0.02]).unwrap();
        let mut lin = LinExt::nominal(chain);
        lin.delay_s = 2e-4;
        crate::diagnose::tests_support::exact_data(&lin, 2000.0, &[2.0, 300.0], 120)
    }

    #[test]
    fn dividing_out_and_multiplying_back_keeps_the_chi2() {
        let (data, lin) = setup();
        let base = model_on(&lin, data.fs, data.kind, &data.full_targets);
        // a made-up amplitude-dependent part: 10 % gain and 5 degrees below 20 Hz
        let factor = |f: f64| {
            if f < 20.0 {
                Complex64::from_polar(1.1, 5f64.to_radians())
            } else {
                Complex64::new(1.0, 0.0)
            }
        };
        let model: Vec<Vec<Complex64>> = data
            .levels
            .iter()
            .zip(&base)
            .map(|(l, b)| l.f.iter().zip(b).map(|(f, b)| b * factor(*f)).collect())
            .collect();
        let fit = EffectFit {
            effect: Effect::CoulombFriction,
            params: vec![],
            added: 2,
            chi2: data.chi2(&model),
            model,
            lin: lin.clone(),
        };
        let (d, r) = divided_out(&data, &fit).expect("not linear");
        // any model's chi² on the divided data equals the model times r on the original
        let mut other = lin.clone();
        other.delay_s = 3e-4;
        let m = model_on(&other, d.fs, d.kind, &d.full_targets);
        let on_divided = d.chi2(&m);
        let back = multiplied(
            EffectFit {
                model: m,
                ..fit.clone()
            },
            &r,
        );
        let on_original = data.chi2(&back.model);
        assert!(
            (on_divided - on_original).abs() <= 1e-9 * on_original.max(1.0),
            "{on_divided} vs {on_original}"
        );
        // a linear fit has nothing to divide out
        let lin_fit = EffectFit { model: base, ..fit };
        assert!(divided_out(&data, &lin_fit).is_none());
    }

    #[test]
    fn a_second_effect_is_added_only_when_it_is_significant() {
        let (data, lin) = setup();
        // the first step: the chain without the delay (the delay is the second effect)
        let mut no_delay = lin.clone();
        no_delay.delay_s = 0.0;
        let first = crate::diagnose::effects::finish_linear(
            &data,
            Effect::CurrentLoop,
            no_delay.clone(),
            vec![],
            1,
        );
        assert!(!data.within_noise(first.chi2));
        let found_delay = crate::diagnose::effects::finish_linear(
            &data,
            Effect::TimeDelay,
            lin.clone(),
            vec![EffectFit::param("delay_s", 2e-4, 1e-6)],
            1,
        );
        let (steps, notes) = forward(
            &data,
            2.0 * first.chi2,
            first.clone(),
            |_, _, _| vec![found_delay.clone()],
            |_, _| None,
        );
        assert_eq!(
            steps.iter().map(|s| s.effect).collect::<Vec<_>>(),
            [Effect::CurrentLoop, Effect::TimeDelay],
            "{notes:?}"
        );
        // the same delay with an uncertainty as large as itself is not added
        let vague = EffectFit {
            params: vec![EffectFit::param("delay_s", 2e-4, 2e-4)],
            ..found_delay
        };
        let (steps, notes) = forward(
            &data,
            2.0 * first.chi2,
            first,
            |_, _, _| vec![vague.clone()],
            |_, _| None,
        );
        assert_eq!(steps.len(), 1, "{notes:?}");
        assert!(
            notes.iter().any(|n| n.contains("not significant")),
            "{notes:?}"
        );
    }

    /// Backfitting: an amplitude-dependent first effect, fitted without the linear second
    /// one, is refitted on top of it and the pair keeps the better fit; without a better
    /// refit the second step's own fit stays.
    #[test]
    fn an_amplitude_dependent_first_effect_is_refitted_with_the_linear_second() {
        let (data, lin) = setup();
        // the first effect's fit made without the delay, its chain bent to mimic it
        let mut bent = lin.clone();
        bent.delay_s = 0.0;
        bent.chain.stiffness_nm_per_rad[0] *= 1.03;
        let finish = |e: Effect, m: &LinExt, p: Vec<super::super::effects::Param>| {
            crate::diagnose::effects::finish_linear(&data, e, m.clone(), p, 1)
        };
        let first = finish(
            Effect::CoulombFriction,
            &bent,
            vec![EffectFit::param("coulomb_nm", 0.1, 0.01)],
        );
        let mut on_bent = bent.clone();
        on_bent.delay_s = lin.delay_s;
        let delay = finish(
            Effect::TimeDelay,
            &on_bent,
            vec![EffectFit::param("delay_s", 2e-4, 1e-6)],
        );
        assert!(delay.chi2 < first.chi2 && !data.within_noise(delay.chi2));
        let refit = finish(
            Effect::CoulombFriction,
            &lin,
            vec![EffectFit::param("coulomb_nm", 0.12, 0.01)],
        );
        let mut asked = Vec::new();
        let (steps, notes) = forward(
            &data,
            2.0 * first.chi2,
            first.clone(),
            |_, _, _| vec![delay.clone()],
            |base, e| {
                asked.push((e, base.delay_s));
                Some(refit.clone())
            },
        );
        assert_eq!(asked, [(Effect::CoulombFriction, lin.delay_s)], "{notes:?}");
        assert_eq!(steps.len(), 2, "{notes:?}");
        assert_eq!(steps[1].effect, Effect::TimeDelay);
        assert_eq!(steps[1].fit.chi2, refit.chi2);
        assert!(notes.iter().any(|n| n.contains("backfitting")), "{notes:?}");
        // no better refit: the delay on the bent chain explains too little of the gap,
        // and the pair is not named
        let (steps, notes) = forward(
            &data,
            2.0 * first.chi2,
            first,
            |_, _, _| vec![delay.clone()],
            |_, _| None,
        );
        assert_eq!(steps.len(), 1, "{notes:?}");
        assert!(notes.iter().any(|n| n.contains("too little")), "{notes:?}");
    }
}
