//! Unit texts of frequency responses.

use flexid_core::frf::FrfKind;

/// The unit of an FRF of this kind, e.g. `(rad/s)/(N m)`; empty for [`FrfKind::Other`].
pub fn frf_unit(kind: FrfKind) -> &'static str {
    match kind {
        FrfKind::DifferencedVelocity | FrfKind::Velocity => "(rad/s)/(N m)",
        FrfKind::Position => "rad/(N m)",
        FrfKind::Other => "",
    }
}

/// The magnitude axis label, e.g. `Magnitude [dB re 1 (rad/s)/(N m)]`, or `Magnitude [dB]`
/// when the unit is not known.
pub fn magnitude_label(kind: FrfKind) -> String {
    match frf_unit(kind) {
        "" => "Magnitude [dB]".to_string(),
        u => format!("Magnitude [dB re 1 {u}]"),
    }
}
