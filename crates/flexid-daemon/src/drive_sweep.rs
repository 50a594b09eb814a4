//! One sweep on an enabled drive, the same for every backend: the sweep library's loop
//! ([`flexid_sweep::run_sweep_into`]) over any [`CyclicDrive`] (a CiA 402 drive on a bus,
//! or the CAN-free simulated drive), wrapped in a [`Tap`] that times the wake-ups and
//! enforces the position window. The rows go once into one sink, the pre-allocated
//! [`PeriodRows`]: after every period the sweep's progress hook publishes them and a relay
//! thread ([`spawn_relay`]) sends them with the FRF estimate so far (to the files and the
//! live Bode); the final recording is read back from the same rows. Its sidecar carries
//! the cycle timing beside the exchange counters.

use super::backend::{AbortSignal, BackendError, Outcome, SweepEvent, SweepHandle, SweepPlan};
use super::canopen_tap::Tap;
use super::config::{AxisConfig, ClockKind};
use super::period_relay::{spawn_relay, PeriodRows, RelayPlan, RowsSink};
use flexid_canopen::CyclicDrive;
use flexid_core::frf::{FrfKind, PeriodicEstimator};
use flexid_files::recording::{CycleTiming, Recording};
use flexid_rt::{clock, RtGranted, RtSetup};
use flexid_sweep::{run_sweep_into, Pacing, StopReason};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;

/// `SCHED_FIFO` priority asked for the cycle thread of a real-time axis.
pub const CYCLE_FIFO_PRIORITY: u8 = 80;

/// A planned sweep on one axis, waiting for its drive.
pub(crate) struct DriveJob {
    pub axis: AxisConfig,
    pub plan: flexid_sweep::SweepPlan,
    pub abort: AbortSignal,
    pub tx: mpsc::Sender<SweepEvent>,
    rows: Arc<PeriodRows>,
    relay: Option<RelayPlan>,
}

impl DriveJob {
    /// The sweep of `plan` on `axis` (pacing from its clock, its limits), and the handle
    /// the service follows it by.
    pub fn plan(axis: &AxisConfig, plan: SweepPlan) -> Result<(Self, SweepHandle), BackendError> {
        let pacing = match axis.clock {
            ClockKind::Monotonic => Pacing::Realtime,
            ClockKind::Simulated => Pacing::Lockstep,
        };
        let info = plan.info.clone();
        // every excitation the daemon plans repeats per period (multisine, chirp): the relay
        // cuts the published rows into periods whatever the sweep loop's reporting step
        let periodic = info.period_samples > 0;
        let estimator = if periodic {
            Some(
                PeriodicEstimator::new(
                    info.period_samples,
                    &info.excited_lines,
                    plan.sample_rate_hz,
                    FrfKind::DifferencedVelocity,
                )
                .map_err(|e| BackendError::Plan {
                    axis: axis.name.clone(),
                    reason: e.to_string(),
                })?
                .with_transient_periods(info.transient_periods),
            )
        } else {
            None
        };
        let rows_total = plan.torque_nm.len();
        // progress calls: one per period (multisine) or per second (other excitations)
        let blocks = rows_total / info.period_samples.max(1)
            + (rows_total as f64 / plan.sample_rate_hz).ceil() as usize
            + 2;
        let mut sp =
            flexid_sweep::SweepPlan::new(plan.sample_rate_hz, plan.torque_nm, plan.info, pacing);
        sp.max_speed_rad_s = axis.limits.max_speed_rad_s;
        if let Some(n) = axis.limits.max_lost_tpdos {
            sp.max_lost_tpdos = n;
        }
        // a limit beyond what a Duration holds is no limit (never a panic)
        sp.max_duration = Some(
            Duration::try_from_secs_f64(axis.limits.max_sweep_s.max(sp.duration_s()) + 5.0)
                .unwrap_or(Duration::MAX),
        );
        let (tx, rx) = mpsc::channel(256);
        let abort = AbortSignal::default();
        let job = DriveJob {
            axis: axis.clone(),
            plan: sp,
            abort: abort.clone(),
            tx,
            rows: Arc::new(PeriodRows::new(rows_total, blocks)),
            relay: Some(RelayPlan {
                period_samples: if periodic { info.period_samples } else { 0 },
                sample_rate_hz: plan.sample_rate_hz,
                estimator,
            }),
        };
        Ok((job, SweepHandle { events: rx, abort }))
    }

    /// Runs `job` on a thread of its own named `name` (never on the async runtime).
    pub fn spawn(
        name: String,
        axis: &str,
        job: impl FnOnce() + Send + 'static,
    ) -> Result<(), BackendError> {
        std::thread::Builder::new()
            .name(name)
            .spawn(job)
            .map(|_| ())
            .map_err(|e| BackendError::Unavailable {
                axis: axis.into(),
                reason: format!("cannot start the cycle thread: {e}"),
            })
    }

    /// The sweep ended before the motor moved (no drive, bring-up failed).
    pub fn failed(&self, reason: String) {
        let _ = self.tx.blocking_send(SweepEvent::Ended {
            outcome: Outcome::Failed,
            reason,
            recording: None,
        });
    }

    /// Runs the sweep loop on the enabled `drive`, hands it to `release` when the loop has
    /// ended (the CANopen drive is disabled there), and sends the outcome with the
    /// recording; `source` names the drive in the sidecar.
    pub fn run_on<D: CyclicDrive>(
        &mut self,
        mut drive: D,
        source: String,
        release: impl FnOnce(D),
    ) {
        let realtime = self.plan.pacing == Pacing::Realtime;
        let relay = match self.relay.take().map(|plan| {
            spawn_relay(
                &format!("relay-{}", self.axis.name),
                self.rows.clone(),
                plan,
                self.tx.clone(),
            )
        }) {
            Some(Ok(h)) => Some(h),
            Some(Err(e)) => {
                tracing::warn!(
                    "axis {}: no live periods (relay thread: {e}); rows are written at the end",
                    self.axis.name
                );
                None
            }
            None => None,
        };
        // after the relay is spawned: it must not inherit the cycle thread's SCHED_FIFO
        let granted = if realtime {
            RtSetup::realtime(CYCLE_FIFO_PRIORITY).apply()
        } else {
            RtGranted::default()
        };
        let rows = self.rows.clone();
        let relay_thread = relay.as_ref().map(|h| h.thread().clone());
        let mut progress = |p: &flexid_sweep::Progress| {
            rows.publish(
                p.cycle as usize,
                p.counters.late,
                p.counters.lost,
                clock::now_ns(),
            );
            if let Some(t) = &relay_thread {
                t.unpark();
            }
        };
        let mut tap = Tap::new(
            &mut drive,
            self.abort.flag(),
            self.axis.limits.position_window_rad,
            realtime,
        );
        let mut sink = RowsSink(&self.rows);
        let outcome = run_sweep_into(
            &mut tap,
            &self.plan,
            self.abort.flag(),
            &mut progress,
            &mut sink,
        );
        let window_trip = tap.window_trip_rad;
        let stats = std::mem::replace(&mut tap.stats, flexid_rt::TimingStats::new(1));
        drop(tap);
        release(drive);
        self.rows.finish();
        if let Some(h) = relay {
            h.thread().unpark();
            let _ = h.join();
        }
        let (kind, reason) = match (&outcome.reason, window_trip) {
            (StopReason::Complete, _) => (Outcome::Completed, "completed".to_string()),
            (StopReason::Interrupted, Some(at)) => (
                Outcome::Failed,
                format!(
                    "position window: {at:+.4} rad from the start, beyond +-{} rad",
                    self.axis.limits.position_window_rad
                ),
            ),
            (StopReason::Interrupted, None) => (
                Outcome::Aborted,
                self.abort.reason().unwrap_or_else(|| "abort".into()),
            ),
            (other, _) => (Outcome::Failed, other.text()),
        };
        // the recording is the rows of the one sink (what the relay streamed to disk)
        let rows = self.rows.columns(outcome.rows);
        let fs = self.plan.cycle_hz;
        // the columns of `flexid sweep` (flexid_sweep::RecordedRows): one format
        let mut recording = Recording {
            time_s: (0..rows.torque_cmd_nm.len())
                .map(|k| k as f64 / fs)
                .collect(),
            torque_cmd_nm: rows.torque_cmd_nm,
            position_rad: Some(rows.position_rad),
            velocity_rad_s: Some(rows.velocity_rad_s),
            acceleration_rad_s2: None,
            torque_actual_nm: Some(rows.torque_actual_nm),
            sample_rate_hz: fs,
            sidecar: outcome.sidecar,
        };
        let sc = &mut recording.sidecar;
        if let Some(end) = sc.end.as_mut() {
            end.reason = reason.clone();
        }
        if kind != Outcome::Completed {
            sc.ended_because = Some(reason.clone());
        }
        sc.source = Some(source);
        sc.cycle_timing = Some(CycleTiming {
            pacing: self.plan.pacing.name().into(),
            rate_hz: self.plan.cycle_hz,
            lateness: realtime.then(|| stats.lateness.summary()),
            late_threshold_ns: stats.late_threshold_ns,
            late_wakeups: stats.late_wakeups,
            overruns: outcome.overruns,
            fifo_priority: granted.fifo_priority,
            memory_locked: granted.memory_locked,
        });
        let _ = self.tx.blocking_send(SweepEvent::Ended {
            outcome: kind,
            reason,
            recording: Some(recording),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Limits;
    use crate::request::{parse_request, plan};
    use flexid_sweep::{LosingDrive, SimulatedPlant};

    /// The embedded plant's drive at `fs`, the same noise every time.
    fn drive(fs: f64) -> flexid_sweep::SimulatedDrive {
        let p = flexid_files::plant::load_plant_file(None).unwrap();
        SimulatedPlant::of_file(&p).drive(fs, 7).unwrap()
    }

    /// A lockstep sweep of `periods` multisine periods on `drive`: the period events' rows
    /// (what the daemon streams to the files and the live Bode) and the final recording.
    fn sweep<D: CyclicDrive>(
        d: D,
        fs: f64,
    ) -> (Vec<super::super::backend::SampleBlock>, Recording) {
        let axis = AxisConfig {
            name: "j1".into(),
            bus: "sim".into(),
            node: 1,
            profile: None,
            cycle_hz: fs,
            clock: ClockKind::Simulated,
            limits: Limits {
                peak_torque_nm: 2.0,
                max_speed_rad_s: 500.0,
                position_window_rad: 100.0,
                max_sweep_s: 60.0,
                max_lost_tpdos: None,
            },
        };
        let req = parse_request(
            br#"{"excitation":"multisine","band_hz":[2,300],"amplitude_nm":1,"periods":3,"duration_s":2}"#,
            &axis,
        )
        .unwrap();
        let (mut job, mut handle) = DriveJob::plan(&axis, plan(&req, &axis, "t").unwrap()).unwrap();
        job.run_on(d, "test".into(), |_| {});
        let mut periods = Vec::new();
        while let Ok(ev) = handle.events.try_recv() {
            match ev {
                SweepEvent::Period { samples, .. } => periods.push(samples),
                SweepEvent::Ended { recording, .. } => return (periods, recording.unwrap()),
            }
        }
        panic!("no end event");
    }

    /// Rows recorded from a lost feedback are filled before the daemon streams them: the
    /// periods sent live hold the same rows as the final recording, and a lost row is the
    /// linear interpolation of its fresh neighbours (which equal a run without loss),
    /// also when the lost row is the last of a period (published before the fresh row
    /// after it came).
    #[test]
    fn lost_feedback_is_filled_before_the_periods_are_streamed() {
        let fs = 1000.0;
        let (clean_periods, clean) = sweep(drive(fs), fs);
        let period = clean_periods[0].position_rad.len();
        let lose = vec![period - 1, 2 * period + 10, 2 * period + 11, 3 * period - 1];
        let (periods, rec) = sweep(LosingDrive::new(drive(fs), lose.clone()), fs);
        assert_eq!(periods.len(), clean_periods.len());
        let x = rec.position_rad.as_ref().unwrap();
        let x0 = clean.position_rad.as_ref().unwrap();
        let streamed: Vec<f64> = periods
            .iter()
            .flat_map(|p| p.position_rad.clone())
            .collect();
        assert_eq!(
            &streamed[..],
            &x[..streamed.len()],
            "streamed rows = recording"
        );
        for k in 0..x.len() {
            if lose.contains(&k) {
                let a = (0..k).rev().find(|j| !lose.contains(j)).unwrap();
                let b = (k + 1..x.len()).find(|j| !lose.contains(j)).unwrap();
                let w = (k - a) as f64 / (b - a) as f64;
                let lerp = x0[a] + w * (x0[b] - x0[a]);
                assert!(
                    (x[k] - lerp).abs() <= 1e-12 * lerp.abs().max(1.0),
                    "row {k}"
                );
                assert_ne!(x[k], x0[k - 1], "row {k} still holds the previous value");
            } else {
                assert_eq!(x[k], x0[k], "row {k}");
            }
        }
    }
}
