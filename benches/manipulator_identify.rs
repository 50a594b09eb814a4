//! The issue-17 identification benchmark, Rust side (`scripts/bench.sh` runs it through
//! `benches/manipulator_identify.py`, which compares it with scipy on the same cost).
//!
//! It builds the reference robot (`robots/flexid-arm6.urdf` + `.flex.toml`: 6 axes,
//! 12 spring-damper pairs, 24 parameters), simulates the two identification poses as
//! `crates/flexid-core/tests/manipulator_identification.rs` does (the same true springs,
//! the same measurement options and seeds), builds the paper's cost (eq. (15), `p = 2`)
//! in the **continuous** model form (so that the Python side can compute the very same
//! model: the sampled form's zero-order-hold plant is not rebuilt there), and writes
//! `problem-<weighting>.json` into `--out DIR` (default `target/bench/manipulator`):
//!
//! * per pose the full mass matrix `M` (arm and motors, `n x n`, arm side) [kg m^2], the
//!   gravity stiffness `K0 = diag(dg/dq, 0)` [N m/rad], the pairs as coordinate pairs
//!   (`[a, m]`, `m` null for a bearing), the motor coordinates and gear ratios, the lines
//!   [Hz];
//! * per cost term the pose, the element `(n, m)`, the line indices, `alpha` and the
//!   measured magnitude [dB]; `p`;
//! * the starts (`ln theta`, from `identify::start_design`), the nominal and the true
//!   parameters, and `V` at reference points (nominal, truth, some starts) for the
//!   Python side's agreement check.
//!
//! It then runs `identify` once on one thread and (without `--serve`) once on every thread
//! (the warm-up, and the results file's) and writes `rust-<weighting>.json`: per
//! start the final `V` and its evaluations, the best parameters, the good starts, the times.
//!
//! Arguments: `[--quick] [--starts N] [--weighting inverse-variance|uniform] [--out DIR]
//! [--serve]` (others, e.g. cargo's `--bench`, are ignored). `--quick`: 8 starts. With
//! `--serve` it then answers timing requests on stdin, one a line: `run T` (T threads, 0:
//! every core the process may use) runs the whole identification once and prints
//! `{"seconds": .., "cost": .., "good": ..}`; `quit` or end of input ends.

use flexid_core::manipulator::flex_file::PoseRole;
use flexid_core::manipulator::identify::{model_frf, start_design};
use flexid_core::manipulator::measure::{simulate, MeasureOptions};
use flexid_core::manipulator::{
    identify, Cost, CostSpec, Flexibilities, FlexibleRobot, FrfForm, Identification,
    IdentifyOptions, PoseMeasurement, RigidPose, Weighting,
};
use serde_json::{json, Value};
use std::hint::black_box;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

/// The paper's number of starts.
const STARTS: usize = 60;
/// Starts with `--quick` (CI's smoke run).
const QUICK_STARTS: usize = 8;

fn reference_robot() -> FlexibleRobot {
    flexid_core::manipulator::reference::robot()
}

/// The robot's true springs: the integration test's (`reference::perturbed_truth`).
fn truth(r: &FlexibleRobot) -> Flexibilities {
    flexid_core::manipulator::reference::perturbed_truth(r)
}

/// The integration test's measurement of pose `seed - 100`.
fn options(seed: u64) -> MeasureOptions {
    MeasureOptions::for_axes(6, 1000.0, seed)
}

/// A matrix as a list of rows.
fn rows(m: &nalgebra::DMatrix<f64>) -> Value {
    json!((0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect::<Vec<_>>())
        .collect::<Vec<_>>())
}

/// One pose of the linear model, everything Python needs to rebuild `Z(s)` and `G(s)`:
/// `M` and `K0` over all `n_a + N` coordinates (arm side), pairs, motors, lines.
fn pose_json(pose: &RigidPose, f_hz: &[f64]) -> Value {
    let n = pose.coords();
    let na = pose.arm_coords();
    let mut mass = nalgebra::DMatrix::zeros(n, n);
    let mut gravity = nalgebra::DMatrix::zeros(n, n);
    mass.view_mut((0, 0), (na, na)).copy_from(&pose.arm_mass);
    gravity
        .view_mut((0, 0), (na, na))
        .copy_from(&pose.gravity_stiffness);
    for (i, m) in pose.motors.iter().enumerate() {
        let c = pose.motor_coord(i);
        mass[(c, c)] = m.arm_side_inertia_kgm2();
    }
    json!({
        "coords": n,
        "mass_kgm2": rows(&mass),
        "gravity_stiffness_nm_per_rad": rows(&gravity),
        "pairs": pose.springs.iter().map(|s| {
            let (a, m) = pose.spring_coords(s);
            json!([a, m])
        }).collect::<Vec<_>>(),
        "motor_coords": (0..pose.axes()).map(|i| pose.motor_coord(i)).collect::<Vec<_>>(),
        "gear_ratios": pose.motors.iter().map(|m| m.gear_ratio).collect::<Vec<_>>(),
        "f_hz": f_hz,
    })
}

/// `V(theta)` in the continuous form.
fn cost_at(poses: &[RigidPose], cost: &Cost, theta: &Flexibilities) -> f64 {
    cost.value(&model_frf(poses, cost, theta, FrfForm::Continuous).expect("model FRF"))
}

/// The largest relative stiffness error against the truth [-].
fn stiffness_error(found: &Flexibilities, truth: &Flexibilities) -> f64 {
    found
        .stiffness_nm_per_rad
        .iter()
        .zip(&truth.stiffness_nm_per_rad)
        .map(|(k, t)| (k / t - 1.0).abs())
        .fold(0.0, f64::max)
}

/// The identification's result as JSON: the best parameters and stiffness errors, per
/// start the final `V` [dB], its model evaluations and failure.
fn result_json(r: &Identification, truth: &Flexibilities) -> Value {
    json!({
        "best_cost": r.cost,
        // values, not logarithms: a damping the data leave free may end at zero
        "best_stiffness_nm_per_rad": r.best.stiffness_nm_per_rad,
        "best_damping_nms_per_rad": r.best.damping_nms_per_rad,
        "good": r.good,
        "max_stiffness_error": stiffness_error(&r.best, truth),
        "stiffness_errors": r.best.stiffness_nm_per_rad.iter()
            .zip(&truth.stiffness_nm_per_rad).map(|(k, t)| k / t - 1.0).collect::<Vec<_>>(),
        "starts": r.starts.iter().map(|s| json!({
            "cost": if s.cost.is_finite() { json!(s.cost) } else { Value::Null },
            "evaluations": s.evaluations,
            "failure": s.failure,
        })).collect::<Vec<_>>(),
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let quick = args.iter().any(|a| a == "--quick");
    let starts = value("--starts").map_or(if quick { QUICK_STARTS } else { STARTS }, |s| {
        s.parse().expect("--starts N: a number")
    });
    let (weighting, wname) = match value("--weighting").as_deref() {
        None | Some("inverse-variance") => (Weighting::InverseVariance, "inverse-variance"),
        Some("uniform") => (Weighting::Uniform, "uniform"),
        Some(w) => {
            eprintln!("bench: --weighting {w}: expected inverse-variance or uniform");
            std::process::exit(2);
        }
    };
    let out =
        value("--out").map_or_else(|| PathBuf::from("target/bench/manipulator"), PathBuf::from);
    std::fs::create_dir_all(&out).expect("create the output directory");
    let log = |s: String| {
        eprintln!("bench (rust): {s}");
        let _ = std::io::stderr().flush();
    };

    // ---- the problem: robot, two simulated poses, the cost ----
    let robot = reference_robot();
    let truth = truth(&robot);
    let t0 = Instant::now();
    let (poses, meas): (Vec<RigidPose>, Vec<PoseMeasurement>) = robot
        .poses_of(PoseRole::Identification)
        .into_iter()
        .enumerate()
        .map(|(i, (_, q))| {
            let pose = robot.pose(&q).expect("pose");
            let frf = simulate(&pose, &truth, &options(100 + i as u64)).expect("measurement");
            (pose, PoseMeasurement::from_mimo(&frf))
        })
        .unzip();
    let cost = Cost::new(
        &meas,
        CostSpec {
            weighting,
            ..CostSpec::default()
        },
    )
    .expect("cost");
    log(format!(
        "{} poses simulated in {:.1} s, {} cost terms, {} weights",
        poses.len(),
        t0.elapsed().as_secs_f64(),
        cost.terms.len(),
        wname
    ));
    let opts = |threads| IdentifyOptions {
        starts,
        threads,
        form: FrfForm::Continuous,
        ..IdentifyOptions::default()
    };
    let design = start_design(&robot.nominal, &opts(1));
    // V at reference points for the Python side's agreement check
    let mut checks = vec![
        json!({"what": "nominal", "theta": robot.nominal.to_log(), "cost": cost_at(&poses, &cost, &robot.nominal)}),
        json!({"what": "truth", "theta": truth.to_log(), "cost": cost_at(&poses, &cost, &truth)}),
    ];
    for i in [1, 2, starts.saturating_sub(1)] {
        if let Some(s) = design.get(i) {
            let th = Flexibilities::from_log(s);
            checks.push(json!({"what": format!("start {i}"), "theta": s, "cost": cost_at(&poses, &cost, &th)}));
        }
    }
    let problem = json!({
        "robot": robot.name,
        "weighting": wname,
        "form": "continuous",
        "p": cost.spec.p,
        "axes": cost.axes,
        "parameter_names": robot.parameter_names(),
        "poses": poses.iter().zip(&cost.f_hz).map(|(p, f)| pose_json(p, f)).collect::<Vec<_>>(),
        "terms": cost.terms.iter().map(|t| json!({
            "pose": t.pose, "n": t.n, "m": t.m, "lines": t.lines,
            "alpha": t.alpha, "measured_db": t.measured_db,
        })).collect::<Vec<_>>(),
        "nominal_theta": robot.nominal.to_log(),
        "truth_theta": truth.to_log(),
        "starts": design,
        "spread": opts(1).spread,
        "seed": opts(1).seed,
        "checks": checks,
    });
    let problem_file = out.join(format!("problem-{wname}.json"));
    std::fs::write(
        &problem_file,
        serde_json::to_string(&problem).expect("json"),
    )
    .expect("write the problem file");

    // ---- the identification, one thread and every thread ----
    let run = |threads| {
        let t0 = Instant::now();
        let r = identify(&poses, &cost, &robot.nominal, &opts(threads)).expect("identify");
        (t0.elapsed().as_secs_f64(), black_box(r))
    };
    let (t1, r1) = run(1);
    log(format!(
        "{starts} starts on 1 thread: {t1:.2} s, best V {:.6}, {} good, max stiffness error {:.3} %",
        r1.cost,
        r1.good.len(),
        100.0 * stiffness_error(&r1.best, &truth)
    ));
    // under --serve the Python side times every-thread runs itself
    let serving = args.iter().any(|a| a == "--serve");
    let all = (!serving).then(|| run(0));
    if let Some((tn, rn)) = &all {
        log(format!(
            "{starts} starts on every thread: {tn:.2} s, best V {:.6}",
            rn.cost
        ));
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let results = json!({
        "weighting": wname,
        "starts": starts,
        "threads_all": cores,
        "seconds_one_thread": t1,
        "seconds_all_threads": all.as_ref().map(|(t, _)| *t),
        "cost_all_threads": all.as_ref().map(|(_, r)| r.cost),
        "result": result_json(&r1, &truth),
    });
    std::fs::write(
        out.join(format!("rust-{wname}.json")),
        serde_json::to_string_pretty(&results).expect("json"),
    )
    .expect("write the results file");
    log(format!("problem and results in {}", out.display()));

    if serving {
        serve(|request| {
            let threads: usize = request.strip_prefix("run ")?.trim().parse().ok()?;
            let (t, r) = run(threads);
            Some(json!({"seconds": t, "cost": r.cost, "good": r.good.len()}).to_string())
        });
    }
}

/// Answers requests on stdin, one a line (`quit` or end of input ends): prints `ready`,
/// then one line per request (`error` for one it does not know).
fn serve(mut answer: impl FnMut(&str) -> Option<String>) {
    use std::io::BufRead;
    let stdout = std::io::stdout();
    let say = |s: &str| {
        let mut o = stdout.lock();
        let _ = writeln!(o, "{s}");
        let _ = o.flush();
    };
    say("ready");
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { break };
        let request = line.trim();
        if request == "quit" {
            break;
        }
        say(&answer(request).unwrap_or_else(|| "error".into()));
    }
}
