//! The drive's half of the CiA 402 state machine, for a simulated drive to reuse.

use super::controlword::{Command, Controlword};
use super::state::State;

/// The state a drive in `state` goes to on `controlword`, one step per call
/// (IEC 61800-7-201 Figure 21, transitions 0-16).
///
/// `controlword` must be the *effective* word ([`Controlword::effective`] with the
/// previous one), so that a fault reset acts only on the rising edge of bit 7.
/// `fault_present`: a fault is active in the drive (transition 13 from any state but
/// the fault states; no fault reset while it persists).
///
/// Automatic transitions take one call: Not ready to switch on -> Switch on disabled
/// (1), Fault reaction active -> Fault (14). Quick stop active stays until Disable
/// voltage (12) or Enable operation (16); a drive whose quick-stop option code ends in
/// Switch on disabled makes that move itself.
pub fn device_transition(state: State, controlword: Controlword, fault_present: bool) -> State {
    use Command as C;
    use State as S;
    if fault_present && !state.is_fault() {
        return S::FaultReactionActive; // 13
    }
    let cmd = controlword.command();
    match state {
        S::NotReadyToSwitchOn => S::SwitchOnDisabled, // 1
        S::FaultReactionActive => S::Fault,           // 14
        S::Fault => match cmd {
            C::FaultReset if !fault_present => S::SwitchOnDisabled, // 15
            _ => S::Fault,
        },
        S::SwitchOnDisabled => match cmd {
            C::Shutdown => S::ReadyToSwitchOn, // 2
            _ => S::SwitchOnDisabled,
        },
        S::ReadyToSwitchOn => match cmd {
            C::SwitchOn => S::SwitchedOn,                            // 3
            C::EnableOperation => S::OperationEnabled, // 3 + 4 (one step in most drives)
            C::DisableVoltage | C::QuickStop => S::SwitchOnDisabled, // 7
            C::Shutdown | C::FaultReset => S::ReadyToSwitchOn,
        },
        S::SwitchedOn => match cmd {
            C::EnableOperation => S::OperationEnabled, // 4
            C::Shutdown => S::ReadyToSwitchOn,         // 6
            C::DisableVoltage | C::QuickStop => S::SwitchOnDisabled, // 10
            C::SwitchOn | C::FaultReset => S::SwitchedOn,
        },
        S::OperationEnabled => match cmd {
            C::SwitchOn => S::SwitchedOn,             // 5 (Disable operation)
            C::Shutdown => S::ReadyToSwitchOn,        // 8
            C::DisableVoltage => S::SwitchOnDisabled, // 9
            C::QuickStop => S::QuickStopActive,       // 11
            C::EnableOperation | C::FaultReset => S::OperationEnabled,
        },
        S::QuickStopActive => match cmd {
            C::DisableVoltage => S::SwitchOnDisabled,  // 12
            C::EnableOperation => S::OperationEnabled, // 16
            _ => S::QuickStopActive,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use State::*;

    #[test]
    fn transitions_of_the_standard() {
        let t = |s, w: u16| device_transition(s, Controlword(w), false);
        assert_eq!(t(NotReadyToSwitchOn, 0), SwitchOnDisabled);
        assert_eq!(t(SwitchOnDisabled, 0x06), ReadyToSwitchOn);
        assert_eq!(t(SwitchOnDisabled, 0x07), SwitchOnDisabled);
        assert_eq!(t(SwitchOnDisabled, 0x0F), SwitchOnDisabled);
        assert_eq!(t(ReadyToSwitchOn, 0x07), SwitchedOn);
        assert_eq!(t(ReadyToSwitchOn, 0x00), SwitchOnDisabled);
        assert_eq!(t(SwitchedOn, 0x0F), OperationEnabled);
        assert_eq!(t(SwitchedOn, 0x06), ReadyToSwitchOn);
        assert_eq!(t(OperationEnabled, 0x07), SwitchedOn);
        assert_eq!(t(OperationEnabled, 0x06), ReadyToSwitchOn);
        assert_eq!(t(OperationEnabled, 0x00), SwitchOnDisabled);
        assert_eq!(t(OperationEnabled, 0x02), QuickStopActive);
        assert_eq!(t(QuickStopActive, 0x00), SwitchOnDisabled);
        assert_eq!(t(QuickStopActive, 0x02), QuickStopActive);
        assert_eq!(t(FaultReactionActive, 0x0F), Fault);
        assert_eq!(t(Fault, 0x0F), Fault);
        assert_eq!(t(Fault, 0x80), SwitchOnDisabled);
        assert_eq!(device_transition(Fault, Controlword(0x80), true), Fault);
        assert_eq!(
            device_transition(OperationEnabled, Controlword(0x0F), true),
            FaultReactionActive
        );
    }
}
