//! The analysis tests' recordings: a plant simulated by the fine-step simulator (not the
//! fit's sampled model) under an excitation, as a drive would record it.

use crate::excitation::ExcitationInfo;
use crate::plant::{PlantSim, PlantSpec};
use crate::recording::{Recording, Sidecar};

/// The recording of `spec`'s plant driven by `signal` [N m] at `fs` [Hz] (`substeps`
/// simulator steps per sample, noise seed `seed`), the excitation described by `info`.
pub fn simulated(
    spec: &PlantSpec,
    signal: &[f64],
    info: ExcitationInfo,
    fs: f64,
    substeps: u32,
    seed: u64,
) -> Recording {
    let mut sim = PlantSim::new(spec, fs, substeps, seed).unwrap();
    let (mut time_s, mut position) = (Vec::new(), Vec::new());
    for &t in signal {
        let s = sim.sample();
        time_s.push(s.time_s);
        position.push(s.position_rad);
        sim.step(t);
    }
    Recording {
        time_s,
        torque_cmd_nm: signal.to_vec(),
        position_rad: Some(position),
        velocity_rad_s: None,
        acceleration_rad_s2: None,
        torque_actual_nm: None,
        sample_rate_hz: fs,
        sidecar: Sidecar {
            sample_rate_hz: Some(fs),
            excitation: Some(info),
            ..Sidecar::default()
        },
    }
}
