//! A whole robot on one bus: the six drives of the reference arm (nodes 2-7, one coupled
//! plant) against the CANopen master's `DriveGroup` (all six set-points, one SYNC, all
//! feedback per cycle) on an in-process bus. The arm is held by a 2 Hz position loop
//! closed over the bus; the motor positions the master receives equal the sampled plant
//! replayed offline with the set-points the master sent, within half an encoder increment,
//! on every axis, with no lag; and a torque on axis 1 alone moves the other motors (the
//! coupling is there).

use flexid_can::InprocBus;
use flexid_canopen::{bring_up, DriveGroup, Feedback, MasterConfig, ProfileSet};
use flexid_core::manipulator::{reference, PoseRole, PositionLoop, SampledPose};
use flexid_vdrive::robot::{robot_drives, RobotDriveOptions};
use flexid_vdrive::Runner;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn the_master_cycles_a_coupled_six_axis_robot_with_one_sync() {
    let robot = reference::robot();
    let (_, q) = robot.poses_of(PoseRole::Identification)[1].clone();
    let pose = robot.pose(&q).unwrap();
    let opts = RobotDriveOptions::default();
    let (set, _plant) = robot_drives(&robot, &q, &robot.nominal, &opts).unwrap();
    assert_eq!(set.node_ids(), vec![2, 3, 4, 5, 6, 7]);
    let bus = InprocBus::new("robot");
    let h = bus.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let th = std::thread::spawn(move || Runner::new(h, set).run(&s2).unwrap());
    let profiles = ProfileSet::builtin();
    let drives: Vec<_> = (0..6u8)
        .map(|i| bring_up(bus.handle(), MasterConfig::for_node(2 + i), &profiles).unwrap())
        .collect();
    let mut group = DriveGroup::enable(drives).expect("enable");
    let fs = 1000.0;
    let hold = PositionLoop::for_pose(&pose, 2.0);
    let n = 1500;
    let axes = 6;
    let mut fb = vec![Feedback::none(Instant::now()); axes];
    let (mut p, mut p_prev, mut loop_t) = (vec![0.0; axes], vec![0.0; axes], vec![0.0; axes]);
    let mut sent = vec![vec![0.0; axes]; n];
    let mut got = vec![vec![0.0; axes]; n];
    let mut tq = vec![0.0; axes];
    for k in 0..n {
        hold.torque(&p, &p_prev, fs, &mut loop_t);
        for i in 0..axes {
            // a torque pulse train on axis 1 only (the others: the loop's torque)
            let drive = if i == 0 && (k / 100) % 2 == 1 && k < 1000 {
                0.5
            } else {
                0.0
            };
            tq[i] = loop_t[i] + drive;
        }
        group
            .cycle(&tq, Instant::now() + Duration::from_millis(500), &mut fb)
            .expect("cycle");
        for i in 0..axes {
            assert!(fb[i].fresh, "cycle {k} axis {i}");
            assert_eq!(fb[i].cycle, k as u64);
            sent[k][i] = fb[i].torque_setpoint_nm;
            got[k][i] = fb[i].position_rad;
        }
        p_prev.copy_from_slice(&p);
        for i in 0..axes {
            p[i] = fb[i].position_rad;
        }
    }
    let _ = group.disable();
    stop.store(true, Ordering::Relaxed);
    th.join().unwrap();

    // the sampled plant replayed with what was sent: feedback k is the state before
    // set-point k acts
    let mut plant = SampledPose::new(&pose, &robot.nominal, fs).unwrap();
    let mut x = vec![0.0; plant.states()];
    let mut want = vec![0.0; axes];
    let quantum = std::f64::consts::TAU / f64::from(1u32 << 20);
    let mut worst = 0.0f64;
    let mut moved = vec![0.0f64; axes];
    for k in 0..n {
        plant.motor_positions(&x, &mut want);
        for i in 0..axes {
            worst = worst.max((got[k][i] - want[i]).abs());
            moved[i] = moved[i].max(want[i].abs());
        }
        plant.step(&mut x, &sent[k]);
    }
    eprintln!(
        "worst {:.3} increments; peak motor excursions {moved:?} rad",
        worst / quantum
    );
    assert!(
        worst <= 0.5 * quantum + 1e-12,
        "{} increments",
        worst / quantum
    );
    for (i, m) in moved.iter().enumerate().skip(1) {
        assert!(
            *m > 20.0 * quantum,
            "axis {} did not feel axis 1's torque: {m:e} rad",
            i + 1
        );
    }
}
