//! The CANopen [`AxisBackend`]: the sweep library ([`crate::sweep::run_sweep`]) over a
//! CiA 402 drive on the axis's bus (`[[bus]]` udp or socketcan), brought up, enabled, run,
//! ramped to zero and disabled on a thread of its own.
//!
//! Limits: `run_sweep` reports progress without the rows, so this backend sends empty
//! sample blocks (the daemon writes the rows from the final recording, and no live Bode
//! estimate is available) until the sweep library streams each period's rows.

use super::backend::{
    AbortSignal, AxisBackend, BackendError, Counters, Outcome, SweepEvent, SweepHandle, SweepPlan,
};
use super::config::{AxisConfig, BusConfig, BusKind, ClockKind};
use crate::sweep::{admission_check, run_sweep, Pacing, StopReason};
use flexid_can::{CanBus, UdpConfig, UdpMulticastBus};
use flexid_canopen::{bring_up, MasterConfig, ProfileSet};
use std::collections::HashMap;
use std::time::Duration;
use tokio::sync::mpsc;

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

impl AxisBackend for CanopenBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
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
        let mut sp =
            crate::sweep::SweepPlan::new(plan.sample_rate_hz, plan.torque_nm, plan.info, pacing);
        sp.max_speed_rad_s = axis.limits.max_speed_rad_s;
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
        };
        std::thread::Builder::new()
            .name(format!("cycle-{}", axis.name))
            .spawn(move || job.run())
            .map_err(|e| BackendError::Unavailable {
                axis: axis.name.clone(),
                reason: format!("cannot start the cycle thread: {e}"),
            })?;
        Ok(SweepHandle { events: rx, abort })
    }
}

struct Job {
    axis: AxisConfig,
    bus: BusConfig,
    plan: crate::sweep::SweepPlan,
    abort: AbortSignal,
    tx: mpsc::Sender<SweepEvent>,
    profiles: ProfileSet,
}

impl Job {
    fn run(self) {
        let r = match self.bus.kind {
            BusKind::Udp => {
                let mut cfg = UdpConfig::default();
                if let Some(g) = self.bus.group {
                    cfg.group = g;
                }
                if let Some(p) = self.bus.port {
                    cfg.port = p;
                }
                UdpMulticastBus::open(cfg)
                    .map_err(|e| format!("bus {}: {e}", self.bus.name))
                    .and_then(|b| self.measure(b))
            }
            BusKind::Socketcan => {
                let iface = self.bus.interface.clone().unwrap_or_default();
                flexid_can::SocketCanBus::open(&iface)
                    .map_err(|e| format!("bus {} ({iface}): {e}", self.bus.name))
                    .and_then(|b| self.measure(b))
            }
        };
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
    fn measure<B: CanBus>(&self, bus: B) -> Result<(), String> {
        let cfg = MasterConfig {
            node: self.axis.node,
            cycle_period: self.plan.period(),
            bitrate: self.bus.bitrate,
            ..MasterConfig::for_node(self.axis.node)
        };
        let drive = bring_up(bus, cfg, &self.profiles).map_err(|e| format!("bring-up: {e}"))?;
        let mut drive = drive.enable().map_err(|e| format!("enable: {e}"))?;
        let period = self.plan.excitation.period_samples;
        let tx = self.tx.clone();
        let mut progress = |p: &crate::sweep::Progress| {
            if p.periods_done == 0 {
                return;
            }
            // never block the cycle loop: a full queue drops a progress event
            let _ = tx.try_send(SweepEvent::Period {
                index: p.periods_done - 1,
                samples: super::backend::SampleBlock {
                    first_sample: (p.periods_done - 1) * period,
                    ..Default::default()
                },
                frf_so_far: None,
                elapsed_s: p.elapsed.as_secs_f64(),
                counters: Counters {
                    cycles: p.cycle,
                    late: p.counters.late,
                    lost: p.counters.lost,
                },
            });
        };
        let outcome = run_sweep(&mut drive, &self.plan, self.abort.flag(), &mut progress);
        if let Err(e) = drive.disable() {
            tracing::warn!("axis {}: disabling the drive: {e}", self.axis.name);
        }
        let (kind, reason) = match &outcome.reason {
            StopReason::Complete => (Outcome::Completed, "completed".to_string()),
            StopReason::Interrupted => (
                Outcome::Aborted,
                self.abort.reason().unwrap_or_else(|| "abort".into()),
            ),
            other => (Outcome::Failed, other.text()),
        };
        let _ = self.tx.blocking_send(SweepEvent::Ended {
            outcome: kind,
            reason,
            recording: Some(outcome.recording),
        });
        Ok(())
    }
}
