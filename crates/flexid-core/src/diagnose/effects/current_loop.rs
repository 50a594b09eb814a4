//! `current_loop`: the current loop's finite bandwidth between command and torque
//! (magnitude and phase roll-off at the top of the band), order 1 or 2 (the better of the
//! two after the penalty for the damping ratio).

use super::{finish_linear, fit_best_start, log_std, EffectFit, Lin, Param};
use crate::diagnose::lti::{LinExt, Loop};
use crate::diagnose::Data;
use crate::diagnose::Effect;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let fmax = data.f_max();
    let pen = (data.lines() as f64).ln();
    let mut best: Option<EffectFit> = None;
    for (order, k) in [(1u8, Lin::Loop1), (2, Lin::Loop2)] {
        let starts: Vec<LinExt> = [0.5, 1.0, 2.0, 5.0]
            .iter()
            .flat_map(|m| [0.5, 0.8].into_iter().map(move |z| (m, z)))
            .filter(|(_, z)| order == 2 || *z == 0.5)
            .map(|(m, z)| {
                let mut s = nominal.clone();
                s.current_loop = Some(Loop {
                    order,
                    bandwidth_hz: m * fmax,
                    zeta: z,
                });
                s
            })
            .collect();
        let Some((m, r)) = fit_best_start(data, k, &starts, 40, 1) else {
            continue;
        };
        let l = m.current_loop.unwrap();
        let i0 = 3 * m.chain.masses() - 2;
        let mut p = vec![
            Param {
                name: "bandwidth_hz".into(),
                value: l.bandwidth_hz,
                std: log_std(&r, i0, l.bandwidth_hz),
            },
            Param {
                name: "order".into(),
                value: order as f64,
                std: 0.0,
            },
        ];
        if order == 2 {
            p.push(Param {
                name: "damping_ratio".into(),
                value: l.zeta,
                std: log_std(&r, i0 + 1, l.zeta),
            });
        }
        let e = finish_linear(data, Effect::CurrentLoop, m, p, order as usize);
        let score = |e: &EffectFit| e.chi2 + pen * e.added as f64;
        if best.as_ref().is_none_or(|b| score(&e) < score(b)) {
            best = Some(e);
        }
    }
    best
}
