//! flexid-core's rigid-body dynamics against Pinocchio (issue 17), an implementation no one
//! on flexid wrote: the mass matrix M(q) (`crba`), the gravity torque g(q)
//! (`computeGeneralizedGravity`) and its derivative dg/dq
//! (`computeGeneralizedGravityDerivatives`) of the reference arm `robots/flexid-arm6.urdf`
//! at 100 random poses from a fixed seed, each within 1e-10 relative; and, beyond the
//! issue, inverse dynamics (`rnea`) at random rates and accelerations at those poses.
//!
//! The norm: per pose and quantity, the largest absolute difference of any entry divided by
//! the largest absolute entry of Pinocchio's matrix (or vector).
//!
//! Pinocchio is the `pin` package of PyPI in `.venv-pinocchio` (scripts/pyenv-pinocchio.sh,
//! run by scripts/test.sh), driven by tests/interop/pinocchio_dynamics.py, which builds the
//! model from the URDF file itself (`buildModelFromUrdf`: its own parser, its own fixed
//! joint handling). Without the venv the test skips with a message; under `CI=true` it
//! fails instead.

use std::path::{Path, PathBuf};
use std::process::Command;

use flexid_core::robot::SerialRobot;
use nalgebra::{DMatrix, DVector};
use rand::{rngs::StdRng, Rng, SeedableRng};

const POSES: usize = 100;
const TOLERANCE: f64 = 1e-10;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `.venv-pinocchio`'s python if it imports pinocchio.
fn pinocchio_python() -> Option<PathBuf> {
    let py = root().join(".venv-pinocchio/bin/python");
    Command::new(&py)
        .args(["-c", "import pinocchio, numpy"])
        .output()
        .is_ok_and(|o| o.status.success())
        .then_some(py)
}

fn matrix(v: &serde_json::Value) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = serde_json::from_value(v.clone()).expect("a matrix as rows");
    DMatrix::from_fn(rows.len(), rows[0].len(), |r, c| rows[r][c])
}

fn vector(v: &serde_json::Value) -> DVector<f64> {
    DVector::from_vec(serde_json::from_value(v.clone()).expect("a vector"))
}

/// Largest absolute difference over the largest absolute entry of Pinocchio's.
fn rel_err(ours: &DMatrix<f64>, theirs: &DMatrix<f64>) -> f64 {
    (ours - theirs).amax() / theirs.amax()
}

#[test]
fn mass_matrix_gravity_stiffness_and_inverse_dynamics_match_pinocchio() {
    let Some(py) = pinocchio_python() else {
        let msg = "no .venv-pinocchio with pinocchio (run scripts/pyenv-pinocchio.sh)";
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("CI=true and {msg}");
        }
        eprintln!("skipped: {msg}");
        return;
    };
    let urdf_path = root().join("robots/flexid-arm6.urdf");
    let urdf = std::fs::read_to_string(&urdf_path).expect("read the reference URDF");
    let robot = SerialRobot::from_urdf_str(&urdf).expect("the reference URDF imports");

    let mut rng = StdRng::seed_from_u64(17);
    let mut random = |half: f64| -> Vec<f64> {
        (0..robot.dof())
            .map(|_| rng.random_range(-half..half))
            .collect()
    };
    // (q [rad], qd [rad/s], qdd [rad/s^2])
    let states: Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> = (0..POSES)
        .map(|_| (random(std::f64::consts::PI), random(3.0), random(10.0)))
        .collect();
    let json: Vec<serde_json::Value> = states
        .iter()
        .map(|(q, qd, qdd)| serde_json::json!({"q": q, "qd": qd, "qdd": qdd}))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let poses_file = dir.path().join("poses.json");
    std::fs::write(&poses_file, serde_json::to_string(&json).unwrap()).unwrap();

    let out = Command::new(&py)
        .arg(root().join("tests/interop/pinocchio_dynamics.py"))
        .arg(&urdf_path)
        .arg(&poses_file)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "pinocchio_dynamics.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let reference: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");

    // the same joints in the same order, the same gravity
    let joints: Vec<String> = serde_json::from_value(reference["joints"].clone()).unwrap();
    let expected: Vec<String> = (1..=6).map(|i| format!("joint_{i}")).collect();
    assert_eq!(joints, expected, "Pinocchio's joint order");
    assert_eq!(
        vector(&reference["gravity"]),
        DVector::from_column_slice(robot.gravity_mps2.as_slice())
    );

    let results = reference["poses"].as_array().expect("poses");
    assert_eq!(results.len(), POSES);
    let mut worst = [0.0f64; 4];
    for ((q, qd, qdd), theirs) in states.iter().zip(results) {
        let m = rel_err(&robot.mass_matrix(q).unwrap(), &matrix(&theirs["M"]));
        let g = vector(&theirs["g"]);
        let g = (robot.gravity_torque(q).unwrap() - &g).amax() / g.amax();
        let k = rel_err(
            &robot.gravity_stiffness(q).unwrap(),
            &matrix(&theirs["dg_dq"]),
        );
        let tau = vector(&theirs["tau"]);
        let tau = (robot.inverse_dynamics(q, qd, qdd).unwrap() - &tau).amax() / tau.amax();
        assert!(
            [m, g, k, tau].iter().all(|&e| e < TOLERANCE),
            "q = {q:?}: relative errors M {m:e}, g {g:e}, dg/dq {k:e}, inverse dynamics {tau:e}"
        );
        for (w, e) in worst.iter_mut().zip([m, g, k, tau]) {
            *w = w.max(e);
        }
    }
    let [m, g, k, tau] = worst;
    eprintln!(
        "against Pinocchio {} at {POSES} poses: largest relative errors M {m:.1e}, g {g:.1e}, dg/dq {k:.1e}, inverse dynamics {tau:.1e}",
        reference["pinocchio"].as_str().unwrap_or("?")
    );
}
