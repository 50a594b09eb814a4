//! The CiA 402 device state machine ("power drive system"), written by hand: canopen-rs
//! has no device profile.
//!
//! States and statusword values (bits 0-3, 5, 6; CiA 402-2 table "statusword"):
//!
//! | state | statusword |
//! |---|---|
//! | Not ready to switch on | `0x0000` |
//! | Switch on disabled | `0x0040` |
//! | Ready to switch on | `0x0021` |
//! | Switched on | `0x0023` |
//! | Operation enabled | `0x0027` |
//! | Quick stop active | `0x0007` |
//! | Fault reaction active | `0x000F` |
//! | Fault | `0x0008` |
//!
//! Other statusword bits the drive sets ([`statusword`]):
//!
//! * bit 4 "voltage enabled": the DC link of the simulated power stage is always charged,
//!   so the bit shows the controlword's voltage command: set from Ready to switch on
//!   ("shutdown" enables the voltage) through Operation enabled and Quick stop active;
//!   clear in Switch on disabled (after "disable voltage") and in Fault;
//! * bit 9 "remote": the controlword is processed; the bus is this drive's only control,
//!   so always set;
//! * bit 11 "internal limit active" while the torque set-point is clamped;
//! * bit 12, operation mode specific: in the cyclic synchronous modes (CST, CSV, CSP) "target
//!   torque / velocity / position ignored" = 0, used as the input of the control loop =
//!   1: set in Operation enabled only (PT: reserved, 0).
//!
//! Bits 7 (warning), 10 (target reached), 13 (following error) stay 0.

/// Controlword bit 7: fault reset (acts on its rising edge).
pub const CW_FAULT_RESET: u16 = 0x0080;
/// Statusword bit 4: voltage enabled.
pub const SW_VOLTAGE_ENABLED: u16 = 0x0010;
/// Statusword bit 9: remote (the controlword is processed).
pub const SW_REMOTE: u16 = 0x0200;
/// Statusword bit 11: internal limit active.
pub const SW_INTERNAL_LIMIT: u16 = 0x0800;
/// Statusword bit 12 in CST/CSV/CSP: the target is followed (not ignored).
pub const SW_TARGET_FOLLOWED: u16 = 0x1000;

/// The whole statusword of `state` in mode of operation `mode`, with the torque clamp
/// acting (`limited`).
pub fn statusword(state: State, mode: i8, limited: bool) -> u16 {
    let mut sw = state.status_bits() | SW_REMOTE;
    if matches!(
        state,
        State::ReadyToSwitchOn
            | State::SwitchedOn
            | State::OperationEnabled
            | State::QuickStopActive
    ) {
        sw |= SW_VOLTAGE_ENABLED;
    }
    if state == State::OperationEnabled {
        if limited {
            sw |= SW_INTERNAL_LIMIT;
        }
        if matches!(mode, mode::CST | mode::CSV | mode::CSP) {
            sw |= SW_TARGET_FOLLOWED;
        }
    }
    sw
}

/// Mode of operation (0x6060 / 0x6061 values).
pub mod mode {
    /// Profile torque.
    pub const PT: i8 = 4;
    /// Cyclic synchronous position.
    pub const CSP: i8 = 8;
    /// Cyclic synchronous velocity.
    pub const CSV: i8 = 9;
    /// Cyclic synchronous torque.
    pub const CST: i8 = 10;
    /// Whether the drive supports `m`.
    pub const fn supported(m: i8) -> bool {
        matches!(m, PT | CSP | CSV | CST)
    }
}

/// A state of the CiA 402 power drive system state machine: the one type the master
/// (`flexid-canopen`) reads from the statusword and this drive writes into it.
pub use flexid_canopen::cia402::State;

/// A device control command decoded from the controlword (bits 0-3, 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// `xxxx xx0x` (e.g. 0x0000).
    DisableVoltage,
    /// `xxxx x01x` (e.g. 0x0002).
    QuickStop,
    /// `xxxx x110` (0x0006).
    Shutdown,
    /// `xxxx 0111` (0x0007); also "disable operation".
    SwitchOn,
    /// `xxxx 1111` (0x000F).
    EnableOperation,
}

impl Command {
    /// Decodes bits 0-3 (bit 7, fault reset, is handled as an edge by [`DeviceControl`]).
    pub const fn decode(cw: u16) -> Command {
        if cw & 0x0002 == 0 {
            Command::DisableVoltage
        } else if cw & 0x0004 == 0 {
            Command::QuickStop
        } else if cw & 0x0001 == 0 {
            Command::Shutdown
        } else if cw & 0x0008 == 0 {
            Command::SwitchOn
        } else {
            Command::EnableOperation
        }
    }
}

/// The state machine: controlword in, state out.
#[derive(Debug, Clone)]
pub struct DeviceControl {
    state: State,
    last_cw: u16,
}

impl Default for DeviceControl {
    fn default() -> Self {
        Self::new()
    }
}

impl DeviceControl {
    /// After power-on: transition 1 (self-test done) leaves the drive in Switch on disabled.
    pub fn new() -> Self {
        Self {
            state: State::SwitchOnDisabled,
            last_cw: 0,
        }
    }

    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Applies a controlword (every RPDO / SDO write is evaluated, as drives do).
    /// `fault_cleared`: whether the cause of a fault is gone (fault reset only then leaves
    /// Fault). Returns the new state.
    pub fn on_controlword(&mut self, cw: u16, fault_cleared: bool) -> State {
        let rising_reset = cw & CW_FAULT_RESET != 0 && self.last_cw & CW_FAULT_RESET == 0;
        self.last_cw = cw;
        use Command::*;
        use State::*;
        self.state = match (self.state, Command::decode(cw)) {
            (Fault, _) if rising_reset && fault_cleared => SwitchOnDisabled, // 15
            (Fault | FaultReactionActive | NotReadyToSwitchOn, _) => self.state,
            (_, _) if cw & CW_FAULT_RESET != 0 => self.state, // bit 7 outside Fault: no command
            (SwitchOnDisabled, Shutdown) => ReadyToSwitchOn,  // 2
            (SwitchOnDisabled, _) => SwitchOnDisabled,
            (ReadyToSwitchOn, SwitchOn) => SwitchedOn, // 3
            (ReadyToSwitchOn, EnableOperation) => OperationEnabled, // 3 + 4
            (ReadyToSwitchOn, DisableVoltage | QuickStop) => SwitchOnDisabled, // 7
            (ReadyToSwitchOn, Shutdown) => ReadyToSwitchOn,
            (SwitchedOn, EnableOperation) => OperationEnabled, // 4
            (SwitchedOn, Shutdown) => ReadyToSwitchOn,         // 6
            (SwitchedOn, DisableVoltage | QuickStop) => SwitchOnDisabled, // 10
            (SwitchedOn, SwitchOn) => SwitchedOn,
            (OperationEnabled, SwitchOn) => SwitchedOn, // 5
            (OperationEnabled, Shutdown) => ReadyToSwitchOn, // 8
            (OperationEnabled, DisableVoltage) => SwitchOnDisabled, // 9
            (OperationEnabled, QuickStop) => QuickStopActive, // 11
            (OperationEnabled, EnableOperation) => OperationEnabled,
            (QuickStopActive, DisableVoltage) => SwitchOnDisabled, // 12
            (QuickStopActive, _) => QuickStopActive, // option code 2: no transition 16
        };
        self.state
    }

    /// A fault: transitions 13 and 14 (the reaction, torque off, is immediate).
    pub fn fault(&mut self) {
        self.state = State::Fault;
    }

    /// Disable voltage from any state but Fault (0x6007 = 2): transitions 7, 9, 10, 12.
    pub fn disable_voltage(&mut self) {
        if !matches!(self.state, State::Fault | State::FaultReactionActive) {
            self.state = State::SwitchOnDisabled;
        }
    }

    /// Quick stop (0x6007 = 3): transition 11 from Operation enabled, else as Disable
    /// voltage.
    pub fn quick_stop(&mut self) {
        match self.state {
            State::OperationEnabled => self.state = State::QuickStopActive,
            State::QuickStopActive => {}
            _ => self.disable_voltage(),
        }
    }

    /// The quick-stop ramp has reached zero torque: quick stop option code 2, transition 12.
    pub fn quick_stop_done(&mut self) {
        if self.state == State::QuickStopActive {
            self.state = State::SwitchOnDisabled;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_commands() {
        assert_eq!(Command::decode(0x0000), Command::DisableVoltage);
        assert_eq!(Command::decode(0x0002), Command::QuickStop);
        assert_eq!(Command::decode(0x0006), Command::Shutdown);
        assert_eq!(Command::decode(0x0007), Command::SwitchOn);
        assert_eq!(Command::decode(0x000F), Command::EnableOperation);
        assert_eq!(Command::decode(0x000B), Command::QuickStop);
    }

    #[test]
    fn fault_reset_needs_a_rising_edge_and_a_cleared_cause() {
        let mut d = DeviceControl::new();
        d.fault();
        assert_eq!(d.on_controlword(0x0080, false), State::Fault);
        assert_eq!(d.on_controlword(0x0080, true), State::Fault); // no edge
        d.on_controlword(0x0000, true);
        assert_eq!(d.on_controlword(0x0080, true), State::SwitchOnDisabled);
    }
}
