//! The trajectory path on closed-loop simulations with known parameters.

use super::closed_loop::{simulate, Plant, Setup};
use super::idim::Column;
use super::*;
use crate::diagnose::{diagnose, json::to_json, DiagnoseOptions, Effect};

const PLANT: Plant = Plant {
    mass: 95.0,
    viscous: 200.0,
    coulomb: 20.0,
    offset: -3.0,
    spring: 0.0,
};

fn opts() -> DiagnoseOptions {
    DiagnoseOptions {
        masses: 1,
        ..DiagnoseOptions::default()
    }
}

/// Every true parameter within 3 standard deviations of its estimate.
fn within_3_sigma(fit: &idim::LsFit, truth: &[(Column, f64)]) {
    for &(c, want) in truth {
        let (v, sd) = fit.param(c).unwrap();
        assert!(
            (v - want).abs() <= 3.0 * sd,
            "{}: {v:.4} +- {sd:.4} (true {want}): {:.1} sigma off",
            c.name(),
            (v - want).abs() / sd
        );
    }
}

/// No NaN and no infinity anywhere in a JSON value (`null` instead).
fn assert_finite_json(v: &serde_json::Value, path: &str) {
    match v {
        serde_json::Value::Number(n) => {
            assert!(n.as_f64().is_some_and(f64::is_finite), "{path}: {n}")
        }
        serde_json::Value::Array(a) => a
            .iter()
            .enumerate()
            .for_each(|(i, x)| assert_finite_json(x, &format!("{path}[{i}]"))),
        serde_json::Value::Object(o) => o
            .iter()
            .for_each(|(k, x)| assert_finite_json(x, &format!("{path}.{k}"))),
        _ => {}
    }
}

#[test]
fn coulomb_and_viscous_friction_found_within_three_sigma() {
    let rec = simulate(&PLANT, &Setup::default());
    let fit = identify(&rec).unwrap();
    within_3_sigma(
        &fit.rigid_friction,
        &[
            (Column::Inertia, PLANT.mass),
            (Column::Viscous, PLANT.viscous),
            (Column::Coulomb, PLANT.coulomb),
            (Column::Offset, PLANT.offset),
        ],
    );
    assert!(fit.coulomb_named && fit.viscous_significant);
    assert_eq!(fit.kept, Kept::RigidFriction);
    // the cut-off is the data's: between the loop's bandwidth and the Nyquist frequency
    let fc = fit.cutoff.cutoff_hz;
    assert!(fc > 20.0 && fc < 250.0, "{fc}");
    assert!(fit.used < fit.candidates, "standstill samples are left out");

    let d = diagnose(std::slice::from_ref(&rec), &opts()).unwrap();
    assert_eq!(d.verdict, Effect::CoulombFriction);
    assert_eq!(d.effects.len(), 1);
    assert_eq!(d.effects[0].fit.params[0].name, "coulomb_nm");
    assert!(d.gap.after_rms_db < d.gap.before_rms_db);
    assert!(d.trajectory.is_some() && d.data.levels.is_empty());
    let json = to_json(&d);
    assert_finite_json(&json, "");
    assert_eq!(json["verdict"], "coulomb_friction");
    assert!(json["gap"]["bands"].as_array().unwrap().is_empty());
    assert!(json["gap"]["before_magnitude_rms_db"].is_null());
    let names: Vec<&str> = json["trajectory"]["params"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert_eq!(
        names,
        [
            "inertia_kgm2",
            "viscous_nms_per_rad",
            "coulomb_nm",
            "offset_nm"
        ]
    );
}

#[test]
fn without_coulomb_friction_the_verdict_is_none() {
    let plant = Plant {
        coulomb: 0.0,
        ..PLANT
    };
    let rec = simulate(&plant, &Setup::default());
    let fit = identify(&rec).unwrap();
    within_3_sigma(
        &fit.rigid_friction,
        &[
            (Column::Inertia, plant.mass),
            (Column::Viscous, plant.viscous),
            (Column::Coulomb, 0.0),
            (Column::Offset, plant.offset),
        ],
    );
    assert!(
        !fit.coulomb_named,
        "Fc {:?}",
        fit.rigid_friction.param(Column::Coulomb)
    );
    assert_eq!(fit.kept, Kept::RigidViscous);
    let d = diagnose(&[rec], &opts()).unwrap();
    assert_eq!(d.verdict, Effect::None, "notes: {:#?}", d.notes);
    assert!(d.effects.is_empty() && d.winner.is_none());
    assert_finite_json(&to_json(&d), "");
}

/// A force the model has no term for (a spring to the ground, 1.5 kN/m: 90 N at the
/// stroke's end), no Coulomb friction: the residual is far beyond the noise and nothing
/// explains it.
#[test]
fn a_force_outside_the_model_is_unexplained() {
    let plant = Plant {
        coulomb: 0.0,
        spring: 1500.0,
        ..PLANT
    };
    let rec = simulate(&plant, &Setup::default());
    let d = diagnose(&[rec], &opts()).unwrap();
    let t = d.trajectory.as_ref().unwrap();
    assert!(
        !t.within_noise(t.kept_fit()),
        "{}",
        t.reduced_chi2(t.kept_fit())
    );
    assert_eq!(d.verdict, Effect::Unexplained, "notes: {:#?}", d.notes);
}

#[test]
fn cross_test_on_another_trajectory_predicts_the_force() {
    let rec = simulate(&PLANT, &Setup::default());
    let other = simulate(
        &PLANT,
        &Setup {
            speeds: vec![0.1031, 0.0717, 0.1823],
            stroke: 0.09,
            seed: 2,
            ..Setup::default()
        },
    );
    let d = diagnose(&[rec, other], &opts()).unwrap();
    let t = d.trajectory.as_ref().unwrap();
    let x = &t.cross_tests[0];
    assert_eq!(x.recording, 1);
    let direct = t.rigid_friction.relative_error;
    // the same plant: the cross-test error is the direct one's order, far below the
    // rigid body's without friction
    assert!(
        x.relative_error < 2.0 * direct,
        "{} vs {direct}",
        x.relative_error
    );
    assert!(x.relative_error < 0.5 * t.rigid.relative_error);
}

#[test]
fn errors_are_typed_not_panics() {
    let rec = simulate(&PLANT, &Setup::default());
    let mut no_pos = rec.clone();
    no_pos.position_rad = None;
    assert!(matches!(
        identify(&no_pos),
        Err(TrajectoryError::NoPosition)
    ));
    let mut short = rec.clone();
    short.torque_cmd_nm.truncate(100);
    assert!(matches!(
        identify(&short),
        Err(TrajectoryError::TooShort { .. })
    ));
    let mut nan = rec.clone();
    nan.torque_cmd_nm[7] = f64::NAN;
    assert!(matches!(
        identify(&nan),
        Err(TrajectoryError::NotFinite { row: 7, .. })
    ));
    let mut still = rec.clone();
    still.position_rad = Some(vec![0.25; rec.len()]);
    assert!(identify(&still).is_err());
    let mut flipped = rec.clone();
    flipped.torque_cmd_nm.iter_mut().for_each(|v| *v = -*v);
    assert!(matches!(
        identify(&flipped),
        Err(TrajectoryError::NegativeInertia(_))
    ));
    let mut other_rate = rec.clone();
    other_rate.sample_rate_hz = 500.0;
    let e = diagnose(&[rec, other_rate], &opts()).unwrap_err();
    assert!(e.to_string().contains("recording 1"), "{e}");
}

#[test]
fn periodic_recordings_and_several_bodies_keep_the_frequency_path() {
    let rec = simulate(&PLANT, &Setup::default());
    assert!(diagnosis::applies(std::slice::from_ref(&rec), 1));
    assert!(!diagnosis::applies(std::slice::from_ref(&rec), 2));
    let mut periodic = rec.clone();
    if let Some(e) = periodic.sidecar.excitation.as_mut() {
        e.kind = crate::excitation::ExcitationKind::Multisine;
        e.period_samples = 1000;
    }
    assert!(!diagnosis::applies(&[periodic], 1));
    assert!(!diagnosis::applies(&[], 1));
}

/// Issue 16: a time cap that passes before the nominal chain is begun is an error of its
/// own (the command line then identifies the nominal chain alone), not a panic or a
/// diagnosis without a model; the trajectory path is not capped (it takes milliseconds).
#[test]
fn a_cap_passed_before_the_nominal_chain_is_its_own_error() {
    let rec = simulate(&PLANT, &Setup::default());
    let two = DiagnoseOptions {
        masses: 2,
        budget: crate::identify::fit::FitBudget::with_cap_s(0.0),
        ..opts()
    };
    match diagnose(std::slice::from_ref(&rec), &two) {
        Err(crate::diagnose::DiagnoseError::CappedBeforeNominal { max_seconds, .. }) => {
            assert_eq!(max_seconds, 0.0)
        }
        other => panic!("{:?}", other.map(|d| d.verdict)),
    }
    let traj = DiagnoseOptions {
        budget: crate::identify::fit::FitBudget::with_cap_s(0.0),
        ..opts()
    };
    let d = diagnose(&[rec], &traj).unwrap();
    assert!(!d.time_cap.capped, "{:?}", d.time_cap);
}
