//! The seam between the daemon and whatever drives an axis: [`AxisBackend`].
//!
//! The daemon validates a request, plans the excitation ([`SweepPlan`]) and only then
//! calls [`AxisBackend::start`]; a refused request never reaches the backend. The backend
//! runs the cycle loop on its own thread and reports through the [`SweepHandle`]'s channel:
//! one [`SweepEvent::Period`] per completed excitation period (with that period's raw
//! samples and the FRF estimate so far), then exactly one [`SweepEvent::Ended`]. The
//! daemon streams the samples to disk, forwards the estimates to the clients, analyses the
//! recording and publishes the model.

use super::config::AxisConfig;
use flexid_core::excitation::ExcitationInfo;
use flexid_core::frf::Frf;
use flexid_files::recording::Recording;
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use tokio::sync::mpsc;

/// Errors of starting a sweep (the motor has not moved).
#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    /// The axis cannot be driven now (bus down, drive in fault, not wired, ...).
    #[error("axis {axis}: {reason}")]
    Unavailable { axis: String, reason: String },
    /// The plan is not runnable on this axis (e.g. the cycle rate differs).
    #[error("axis {axis}: {reason}")]
    Plan { axis: String, reason: String },
}

/// A validated, planned sweep: exactly the torque sequence to apply, one value per cycle.
#[derive(Debug, Clone)]
pub struct SweepPlan {
    /// The sweep id (names the results directory).
    pub sweep_id: String,
    /// Cycle rate = sample rate [Hz] (the axis's `cycle_hz`).
    pub sample_rate_hz: f64,
    /// Torque command per cycle [N m]: `(transient_periods + periods) * period_samples`
    /// values, `|torque| <= amplitude_nm <= limits.peak_torque_nm`.
    pub torque_nm: Vec<f64>,
    /// Description of the excitation (periods, lines, band), written to the sidecar.
    pub info: ExcitationInfo,
    /// The two amplitude levels [N m] requested for a later gap diagnosis, if any (the
    /// backend records them; the simulated backend does not act on them).
    pub levels_nm: Option<[f64; 2]>,
}

impl SweepPlan {
    /// Total periods including the transient ones.
    pub fn total_periods(&self) -> usize {
        self.info.periods + self.info.transient_periods
    }

    /// Planned duration [s].
    pub fn duration_s(&self) -> f64 {
        self.torque_nm.len() as f64 / self.sample_rate_hz
    }
}

/// Samples of one period, as they were measured.
#[derive(Debug, Clone, Default)]
pub struct SampleBlock {
    /// Index of the first sample in the whole sweep.
    pub first_sample: usize,
    /// Commanded torque [N m].
    pub torque_cmd_nm: Vec<f64>,
    /// Motor position [rad].
    pub position_rad: Vec<f64>,
    /// Motor velocity [rad/s].
    pub velocity_rad_s: Vec<f64>,
    /// Torque actual [N m].
    pub torque_actual_nm: Vec<f64>,
}

/// Cycle counters reported with every period.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Counters {
    /// Cycles run so far.
    pub cycles: u64,
    /// Cycles whose feedback arrived after the deadline.
    pub late: u64,
    /// Cycles without feedback.
    pub lost: u64,
    /// When the period ended on the cycle thread: `CLOCK_MONOTONIC` [ns]
    /// ([`flexid_rt::clock::now_ns`], comparable across processes on the host), for the
    /// latency from a period's end to its Bode update on the event stream.
    pub period_end_mono_ns: u64,
}

/// How a sweep ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// The planned excitation ran to its end.
    Completed,
    /// Stopped on request (operator abort, daemon shutdown): torque ramped to zero.
    Aborted,
    /// Stopped by a limit or a fault (speed, position window, drive fault, bus error).
    Failed,
    /// The daemon died while the sweep ran (found at the next start).
    Interrupted,
}

/// What a running sweep reports.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one Ended per sweep; boxing buys nothing
pub enum SweepEvent {
    /// Period `index` (0-based, transient periods included) is complete.
    Period {
        index: usize,
        /// The period's raw samples, contiguous with the previous block. A backend that
        /// cannot stream rows sends an empty block; the daemon then writes the rows from
        /// the final recording (and a crash loses the whole sweep's data).
        samples: SampleBlock,
        /// The FRF estimate over the steady periods so far (`None` during the transient).
        frf_so_far: Option<Arc<Frf>>,
        /// Sweep time at the end of this period [s] (samples / cycle rate).
        elapsed_s: f64,
        counters: Counters,
    },
    /// The sweep is over (always the last event; the motor is at rest, torque zero).
    Ended {
        outcome: Outcome,
        /// Why, for people: `"completed"`, `"operator abort"`, `"speed limit: ..."`.
        reason: String,
        /// The whole recording as measured (possibly partial), with its sidecar.
        recording: Option<Recording>,
    },
}

/// Requests a running sweep to stop: the backend ramps the torque to zero, ends the sweep
/// with [`Outcome::Aborted`] and the given reason, and keeps the recording.
#[derive(Debug, Clone, Default)]
pub struct AbortSignal {
    flag: Arc<AtomicBool>,
    reason: Arc<std::sync::Mutex<Option<String>>>,
}

impl AbortSignal {
    /// Ask the sweep to stop, e.g. with `"operator abort"`. The first reason wins.
    pub fn abort(&self, reason: &str) {
        if let Ok(mut r) = self.reason.lock() {
            r.get_or_insert_with(|| reason.to_string());
        }
        self.flag.store(true, Ordering::Release);
    }

    /// Has a stop been requested? (cheap: one atomic load, for the cycle loop)
    pub fn is_aborted(&self) -> bool {
        self.flag.load(Ordering::Acquire)
    }

    /// The flag itself, for loops that poll an `AtomicBool` (e.g. `flexid_sweep::run_sweep`).
    pub fn flag(&self) -> &AtomicBool {
        &self.flag
    }

    /// The reason given to [`abort`](Self::abort).
    pub fn reason(&self) -> Option<String> {
        self.reason.lock().ok().and_then(|r| r.clone())
    }
}

/// A started sweep.
#[derive(Debug)]
pub struct SweepHandle {
    /// Progress events; the last one is [`SweepEvent::Ended`], then the channel closes.
    pub events: mpsc::Receiver<SweepEvent>,
    /// Stops the sweep.
    pub abort: AbortSignal,
}

/// Something that can run sweeps on the configured axes.
///
/// `start` must return quickly (spawn the cycle loop on its own thread) and must not move
/// the motor when it returns an error. Implementations: [`super::sim_backend::SimBackend`]
/// (a simulated chain) and [`super::canopen_backend::CanopenBackend`] (the CANopen sweep,
/// `flexid_sweep`, on CiA 402 drives).
pub trait AxisBackend: Send + Sync + 'static {
    /// Start `plan` on `axis`.
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError>;
}
