//! The firmware profile of an EtherCAT drive, chosen from its SubDevice's SII identity
//! (vendor id, product code, revision) against the profiles' `[ethercat]` tables, as the CAN
//! path chooses it from 0x1018. An unknown drive is refused unless the generic CiA 402
//! profile is chosen on purpose ([`ProfileChoice::Generic`]): on EtherCAT a drive's units
//! and limits are not guessed.

use flexid_canopen::profile::GENERIC;
use flexid_canopen::{Identity, Profile, ProfileSet};
use std::time::Duration;
use thiserror::Error;

/// How the drive's profile is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ProfileChoice {
    /// The profile whose `[ethercat]` identity matches the SII's; an unknown drive is an
    /// error.
    #[default]
    ByIdentity,
    /// `generic-cia402` whatever the identity: units read from the drive (0x6076, 0x608F),
    /// no cycle limit of the firmware known.
    Generic,
}

/// Why no profile could be used for a SubDevice.
#[derive(Debug, Error)]
pub enum ProfileError {
    #[error(
        "unknown EtherCAT drive: SII vendor id {vendor_id:#010x}, product code \
         {product_code:#010x}, revision {revision:#010x} match no firmware profile's \
         [ethercat] identity; add a profile for it (firmware-profiles/README.md) or choose \
         the generic CiA 402 profile"
    )]
    Unknown {
        vendor_id: u32,
        product_code: u32,
        revision: u32,
    },
    #[error("no `{GENERIC}` profile loaded")]
    NoGeneric,
    #[error(
        "profile {profile}: the cycle of {cycle_us} us is shorter than the firmware's \
         {min_us} us over EtherCAT"
    )]
    CycleTooShort {
        profile: String,
        cycle_us: u64,
        min_us: u32,
    },
}

/// The profile for a SubDevice of SII identity `identity` run at `cycle`.
pub fn choose(
    profiles: &ProfileSet,
    identity: &Identity,
    choice: ProfileChoice,
    cycle: Duration,
) -> Result<Profile, ProfileError> {
    let profile = match choice {
        ProfileChoice::Generic => profiles.get(GENERIC).ok_or(ProfileError::NoGeneric)?,
        ProfileChoice::ByIdentity => {
            profiles
                .select_ethercat(identity)
                .ok_or(ProfileError::Unknown {
                    vendor_id: identity.vendor_id,
                    product_code: identity.product_code,
                    revision: identity.revision,
                })?
        }
    };
    if let Some(min_us) = profile.ethercat.and_then(|e| e.min_cycle_us) {
        let cycle_us = cycle.as_micros() as u64;
        if cycle_us < u64::from(min_us) {
            return Err(ProfileError::CycleTooShort {
                profile: profile.name.clone(),
                cycle_us,
                min_us,
            });
        }
    }
    Ok(profile.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(vendor_id: u32, product_code: u32) -> Identity {
        Identity {
            vendor_id,
            product_code,
            revision: 1,
            ..Identity::default()
        }
    }

    #[test]
    fn known_drives_get_their_profile_unknown_ones_only_the_generic_on_purpose() {
        let set = ProfileSet::builtin();
        let us = Duration::from_micros;
        let servo = id(0x0A1D, 0x0402_0000);
        let p = choose(&set, &servo, ProfileChoice::ByIdentity, us(250)).expect("known");
        assert_eq!(p.name, "flexid-vdrive");
        let err = choose(&set, &servo, ProfileChoice::ByIdentity, us(100)).unwrap_err();
        assert!(
            err.to_string()
                .contains("cycle of 100 us is shorter than the firmware's 125 us"),
            "{err}"
        );
        let other = id(0x0539, 7);
        let err = choose(&set, &other, ProfileChoice::ByIdentity, us(250)).unwrap_err();
        assert!(
            err.to_string()
                .contains("vendor id 0x00000539, product code 0x00000007"),
            "{err}"
        );
        let g = choose(&set, &other, ProfileChoice::Generic, us(250)).expect("generic");
        assert_eq!(g.name, GENERIC);
    }
}
