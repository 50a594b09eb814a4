use super::*;
use crate::manipulator::pose::Motor;
use crate::manipulator::springs::{Spring, SpringKind};
use crate::manipulator::tests_support::two_axis_pose;

/// The same model as a first-order state space `x' = A x + B u`, `v = C x` built with
/// nalgebra (from [`second_order`](crate::manipulator::sampled::second_order), not the
/// plan's per-line assembly), its FRF
/// `C (sI - A)^-1 B` by nalgebra's LU: the independent reference.
fn state_space_frf(pose: &RigidPose, theta: &Flexibilities, f_hz: f64) -> DMatrix<Complex64> {
    let na = pose.arm_coords();
    let ax = pose.axes();
    let n = na + ax;
    // the matrices the sampled plant uses, assembled apart from the plan's per-line Z
    let (m, c, k) = crate::manipulator::sampled::second_order(pose, theta);
    let minv = m.clone().try_inverse().unwrap();
    let mut a = DMatrix::<f64>::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n))
        .copy_from(&DMatrix::identity(n, n));
    a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * &k));
    a.view_mut((n, n), (n, n)).copy_from(&(-&minv * &c));
    let mut bu = DMatrix::<f64>::zeros(n, ax);
    for (i, mo) in pose.motors.iter().enumerate() {
        bu[(na + i, i)] = mo.gear_ratio;
    }
    let mut b = DMatrix::<f64>::zeros(2 * n, ax);
    b.view_mut((n, 0), (n, ax)).copy_from(&(&minv * &bu));
    let mut cy = DMatrix::<f64>::zeros(ax, 2 * n);
    for (i, mo) in pose.motors.iter().enumerate() {
        cy[(i, n + na + i)] = mo.gear_ratio;
    }
    let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz);
    let sia = DMatrix::<Complex64>::identity(2 * n, 2 * n) * s - a.map(|x| Complex64::new(x, 0.0));
    let x = sia.lu().solve(&b.map(|x| Complex64::new(x, 0.0))).unwrap();
    cy.map(|x| Complex64::new(x, 0.0)) * x
}

fn max_rel(a: &DMatrix<Complex64>, b: &DMatrix<Complex64>) -> f64 {
    let scale = b.iter().map(|x| x.norm()).fold(0.0, f64::max);
    a.iter()
        .zip(b.iter())
        .map(|(x, y)| (x - y).norm() / scale)
        .fold(0.0, f64::max)
}

#[test]
fn the_frf_equals_the_state_space_one() {
    for seed in 0..5 {
        let (pose, theta) = two_axis_pose(seed);
        let mut plan = FrfPlan::new(&pose);
        let freqs: Vec<f64> = (0..60).map(|i| 0.5 * 1.1f64.powi(i)).collect();
        let model = plan.frf(&freqs, &theta).unwrap();
        for (f, g) in freqs.iter().zip(&model.g) {
            let reference = state_space_frf(&pose, &theta, *f);
            let e = max_rel(g, &reference);
            assert!(e < 1e-9, "seed {seed}, {f} Hz: {e:e}");
            // reciprocity: the paper's eq. (13)
            assert!(max_rel(&g.transpose(), g) < 1e-9, "seed {seed}, {f} Hz");
        }
    }
}

/// One axis with no bearing pair is the project's two-mass chain (motor `J_m r^2`, arm
/// `J_a`, the gear between them): its motor mobility times `r^2` on the motor side.
#[test]
fn one_axis_is_the_two_mass_chain() {
    let (jm, r, ja, k, c) = (3e-4, 100.0, 12.0, 4e5, 60.0);
    let pose = RigidPose::new(
        DMatrix::from_element(1, 1, ja),
        DMatrix::zeros(1, 1),
        vec![Motor {
            rotor_inertia_kgm2: jm,
            gear_ratio: r,
        }],
        vec![Spring {
            kind: SpringKind::Gear { joint: 0 },
            arm_coord: 0,
        }],
    )
    .unwrap();
    let theta = Flexibilities::new(vec![k], vec![c]).unwrap();
    let chain = crate::model::Chain::new(vec![jm * r * r, ja], vec![k], vec![c]).unwrap();
    let mut plan = FrfPlan::new(&pose);
    let mut g = [Complex64::new(0.0, 0.0)];
    for f in [0.3, 3.0, 17.0, 30.0, 31.5, 90.0, 400.0] {
        plan.frf_into(f, &theta, &mut g).unwrap();
        let reference = chain.mobility(f) * r * r;
        assert!(
            (g[0] - reference).norm() < 1e-10 * reference.norm(),
            "{f} Hz: {} vs {reference}",
            g[0]
        );
    }
}

/// The analytic derivatives equal central differences in the logarithms.
#[test]
fn derivatives_equal_central_differences() {
    let (pose, theta) = two_axis_pose(3);
    let mut plan = FrfPlan::new(&pose);
    let ax = plan.axes();
    let nn = ax * ax;
    let np = 2 * plan.pairs();
    let mut g = vec![Complex64::new(0.0, 0.0); nn];
    let mut dg = vec![Complex64::new(0.0, 0.0); np * nn];
    let (mut gp, mut gm) = (g.clone(), g.clone());
    let log = theta.to_log();
    for f in [2.0, 25.0, 60.0, 140.0] {
        plan.frf_and_derivatives_into(f, &theta, &mut g, &mut dg)
            .unwrap();
        for p in 0..np {
            let h = 1e-6;
            let mut t = log.clone();
            t[p] += h;
            plan.frf_into(f, &Flexibilities::from_log(&t), &mut gp)
                .unwrap();
            t[p] -= 2.0 * h;
            plan.frf_into(f, &Flexibilities::from_log(&t), &mut gm)
                .unwrap();
            let scale = g.iter().map(|x| x.norm()).fold(0.0, f64::max);
            for e in 0..nn {
                let fd = (gp[e] - gm[e]) / (2.0 * h);
                let d = (fd - dg[p * nn + e]).norm();
                assert!(
                    d < 1e-6 * scale,
                    "{f} Hz, parameter {p}, element {e}: {d:e}"
                );
            }
        }
    }
}

#[test]
fn a_pose_with_a_coordinate_held_twice_is_refused() {
    let (pose, _) = two_axis_pose(1);
    let mut springs = pose.springs.clone();
    springs[1].arm_coord = 1;
    let e = RigidPose::new(
        pose.arm_mass.clone(),
        pose.gravity_stiffness.clone(),
        pose.motors.clone(),
        springs,
    );
    assert!(
        matches!(e, Err(ManipulatorError::Coordinate { .. })),
        "{e:?}"
    );
    let e = RigidPose::new(
        pose.arm_mass.clone(),
        DMatrix::zeros(3, 3),
        pose.motors.clone(),
        pose.springs.clone(),
    );
    assert!(matches!(e, Err(ManipulatorError::Shape { .. })), "{e:?}");
}

/// The largest difference of `a` from `b`, relative to the largest element of `b`.
fn rel(a: &[Complex64], b: &[Complex64]) -> f64 {
    let scale = b.iter().map(|x| x.norm()).fold(0.0, f64::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm() / scale)
        .fold(0.0, f64::max)
}

/// The FRF and its derivatives of `plan` and of the full-form reference at `f_hz`, the
/// largest difference relative to the largest element of each.
fn reduced_against_full(pose: &RigidPose, theta: &Flexibilities, f_hz: &[f64]) -> (f64, f64) {
    let mut plan = FrfPlan::new(pose);
    let mut reference = FrfPlan::full_form(pose);
    let nn = plan.axes() * plan.axes();
    let np = 2 * plan.pairs();
    let zero = Complex64::new(0.0, 0.0);
    let (mut g, mut dg) = (vec![zero; nn], vec![zero; np * nn]);
    let (mut gr, mut dgr) = (g.clone(), dg.clone());
    let (mut worst_g, mut worst_dg) = (0.0f64, 0.0f64);
    for &f in f_hz {
        plan.frf_and_derivatives_into(f, theta, &mut g, &mut dg)
            .unwrap();
        reference
            .frf_and_derivatives_into(f, theta, &mut gr, &mut dgr)
            .unwrap();
        worst_g = worst_g.max(rel(&g, &gr));
        worst_dg = worst_dg.max(rel(&dg, &dgr));
        // frf_into takes the same path
        let mut g1 = vec![zero; nn];
        plan.frf_into(f, theta, &mut g1).unwrap();
        assert_eq!(g1, g);
    }
    (worst_g, worst_dg)
}

/// The motors eliminated (the plan's `n_a x n_a` solve) give the full `Z`'s FRF and
/// derivatives: the made-up arms over 0.5-500 Hz, and the reference robot's two
/// identification poses on the benchmark's lines.
#[test]
fn the_reduced_solve_equals_the_full_one() {
    let freqs: Vec<f64> = (0..70).map(|i| 0.5 * 1.105f64.powi(i)).collect();
    for seed in 0..5 {
        let (pose, theta) = two_axis_pose(seed);
        let (eg, edg) = reduced_against_full(&pose, &theta, &freqs);
        assert!(eg < 1e-10 && edg < 1e-10, "seed {seed}: {eg:e} {edg:e}");
    }
    let robot = crate::manipulator::reference::robot();
    let truth = crate::manipulator::reference::perturbed_truth(&robot);
    let lines: Vec<f64> = (0..299)
        .map(|i| 2.0 * 100f64.powf(i as f64 / 298.0))
        .collect();
    for (_, q) in robot.poses_of(crate::manipulator::flex_file::PoseRole::Identification) {
        let pose = robot.pose(&q).unwrap();
        for theta in [&truth, &robot.nominal] {
            let (eg, edg) = reduced_against_full(&pose, theta, &lines);
            assert!(eg < 1e-10 && edg < 1e-10, "{eg:e} {edg:e}");
        }
    }
}

/// An undamped gear exactly at its motor's resonance with the arm held
/// (`d = s^2 m + k = 0`): the motors are not eliminated there (the full form answers), and
/// close to it the reduced form keeps its precision.
#[test]
fn a_motor_at_its_own_resonance_takes_the_full_form() {
    let (pose, mut theta) = two_axis_pose(2);
    let m = pose.motors[0].arm_side_inertia_kgm2();
    // gear of axis 0: pair 2
    theta.damping_nms_per_rad[2] = 0.0;
    let f0 = (theta.stiffness_nm_per_rad[2] / m).sqrt() / (2.0 * std::f64::consts::PI);
    let freqs = [f0, f0 * (1.0 + 1e-9), f0 * (1.0 + 1e-5), f0 * 1.01];
    let (eg, edg) = reduced_against_full(&pose, &theta, &freqs);
    assert!(eg < 1e-9 && edg < 1e-9, "{eg:e} {edg:e}");
}

/// The worst differences, relative to each line's largest element, of the lines solved
/// together ([`FrfPlan::frf_lines_into`], [`FrfPlan::frf_and_pair_rows_lines_into`])
/// against the full form solved line by line: of `G` from the cost pass's rows, of `G`
/// and of the derivatives `factor a_s^T a_s` from the derivatives' pass.
fn batched_against_full(pose: &RigidPose, theta: &Flexibilities, f_hz: &[f64]) -> [f64; 3] {
    let mut plan = FrfPlan::new(pose);
    let mut reference = FrfPlan::full_form(pose);
    let (ax, np) = (plan.axes(), 2 * plan.pairs());
    let (nn, nr) = (ax * ax, plan.pairs() * ax);
    let zero = Complex64::new(0.0, 0.0);
    let lanes = LINES_PER_BATCH;
    let (mut g, mut g2) = (vec![zero; lanes * nn], vec![zero; lanes * nn]);
    let (mut rows, mut factors) = (vec![zero; lanes * nr], vec![zero; lanes * np]);
    let (mut gr, mut rr, mut fr) = (vec![zero; nn], vec![zero; nr], vec![zero; np]);
    let derivatives = |rows: &[Complex64], factors: &[Complex64]| -> Vec<Complex64> {
        (0..np)
            .flat_map(|p| {
                let a = &rows[(p % (np / 2)) * ax..(p % (np / 2) + 1) * ax];
                (0..nn).map(move |k| factors[p] * a[k / ax] * a[k % ax])
            })
            .collect()
    };
    let mut worst = [0.0f64; 3];
    for batch in f_hz.chunks(lanes) {
        plan.frf_lines_into(batch, theta, &mut g).unwrap();
        plan.frf_and_pair_rows_lines_into(batch, theta, &mut g2, &mut rows, &mut factors)
            .unwrap();
        for (lane, &f) in batch.iter().enumerate() {
            reference
                .frf_and_pair_rows_into(f, theta, &mut gr, &mut rr, &mut fr)
                .unwrap();
            let line = |x: &[Complex64], n: usize| x[lane * n..(lane + 1) * n].to_vec();
            worst[0] = worst[0].max(rel(&line(&g, nn), &gr));
            worst[1] = worst[1].max(rel(&line(&g2, nn), &gr));
            worst[2] = worst[2].max(rel(
                &derivatives(&line(&rows, nr), &line(&factors, np)),
                &derivatives(&rr, &fr),
            ));
        }
    }
    worst
}

/// The lines solved together (the symmetric elimination without pivoting, four lines a
/// vector) give the full `Z`'s FRF and derivatives to 1e-10: the made-up arms over
/// 0.5-500 Hz (batches of 4 and a last one of 2), and the reference robot's two
/// identification poses at the true and nominal springs and at every start of the
/// benchmark's 60 (which reach a factor 3 from the nominal values).
#[test]
fn the_batched_solve_equals_the_full_one() {
    let freqs: Vec<f64> = (0..70).map(|i| 0.5 * 1.105f64.powi(i)).collect();
    for seed in 0..5 {
        let (pose, theta) = two_axis_pose(seed);
        let w = batched_against_full(&pose, &theta, &freqs);
        assert!(w.iter().all(|&e| e < 1e-10), "seed {seed}: {w:?}");
    }
    let robot = crate::manipulator::reference::robot();
    let truth = crate::manipulator::reference::perturbed_truth(&robot);
    let lines: Vec<f64> = (0..299)
        .map(|i| 2.0 * 150f64.powf(i as f64 / 298.0))
        .collect();
    let starts = crate::manipulator::identify::start_design(
        &robot.nominal,
        &crate::manipulator::IdentifyOptions::default(),
    );
    let mut thetas = vec![truth, robot.nominal.clone()];
    thetas.extend(starts.iter().map(|s| Flexibilities::from_log(s)));
    let mut worst = [0.0f64; 3];
    let (mut pivoted, mut all) = (0, 0);
    for (_, q) in robot.poses_of(crate::manipulator::flex_file::PoseRole::Identification) {
        let pose = robot.pose(&q).unwrap();
        let mut batch = FrfPlan::new(&pose).batched.unwrap();
        for theta in &thetas {
            let w = batched_against_full(&pose, theta, &lines);
            for (a, b) in worst.iter_mut().zip(w) {
                *a = a.max(b);
            }
            for f in lines.chunks(LINES_PER_BATCH) {
                let solved = batch.solve(f, theta, batched::Rows::All);
                pivoted += solved[..f.len()].iter().filter(|s| !**s).count();
                all += f.len();
            }
        }
    }
    eprintln!("batched against full: worst {worst:?}; {pivoted} of {all} lines pivoted");
    assert!(worst.iter().all(|&e| e < 1e-10), "{worst:?}");
}

/// A line whose first pivot is zero (an undamped bearing at its own resonance with the
/// rest of the arm held: no elimination without pivoting solves it) is solved by the
/// pivoted LU, and the other lines of its batch by the batch.
#[test]
fn a_zero_pivot_takes_the_pivoted_solve() {
    let (pose, mut theta) = two_axis_pose(1);
    // bearing pair 0 on arm coordinate 1: the first unknown of the batched order
    theta.damping_nms_per_rad[0] = 0.0;
    let kb = pose.gravity_stiffness[(1, 1)] + theta.stiffness_nm_per_rad[0];
    let f0 = (kb / pose.arm_mass[(1, 1)]).sqrt() / (2.0 * std::f64::consts::PI);
    let mut plan = FrfPlan::new(&pose);
    let batch = plan.batched.as_mut().unwrap();
    let solved = batch.solve(&[f0 * 0.5, f0, f0 * 2.0], &theta, batched::Rows::All);
    assert_eq!(solved, [true, false, true, false]);
    let w = batched_against_full(&pose, &theta, &[f0 * 0.5, f0, f0 * 2.0]);
    assert!(w.iter().all(|&e| e < 1e-10), "{w:?}");
}

/// The AVX2 build of the batched solve and the plain one give the same bits.
#[test]
fn every_build_of_the_batch_gives_the_same_bits() {
    let robot = crate::manipulator::reference::robot();
    let truth = crate::manipulator::reference::perturbed_truth(&robot);
    let q = &robot.poses_of(crate::manipulator::flex_file::PoseRole::Identification)[0].1;
    let pose = robot.pose(q).unwrap();
    let mut a = FrfPlan::new(&pose).batched.unwrap();
    let mut b = a.clone();
    let f = [3.0, 17.5, 60.0, 211.0];
    let sa = a.solve(&f, &truth, batched::Rows::All);
    let sb = b.solve_here(&f, &truth, batched::Rows::All);
    assert_eq!(sa, sb);
    let (mut xa, mut xb) = (
        vec![Complex64::new(0.0, 0.0); 18 * 6],
        vec![Complex64::new(1.0, 0.0); 18 * 6],
    );
    for lane in 0..LINES_PER_BATCH {
        a.x_into(lane, &mut xa);
        b.x_into(lane, &mut xb);
        assert_eq!(xa, xb);
    }
}

/// The derivatives' pass from the cost pass's kept solve
/// ([`FrfPlan::frf_lines_keep_into`], then [`FrfPlan::frf_and_pair_rows_lines_kept_into`])
/// gives the same bits as its fresh solve ([`FrfPlan::frf_and_pair_rows_lines_into`]), and
/// the cost pass the same `G` as [`FrfPlan::frf_lines_into`]: the reference robot's poses
/// at the truth and at a start, batches of four and a last one of three, two kept batches
/// alive at once, and a made-up arm with a lane that takes the pivoted solve.
#[test]
fn the_kept_solve_gives_the_fresh_bits() {
    let robot = crate::manipulator::reference::robot();
    let truth = crate::manipulator::reference::perturbed_truth(&robot);
    let start = crate::manipulator::identify::start_design(
        &robot.nominal,
        &crate::manipulator::IdentifyOptions::default(),
    )[7]
    .clone();
    let lines: Vec<f64> = (0..23)
        .map(|i| 2.0 * 150f64.powf(i as f64 / 22.0))
        .collect();
    let mut cases: Vec<(RigidPose, Flexibilities, Vec<f64>)> = Vec::new();
    for (_, q) in robot.poses_of(crate::manipulator::flex_file::PoseRole::Identification) {
        let pose = robot.pose(&q).unwrap();
        cases.push((pose.clone(), truth.clone(), lines.clone()));
        cases.push((pose, Flexibilities::from_log(&start), lines.clone()));
    }
    let (pose, mut theta) = two_axis_pose(1);
    theta.damping_nms_per_rad[0] = 0.0;
    let kb = pose.gravity_stiffness[(1, 1)] + theta.stiffness_nm_per_rad[0];
    let f0 = (kb / pose.arm_mass[(1, 1)]).sqrt() / (2.0 * std::f64::consts::PI);
    cases.push((
        pose,
        theta,
        vec![f0 * 0.5, f0, f0 * 2.0, f0 * 3.0, f0 * 4.0],
    ));
    for (pose, theta, f_hz) in &cases {
        let (mut kept, mut fresh) = (FrfPlan::new(pose), FrfPlan::new(pose));
        let (ax, np) = (kept.axes(), 2 * kept.pairs());
        let (nn, nr) = (ax * ax, kept.pairs() * ax);
        let zero = Complex64::new(0.0, 0.0);
        let lanes = LINES_PER_BATCH;
        let buffers = || {
            (
                vec![zero; lanes * nn],
                vec![zero; lanes * nr],
                vec![zero; lanes * np],
            )
        };
        let (mut gk, mut rk, mut fk) = buffers();
        let (mut gf, mut rf, mut ff) = buffers();
        let batches: Vec<&[f64]> = f_hz.chunks(lanes).collect();
        // every batch's cost pass first, then every batch's derivatives' pass
        for (b, f) in batches.iter().enumerate() {
            kept.frf_lines_keep_into(b, f, theta, &mut gk).unwrap();
            fresh.frf_lines_into(f, theta, &mut gf).unwrap();
            assert_eq!(gk, gf, "cost pass, batch {b}");
        }
        for (b, f) in batches.iter().enumerate() {
            kept.frf_and_pair_rows_lines_kept_into(b, f, theta, &mut gk, &mut rk, &mut fk)
                .unwrap();
            fresh
                .frf_and_pair_rows_lines_into(f, theta, &mut gf, &mut rf, &mut ff)
                .unwrap();
            assert_eq!((&gk, &rk, &fk), (&gf, &rf, &ff), "derivatives, batch {b}");
        }
    }
}
