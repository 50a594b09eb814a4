//! Enable, the cycle, disable and quick stop: the blocking layer around
//! [`super::exchange::Exchange`].

use std::time::{Duration, Instant};

use flexid_can::CanBus;

use super::exchange::{Event, Exchange};
use super::{emcy_text, Configured, Drive, Enabled, Link, MasterError};
use crate::cia402::{next_controlword, Controlword, State, Statusword, Target};
use crate::cob;
use crate::drive::{Counters, CyclicDrive, Feedback};
use crate::objects::comm;
use crate::scaling::PositionUnwrap;

const NMT_START: u8 = 0x01;
/// Longest wait for one step's feedback in the CiA 402 walks (enable, disable, quick stop).
const WALK_FEEDBACK_WAIT: Duration = Duration::from_millis(20);
const NMT_ENTER_PRE_OPERATIONAL: u8 = 0x80;
/// Heartbeat state byte of an NMT stopped node (CiA 301).
const NMT_STATE_STOPPED: u8 = 0x04;

/// How strict one exchange is.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Mode {
    /// Enabled cycle: EMCYs and NMT state changes are errors.
    Strict,
    /// State-machine walks: EMCYs are remembered (the walk resets faults).
    Walk,
}

impl<B: CanBus> Link<B> {
    /// One SYNC cycle: heartbeat if due, drain what the previous cycle left, send RPDO1
    /// and SYNC, collect this cycle's TPDOs until `deadline`. Returns the SYNC time and
    /// whether the feedback is complete.
    fn exchange(
        &mut self,
        controlword: Controlword,
        torque_permille: i16,
        deadline: Instant,
        mode: Mode,
    ) -> Result<(Instant, bool), MasterError> {
        let sync = self.exchange_begin(controlword, torque_permille, mode, true)?;
        let sync_time = self.now();
        // frames that arrived before this instant answer an earlier SYNC (see exchange)
        self.exchange_sync_sent(sync_time);
        self.send(&sync, "sending SYNC")?;
        let complete = self.exchange_collect(deadline, mode)?;
        Ok((sync_time, complete))
    }

    /// The first phase of a cycle: the master heartbeat if due (and `heartbeat`), the
    /// drain of what the previous cycle left, RPDO1 sent. Returns the SYNC frame to send
    /// (by this link or, in a group, by the first drive's).
    pub(super) fn exchange_begin(
        &mut self,
        controlword: Controlword,
        torque_permille: i16,
        mode: Mode,
        heartbeat: bool,
    ) -> Result<flexid_can::CanFrame, MasterError> {
        let now = self.now();
        if heartbeat && self.next_heartbeat.is_none_or(|t| now >= t) {
            let f = flexid_can::CanFrame::standard(cob::heartbeat(self.cfg.master_node), &[0x05])
                .expect("1 byte");
            self.send(&f, "sending the master heartbeat")?;
            self.next_heartbeat = Some(now + self.cfg.heartbeat_period);
        }
        loop {
            match self.bus.recv_timeout(Duration::ZERO) {
                Ok(Some(r)) => {
                    let ev = self.exchange.on_frame(&r.frame, r.timestamp);
                    self.on_event(ev, mode)?;
                }
                Ok(None) => break,
                Err(source) => self.on_bus_error(source)?,
            }
        }
        let [rpdo, sync] = self.exchange.begin(controlword.0, torque_permille);
        self.send(&rpdo, "sending RPDO1")?;
        self.last_cw = controlword;
        Ok(sync)
    }

    /// The second phase: the SYNC goes out at `sync_time` (read just before sending it).
    pub(super) fn exchange_sync_sent(&mut self, sync_time: Instant) {
        self.exchange.sync_sent(sync_time);
        self.last_sync = Some(sync_time);
    }

    /// The last phase: this cycle's TPDOs until `deadline`; whether all came. Too many
    /// incomplete cycles in a row end the cycle in [`Mode::Strict`].
    pub(super) fn exchange_collect(
        &mut self,
        deadline: Instant,
        mode: Mode,
    ) -> Result<bool, MasterError> {
        let node = self.node();
        while !self.exchange.complete() {
            let left = deadline.saturating_duration_since(self.now());
            if left.is_zero() {
                break;
            }
            match self.bus.recv_timeout(left) {
                Ok(Some(r)) => {
                    let ev = self.exchange.on_frame(&r.frame, r.timestamp);
                    self.on_event(ev, mode)?;
                }
                Ok(None) => {}
                Err(source) => self.on_bus_error(source)?,
            }
        }
        let (complete, consecutive) = self.exchange.end();
        // In walks the state timeout bounds the time; in the cycle, missing feedback.
        if mode == Mode::Strict && consecutive >= self.cfg.missed_cycles_limit() {
            return Err(MasterError::TpdoLost { node, consecutive });
        }
        Ok(complete)
    }

    /// The set-point of `torque_nm` [N m] (finite, or an error), counted when clamped.
    pub(super) fn setpoint(
        &mut self,
        torque_nm: f64,
    ) -> Result<crate::scaling::TorqueSetpoint, MasterError> {
        if !torque_nm.is_finite() {
            return Err(MasterError::InvalidSetpoint {
                node: self.node(),
                torque_nm,
            });
        }
        let sp = self.scaling.torque_permille(torque_nm);
        if sp.saturated {
            self.exchange.counters.saturated += 1;
        }
        Ok(sp)
    }

    /// This cycle's feedback after its exchange (cycle number `cycle`, SYNC at
    /// `sync_time`, `fresh`), or the error its state shows.
    pub(super) fn feedback(
        &mut self,
        cycle: u64,
        sync_time: Instant,
        fresh: bool,
        sp: crate::scaling::TorqueSetpoint,
    ) -> Result<Feedback, MasterError> {
        let node = self.node();
        let state = self.state();
        match state {
            Some(s) if s.is_fault() => return Err(self.fault_error()),
            Some(State::OperationEnabled) | None => {}
            Some(s) => return Err(MasterError::Disabled { node, state: s }),
        }
        let t1 = self.exchange.tpdo1;
        let position = self.unwrap.update(t1.position);
        Ok(Feedback {
            cycle,
            sync_time,
            statusword: t1.statusword,
            state,
            position_rad: self.scaling.position_rad(position),
            velocity_rad_s: self.scaling.velocity_rad_s(self.exchange.tpdo2.velocity),
            torque_nm: self.scaling.torque_nm(t1.torque),
            torque_setpoint_nm: self.scaling.torque_nm(sp.permille),
            saturated: sp.saturated,
            fresh,
            drive_cycle: None,
            counters: self.exchange.counters,
        })
    }

    /// A bus error while receiving: tolerated (counted) or the end of the exchange, as
    /// the error-frame policy says.
    fn on_bus_error(&mut self, source: flexid_can::BusError) -> Result<(), MasterError> {
        use super::error_frames::Verdict;
        let node = self.node();
        match self.error_watch.on_error(&source, self.now()) {
            Verdict::Tolerate => {
                tracing::warn!(node, "{source} (tolerated)");
                if matches!(source, flexid_can::BusError::ErrorFrame { .. }) {
                    self.exchange.counters.bus_errors += 1;
                }
                Ok(())
            }
            Verdict::Burst { frames } => Err(MasterError::ErrorFrameBurst {
                node,
                frames,
                window: self.cfg.error_frames.window,
                max: self.cfg.error_frames.max_frames,
                last: source.to_string(),
            }),
            Verdict::Abort => Err(MasterError::Bus {
                node,
                during: "receiving feedback",
                source,
            }),
        }
    }

    fn on_event(&mut self, ev: Event, mode: Mode) -> Result<(), MasterError> {
        let node = self.node();
        match ev {
            Event::Emergency(m) => {
                self.last_emcy = Some(m);
                if mode == Mode::Strict {
                    return Err(MasterError::Emergency {
                        node,
                        error_code: m.error_code,
                        register: m.error_register.0,
                        data: m.vendor_specific,
                        text: emcy_text(m.error_code),
                    });
                }
            }
            Event::NmtState(state) => {
                self.drive_nmt = Some(state);
                if mode == Mode::Strict {
                    return Err(MasterError::NmtStateChanged { node, state });
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn state(&self) -> Option<State> {
        Statusword(self.exchange.tpdo1.statusword).state()
    }

    /// The fault error: code and register from the last EMCY, else from 0x603F/0x1001.
    fn fault_error(&mut self) -> MasterError {
        let node = self.node();
        let (error_code, register) = match self.last_emcy {
            Some(m) => (m.error_code, m.error_register.0),
            // a stopped node answers no SDO: nothing to read
            None if self.drive_nmt == Some(NMT_STATE_STOPPED) => (0, 0),
            None => {
                let code_index = self.profile.objects.error_code;
                let code = self.sdo.read_u16(code_index, 0).unwrap_or(0);
                let reg = self.sdo.read_u8(comm::ERROR_REGISTER, 0).unwrap_or(0);
                (code, reg)
            }
        };
        MasterError::Fault {
            node,
            error_code,
            register,
            text: emcy_text(error_code),
        }
    }

    /// Walks the CiA 402 state machine to `target`, one controlword per cycle, at the
    /// cycle period, torque 0. With `quick_stop_first`, sends Quick stop while the drive
    /// is in Operation enabled.
    fn walk(&mut self, target: Target, quick_stop_first: bool) -> Result<(), MasterError> {
        let node = self.node();
        let period = self.cfg.cycle_period;
        let limit = self.cfg.state_timeout;
        let start = self.now();
        // The state of the last feedback (a fresh exchange shows statusword 0, Not ready
        // to switch on: Disable voltage until the drive reports).
        let mut seen = self.state();
        loop {
            // A stopped node processes no PDO: walking it down can only time out.
            if target == Target::SwitchOnDisabled && self.drive_nmt == Some(NMT_STATE_STOPPED) {
                return Err(MasterError::NmtStopped { node });
            }
            let cw = match seen {
                None => Controlword::DISABLE_VOLTAGE,
                Some(State::OperationEnabled) if quick_stop_first => Controlword::QUICK_STOP,
                Some(s) => next_controlword(s, target),
            }
            .after(self.last_cw);
            // One SYNC per cycle period, from the last one sent (by an earlier walk or
            // the cycle).
            self.wait_for_slot();
            // Paced at the cycle period, but the feedback of a slow drive or bus (an
            // emulated machine, a loaded host) is awaited up to WALK_FEEDBACK_WAIT: a
            // TPDO that misses its cycle's deadline is stale and is never used.
            let cycle_start = self.now();
            let feedback_deadline = cycle_start + period.max(WALK_FEEDBACK_WAIT);
            let (_, _) = self.exchange(cw, 0, feedback_deadline, Mode::Walk)?;
            seen = self.state();
            if seen == Some(target.state()) {
                // The walk's last cycle lasts its whole period too: whoever sends the
                // next SYNC (the caller's first cycle) sends it a period after this one.
                self.wait_for_slot();
                return Ok(());
            }
            if self.now().duration_since(start) >= limit {
                if seen.is_some_and(State::is_fault) {
                    return Err(self.fault_error());
                }
                return Err(MasterError::StateMachine {
                    node,
                    target: target.state(),
                    last: match seen {
                        Some(s) => s.to_string(),
                        None => format!("statusword {:#06x}", self.exchange.tpdo1.statusword),
                    },
                    after: limit,
                });
            }
        }
    }

    /// Sleeps until one cycle period after the last SYNC sent (at once if none was, or
    /// if that time has passed).
    fn wait_for_slot(&self) {
        if let Some(last) = self.last_sync {
            let left = (last + self.cfg.cycle_period).saturating_duration_since(self.now());
            if !left.is_zero() {
                std::thread::sleep(left);
            }
        }
    }

    /// Walk down to Switch on disabled, then NMT pre-operational.
    fn shut_down(&mut self, quick_stop_first: bool) -> Result<(), MasterError> {
        let r = self.walk(Target::SwitchOnDisabled, quick_stop_first);
        self.armed = false;
        self.nmt(NMT_ENTER_PRE_OPERATIONAL, "NMT enter pre-operational")?;
        self.nmt_operational = false;
        r
    }
}

impl<B: CanBus> Drive<B, Configured> {
    /// Starts the drive (NMT start, if not operational) and walks the CiA 402 state
    /// machine to Operation enabled with [`next_controlword`], one controlword per
    /// cycle (RPDO1, torque 0, SYNC), through a fault reset if the drive is in Fault.
    /// Fails after `config.state_timeout`. Counters start from zero.
    pub fn enable(mut self) -> Result<Drive<B, Enabled>, MasterError> {
        let l = &mut self.link;
        l.drain();
        if !l.nmt_operational || l.drive_nmt.is_some() {
            l.nmt(NMT_START, "NMT start")?;
            l.nmt_operational = true;
        }
        l.drive_nmt = None;
        l.exchange = Exchange::new(l.node());
        l.unwrap = PositionUnwrap::default();
        l.last_emcy = None;
        l.armed = true;
        if let Err(e) = l.walk(Target::OperationEnabled, false) {
            let _ = l.shut_down(false);
            return Err(e);
        }
        l.exchange.counters = Counters::default();
        l.last_emcy = None;
        Ok(self.into_state())
    }
}

impl<B: CanBus> Drive<B, Enabled> {
    /// One cycle: RPDO1 (Enable operation, `torque_nm` converted to ‰ of rated torque,
    /// clamped), SYNC, then this cycle's TPDO1/TPDO2 until `deadline`; the master
    /// heartbeat when due. A missing TPDO gives `fresh: false` (previous values) and is
    /// counted; `config.missed_cycles_limit()` in a row is an error. EMCYs from the drive,
    /// a Fault state, leaving Operation enabled, an NMT state change and bus errors are
    /// errors; other and malformed frames are counted and ignored. No allocation.
    pub fn cycle(&mut self, torque_nm: f64, deadline: Instant) -> Result<Feedback, MasterError> {
        let l = &mut self.link;
        let sp = l.setpoint(torque_nm)?;
        let cycle = l.exchange.counters.cycles;
        let (sync_time, fresh) = l.exchange(
            Controlword::ENABLE_OPERATION,
            sp.permille,
            deadline,
            Mode::Strict,
        )?;
        l.feedback(cycle, sync_time, fresh, sp)
    }

    /// Disable operation then Disable voltage (cycle by cycle, torque 0) to Switch on
    /// disabled, then NMT pre-operational. Ramp the torque down before calling.
    pub fn disable(mut self) -> Result<Drive<B, Configured>, MasterError> {
        self.link.shut_down(false)?;
        Ok(self.into_state())
    }

    /// Quick stop (controlword 0x0002) until the drive leaves Operation enabled, then
    /// Disable voltage to Switch on disabled, then NMT pre-operational.
    pub fn quick_stop(mut self) -> Result<Drive<B, Configured>, MasterError> {
        self.link.shut_down(true)?;
        Ok(self.into_state())
    }
}

impl<B: CanBus> CyclicDrive for Drive<B, Enabled> {
    type Error = MasterError;

    fn cycle(&mut self, torque_nm: f64, deadline: Instant) -> Result<Feedback, MasterError> {
        Drive::cycle(self, torque_nm, deadline)
    }

    fn cycle_period(&self) -> Duration {
        self.link.cfg.cycle_period
    }

    fn rated_torque_nm(&self) -> f64 {
        self.link.scaling.rated_torque_nm
    }

    fn counters(&self) -> Counters {
        self.link.exchange.counters
    }
}
