//! The rows a sweep records, one per cycle, and where the loop puts them.

use flexid_core::recording::{Recording, Sidecar};

/// One cycle's row as the sweep loop records it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// The set-point sent [N m] (after the drive's rounding and clamping).
    pub torque_setpoint_nm: f64,
    /// Motor position [rad].
    pub position_rad: f64,
    /// Motor velocity [rad/s].
    pub velocity_rad_s: f64,
    /// Torque actual [N m].
    pub torque_actual_nm: f64,
}

/// Where the sweep loop puts every recorded row, once (row `k` is cycle `k`): the loop keeps
/// no copy of its own. Implementations must not allocate per row (they size their storage
/// for the plan up front): `push` runs in the real-time cycle.
pub trait RowSink {
    /// Row `k`: a new row, or a row already pushed, rewritten (a row recorded from a lost
    /// feedback, filled once the fresh row after it has come: [`crate::stale_fill`]).
    fn push(&mut self, k: usize, row: &Row);
}

/// The rows in four columns, for [`crate::run_sweep`]'s recording.
#[derive(Debug, Clone, Default)]
pub struct RecordedRows {
    torque: Vec<f64>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    torque_actual: Vec<f64>,
}

impl RecordedRows {
    /// Room for `n` rows.
    pub fn with_capacity(n: usize) -> Self {
        RecordedRows {
            torque: Vec::with_capacity(n),
            position: Vec::with_capacity(n),
            velocity: Vec::with_capacity(n),
            torque_actual: Vec::with_capacity(n),
        }
    }

    /// The recording of these rows at `fs` [Hz] with `sidecar`.
    pub fn into_recording(self, fs: f64, sidecar: Sidecar) -> Recording {
        Recording {
            time_s: (0..self.torque.len()).map(|k| k as f64 / fs).collect(),
            torque_cmd_nm: self.torque,
            position_rad: Some(self.position),
            velocity_rad_s: Some(self.velocity),
            acceleration_rad_s2: None,
            torque_actual_nm: Some(self.torque_actual),
            sample_rate_hz: fs,
            sidecar,
        }
    }
}

impl RowSink for RecordedRows {
    /// Row `k` appended, or rewritten when already there (a filled held row).
    fn push(&mut self, k: usize, row: &Row) {
        let values = [
            (&mut self.torque, row.torque_setpoint_nm),
            (&mut self.position, row.position_rad),
            (&mut self.velocity, row.velocity_rad_s),
            (&mut self.torque_actual, row.torque_actual_nm),
        ];
        for (column, v) in values {
            match column.get_mut(k) {
                Some(old) => *old = v,
                None => column.push(v),
            }
        }
    }
}
