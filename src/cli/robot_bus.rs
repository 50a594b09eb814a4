//! `flexid robot --bus SPEC --pose NAME --out DIR`: one pose of a real (or simulated)
//! robot measured through its drives on a CAN bus, all axes at once (orthogonal
//! random-phase multisines under a holding position loop, every set-point in the same
//! SYNC cycle), the FRF matrix written to `DIR/frf_matrix.json` and `DIR/bode_matrix.svg`;
//! and `flexid robot --from DIR --from DIR ...`: the flexibilities identified from such
//! measurements. The robot stands at the pose while it is measured (move it there first).

use super::sweep::{install_signal_handlers, restore_signal_handlers, STOP};
use super::CliError;
use flexid_can::{BusSpec, CanBus, UdpMulticastBus};
use flexid_canopen::{bring_up, DriveGroup, MasterConfig, ProfileSet};
use flexid_core::manipulator::measure::MeasureOptions;
use flexid_core::manipulator::FlexibleRobot;
use flexid_daemon::robot::files::{identify_files, write_json, write_pose_files, FrfMatrixFile};
use flexid_daemon::robot::{measure_pose, plan_pose};
use flexid_sweep::{MultiProgress, Pacing};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How a pose is measured on a bus.
pub struct BusMeasurement<'a> {
    pub robot: &'a FlexibleRobot,
    pub bus: &'a str,
    pub pose: &'a str,
    pub out: &'a Path,
    pub first_node: u8,
    pub cycle_hz: f64,
    pub periods: usize,
    pub transient_periods: usize,
    pub pacing: Pacing,
}

/// Measures the pose on the bus; writes its files.
pub fn measure_on_bus(m: &BusMeasurement) -> Result<(), CliError> {
    let spec = m
        .robot
        .poses
        .iter()
        .find(|p| p.name == m.pose)
        .ok_or_else(|| {
            let names: Vec<_> = m.robot.poses.iter().map(|p| p.name.as_str()).collect();
            CliError::input(format!(
                "--pose {}: the robot's file has {}",
                m.pose,
                names.join(", ")
            ))
        })?;
    let axes = m.robot.axes();
    if m.first_node == 0 || usize::from(m.first_node) + axes - 1 > 127 {
        return Err(CliError::input(format!(
            "--first-node {}: {axes} axes leave the node-id range 1..=127",
            m.first_node
        )));
    }
    let bus = BusSpec::parse(m.bus).map_err(CliError::input)?;
    let name = bus.describe();
    match &bus {
        BusSpec::Udp(cfg) => UdpMulticastBus::open(cfg.clone())
            .map_err(|e| CliError::failed(format!("{name}: {e}")))
            .and_then(|b| measure_with(b, m, &spec.q_deg)),
        #[cfg(target_os = "linux")]
        BusSpec::SocketCan(iface) => flexid_can::SocketCanBus::open(iface)
            .map_err(|e| CliError::failed(format!("{name}: {e}")))
            .and_then(|b| measure_with(b, m, &spec.q_deg)),
        #[cfg(not(target_os = "linux"))]
        BusSpec::SocketCan(_) => Err(CliError::input("SocketCAN is Linux only")),
    }
}

fn measure_with<B: CanBus>(bus: B, m: &BusMeasurement, q_deg: &[f64]) -> Result<(), CliError> {
    let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
    let pose = m
        .robot
        .pose(&q)
        .map_err(|e| CliError::input(format!("pose {}: {e}", m.pose)))?;
    let axes = m.robot.axes();
    let nodes: Vec<u8> = (0..axes).map(|i| m.first_node + i as u8).collect();
    let profiles = ProfileSet::builtin();
    let master = MasterConfig {
        cycle_period: Duration::from_secs_f64(1.0 / m.cycle_hz),
        ..MasterConfig::for_node(m.first_node)
    };
    let mut drives = Vec::with_capacity(axes);
    for &node in &nodes {
        let handle = bus
            .try_clone()
            .map_err(|e| CliError::failed(format!("{}: {e}", bus.interface())))?;
        let d = bring_up(handle, MasterConfig { node, ..master }, &profiles)
            .map_err(|e| CliError::failed(format!("bringing node {node} up: {e}")))?;
        drives.push(d);
    }
    let mut group =
        DriveGroup::enable(drives).map_err(|e| CliError::failed(format!("enable: {e}")))?;
    let opts = MeasureOptions {
        periods: m.periods,
        transient_periods: m.transient_periods,
        ..MeasureOptions::for_axes(axes, m.cycle_hz, 100)
    };
    let plan =
        plan_pose(m.pose, &pose, &opts, m.pacing).map_err(|e| CliError::failed(e.to_string()))?;
    eprintln!(
        "flexid robot: {} at pose {}: {} axes (nodes {}-{}) on {}, {} experiments of {} periods, {:.0} s at {} Hz",
        m.robot.name,
        m.pose,
        axes,
        nodes[0],
        nodes[axes - 1],
        bus.interface(),
        plan.excitation.experiments(),
        m.periods + m.transient_periods,
        plan.duration_s(),
        m.cycle_hz
    );
    install_signal_handlers();
    let mut last = usize::MAX;
    let result = measure_pose(
        m.pose,
        &mut group,
        &plan,
        &STOP,
        &mut |p: &MultiProgress| {
            if p.experiment != last {
                last = p.experiment;
                eprintln!(
                    "flexid robot: experiment {} of {} ({:.1} s)",
                    p.experiment + 1,
                    p.experiments,
                    p.elapsed.as_secs_f64()
                );
            }
        },
    );
    let disabled = group.disable();
    restore_signal_handlers();
    let (outcome, frf) = result.map_err(|e| CliError::failed(e.to_string()))?;
    if let Err(e) = disabled {
        eprintln!("flexid robot: disabling the drives: {e}");
    }
    let summary = write_pose_files(m.out, &m.robot.name, m.pose, q_deg, &nodes, &frf, &outcome)
        .map_err(|e| CliError::write(e, None))?;
    eprintln!("flexid robot: {summary}; wrote {}", m.out.display());
    Ok(())
}

/// Identifies from the measurement directories `from`; prints the parameters, writes
/// `json` when given.
pub fn identify_from(
    robot: &FlexibleRobot,
    from: &[PathBuf],
    starts: usize,
    json: Option<&Path>,
) -> Result<(), CliError> {
    let mut files = Vec::new();
    let mut fs_hz = None;
    for d in from {
        let p = d.join("frf_matrix.json");
        let text = std::fs::read_to_string(&p)
            .map_err(|e| CliError::input(format!("{}: {e}", p.display())))?;
        let f: FrfMatrixFile = serde_json::from_str(&text)
            .map_err(|e| CliError::input(format!("{}: {e}", p.display())))?;
        if fs_hz.is_some_and(|fs| fs != f.sample_rate_hz) {
            return Err(CliError::input(format!(
                "{}: measured at {} Hz, the others at {} Hz",
                p.display(),
                f.sample_rate_hz,
                fs_hz.unwrap_or(0.0)
            )));
        }
        fs_hz = Some(f.sample_rate_hz);
        files.push((d.display().to_string(), f));
    }
    let fs_hz = fs_hz.ok_or_else(|| CliError::input("--from: no measurement given"))?;
    eprintln!(
        "flexid robot: identifying {} from {} poses, {starts} starts ...",
        robot.name,
        files.len()
    );
    let (doc, summary) =
        identify_files(robot, &robot.name, &files, starts, fs_hz).map_err(CliError::failed)?;
    println!("parameter      identified    file value   uncertainty  unit");
    for p in doc["parameters"].as_array().into_iter().flatten() {
        let std = match (p["identifiable"].as_bool(), p["std_rel"].as_f64()) {
            (Some(true), Some(s)) => format!("{:.2e} %", 100.0 * s),
            _ => "not identifiable".into(),
        };
        println!(
            "{:<13} {:>11.4e} {:>13.4e}  {std:>11}  {}",
            p["name"].as_str().unwrap_or(""),
            p["value"].as_f64().unwrap_or(f64::NAN),
            p["nominal"].as_f64().unwrap_or(f64::NAN),
            p["unit"].as_str().unwrap_or("")
        );
    }
    println!("{summary}");
    if let Some(path) = json {
        write_json(path, &doc).map_err(|e| CliError::write(e, None))?;
        eprintln!("flexid robot: wrote {}", path.display());
    }
    Ok(())
}
