//! `time_delay`: a pure delay between command and torque (phase falling linearly with
//! frequency, magnitude untouched). The zero-order hold and the differencing are already in
//! the nominal model, so a plant without delay gives zero.

use super::{finish_linear, fit_best_start, EffectFit, Lin, Param};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;
use crate::diagnose::Effect;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let ts = 1.0 / data.fs;
    // a grid of a quarter sample up to 4 samples: the phase wraps, so LM alone can lock
    // onto a wrong branch; where the drive's torque reading shows the delay's whole
    // samples ([`crate::diagnose::torque_path::TorquePath::whole_samples_beyond`]), the quarters of that sample
    let io_delay = data.levels.first().map_or(0, |l| l.io_delay);
    let grid: Vec<f64> = match data
        .torque
        .as_ref()
        .and_then(|t| t.whole_samples_beyond(io_delay))
    {
        Some(m) => (0..4).map(|i| m as f64 + i as f64 * 0.25).collect(),
        None => (0..=16).map(|i| i as f64 * 0.25).collect(),
    };
    let starts: Vec<LinExt> = grid
        .into_iter()
        .map(|x| {
            let mut s = nominal.clone();
            s.delay_s = x * ts;
            s
        })
        .collect();
    let (m, r) = fit_best_start(data, Lin::Delay, &starts, 40, 2)?;
    let np = r.x.len();
    // the parameter is the delay in ms
    let std = r.cov[np * np - 1].max(0.0).sqrt() * 1e-3;
    let p = vec![Param {
        name: "delay_s".into(),
        value: m.delay_s,
        std,
    }];
    Some(finish_linear(data, Effect::TimeDelay, m, p, 1))
}
