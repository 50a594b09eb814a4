//! The statusword (0x6041) and the eight states of the CiA 402 power state machine.

/// The eight states of the CiA 402 state machine (IEC 61800-7-201 §6.5.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    /// Not ready to switch on: drive initialising; leaves by itself to Switch on disabled.
    NotReadyToSwitchOn,
    /// Switch on disabled: no power stage; the rest state after init and fault reset.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on: power stage on, no torque.
    SwitchedOn,
    /// Operation enabled: the drive follows its set-points.
    OperationEnabled,
    /// Quick stop active: decelerating (or stopped) under the quick-stop function.
    QuickStopActive,
    /// Fault reaction active: reacting to a fault; leaves by itself to Fault.
    FaultReactionActive,
    /// Fault: needs a fault reset (rising edge of controlword bit 7).
    Fault,
}

impl State {
    /// All eight states.
    pub const ALL: [State; 8] = [
        State::NotReadyToSwitchOn,
        State::SwitchOnDisabled,
        State::ReadyToSwitchOn,
        State::SwitchedOn,
        State::OperationEnabled,
        State::QuickStopActive,
        State::FaultReactionActive,
        State::Fault,
    ];

    /// `(mask, value)` of the statusword bits that identify this state (the table of
    /// the standard: bits 0-3 ready to switch on / switched on / operation enabled /
    /// fault, bit 5 quick stop, bit 6 switch on disabled).
    pub const fn mask_value(self) -> (u16, u16) {
        match self {
            State::NotReadyToSwitchOn => (0x004F, 0x0000), // xxxx xxxx x0xx 0000
            State::SwitchOnDisabled => (0x004F, 0x0040),   // xxxx xxxx x1xx 0000
            State::ReadyToSwitchOn => (0x006F, 0x0021),    // xxxx xxxx x01x 0001
            State::SwitchedOn => (0x006F, 0x0023),         // xxxx xxxx x01x 0011
            State::OperationEnabled => (0x006F, 0x0027),   // xxxx xxxx x01x 0111
            State::QuickStopActive => (0x006F, 0x0007),    // xxxx xxxx x00x 0111
            State::FaultReactionActive => (0x004F, 0x000F), // xxxx xxxx x0xx 1111
            State::Fault => (0x004F, 0x0008),              // xxxx xxxx x0xx 1000
        }
    }

    /// The statusword bits a drive in this state shows (the table's value; the drive
    /// ORs in its other bits: voltage enabled, warning, remote, target reached, ...).
    pub const fn status_bits(self) -> u16 {
        self.mask_value().1
    }

    /// Whether the power stage produces torque in this state (Operation enabled, Quick stop
    /// active).
    pub const fn torque_enabled(self) -> bool {
        matches!(self, State::OperationEnabled | State::QuickStopActive)
    }

    /// Whether the drive is in a fault state (Fault reaction active or Fault).
    pub const fn is_fault(self) -> bool {
        matches!(self, State::Fault | State::FaultReactionActive)
    }
}

impl std::fmt::Display for State {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            State::NotReadyToSwitchOn => "Not ready to switch on",
            State::SwitchOnDisabled => "Switch on disabled",
            State::ReadyToSwitchOn => "Ready to switch on",
            State::SwitchedOn => "Switched on",
            State::OperationEnabled => "Operation enabled",
            State::QuickStopActive => "Quick stop active",
            State::FaultReactionActive => "Fault reaction active",
            State::Fault => "Fault",
        })
    }
}

/// A statusword (0x6041) as received.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Statusword(pub u16);

impl Statusword {
    /// Bit 4: voltage enabled.
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Bit 7: warning.
    pub const WARNING: u16 = 1 << 7;
    /// Bit 9: remote (the controlword is obeyed).
    pub const REMOTE: u16 = 1 << 9;
    /// Bit 10: target reached.
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// Bit 11: internal limit active.
    pub const INTERNAL_LIMIT: u16 = 1 << 11;

    /// The state the statusword shows; `None` for a bit pattern outside the table
    /// (e.g. 0x0001: ready to switch on with bit 5 clear).
    pub fn state(self) -> Option<State> {
        State::ALL.into_iter().find(|s| {
            let (m, v) = s.mask_value();
            self.0 & m == v
        })
    }

    /// Whether all of `bits` are set.
    pub const fn has(self, bits: u16) -> bool {
        self.0 & bits == bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statusword_table() {
        // Expected bytes from the CiA 402 table, written out by hand (x bits set to 1
        // in the second column to show they are ignored).
        let cases: [(u16, u16, State); 8] = [
            (0x0000, 0xFFB0, State::NotReadyToSwitchOn),
            (0x0040, 0xFFF0, State::SwitchOnDisabled),
            (0x0021, 0xFFB1, State::ReadyToSwitchOn),
            (0x0023, 0xFFB3, State::SwitchedOn),
            (0x0027, 0xFFB7, State::OperationEnabled),
            (0x0007, 0xFF97, State::QuickStopActive),
            (0x000F, 0xFFBF, State::FaultReactionActive),
            (0x0008, 0xFFB8, State::Fault),
        ];
        for (clean, dirty, s) in cases {
            assert_eq!(Statusword(clean).state(), Some(s), "{clean:#06x}");
            assert_eq!(Statusword(dirty).state(), Some(s), "{dirty:#06x}");
            assert_eq!(Statusword(s.status_bits()).state(), Some(s));
        }
        // typical real statuswords
        assert_eq!(Statusword(0x0250).state(), Some(State::SwitchOnDisabled));
        assert_eq!(Statusword(0x0231).state(), Some(State::ReadyToSwitchOn));
        assert_eq!(Statusword(0x0637).state(), Some(State::OperationEnabled));
        assert_eq!(Statusword(0x0218).state(), Some(State::Fault));
        // patterns outside the table
        for bad in [0x0001u16, 0x0003, 0x0061, 0x0002, 0x0004, 0x0048] {
            assert_eq!(Statusword(bad).state(), None, "{bad:#06x}");
        }
    }

    #[test]
    fn every_word_decodes_to_at_most_one_state() {
        for w in 0..=u16::MAX {
            let n = State::ALL
                .iter()
                .filter(|s| w & s.mask_value().0 == s.mask_value().1)
                .count();
            assert!(n <= 1, "{w:#06x} matches {n} states");
        }
    }
}
