//! The flexibility file (TOML) of a robot: beside its URDF (the rigid links), the motors,
//! the gears and the bearing flexibilities, every convention stated
//! (`../shared/design/multiaxis.md`, fact 5: each one moves the model FRF by more than the
//! noise), and the poses it is measured at. `robots/flexid-arm6.flex.toml` is the
//! reference robot's.
//!
//! ```toml
//! name = "flexid-arm6"
//! urdf = "flexid-arm6.urdf"           # relative to this file
//!
//! [conventions]
//! stiffness_side = "arm"              # or "motor": k_arm = k_motor r^2 (dampings alike)
//! bearing_axes = "joint_frame"        # axes of the joint's frame after its rotation,
//!                                     # rotated in the order listed
//! gravity_on_bearings = true          # gravity stiffness on the bearing coordinates
//! units = "SI"                        # N m/rad, N m s/rad, kg m^2, rad
//!
//! [[axis]]
//! joint = "joint_1"                   # the URDF joint this motor drives
//! motor_inertia_kgm2 = 1.5e-3         # motor side
//! gear_ratio = 120.0                  # motor angle / joint angle
//! gear = { stiffness = 6.0e5, damping = 250.0 }
//! bearings = [ { axis = "x", stiffness = 1.5e6, damping = 400.0 },
//!              { axis = "y", stiffness = 1.5e6, damping = 400.0 } ]
//!
//! [[pose]]
//! name = "id-1"
//! role = "identification"             # or "validation"
//! q_deg = [0, -30, 20, 0, 40, 0]      # joint angles [deg]
//! ```

use super::springs::BearingAxis;
use serde::Deserialize;

/// Errors of a flexibility file, naming it.
#[derive(Debug, thiserror::Error)]
pub enum FlexFileError {
    #[error("{origin}: {source}")]
    Syntax {
        origin: String,
        #[source]
        source: toml::de::Error,
    },
    #[error("{origin}: {what} {detail}")]
    Invalid {
        origin: String,
        what: String,
        detail: String,
    },
}

/// A flexibility file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlexFile {
    /// A human-readable name.
    #[serde(default)]
    pub name: Option<String>,
    /// The robot's URDF, relative to this file.
    pub urdf: String,
    /// The conventions the numbers follow.
    pub conventions: Conventions,
    /// One per motor, in joint order.
    #[serde(rename = "axis")]
    pub axes: Vec<AxisFlex>,
    /// The poses the robot is measured at.
    #[serde(default, rename = "pose")]
    pub poses: Vec<PoseSpec>,
}

/// Which side of the gear the stiffnesses and dampings refer to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// The joint (link) side.
    Arm,
    /// The motor side: `k_arm = k_motor r^2`.
    Motor,
}

/// How bearing axes are given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BearingAxesFrame {
    /// Unit axes of the joint's frame after its rotation; the pair's first axis rotates
    /// first.
    JointFrame,
}

/// The units of the file's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum Units {
    /// N m/rad, N m s/rad, kg m^2, rad (poses in degrees, named `_deg`).
    #[serde(rename = "SI")]
    Si,
}

/// The conventions, all required: a file that does not state one is refused.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Conventions {
    pub stiffness_side: Side,
    pub bearing_axes: BearingAxesFrame,
    /// Whether the gravity stiffness acts on the bearing coordinates too.
    pub gravity_on_bearings: bool,
    pub units: Units,
}

/// A stiffness and its damping.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairValues {
    /// [N m/rad] on the stated side.
    pub stiffness: f64,
    /// [N m s/rad] on the stated side.
    pub damping: f64,
}

/// A bearing flexibility.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BearingValues {
    /// `x`, `y` or `z` of the joint's frame (orthogonal to the joint's axis).
    pub axis: AxisLetter,
    /// [N m/rad] on the stated side.
    pub stiffness: f64,
    /// [N m s/rad] on the stated side.
    pub damping: f64,
}

/// An axis letter as written in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AxisLetter {
    X,
    Y,
    Z,
}

impl From<AxisLetter> for BearingAxis {
    fn from(a: AxisLetter) -> Self {
        match a {
            AxisLetter::X => BearingAxis::X,
            AxisLetter::Y => BearingAxis::Y,
            AxisLetter::Z => BearingAxis::Z,
        }
    }
}

/// One motor with its gear and the bearing flexibilities after its joint.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisFlex {
    /// The URDF joint it drives.
    pub joint: String,
    /// Rotor inertia on the motor side [kg m^2].
    pub motor_inertia_kgm2: f64,
    /// Motor angle / joint angle [-].
    pub gear_ratio: f64,
    /// The gear's spring-damper.
    pub gear: PairValues,
    /// Bearing flexibilities after the joint (none, or two orthogonal ones).
    #[serde(default)]
    pub bearings: Vec<BearingValues>,
}

/// What a measured pose is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PoseRole {
    Identification,
    Validation,
}

/// A pose the robot is measured at.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    pub name: String,
    pub role: PoseRole,
    /// Joint angles [deg], one per axis.
    pub q_deg: Vec<f64>,
}

impl FlexFile {
    /// Parses and checks a flexibility file's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, FlexFileError> {
        let f: FlexFile = toml::from_str(text).map_err(|source| FlexFileError::Syntax {
            origin: origin.to_string(),
            source,
        })?;
        f.check(origin)?;
        Ok(f)
    }

    /// The file's values are physical: positive inertias, ratios and stiffnesses,
    /// non-negative dampings, bearing pairs of two different axes, poses of one angle per
    /// axis.
    fn check(&self, origin: &str) -> Result<(), FlexFileError> {
        let bad = |what: String, detail: &str| FlexFileError::Invalid {
            origin: origin.to_string(),
            what,
            detail: detail.to_string(),
        };
        if self.axes.is_empty() {
            return Err(bad(
                "[[axis]]".into(),
                "is missing: a robot needs at least one axis",
            ));
        }
        for (i, a) in self.axes.iter().enumerate() {
            let at = |key: &str| format!("axis {} ({}) {key}", i + 1, a.joint);
            for (key, v) in [
                ("motor_inertia_kgm2", a.motor_inertia_kgm2),
                ("gear_ratio", a.gear_ratio),
                ("gear.stiffness", a.gear.stiffness),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(bad(at(key), &format!("= {v} must be positive and finite")));
                }
            }
            let dampings =
                std::iter::once(a.gear.damping).chain(a.bearings.iter().map(|b| b.damping));
            for v in dampings {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(bad(
                        at("damping"),
                        &format!("= {v} must be zero or positive and finite"),
                    ));
                }
            }
            for b in &a.bearings {
                if !(b.stiffness.is_finite() && b.stiffness > 0.0) {
                    return Err(bad(
                        at("bearing stiffness"),
                        &format!("= {} must be positive and finite", b.stiffness),
                    ));
                }
            }
            match a.bearings.as_slice() {
                [] => {}
                [p, q] if p.axis != q.axis => {}
                _ => {
                    return Err(bad(
                        at("bearings"),
                        "must be none or two about different axes (a pair of orthogonal bearing flexibilities)",
                    ))
                }
            }
        }
        for p in &self.poses {
            if p.q_deg.len() != self.axes.len() || p.q_deg.iter().any(|q| !q.is_finite()) {
                return Err(bad(
                    format!("pose {}", p.name),
                    &format!(
                        "needs {} finite joint angles, has {:?}",
                        self.axes.len(),
                        p.q_deg
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The factor that takes the file's stiffnesses and dampings of axis `i` to the arm
    /// side: 1, or `r^2` for motor-side values.
    pub fn to_arm_side(&self, i: usize) -> f64 {
        match self.conventions.stiffness_side {
            Side::Arm => 1.0,
            Side::Motor => self.axes[i].gear_ratio.powi(2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = r#"
name = "two axes"
urdf = "two.urdf"
[conventions]
stiffness_side = "motor"
bearing_axes = "joint_frame"
gravity_on_bearings = true
units = "SI"
[[axis]]
joint = "j1"
motor_inertia_kgm2 = 1e-3
gear_ratio = 100.0
gear = { stiffness = 50.0, damping = 0.01 }
bearings = [ { axis = "x", stiffness = 100.0, damping = 0.02 }, { axis = "y", stiffness = 120.0, damping = 0.02 } ]
[[axis]]
joint = "j2"
motor_inertia_kgm2 = 5e-4
gear_ratio = 80.0
gear = { stiffness = 30.0, damping = 0.01 }
[[pose]]
name = "a"
role = "identification"
q_deg = [0, 45]
"#;

    #[test]
    fn the_example_parses_with_its_conventions() {
        let f = FlexFile::parse(EXAMPLE, "example").unwrap();
        assert_eq!(f.axes.len(), 2);
        assert_eq!(f.axes[0].bearings[1].axis, AxisLetter::Y);
        assert_eq!(f.poses[0].role, PoseRole::Identification);
        // motor-side values go to the arm side by r^2
        assert_eq!(f.to_arm_side(0), 1e4);
        assert_eq!(f.to_arm_side(1), 6400.0);
    }

    #[test]
    fn files_that_do_not_state_a_convention_or_are_not_physical_are_refused() {
        let no_convention = EXAMPLE.replace("gravity_on_bearings = true\n", "");
        let e = FlexFile::parse(&no_convention, "f.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f.toml") && e.contains("gravity_on_bearings"),
            "{e}"
        );
        let negative = EXAMPLE.replace("stiffness = 50.0", "stiffness = -50.0");
        let e = FlexFile::parse(&negative, "f.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("axis 1 (j1) gear.stiffness"), "{e}");
        let same_axes = EXAMPLE.replace(r#"axis = "y""#, r#"axis = "x""#);
        let e = FlexFile::parse(&same_axes, "f.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("bearings"), "{e}");
        let short_pose = EXAMPLE.replace("q_deg = [0, 45]", "q_deg = [0]");
        let e = FlexFile::parse(&short_pose, "f.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pose a"), "{e}");
        let unknown = EXAMPLE.replace("units = \"SI\"", "units = \"SI\"\nside = 1");
        assert!(FlexFile::parse(&unknown, "f.toml").is_err());
    }
}
