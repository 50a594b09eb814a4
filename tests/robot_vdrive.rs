//! Issue 17, end to end: the reference robot simulated by `flexid-vdrive` (six CiA 402
//! drives, nodes 2-7, one coupled 18-DOF plant per pose) on an in-process CAN bus, driven
//! by the CANopen master's drive group (all set-points, one SYNC per cycle), measured
//! with orthogonal random-phase multisines under a 2 Hz holding loop closed over the bus;
//! the N x N FRF matrices of two identification poses identify the 18-DOF model (every
//! stiffness within 5 %), and the model matches the measurements of the twelve validation
//! poses (the paper's V per pose, reported; the complex error within the measurement's
//! uncertainty). The measured FRF matrix equals the simulated plant's own (its exact
//! sampled FRF) within its uncertainty.

use flexid_canopen::MasterConfig;
use flexid_core::frf::MimoFrf;
use flexid_core::manipulator::identify::{model_frf, FrfForm};
use flexid_core::manipulator::measure::MeasureOptions;
use flexid_core::manipulator::{
    identify, reference, Cost, CostSpec, Flexibilities, FlexibleRobot, IdentifyOptions,
    PoseMeasurement, PoseRole, RigidPose, SampledPose, Weighting,
};
use flexid_daemon::robot::{measure_pose, plan_pose, SimulatedRobot};
use flexid_sweep::Pacing;
use flexid_vdrive::robot::RobotDriveOptions;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

const FS_HZ: f64 = 1000.0;

/// The measurement: the core's reference measurement (1 Hz lines over 2-300 Hz, the
/// reference arm's multisine levels, 2 Hz loop), with one settling and four averaged
/// periods per experiment (30 s of robot time per pose).
fn options(seed: u64) -> MeasureOptions {
    MeasureOptions {
        transient_periods: 1,
        periods: 4,
        ..MeasureOptions::for_axes(6, FS_HZ, seed)
    }
}

/// Pose `name` at `q` measured through the simulated robot's drives on a bus.
fn measure_through_drives(
    robot: &FlexibleRobot,
    theta: &Flexibilities,
    name: &str,
    q: &[f64],
    seed: u64,
) -> (RigidPose, MimoFrf) {
    let pose = robot.pose(q).unwrap();
    let sim = SimulatedRobot::start(name, robot, q, theta, &RobotDriveOptions::default()).unwrap();
    let mut group = sim.enable_group(&MasterConfig::for_node(2)).unwrap();
    let plan = plan_pose(name, &pose, &options(seed), Pacing::Lockstep).unwrap();
    let t0 = Instant::now();
    let stop = AtomicBool::new(false);
    let (outcome, frf) = measure_pose(name, &mut group, &plan, &stop, &mut |_| {}).unwrap();
    let _ = group.disable();
    let lost: u64 = outcome.counters.iter().map(|c| c.lost).sum();
    eprintln!(
        "{name}: {} cycles through 6 drives in {:.1} s ({:.0} cycles/s), lost feedback {lost}",
        outcome.record.len(),
        t0.elapsed().as_secs_f64(),
        outcome.record.len() as f64 / t0.elapsed().as_secs_f64()
    );
    assert_eq!(lost, 0, "{name}");
    (pose, frf)
}

/// Every pose of `role`, two at a time (two threads, each its own bus).
fn measured(
    robot: &FlexibleRobot,
    theta: &Flexibilities,
    role: PoseRole,
) -> Vec<(String, RigidPose, MimoFrf)> {
    let poses = robot.poses_of(role);
    let mut out: Vec<Option<(String, RigidPose, MimoFrf)>> = vec![None; poses.len()];
    std::thread::scope(|s| {
        for (chunk, slots) in poses
            .chunks(poses.len().div_ceil(2))
            .zip(out.chunks_mut(poses.len().div_ceil(2)))
        {
            s.spawn(move || {
                for ((name, q), slot) in chunk.iter().zip(slots) {
                    let seed = 100 + name.bytes().map(u64::from).sum::<u64>();
                    let (pose, frf) = measure_through_drives(robot, theta, name, q, seed);
                    *slot = Some((name.clone(), pose, frf));
                }
            });
        }
    });
    out.into_iter().map(Option::unwrap).collect()
}

/// Mean `|G^ - G|^2 / var` over lines and elements: about one where `g` is right.
fn mean_z2(m: &PoseMeasurement, g: &[nalgebra::DMatrix<num_complex::Complex64>]) -> f64 {
    let var = m.var.as_ref().unwrap();
    let (mut s, mut n) = (0.0, 0usize);
    for (k, gk) in g.iter().enumerate() {
        for (e, x) in gk.iter().enumerate() {
            s += (m.g[k][e] - x).norm_sqr() / var[k][e];
            n += 1;
        }
    }
    s / n as f64
}

#[test]
fn the_robot_simulated_by_flexid_vdrive_is_identified_within_5_percent() {
    let robot = reference::robot();
    let truth = reference::perturbed_truth(&robot);
    let t0 = Instant::now();
    let id = measured(&robot, &truth, PoseRole::Identification);
    eprintln!(
        "identification poses measured in {:.1} s",
        t0.elapsed().as_secs_f64()
    );

    // the estimate equals the simulated plant's own FRF matrix within its uncertainty
    for (name, pose, frf) in &id {
        let plant = SampledPose::new(pose, &truth, FS_HZ).unwrap();
        let exact: Vec<_> = frf.freq_hz.iter().map(|&f| plant.frf(f).unwrap()).collect();
        let z2 = mean_z2(&PoseMeasurement::from_mimo(frf), &exact);
        eprintln!("{name}: measured vs the plant's exact sampled FRF: mean z2 {z2:.3}");
        assert!((0.8..1.25).contains(&z2), "{name}: {z2}");
    }

    let poses: Vec<_> = id.iter().map(|(_, p, _)| p.clone()).collect();
    let meas: Vec<_> = id
        .iter()
        .map(|(_, _, f)| PoseMeasurement::from_mimo(f))
        .collect();
    let spec = CostSpec {
        weighting: Weighting::InverseVariance,
        ..CostSpec::default()
    };
    let cost = Cost::new(&meas, spec.clone()).unwrap();
    let form = FrfForm::Sampled { fs_hz: FS_HZ };
    let t1 = Instant::now();
    let result = identify(
        &poses,
        &cost,
        &robot.nominal,
        &IdentifyOptions {
            starts: 4,
            form,
            ..IdentifyOptions::default()
        },
    )
    .unwrap();
    eprintln!(
        "identified in {:.1} s; V per pose {:?}",
        t1.elapsed().as_secs_f64(),
        result.cost_per_pose
    );
    let names = robot.parameter_names();
    for (j, (k, t)) in result
        .best
        .stiffness_nm_per_rad
        .iter()
        .zip(&truth.stiffness_nm_per_rad)
        .enumerate()
    {
        eprintln!(
            "{}: {k:.4e} for {t:.4e} ({:+.3} %)",
            names[j],
            100.0 * (k / t - 1.0)
        );
        assert!(
            (k / t - 1.0).abs() < 0.05,
            "{}: {k:.4e} for {t:.4e}",
            names[j]
        );
    }
    for (j, name) in names.iter().enumerate() {
        assert_eq!(result.identifiable(j), Some(true), "{name}");
    }

    // validation on the twelve other poses
    let val = measured(&robot, &truth, PoseRole::Validation);
    assert_eq!(val.len(), 12);
    for (name, pose, frf) in &val {
        let m = PoseMeasurement::from_mimo(frf);
        let c = Cost::new(std::slice::from_ref(&m), spec.clone()).unwrap();
        let g =
            |theta: &Flexibilities| model_frf(std::slice::from_ref(pose), &c, theta, form).unwrap();
        let (g_fit, g_truth) = (g(&result.best), g(&truth));
        let (v_fit, v_truth) = (c.value(&g_fit), c.value(&g_truth));
        let (z_fit, z_truth) = (mean_z2(&m, &g_fit[0]), mean_z2(&m, &g_truth[0]));
        eprintln!(
            "{name}: V {v_fit:.4} dB (true springs {v_truth:.4}); mean z2 {z_fit:.3} (true springs {z_truth:.3})"
        );
        assert!((0.8..1.25).contains(&z_truth), "{name}: {z_truth}");
        assert!(
            v_fit <= 1.1 * v_truth,
            "{name}: V {v_fit} against {v_truth}"
        );
        assert!(z_fit <= 2.0, "{name}: mean z2 {z_fit}");
    }
}
