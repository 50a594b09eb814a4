//! The simulated CiA 402 servo behind an emulated ESC: the same drive as `flexid-vdrive`'s
//! on CAN (CiA 402 device state machine, torque set-point in per mille of the rated torque,
//! the plant sampled then stepped one cycle with the latched torque), as a segment
//! [`Application`] run in lock-step with the process-data exchange.
//!
//! Reuse: the device state machine is `flexid_canopen::cia402::device_transition` (the
//! drive's half that flexid-canopen keeps for simulated drives), the plant is the core's
//! [`Physics`] (`flexid_core::plant::physics::LinearChain` for the exact ZOH chain), the
//! scaling is flexid-vdrive's (position and velocity in encoder increments and increments/s,
//! torque in per mille of 0x6076). flexid-ecat depends on flexid-canopen and flexid-core, not
//! on flexid-vdrive (its CAN slave, canopen-rs and runner are not needed here), so nothing
//! moved between crates; [`statusword`] mirrors `flexid_vdrive::cia402::statusword`.
//!
//! Timing (one process-data frame = one cycle `k`):
//!
//! 1. the frame arrives: [`Application::latch_inputs`] samples the plant, `x_k`, the state
//!    before torque `k` acts, and publishes it (0x6041, 0x6064, 0x606C, 0x6077, 0x6061); the
//!    ESC maps it into this frame's inputs;
//! 2. the frame has passed: [`Application::apply_outputs`] evaluates the controlword of this
//!    frame, latches its target torque `k` and steps the plant one cycle: `x_k -> x_(k+1)`.
//!
//! So the inputs of exchange `k` are the state before the torque of exchange `k` acts: the
//! pairing of the CAN drive (TPDO `k` answers SYNC `k`), a real drive whose inputs are
//! latched just before the frame and whose outputs act just after it. The statusword of
//! exchange `k` shows the controlword of exchange `k - 1`.
//!
//! That is [`ServoClock::LockStep`], deterministic and as fast as the frames come. With
//! [`ServoClock::Sync0`] the servo runs on its own clock, the SYNC0 pulses of the ESC's DC
//! unit at the cycle the MainDevice configured, whatever the frames do. At every pulse
//! (SAFE-OP or OP) it samples the plant into the inputs (the next frame carries them) and,
//! in OP, takes the controlword and target torque the last frame left, steps the state
//! machine and the plant one cycle. A pulse with no frame since the one before is a missed
//! cycle: the outputs are held (the last torque goes on acting) and counted; after
//! [`ServoConfig::fault_after_missed_cycles`] in a row the drive faults (torque off,
//! statusword Fault), as a drive's SYNC / process-data watchdog does. Two frames in one
//! cycle count as an overwritten set-point. A MainDevice that sends cycle `k` after pulse
//! `k` and before pulse `k + 1` reads the inputs latched at pulse `k` (the state before
//! the torque of cycle `k - 1` acts): one cycle of I/O delay against lock-step.

use crate::esc::al::{AlState, AlStatusCode};
use crate::esc::dictionary::{Mappable, ObjectAccess, ObjectDictionary};
use crate::esc::sii::Identity;
use crate::esc::SubDeviceConfig;
use crate::segment::{Application, CycleStats};
use crate::SubDevice;
use flexid_canopen::cia402::{device_transition, Controlword, State, Statusword};
use flexid_core::plant::physics::Physics;
use flexid_core::plant::PlantFile;

/// Objects of the servo beyond the CST process data.
pub mod object {
    /// Controlword, u16.
    pub const CONTROLWORD: u16 = 0x6040;
    /// Statusword, u16.
    pub const STATUSWORD: u16 = 0x6041;
    /// Modes of operation, i8.
    pub const MODES: u16 = 0x6060;
    /// Modes of operation display, i8.
    pub const MODES_DISPLAY: u16 = 0x6061;
    /// Position actual value, i32, increments.
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// Velocity actual value, i32, increments/s.
    pub const VELOCITY_ACTUAL: u16 = 0x606C;
    /// Target torque, i16, per mille of rated torque.
    pub const TARGET_TORQUE: u16 = 0x6071;
    /// Max torque, u16, per mille of rated torque.
    pub const MAX_TORQUE: u16 = 0x6072;
    /// Rated torque, u32, mN m.
    pub const RATED_TORQUE: u16 = 0x6076;
    /// Torque actual value, i16, per mille of rated torque.
    pub const TORQUE_ACTUAL: u16 = 0x6077;
    /// Position encoder resolution: sub 1 encoder increments, sub 2 motor revolutions, u32.
    pub const ENCODER_RESOLUTION: u16 = 0x608F;
    /// Error code, u16: the CiA 301 / 402 code of the last fault (0: none).
    pub const ERROR_CODE: u16 = 0x603F;
}

/// Error code (0x603F) of an overload: excess torque (CiA 402).
pub const ERROR_EXCESS_TORQUE: u16 = 0x8311;
/// Error code (0x603F) of a lost synchronisation: the ESC left OP under the running axis
/// (SYNC0 lost, process-data watchdog), CiA 301 "sync controller".
pub const ERROR_SYNC: u16 = 0x8700;

/// Mode of operation code of cyclic synchronous torque.
pub const MODE_CST: i8 = 10;
/// Statusword bit 12 in the cyclic synchronous modes: the target is followed.
pub const SW_TARGET_FOLLOWED: u16 = 1 << 12;

/// What advances the servo's plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ServoClock {
    /// One cycle per process-data frame (deterministic; the in-process tests).
    #[default]
    LockStep,
    /// One cycle per SYNC0 pulse, process data latched at the pulse (real-time sweeps).
    Sync0,
}

/// The drive's constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoConfig {
    /// Rated torque (0x6076), N m: 1000 per mille of target and actual torque.
    pub rated_torque_nm: f64,
    /// Largest torque applied (0x6072), N m.
    pub peak_torque_nm: f64,
    /// Encoder increments per motor revolution (0x608F:1, with 0x608F:2 = 1).
    pub increments_per_rev: u32,
    /// What advances the plant.
    pub clock: ServoClock,
    /// SYNC0 clock: consecutive missed cycles (pulses in OP without a frame) that fault
    /// the drive; 0: never (the outputs are held however long).
    pub fault_after_missed_cycles: u32,
    /// Overload protection: consecutive cycles with a target torque beyond the peak torque
    /// (clamped) after which the drive faults with excess torque (0x8311); 0: off.
    pub overtorque_cycles: u32,
}

impl Default for ServoConfig {
    /// flexid-vdrive's defaults: 1 N m rated, 3 N m peak, a 20-bit encoder; lock-step; on
    /// the SYNC0 clock a fault after 100 missed cycles in a row.
    fn default() -> Self {
        Self {
            rated_torque_nm: 1.0,
            peak_torque_nm: 3.0,
            increments_per_rev: 1 << 20,
            clock: ServoClock::LockStep,
            fault_after_missed_cycles: 100,
            overtorque_cycles: 0,
        }
    }
}

impl ServoConfig {
    /// From a plant file's `[drive]` section (`rated_torque_nm`, `peak_torque_nm`,
    /// `encoder_increments_per_rev`), the defaults where absent.
    pub fn from_plant(plant: &PlantFile) -> Self {
        let mut c = Self::default();
        if let Some(d) = &plant.drive {
            let float = |k: &str| {
                d.get(k)
                    .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
            };
            if let Some(v) = float("rated_torque_nm") {
                c.rated_torque_nm = v;
            }
            if let Some(v) = float("peak_torque_nm") {
                c.peak_torque_nm = v;
            }
            if let Some(v) = d
                .get("encoder_increments_per_rev")
                .and_then(|v| v.as_integer())
                .and_then(|i| u32::try_from(i).ok())
            {
                c.increments_per_rev = v;
            }
        }
        c
    }

    /// The emulated SubDevice of this servo: [`SubDeviceConfig::servo_axis`] with the rated
    /// torque, max torque and encoder resolution objects.
    pub fn subdevice_config(&self, identity: Identity, name: &str) -> SubDeviceConfig {
        let mut config = SubDeviceConfig::servo_axis(identity, name);
        self.add_objects(&mut config.dictionary);
        config
    }

    fn add_objects(&self, od: &mut ObjectDictionary) {
        use Mappable::No;
        use ObjectAccess::ReadOnly as Ro;
        let rated_mnm = (self.rated_torque_nm * 1000.0).round() as u32;
        let max_permille = (self.peak_torque_nm / self.rated_torque_nm * 1000.0)
            .round()
            .clamp(0.0, f64::from(u16::MAX)) as u16;
        od.insert(object::RATED_TORQUE, 0, Ro, No, &rated_mnm.to_le_bytes());
        od.insert(object::MAX_TORQUE, 0, Ro, No, &max_permille.to_le_bytes());
        od.insert(object::ENCODER_RESOLUTION, 0, Ro, No, &[2]);
        od.insert(
            object::ENCODER_RESOLUTION,
            1,
            Ro,
            No,
            &self.increments_per_rev.to_le_bytes(),
        );
        od.insert(object::ENCODER_RESOLUTION, 2, Ro, No, &1u32.to_le_bytes());
        od.insert(object::ERROR_CODE, 0, Ro, No, &0u16.to_le_bytes());
    }

    /// An emulated SubDevice and the servo behind it, ready for [`crate::Segment::push_with`].
    pub fn build<P: Physics + std::fmt::Debug + 'static>(
        &self,
        identity: Identity,
        name: &str,
        physics: P,
    ) -> Result<(SubDevice, Box<dyn Application>), crate::esc::sii::SiiError> {
        let device = SubDevice::new(self.subdevice_config(identity, name))?;
        Ok((device, Box::new(Servo::new(*self, physics))))
    }
}

/// The whole statusword of `state` in mode `mode`, the torque clamp acting (`limited`):
/// state bits, remote (9), voltage enabled (4) from Ready to switch on through Quick stop
/// active, internal limit (11) and target followed (12, cyclic synchronous modes) in
/// Operation enabled. As `flexid_vdrive::cia402::statusword`.
pub fn statusword(state: State, mode: i8, limited: bool) -> u16 {
    let mut sw = state.status_bits() | Statusword::REMOTE;
    if matches!(
        state,
        State::ReadyToSwitchOn
            | State::SwitchedOn
            | State::OperationEnabled
            | State::QuickStopActive
    ) {
        sw |= Statusword::VOLTAGE_ENABLED;
    }
    if state == State::OperationEnabled {
        if limited {
            sw |= Statusword::INTERNAL_LIMIT;
        }
        if matches!(mode, 8..=10) {
            sw |= SW_TARGET_FOLLOWED;
        }
    }
    sw
}

/// The simulated CiA 402 servo in cyclic synchronous torque mode.
#[derive(Debug)]
pub struct Servo<P> {
    config: ServoConfig,
    physics: P,
    state: State,
    previous_cw: Controlword,
    limited: bool,
    /// Torque held over the current cycle, N m.
    applied_nm: f64,
    inc_per_rad: f64,
    stats: CycleStats,
    /// SYNC0 clock: frames whose outputs arrived since the last pulse.
    frames_since_pulse: u32,
    /// SYNC0 clock: the current run of missed cycles.
    missed_run: u64,
    /// SYNC0 clock: the watchdog fired (cleared by a fault reset once frames come again).
    watchdog: bool,
    /// SYNC0 clock: a frame has reached the outputs in OP (the watchdog is armed by the
    /// first one, as a sync manager watchdog is).
    armed: bool,
    /// Consecutive cycles clamped to the peak torque.
    clamped_cycles: u32,
    /// SYNC0 was active when the axis was enabled in OP: its loss is a fault.
    synchronised: bool,
    /// A fault is present (its code in 0x603F) and not cleared.
    fault: Option<u16>,
}

impl<P: Physics> Servo<P> {
    /// A servo after power-up (Switch on disabled) in front of `physics`, which steps at the
    /// cycle rate of the MainDevice.
    pub fn new(config: ServoConfig, physics: P) -> Self {
        Self {
            inc_per_rad: f64::from(config.increments_per_rev) / std::f64::consts::TAU,
            config,
            physics,
            state: State::SwitchOnDisabled,
            previous_cw: Controlword::default(),
            limited: false,
            applied_nm: 0.0,
            stats: CycleStats::default(),
            frames_since_pulse: 0,
            missed_run: 0,
            watchdog: false,
            armed: false,
            clamped_cycles: 0,
            synchronised: false,
            fault: None,
        }
    }

    /// The fault present, as its error code (0x603F), if any.
    pub fn fault(&self) -> Option<u16> {
        self.fault
    }

    /// Records a fault: the error code into 0x603F, the torque off at once (the CiA 402
    /// state follows through Fault reaction active at the next controlword).
    fn raise_fault(&mut self, device: &mut SubDevice, code: u16) {
        self.fault = Some(code);
        self.applied_nm = 0.0;
        let _ = device
            .dictionary_mut()
            .set(object::ERROR_CODE, 0, &code.to_le_bytes());
    }

    /// The synchronisation watch, at every latch of the inputs: an axis enabled in OP with
    /// SYNC0 active that finds SYNC0 gone raises the AL error Fatal SYNC error (0x002C: the
    /// ESC falls to SAFE-OP); an enabled axis whose ESC fell back to SAFE-OP (that error,
    /// the process-data watchdog) faults with 0x8700 and drops its torque.
    fn watch_synchronisation(&mut self, device: &mut SubDevice) {
        let op = device.al_state() == AlState::Op;
        let enabled = self.state == State::OperationEnabled;
        if op && enabled && device.sync0().is_some() {
            self.synchronised = true;
        }
        if op && self.synchronised && device.sync0().is_none() {
            device.raise_al_error(AlStatusCode::FatalSyncError);
        }
        if device.al_state() == AlState::SafeOp && enabled && self.fault.is_none() {
            self.raise_fault(device, ERROR_SYNC);
            self.state = device_transition(self.state, Controlword(0), true);
        }
    }

    /// The overload protection after each set-point: [`ServoConfig::overtorque_cycles`]
    /// consecutive clamped cycles fault the drive with excess torque (0x8311).
    fn watch_overload(&mut self, device: &mut SubDevice) {
        self.clamped_cycles = if self.limited {
            self.clamped_cycles + 1
        } else {
            0
        };
        let limit = self.config.overtorque_cycles;
        if limit > 0 && self.clamped_cycles >= limit && self.fault.is_none() {
            self.raise_fault(device, ERROR_EXCESS_TORQUE);
        }
    }

    /// The CiA 402 state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The torque held over the current cycle, N m.
    pub fn applied_torque_nm(&self) -> f64 {
        self.applied_nm
    }

    pub fn stats(&self) -> CycleStats {
        self.stats
    }

    fn mode(od: &ObjectDictionary) -> i8 {
        od.get(object::MODES, 0)
            .and_then(|b| b.first())
            .map_or(0, |&b| b as i8)
    }

    /// The torque for the coming cycle, N m, from the latched target torque and the state.
    fn setpoint(&mut self, od: &ObjectDictionary) -> f64 {
        self.limited = false;
        if self.state != State::OperationEnabled || Self::mode(od) != MODE_CST {
            return 0.0;
        }
        let permille = od
            .get(object::TARGET_TORQUE, 0)
            .and_then(|b| b.try_into().ok())
            .map_or(0, i16::from_le_bytes);
        let want = f64::from(permille) * self.config.rated_torque_nm / 1000.0;
        let peak = self.config.peak_torque_nm;
        let t = want.clamp(-peak, peak);
        self.limited = t != want;
        t
    }
}

impl<P: Physics> Servo<P> {
    /// Samples the plant into the input objects (statusword, position, velocity, torque,
    /// mode display); the ESC maps them into the next frame.
    fn publish_inputs(&mut self, device: &mut SubDevice) {
        self.stats.latches += 1;
        self.watch_synchronisation(device);
        let s = self.physics.sample();
        let rated = self.config.rated_torque_nm;
        let position = (s.position_rad * self.inc_per_rad).round() as i64 as i32;
        let velocity = (s.velocity_rad_s * self.inc_per_rad).round() as i32;
        let torque = (s.torque_nm / rated * 1000.0).round() as i16;
        let od = device.dictionary_mut();
        let mode = Self::mode(od);
        let sw = statusword(self.state, mode, self.limited);
        // The objects exist (the servo's dictionary): a failed set would be a bug of the
        // dictionary builder, and the input keeps its previous value.
        let _ = od.set(object::STATUSWORD, 0, &sw.to_le_bytes());
        let _ = od.set(object::POSITION_ACTUAL, 0, &position.to_le_bytes());
        let _ = od.set(object::VELOCITY_ACTUAL, 0, &velocity.to_le_bytes());
        let _ = od.set(object::TORQUE_ACTUAL, 0, &torque.to_le_bytes());
        let _ = od.set(object::MODES_DISPLAY, 0, &[mode as u8]);
    }

    /// Takes the controlword and target torque in the dictionary, steps the state machine
    /// (`watchdog`: the SYNC0 watchdog holds the drive in fault, beside a raised fault) and
    /// the plant one cycle.
    fn step_cycle(&mut self, device: &mut SubDevice, watchdog: bool) {
        let od = device.dictionary();
        let cw = Controlword(
            od.get(object::CONTROLWORD, 0)
                .and_then(|b| b.try_into().ok())
                .map_or(0, u16::from_le_bytes),
        );
        let effective = cw.effective(self.previous_cw);
        self.previous_cw = cw;
        // A raised fault takes the drive to Fault; once there, a fault reset clears it (its
        // condition, the torque or the synchronisation, is gone with the power stage off);
        // the SYNC0 watchdog holds the drive in Fault while frames stay missing.
        let raised = self.fault.is_some() && !self.state.is_fault();
        self.state = device_transition(self.state, effective, watchdog || raised);
        if self.state == State::SwitchOnDisabled {
            // Fault reset (transition 15) clears the fault.
            self.fault = None;
        }
        let t = self.setpoint(device.dictionary());
        self.watch_overload(device);
        let t = if self.fault.is_some() { 0.0 } else { t };
        self.physics.step(t);
        self.applied_nm = t;
        self.stats.cycles += 1;
    }

    /// The SYNC0 watchdog at a pulse in OP: counts a pulse without a frame as missed and
    /// says whether the drive is in fault (the run reached the limit; it stays until
    /// frames come again).
    fn watch_frames(&mut self) -> bool {
        self.armed |= self.frames_since_pulse > 0;
        if !self.armed {
            return false;
        }
        if self.frames_since_pulse == 0 {
            self.stats.missed += 1;
            self.missed_run += 1;
            self.stats.longest_missed_run = self.stats.longest_missed_run.max(self.missed_run);
            let limit = u64::from(self.config.fault_after_missed_cycles);
            if limit > 0 && self.missed_run >= limit {
                self.watchdog = true;
            }
        } else {
            self.stats.overwritten += u64::from(self.frames_since_pulse - 1);
            self.missed_run = 0;
            self.watchdog = false;
        }
        self.frames_since_pulse = 0;
        self.watchdog
    }
}

impl<P: Physics> Servo<P> {
    /// A SYNC0 pulse (the SYNC0 clock only): inputs sampled; in OP (`op`) the outputs the
    /// last frame left applied for one cycle (held when no frame came: a missed cycle),
    /// outside OP the plant stepped with no torque.
    fn on_pulse(&mut self, device: &mut SubDevice, op: bool) {
        if self.config.clock != ServoClock::Sync0 {
            return;
        }
        self.stats.pulses += 1;
        self.publish_inputs(device);
        if op {
            let watchdog = self.watch_frames();
            if watchdog && self.fault.is_none() {
                // the drive's process-data watchdog: a lost synchronisation (0x8700)
                self.raise_fault(device, ERROR_SYNC);
            }
            self.step_cycle(device, watchdog);
        } else {
            self.physics.step(0.0);
            self.applied_nm = 0.0;
            self.frames_since_pulse = 0;
        }
    }
}

impl<P: Physics + std::fmt::Debug> Application for Servo<P> {
    fn latch_inputs(&mut self, device: &mut SubDevice) {
        if self.config.clock == ServoClock::LockStep {
            self.publish_inputs(device);
        }
    }

    fn apply_outputs(&mut self, device: &mut SubDevice) {
        match self.config.clock {
            ServoClock::LockStep => self.step_cycle(device, false),
            ServoClock::Sync0 => self.frames_since_pulse += 1,
        }
    }

    fn sync0(&mut self, device: &mut SubDevice) {
        let op = device.al_state() == crate::esc::al::AlState::Op;
        self.on_pulse(device, op);
    }

    fn stats(&self) -> CycleStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flexid_core::model::Chain;
    use flexid_core::plant::physics::LinearChain;

    fn servo() -> (SubDevice, Servo<LinearChain>) {
        let chain = Chain {
            inertia_kgm2: vec![1e-3, 2e-3],
            stiffness_nm_per_rad: vec![500.0],
            damping_nms_per_rad: vec![0.01],
        };
        let config = ServoConfig::default();
        let identity = Identity {
            vendor_id: 1,
            product_code: 2,
            revision: 3,
            serial: 4,
        };
        let device = SubDevice::new(config.subdevice_config(identity, "S")).expect("SII");
        let physics = LinearChain::new(&chain, 4000.0).expect("chain");
        (device, Servo::new(config, physics))
    }

    fn exchange(d: &mut SubDevice, s: &mut Servo<LinearChain>, cw: u16, permille: i16) -> u16 {
        s.latch_inputs(d);
        let sw = d
            .dictionary()
            .get(object::STATUSWORD, 0)
            .and_then(|b| b.try_into().ok())
            .map_or(0, u16::from_le_bytes);
        let od = d.dictionary_mut();
        od.set(object::CONTROLWORD, 0, &cw.to_le_bytes())
            .expect("cw");
        od.set(object::TARGET_TORQUE, 0, &permille.to_le_bytes())
            .expect("torque");
        s.apply_outputs(d);
        sw
    }

    #[test]
    fn walks_to_operation_enabled_and_applies_the_clamped_cst_torque() {
        let (mut d, mut s) = servo();
        d.dictionary_mut()
            .set(object::MODES, 0, &[MODE_CST as u8])
            .expect("mode");
        // Switch on disabled, voltage off, remote.
        assert_eq!(exchange(&mut d, &mut s, 0x0006, 500), 0x0240);
        assert_eq!(s.state(), State::ReadyToSwitchOn);
        // Not enabled yet: no torque, whatever the target.
        assert_eq!(s.applied_torque_nm(), 0.0);
        assert_eq!(exchange(&mut d, &mut s, 0x000F, 500), 0x0231);
        assert_eq!(s.state(), State::OperationEnabled);
        assert_eq!(s.applied_torque_nm(), 0.5);
        // Operation enabled, voltage, remote, target followed.
        assert_eq!(exchange(&mut d, &mut s, 0x000F, 5000), 0x1237);
        assert_eq!(s.applied_torque_nm(), 3.0, "clamped to the peak torque");
        // The clamp shows as internal limit active.
        assert_eq!(exchange(&mut d, &mut s, 0x000F, 0), 0x1A37);
        assert_eq!(s.stats().cycles, 4);
        // 0x6076 in mN m, 0x6072 in per mille, 0x608F:1 the encoder.
        let od = d.dictionary();
        assert_eq!(
            od.get(object::RATED_TORQUE, 0),
            Some(&1000u32.to_le_bytes()[..])
        );
        assert_eq!(
            od.get(object::MAX_TORQUE, 0),
            Some(&3000u16.to_le_bytes()[..])
        );
        assert_eq!(
            od.get(object::ENCODER_RESOLUTION, 1),
            Some(&(1u32 << 20).to_le_bytes()[..])
        );
    }

    fn sync0_servo(fault_after: u32) -> (SubDevice, Servo<LinearChain>) {
        let (mut d, s) = servo();
        let config = ServoConfig {
            clock: ServoClock::Sync0,
            fault_after_missed_cycles: fault_after,
            ..ServoConfig::default()
        };
        d.dictionary_mut()
            .set(object::MODES, 0, &[MODE_CST as u8])
            .expect("mode");
        (d, Servo::new(config, s.physics))
    }

    /// A frame on the SYNC0 clock: the outputs reach the dictionary; the inputs it carries
    /// are the last pulse's (statusword returned).
    fn frame(d: &mut SubDevice, s: &mut Servo<LinearChain>, cw: u16, permille: i16) -> u16 {
        s.latch_inputs(d);
        let od = d.dictionary_mut();
        let sw = od
            .get(object::STATUSWORD, 0)
            .and_then(|b| b.try_into().ok())
            .map_or(0, u16::from_le_bytes);
        od.set(object::CONTROLWORD, 0, &cw.to_le_bytes())
            .expect("cw");
        od.set(object::TARGET_TORQUE, 0, &permille.to_le_bytes())
            .expect("torque");
        s.apply_outputs(d);
        sw
    }

    fn position(d: &SubDevice) -> i32 {
        d.dictionary()
            .get(object::POSITION_ACTUAL, 0)
            .and_then(|b| b.try_into().ok())
            .map_or(0, i32::from_le_bytes)
    }

    #[test]
    fn on_the_sync0_clock_the_plant_steps_per_pulse_and_missed_cycles_hold_the_torque() {
        let (mut d, mut s) = sync0_servo(0);
        // Frames alone do not advance the plant or the state machine.
        frame(&mut d, &mut s, 0x0006, 0);
        frame(&mut d, &mut s, 0x0006, 0);
        assert_eq!(s.stats().cycles, 0);
        assert_eq!(s.state(), State::SwitchOnDisabled);
        // The pulse applies the last frame's controlword; two frames in a cycle: one
        // set-point overwritten.
        s.on_pulse(&mut d, true);
        assert_eq!(s.state(), State::ReadyToSwitchOn);
        assert_eq!(s.stats().overwritten, 1);
        frame(&mut d, &mut s, 0x000F, 500);
        s.on_pulse(&mut d, true);
        assert_eq!(s.state(), State::OperationEnabled);
        assert_eq!(s.applied_torque_nm(), 0.5);
        // The statusword the next frame carries was latched at the pulse, before the
        // enable acted: the pulse's inputs come first.
        assert_eq!(frame(&mut d, &mut s, 0x000F, 200) & 0x006F, 0x0021);
        s.on_pulse(&mut d, true);
        assert_eq!(s.applied_torque_nm(), 0.2);
        // Five pulses with no frame: five missed cycles, the torque held, the plant moving.
        let before = position(&d);
        for _ in 0..5 {
            s.on_pulse(&mut d, true);
            assert_eq!(s.applied_torque_nm(), 0.2, "held");
        }
        let st = s.stats();
        assert_eq!((st.missed, st.longest_missed_run), (5, 5));
        assert_eq!(st.cycles, 8);
        assert_eq!(st.pulses, 8);
        assert!(position(&d) > before + 10, "the plant ran on");
        assert_eq!(s.state(), State::OperationEnabled, "no watchdog limit");
        frame(&mut d, &mut s, 0x000F, -100);
        s.on_pulse(&mut d, true);
        assert_eq!(s.applied_torque_nm(), -0.1);
        assert_eq!(s.stats().missed, 5);
    }

    #[test]
    fn on_the_sync0_clock_missed_cycles_in_a_row_fault_the_drive() {
        let (mut d, mut s) = sync0_servo(3);
        // Pulses before the first frame in OP do not count (the watchdog is not armed).
        for _ in 0..10 {
            s.on_pulse(&mut d, true);
        }
        assert_eq!(s.stats().missed, 0);
        for cw in [0x0006, 0x000F] {
            frame(&mut d, &mut s, cw, 300);
            s.on_pulse(&mut d, true);
        }
        assert_eq!(s.state(), State::OperationEnabled);
        s.on_pulse(&mut d, true);
        s.on_pulse(&mut d, true);
        assert_eq!(s.state(), State::OperationEnabled, "2 missed: held");
        assert_eq!(s.applied_torque_nm(), 0.3);
        s.on_pulse(&mut d, true);
        assert!(s.state().is_fault(), "{:?}", s.state());
        assert_eq!(s.applied_torque_nm(), 0.0, "torque off");
        // Fault reaction active, then Fault at the next pulse.
        s.on_pulse(&mut d, true);
        s.on_pulse(&mut d, true);
        assert_eq!(
            frame(&mut d, &mut s, 0x0080, 0) & 0x004F,
            0x0008,
            "Fault shown"
        );
        // Frames again and a fault reset: back to Switch on disabled.
        s.on_pulse(&mut d, true);
        assert_eq!(s.state(), State::SwitchOnDisabled);
    }

    #[test]
    fn a_lockstep_servo_ignores_sync0_pulses() {
        let (mut d, mut s) = servo();
        s.on_pulse(&mut d, true);
        assert_eq!(s.stats(), CycleStats::default());
    }

    #[test]
    fn a_mode_other_than_cst_applies_no_torque() {
        let (mut d, mut s) = servo();
        exchange(&mut d, &mut s, 0x0006, 0);
        exchange(&mut d, &mut s, 0x000F, 400);
        assert_eq!(s.state(), State::OperationEnabled);
        assert_eq!(s.applied_torque_nm(), 0.0, "mode 0: no torque");
    }
}
