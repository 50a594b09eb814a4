//! `flexid robot [--robot FLEX.toml] [--starts N] [--start-scale X] [--svg OUT] [--json OUT]`:
//! the multi-axis identification of issue 17 on a simulated robot. The robot's rigid links
//! come from the URDF its flexibility file names, its true springs are the file's values;
//! each identification pose of the file is measured with orthogonal random-phase
//! multisines under a position loop (encoder noise), the 18-DOF model is identified from
//! the file's values scaled by `--start-scale` (the paper's multi-start search), and the
//! model is checked on the file's validation poses. Without `--robot`, the reference arm
//! shipped in `robots/`.
//!
//! With `--bus SPEC --pose NAME --out DIR`, one pose is measured through the robot's
//! drives instead (`flexid-vdrive --robot` simulates them on a bus); with `--from DIR ...`
//! the flexibilities are identified from such measurements (`cli::robot_bus`).

use super::CliError;
use crate::plot::{bode_matrix_svg, BodeMatrix};
use crate::recording::write_bytes_atomic;
use clap::Args;
use flexid_core::manipulator::flex_file::PoseRole;
use flexid_core::manipulator::identify::{model_frf, FrfForm};
use flexid_core::manipulator::measure::{simulate, MeasureOptions};
use flexid_core::manipulator::{
    identify, Cost, CostSpec, Flexibilities, FlexibleRobot, IdentifyOptions, PoseMeasurement,
    Weighting,
};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct RobotArgs {
    /// The robot's flexibility file (TOML; its `urdf` is read relative to it). Default: the
    /// reference arm `robots/flexid-arm6.flex.toml`, embedded.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Starts of the identification (the paper: 60).
    #[arg(long, default_value_t = 60)]
    pub starts: usize,
    /// The identification starts from the file's values times this factor (the simulated
    /// robot has the file's values).
    #[arg(long, default_value_t = 1.5)]
    pub start_scale: f64,
    /// Sample rate of the simulated drives [Hz].
    #[arg(long, default_value_t = 1000.0)]
    pub fs: f64,
    /// Write the first identification pose's measured N x N Bode matrix with the identified
    /// model here (SVG).
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Write the identified parameters, their uncertainties and the cost per pose here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Measure the robot through its drives on this bus instead of simulating it
    /// (`udp[:GROUP[:PORT]]` or `socketcan:IFACE`): one pose (`--pose`), written to `--out`.
    #[arg(long, requires_all = ["pose", "out"], conflicts_with = "from")]
    pub bus: Option<String>,
    /// The pose the robot stands at (a pose name of its file).
    #[arg(long, requires = "bus")]
    pub pose: Option<String>,
    /// Directory for the measured pose (`frf_matrix.json`, `bode_matrix.svg`).
    #[arg(long, requires = "bus")]
    pub out: Option<PathBuf>,
    /// Node id of axis 1 on the bus (axis i is first-node + i - 1).
    #[arg(long, default_value_t = 2)]
    pub first_node: u8,
    /// Averaged periods per experiment (the bus measurement), after `--transient-periods`.
    #[arg(long, default_value_t = 4)]
    pub periods: usize,
    #[arg(long, default_value_t = 1)]
    pub transient_periods: usize,
    /// Pacing of the bus measurement: `realtime` for drives that keep their own time
    /// (real drives), `lockstep` for a simulated robot in lock-step.
    #[arg(long, default_value = "realtime", value_parser = ["realtime", "lockstep"])]
    pub clock: String,
    /// Identify from these measured poses (directories written by `--bus ... --out`)
    /// instead of simulating.
    #[arg(long, num_args = 1..)]
    pub from: Vec<PathBuf>,
}

pub fn robot(a: &RobotArgs) -> Result<(), CliError> {
    if !(a.start_scale.is_finite() && a.start_scale > 0.0) || a.starts == 0 {
        return Err(CliError::input(format!(
            "--start-scale {} and --starts {}: need a positive factor and at least one start",
            a.start_scale, a.starts
        )));
    }
    let robot = load(a)?;
    if let Some(bus) = &a.bus {
        if !(1..=64).contains(&a.periods) || a.transient_periods > 16 {
            return Err(CliError::input(
                "--periods must be 1..=64 and --transient-periods 0..=16",
            ));
        }
        return super::robot_bus::measure_on_bus(&super::robot_bus::BusMeasurement {
            robot: &robot,
            bus,
            pose: a.pose.as_deref().unwrap_or_default(),
            out: a.out.as_deref().unwrap_or(std::path::Path::new(".")),
            first_node: a.first_node,
            cycle_hz: a.fs,
            periods: a.periods,
            transient_periods: a.transient_periods,
            pacing: if a.clock == "lockstep" {
                flexid_sweep::Pacing::Lockstep
            } else {
                flexid_sweep::Pacing::Realtime
            },
        });
    }
    if !a.from.is_empty() {
        return super::robot_bus::identify_from(&robot, &a.from, a.starts, a.json.as_deref());
    }
    let truth = robot.nominal.clone();
    let start = Flexibilities::new(
        truth
            .stiffness_nm_per_rad
            .iter()
            .map(|k| k * a.start_scale)
            .collect(),
        truth
            .damping_nms_per_rad
            .iter()
            .map(|c| c * a.start_scale)
            .collect(),
    )
    .map_err(|e| CliError::input(e.to_string()))?;
    let measure = |role: PoseRole| {
        robot
            .poses_of(role)
            .into_iter()
            .enumerate()
            .map(|(i, (name, q))| {
                let pose = robot
                    .pose(&q)
                    .map_err(|e| CliError::input(format!("pose {name}: {e}")))?;
                let frf = simulate(
                    &pose,
                    &truth,
                    &MeasureOptions::for_axes(robot.axes(), a.fs, 100 + i as u64),
                )
                .map_err(|e| CliError::failed(format!("pose {name}: {e}")))?;
                Ok((name, pose, PoseMeasurement::from_mimo(&frf)))
            })
            .collect::<Result<Vec<_>, CliError>>()
    };
    let t0 = Instant::now();
    let id = measure(PoseRole::Identification)?;
    if id.is_empty() {
        return Err(CliError::input(
            "the flexibility file has no pose of role \"identification\"",
        ));
    }
    eprintln!(
        "flexid robot: {} ({} axes, {} spring-damper pairs), {} identification poses measured in {:.1} s",
        robot.name,
        robot.axes(),
        robot.springs.len(),
        id.len(),
        t0.elapsed().as_secs_f64()
    );
    let poses: Vec<_> = id.iter().map(|(_, p, _)| p.clone()).collect();
    let meas: Vec<_> = id.iter().map(|(_, _, m)| m.clone()).collect();
    let spec = CostSpec {
        weighting: Weighting::InverseVariance,
        ..CostSpec::default()
    };
    let cost = Cost::new(&meas, spec.clone()).map_err(|e| CliError::failed(e.to_string()))?;
    let form = FrfForm::Sampled { fs_hz: a.fs };
    let opts = IdentifyOptions {
        starts: a.starts,
        form,
        ..IdentifyOptions::default()
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    eprintln!(
        "flexid robot: identifying from {} starts on {threads} threads ...",
        a.starts
    );
    let t1 = Instant::now();
    let result =
        identify(&poses, &cost, &start, &opts).map_err(|e| CliError::failed(e.to_string()))?;
    eprintln!(
        "flexid robot: identified in {:.1} s; {} of {} starts reached the best cost {:.4} dB",
        t1.elapsed().as_secs_f64(),
        result.good.len(),
        result.starts.len(),
        result.cost
    );
    print_table(&robot, &truth, &result);
    // validation
    let val = measure(PoseRole::Validation)?;
    println!("\npose          role            V [dB] identified   V [dB] true springs");
    let mut per_pose = Vec::new();
    for ((name, pose, m), role) in id
        .iter()
        .map(|x| (x, "identification"))
        .chain(val.iter().map(|x| (x, "validation")))
    {
        let c = Cost::new(std::slice::from_ref(m), spec.clone())
            .map_err(|e| CliError::failed(e.to_string()))?;
        let v = |theta: &Flexibilities| {
            model_frf(std::slice::from_ref(pose), &c, theta, form).map(|g| c.value(&g))
        };
        let (vi, vt) = (
            v(&result.best).map_err(|e| CliError::failed(e.to_string()))?,
            v(&truth).map_err(|e| CliError::failed(e.to_string()))?,
        );
        println!("{name:<13} {role:<15} {vi:>17.4} {vt:>21.4}");
        per_pose.push(serde_json::json!({"pose": name, "role": role, "v_db": vi, "v_true_db": vt}));
    }
    if let Some(path) = &a.svg {
        let (name, pose, m) = &id[0];
        let c = Cost::new(std::slice::from_ref(m), spec.clone())
            .map_err(|e| CliError::failed(e.to_string()))?;
        let model = model_frf(std::slice::from_ref(pose), &c, &result.best, form)
            .map_err(|e| CliError::failed(e.to_string()))?;
        let title = format!(
            "flexid robot: {} at pose {name}, measured and identified",
            robot.name
        );
        let svg = bode_matrix_svg(&BodeMatrix {
            title: &title,
            f_hz: &m.f_hz,
            measured: &m.g,
            var: m.var.as_deref(),
            model: Some((&model[0], "identified 18-DOF model")),
        });
        write_bytes_atomic(path, svg.as_bytes())
            .map_err(|e| CliError::write(format!("{}: {e}", path.display()), Some(&e)))?;
        eprintln!("flexid robot: Bode matrix written to {}", path.display());
    }
    if let Some(path) = &a.json {
        let params = flexid_daemon::robot::files::parameters_json(&robot, &result);
        let doc = serde_json::json!({
            "robot": robot.name,
            "cost_db": result.cost,
            "starts": result.starts.iter().map(|s| s.cost).collect::<Vec<_>>(),
            "good_starts": result.good.len(),
            "parameters": params,
            "poses": per_pose,
        });
        let text =
            serde_json::to_string_pretty(&doc).map_err(|e| CliError::failed(e.to_string()))?;
        write_bytes_atomic(path, text.as_bytes())
            .map_err(|e| CliError::write(format!("{}: {e}", path.display()), Some(&e)))?;
    }
    Ok(())
}

/// The robot of `--robot`, or the embedded reference arm.
fn load(a: &RobotArgs) -> Result<FlexibleRobot, CliError> {
    flexid_vdrive::robot::load_robot(a.robot.as_deref()).map_err(CliError::input)
}

/// The identified parameters against the simulated robot's.
fn print_table(
    robot: &FlexibleRobot,
    truth: &Flexibilities,
    r: &flexid_core::manipulator::Identification,
) {
    let names = robot.parameter_names();
    let s = robot.springs.len();
    println!(
        "parameter   unit            identified       simulated   error [%]   uncertainty [%]"
    );
    for (j, name) in names.iter().enumerate() {
        let (v, t, unit) = if j < s {
            (
                r.best.stiffness_nm_per_rad[j],
                truth.stiffness_nm_per_rad[j],
                "N m/rad",
            )
        } else {
            (
                r.best.damping_nms_per_rad[j - s],
                truth.damping_nms_per_rad[j - s],
                "N m s/rad",
            )
        };
        let unc = match (r.std_ln.as_ref().map(|x| x[j]), r.identifiable(j)) {
            (Some(u), Some(true)) => format!("{:.3}", 100.0 * u),
            (_, Some(false)) => "not identifiable".to_string(),
            _ => "-".to_string(),
        };
        println!(
            "{name:<11} {unit:<10} {v:>15.5e} {t:>15.5e} {:>11.3} {unc:>17}",
            100.0 * (v / t - 1.0)
        );
    }
}
