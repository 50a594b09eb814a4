//! What a sweep will do: the excitation, the pacing and the limits; the bus-load admission.

use flexid_canopen::pdo::{check_bus_load, default_mapping, BusLoadError};
use flexid_canopen::profile::ObjectMap;
use flexid_canopen::MasterConfig;
use flexid_core::excitation::{ExcitationInfo, Multisine};
use std::time::Duration;

/// How cycles are paced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// Absolute deadlines at the cycle rate on the monotonic clock: SYNC k at
    /// `t0 + k / cycle_hz`, its feedback awaited until the next one.
    Realtime,
    /// The next cycle as soon as this one's feedback is in (a simulated drive in
    /// lock-step: deterministic, faster than real time).
    Lockstep,
}

impl Pacing {
    /// `realtime` / `lockstep`.
    pub fn name(self) -> &'static str {
        match self {
            Pacing::Realtime => "realtime",
            Pacing::Lockstep => "lockstep",
        }
    }
}

/// A planned sweep.
#[derive(Debug, Clone)]
pub struct SweepPlan {
    /// Cycle rate [Hz] (the drive's SYNC rate; the recording's sample rate).
    pub cycle_hz: f64,
    /// The torque set-point of every cycle [N m].
    pub torque_nm: Vec<f64>,
    /// Its description (as `flexid excite` writes it), copied into the sidecar.
    pub excitation: ExcitationInfo,
    /// Pacing of the cycles.
    pub pacing: Pacing,
    /// Cycles over which the torque is ramped to zero at the end (not recorded).
    pub ramp_cycles: usize,
    /// Stop when |motor velocity| exceeds this [rad/s].
    pub max_speed_rad_s: f64,
    /// Stop after this much wall time (none: no limit).
    pub max_duration: Option<Duration>,
    /// Stop when more feedback messages than this are lost (never arrive).
    pub max_lost_tpdos: u64,
    /// Lock-step: how long one cycle's feedback is awaited.
    pub feedback_timeout: Duration,
}

impl SweepPlan {
    /// A plan with the default limits: ramp over 10 ms (at least 5 cycles), speed limit
    /// 100 rad/s, duration 3 x the planned one + 10 s, lost-feedback budget 0.5 % of the
    /// cycles (at least 20), lock-step feedback timeout 50 ms (at least 10 cycles).
    pub fn new(
        cycle_hz: f64,
        torque_nm: Vec<f64>,
        excitation: ExcitationInfo,
        pacing: Pacing,
    ) -> Self {
        let planned_s = torque_nm.len() as f64 / cycle_hz;
        let cycles = torque_nm.len() as u64;
        SweepPlan {
            cycle_hz,
            ramp_cycles: ((0.01 * cycle_hz).round() as usize).max(5),
            max_speed_rad_s: 100.0,
            max_duration: Some(Duration::from_secs_f64(3.0 * planned_s + 10.0)),
            max_lost_tpdos: (cycles / 200).max(20),
            feedback_timeout: Duration::from_secs_f64((10.0 / cycle_hz).max(0.05)),
            torque_nm,
            excitation,
            pacing,
        }
    }

    /// [`SweepPlan::new`] of `ms` repeated `transient_periods + periods` times, each
    /// set-point rounded to the grid a drive takes them on, `steps_per_nm` steps per N m
    /// (CiA 402: one per mille of the rated torque, `1000 / rated`), so that the
    /// set-points sent are the ones planned.
    pub fn from_multisine(
        cycle_hz: f64,
        ms: &Multisine,
        periods: usize,
        transient_periods: usize,
        steps_per_nm: f64,
        pacing: Pacing,
    ) -> Self {
        let torque = ms
            .repeat(periods + transient_periods)
            .iter()
            .map(|t| (t * steps_per_nm).round() / steps_per_nm)
            .collect();
        SweepPlan::new(
            cycle_hz,
            torque,
            ms.info(periods, transient_periods),
            pacing,
        )
    }

    /// Cycle period.
    pub fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.cycle_hz)
    }

    /// Planned duration at the cycle rate [s] (without the ramp).
    pub fn duration_s(&self) -> f64 {
        self.torque_nm.len() as f64 / self.cycle_hz
    }
}

/// Heartbeat periods of the default master configuration (the master's and the drive's),
/// as the bus-load check counts them.
pub fn default_heartbeats() -> [Duration; 2] {
    let c = MasterConfig::default();
    [c.heartbeat_period, c.drive_heartbeat_period]
}

/// Admission: the bus load of the default PDO mapping (RPDO1, TPDO1, TPDO2 and SYNC every
/// cycle, plus heartbeats) at `cycle_hz` on `bitrate` must stay within the master's
/// admissible load (70 %). Returns the load, or the refusal whose message says which
/// cycle rate or bitrate would fit. Touches no bus.
pub fn admission_check(cycle_hz: f64, bitrate: u32) -> Result<f64, BusLoadError> {
    let mapping = default_mapping(&ObjectMap::default());
    check_bus_load(
        &mapping,
        &default_heartbeats(),
        cycle_hz,
        bitrate,
        MasterConfig::default().max_bus_load,
    )
}
