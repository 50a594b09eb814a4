use crate::excitation::ExcitationInfo;
use serde::{Deserialize, Serialize};

/// The `REC.json` sidecar written beside every recording.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// Sample rate [Hz]. Without it the rate is inferred from `time_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// The excitation that produced the recording.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub excitation: Option<ExcitationInfo>,
    /// Total inertia [kg m^2], if known from elsewhere (e.g. a transient test).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total_inertia_kgm2: Option<f64>,
    /// Delay between the torque command of sample k and its application, in whole samples,
    /// beyond the zero-order hold (e.g. 1 for a drive that applies a set-point at the next SYNC).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub io_delay_samples: Option<u32>,
    /// Where the data came from and what the columns mean, free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Why the recording ended, if not by completing the planned excitation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended_because: Option<String>,
    /// How a measurement on a drive (`flexid sweep`) ended: complete, or why not and at
    /// which cycle. Absent in files written before sweeps (and by simulations).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end: Option<RecordingEnd>,
    /// The drive the recording was measured on (identity, firmware profile, cycle).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<DriveInfo>,
    /// Counters of the cyclic exchange (late/lost feedback, clamped set-points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycle_counters: Option<CycleCounters>,
    /// Timing of the cycle thread (wake-up lateness, late wake-ups, overruns, real-time
    /// rights), written by the daemon's drive backend.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycle_timing: Option<CycleTiming>,
}

/// How a measurement ended (the sidecar's `end` object).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RecordingEnd {
    /// True when the planned excitation ran to its end.
    pub complete: bool,
    /// What happened (`"excitation complete"`, `"drive fault: ..."`, `"interrupted (Ctrl-C)"`, ...).
    pub reason: String,
    /// The cycle (0 = the first row) at which the measurement stopped; for a complete
    /// one, the number of rows.
    pub cycle: u64,
}

/// The drive a recording was measured on (the sidecar's `drive` object).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DriveInfo {
    /// The bus (`udp:239.74.163.2:43113`, `socketcan:vcan0`, `simulated`).
    #[serde(default)]
    pub bus: String,
    /// CANopen node-id.
    #[serde(default)]
    pub node: u8,
    /// 0x1000 device type.
    #[serde(default)]
    pub device_type: u32,
    /// 0x1018:1 vendor-id.
    #[serde(default)]
    pub vendor_id: u32,
    /// 0x1018:2 product code.
    #[serde(default)]
    pub product_code: u32,
    /// 0x1018:3 revision.
    #[serde(default)]
    pub revision: u32,
    /// 0x1018:4 serial number.
    #[serde(default)]
    pub serial: u32,
    /// The firmware profile used (name and file).
    #[serde(default)]
    pub profile: String,
    /// Rated torque [N m] (the unit of the set-points, per mille).
    #[serde(default)]
    pub rated_torque_nm: f64,
    /// Cycle rate [Hz].
    #[serde(default)]
    pub cycle_hz: f64,
    /// Pacing of the cycles: `realtime` or `lockstep`.
    #[serde(default)]
    pub clock: String,
}

/// Counters of the cyclic exchange over the whole measurement (the sidecar's
/// `cycle_counters`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CycleCounters {
    /// Cycles run (recorded rows plus the ramp to zero torque).
    #[serde(default)]
    pub cycles: u64,
    /// Feedback messages (TPDOs) missing at their cycle's deadline.
    #[serde(default)]
    pub missed: u64,
    /// Of those, arrived late.
    #[serde(default)]
    pub late: u64,
    /// Of those, never arrived.
    #[serde(default)]
    pub lost: u64,
    /// Set-points clamped to the drive's range.
    #[serde(default)]
    pub saturated: u64,
    /// Frames for this exchange that could not be decoded.
    #[serde(default)]
    pub malformed: u64,
    /// Cycles the master started more than half a period behind its schedule (a
    /// preempted or overloaded host, real-time pacing only); the schedule then restarts
    /// from that cycle instead of sending the missed SYNCs back to back.
    #[serde(default)]
    pub overruns: u64,
    /// Rows recorded without their own feedback (lost, or a cycle the drive went through
    /// holding its last torque: a late frame, a skipped slot), their motion interpolated
    /// from the rows either side and their torque the one the drive held.
    #[serde(default)]
    pub held_rows: u64,
    /// Frames that passed the drive one or more of its cycles after their row's (drives
    /// that count their cycles: EtherCAT's DC time).
    #[serde(default)]
    pub late_passes: u64,
    /// Frames that passed the drive in the cycle of the row before, whose set-point then
    /// replaced that row's (which never acted).
    #[serde(default)]
    pub replaced_setpoints: u64,
}

/// Percentiles of a set of durations, ns (percentiles within 0.4 %, max exact).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LatencySummary {
    /// Number of values.
    pub count: u64,
    /// Median, ns.
    pub p50_ns: u64,
    /// 99th percentile, ns.
    pub p99_ns: u64,
    /// 99.9th percentile, ns.
    pub p999_ns: u64,
    /// Maximum, ns (exact).
    pub max_ns: u64,
    /// Mean, ns (exact).
    pub mean_ns: f64,
}

/// Timing of the cycle thread over a measurement (the sidecar's `cycle_timing`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CycleTiming {
    /// `"realtime"` (absolute deadlines) or `"lockstep"` (as fast as the drive answers;
    /// no lateness is measured).
    pub pacing: String,
    /// Cycle rate [Hz].
    pub rate_hz: f64,
    /// Wake-up lateness after the deadline waited for, ns (real-time pacing only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lateness: Option<LatencySummary>,
    /// A wake-up later than this (10 % of the period), ns, counts as late.
    #[serde(default)]
    pub late_threshold_ns: u64,
    /// Wake-ups later than `late_threshold_ns`.
    #[serde(default)]
    pub late_wakeups: u64,
    /// Cycles started more than half a period behind the schedule (it then restarts).
    #[serde(default)]
    pub overruns: u64,
    /// `SCHED_FIFO` priority in effect, if granted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fifo_priority: Option<u8>,
    /// Whether the process memory was locked (`mlockall`).
    #[serde(default)]
    pub memory_locked: bool,
}

/// Which motion signal a recording's response columns hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionSignal {
    /// `position_rad`: encoder position [rad] (velocity is derived by backward difference).
    Position,
    /// `velocity_rad_s`: a measured velocity [rad/s].
    Velocity,
    /// `acceleration_rad_s2`: a measured acceleration [rad/s^2] (e.g. accelerometer data).
    Acceleration,
}

/// A recording in memory: uniformly sampled torque command and motion response.
///
/// Column names in `REC.csv`: `time_s`, `torque_cmd_nm`, `position_rad`, optional
/// `velocity_rad_s`, optional `acceleration_rad_s2`. At least one motion column is present.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// Sample times [s].
    pub time_s: Vec<f64>,
    /// Commanded motor torque [N m].
    pub torque_cmd_nm: Vec<f64>,
    /// Motor position [rad].
    pub position_rad: Option<Vec<f64>>,
    /// Motor velocity [rad/s] as recorded (not derived).
    pub velocity_rad_s: Option<Vec<f64>>,
    /// Acceleration [rad/s^2] as recorded.
    pub acceleration_rad_s2: Option<Vec<f64>>,
    /// Actual motor torque [N m] reported by the drive (`torque_actual_nm`), information
    /// only: the analysis uses the command.
    pub torque_actual_nm: Option<Vec<f64>>,
    /// Sample rate [Hz] (from the sidecar or inferred from `time_s`).
    pub sample_rate_hz: f64,
    /// The sidecar, or a default one if none was found.
    pub sidecar: Sidecar,
}

impl Recording {
    /// A recording of the torque command and the motor position [rad] at
    /// `sample_rate_hz`, sampled from `t = 0`, with the excitation's description (no
    /// velocity, acceleration or torque reading).
    pub fn of_position(
        sample_rate_hz: f64,
        torque_cmd_nm: Vec<f64>,
        position_rad: Vec<f64>,
        excitation: Option<crate::excitation::ExcitationInfo>,
    ) -> Recording {
        Recording {
            time_s: (0..torque_cmd_nm.len())
                .map(|k| k as f64 / sample_rate_hz)
                .collect(),
            torque_cmd_nm,
            position_rad: Some(position_rad),
            velocity_rad_s: None,
            acceleration_rad_s2: None,
            torque_actual_nm: None,
            sample_rate_hz,
            sidecar: Sidecar {
                sample_rate_hz: Some(sample_rate_hz),
                excitation,
                ..Sidecar::default()
            },
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.torque_cmd_nm.len()
    }

    /// True when the recording holds no samples.
    pub fn is_empty(&self) -> bool {
        self.torque_cmd_nm.is_empty()
    }

    /// The preferred motion signal for estimating the motor mobility: position (differenced)
    /// when present, else velocity, else acceleration.
    pub fn preferred_motion(&self) -> Option<(MotionSignal, &[f64])> {
        if let Some(p) = &self.position_rad {
            Some((MotionSignal::Position, p))
        } else if let Some(v) = &self.velocity_rad_s {
            Some((MotionSignal::Velocity, v))
        } else {
            self.acceleration_rad_s2
                .as_deref()
                .map(|a| (MotionSignal::Acceleration, a))
        }
    }
}
