//! The master's half of the CiA 402 state machine: which controlword to send next.

use super::controlword::Controlword;
use super::state::State;

/// Where the master wants the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// Operation enabled (torque on).
    OperationEnabled,
    /// Switch on disabled (power stage off), through a fault reset if in Fault.
    SwitchOnDisabled,
}

impl Target {
    /// The state that is the target.
    pub const fn state(self) -> State {
        match self {
            Target::OperationEnabled => State::OperationEnabled,
            Target::SwitchOnDisabled => State::SwitchOnDisabled,
        }
    }
}

/// The controlword that moves a drive in `state` one step towards `target` (and holds
/// it there once reached). Send it cycle by cycle and re-plan from each statusword.
///
/// - to Operation enabled: Switch on disabled -Shutdown-> Ready to switch on -Switch on->
///   Switched on -Enable operation-> Operation enabled; Quick stop active goes back to
///   Switch on disabled first (Disable voltage) rather than resuming (transition 16 is
///   optional in drives);
/// - to Switch on disabled: Operation enabled -Disable operation-> Switched on
///   -Disable voltage-> Switch on disabled; other powered states Disable voltage;
/// - Fault: Fault reset (bit 7; combine with [`Controlword::after`] so that each reset is
///   a rising edge); Not ready to switch on and Fault reaction active: Disable voltage
///   while the drive leaves them by itself.
pub const fn next_controlword(state: State, target: Target) -> Controlword {
    match (state, target) {
        (State::Fault, _) => Controlword::FAULT_RESET,
        (State::NotReadyToSwitchOn | State::FaultReactionActive, _) => Controlword::DISABLE_VOLTAGE,
        (State::QuickStopActive, _) => Controlword::DISABLE_VOLTAGE,
        (State::SwitchOnDisabled, Target::OperationEnabled) => Controlword::SHUTDOWN,
        (State::ReadyToSwitchOn, Target::OperationEnabled) => Controlword::SWITCH_ON,
        (State::SwitchedOn | State::OperationEnabled, Target::OperationEnabled) => {
            Controlword::ENABLE_OPERATION
        }
        (State::OperationEnabled, Target::SwitchOnDisabled) => Controlword::DISABLE_OPERATION,
        (
            State::SwitchOnDisabled | State::ReadyToSwitchOn | State::SwitchedOn,
            Target::SwitchOnDisabled,
        ) => Controlword::DISABLE_VOLTAGE,
    }
}

#[cfg(test)]
mod tests {
    use super::super::device::device_transition;
    use super::*;

    #[test]
    fn every_state_planner_step() {
        use State::*;
        // (state, to Operation enabled, to Switch on disabled), values from CiA 402.
        let table: [(State, u16, u16); 8] = [
            (NotReadyToSwitchOn, 0x0000, 0x0000),
            (SwitchOnDisabled, 0x0006, 0x0000),
            (ReadyToSwitchOn, 0x0007, 0x0000),
            (SwitchedOn, 0x000F, 0x0000),
            (OperationEnabled, 0x000F, 0x0007),
            (QuickStopActive, 0x0000, 0x0000),
            (FaultReactionActive, 0x0000, 0x0000),
            (Fault, 0x0080, 0x0080),
        ];
        for (s, up, down) in table {
            assert_eq!(next_controlword(s, Target::OperationEnabled).0, up, "{s}");
            assert_eq!(next_controlword(s, Target::SwitchOnDisabled).0, down, "{s}");
        }
    }

    fn walk(start: State, target: Target, previous: Controlword) -> (State, usize) {
        let mut s = start;
        let mut prev = previous;
        for step in 0..12 {
            if s == target.state() {
                return (s, step);
            }
            let cw = next_controlword(s, target).after(prev);
            s = device_transition(s, cw.effective(prev), false);
            prev = cw;
        }
        (s, usize::MAX)
    }

    #[test]
    fn planner_and_device_reach_every_target_from_every_state() {
        for start in State::ALL {
            for target in [Target::OperationEnabled, Target::SwitchOnDisabled] {
                // also starting with bit 7 held high (a reset already sent)
                for prev in [Controlword(0), Controlword::FAULT_RESET] {
                    let (end, steps) = walk(start, target, prev);
                    assert_eq!(end, target.state(), "{start} -> {target:?}");
                    assert!(steps <= 7, "{start} -> {target:?} took {steps}");
                }
            }
        }
        // the nominal walk up is three commands
        assert_eq!(
            walk(
                State::SwitchOnDisabled,
                Target::OperationEnabled,
                Controlword(0)
            )
            .1,
            3
        );
    }

    #[test]
    fn a_persisting_fault_is_never_left() {
        let mut s = State::Fault;
        let mut prev = Controlword(0);
        for _ in 0..10 {
            let cw = next_controlword(s, Target::OperationEnabled).after(prev);
            s = device_transition(s, cw.effective(prev), true);
            prev = cw;
            assert_eq!(s, State::Fault);
        }
    }
}
