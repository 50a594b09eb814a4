//! The controlword (0x6040) commands of the CiA 402 state machine.

/// A controlword (0x6040). Bits: 0 switch on, 1 enable voltage, 2 quick stop (active
/// low), 3 enable operation, 7 fault reset (rising edge), 8 halt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Controlword(pub u16);

/// A device-side command decoded from a controlword (IEC 61800-7-201 Table 32).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// Shutdown: bits 7,2,1,0 = 0,1,1,0.
    Shutdown,
    /// Switch on / Disable operation: bits 7,3,2,1,0 = 0,0,1,1,1.
    SwitchOn,
    /// Switch on + enable operation / Enable operation: bits 7,3,2,1,0 = 0,1,1,1,1.
    EnableOperation,
    /// Disable voltage: bits 7,1 = 0,0.
    DisableVoltage,
    /// Quick stop: bits 7,2,1 = 0,0,1.
    QuickStop,
    /// Fault reset: bit 7 set (acts on its rising edge, see [`Controlword::effective`]).
    FaultReset,
}

impl Controlword {
    /// Shutdown: to Ready to switch on.
    pub const SHUTDOWN: Self = Self(0x0006);
    /// Switch on: to Switched on.
    pub const SWITCH_ON: Self = Self(0x0007);
    /// Enable operation (also Switch on + enable operation): to Operation enabled.
    pub const ENABLE_OPERATION: Self = Self(0x000F);
    /// Disable voltage: to Switch on disabled.
    pub const DISABLE_VOLTAGE: Self = Self(0x0000);
    /// Quick stop: to Quick stop active (from Operation enabled).
    pub const QUICK_STOP: Self = Self(0x0002);
    /// Disable operation: Operation enabled to Switched on (same bits as Switch on).
    pub const DISABLE_OPERATION: Self = Self(0x0007);
    /// Fault reset: acts on the rising edge of bit 7.
    pub const FAULT_RESET: Self = Self(0x0080);
    /// Bit 7, fault reset.
    pub const FAULT_RESET_BIT: u16 = 0x0080;
    /// Bit 8, halt.
    pub const HALT_BIT: u16 = 0x0100;

    /// The command these bits give, by the priority of the standard's table: fault
    /// reset (bit 7), then disable voltage (bit 1 low), quick stop (bit 2 low), shutdown
    /// (bit 0 low), switch on (bit 3 low), enable operation. Every word is one command.
    pub const fn command(self) -> Command {
        let w = self.0;
        if w & 0x0080 != 0 {
            return Command::FaultReset;
        }
        if w & 0x0002 == 0 {
            return Command::DisableVoltage;
        }
        if w & 0x0006 == 0x0002 {
            return Command::QuickStop;
        }
        if w & 0x0007 == 0x0006 {
            return Command::Shutdown;
        }
        if w & 0x000F == 0x0007 {
            return Command::SwitchOn;
        }
        Command::EnableOperation
    }

    /// What a drive acts on, given the previous controlword: bit 7 counts only on its
    /// rising edge, so a held fault-reset bit is cleared here.
    pub const fn effective(self, previous: Controlword) -> Controlword {
        if self.0 & 0x0080 != 0 && previous.0 & 0x0080 != 0 {
            Controlword(self.0 & !0x0080)
        } else {
            self
        }
    }

    /// What the master must send so that `self` takes effect after `previous`: a fault
    /// reset right after another one is replaced by bit 7 low (0x0000, Disable voltage)
    /// to make the next one a rising edge.
    pub const fn after(self, previous: Controlword) -> Controlword {
        if self.0 & 0x0080 != 0 && previous.0 & 0x0080 != 0 {
            Controlword(self.0 & !0x0080)
        } else {
            self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_values_from_the_standard() {
        assert_eq!(Controlword(0x0006).command(), Command::Shutdown);
        assert_eq!(Controlword(0x000E).command(), Command::Shutdown);
        assert_eq!(Controlword(0x0007).command(), Command::SwitchOn);
        assert_eq!(Controlword(0x000F).command(), Command::EnableOperation);
        assert_eq!(Controlword(0x0000).command(), Command::DisableVoltage);
        assert_eq!(Controlword(0x000D).command(), Command::DisableVoltage);
        assert_eq!(Controlword(0x0002).command(), Command::QuickStop);
        assert_eq!(Controlword(0x000B).command(), Command::QuickStop);
        assert_eq!(Controlword(0x0080).command(), Command::FaultReset);
        assert_eq!(Controlword(0x010F).command(), Command::EnableOperation); // halt
        assert_eq!(
            (
                Controlword::SHUTDOWN.0,
                Controlword::SWITCH_ON.0,
                Controlword::ENABLE_OPERATION.0
            ),
            (0x0006, 0x0007, 0x000F)
        );
        assert_eq!(
            (
                Controlword::DISABLE_VOLTAGE.0,
                Controlword::QUICK_STOP.0,
                Controlword::DISABLE_OPERATION.0
            ),
            (0x0000, 0x0002, 0x0007)
        );
    }

    #[test]
    fn fault_reset_is_edge_triggered() {
        let r = Controlword::FAULT_RESET;
        assert_eq!(r.effective(Controlword(0)), r);
        assert_eq!(r.effective(r).command(), Command::DisableVoltage);
        assert_eq!(r.after(r), Controlword(0));
        assert_eq!(r.after(Controlword(0x000F)), r);
    }
}
