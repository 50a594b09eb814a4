//! The sans-I/O drive core: frames and time in, frames out.
//!
//! [`VirtualDrive`] joins the CiA 301 slave ([`crate::slave`]), the CiA 402 state machine
//! ([`crate::cia402`]), the limits ([`crate::limits`]), the heartbeat timers
//! ([`crate::heartbeat`]) and the physics ([`crate::physics`]). Time is injected (`now`:
//! a monotonic [`Duration`] since any fixed epoch), so tests drive it without sleeping.
//!
//! Timing convention (the identification relies on it): RPDOs received during cycle `k`
//! are latched in the dictionary; on SYNC `k` the drive (1) samples the plant (position,
//! velocity, torque at the SYNC instant, before the new set-point acts), publishes the
//! sample and sends its TPDOs, then (2) applies the latched set-point and advances the
//! plant by one cycle (zero-order hold). TPDO `k` is the state before torque `k`, exactly
//! like `flexid_core::sim`. The controlword is evaluated as soon as it is received.

use std::time::Duration;

use canopen_rs::{Address, NmtState, Value};
use flexid_can::CanFrame;

use crate::cia402::{self, DeviceControl, State};
use crate::config::{ClockMode, DriveConfig};
use crate::heartbeat::{Consumer, Producer};
use crate::limits::{FaultKind, Limiter};
use crate::od::{self, idx, Od, OdDefaults};
use crate::physics::{AxisSample, Physics};
use crate::slave::{Slave, SlaveError, SlaveEvent};
use crate::sync_watch::{SyncWatch, LOCKSTEP_FLOOR};

/// Most frames one call can produce.
pub const MAX_OUTPUTS: usize = 8;

/// The frames to send after one call, in order. Fixed capacity, no heap.
#[derive(Debug, Clone, Copy, Default)]
pub struct Outputs {
    frames: [Option<CanFrame>; MAX_OUTPUTS],
    len: usize,
    dropped: usize,
}

impl Outputs {
    /// Appends a frame (`None` is skipped; beyond capacity the frame is counted as dropped).
    pub fn push(&mut self, frame: Option<CanFrame>) {
        let Some(f) = frame else { return };
        if self.len < MAX_OUTPUTS {
            self.frames[self.len] = Some(f);
            self.len += 1;
        } else {
            self.dropped += 1;
        }
    }

    /// The frames, in sending order.
    pub fn iter(&self) -> impl Iterator<Item = &CanFrame> + '_ {
        self.frames[..self.len].iter().flatten()
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there is nothing to send.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Frames that did not fit (a bug if ever non-zero).
    pub fn dropped(&self) -> usize {
        self.dropped
    }
}

/// Counters of a drive.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DriveStats {
    /// Frames handed to [`VirtualDrive::on_frame`].
    pub frames: u64,
    /// SYNCs processed.
    pub syncs: u64,
    /// Frames ignored as malformed (SYNC with DLC > 1, extended ids, error frames).
    pub ignored: u64,
    /// Plant cycles stepped.
    pub cycles: u64,
}

/// Errors building a drive.
#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    /// The CiA 301 slave could not be built.
    #[error("node {node_id}: {source}")]
    Slave {
        node_id: u8,
        #[source]
        source: SlaveError,
    },
    /// The cycle rate is not usable.
    #[error("cycle rate {cycle_hz} Hz must be positive and at most 1 MHz")]
    CycleRate { cycle_hz: f64 },
}

/// The simulated CiA 402 servo drive.
pub struct VirtualDrive<P: Physics> {
    cfg: DriveConfig,
    slave: Slave,
    dc: DeviceControl,
    limiter: Limiter,
    physics: P,
    producer: Producer,
    consumer: Consumer,
    sync_watch: SyncWatch,
    /// Whether the master has written 0x1006 since the last reset: only a period the
    /// master declared is supervised (the default is the plant file's, not the master's).
    sync_period_declared: bool,
    /// An RPDO of the wrong length was reported (EMCY once until a right one comes).
    pdo_length_error: bool,
    /// A SYNC of the wrong length was reported (EMCY once until a right one comes).
    sync_length_error: bool,
    fault: Option<FaultKind>,
    /// Torque held over the current cycle [N m].
    applied_nm: f64,
    limited: bool,
    velocity_integral: f64,
    last: AxisSample,
    ts: f64,
    inc_per_rad: f64,
    anchor: Option<Duration>,
    cycles_since_anchor: u64,
    /// The plant file's cycle rate (0x1006 default) [Hz].
    base_cycle_hz: f64,
    stats: DriveStats,
}

impl<P: Physics> VirtualDrive<P> {
    /// A powered-off drive in front of `physics` (which must step at `cfg.cycle_hz`).
    /// Call [`VirtualDrive::power_on`] to boot it.
    pub fn new(cfg: DriveConfig, mut physics: P) -> Result<Self, DriveError> {
        if !(cfg.cycle_hz.is_finite() && cfg.cycle_hz > 0.0 && cfg.cycle_hz <= 1e6) {
            return Err(DriveError::CycleRate {
                cycle_hz: cfg.cycle_hz,
            });
        }
        let mut slave = Slave::new(defaults(&cfg)).map_err(|source| DriveError::Slave {
            node_id: cfg.node_id,
            source,
        })?;
        slave.set_cycle_adjustable(physics.cycle_adjustable());
        let last = physics.sample();
        let base_cycle_hz = cfg.cycle_hz;
        let sync_watch = SyncWatch::new(cfg.sync_loss_cycles);
        Ok(Self {
            ts: 1.0 / cfg.cycle_hz,
            inc_per_rad: f64::from(cfg.encoder_increments_per_rev) / (2.0 * std::f64::consts::PI),
            limiter: Limiter::new(cfg.limits),
            cfg,
            slave,
            dc: DeviceControl::new(),
            physics,
            producer: Producer::default(),
            consumer: Consumer::default(),
            sync_watch,
            sync_period_declared: false,
            pdo_length_error: false,
            sync_length_error: false,
            fault: None,
            applied_nm: 0.0,
            limited: false,
            velocity_integral: 0.0,
            last,
            anchor: None,
            cycles_since_anchor: 0,
            base_cycle_hz,
            stats: DriveStats::default(),
        })
    }

    /// Power-on: boot-up frame (0x700 + id, `[0x00]`), timers started.
    pub fn power_on(&mut self, now: Duration) -> Outputs {
        let mut out = Outputs::default();
        self.boot(now, &mut out);
        out
    }

    /// Handles one received frame at `now`. Never panics, whatever the frame.
    pub fn on_frame(&mut self, frame: &CanFrame, now: Duration) -> Outputs {
        let mut out = Outputs::default();
        self.stats.frames += 1;
        if frame.is_error() || frame.id().is_extended() {
            self.stats.ignored += 1;
            return out;
        }
        let cob = frame.id().raw() as u16;
        let id = u16::from(self.cfg.node_id);
        if frame.is_remote() {
            if cob == 0x700 + id && self.slave.nmt() != NmtState::Initialising {
                out.push(self.slave.node_guard());
            }
            return out;
        }
        let data = frame.data();
        if self.consumer.enabled() && cob == 0x700 + u16::from(self.consumer.node()) {
            if data.len() == 1 {
                self.consumer.seen(now);
            }
            return out;
        }
        if cob == self.slave.sync_cob_id() {
            // no 0x1019 (counter overflow 0): a SYNC carries no data (CiA 301)
            if data.is_empty() {
                self.sync_length_error = false;
            } else if !self.sync_length_error {
                self.sync_length_error = true;
                self.warn(crate::slave::EMCY_SYNC_LENGTH, &mut out);
            }
            if data.len() <= 1 {
                self.sync_into(now, &mut out); // a counter byte: still a SYNC
            } else {
                self.stats.ignored += 1;
            }
            return out;
        }
        let nmt_before = self.slave.nmt();
        let (resp, ev) = self.slave.on_frame(cob, data);
        out.push(resp);
        match ev {
            SlaveEvent::None => {}
            SlaveEvent::Reset { communication_only } => {
                if let Err(e) = self.slave.reset(communication_only) {
                    tracing::error!("reset failed: {e}"); // the defaults built once already
                }
                // 0x1006 is back at its default: the plant file's cycle.
                if self.cfg.cycle_hz != self.base_cycle_hz {
                    self.change_cycle(self.base_cycle_hz);
                }
                if !communication_only {
                    self.reset_application();
                    self.boot(now, &mut out);
                    return out;
                }
                if let Some(k) = self.fault {
                    // The fault outlives a communication reset: keep 0x1001 showing it.
                    let reg = k.error_register().0 | canopen_rs::ErrorRegister::GENERIC;
                    od::set(
                        self.slave.od_mut(),
                        idx::ERROR_REGISTER,
                        Value::Unsigned8(reg),
                    );
                }
                self.boot(now, &mut out);
                // reset communication: the master's connection is gone
                self.abort_connection(&mut out);
            }
            SlaveEvent::Nmt(cmd) => {
                tracing::debug!(cmd, "NMT");
                // Stopped, or Operational left: no more set-points arrive (CiA 402 abort
                // connection).
                if cmd == 0x02 || (cmd == 0x80 && nmt_before == NmtState::Operational) {
                    self.abort_connection(&mut out);
                }
            }
            SlaveEvent::Rpdo => {
                self.pdo_length_error = false;
                self.on_controlword(&mut out);
            }
            SlaveEvent::RpdoLength { code, processed } => {
                if !self.pdo_length_error {
                    self.pdo_length_error = true;
                    self.warn(code, &mut out);
                }
                if processed {
                    self.on_controlword(&mut out);
                }
            }
            SlaveEvent::Written(a) => self.on_written(a, now, &mut out),
        }
        out
    }

    /// A SYNC at `now` (also reachable through [`VirtualDrive::on_frame`]).
    pub fn on_sync(&mut self, now: Duration) -> Outputs {
        let mut out = Outputs::default();
        self.sync_into(now, &mut out);
        out
    }

    /// Timers at `now`: heartbeat production, heartbeat consumer and SYNC-loss
    /// supervision.
    pub fn tick(&mut self, now: Duration) -> Outputs {
        let mut out = Outputs::default();
        if self.producer.due(now) {
            out.push(self.slave.heartbeat());
        }
        if self.fault.is_none()
            && self.dc.state().torque_enabled()
            && self.sync_watch.overdue(now, self.sync_window())
        {
            tracing::warn!(cycles = self.sync_watch.cycles(), "SYNC lost: torque off");
            self.raise(FaultKind::SyncLost, &mut out);
        }
        if self.fault.is_none()
            && self.dc.state() == State::OperationEnabled
            && self.consumer.overdue(now)
        {
            tracing::warn!("master heartbeat lost");
            self.raise(FaultKind::HeartbeatLost, &mut out);
        }
        out
    }

    /// When [`VirtualDrive::tick`] next has something to do.
    pub fn next_deadline(&self) -> Option<Duration> {
        // The consumer only matters while it can fault the drive (else a lost master
        // would leave a deadline in the past and a runner spinning on it).
        let supervised = self.fault.is_none() && self.dc.state() == State::OperationEnabled;
        let consumer = self.consumer.deadline().filter(|_| supervised);
        let sync = self
            .sync_watch
            .deadline(self.sync_window())
            .filter(|_| self.fault.is_none() && self.dc.state().torque_enabled());
        [self.producer.next_due(), consumer, sync]
            .into_iter()
            .flatten()
            .min()
    }

    /// The SYNC-loss window: `sync_loss_cycles` periods of 0x1006 as the master wrote it
    /// (`None`: off, or the master never declared its period), at least
    /// [`LOCKSTEP_FLOOR`] in lock-step.
    fn sync_window(&self) -> Option<Duration> {
        if !self.sync_period_declared {
            return None;
        }
        let us = od::get_u32(self.slave.od(), idx::CYCLE_PERIOD, 0).unwrap_or(0);
        let floor = match self.cfg.clock {
            ClockMode::LockStep => LOCKSTEP_FLOOR,
            ClockMode::RealTime => Duration::ZERO,
        };
        self.sync_watch
            .window(Duration::from_micros(u64::from(us)), floor)
    }

    /// The CiA 402 state.
    pub fn state(&self) -> State {
        self.dc.state()
    }

    /// The NMT state.
    pub fn nmt(&self) -> NmtState {
        self.slave.nmt()
    }

    /// The active fault, if any.
    pub fn fault(&self) -> Option<FaultKind> {
        self.fault
    }

    /// The torque held over the current cycle [N m].
    pub fn applied_torque_nm(&self) -> f64 {
        self.applied_nm
    }

    /// The last SYNC sample.
    pub fn last_sample(&self) -> AxisSample {
        self.last
    }

    /// The object dictionary.
    pub fn od(&self) -> &Od {
        self.slave.od()
    }

    /// The physics.
    pub fn physics(&self) -> &P {
        &self.physics
    }

    /// The configuration.
    pub fn config(&self) -> &DriveConfig {
        &self.cfg
    }

    /// Counters.
    pub fn stats(&self) -> DriveStats {
        self.stats
    }

    fn boot(&mut self, now: Duration, out: &mut Outputs) {
        out.push(self.slave.boot());
        self.sync_period_declared = false; // 0x1006 is back at its default
        let hb = od::get_u32(self.slave.od(), idx::HB_PRODUCER, 0).unwrap_or(0) as u16;
        self.producer.restart(hb, now);
        self.consumer
            .configure(od::get_u32(self.slave.od(), idx::HB_CONSUMER, 1).unwrap_or(0));
        self.publish(&self.last.clone());
    }

    fn reset_application(&mut self) {
        self.dc = DeviceControl::new();
        self.fault = None;
        self.limiter.reset();
        self.limited = false;
        self.velocity_integral = 0.0;
    }

    fn on_written(&mut self, a: Address, now: Duration, out: &mut Outputs) {
        match a.index {
            idx::CONTROLWORD => self.on_controlword(out),
            idx::HB_PRODUCER => {
                let ms = od::get_u32(self.slave.od(), idx::HB_PRODUCER, 0).unwrap_or(0) as u16;
                self.producer.restart(ms, now);
            }
            idx::HB_CONSUMER => self
                .consumer
                .configure(od::get_u32(self.slave.od(), idx::HB_CONSUMER, 1).unwrap_or(0)),
            idx::MODES => self.publish_status(),
            idx::CYCLE_PERIOD => {
                let us = od::get_u32(self.slave.od(), idx::CYCLE_PERIOD, 0).unwrap_or(0);
                self.sync_period_declared = us != 0;
                if us != 0 {
                    let hz = 1e6 / f64::from(us);
                    if (hz - self.cfg.cycle_hz).abs() > 1e-9 * hz && !self.change_cycle(hz) {
                        let old = (1e6 / self.cfg.cycle_hz).round() as u32;
                        od::set(
                            self.slave.od_mut(),
                            idx::CYCLE_PERIOD,
                            Value::Unsigned32(old),
                        );
                    }
                }
            }
            _ => {}
        }
    }

    /// Re-discretises the plant at `hz` (the master's 0x1006); false if it cannot.
    fn change_cycle(&mut self, hz: f64) -> bool {
        match self.physics.set_cycle_hz(hz) {
            Ok(()) => {
                tracing::info!(from = self.cfg.cycle_hz, to = hz, "cycle rate changed");
                self.cfg.cycle_hz = hz;
                self.ts = 1.0 / hz;
                self.anchor = None;
                self.cycles_since_anchor = 0;
                true
            }
            Err(e) => {
                tracing::error!("cycle rate {hz} Hz refused: {e}");
                false
            }
        }
    }

    fn on_controlword(&mut self, out: &mut Outputs) {
        let cw = od::get_u32(self.slave.od(), idx::CONTROLWORD, 0).unwrap_or(0) as u16;
        let cleared = self
            .fault
            .is_none_or(|k| self.limiter.cleared(k, self.last.velocity_rad_s));
        let before = self.dc.state();
        let after = self.dc.on_controlword(cw, cleared);
        if before == State::Fault && after != State::Fault {
            self.fault = None;
            od::set(self.slave.od_mut(), idx::ERROR_CODE, Value::Unsigned16(0));
            out.push(self.slave.error_reset());
        }
        if after == State::OperationEnabled && before != State::OperationEnabled {
            self.velocity_integral = 0.0;
            self.sync_watch.disarm(); // supervised from the next SYNC on
        }
        if before != after {
            tracing::debug!(?before, ?after, cw, "CiA 402");
        }
        self.publish_status();
    }

    /// The connection to the master is aborted (NMT Operational left, reset
    /// communication): with the power stage on, 0x6007 says what happens.
    fn abort_connection(&mut self, out: &mut Outputs) {
        use od::abort_connection as code;
        if !self.dc.state().torque_enabled() {
            return;
        }
        let option = od::get_i64(self.slave.od(), idx::ABORT_CONNECTION)
            .unwrap_or(i64::from(code::DISABLE_VOLTAGE)) as i16;
        tracing::warn!(option, "connection aborted while the power stage is on");
        match option {
            code::NO_ACTION => {}
            code::FAULT => self.raise(FaultKind::ConnectionAborted, out),
            code::QUICK_STOP => {
                self.dc.quick_stop();
                self.publish_status();
            }
            _ => {
                self.dc.disable_voltage();
                self.applied_nm = 0.0;
                self.limited = false;
                self.publish_status();
            }
        }
    }

    /// A communication EMCY that is no fault (wrong PDO or SYNC length): 0x1001 and
    /// 0x1003 record it; not sent in NMT stopped (CiA 301).
    fn warn(&mut self, code: u16, out: &mut Outputs) {
        tracing::warn!(code, "EMCY");
        let reg = canopen_rs::ErrorRegister(canopen_rs::ErrorRegister::COMMUNICATION);
        let emcy = self.slave.emergency(code, reg);
        if !matches!(self.slave.nmt(), NmtState::Stopped | NmtState::Initialising) {
            out.push(emcy);
        }
    }

    fn raise(&mut self, kind: FaultKind, out: &mut Outputs) {
        if self.fault.is_some() {
            return;
        }
        tracing::warn!(?kind, code = kind.emcy_code(), "fault");
        self.fault = Some(kind);
        self.dc.fault();
        // the reaction is immediate: no torque from now on, SYNC or not
        self.applied_nm = 0.0;
        self.limited = false;
        od::set(
            self.slave.od_mut(),
            idx::ERROR_CODE,
            Value::Unsigned16(kind.emcy_code()),
        );
        let emcy = self
            .slave
            .emergency(kind.emcy_code(), kind.error_register());
        // CiA 301: no EMCY in NMT stopped (0x1001 and 0x1003 still record it)
        if self.slave.nmt() != NmtState::Stopped {
            out.push(emcy);
        }
        self.publish_status();
        if kind.is_communication() {
            self.error_behaviour();
        }
    }

    /// CiA 301 0x1029:1: the NMT state after a communication error.
    fn error_behaviour(&mut self) {
        use od::error_behaviour as eb;
        let b = od::get_u32(self.slave.od(), idx::ERROR_BEHAVIOUR, 1).unwrap_or(0) as u8;
        match b {
            eb::PRE_OPERATIONAL if self.slave.nmt() == NmtState::Operational => {
                tracing::warn!("communication error: NMT pre-operational (0x1029:1 = 0)");
                self.slave.enter_nmt(0x80);
            }
            eb::STOPPED => {
                tracing::warn!("communication error: NMT stopped (0x1029:1 = 2)");
                self.slave.enter_nmt(0x02);
            }
            _ => {}
        }
    }

    fn sync_into(&mut self, now: Duration, out: &mut Outputs) {
        self.stats.syncs += 1;
        if self.dc.state().torque_enabled() {
            self.sync_watch.seen(now);
        } else {
            self.sync_watch.disarm();
        }
        if self.cfg.clock == ClockMode::RealTime {
            self.catch_up(now);
        }
        let s = self.physics.sample();
        self.last = s;
        if self.fault.is_none() {
            if let Some(k) = self.limiter.check_speed(s.velocity_rad_s) {
                self.raise(k, out);
            }
        }
        self.publish(&s);
        self.slave.sync_tpdos(|f| out.push(Some(f)));
        let t = self.setpoint(&s);
        self.physics.step(t);
        self.applied_nm = t;
        self.stats.cycles += 1;
        self.cycles_since_anchor += 1;
        if self.fault.is_none() {
            if let Some(k) = self.limiter.integrate_i2t(t, self.ts) {
                self.raise(k, out);
            }
        } else {
            let _ = self.limiter.integrate_i2t(t, self.ts);
        }
    }

    /// Real-time clock: step the plant (holding the torque) through the whole cycles of
    /// wall time elapsed since the first SYNC that it has not stepped yet.
    fn catch_up(&mut self, now: Duration) {
        let Some(anchor) = self.anchor else {
            self.anchor = Some(now);
            self.cycles_since_anchor = 0;
            return;
        };
        let due = (now.saturating_sub(anchor).as_secs_f64() / self.ts + 1e-6).floor() as u64;
        let extra = due.saturating_sub(self.cycles_since_anchor);
        let cap = self.cfg.cycle_hz.ceil() as u64; // one second
        if extra > cap {
            tracing::warn!(extra, "SYNC gap over 1 s: plant re-anchored, not caught up");
            self.anchor = Some(now);
            self.cycles_since_anchor = 0;
            return;
        }
        for _ in 0..extra {
            self.physics.step(self.applied_nm);
            self.stats.cycles += 1;
        }
        self.cycles_since_anchor += extra;
    }

    /// The torque for the coming cycle [N m] from the latched set-point, state and mode.
    fn setpoint(&mut self, s: &AxisSample) -> f64 {
        let od = self.slave.od();
        let rated = od::get_u32(od, idx::RATED_TORQUE, 0).unwrap_or(1000) as f64 / 1000.0;
        let max_t = od::get_u32(od, idx::MAX_TORQUE, 0).unwrap_or(0) as f64 * rated / 1000.0;
        match self.dc.state() {
            State::OperationEnabled => {
                let mode = od::get_i64(od, idx::MODES).unwrap_or(0) as i8;
                let want = match mode {
                    cia402::mode::CST | cia402::mode::PT => {
                        od::get_i64(od, idx::TARGET_TORQUE).unwrap_or(0) as f64 * rated / 1000.0
                    }
                    cia402::mode::CSV => {
                        let v = od::get_i64(od, idx::TARGET_VELOCITY).unwrap_or(0) as f64
                            / self.inc_per_rad;
                        self.velocity_pi(v, s.velocity_rad_s)
                    }
                    cia402::mode::CSP => {
                        let target = od::get_i64(od, idx::TARGET_POSITION).unwrap_or(0) as i32;
                        let actual = od::get_i64(od, idx::POSITION_ACTUAL).unwrap_or(0) as i32;
                        let err = f64::from(target.wrapping_sub(actual)) / self.inc_per_rad;
                        let v = self.cfg.position_kp * err;
                        self.velocity_pi(v, s.velocity_rad_s)
                    }
                    _ => 0.0,
                };
                let (t, limited) = self.limiter.clamp(want, max_t);
                self.limited = limited;
                t
            }
            State::QuickStopActive => {
                let step = self.cfg.quick_stop_slope_nm_per_s * self.ts;
                let t = if self.applied_nm.abs() <= step {
                    0.0
                } else {
                    self.applied_nm - step.copysign(self.applied_nm)
                };
                self.limited = false;
                if t == 0.0 {
                    self.dc.quick_stop_done();
                }
                t
            }
            _ => {
                self.limited = false;
                self.velocity_integral = 0.0;
                0.0
            }
        }
    }

    /// Velocity PI with a clamped integrator [N m].
    fn velocity_pi(&mut self, target_rad_s: f64, actual_rad_s: f64) -> f64 {
        let e = target_rad_s - actual_rad_s;
        let ki = self.cfg.velocity_ki;
        if ki > 0.0 {
            let bound = self.cfg.limits.peak_torque_nm / ki;
            self.velocity_integral = (self.velocity_integral + e * self.ts).clamp(-bound, bound);
        }
        self.cfg.velocity_kp * e + ki * self.velocity_integral
    }

    fn publish(&mut self, s: &AxisSample) {
        let rated =
            od::get_u32(self.slave.od(), idx::RATED_TORQUE, 0).unwrap_or(1000) as f64 / 1000.0;
        let pos = (s.position_rad * self.inc_per_rad).round() as i64 as i32;
        let vel = (s.velocity_rad_s * self.inc_per_rad).round() as i32;
        let tq = (s.torque_nm / rated * 1000.0).round() as i16;
        let od = self.slave.od_mut();
        od::set(od, idx::POSITION_ACTUAL, Value::Integer32(pos));
        od::set(od, idx::VELOCITY_ACTUAL, Value::Integer32(vel));
        od::set(od, idx::TORQUE_ACTUAL, Value::Integer16(tq));
        self.publish_status();
    }

    fn publish_status(&mut self) {
        let state = self.dc.state();
        let mode = od::get_i64(self.slave.od(), idx::MODES).unwrap_or(0) as i8;
        let sw = cia402::statusword(state, mode, self.limited);
        let od = self.slave.od_mut();
        od::set(od, idx::STATUSWORD, Value::Unsigned16(sw));
        od::set(od, idx::MODES_DISPLAY, Value::Integer8(mode));
    }
}

fn defaults(cfg: &DriveConfig) -> OdDefaults {
    let peak_permille = cfg.limits.peak_torque_nm / cfg.rated_torque_nm * 1000.0;
    OdDefaults {
        node_id: cfg.node_id,
        cycle_us: (1e6 / cfg.cycle_hz).round() as u32,
        heartbeat_ms: cfg.heartbeat_producer_ms,
        heartbeat_consumer: cfg.heartbeat_consumer,
        rated_torque_mnm: (cfg.rated_torque_nm * 1000.0).round() as u32,
        max_torque_permille: peak_permille.round().min(f64::from(u16::MAX)) as u16,
        mode: cia402::mode::CST,
    }
}
