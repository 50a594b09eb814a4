//! One measurement on one axis: the excitation streamed to a drive in cyclic synchronous
//! torque mode, every cycle recorded, the torque ramped to zero at the end.
//!
//! The loop runs over any [`flexid_canopen::CyclicDrive`] (a CANopen drive, or the CAN-free
//! [`SimulatedDrive`]) and knows no bus: `flexid sweep` brings the drive up, calls
//! [`run_sweep`], disables the drive and saves [`SweepOutcome::recording`].
//!
//! Pairing: the feedback answering SYNC k is the state *before* torque k acts, so row k
//! of the recording is `(torque_k, position_k)`, as in the recording format and
//! `flexid_core::sim`. The recorded torque is the set-point actually sent (after the drive's
//! per-mille rounding and clamping).
//!
//! Nothing is lost on a stop: a drive fault (EMCY, Fault state), feedback lost beyond the
//! budget, a speed above the limit, a bus error, the duration limit or an interrupt end
//! the loop with the rows measured so far and an [`RecordingEnd`] that says why.

mod losing;
mod multi;
mod plan;
mod rows;
mod run;
mod simulated;
pub mod stale_fill;

pub use losing::LosingDrive;
pub use multi::{
    run_multi_sweep, MultiAxisRecord, MultiProgress, MultiSweepOutcome, MultiSweepPlan,
};
pub use plan::{admission_check, default_heartbeats, Pacing, SweepPlan};
pub use rows::{RecordedRows, Row, RowSink};
pub use run::{
    realtime_setup, run_sweep, run_sweep_into, run_sweep_on_cycle_thread, GridPlacement, Progress,
    StopReason, SweepEnd, SweepOutcome,
};
pub use simulated::{SimulatedDrive, SimulatedFault, SimulatedPlant};

pub use flexid_core::recording::RecordingEnd;
