//! `unmodelled_mode`: one more anti-resonance/resonance pair than the nominal model has: a
//! chain of one more body appended to the nominal one, its frequency started at the
//! localised bands (and at the pipeline's own (n+1)-mass identification when it has one),
//! refined jointly on all levels.
//!
//! The starts are ranked after a short fit of the appended body alone (the nominal chain
//! held), not by their cost as given: the cost of an untuned start says little about the
//! basin it lies in. On seed 1614 of the withheld-effect benchmark the two starts of lowest
//! cost both led the joint fit to a pair at 2.5/3.0 Hz (chi² 1.25e7) while the true one is
//! at 5.8/7.3 Hz (chi² 487, reached from 7 of the 36 starts); after
//! [`PREFIT_ITERS`] iterations of the body alone the starts near the true pair lead.

use super::{build_on, finish_linear, fit_linear, residuals, theta, EffectFit, Lin, Param};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;
use crate::diagnose::Effect;
use crate::identify::fit::FitBudget;
use crate::lsq::{minimise, LmResult};
use crate::model::Chain;

/// LM iterations of the appended body alone (inertia, spring, damper) per start.
pub const PREFIT_ITERS: usize = 3;
/// Prefitted starts refined jointly with the chain (the best of them is kept).
pub const JOINT_STARTS: usize = 2;
/// LM iterations of the joint refinement.
pub const JOINT_ITERS: usize = 60;

pub use super::START_FREQ_RATIO;

/// Starts: the nominal chain with a body of `r` times the last inertia appended, tuned to
/// each frequency in `freqs_hz` (those within [`START_FREQ_RATIO`] of an earlier one
/// skipped), plus `extra` chains.
pub fn starts(nominal: &Chain, freqs_hz: &[f64], extra: &[Chain]) -> Vec<Chain> {
    let jl = *nominal.inertia_kgm2.last().unwrap();
    let mut out: Vec<Chain> = extra.to_vec();
    let mut taken: Vec<f64> = Vec::new();
    for &f in freqs_hz {
        if taken
            .iter()
            .any(|&g| (f / g).ln().abs() < START_FREQ_RATIO.ln())
        {
            continue;
        }
        taken.push(f);
        for r in [0.1, 0.3, 1.0] {
            let je = r * jl;
            let c = je * (2.0 * std::f64::consts::PI * f).powi(2);
            let mut ch = nominal.clone();
            ch.inertia_kgm2.push(je);
            ch.stiffness_nm_per_rad.push(c);
            ch.damping_nms_per_rad.push(2.0 * 0.03 * (c * je).sqrt());
            out.push(ch);
        }
    }
    out
}

/// The extra-body fit from `starts` (chains of one more body than the nominal one), each
/// with the linear extensions of `base` (the effects named before it, if any).
/// Under `budget`: once it has passed, the starts not yet prefitted or refined are skipped
/// (the first of each always runs, so a search under way still ends with a fit).
pub fn fit(data: &Data, base: &LinExt, starts: &[Chain], budget: &FitBudget) -> Option<EffectFit> {
    fit_as(data, base, starts, Lin::Mode, budget)
}

/// [`fit`] with the joint refinement over `joint` ([`Lin::Mode`], or [`Lin::ModeViscous`]
/// to free the motor-ground damper too).
pub fn fit_as(
    data: &Data,
    base: &LinExt,
    starts: &[Chain],
    joint: Lin,
    budget: &FitBudget,
) -> Option<EffectFit> {
    let s: Vec<LinExt> = starts
        .iter()
        .map(|c| LinExt {
            chain: c.clone(),
            ..base.clone()
        })
        .collect();
    let base_in_band = in_band(&base.chain, [data.f_min(), data.f_max()]);
    let (m, _r) = fit_prefitted(data, base_in_band, &s, joint, budget)?;
    let ch = &m.chain;
    let n = ch.masses();
    let mut p = vec![
        Param {
            name: "extra_inertia_kgm2".into(),
            value: ch.inertia_kgm2[n - 1],
            std: f64::NAN,
        },
        Param {
            name: "extra_stiffness_nm_per_rad".into(),
            value: ch.stiffness_nm_per_rad[n - 2],
            std: f64::NAN,
        },
    ];
    for (i, (fa, fr)) in ch
        .antiresonances_hz()
        .into_iter()
        .zip(ch.resonances_hz())
        .enumerate()
    {
        p.push(Param {
            name: format!("pair{}_ar_hz", i + 1),
            value: fa,
            std: f64::NAN,
        });
        p.push(Param {
            name: format!("pair{}_r_hz", i + 1),
            value: fr,
            std: f64::NAN,
        });
    }
    Some(finish_linear(data, Effect::UnmodelledMode, m, p, 3))
}

/// Each start's appended body prefitted ([`prefit_body`]); the [`JOINT_STARTS`] best of
/// them refined jointly with the chain, those with more resonances in the band than the
/// base chain's `base_in_band` (or whose appended body is the ground) first; the best
/// joint fit.
fn fit_prefitted(
    data: &Data,
    base_in_band: usize,
    starts: &[LinExt],
    joint: Lin,
    budget: &FitBudget,
) -> Option<(LinExt, LmResult)> {
    let mut scored: Vec<(f64, LinExt)> = Vec::new();
    for (i, st) in starts.iter().enumerate() {
        if !scored.is_empty() && budget.expired() {
            budget.skip_starts(starts.len() - i);
            break;
        }
        scored.extend(prefit_body(data, st, PREFIT_ITERS).filter(|(c, _)| c.is_finite()));
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    // a prefit that moved the appended pair out of the measured band reproduces the base
    // and explains nothing: refined jointly, it returns to the base. The starts whose
    // prefit keeps more resonances in the band than the base chain has go first, in the
    // order of their cost (dev C 70004 and 70400, an extra mode beside friction or a
    // current loop: the starts at 16.5 and 23.5 Hz, for a pair at 20 Hz, ended their
    // prefit above two starts whose appended couplings had gone to 700 Hz, and only those
    // two were refined), and so do those whose appended body became the ground
    // ([`super::gravity::ends_in_ground`]: the load swinging on a spring, whose resonance
    // may lie below the band; taken as gravity, dev A 50804)
    let band = [data.f_min(), data.f_max()];
    scored.sort_by_key(|(_, m)| {
        !(in_band(&m.chain, band) > base_in_band || super::gravity::ends_in_ground(&m.chain))
    });
    let mut best: Option<(LinExt, LmResult)> = None;
    for (i, (_, st)) in scored.iter().take(JOINT_STARTS).enumerate() {
        if best.is_some() && budget.expired() {
            budget.skip_starts(scored.len().min(JOINT_STARTS) - i);
            break;
        }
        if let Some((m, r)) = fit_linear(data, &data.targets, joint, st, JOINT_ITERS) {
            if best.as_ref().is_none_or(|b| r.cost < b.1.cost) {
                best = Some((m, r));
            }
        }
    }
    best
}

/// The resonances of `chain` in `[lo, hi]` [Hz].
fn in_band(chain: &Chain, [lo, hi]: [f64; 2]) -> usize {
    chain
        .resonances_hz()
        .into_iter()
        .filter(|f| *f >= lo && *f <= hi)
        .count()
}

/// The appended body's inertia, spring and damper fitted with the rest of the chain held
/// (`iters` LM iterations): its cost on the decimated targets and the model.
fn prefit_body(data: &Data, start: &LinExt, iters: usize) -> Option<(f64, LinExt)> {
    let n = start.chain.masses();
    let t0 = theta(start, Lin::Mode);
    let idx = [n - 1, 2 * n - 2, 3 * n - 3];
    let e0: Vec<f64> = idx.iter().map(|&i| t0[i]).collect();
    let full = |e: &[f64]| {
        let mut t = t0.clone();
        for (&i, &v) in idx.iter().zip(e) {
            t[i] = v;
        }
        t
    };
    let r = minimise(&e0, iters, |e| {
        residuals(
            &build_on(start, &full(e), n, Lin::Mode)?,
            data,
            &data.targets,
        )
    })?;
    Some((r.cost, build_on(start, &full(&r.x), n, Lin::Mode)?))
}
