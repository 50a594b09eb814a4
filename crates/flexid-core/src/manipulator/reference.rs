//! The reference arm shipped in `robots/` (`flexid-arm6.urdf`, `flexid-arm6.flex.toml`),
//! embedded: the robot of `flexid robot` without `--robot`, of the multi-axis tests and of
//! the benchmark against scipy.

use super::flex_file::FlexFile;
use super::flexible::FlexibleRobot;
use super::springs::Flexibilities;
use crate::robot::SerialRobot;

/// The reference arm's URDF.
pub const URDF: &str = include_str!("../../../../robots/flexid-arm6.urdf");
/// The reference arm's flexibility file.
pub const FLEX: &str = include_str!("../../../../robots/flexid-arm6.flex.toml");

/// The reference arm as a flexible robot (its springs the file's values).
pub fn robot() -> FlexibleRobot {
    // both files are in the repository and parsed by the tests: a failure here is a
    // broken build, not input
    let rigid = SerialRobot::from_urdf_str(URDF).expect("robots/flexid-arm6.urdf parses");
    let file =
        FlexFile::parse(FLEX, "robots/flexid-arm6.flex.toml").expect("the flexibility file parses");
    FlexibleRobot::new(rigid, &file).expect("the reference arm builds")
}

/// The tests' and the benchmark's "true" springs: the file's values (where the
/// identification starts) off by fixed factors between 0.7 and 1.4, the dampings by the
/// same factors in reverse order.
pub fn perturbed_truth(r: &FlexibleRobot) -> Flexibilities {
    const F: [f64; 12] = [
        1.3, 0.8, 1.15, 0.7, 1.4, 0.9, 1.2, 0.75, 1.1, 0.85, 1.35, 0.95,
    ];
    let factor = |i: usize| F[i % F.len()];
    let n = r.nominal.pairs();
    Flexibilities {
        stiffness_nm_per_rad: (0..n)
            .map(|i| r.nominal.stiffness_nm_per_rad[i] * factor(i))
            .collect(),
        damping_nms_per_rad: (0..n)
            .map(|i| r.nominal.damping_nms_per_rad[i] * factor(F.len() - 1 - i % F.len()))
            .collect(),
    }
}
