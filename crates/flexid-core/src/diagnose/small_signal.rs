//! The small-signal chain of an axis whose FRF changes with the level, and how much a
//! coupling stiffens (or softens) at the highest level.
//!
//! A spring that stiffens strongly with deflection (a hardening coupling swept through its
//! resonance) bends each level's own linear fit far from the chain behind it: on a world
//! sweep the low level's fit put the resonance at 122 Hz where the chain has it at 75 Hz
//! (the spring jumps), and every start built on that fit was worse than the nominal model.
//! The lines where the two levels agree within the noise are where the spring does not act
//! at either level: the chain fitted there is the small-signal one (that sweep: inertias
//! within 0.2 %, the stiffness within 4 %). On the lines where the levels differ, the
//! highest level's FRF is that chain with one coupling's stiffness raised or lowered; the
//! ratio, with the coupling's deflection there, gives the spring's parameter through its
//! describing function ([`super::search::fit_spring`]).

use super::effects::{fit_linear, model_on, Lin, Target};
use super::lti::LinExt;
use super::{target_on, Data};

/// The small-signal chain and the highest level's lines where the FRF changed.
pub struct Split {
    pub chain: LinExt,
    /// The highest level's lines whose FRF differs from the lowest level's beyond the
    /// noise.
    pub changed_hi: Target,
}

/// `ln 100`: noise alone puts 1 % of the lines above it (`|ΔH|² / var` of a complex
/// difference is exponential with unit mean).
const AGREE_Z2: f64 = 4.605_170_185_988_091;

/// The chain fitted (from `start`) on the lines where the lowest level `lo` and the highest
/// `hi` agree within the noise ([`AGREE_Z2`]), and the highest level's other lines. `None`
/// when the levels agree everywhere, share no lines, or leave fewer than four lines per
/// chain parameter, or fewer than four changed lines.
pub fn split(data: &Data, start: &LinExt, lo: usize, hi: usize) -> Option<Split> {
    if lo == hi {
        return None;
    }
    let (a, b) = (&data.levels[lo], &data.levels[hi]);
    let (mut keep_a, mut keep_b, mut changed) = (Vec::new(), Vec::new(), Vec::new());
    let mut j = 0usize;
    for (i, &f) in a.f.iter().enumerate() {
        while j < b.f.len() && b.f[j] < f * (1.0 - 1e-9) {
            j += 1;
        }
        if j < b.f.len() && (b.f[j] - f).abs() <= 1e-9 * f {
            let z2 = (a.h[i] - b.h[j]).norm_sqr() / (a.var[i] + b.var[j]);
            if z2 < AGREE_Z2 {
                keep_a.push(i);
                keep_b.push(j);
            } else {
                changed.push(j);
            }
        }
    }
    let params = 3 * start.chain.masses();
    if changed.len() < 4 || 2 * keep_a.len() < 4 * params {
        return None;
    }
    let agree = [target_on(a, keep_a), target_on(b, keep_b)];
    let chain = fit_linear(data, &agree, Lin::None, start, 30)?.0;
    Some(Split {
        chain,
        changed_hi: target_on(b, changed),
    })
}

/// The stiffness [N m/rad] of coupling `k` of `chain`, everything else held, that fits the
/// lines `t` best (weighted log-complex least squares, a golden search over 1/30 to 30
/// times the chain's own): the coupling's equivalent stiffness where the level changed it.
pub fn equivalent_stiffness(data: &Data, chain: &LinExt, k: usize, t: &Target) -> f64 {
    let c0 = chain.chain.stiffness_nm_per_rad[k];
    let cost = |c: f64| {
        let mut l = chain.clone();
        l.chain.stiffness_nm_per_rad[k] = c;
        let m = model_on(&l, data.fs, data.kind, std::slice::from_ref(t));
        t.h.iter()
            .zip(&t.w)
            .zip(&m[0])
            .map(|((h, w), hm)| {
                let r = (hm / h).ln() * *w;
                r.norm_sqr()
            })
            .sum::<f64>()
    };
    // a log grid of 61 points (a factor 1.12 apart), then golden steps around the best
    let (la, lb) = ((c0 / 30.0).ln(), (c0 * 30.0).ln());
    let pts: Vec<f64> = (0..61).map(|i| la + (lb - la) * i as f64 / 60.0).collect();
    let vals: Vec<f64> = pts.iter().map(|&x| cost(x.exp())).collect();
    let ib = (0..pts.len())
        .filter(|&i| vals[i].is_finite())
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap_or(30);
    let (mut a, mut b) = (pts[ib.saturating_sub(1)], pts[(ib + 1).min(60)]);
    let gr = 0.618_033_988_75;
    for _ in 0..30 {
        let (c, d) = (b - gr * (b - a), a + gr * (b - a));
        if cost(c.exp()) < cost(d.exp()) {
            b = d;
        } else {
            a = c;
        }
    }
    (0.5 * (a + b)).exp()
}
