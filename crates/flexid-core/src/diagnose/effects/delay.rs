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
    // onto a wrong branch
    let starts: Vec<LinExt> = (0..=16)
        .map(|i| i as f64 * 0.25)
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
