use super::*;

use crate::manipulator::reference::{FLEX, URDF};

fn reference_robot() -> FlexibleRobot {
    crate::manipulator::reference::robot()
}

/// Undamped natural frequencies [Hz] of a pose (the generalised eigenvalues of `K`, `M`;
/// negative ones, gravity's unstable directions, as negative frequencies).
fn natural_frequencies(pose: &RigidPose, theta: &Flexibilities) -> Vec<f64> {
    let (m, _, k) = crate::manipulator::sampled::second_order(pose, theta);
    let l = m.cholesky().unwrap().l();
    let linv = l.try_inverse().unwrap();
    let a = &linv * k * linv.transpose();
    let a = (&a + a.transpose()) * 0.5;
    let mut f: Vec<f64> = a
        .symmetric_eigenvalues()
        .iter()
        .map(|&l| l.signum() * l.abs().sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    f.sort_by(f64::total_cmp);
    f
}

/// The reference robot at every pose of its file: six modes near zero frequency (the
/// rigid body held by gravity's stiffness alone: real poles of a few tenths of a hertz,
/// which the position loop stabilises) and twelve flexible modes inside the band the
/// measurement excites (2-300 Hz), the lowest at 10-20 Hz as on arms of its class.
#[test]
fn the_reference_robots_modes_lie_in_the_measured_band() {
    let r = reference_robot();
    assert_eq!(r.arm.dof(), 12);
    assert_eq!(r.springs.len(), 12);
    assert_eq!(r.parameter_names()[0], "k_b1x");
    assert_eq!(r.parameter_names()[23], "c_g6");
    let all: Vec<_> = r
        .poses_of(PoseRole::Identification)
        .into_iter()
        .chain(r.poses_of(PoseRole::Validation))
        .collect();
    assert_eq!(all.len(), 14);
    for (name, q) in all {
        let f = natural_frequencies(&r.pose(&q).unwrap(), &r.nominal);
        assert!(f[..6].iter().all(|f| f.abs() < 1.0), "{name}: {f:?}");
        assert!(
            f[6..].iter().all(|f| (5.0..300.0).contains(f)),
            "{name}: {f:?}"
        );
        assert!((10.0..20.0).contains(&f[6]), "{name}: {f:?}");
    }
}

/// A bearing axis along the joint's own axis is refused, naming the axis.
#[test]
fn a_bearing_along_the_joint_axis_is_refused() {
    let rigid = SerialRobot::from_urdf_str(URDF).unwrap();
    let bad = FLEX.replacen(
        r#"axis = "y", stiffness = 1.6e6"#,
        r#"axis = "z", stiffness = 1.6e6"#,
        1,
    );
    let file = FlexFile::parse(&bad, "bad.toml").unwrap();
    let e = FlexibleRobot::new(rigid, &file).unwrap_err().to_string();
    assert!(
        e.contains("axis 1 (joint_1)") && e.contains("orthogonal"),
        "{e}"
    );
}
