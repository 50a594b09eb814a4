//! The CAN-free drive interface: what a sweep needs from a drive in cyclic synchronous
//! torque mode, whatever the fieldbus (CANopen here; EtherCAT CoE can implement it too).

use std::time::{Duration, Instant};

use crate::cia402::State;

/// One cycle's feedback, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feedback {
    /// Cycle number, from 0 at enable.
    pub cycle: u64,
    /// When the master sent this cycle's SYNC (caller's clock).
    pub sync_time: Instant,
    /// Statusword (0x6041) as received (the last one if this cycle's is missing).
    pub statusword: u16,
    /// The CiA 402 state it shows (`None`: a pattern outside the standard's table).
    pub state: Option<State>,
    /// Position actual, rad (multi-turn, unwrapped past the i32 range).
    pub position_rad: f64,
    /// Velocity actual, rad/s.
    pub velocity_rad_s: f64,
    /// Torque actual, N m.
    pub torque_nm: f64,
    /// The torque set-point actually sent, N m (after rounding to ‰ and clamping).
    pub torque_setpoint_nm: f64,
    /// The requested torque did not fit the set-point range and was clamped.
    pub saturated: bool,
    /// All of this cycle's feedback arrived before the deadline; if not, the missing
    /// values are the previous cycle's.
    pub fresh: bool,
    /// The drive's own cycle whose inputs this feedback holds, counted on the drive's clock
    /// (EtherCAT: SYNC0 pulses, from the DC system time the frame read as it passed), so
    /// the feedback can be placed where it belongs whenever the exchange came back; `None`
    /// where the bus does not say (CANopen: the SYNC is the master's own).
    pub drive_cycle: Option<u64>,
    /// Counters since enable.
    pub counters: Counters,
}

impl Feedback {
    /// A placeholder before any cycle (all zero, not fresh, SYNC time `at`): fills the
    /// slots a [`MultiAxisDrive::cycle`] writes.
    pub fn none(at: Instant) -> Self {
        Feedback {
            cycle: 0,
            sync_time: at,
            statusword: 0,
            state: None,
            position_rad: 0.0,
            velocity_rad_s: 0.0,
            torque_nm: 0.0,
            torque_setpoint_nm: 0.0,
            saturated: false,
            fresh: false,
            drive_cycle: None,
            counters: Counters::default(),
        }
    }
}

/// Counters of the cyclic exchange since enable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counters {
    /// Cycles run.
    pub cycles: u64,
    /// Feedback messages (TPDOs) missing at their cycle's deadline.
    pub missed: u64,
    /// Of those, arrived after the deadline (before the next cycle began).
    pub late: u64,
    /// Of those, never arrived (`missed - late`, counted when the next cycle begins).
    pub lost: u64,
    /// Set-points clamped to the drive's range.
    pub saturated: u64,
    /// Frames not for this exchange (other nodes, SDO, unknown COB-IDs, duplicates),
    /// ignored.
    pub ignored: u64,
    /// Frames for this exchange that could not be decoded (short PDO, EMCY not 8
    /// bytes, bad heartbeat), ignored.
    pub malformed: u64,
    /// CAN error frames received and tolerated (the error-frame policy).
    pub bus_errors: u64,
}

/// What kind of failure an error of a [`CyclicDrive`] is, whatever the fieldbus: the sweep's
/// stop reason is made from it ([`CyclicDrive::error_kind`]), so a CAN and an EtherCAT
/// cause read the same way in the report and the recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveErrorKind {
    /// The drive itself faulted or left its operating state (CiA 402 Fault, EMCY, NMT
    /// change; EtherCAT: an AL error such as a watchdog or DC out of sync).
    DriveFault,
    /// The drive's feedback stopped arriving in time (CAN: TPDOs lost; EtherCAT: missed
    /// cycles, frames lost).
    FeedbackLost,
    /// The bus or the line failed (CAN: bus off, error frames; EtherCAT: a SubDevice lost,
    /// a wrong working counter).
    Bus,
    /// Anything else the drive interface reports.
    Other,
}

/// A drive in cyclic synchronous torque mode, enabled. Fieldbus-independent.
pub trait CyclicDrive {
    /// The error type of the implementation.
    type Error: std::error::Error + Send + Sync + 'static;

    /// One cycle: sends the torque set-point (N m) and the synchronisation, then waits,
    /// at most until `deadline`, for the feedback of this cycle. Pace calls at the
    /// drive's cycle period.
    fn cycle(&mut self, torque_nm: f64, deadline: Instant) -> Result<Feedback, Self::Error>;

    /// The configured cycle period.
    fn cycle_period(&self) -> Duration;

    /// Rated torque, N m (the set-point range is about ±32 times it).
    fn rated_torque_nm(&self) -> f64;

    /// Counters since enable.
    fn counters(&self) -> Counters;

    /// Where a drive with a cycle clock of its own (EtherCAT's SYNC0, which latches the
    /// process data) wants the master's cycles to start: one instant of the grid of
    /// cycle starts, the others whole periods away. A real-time sweep starts its
    /// cycles on it. `None` (the default): the master's cycle is the drive's (CAN: the
    /// drive acts on the master's SYNC).
    fn cycle_grid(&self) -> Option<Instant> {
        None
    }

    /// Cycles from a set-point's cycle to the first feedback that shows it acting, when
    /// the cycles run on [`CyclicDrive::cycle_grid`] (EtherCAT: inputs and outputs latched
    /// at SYNC0, the frame between two pulses reads the inputs of the one before it: 1).
    /// The recording's I/O delay. Default 0 (the feedback of cycle k is the state before
    /// set-point k acts, as on CAN).
    fn grid_io_delay_cycles(&self) -> u32 {
        0
    }

    /// What kind of failure `error` is. The default, `None`, leaves the caller to find out
    /// by itself (the sweep downcasts the CANopen master's errors).
    fn error_kind(error: &Self::Error) -> Option<DriveErrorKind> {
        let _ = error;
        None
    }
}

/// Several drives in cyclic synchronous torque mode on one bus, enabled, whose set-points
/// act in the same cycle (one SYNC for all): the multi-axis measurement. Fieldbus-
/// independent.
pub trait MultiAxisDrive {
    /// The error type of the implementation.
    type Error: std::error::Error + Send + Sync + 'static;

    /// Number of axes `N`.
    fn axes(&self) -> usize;

    /// One cycle: sends every axis's torque set-point (`torques_nm`, N m, one per axis) and
    /// one synchronisation, then waits, at most until `deadline`, for every axis's
    /// feedback of this cycle, written to `out` (one per axis). Pace calls at the cycle
    /// period.
    fn cycle(
        &mut self,
        torques_nm: &[f64],
        deadline: Instant,
        out: &mut [Feedback],
    ) -> Result<(), Self::Error>;

    /// The configured cycle period.
    fn cycle_period(&self) -> Duration;

    /// Axis `axis`'s rated torque [N m].
    fn rated_torque_nm(&self, axis: usize) -> f64;

    /// Axis `axis`'s node address on its bus.
    fn node(&self, axis: usize) -> u8;
}
