//! The application layer (AL) state machine: INIT, PRE-OP, SAFE-OP, OP (and the refused
//! BOOT), with the AL status codes (ETG.1000.6 table 11) a SubDevice reports on refusal.

/// An AL state, as coded in AL control (0x0120) and AL status (0x0130) bits 0..3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum AlState {
    Init,
    PreOp,
    Bootstrap,
    SafeOp,
    Op,
}

impl AlState {
    /// The 4-bit code of the state.
    pub fn code(self) -> u8 {
        match self {
            Self::Init => 0x1,
            Self::PreOp => 0x2,
            Self::Bootstrap => 0x3,
            Self::SafeOp => 0x4,
            Self::Op => 0x8,
        }
    }

    /// The state of a 4-bit code, `None` for codes that name no state.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x1 => Self::Init,
            0x2 => Self::PreOp,
            0x3 => Self::Bootstrap,
            0x4 => Self::SafeOp,
            0x8 => Self::Op,
            _ => return None,
        })
    }
}

/// Why a SubDevice refused a state change (register 0x0134).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum AlStatusCode {
    NoError = 0x0000,
    /// The requested transition skips a state (INIT -> SAFE-OP, PRE-OP -> OP, ...).
    InvalidRequestedStateChange = 0x0011,
    /// AL control names no state.
    UnknownRequestedState = 0x0012,
    /// BOOT is not supported.
    BootstrapNotSupported = 0x0013,
    /// The mailbox sync managers do not match the SII (INIT -> PRE-OP).
    InvalidMailboxConfiguration = 0x0016,
    /// The process-data watchdog expired: no outputs written within the sync manager
    /// watchdog time (OP -> SAFE-OP).
    SyncManagerWatchdog = 0x001B,
    /// The SYNC0 signal the application runs on stopped (OP -> SAFE-OP): DC out of sync.
    FatalSyncError = 0x002C,
    /// The output sync manager does not match the RxPDO mapping (PRE-OP -> SAFE-OP).
    InvalidOutputConfiguration = 0x001D,
    /// The input sync manager does not match the TxPDO mapping (PRE-OP -> SAFE-OP).
    InvalidInputConfiguration = 0x001E,
    /// SYNC0 is active with an inconsistent setting (PRE-OP -> SAFE-OP).
    InvalidDcSyncConfiguration = 0x0030,
    /// The SYNC0 cycle is shorter than the SubDevice supports.
    SyncCycleTimeTooSmall = 0x0036,
}

impl AlStatusCode {
    /// The 16-bit code.
    pub fn code(self) -> u16 {
        self as u16
    }
}

/// What the ESC found when the MainDevice asked for a state change; the checks of the
/// transition use them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TransitionChecks {
    /// Sync managers 0 and 1 are configured as the SII's mailboxes.
    pub mailbox_ok: bool,
    /// Sync manager 2 matches the RxPDOs (outputs).
    pub outputs_ok: bool,
    /// Sync manager 3 matches the TxPDOs (inputs).
    pub inputs_ok: bool,
    /// `Err` when SYNC0 is active with a bad setting.
    pub dc: Result<(), AlStatusCode>,
}

/// The state machine: the current state, and the error flag with its code until the
/// MainDevice acknowledges it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlStateMachine {
    state: AlState,
    error: Option<AlStatusCode>,
}

impl Default for AlStateMachine {
    fn default() -> Self {
        Self::new()
    }
}

impl AlStateMachine {
    /// A SubDevice after power-up: INIT, no error.
    pub const fn new() -> Self {
        Self {
            state: AlState::Init,
            error: None,
        }
    }

    /// The current state.
    pub fn state(&self) -> AlState {
        self.state
    }

    /// The pending error, if a state change was refused and not yet acknowledged.
    pub fn error(&self) -> Option<AlStatusCode> {
        self.error
    }

    /// AL status register value: the state, bit 4 the error flag.
    pub fn status_register(&self) -> u16 {
        u16::from(self.state.code()) | if self.error.is_some() { 0x10 } else { 0 }
    }

    /// AL status code register value.
    pub fn status_code_register(&self) -> u16 {
        self.error.unwrap_or(AlStatusCode::NoError).code()
    }

    /// A local AL error, raised by the ESC (watchdog) or the application behind it (SYNC
    /// lost): the state falls back to SAFE-OP if it was above, the error flag is set with
    /// `code` until the MainDevice acknowledges it.
    pub fn fault(&mut self, code: AlStatusCode) {
        self.state = self.state.min(AlState::SafeOp);
        self.error = Some(code);
    }

    /// Handles a write of `control` to AL control (bits 0..3 the requested state, bit 4 the
    /// error acknowledgement). Returns the state entered, if it changed.
    pub fn request(&mut self, control: u16, checks: &TransitionChecks) -> Option<AlState> {
        let acknowledge = control & 0x10 != 0;
        if acknowledge {
            self.error = None;
        } else if self.error.is_some() {
            // An unacknowledged error blocks further requests (ETG.1000.6 6.4.1.4).
            return None;
        }
        let requested = match AlState::from_code((control & 0x0F) as u8) {
            Some(s) => s,
            None => {
                self.error = Some(AlStatusCode::UnknownRequestedState);
                return None;
            }
        };
        match self.check(requested, checks) {
            Ok(()) if requested == self.state => None,
            Ok(()) => {
                self.state = requested;
                Some(requested)
            }
            Err(code) => {
                self.error = Some(code);
                None
            }
        }
    }

    fn check(&self, to: AlState, checks: &TransitionChecks) -> Result<(), AlStatusCode> {
        use AlState::*;
        match (self.state, to) {
            (_, Bootstrap) => Err(AlStatusCode::BootstrapNotSupported),
            // Back down, or staying: always allowed.
            (from, to) if to <= from => Ok(()),
            (Init, PreOp) if checks.mailbox_ok => Ok(()),
            (Init, PreOp) => Err(AlStatusCode::InvalidMailboxConfiguration),
            (PreOp, SafeOp) if !checks.outputs_ok => Err(AlStatusCode::InvalidOutputConfiguration),
            (PreOp, SafeOp) if !checks.inputs_ok => Err(AlStatusCode::InvalidInputConfiguration),
            (PreOp, SafeOp) => checks.dc,
            (SafeOp, Op) => Ok(()),
            _ => Err(AlStatusCode::InvalidRequestedStateChange),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL_OK: TransitionChecks = TransitionChecks {
        mailbox_ok: true,
        outputs_ok: true,
        inputs_ok: true,
        dc: Ok(()),
    };

    #[test]
    fn walks_up_one_state_at_a_time_and_refuses_skips_with_a_code() {
        let mut al = AlStateMachine::new();
        assert_eq!(al.request(0x04, &ALL_OK), None);
        assert_eq!(al.state(), AlState::Init);
        assert_eq!(al.status_register(), 0x11);
        assert_eq!(al.status_code_register(), 0x0011);
        // Blocked until acknowledged, then accepted.
        assert_eq!(al.request(0x02, &ALL_OK), None);
        assert_eq!(al.request(0x12, &ALL_OK), Some(AlState::PreOp));
        assert_eq!(al.request(0x04, &ALL_OK), Some(AlState::SafeOp));
        assert_eq!(al.request(0x08, &ALL_OK), Some(AlState::Op));
        assert_eq!(al.status_register(), 0x08);
        assert_eq!(al.request(0x01, &ALL_OK), Some(AlState::Init));
    }

    #[test]
    fn a_local_error_drops_op_to_safe_op_until_acknowledged() {
        let mut al = AlStateMachine::new();
        for c in [0x02, 0x04, 0x08] {
            al.request(c, &ALL_OK);
        }
        al.fault(AlStatusCode::SyncManagerWatchdog);
        assert_eq!(al.state(), AlState::SafeOp);
        assert_eq!(al.status_register(), 0x14);
        assert_eq!(al.status_code_register(), 0x001B);
        assert_eq!(
            al.request(0x08, &ALL_OK),
            None,
            "blocked until acknowledged"
        );
        assert_eq!(al.request(0x18, &ALL_OK), Some(AlState::Op));
        // Below SAFE-OP a local error keeps the state.
        let mut al = AlStateMachine::new();
        al.fault(AlStatusCode::FatalSyncError);
        assert_eq!(al.state(), AlState::Init);
        assert_eq!(al.status_code_register(), 0x002C);
    }

    #[test]
    fn refuses_bad_configurations_with_their_codes() {
        let mut al = AlStateMachine::new();
        let no_mailbox = TransitionChecks {
            mailbox_ok: false,
            ..ALL_OK
        };
        al.request(0x02, &no_mailbox);
        assert_eq!(al.error(), Some(AlStatusCode::InvalidMailboxConfiguration));
        al.request(0x12, &ALL_OK);
        let bad_inputs = TransitionChecks {
            inputs_ok: false,
            ..ALL_OK
        };
        al.request(0x04, &bad_inputs);
        assert_eq!(al.error(), Some(AlStatusCode::InvalidInputConfiguration));
        assert_eq!(al.state(), AlState::PreOp);
        let fast_sync = TransitionChecks {
            dc: Err(AlStatusCode::SyncCycleTimeTooSmall),
            ..ALL_OK
        };
        al.request(0x14, &fast_sync);
        assert_eq!(al.status_code_register(), 0x0036);
        al.request(0x03 | 0x10, &ALL_OK);
        assert_eq!(al.error(), Some(AlStatusCode::BootstrapNotSupported));
        al.request(0x1F, &ALL_OK);
        assert_eq!(al.error(), Some(AlStatusCode::UnknownRequestedState));
    }
}
