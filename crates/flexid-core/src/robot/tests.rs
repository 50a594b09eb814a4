//! The dynamics against independent computations: RNEA columns, finite and complex-step
//! differences, energies from a forward kinematics of its own (4x4 complex matrices,
//! Rodrigues' formula: no code shared with the module), textbook closed forms, and the
//! URDF import against hand computations. Random serial robots (any axes, origins,
//! revolute and prismatic joints, physical inertias, any gravity) and the reference arm
//! `robots/flexid-arm6.urdf`.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Matrix4, Rotation3, Translation3, Unit, UnitQuaternion,
    Vector3,
};
use num_complex::Complex64;
use rand::{rngs::StdRng, Rng, SeedableRng};

use super::*;

const ARM6: &str = include_str!("../../../../robots/flexid-arm6.urdf");

fn arm6() -> SerialRobot {
    SerialRobot::from_urdf_str(ARM6).expect("the reference arm parses")
}

/// Largest absolute difference relative to the largest absolute entry of `reference` (0
/// when both are exactly zero, as dg/dq of a lone prismatic joint).
fn rel_err(got: &DMatrix<f64>, reference: &DMatrix<f64>) -> f64 {
    (got - reference).amax() / reference.amax().max(f64::MIN_POSITIVE)
}

fn rel_err_v(got: &DVector<f64>, reference: &DVector<f64>) -> f64 {
    (got - reference).amax() / reference.amax().max(f64::MIN_POSITIVE)
}

fn random_rotation(rng: &mut StdRng) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(
        rng.random_range(-PI..PI),
        rng.random_range(-PI..PI),
        rng.random_range(-PI..PI),
    )
}

fn random_unit(rng: &mut StdRng) -> Unit<Vector3<f64>> {
    Unit::new_normalize(Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)) + Vector3::x() * 0.1)
}

/// A physical body: principal moments of a box, turned at random, off-origin centre.
fn random_inertial(rng: &mut StdRng) -> Inertial {
    let m = rng.random_range(0.5..20.0);
    let [a, b, c]: [f64; 3] = std::array::from_fn(|_| rng.random_range(0.05..0.6));
    let principal = Matrix3::from_diagonal(&Vector3::new(
        m * (b * b + c * c) / 12.0,
        m * (a * a + c * c) / 12.0,
        m * (a * a + b * b) / 12.0,
    ));
    let r = random_rotation(rng).to_rotation_matrix();
    Inertial {
        mass_kg: m,
        com_m: Vector3::from_fn(|_, _| rng.random_range(-0.4..0.4)),
        inertia_kgm2: r.matrix() * principal * r.matrix().transpose(),
    }
}

/// A random serial robot of `n` joints, about one in four prismatic.
fn random_robot(rng: &mut StdRng, n: usize) -> SerialRobot {
    let links = (0..n)
        .map(|i| Link {
            name: format!("l{i}"),
            joint: String::new(),
            origin: Isometry3::from_parts(
                Translation3::from(Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5))),
                random_rotation(rng),
            ),
            axis: random_unit(rng),
            kind: if rng.random_range(0.0..1.0) < 0.25 {
                JointKind::Prismatic
            } else {
                JointKind::Revolute
            },
            inertial: random_inertial(rng),
        })
        .collect();
    SerialRobot {
        base: None,
        links,
        gravity_mps2: random_unit(rng).into_inner() * 9.81,
    }
}

fn random_vec(rng: &mut StdRng, n: usize, half: f64) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(-half..half)).collect()
}

/// Random robots of 1 to 8 joints and the reference arm, each with a random pose.
fn cases(seed: u64, count: usize) -> Vec<(SerialRobot, Vec<f64>)> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..count)
        .map(|k| {
            let robot = if k % 4 == 0 {
                arm6()
            } else {
                let n = rng.random_range(1..=8);
                random_robot(&mut rng, n)
            };
            let q = random_vec(&mut rng, robot.dof(), PI);
            (robot, q)
        })
        .collect()
}

// --- An independent forward kinematics: homogeneous 4x4 matrices over complex numbers ---

type C4 = Matrix4<Complex64>;

fn complex(m: &Matrix4<f64>) -> C4 {
    m.map(|x| Complex64::new(x, 0.0))
}

/// Rotation by `angle` about the unit `axis` (Rodrigues: `I + sin K + (1 - cos) K^2`).
fn rodrigues(axis: &Vector3<f64>, angle: Complex64) -> C4 {
    let k = complex(&Matrix4::new(
        0.0, -axis.z, axis.y, 0.0, //
        axis.z, 0.0, -axis.x, 0.0, //
        -axis.y, axis.x, 0.0, 0.0, //
        0.0, 0.0, 0.0, 0.0,
    ));
    C4::identity() + k * angle.sin() + k * k * (Complex64::new(1.0, 0.0) - angle.cos())
}

/// Every link's homogeneous transform in the base frame at a complex pose.
fn fk_complex(robot: &SerialRobot, q: &[Complex64]) -> Vec<C4> {
    let mut t = C4::identity();
    robot
        .links
        .iter()
        .zip(q)
        .map(|(link, &qi)| {
            let axis = link.axis.into_inner();
            let motion = match link.kind {
                JointKind::Revolute => rodrigues(&axis, qi),
                JointKind::Prismatic => {
                    let mut m = C4::identity();
                    for r in 0..3 {
                        m[(r, 3)] = qi * axis[r];
                    }
                    m
                }
            };
            t = t * complex(&link.origin.to_homogeneous()) * motion;
            t
        })
        .collect()
}

/// Complex-step step: derivatives exact to rounding, `Im f(x + i h) / h`.
const CS: f64 = 1e-30;

/// The kinetic energy at (q, qd) from the complex-step velocities of the link frames:
/// `sum 0.5 m |v_c|^2 + 0.5 w^T (R I R^T) w`, `[w]x = dR/dt R^T` [J].
fn kinetic_energy(robot: &SerialRobot, q: &[f64], qd: &[f64]) -> f64 {
    let qc: Vec<Complex64> = q
        .iter()
        .zip(qd)
        .map(|(&a, &v)| Complex64::new(a, CS * v))
        .collect();
    let frames = fk_complex(robot, &qc);
    robot
        .links
        .iter()
        .zip(&frames)
        .map(|(link, t)| {
            let re = t.map(|z| z.re);
            let dot = t.map(|z| z.im / CS);
            let r = re.fixed_view::<3, 3>(0, 0).into_owned();
            let rdot = dot.fixed_view::<3, 3>(0, 0).into_owned();
            let w_skew = rdot * r.transpose();
            let w = Vector3::new(w_skew[(2, 1)], w_skew[(0, 2)], w_skew[(1, 0)]);
            let c = link.inertial.com_m;
            let v = rdot * c + dot.fixed_view::<3, 1>(0, 3);
            let i_world = r * link.inertial.inertia_kgm2 * r.transpose();
            0.5 * link.inertial.mass_kg * v.norm_squared() + 0.5 * w.dot(&(i_world * w))
        })
        .sum()
}

/// The potential energy `-sum m g0 . c` at a complex pose [J].
fn potential_energy(robot: &SerialRobot, q: &[Complex64]) -> Complex64 {
    let g0 = robot.gravity_mps2.map(|x| Complex64::new(x, 0.0));
    fk_complex(robot, q)
        .iter()
        .zip(&robot.links)
        .map(|(t, link)| {
            let c = link.inertial.com_m.map(|x| Complex64::new(x, 0.0));
            let c = t.fixed_view::<3, 3>(0, 0) * c + t.fixed_view::<3, 1>(0, 3);
            -c.dot(&g0) * link.inertial.mass_kg
        })
        .sum()
}

// --- The dynamics against each other and against the energies ---

#[test]
fn mass_matrix_is_the_rnea_response_to_unit_accelerations() {
    for (robot, q) in cases(1, 40) {
        let n = robot.dof();
        let zero = vec![0.0; n];
        let g = robot.inverse_dynamics(&q, &zero, &zero).unwrap();
        let m = robot.mass_matrix(&q).unwrap();
        let mut by_rnea = DMatrix::zeros(n, n);
        for i in 0..n {
            let mut e = zero.clone();
            e[i] = 1.0;
            by_rnea.set_column(i, &(robot.inverse_dynamics(&q, &zero, &e).unwrap() - &g));
        }
        let err = rel_err(&m, &by_rnea);
        assert!(err < 1e-12, "n = {n}: M against RNEA columns: {err:e}");
        // and g is RNEA at rest
        let err = rel_err_v(&robot.gravity_torque(&q).unwrap(), &g);
        assert!(err < 1e-12, "g against RNEA at rest: {err:e}");
    }
}

#[test]
fn gravity_stiffness_is_the_derivative_of_the_gravity_torque() {
    let h = 1e-5;
    for (robot, q) in cases(2, 40) {
        let n = robot.dof();
        let k = robot.gravity_stiffness(&q).unwrap();
        let mut fd = DMatrix::zeros(n, n);
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += h;
            qm[j] -= h;
            let col = (robot.gravity_torque(&qp).unwrap() - robot.gravity_torque(&qm).unwrap())
                / (2.0 * h);
            fd.set_column(j, &col);
        }
        let err = rel_err(&k, &fd);
        assert!(
            err < 1e-6,
            "n = {n}: dg/dq against central differences: {err:e}\n{k}\n{fd}"
        );
        assert!(
            (&k - k.transpose()).amax() <= 1e-12 * k.amax(),
            "dg/dq is a Hessian"
        );
    }
}

#[test]
fn kinetic_energy_of_the_mass_matrix_is_that_of_the_moving_bodies() {
    let mut rng = StdRng::seed_from_u64(3);
    for (robot, q) in cases(3, 40) {
        let qd = random_vec(&mut rng, robot.dof(), 2.0);
        let m = robot.mass_matrix(&q).unwrap();
        let v = DVector::from_column_slice(&qd);
        let from_m = 0.5 * v.dot(&(&m * &v));
        let from_bodies = kinetic_energy(&robot, &q, &qd);
        let err = (from_m - from_bodies).abs() / from_bodies;
        assert!(
            err < 1e-12,
            "kinetic energy {from_m} against {from_bodies}: {err:e}"
        );
    }
}

#[test]
fn gravity_torque_is_the_gradient_of_the_potential_energy() {
    for (robot, q) in cases(4, 40) {
        let n = robot.dof();
        let g = robot.gravity_torque(&q).unwrap();
        let grad = DVector::from_fn(n, |k, _| {
            let qc: Vec<Complex64> = (0..n)
                .map(|j| Complex64::new(q[j], if j == k { CS } else { 0.0 }))
                .collect();
            potential_energy(&robot, &qc).im / CS
        });
        let err = rel_err_v(&g, &grad);
        assert!(err < 1e-12, "g against dV/dq: {err:e}\n{g}\n{grad}");
    }
}

/// The Coriolis and centrifugal torques do no work against the change of the mass
/// matrix: `qd^T C qd = 0.5 qd^T dM/dt qd` (dM/dt by central differences along qd).
#[test]
fn velocity_torques_balance_the_power_of_the_changing_mass_matrix() {
    let mut rng = StdRng::seed_from_u64(5);
    let h = 1e-6;
    for (robot, q) in cases(5, 40) {
        let n = robot.dof();
        let qd = random_vec(&mut rng, n, 2.0);
        let zero = vec![0.0; n];
        let c_qd = robot.inverse_dynamics(&q, &qd, &zero).unwrap()
            - robot.inverse_dynamics(&q, &zero, &zero).unwrap();
        let shifted = |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, v)| a + s * v).collect() };
        let m_dot = (robot.mass_matrix(&shifted(h)).unwrap()
            - robot.mass_matrix(&shifted(-h)).unwrap())
            / (2.0 * h);
        let v = DVector::from_column_slice(&qd);
        let (lhs, rhs) = (v.dot(&c_qd), 0.5 * v.dot(&(&m_dot * &v)));
        let scale = v.dot(&(robot.mass_matrix(&q).unwrap() * &v)) * v.amax();
        assert!(
            (lhs - rhs).abs() < 1e-7 * scale,
            "qd C qd {lhs} against {rhs}"
        );
    }
}

#[test]
fn mass_matrix_is_symmetric_positive_definite() {
    for (robot, q) in cases(6, 60) {
        let m = robot.mass_matrix(&q).unwrap();
        assert_eq!(m, m.transpose());
        let chol = nalgebra::Cholesky::new(m.clone()).expect("positive definite");
        let d = chol.l().diagonal();
        assert!(d.iter().all(|&x| x > 0.0), "{m}");
    }
}

// --- Textbook closed forms ---

#[test]
fn a_pendulum_matches_its_closed_form() {
    let (m, l, iyy) = (3.0, 0.7, 0.05);
    let robot = SerialRobot {
        base: None,
        links: vec![Link {
            name: "pendulum".into(),
            joint: String::new(),
            origin: Isometry3::translation(0.0, 0.0, 1.0),
            axis: Vector3::y_axis(),
            kind: JointKind::Revolute,
            inertial: Inertial {
                mass_kg: m,
                com_m: Vector3::new(l, 0.0, 0.0),
                inertia_kgm2: Matrix3::from_diagonal(&Vector3::new(0.01, iyy, 0.04)),
            },
        }],
        gravity_mps2: Vector3::new(0.0, 0.0, -9.81),
    };
    for &q in &[0.0, 0.4, -1.2, 2.5] {
        // the centre at (l cos q, 0, 1 - l sin q): V = m 9.81 (1 - l sin q)
        let g = -m * 9.81 * l * f64::cos(q);
        let k = m * 9.81 * l * f64::sin(q);
        let j = iyy + m * l * l;
        let (qd, qdd) = (1.3, -0.7);
        assert!((robot.mass_matrix(&[q]).unwrap()[(0, 0)] - j).abs() < 1e-14);
        assert!((robot.gravity_torque(&[q]).unwrap()[0] - g).abs() < 1e-13);
        assert!((robot.gravity_stiffness(&[q]).unwrap()[(0, 0)] - k).abs() < 1e-13);
        let tau = robot.inverse_dynamics(&[q], &[qd], &[qdd]).unwrap()[0];
        assert!((tau - (j * qdd + g)).abs() < 1e-13);
    }
}

#[test]
fn a_planar_two_link_arm_matches_its_closed_form() {
    let (m1, m2, l1, lc1, lc2, i1, i2) = (4.0, 2.5, 0.8, 0.35, 0.3, 0.2, 0.07);
    let g0 = 9.81;
    let link = |origin: Isometry3<f64>, m: f64, lc: f64, izz: f64| Link {
        name: String::new(),
        joint: String::new(),
        origin,
        axis: Vector3::z_axis(),
        kind: JointKind::Revolute,
        inertial: Inertial {
            mass_kg: m,
            com_m: Vector3::new(lc, 0.0, 0.0),
            inertia_kgm2: Matrix3::from_diagonal(&Vector3::new(0.01, 0.02, izz)),
        },
    };
    let robot = SerialRobot {
        base: None,
        links: vec![
            link(Isometry3::identity(), m1, lc1, i1),
            link(Isometry3::translation(l1, 0.0, 0.0), m2, lc2, i2),
        ],
        gravity_mps2: Vector3::new(0.0, -g0, 0.0),
    };
    let mut rng = StdRng::seed_from_u64(7);
    for _ in 0..20 {
        let q = random_vec(&mut rng, 2, PI);
        let qd = random_vec(&mut rng, 2, 3.0);
        let qdd = random_vec(&mut rng, 2, 5.0);
        let (c2, s2) = (q[1].cos(), q[1].sin());
        let m11 = i1 + i2 + m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2.0 * l1 * lc2 * c2);
        let m12 = i2 + m2 * (lc2 * lc2 + l1 * lc2 * c2);
        let m22 = i2 + m2 * lc2 * lc2;
        let h = m2 * l1 * lc2 * s2;
        let g1 = (m1 * lc1 + m2 * l1) * g0 * q[0].cos() + m2 * lc2 * g0 * (q[0] + q[1]).cos();
        let g2 = m2 * lc2 * g0 * (q[0] + q[1]).cos();
        let tau = DVector::from_vec(vec![
            m11 * qdd[0] + m12 * qdd[1] - h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]) + g1,
            m12 * qdd[0] + m22 * qdd[1] + h * qd[0] * qd[0] + g2,
        ]);
        let m = DMatrix::from_row_slice(2, 2, &[m11, m12, m12, m22]);
        assert!(rel_err(&robot.mass_matrix(&q).unwrap(), &m) < 1e-14);
        let g = DVector::from_vec(vec![g1, g2]);
        assert!(rel_err_v(&robot.gravity_torque(&q).unwrap(), &g) < 1e-14);
        assert!(rel_err_v(&robot.inverse_dynamics(&q, &qd, &qdd).unwrap(), &tau) < 1e-13);
        let s1 = q[0].sin();
        let s12 = (q[0] + q[1]).sin();
        let k = DMatrix::from_row_slice(
            2,
            2,
            &[
                -(m1 * lc1 + m2 * l1) * g0 * s1 - m2 * lc2 * g0 * s12,
                -m2 * lc2 * g0 * s12,
                -m2 * lc2 * g0 * s12,
                -m2 * lc2 * g0 * s12,
            ],
        );
        assert!(rel_err(&robot.gravity_stiffness(&q).unwrap(), &k) < 1e-14);
    }
}

// --- Inserted joints ---

/// The paper's bearing flexibilities: two massless rotations orthogonal to joint i after
/// it; held at 0 they change nothing of the old joints' M, g and dg/dq.
#[test]
fn inserted_joints_held_at_zero_change_nothing() {
    let mut rng = StdRng::seed_from_u64(8);
    let rigid = arm6();
    for after in 0..rigid.dof() {
        let mut flexible = rigid.clone();
        // the axes orthogonal to joint `after`'s, in its frame
        let a = rigid.links[after].axis.into_inner();
        let bx = Unit::new_normalize(a.cross(&Vector3::new(0.3, -0.5, 0.8)));
        let by = Unit::new_normalize(a.cross(&bx));
        flexible.insert_joint(after, Link::massless_revolute("bx", bx));
        flexible.insert_joint(after + 1, Link::massless_revolute("by", by));
        // and one with an origin and a small mass of its own, after the last joint
        let mut odd = Link::massless_revolute("odd", random_unit(&mut rng));
        odd.origin = Isometry3::from_parts(
            Translation3::new(0.05, -0.02, 0.1),
            random_rotation(&mut rng),
        );
        odd.inertial = random_inertial(&mut rng);
        assert_eq!(flexible.links[after].inertial, Inertial::zero());
        assert_eq!(flexible.links[after + 1].inertial, Inertial::zero());
        assert_eq!(
            flexible.links[after + 2].inertial,
            rigid.links[after].inertial
        );
        let last = flexible.dof() - 1;
        let mut rigid = rigid.clone();
        let end = rigid.dof() - 1;
        rigid.links[end].inertial = rigid.links[end].inertial.combined(&odd.inertial);
        flexible.insert_joint(last, odd);
        assert_eq!(flexible.dof(), rigid.dof() + 3);
        // old joint j sits at index old[j] of the flexible robot
        let old: Vec<usize> = (0..rigid.dof())
            .map(|j| if j <= after { j } else { j + 2 })
            .collect();
        for _ in 0..5 {
            let q = random_vec(&mut rng, rigid.dof(), PI);
            let mut qf = vec![0.0; flexible.dof()];
            old.iter().zip(&q).for_each(|(&i, &v)| qf[i] = v);
            let pick =
                |m: &DMatrix<f64>| DMatrix::from_fn(q.len(), q.len(), |r, c| m[(old[r], old[c])]);
            let m = rigid.mass_matrix(&q).unwrap();
            assert!(rel_err(&pick(&flexible.mass_matrix(&qf).unwrap()), &m) < 1e-13);
            let g = rigid.gravity_torque(&q).unwrap();
            let gf = flexible.gravity_torque(&qf).unwrap();
            assert!(rel_err_v(&DVector::from_fn(q.len(), |r, _| gf[old[r]]), &g) < 1e-13);
            let k = rigid.gravity_stiffness(&q).unwrap();
            assert!(rel_err(&pick(&flexible.gravity_stiffness(&qf).unwrap()), &k) < 1e-13);
            // the bearings feel the arm: a non-zero mass matrix on their diagonal
            let mf = flexible.mass_matrix(&qf).unwrap();
            assert!(mf[(after + 1, after + 1)] > 0.0 && mf[(after + 2, after + 2)] > 0.0);
        }
    }
}

#[test]
#[should_panic(expected = "insert_joint")]
fn inserting_after_a_joint_that_is_not_there_panics() {
    let mut robot = arm6();
    robot.insert_joint(6, Link::massless_revolute("b", Vector3::x_axis()));
}

#[test]
fn wrong_lengths_are_errors() {
    let robot = arm6();
    let err = robot.mass_matrix(&[0.0; 5]).unwrap_err();
    assert!(
        matches!(
            err,
            RobotError::WrongLength {
                what: "q",
                got: 5,
                dof: 6
            }
        ),
        "{err}"
    );
    let err = robot
        .inverse_dynamics(&[0.0; 6], &[0.0; 6], &[0.0; 7])
        .unwrap_err();
    assert_eq!(err.to_string(), "qdd has 7 entries, the robot has 6 joints");
    assert!(robot.gravity_torque(&[]).is_err());
    assert!(robot.gravity_stiffness(&[0.0; 8]).is_err());
    assert!(robot.forward_kinematics(&[0.0; 2]).is_err());
}

// --- URDF import ---

#[test]
fn the_reference_arm_is_a_plausible_six_axis_robot() {
    let robot = arm6();
    assert_eq!(robot.dof(), 6);
    assert!(robot.links.iter().all(|l| l.kind == JointKind::Revolute));
    let axes: Vec<Vector3<f64>> = robot.links.iter().map(|l| l.axis.into_inner()).collect();
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    assert_eq!(axes, vec![z, y, y, x, y, x]);
    // the flange (1.5 kg) and the payload (10 kg) merged into the wrist rotor (5 kg);
    // the base 180 kg
    assert!((robot.moving_mass_kg() - 281.5).abs() < 1e-12);
    assert!((robot.links[5].inertial.mass_kg - 16.5).abs() < 1e-12);
    assert!((robot.base.unwrap().mass_kg - 180.0).abs() < 1e-12);
    for (name, inertial) in robot
        .links
        .iter()
        .map(|l| (l.name.as_str(), l.inertial))
        .chain(robot.base.map(|b| ("base", b)))
    {
        assert_eq!(inertial.unphysical(), None, "{name}");
        let i = inertial.inertia_kgm2;
        assert!(
            i[(0, 1)] != 0.0 && i[(0, 2)] != 0.0 && i[(1, 2)] != 0.0,
            "{name}: products"
        );
    }
    // reach: the flange 1.9 m from axis 1 with the arm stretched forward
    let stretched = robot
        .forward_kinematics(&[0.0, FRAC_PI_2, -FRAC_PI_2, 0.0, 0.0, 0.0])
        .unwrap();
    let wrist = stretched[5].translation.vector;
    assert!((1.7..2.0).contains(&wrist.x), "{wrist}");
    // gravity stiffness not trivial at the home pose
    let k = robot.gravity_stiffness(&[0.0; 6]).unwrap();
    assert!(k[(1, 1)].abs() > 100.0 && k[(4, 4)].abs() > 0.1, "{k}");
}

/// A fixed joint is a revolute joint held at 0: replacing the flange's fixed joint by one
/// leaves the other joints' M, g and dg/dq as they are.
#[test]
fn a_merged_fixed_joint_is_a_joint_held_at_zero() {
    let merged = arm6();
    let unmerged = SerialRobot::from_urdf_str(&ARM6.replace(
        r#"<joint name="flange_fixed" type="fixed">"#,
        r#"<joint name="flange_fixed" type="continuous"><axis xyz="0.3 0.5 -0.2"/>"#,
    ))
    .unwrap();
    assert_eq!(unmerged.dof(), 7);
    let mut rng = StdRng::seed_from_u64(9);
    for _ in 0..10 {
        let q = random_vec(&mut rng, 6, PI);
        let mut q7 = q.clone();
        q7.push(0.0);
        let cut = |m: DMatrix<f64>| m.view((0, 0), (6, 6)).into_owned();
        let m = merged.mass_matrix(&q).unwrap();
        assert!(rel_err(&cut(unmerged.mass_matrix(&q7).unwrap()), &m) < 1e-13);
        let g = merged.gravity_torque(&q).unwrap();
        assert!(
            rel_err_v(
                &unmerged
                    .gravity_torque(&q7)
                    .unwrap()
                    .rows(0, 6)
                    .into_owned(),
                &g
            ) < 1e-13
        );
        let k = merged.gravity_stiffness(&q).unwrap();
        assert!(rel_err(&cut(unmerged.gravity_stiffness(&q7).unwrap()), &k) < 1e-13);
    }
}

const TWO_BODIES: &str = r#"<robot name="t">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 2"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="a">
    <inertial><origin xyz="0.1 0 0"/><mass value="2"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.25"/></inertial>
  </link>
  <joint name="bolt" type="fixed">
    <parent link="a"/><child link="b"/>
    <origin xyz="0.4 0 0" rpy="0 0 1.5707963267948966"/>
  </joint>
  <link name="b">
    <inertial><origin xyz="0.2 0 0"/><mass value="3"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.04"/></inertial>
  </link>
  <joint name="j2" type="prismatic">
    <parent link="b"/><child link="c"/>
    <origin xyz="0 0.1 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="c">
    <inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
</robot>"#;

#[test]
fn a_fixed_joint_merges_by_the_parallel_axis_theorem() {
    let robot = SerialRobot::from_urdf_str(TWO_BODIES).unwrap();
    assert_eq!(robot.dof(), 2);
    assert_eq!(robot.base, None);
    assert_eq!(robot.links[0].name, "a");
    assert_eq!(robot.links[1].kind, JointKind::Prismatic);
    assert_eq!(robot.links[0].axis, Vector3::z_axis());
    let body = robot.links[0].inertial;
    // b's frame is at x = 0.4, turned 90 deg about z: its centre at (0.4, 0.2, 0) in a's
    // frame, its x and y moments swapped. a's centre at (0.1, 0, 0).
    assert!((body.mass_kg - 5.0).abs() < 1e-15);
    let com = Vector3::new((2.0 * 0.1 + 3.0 * 0.4) / 5.0, 3.0 * 0.2 / 5.0, 0.0);
    assert!((body.com_m - com).norm() < 1e-15, "{}", body.com_m);
    let (da, db) = (
        Vector3::new(0.1, 0.0, 0.0) - com,
        Vector3::new(0.4, 0.2, 0.0) - com,
    );
    // the parallel-axis theorem written out entry by entry
    let steiner = |m: f64, d: Vector3<f64>| {
        Matrix3::new(
            m * (d.y * d.y + d.z * d.z),
            -m * d.x * d.y,
            -m * d.x * d.z,
            -m * d.x * d.y,
            m * (d.x * d.x + d.z * d.z),
            -m * d.y * d.z,
            -m * d.x * d.z,
            -m * d.y * d.z,
            m * (d.x * d.x + d.y * d.y),
        )
    };
    let expected = Matrix3::from_diagonal(&Vector3::new(0.1, 0.2, 0.25))
        + steiner(2.0, da)
        + Matrix3::from_diagonal(&Vector3::new(0.03, 0.01, 0.04))
        + steiner(3.0, db);
    assert!(
        (body.inertia_kgm2 - expected).amax() < 1e-15,
        "{}",
        body.inertia_kgm2
    );
    // j2's origin composed with the bolt's: at (0.4, 0, 0) + Rz(90) (0, 0.1, 0) = (0.3, 0, 0)
    let o = robot.links[1].origin;
    assert!((o.translation.vector - Vector3::new(0.3, 0.0, 0.0)).norm() < 1e-15);
    assert!(
        o.rotation.angle_to(&UnitQuaternion::from_axis_angle(
            &Vector3::z_axis(),
            FRAC_PI_2
        )) < 1e-15
    );
}

#[test]
fn origin_rpy_is_roll_then_pitch_then_yaw_about_fixed_axes() {
    let (r, p, y): (f64, f64, f64) = (0.3, -0.2, 0.5);
    let urdf = format!(
        r#"<robot name="rpy"><link name="base"/>
        <joint name="j" type="continuous"><parent link="base"/><child link="l"/>
          <origin xyz="0.1 0.2 0.3" rpy="{r} {p} {y}"/><axis xyz="0 0 1"/></joint>
        <link name="l"><inertial><origin xyz="0.4 0 0" rpy="0 0 1.5707963267948966"/><mass value="1"/>
          <inertia ixx="1" ixy="0" ixz="0" iyy="2" iyz="0" izz="3"/></inertial></link>
        </robot>"#
    );
    let robot = SerialRobot::from_urdf_str(&urdf).unwrap();
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, r.cos(), -r.sin(), 0.0, r.sin(), r.cos());
    let ry = Matrix3::new(p.cos(), 0.0, p.sin(), 0.0, 1.0, 0.0, -p.sin(), 0.0, p.cos());
    let rz = Matrix3::new(y.cos(), -y.sin(), 0.0, y.sin(), y.cos(), 0.0, 0.0, 0.0, 1.0);
    let by_hand = rz * ry * rx;
    let pose = robot.forward_kinematics(&[0.0]).unwrap()[0];
    let got = pose.rotation.to_rotation_matrix();
    assert!((got.matrix() - by_hand).amax() < 1e-15, "{got}\n{by_hand}");
    // the centre of mass at q = 0.7: base + R_rpy Rz(0.7) (0.4, 0, 0)
    let q = 0.7;
    let rq = Rotation3::from_axis_angle(&Vector3::z_axis(), q);
    let com = Vector3::new(0.1, 0.2, 0.3) + by_hand * (rq * Vector3::new(0.4, 0.0, 0.0));
    let pose = robot.forward_kinematics(&[q]).unwrap()[0];
    assert!(
        (pose * nalgebra::Point3::from(robot.links[0].inertial.com_m)
            - nalgebra::Point3::from(com))
        .norm()
            < 1e-15
    );
    // the inertial's yaw of 90 deg swaps the tensor's x and y moments
    let expected = Matrix3::from_diagonal(&Vector3::new(2.0, 1.0, 3.0));
    assert!((robot.links[0].inertial.inertia_kgm2 - expected).amax() < 1e-15);
}

#[test]
fn a_branched_urdf_is_refused_naming_the_link() {
    let branched = TWO_BODIES.replace(
        "</robot>",
        r#"<joint name="side" type="revolute"><parent link="a"/><child link="d"/>
           <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
           <link name="d"/></robot>"#,
    );
    let err = SerialRobot::from_urdf_str(&branched).unwrap_err();
    match &err {
        RobotError::NotSerial { link, why } => {
            assert_eq!(link, "a");
            assert!(why.contains("bolt") && why.contains("side"), "{why}");
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("`a`"), "{err}");
}

#[test]
fn bad_urdfs_are_refused_with_the_reason() {
    let floating = TWO_BODIES.replace(
        r#"name="j2" type="prismatic""#,
        r#"name="j2" type="floating""#,
    );
    let err = SerialRobot::from_urdf_str(&floating).unwrap_err();
    assert!(
        matches!(&err, RobotError::UnsupportedJoint { joint, kind } if joint == "j2" && kind == "floating"),
        "{err}"
    );
    let missing = TWO_BODIES.replace(r#"<child link="c"/>"#, r#"<child link="nowhere"/>"#);
    let err = SerialRobot::from_urdf_str(&missing).unwrap_err();
    assert!(
        matches!(&err, RobotError::MissingLink { link, .. } if link == "nowhere"),
        "{err}"
    );
    let zero_axis = TWO_BODIES.replace(r#"<axis xyz="0 0 2"/>"#, r#"<axis xyz="0 0 0"/>"#);
    let err = SerialRobot::from_urdf_str(&zero_axis).unwrap_err();
    assert!(
        matches!(&err, RobotError::BadAxis { joint, .. } if joint == "j1"),
        "{err}"
    );
    let negative = TWO_BODIES.replace(r#"<mass value="3"/>"#, r#"<mass value="-3"/>"#);
    let err = SerialRobot::from_urdf_str(&negative).unwrap_err();
    assert!(
        matches!(&err, RobotError::BadInertial { link, .. } if link == "b"),
        "{err}"
    );
    let two_roots = TWO_BODIES.replace("</robot>", r#"<link name="stray"/></robot>"#);
    let err = SerialRobot::from_urdf_str(&two_roots).unwrap_err();
    assert!(
        matches!(&err, RobotError::NotSerial { link, .. } if link == "stray"),
        "{err}"
    );
    assert!(matches!(
        SerialRobot::from_urdf_str("<robot"),
        Err(RobotError::Urdf(_))
    ));
}
