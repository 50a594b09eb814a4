//! The candidate effects, each a model extension with its own few parameters, identified on
//! the same data as the nominal chain.
//!
//! Linear ones (`delay`, `current_loop`, `mode`, `gravity`) are fitted in the frequency
//! domain jointly with the chain ([`fit_linear`]); amplitude-dependent ones (`friction`,
//! `backlash`, `hardening`) by a small parameter search with the time-domain simulation of
//! [`super::nlsim`] on the recorded excitation, the chain corrected between rounds.

pub mod backlash;
pub mod current_loop;
pub mod delay;
pub mod friction;
pub mod gravity;
pub mod hardening;
pub mod mode;
pub mod viscous;

use super::lti::{Discrete, LinExt, Loop};
use super::Data;
use crate::diagnose::Effect;
use crate::lsq::{minimise, LmResult};
use crate::model::Chain;
use num_complex::Complex64;
use serde::Serialize;

/// Start frequencies closer than this ratio to an earlier one give no starts of their own
/// (the extra mode's and gravity's: the bands of the levels overlap; each start costs a
/// fit). Here, not in `mode`, so that `gravity` and `mode` use it without importing
/// each other.
pub const START_FREQ_RATIO: f64 = 1.2;

/// One identified parameter of an effect.
#[derive(Debug, Clone, Serialize)]
pub struct Param {
    pub name: String,
    pub value: f64,
    /// One-sigma uncertainty (NaN when not available).
    pub std: f64,
}

/// An effect identified on the data.
#[derive(Debug, Clone)]
pub struct EffectFit {
    pub effect: Effect,
    pub params: Vec<Param>,
    /// Parameters the effect adds to the nominal chain.
    pub added: usize,
    /// `sum |H_meas - H_model|²/var` over all lines of all levels.
    pub chi2: f64,
    /// Model FRF per level on the measured lines.
    pub model: Vec<Vec<Complex64>>,
    /// The linear part (chain and linear extensions) under the effect.
    pub lin: LinExt,
}

impl Param {
    /// Whether the data fix the parameter: its one-sigma uncertainty is at most the
    /// value's magnitude (a relative uncertainty above 100 % says nothing but that the fit
    /// ran to where the cost no longer changes: a current loop's bandwidth of 6e12 Hz
    /// +- 3e21). An infinite uncertainty: the data bound the parameter on one side only (a
    /// spring that does not act at the measured deflections), not identifiable. `None`: no
    /// uncertainty was computed.
    pub fn identifiable(&self) -> Option<bool> {
        if self.std == f64::INFINITY {
            return Some(false);
        }
        self.std.is_finite().then(|| self.std <= self.value.abs())
    }
}

impl EffectFit {
    pub fn param(name: &str, value: f64, std: f64) -> Param {
        Param {
            name: name.into(),
            value,
            std,
        }
    }
}

/// Which linear extension a parameter vector describes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lin {
    None,
    Delay,
    Loop1,
    Loop2,
    Gravity,
    /// One more body (chain of n+1).
    Mode,
    /// Viscous damping motor-ground.
    Viscous,
    /// One more body and the viscous damping motor-ground together (an extra mode on a
    /// nominal chain whose damper was not significant alone).
    ModeViscous,
}

impl Lin {
    /// The linear extension `m` carries from an earlier step of the forward selection
    /// (delay, current loop, gravity), which a later step's fit refits with the chain
    /// (backfitting: the first effect's parameters, fitted alone, have taken up part of the
    /// second's signature); `Lin::None` when it carries none. A nominal model's own ground
    /// spring (`--ground-spring`) is no extension.
    pub fn carried_by(m: &LinExt) -> Lin {
        match m.current_loop {
            _ if m.delay_s > 0.0 => Lin::Delay,
            Some(l) if l.order == 1 => Lin::Loop1,
            Some(_) => Lin::Loop2,
            None if m.ground_k > 0.0 && !m.ground_spring => Lin::Gravity,
            None => Lin::None,
        }
    }

    fn extra(self) -> usize {
        match self {
            Lin::None | Lin::Mode => 0,
            Lin::Loop2 | Lin::Gravity => 2,
            Lin::ModeViscous => 1,
            _ => 1,
        }
    }
}

/// Floor of a coupling's damping in a fit's start, as a fraction of the coupling's
/// critical damping `2 sqrt(c J_a J_b / (J_a + J_b))`: a fit works on ln d, whose gradient
/// vanishes with d, so a damping far below this has left the fit's reach.
pub const DAMPING_FLOOR: f64 = 1e-4;

/// Critical damping [N m s/rad] of coupling `i` of `c` (the two bodies alone on it).
pub fn critical_damping(c: &Chain, i: usize) -> f64 {
    let (ja, jb) = (c.inertia_kgm2[i], c.inertia_kgm2[i + 1]);
    2.0 * (c.stiffness_nm_per_rad[i] * ja * jb / (ja + jb)).sqrt()
}

/// Log-parameters of a chain: ln J, ln c, ln d (dampings floored at [`DAMPING_FLOOR`]).
pub fn chain_theta(c: &Chain) -> Vec<f64> {
    let mut t: Vec<f64> = c.inertia_kgm2.iter().map(|v| v.ln()).collect();
    t.extend(c.stiffness_nm_per_rad.iter().map(|v| v.ln()));
    for (i, &d) in c.damping_nms_per_rad.iter().enumerate() {
        t.push(d.max(DAMPING_FLOOR * critical_damping(c, i)).ln());
    }
    t
}

fn chain_of(t: &[f64], n: usize) -> Option<Chain> {
    if t.iter().any(|v| !v.is_finite() || v.abs() > 60.0) {
        return None;
    }
    Chain::new(
        t[..n].iter().map(|v| v.exp()).collect(),
        t[n..2 * n - 1].iter().map(|v| v.exp()).collect(),
        t[2 * n - 1..3 * n - 2].iter().map(|v| v.exp()).collect(),
    )
    .ok()
}

/// Whether `m`'s ground spring is a parameter of the fit of extension `k`: a nominal
/// model with a ground spring ([`LinExt::ground_spring`]) fits it with the chain, except in
/// gravity's fit, whose own parameter it is.
fn fits_ground(m: &LinExt, k: Lin) -> bool {
    m.ground_spring && k != Lin::Gravity
}

/// Whether `m`'s viscous friction to the ground is a parameter of the fit of extension `k`:
/// a nominal model with viscous friction (`motor_b > 0`) fits it with the chain, as it fits
/// the chain (held at the nominal fit's value, it stays where the chain bent to mimic
/// the effect had put it: world seed 30805, gravity's load damper 30 % off beside the
/// nominal's 0.048 for 0.037 N m s/rad), except in the fits whose own parameter it is.
fn fits_viscous(m: &LinExt, k: Lin) -> bool {
    m.motor_b > 0.0 && !matches!(k, Lin::Viscous | Lin::ModeViscous)
}

/// Number of leading entries of [`theta`] that belong to the nominal model: the chain's
/// `3n - 2` log-parameters and, with a ground spring in the nominal model, its log-stiffness,
/// with viscous friction its log-damping (the extension's own parameters follow).
pub fn nominal_params(m: &LinExt, k: Lin) -> usize {
    3 * m.chain.masses() - 2 + usize::from(fits_ground(m, k)) + usize::from(fits_viscous(m, k))
}

/// Parameter vector of `m` for extension `k`.
pub fn theta(m: &LinExt, k: Lin) -> Vec<f64> {
    let mut t = chain_theta(&m.chain);
    let fs_guard = 1e-12;
    if fits_ground(m, k) {
        t.push(m.ground_k.max(fs_guard).ln());
    }
    if fits_viscous(m, k) {
        t.push(m.motor_b.ln());
    }
    match k {
        Lin::None | Lin::Mode => {}
        Lin::Delay => t.push(m.delay_s * 1e3),
        Lin::Loop1 | Lin::Loop2 => {
            let l = m.current_loop.expect("loop");
            t.push(l.bandwidth_hz.ln());
            if k == Lin::Loop2 {
                t.push(l.zeta.ln());
            }
        }
        Lin::Gravity => {
            t.push(m.ground_k.max(fs_guard).ln());
            t.push(m.ground_b.max(fs_guard).ln());
        }
        Lin::Viscous | Lin::ModeViscous => t.push(m.motor_b.max(fs_guard).ln()),
    }
    t
}

/// The model a parameter vector describes (`n`: bodies of its chain), on top of `base`:
/// the extensions `k` does not fit (viscous friction of the nominal model, ...) are kept
/// as `base` has them (they used to be reset, so that a candidate fitted on a nominal
/// model with viscous friction lost it).
pub fn build_on(base: &LinExt, t: &[f64], n: usize, k: Lin) -> Option<LinExt> {
    let mut m = base.clone();
    m.chain = chain_of(t, n)?;
    let mut at = 3 * n - 2;
    // the nominal model's log-parameters after the chain's, in `theta`'s order
    let mut next = || {
        let v = *t.get(at)?;
        at += 1;
        (v.is_finite() && v.abs() <= 60.0).then(|| v.exp())
    };
    if fits_ground(base, k) {
        m.ground_k = next()?;
    }
    if fits_viscous(base, k) {
        m.motor_b = next()?;
    }
    let e = t.get(at..)?;
    match k {
        Lin::None | Lin::Mode => {}
        Lin::Delay => m.delay_s = (e[0] * 1e-3).max(0.0),
        Lin::Loop1 => {
            m.current_loop = Some(Loop {
                order: 1,
                bandwidth_hz: e[0].exp(),
                zeta: 0.7,
            })
        }
        Lin::Loop2 => {
            m.current_loop = Some(Loop {
                order: 2,
                bandwidth_hz: e[0].exp(),
                zeta: e[1].exp().min(5.0),
            })
        }
        Lin::Gravity => {
            m.ground_k = e[0].exp();
            m.ground_b = e[1].exp();
        }
        Lin::Viscous | Lin::ModeViscous => m.motor_b = e[0].exp(),
    }
    if e.iter().any(|v| !v.is_finite() || v.abs() > 60.0) {
        return None;
    }
    // gravity stiffer than the last spring would ground the last body: a different model
    // (the chain one body shorter), not a restoring stiffness
    if k == Lin::Gravity
        && m.chain
            .stiffness_nm_per_rad
            .last()
            .is_some_and(|&c| m.ground_k > c)
    {
        return None;
    }
    Some(m)
}

/// The targets of a fit: per level the (decimated) lines, the response to match and the
/// weights `|H|/sigma`.
#[derive(Debug, Clone)]
pub struct Target {
    /// Indices of the lines in the level's measured FRF.
    pub idx: Vec<usize>,
    pub f: Vec<f64>,
    pub h: Vec<Complex64>,
    pub w: Vec<f64>,
    pub io_delay: u32,
    /// The level's input is band-limited, not held ([`Discrete::band_limited`]).
    pub band_limited: bool,
}

/// Model FRF per level on lines `f` of each target.
pub fn model_on(
    m: &LinExt,
    fs: f64,
    kind: crate::frf::FrfKind,
    targets: &[Target],
) -> Vec<Vec<Complex64>> {
    let mut cache: Option<((u32, bool), Discrete)> = None;
    targets
        .iter()
        .map(|t| {
            let key = (t.io_delay, t.band_limited);
            if cache.as_ref().map(|c| c.0) != Some(key) {
                cache = Some((key, Discrete::with_input(m, fs, t.io_delay, t.band_limited)));
            }
            cache.as_ref().unwrap().1.frf_lines(&t.f, kind)
        })
        .collect()
}

fn residuals(m: &LinExt, data: &Data, targets: &[Target]) -> Option<Vec<f64>> {
    let mut r = Vec::new();
    for (t, hm) in targets.iter().zip(model_on(m, data.fs, data.kind, targets)) {
        for ((h, w), hm) in t.h.iter().zip(&t.w).zip(hm) {
            let l = (hm / h).ln() * *w;
            if !l.re.is_finite() || !l.im.is_finite() {
                return None;
            }
            r.push(l.re);
            r.push(l.im);
        }
    }
    Some(r)
}

/// Fit the chain and extension `k` jointly to `targets` from `start` (whose chain has
/// `n` bodies). Returns the model and the LM result (parameters in [`theta`] order).
pub fn fit_linear(
    data: &Data,
    targets: &[Target],
    k: Lin,
    start: &LinExt,
    iters: usize,
) -> Option<(LinExt, LmResult)> {
    let n = start.chain.masses();
    let t0 = theta(start, k);
    debug_assert_eq!(t0.len(), nominal_params(start, k) + k.extra());
    let r = minimise(&t0, iters, |t| {
        residuals(&build_on(start, t, n, k)?, data, targets)
    })?;
    Some((build_on(start, &r.x, n, k)?, r))
}

/// Screen `starts` by their cost (one evaluation each) and refine the best `keep` of them;
/// the best refined fit.
pub fn fit_best_start(
    data: &Data,
    k: Lin,
    starts: &[LinExt],
    iters: usize,
    keep: usize,
) -> Option<(LinExt, LmResult)> {
    let mut scored: Vec<(f64, &LinExt)> = starts
        .iter()
        .filter_map(|s| {
            let r = residuals(s, data, &data.targets)?;
            Some((r.iter().map(|v| v * v).sum::<f64>(), s))
        })
        .filter(|(c, _)| c.is_finite())
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best: Option<(LinExt, LmResult)> = None;
    // the `keep` best starts that can be fitted (a start whose fit fails, e.g. a singular
    // step, does not use up a place: with all of the first `keep` failing there was no fit
    // at all)
    let mut fitted = 0;
    for (_, s) in scored {
        if fitted == keep {
            break;
        }
        let fit = if k == Lin::Gravity {
            prefit_then_joint(data, k, s, iters)
        } else {
            fit_linear(data, &data.targets, k, s, iters)
        };
        if let Some((m, r)) = fit {
            fitted += 1;
            if best.as_ref().is_none_or(|b| r.cost < b.1.cost) {
                best = Some((m, r));
            }
        }
    }
    let (m, r) = best?;
    Some(revived(data, k, m, r, iters))
}

/// A fit whose coupling dampings collapsed below [`DAMPING_FLOOR`] on the way (the joint
/// fit's first steps, far from the optimum, pushed them down; at ln d's vanishing gradient
/// they cannot come back, and a damping the data do fix stays at zero: world seed 30806,
/// the load coupling at 1e-15 for 0.2 N m s/rad) refitted once with them at 3 % of
/// critical, the extra-body start's value ([`mode::starts`]); the better of the two.
fn revived(data: &Data, k: Lin, m: LinExt, r: LmResult, iters: usize) -> (LinExt, LmResult) {
    let mut start = m.clone();
    let mut any = false;
    for i in 0..start.chain.damping_nms_per_rad.len() {
        let crit = critical_damping(&start.chain, i);
        if start.chain.damping_nms_per_rad[i] < DAMPING_FLOOR * crit {
            start.chain.damping_nms_per_rad[i] = 0.03 * crit;
            any = true;
        }
    }
    if !any {
        return (m, r);
    }
    match fit_linear(data, &data.targets, k, &start, iters) {
        Some((m2, r2)) if r2.cost < r.cost => (m2, r2),
        _ => (m, r),
    }
}

/// The effect's own parameters first (chain held), then everything jointly: for effects
/// that the nominal chain has bent itself to mimic (gravity).
pub fn prefit_then_joint(
    data: &Data,
    k: Lin,
    start: &LinExt,
    iters: usize,
) -> Option<(LinExt, LmResult)> {
    let n = start.chain.masses();
    let t0 = theta(start, k);
    let nc = nominal_params(start, k);
    let chain_t = t0[..nc].to_vec();
    let r0 = minimise(&t0[nc..], 30, |e| {
        let mut t = chain_t.clone();
        t.extend_from_slice(e);
        residuals(&build_on(start, &t, n, k)?, data, &data.targets)
    })?;
    let mut t1 = chain_t.clone();
    t1.extend(r0.x);
    let s1 = build_on(start, &t1, n, k)?;
    fit_linear(data, &data.targets, k, &s1, iters)
}

/// Std of the value of log-parameter `i` (value `v`): `v * sqrt(cov_ii)`.
pub fn log_std(r: &LmResult, i: usize, v: f64) -> f64 {
    let np = r.x.len();
    v * r.cov[i * np + i].max(0.0).sqrt()
}

/// The finished effect: model on all lines, chi² and parameters.
pub fn finish_linear(
    data: &Data,
    effect: Effect,
    lin: LinExt,
    params: Vec<Param>,
    added: usize,
) -> EffectFit {
    let model = model_on(&lin, data.fs, data.kind, &data.full_targets);
    let chi2 = data.chi2(&model);
    EffectFit {
        effect,
        params,
        added,
        chi2,
        model,
        lin,
    }
}
