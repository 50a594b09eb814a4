//! The world's nominal axes: chains of 2 to 4 bodies whose parameters are drawn over wide
//! ranges (not one family scaled), modes anywhere in the band, with or without viscous
//! friction from the motor to the ground.

use flexid::model::Chain;
use rand::Rng;

/// A chain of `n` bodies whose anti-resonances and resonances lie in `[lo_hz, hi_hz]`,
/// every two features at least 8 % and `min_gap_hz` apart. The motor's inertia is drawn
/// over two decades (1e-4 .. 1e-2 kg m^2), every other body from 0.3x to 20x the motor's,
/// each coupling's two-body frequency log-uniform in the band, coupling damping ratio
/// 0.5 .. 4 %.
pub fn random_chain(
    rng: &mut impl Rng,
    n: usize,
    lo_hz: f64,
    hi_hz: f64,
    min_gap_hz: f64,
) -> Chain {
    let j1 = 10f64.powf(rng.random_range(-4.0..-2.0));
    for _ in 0..20_000 {
        let inertia: Vec<f64> = (0..n)
            .map(|i| {
                if i == 0 {
                    j1
                } else {
                    j1 * 10f64.powf(rng.random_range(-0.5..1.3))
                }
            })
            .collect();
        let pair = |i: usize| 1.0 / (1.0 / inertia[i] + 1.0 / inertia[i + 1]);
        let stiffness: Vec<f64> = (0..n - 1)
            .map(|i| {
                let f = rng.random_range(lo_hz.ln()..hi_hz.ln()).exp();
                pair(i) * (2.0 * std::f64::consts::PI * f).powi(2)
            })
            .collect();
        let damping: Vec<f64> = (0..n - 1)
            .map(|i| {
                let z = rng.random_range(0.005..0.04);
                2.0 * z * (stiffness[i] * pair(i)).sqrt()
            })
            .collect();
        let Ok(c) = Chain::new(inertia, stiffness, damping) else {
            continue;
        };
        let mut all: Vec<f64> = c.antiresonances_hz();
        all.extend(c.resonances_hz());
        if all.len() != 2 * (n - 1) || all.iter().any(|f| *f < lo_hz || *f > hi_hz) {
            continue;
        }
        all.sort_by(f64::total_cmp);
        if all
            .windows(2)
            .all(|w| w[1] / w[0] > 1.08 && w[1] - w[0] >= min_gap_hz)
        {
            return c;
        }
    }
    panic!("no {n}-body chain in {lo_hz:.1} .. {hi_hz:.1} Hz");
}

/// Viscous friction from the motor to the ground [N m s/rad]: zero in a third of the
/// axes, else a corner frequency `b / J_total` of 0.1 .. 3 Hz.
pub fn motor_viscous(rng: &mut impl Rng, chain: &Chain) -> f64 {
    if rng.random_bool(1.0 / 3.0) {
        0.0
    } else {
        let corner_hz = rng.random_range(0.1f64.ln()..3f64.ln()).exp();
        chain.total_inertia() * 2.0 * std::f64::consts::PI * corner_hz
    }
}
