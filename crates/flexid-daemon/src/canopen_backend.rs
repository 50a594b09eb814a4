//! The CANopen [`AxisBackend`]: the sweep library ([`flexid_sweep::run_sweep`]) over a
//! CiA 402 drive on the axis's bus (`[[bus]]` udp or socketcan), brought up, enabled, run,
//! ramped to zero and disabled on a plain OS thread of its own (never on the async
//! runtime; `SCHED_FIFO` and locked memory when the service has the rights and the axis
//! runs in real time).
//!
//! While the sweep runs, the drive is wrapped in a [`Tap`] that stores every row into a
//! pre-allocated [`PeriodRows`] and enforces the position window; after every period the
//! sweep's progress hook publishes the rows and a relay thread ([`spawn_relay`]) sends
//! them with the FRF estimate so far, so the daemon streams them to disk and the clients
//! see a Bode update per period, exactly as with the simulated backend. The final
//! recording's sidecar carries the cycle timing (`cycle_timing`: wake-up lateness, late
//! wake-ups, overruns) beside the exchange counters (late and lost TPDOs).
use super::backend::{
    AbortSignal, AxisBackend, BackendError, Outcome, SweepEvent, SweepHandle, SweepPlan,
};
use super::canopen_tap::Tap;
use super::config::{AxisConfig, BusConfig, BusKind, ClockKind};
use super::period_relay::{spawn_relay, PeriodRows, RelayPlan};
use flexid_can::{CanBus, UdpConfig, UdpMulticastBus};
use flexid_canopen::{bring_up, MasterConfig, ProfileSet};
use flexid_core::frf::{FrfKind, PeriodicEstimator};
use flexid_files::recording::CycleTiming;
use flexid_rt::{clock, RtGranted, RtSetup};
use flexid_sweep::{admission_check, run_sweep, Pacing, StopReason};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;

/// `SCHED_FIFO` priority asked for the cycle thread of a real-time axis.
pub const CYCLE_FIFO_PRIORITY: u8 = 80;

/// Runs sweeps on CiA 402 drives.
pub struct CanopenBackend {
    buses: HashMap<String, BusConfig>,
    profiles: ProfileSet,
}

impl CanopenBackend {
    /// A backend for the configured buses with the built-in firmware profiles.
    pub fn new(buses: &[BusConfig]) -> Self {
        CanopenBackend {
            buses: buses.iter().map(|b| (b.name.clone(), b.clone())).collect(),
            profiles: ProfileSet::builtin(),
        }
    }
}

impl CanopenBackend {
    /// Starts `plan` on `axis` over the bus `open` returns (called on the cycle thread with
    /// the axis's `[[bus]]`): the seam for buses that are not in the configuration, e.g. a
    /// test's bus that fails on purpose. An error of `open` ends the sweep as failed before
    /// the motor moves.
    pub fn start_on<B, F>(
        &self,
        axis: &AxisConfig,
        plan: SweepPlan,
        open: F,
    ) -> Result<SweepHandle, BackendError>
    where
        B: CanBus + 'static,
        F: FnOnce(&BusConfig) -> Result<B, String> + Send + 'static,
    {
        let bus = self
            .buses
            .get(&axis.bus)
            .cloned()
            .ok_or_else(|| BackendError::Unavailable {
                axis: axis.name.clone(),
                reason: format!("no bus {:?}", axis.bus),
            })?;
        admission_check(axis.cycle_hz, bus.bitrate).map_err(|e| BackendError::Plan {
            axis: axis.name.clone(),
            reason: e.to_string(),
        })?;
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
        sp.max_duration = Some(Duration::from_secs_f64(
            axis.limits.max_sweep_s.max(sp.duration_s()) + 5.0,
        ));
        let (tx, rx) = mpsc::channel(256);
        let abort = AbortSignal::default();
        let job = Job {
            axis: axis.clone(),
            bus,
            plan: sp,
            abort: abort.clone(),
            tx,
            profiles: self.profiles.clone(),
            rows: Arc::new(PeriodRows::new(rows_total, blocks)),
            relay: Some(RelayPlan {
                period_samples: if periodic { info.period_samples } else { 0 },
                sample_rate_hz: plan.sample_rate_hz,
                estimator,
            }),
        };
        std::thread::Builder::new()
            .name(format!("cycle-{}", axis.name))
            .spawn(move || job.run(open))
            .map_err(|e| BackendError::Unavailable {
                axis: axis.name.clone(),
                reason: format!("cannot start the cycle thread: {e}"),
            })?;
        Ok(SweepHandle { events: rx, abort })
    }
}

impl AxisBackend for CanopenBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        match self.buses.get(&axis.bus).map(|b| b.kind) {
            Some(BusKind::Socketcan) => self.start_on(axis, plan, |bus: &BusConfig| {
                let iface = bus.interface.clone().unwrap_or_default();
                flexid_can::SocketCanBus::open(&iface)
                    .map_err(|e| format!("bus {} ({iface}): {e}", bus.name))
            }),
            _ => self.start_on(axis, plan, open_udp),
        }
    }
}

/// Opens a `kind = "udp"` bus of the configuration.
pub fn open_udp(bus: &BusConfig) -> Result<UdpMulticastBus, String> {
    let mut cfg = UdpConfig::default();
    if let Some(g) = bus.group {
        cfg.group = g;
    }
    if let Some(p) = bus.port {
        cfg.port = p;
    }
    UdpMulticastBus::open(cfg).map_err(|e| format!("bus {}: {e}", bus.name))
}

struct Job {
    axis: AxisConfig,
    bus: BusConfig,
    plan: flexid_sweep::SweepPlan,
    abort: AbortSignal,
    tx: mpsc::Sender<SweepEvent>,
    profiles: ProfileSet,
    rows: Arc<PeriodRows>,
    relay: Option<RelayPlan>,
}

impl Job {
    fn run<B: CanBus, F: FnOnce(&BusConfig) -> Result<B, String>>(mut self, open: F) {
        let r = open(&self.bus).and_then(|b| self.measure(b));
        if let Err(reason) = r {
            let _ = self.tx.blocking_send(SweepEvent::Ended {
                outcome: Outcome::Failed,
                reason,
                recording: None,
            });
        }
    }

    /// Bring-up and enable errors are returned (the motor has not moved); after enable the
    /// outcome is always sent.
    fn measure<B: CanBus>(&mut self, bus: B) -> Result<(), String> {
        let cfg = MasterConfig {
            node: self.axis.node,
            cycle_period: self.plan.period(),
            bitrate: self.bus.bitrate,
            ..MasterConfig::for_node(self.axis.node)
        };
        let drive = bring_up(bus, cfg, &self.profiles).map_err(|e| format!("bring-up: {e}"))?;
        let mut drive = drive.enable().map_err(|e| format!("enable: {e}"))?;
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
            &self.rows,
            self.abort.flag(),
            self.axis.limits.position_window_rad,
            realtime,
        );
        let outcome = run_sweep(&mut tap, &self.plan, self.abort.flag(), &mut progress);
        let window_trip = tap.window_trip_rad;
        let stats = std::mem::replace(&mut tap.stats, flexid_rt::TimingStats::new(1));
        drop(tap);
        if let Err(e) = drive.disable() {
            tracing::warn!("axis {}: disabling the drive: {e}", self.axis.name);
        }
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
        let mut recording = outcome.recording;
        let sc = &mut recording.sidecar;
        if let Some(end) = sc.end.as_mut() {
            end.reason = reason.clone();
        }
        if kind != Outcome::Completed {
            sc.ended_because = Some(reason.clone());
        }
        sc.source = Some(format!(
            "flexid daemon: axis {} (node {} on bus {})",
            self.axis.name, self.axis.node, self.bus.name
        ));
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
        Ok(())
    }
}
