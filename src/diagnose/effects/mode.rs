//! `unmodelled_mode`: one more anti-resonance/resonance pair than the nominal model has: a
//! chain of one more body appended to the nominal one, its frequency started at the
//! localised bands (and at the pipeline's own (n+1)-mass identification when it has one),
//! refined jointly on all levels.

use super::{finish_linear, fit_best_start, EffectFit, Lin, Param};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;
use crate::model::Chain;

/// Starts: the nominal chain with a body of `r` times the last inertia appended, tuned to
/// each frequency in `freqs_hz`, plus `extra` chains.
pub fn starts(nominal: &Chain, freqs_hz: &[f64], extra: &[Chain]) -> Vec<Chain> {
    let jl = *nominal.inertia_kgm2.last().unwrap();
    let mut out: Vec<Chain> = extra.to_vec();
    for &f in freqs_hz {
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

pub fn fit(data: &Data, starts: &[Chain]) -> Option<EffectFit> {
    let s: Vec<LinExt> = starts.iter().map(|c| LinExt::nominal(c.clone())).collect();
    let (m, _r) = fit_best_start(data, Lin::Mode, &s, 60, 2)?;
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
    Some(finish_linear(data, "unmodelled_mode", m, p, 3))
}
