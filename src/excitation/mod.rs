//! Excitation signals in torque units [N m] and their description.

mod description;
pub use description::{ExcitationInfo, ExcitationKind};
