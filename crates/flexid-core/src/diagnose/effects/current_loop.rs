//! `current_loop`: the current loop's finite bandwidth between command and torque
//! (magnitude and phase roll-off at the top of the band), order 1 or 2 (the better of the
//! two after the penalty for the damping ratio).
//!
//! The defining parameter is the -3 dB bandwidth: for an overdamped second order the
//! natural frequency and the damping ratio slide along a valley (a far pole and a near one;
//! on a viscous benchmark plant 5.4 kHz +- 5.3 kHz with zeta 4 for a true first-order loop
//! at 623 Hz) while the -3 dB frequency, what the data show, is sharp. Its uncertainty by
//! the delta method from the covariance of (ln f_n, ln zeta).

use super::{finish_linear, fit_best_start, log_std, EffectFit, Lin, Param};
use crate::diagnose::lti::{LinExt, Loop};
use crate::diagnose::torque_path::Shape;
use crate::diagnose::Data;
use crate::diagnose::Effect;

pub fn fit(data: &Data, nominal: &LinExt) -> Option<EffectFit> {
    let fmax = data.f_max();
    let pen = (data.lines() as f64).ln();
    let mut best: Option<EffectFit> = None;
    // the loop the drive's torque reading shows, where it shows one: measured, so a start
    let read = data
        .torque
        .as_ref()
        .filter(|tp| tp.shape == Shape::Loop)
        .and_then(|tp| tp.with_loop.lp);
    // and the chain behind it ([`crate::diagnose::loop_free`]), where the candidate is
    // fitted on the nominal chain alone (not on top of another linear extension)
    let behind = data
        .torque
        .as_ref()
        .and_then(|tp| tp.loop_free.clone())
        .filter(|_| Lin::carried_by(nominal) == Lin::None);
    for (order, k) in [(1u8, Lin::Loop1), (2, Lin::Loop2)] {
        let from_reading = read.filter(|l| l.order == order).map(|l| {
            let mut s = nominal.clone();
            s.current_loop = Some(l);
            s
        });
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
            .chain(from_reading)
            .chain(
                behind
                    .clone()
                    .filter(|b| b.current_loop.map(|l| l.order) == Some(order)),
            )
            .collect();
        let Some((m, r)) = fit_best_start(data, k, &starts, 40, 1) else {
            continue;
        };
        let l = m.current_loop.unwrap();
        let i0 = super::nominal_params(&m, k);
        let f3 = l.bandwidth_hz * minus_3db_ratio(l.zeta, order);
        let std3 = if order == 1 {
            log_std(&r, i0, f3)
        } else {
            // d ln f3 / d ln fn = 1, d ln f3 / d ln zeta numerically
            let h = 1e-4;
            let g = ((minus_3db_ratio(l.zeta * (1.0 + h), 2)).ln()
                - (minus_3db_ratio(l.zeta * (1.0 - h), 2)).ln())
                / (2.0 * h);
            let np = r.x.len();
            let c = |a: usize, b: usize| r.cov[a * np + b];
            let var = c(i0, i0) + 2.0 * g * c(i0, i0 + 1) + g * g * c(i0 + 1, i0 + 1);
            f3 * var.max(0.0).sqrt()
        };
        let mut p = vec![
            Param {
                name: "bandwidth_3db_hz".into(),
                value: f3,
                std: std3,
            },
            Param {
                name: "natural_frequency_hz".into(),
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

/// The -3 dB frequency of the loop over its natural frequency: 1 for order 1; for order 2,
/// `sqrt(1 - 2 z² + sqrt((1 - 2 z²)² + 1))`.
pub fn minus_3db_ratio(zeta: f64, order: u8) -> f64 {
    if order < 2 {
        return 1.0;
    }
    let a = 1.0 - 2.0 * zeta * zeta;
    (a + (a * a + 1.0).sqrt()).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    #[test]
    fn the_3db_ratio_is_where_the_second_order_magnitude_is_half_power() {
        for z in [0.3, 0.7071, 1.0, 4.0] {
            let r = minus_3db_ratio(z, 2);
            let s = Complex64::new(0.0, r);
            let h = 1.0 / (s * s + 2.0 * z * s + 1.0);
            assert!(
                (h.norm_sqr() - 0.5).abs() < 1e-9,
                "zeta {z}: {}",
                h.norm_sqr()
            );
        }
        assert!((minus_3db_ratio(0.7071067811865476, 2) - 1.0).abs() < 1e-9);
        assert_eq!(minus_3db_ratio(0.5, 1), 1.0);
    }
}
