//! Test helpers: measurements made exactly from a model, for the diagnosis's unit tests.

use super::effects::{model_on, Target};
use super::lti::LinExt;
use super::{noise, Data, Level};
use crate::frf::FrfKind;
use crate::recording::{Recording, Sidecar};

/// A one-level measurement of `lin` (differenced velocity) on `lines` log-spaced lines in
/// `band_hz`, exactly the model, each line with a 1 % relative standard deviation estimated
/// from 8 averages. The level's recording is empty (no simulation possible).
pub fn exact_data(lin: &LinExt, fs: f64, band_hz: &[f64; 2], lines: usize) -> (Data, LinExt) {
    let f: Vec<f64> = (0..lines)
        .map(|i| band_hz[0] * (band_hz[1] / band_hz[0]).powf(i as f64 / (lines - 1) as f64))
        .collect();
    let idx: Vec<usize> = (0..lines).collect();
    let probe = Target {
        idx: idx.clone(),
        f: f.clone(),
        h: vec![num_complex::Complex64::new(1.0, 0.0); lines],
        w: vec![1.0; lines],
        io_delay: 0,
        band_limited: false,
    };
    let kind = FrfKind::DifferencedVelocity;
    let h = model_on(lin, fs, kind, std::slice::from_ref(&probe)).remove(0);
    let var: Vec<f64> = h.iter().map(|h| 1e-4 * h.norm_sqr()).collect();
    let target = Target {
        w: h.iter()
            .zip(&var)
            .map(|(h, v)| h.norm() / v.sqrt())
            .collect(),
        h: h.clone(),
        ..probe
    };
    let rec = Recording {
        time_s: vec![],
        torque_cmd_nm: vec![],
        position_rad: None,
        velocity_rad_s: None,
        acceleration_rad_s2: None,
        torque_actual_nm: None,
        sample_rate_hz: fs,
        sidecar: Sidecar::default(),
    };
    let level = Level {
        f,
        h,
        var,
        keep: idx,
        nonexcited: None,
        rec,
        torque_rms: 1.0,
        io_delay: 0,
        averages: 8,
        spread_var: None,
        shortened: Default::default(),
        sweep_plan: Default::default(),
        measured: None,
    };
    let data = Data {
        noise: noise::reduced_chi2(&[(lines, 8)]),
        levels: vec![level],
        fs,
        kind,
        band: Some(*band_hz),
        substeps: 1,
        spring_substeps: 1,
        targets: vec![target.clone()],
        full_targets: vec![target],
        torque: None,
    };
    (data, lin.clone())
}
