//! The closed set of answers the diagnosis can give: [`Effect`]. Its names on the wire
//! (JSON `verdict`, `ranking[].effect`, the daemon's events) are the snake_case ones of
//! [`Effect::name`].

use serde::{Deserialize, Serialize};
use std::fmt;

/// An unmodelled effect the diagnosis can name, `None` (the gap is within the noise, or no
/// effect is needed), `Unexplained` (the gap is real but no candidate explains it) or
/// `AmplitudeDependentMode` (no candidate explains it, but a mode moves with the level).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// The nominal chain explains the measurement (or nothing explains it better).
    None,
    /// Coulomb friction on the motor.
    CoulombFriction,
    /// Backlash in a coupling.
    Backlash,
    /// A stiffness that grows with deflection.
    HardeningStiffness,
    /// A pure time delay in the torque path.
    TimeDelay,
    /// The current loop's low-pass in the torque path.
    CurrentLoop,
    /// A further body (anti-resonance/resonance pair) beyond the nominal chain.
    UnmodelledMode,
    /// Gravity (a stiffness to the ground, and its viscous part).
    Gravity,
    /// Not a candidate: the verdict when the gap is significant but no candidate explains
    /// it significantly (the localised bands say where to look).
    Unexplained,
    /// Not a candidate of the ranking: the verdict when no candidate explains a real gap but
    /// the FRF changes between levels and a mode in that band changes its natural frequency
    /// (a softening or hardening stiffness) or its damping ratio significantly with the
    /// amplitude ([`super::amplitude_mode`]; which, in `Diagnosis::amplitude_mode`).
    AmplitudeDependentMode,
}

impl Effect {
    /// Every candidate, in the order they are reported when tied.
    pub const ALL: [Effect; 8] = [
        Effect::None,
        Effect::CoulombFriction,
        Effect::Backlash,
        Effect::HardeningStiffness,
        Effect::TimeDelay,
        Effect::CurrentLoop,
        Effect::UnmodelledMode,
        Effect::Gravity,
    ];

    /// The name on the wire and in reports (`"coulomb_friction"`, ...).
    pub const fn name(self) -> &'static str {
        match self {
            Effect::None => "none",
            Effect::CoulombFriction => "coulomb_friction",
            Effect::Backlash => "backlash",
            Effect::HardeningStiffness => "hardening_stiffness",
            Effect::TimeDelay => "time_delay",
            Effect::CurrentLoop => "current_loop",
            Effect::UnmodelledMode => "unmodelled_mode",
            Effect::Gravity => "gravity",
            Effect::Unexplained => "unexplained",
            Effect::AmplitudeDependentMode => "amplitude_dependent_mode",
        }
    }

    /// A candidate whose model is linear (an extension of the chain's FRF: fitted by
    /// least squares on the FRF, no simulation): delay, current loop, extra mode, gravity.
    pub const fn is_linear(self) -> bool {
        matches!(
            self,
            Effect::TimeDelay | Effect::CurrentLoop | Effect::UnmodelledMode | Effect::Gravity
        )
    }

    /// The effect of a wire name, if it is one (the candidates, `unexplained` and
    /// `amplitude_dependent_mode`).
    pub fn from_name(name: &str) -> Option<Effect> {
        Effect::ALL
            .into_iter()
            .chain([Effect::Unexplained, Effect::AmplitudeDependentMode])
            .find(|e| e.name() == name)
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.name())
    }
}

impl PartialEq<str> for Effect {
    fn eq(&self, other: &str) -> bool {
        self.name() == other
    }
}

impl PartialEq<&str> for Effect {
    fn eq(&self, other: &&str) -> bool {
        self.name() == *other
    }
}

impl PartialEq<Effect> for &str {
    fn eq(&self, other: &Effect) -> bool {
        *self == other.name()
    }
}

impl PartialEq<Effect> for str {
    fn eq(&self, other: &Effect) -> bool {
        self == other.name()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_names_round_trip_through_serde_and_from_name() {
        for e in Effect::ALL
            .into_iter()
            .chain([Effect::Unexplained, Effect::AmplitudeDependentMode])
        {
            let json = serde_json::to_string(&e).unwrap();
            assert_eq!(json, format!("\"{}\"", e.name()));
            assert_eq!(serde_json::from_str::<Effect>(&json).unwrap(), e);
            assert_eq!(Effect::from_name(e.name()), Some(e));
            assert_eq!(e.to_string(), e.name());
        }
        assert_eq!(Effect::from_name("friction"), None);
        let names: std::collections::BTreeSet<_> = Effect::ALL.iter().map(|e| e.name()).collect();
        assert_eq!(names.len(), Effect::ALL.len(), "distinct names");
    }
}
