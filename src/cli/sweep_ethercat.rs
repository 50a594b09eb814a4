//! `flexid sweep --bus ethercat:IFACE | ethercat:emulated[:PLANT.toml]`: the same
//! measurement, files and identification as over CAN, on a CiA 402 drive over EtherCAT (one
//! MainDevice session, [`flexid_ecat::with_drive`]): the SubDevice at position `--node`,
//! its firmware profile from its SII identity (`--generic-profile` for a drive no profile
//! knows), CST with SYNC0 at `--cycle-hz`. No CAN admission (EtherCAT carries the cycle at
//! 100 Mbit/s); the profile's EtherCAT minimum cycle is checked at bring-up.

use super::sweep::{
    drive_info, install_signal_handlers, plan, print_plan_on, profiles, restore_signal_handlers,
    run_paced, save_and_identify, SweepArgs, SweepRun,
};
use super::CliError;
use flexid_ecat::{with_drive, EcatConfig, Link, ProfileChoice};
use std::path::PathBuf;

/// Where an EtherCAT sweep goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EcatTarget {
    /// A network interface (`ethercat:eth1`).
    Interface(String),
    /// Emulated servos in this process, in front of a plant file (the embedded default when
    /// `None`).
    Emulated(Option<PathBuf>),
}

impl EcatTarget {
    /// `ethercat:IFACE`, `ethercat:emulated`, `ethercat:emulated:PLANT.toml`; `None` for
    /// any other bus.
    pub fn parse(bus: &str) -> Option<EcatTarget> {
        let rest = bus.strip_prefix("ethercat:")?;
        Some(match rest.strip_prefix("emulated") {
            Some("") => EcatTarget::Emulated(None),
            Some(p) if p.starts_with(':') => EcatTarget::Emulated(Some(PathBuf::from(&p[1..]))),
            _ => EcatTarget::Interface(rest.to_string()),
        })
    }
}

/// The sweep of `a` on the EtherCAT drive of `target`.
pub fn sweep_run_ethercat(a: &SweepArgs, target: &EcatTarget) -> Result<SweepRun, CliError> {
    if a.node == 0 {
        return Err(CliError::input(
            "--node 0: on EtherCAT the SubDevice's position, 1 = the first",
        ));
    }
    if a.masses == Some(0) {
        return Err(CliError::input("--masses must be at least 1"));
    }
    let plan = plan(a)?;
    let profiles = profiles(a)?;
    let link = match target {
        EcatTarget::Interface(i) if i.is_empty() => {
            return Err(CliError::input(
                "--bus ethercat:IFACE needs an interface name",
            ))
        }
        EcatTarget::Interface(i) => Link::Interface(i.clone()),
        EcatTarget::Emulated(path) => {
            let plant = crate::plant_file::load_plant_file(path.as_deref())
                .map_err(|e| CliError::input(e.to_string()))?;
            let line = flexid_ecat::emulated::servo_line(&plant, usize::from(a.node), a.cycle_hz)
                .map_err(|e| CliError::input(e.to_string()))?;
            Link::Emulated(line)
        }
    };
    let name = link.describe();
    print_plan_on(a, &plan, &format!("{name}, SubDevice {}", a.node));
    let config = EcatConfig {
        axis: usize::from(a.node) - 1,
        profile: if a.generic_profile {
            ProfileChoice::Generic
        } else {
            ProfileChoice::ByIdentity
        },
        ..EcatConfig::at_hz(a.cycle_hz)
    };
    install_signal_handlers();
    let measured = with_drive(link, config, &profiles, |mut drive| {
        let info = drive_info(
            a,
            &plan,
            &name,
            &drive.identity(),
            drive.profile(),
            drive.scaling().rated_torque_nm,
        );
        let outcome = run_paced(&mut drive, &plan);
        match drive.disable() {
            Ok(()) => eprintln!("flexid sweep: drive disabled"),
            Err(e) => eprintln!("flexid sweep: disabling the drive failed (best effort): {e}"),
        }
        (outcome, info)
    });
    restore_signal_handlers();
    let (outcome, info) = measured.map_err(|e| CliError::failed(e.to_string()))?;
    save_and_identify(outcome, info, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ethercat_buses_parse_and_others_are_left_to_can() {
        assert_eq!(
            EcatTarget::parse("ethercat:eth1"),
            Some(EcatTarget::Interface("eth1".into()))
        );
        assert_eq!(
            EcatTarget::parse("ethercat:emulated"),
            Some(EcatTarget::Emulated(None))
        );
        assert_eq!(
            EcatTarget::parse("ethercat:emulated:plants/x.toml"),
            Some(EcatTarget::Emulated(Some("plants/x.toml".into())))
        );
        assert_eq!(EcatTarget::parse("udp"), None);
        assert_eq!(EcatTarget::parse("socketcan:can0"), None);
    }
}
