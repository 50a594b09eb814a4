//! The FRF matrix from a recorded multi-axis measurement: per axis the torque of every
//! cycle and the motor position, the orthogonal multisine's experiments back to back.

use super::mimo::{MimoError, MimoEstimator, MimoFrf};

/// Feeds `estimator` (planned for the record's multisine, with its transient periods
/// set) with a record of `torque_nm[axis][cycle]` and `position_rad[axis][cycle]` at
/// `sample_rate_hz` [Hz]: experiment after experiment, `periods_per_experiment` periods
/// each (transient ones included), the output the backward-differenced motor speed
/// `(p[k] - p[k-1]) fs` (the first cycle's difference is taken from itself: 0, inside the
/// first experiment's transient). A record cut short gives the periods it holds; then
/// the estimate. Errors: the estimator's (an experiment without averaged periods among
/// them).
pub fn estimate_from_positions(
    mut estimator: MimoEstimator,
    sample_rate_hz: f64,
    periods_per_experiment: usize,
    torque_nm: &[Vec<f64>],
    position_rad: &[Vec<f64>],
) -> Result<MimoFrf, MimoError> {
    let axes = torque_nm.len();
    let n = estimator.period_samples();
    let len = torque_nm
        .iter()
        .chain(position_rad)
        .map(Vec::len)
        .min()
        .unwrap_or(0);
    let mut y = vec![vec![0.0; n]; axes];
    let mut start = 0;
    let mut experiment = 0;
    while experiment < estimator.experiments() {
        for _ in 0..periods_per_experiment {
            if start + n > len {
                return estimator.estimate();
            }
            for (yi, p) in y.iter_mut().zip(position_rad) {
                for (k, v) in yi.iter_mut().enumerate() {
                    let c = start + k;
                    *v = (p[c] - p[c.saturating_sub(1)]) * sample_rate_hz;
                }
            }
            let us: Vec<&[f64]> = torque_nm.iter().map(|t| &t[start..start + n]).collect();
            let ys: Vec<&[f64]> = y.iter().map(Vec::as_slice).collect();
            estimator.push_period(experiment, &us, &ys)?;
            start += n;
        }
        experiment += 1;
    }
    estimator.estimate()
}
