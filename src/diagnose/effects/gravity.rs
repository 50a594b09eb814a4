//! `gravity`: a restoring stiffness from the load to the ground (at small angles
//! `m g l`), so that the low-frequency end no longer behaves like a free inertia.

use super::{finish_linear, fit_best_start, log_std, EffectFit, Lin, Param};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let jt = nominal.chain.total_inertia();
    let w0 = 2.0 * std::f64::consts::PI * data.f_min();
    let starts: Vec<LinExt> = [0.1, 0.5, 2.0, 8.0]
        .iter()
        .map(|m| {
            let mut s = nominal.clone();
            s.ground_k = m * jt * w0 * w0;
            s
        })
        .collect();
    let (m, r) = fit_best_start(data, Lin::Gravity, &starts, 40, 1)?;
    let i0 = 3 * m.chain.masses() - 2;
    let p = vec![Param {
        name: "m_g_l_nm".into(),
        value: m.ground_k,
        std: log_std(&r, i0, m.ground_k),
    }];
    Some(finish_linear(data, "gravity", m, p, 1))
}
