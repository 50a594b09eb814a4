//! Import presets for the measurement data sets in the shared data folder.

use super::daisy::text_to_recording;
use super::spec::{mat_to_recording, MatSpec};
use super::ImportError;
use crate::recording::{MotionSignal, Recording};
use std::path::{Path, PathBuf};

/// Environment variable overriding the location of the shared data folder.
pub const SHARED_DATA_ENV: &str = "FLEXID_SHARED_DATA";

/// Names accepted by [`preset`].
pub const PRESET_NAMES: &[&str] = &[
    "fditools-typeA",
    "fditools-typeB",
    "fditools-typeA-load",
    "fditools-typeB-load",
    "daisy-robot-arm",
    "f16",
    "f16-level1",
    "f16-level2-validation",
    "f16-level3",
    "f16-level5",
    "f16-level7",
    "f16-special-odd",
    "emps",
    "emps-pulses",
    "silverbox",
];

/// The shared data folder: `$FLEXID_SHARED_DATA` if set, else `shared/data` beside the
/// repository checkout (`CARGO_MANIFEST_DIR/../../../shared/data`). It may not exist.
pub fn shared_data_dir() -> PathBuf {
    match std::env::var_os(SHARED_DATA_ENV) {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    }
}

fn fditools(file: &'static str, load_side: bool, type_b: bool) -> (&'static str, MatSpec) {
    let (output, scale) = if load_side {
        ("theta_my", -1.0)
    } else {
        ("theta_mx", 1.0)
    };
    let spec = MatSpec {
        output_scale: scale,
        sample_rate_var: Some("fs".into()),
        period_samples: Some(2500),
        transient_periods: 1,
        excitation_reference: Some("xf".into()),
        line_threshold: 1e-6,
        design: Some(if type_b { "odd_odd_random_phase" } else { "schroeder" }.into()),
        notes: format!(
            "FdiTools two-inertia motor bench (MIT, Hori-Fujimoto Lab / Beauduin / Ohnishi): the torque column holds the measured q-axis current iq [A], not torque [N m] (torque constant unknown); {} angle `{output}`, units not stated (rad presumed){}; {}",
            if load_side { "load-side" } else { "motor-side" },
            if load_side { ", sign flipped as in the FdiTools examples" } else { "" },
            if type_b {
                "odd-odd random-phase multisine 13, 17, ..., 249 Hz"
            } else {
                "Schroeder multisine 11..250 Hz"
            },
        ),
        ..MatSpec::new("iq_adx", output, MotionSignal::Position)
    };
    (file, spec)
}

fn f16(file: &'static str, period: usize) -> (&'static str, MatSpec) {
    let spec = MatSpec {
        output_column: Some(0),
        sample_rate_var: Some("Fs".into()),
        period_samples: Some(period),
        transient_periods: 1,
        excitation_reference: Some("Voltage".into()),
        line_threshold: 1e-2,
        design: Some(if period == 8192 { "full_grid_multisine" } else { "odd_random_phase" }.into()),
        notes: "F-16 ground vibration test (Noel & Schoukens, nonlinearbenchmark.org): the torque column holds the shaker force [N], the acceleration column the translational acceleration at the excitation location (channel 1 of 3; units not stated in the files), not rad/s^2; lines from the mean over steady-state periods of the measured generator voltage".into(),
        ..MatSpec::new("Force", "Acceleration", MotionSignal::Acceleration)
    };
    (file, spec)
}

/// EMPS: `vir` is the controller output in volts (its range is +-4.3 under a 10 V
/// saturation; the PDF's eq. 7: force = gtau nu), so the force in N is `gtau * vir` with the
/// file's own `gtau` (35.15 N/V). The IDIM-LS on the converted force finds M = 94.8 kg
/// (published 95.1 kg); on `vir` itself it would be 2.70 V s²/m.
fn emps(file: &'static str) -> (&'static str, MatSpec) {
    let spec = MatSpec {
        sample_rate_hz: Some(1000.0),
        input_scale_var: Some("gtau".into()),
        notes: "EMPS prismatic drive (Janot, Gautier & Brunot 2019), closed loop, bang-bang trajectories: the torque column holds the motor force on the load side [N] = gtau [N/V] x the controller output `vir` [V], the position column the motor position on the load side `qm` [m], not rad; fs 1 kHz (dt of `t`)".into(),
        ..MatSpec::new("vir", "qm", MotionSignal::Position)
    };
    (file, spec)
}

/// The Silverbox (Wigren & Schoukens 2013): an electronic Duffing oscillator, input `V1`
/// [V] -> output `V2` [V] (a displacement-like voltage), fs = 10 MHz / 2^14 = 610.35 Hz.
/// `SNLS80mV.mat` holds, after the noise "arrow head", 10 realisations of an odd
/// random-phase multisine of 8192 samples per period, each after a lead-in; they are found
/// by the input's periodicity ([`super::realisations`]), the means removed as the data's
/// README asks. Both voltages are measured by ADCs from analogue signals: the input is
/// band-limited between samples, not held (a model on the zero-order-hold footing is off by
/// half a sample, 59 degrees at 200 Hz).
fn silverbox() -> (&'static str, MatSpec) {
    let spec = MatSpec {
        sample_rate_hz: Some(610.35),
        period_samples: Some(8192),
        realisations: true,
        remove_mean: true,
        band_limited: true,
        design: Some("odd_random_phase_realisations".into()),
        notes: "Silverbox electronic Duffing oscillator (Wigren & Schoukens 2013, nonlinearbenchmark.org): the torque column holds the input voltage V1 [V], the position column the output voltage V2 [V] (a displacement-like quantity), not N m and rad; fs = 10 MHz / 2^14 = 610.35 Hz; the multisine part only (the arrow-head test signal before it is left out)".into(),
        ..MatSpec::new("V1", "V2", MotionSignal::Position)
    };
    ("silverbox/SNLS80mV.mat", spec)
}

/// An import preset: the file's path relative to the shared data folder and the spec.
///
/// * `fditools-typeA` / `fditools-typeB`: `MultisineType{A,B}.mat`, `iq_adx` [A] ->
///   `theta_mx` (motor angle, position), fs from `fs` (2500 Hz), 20 periods of 2500 samples,
///   1 transient; excited lines from `xf` (one designed period): A all 240 lines 11..250 Hz,
///   B the 60 odd-odd lines 13, 17, ..., 249 Hz. `*-load`: load angle `theta_my`, sign flipped.
/// * `daisy-robot-arm`: `robot_arm.dat`, torque -> arm acceleration, 1024 samples, fs
///   100 Hz **assumed** (DaISy gives none; the guess of ControlSystemIdentification.jl),
///   not treated as periodic.
/// * `f16` (= `f16-level1`), `f16-level{2-validation,3,5,7}`: `Force` [N] -> `Acceleration`
///   channel 0 (at the shaker), fs from `Fs` (400 Hz), 9 periods of 8192, 1 transient; 267
///   lines 41..307 (2-15 Hz) from `Voltage`. `f16-special-odd`: 3 periods of 16384.
/// * `emps`, `emps-pulses`: `gtau * vir` [N] -> `qm` [m], 1 kHz, not periodic, closed loop.
/// * `silverbox`: `SNLS80mV.mat`, `V1` [V] -> `V2` [V], 610.35 Hz, 10 realisations of an odd
///   random-phase multisine (8192 samples, odd lines 0.07-200 Hz), each one steady period
///   after its lead-in ([`silverbox`]).
pub fn preset(name: &str) -> Option<(&'static str, MatSpec)> {
    Some(match name {
        "fditools-typeA" => fditools("fditools-motor-bench/MultisineTypeA.mat", false, false),
        "fditools-typeB" => fditools("fditools-motor-bench/MultisineTypeB.mat", false, true),
        "fditools-typeA-load" => fditools("fditools-motor-bench/MultisineTypeA.mat", true, false),
        "fditools-typeB-load" => fditools("fditools-motor-bench/MultisineTypeB.mat", true, true),
        "daisy-robot-arm" => (
            "daisy-robot-arm/robot_arm.dat",
            MatSpec {
                input_column: Some(0),
                output_column: Some(1),
                sample_rate_hz: Some(100.0),
                design: Some("periodic_sine_sweep".into()),
                notes: "DaISy 96-009 flexible robot arm (KU Leuven): column 1 reaction torque, column 2 arm acceleration (units not stated); fs NOT stated by DaISy, 100 Hz assumed as in ControlSystemIdentification.jl; periodic sine sweep with an unknown number of periods, imported as non-periodic".into(),
                ..MatSpec::new("reaction torque", "arm acceleration", MotionSignal::Acceleration)
            },
        ),
        "f16" | "f16-level1" => f16("f16-gvt/F16Data_FullMSine_Level1.mat", 8192),
        "f16-level2-validation" => f16("f16-gvt/F16Data_FullMSine_Level2_Validation.mat", 8192),
        "f16-level3" => f16("f16-gvt/F16Data_FullMSine_Level3.mat", 8192),
        "f16-level5" => f16("f16-gvt/F16Data_FullMSine_Level5.mat", 8192),
        "f16-level7" => f16("f16-gvt/F16Data_FullMSine_Level7.mat", 8192),
        "f16-special-odd" => f16("f16-gvt/F16Data_SpecialOddMSine_Level1_Validation.mat", 16384),
        "emps" => emps("emps/DATA_EMPS.mat"),
        "emps-pulses" => emps("emps/DATA_EMPS_PULSES.mat"),
        "silverbox" => silverbox(),
        _ => return None,
    })
}

/// Imports any file with a spec: `.mat` through [`mat_to_recording`], anything else as
/// column text through [`text_to_recording`].
pub fn import_file(path: &Path, spec: &MatSpec) -> Result<Recording, ImportError> {
    let is_mat = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mat"));
    if is_mat {
        mat_to_recording(path, spec)
    } else {
        text_to_recording(path, spec)
    }
}

/// Imports preset `name` from the data folder `data_dir` (see [`shared_data_dir`]).
/// `Ok(None)` for an unknown preset name.
pub fn load_preset(name: &str, data_dir: &Path) -> Result<Option<Recording>, ImportError> {
    match preset(name) {
        Some((rel, spec)) => import_file(&data_dir.join(rel), &spec).map(Some),
        None => Ok(None),
    }
}
