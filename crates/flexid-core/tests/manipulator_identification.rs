//! Issue 17: the 18-DOF flexible model of the reference robot identified from simulated
//! multi-axis measurements at two poses (orthogonal multisines under the position loop,
//! encoder noise), validated on twelve others (the paper's split), as a pure-core test
//! (the same through the simulated robot drive is the vdrive's test).

use flexid_core::manipulator::flex_file::PoseRole;
use flexid_core::manipulator::identify::{model_frf, FrfForm};
use flexid_core::manipulator::measure::{simulate, MeasureOptions};
use flexid_core::manipulator::{
    identify, Cost, CostSpec, Flexibilities, FlexibleRobot, IdentifyOptions, PoseMeasurement,
    RigidPose, Weighting,
};

fn reference_robot() -> FlexibleRobot {
    flexid_core::manipulator::reference::robot()
}

fn truth(r: &FlexibleRobot) -> Flexibilities {
    flexid_core::manipulator::reference::perturbed_truth(r)
}

fn measured(
    r: &FlexibleRobot,
    theta: &Flexibilities,
    role: PoseRole,
) -> Vec<(String, RigidPose, PoseMeasurement)> {
    r.poses_of(role)
        .into_iter()
        .enumerate()
        .map(|(i, (name, q))| {
            let pose = r.pose(&q).unwrap();
            let frf = simulate(
                &pose,
                theta,
                &MeasureOptions::for_axes(6, 1000.0, 100 + i as u64),
            )
            .unwrap();
            (name, pose, PoseMeasurement::from_mimo(&frf))
        })
        .collect()
}

#[test]
fn the_18_dof_model_is_identified_from_two_poses_and_holds_on_twelve() {
    let r = reference_robot();
    let truth = truth(&r);
    let id = measured(&r, &truth, PoseRole::Identification);
    let poses: Vec<_> = id.iter().map(|(_, p, _)| p.clone()).collect();
    let meas: Vec<_> = id.iter().map(|(_, _, m)| m.clone()).collect();
    let cost = Cost::new(
        &meas,
        CostSpec {
            weighting: Weighting::InverseVariance,
            ..CostSpec::default()
        },
    )
    .unwrap();
    let t0 = std::time::Instant::now();
    let result = identify(
        &poses,
        &cost,
        &r.nominal,
        &IdentifyOptions {
            starts: 4,
            form: FrfForm::Sampled { fs_hz: 1000.0 },
            ..IdentifyOptions::default()
        },
    )
    .unwrap();
    eprintln!(
        "identification: {:.1} s, costs {:?}",
        t0.elapsed().as_secs_f64(),
        result
            .starts
            .iter()
            .map(|s| (s.cost, s.evaluations))
            .collect::<Vec<_>>()
    );
    let names = r.parameter_names();
    let found = result
        .best
        .stiffness_nm_per_rad
        .iter()
        .chain(&result.best.damping_nms_per_rad);
    let true_values = truth
        .stiffness_nm_per_rad
        .iter()
        .chain(&truth.damping_nms_per_rad);
    let std_ln = result.std_ln.clone().expect("variance weights");
    for (j, (k, t)) in found.zip(true_values).enumerate() {
        eprintln!(
            "{}: {k:.4e} for {t:.4e} ({:+.3} %, uncertainty {:.3} %{})",
            names[j],
            100.0 * (k / t - 1.0),
            100.0 * std_ln[j],
            if result.identifiable(j) == Some(false) {
                ", not identifiable"
            } else {
                ""
            }
        );
    }
    // every parameter identified by the two poses (its uncertainty from the measured
    // variance under a factor of two); the dampings within 10 % (measured: 6.2 % at most;
    // the design notes' independent fit: about 10 %). The errors are 1-6 of those
    // uncertainties: the weights come from the measured magnitudes, which noise moves
    // (docs/multi-axis.md)
    for (j, name) in names.iter().enumerate() {
        assert_eq!(result.identifiable(j), Some(true), "{name}");
    }
    for (j, (c, t)) in result
        .best
        .damping_nms_per_rad
        .iter()
        .zip(&truth.damping_nms_per_rad)
        .enumerate()
    {
        assert!(
            (c / t - 1.0).abs() < 0.10,
            "{}: {c:.4e} for {t:.4e}",
            names[12 + j]
        );
    }
    // every stiffness within 5 % (the bound; measured: 0.03 % at most)
    for (j, (k, t)) in result
        .best
        .stiffness_nm_per_rad
        .iter()
        .zip(&truth.stiffness_nm_per_rad)
        .enumerate()
    {
        assert!(
            (k / t - 1.0).abs() < 0.05,
            "{}: {k:.4e} for {t:.4e}",
            names[j]
        );
    }
    // the search reached the cost's minimum: at or below the truth's cost on these data
    let form = FrfForm::Sampled { fs_hz: 1000.0 };
    let v_truth: f64 = cost
        .per_pose(&model_frf(&poses, &cost, &truth, form).unwrap())
        .iter()
        .sum();
    eprintln!(
        "V per pose {:?}, V at the truth {v_truth:.4}",
        result.cost_per_pose
    );
    assert!(
        result.cost <= v_truth * (1.0 + 1e-6),
        "{} > {v_truth}",
        result.cost
    );

    // validation on the twelve other poses: the paper's V per pose (variance weights: with
    // the paper's uniform ones, the elements a pose's symmetry makes zero are noise and
    // dominate V) against the true springs' V, the noise floor; and the complex error by
    // the measurement's own uncertainty (mean |G^ - G|^2 / var over lines and elements:
    // one where the model is right); the file's nominal springs for contrast
    let val = measured(&r, &truth, PoseRole::Validation);
    assert_eq!(val.len(), 12);
    for (name, pose, m) in &val {
        let v_cost = Cost::new(
            std::slice::from_ref(m),
            CostSpec {
                weighting: Weighting::InverseVariance,
                ..CostSpec::default()
            },
        )
        .unwrap();
        let z2 = |theta: &Flexibilities| {
            let g = model_frf(std::slice::from_ref(pose), &v_cost, theta, form).unwrap();
            let var = m.var.as_ref().unwrap();
            let (mut s, mut n) = (0.0, 0usize);
            for (k, gk) in g[0].iter().enumerate() {
                for (e, x) in gk.iter().enumerate() {
                    s += (m.g[k][e] - x).norm_sqr() / var[k][e];
                    n += 1;
                }
            }
            (s / n as f64, v_cost.value(&g))
        };
        let (fit_z2, fit_v) = z2(&result.best);
        let (nominal_z2, nominal_v) = z2(&r.nominal);
        let (truth_z2, truth_v) = z2(&truth);
        eprintln!(
            "{name}: V {fit_v:.3} dB (true springs {truth_v:.3}, nominal {nominal_v:.2}); \
             mean z2 {fit_z2:.2} (true springs {truth_z2:.2}, nominal {nominal_z2:.3e})"
        );
        // the measurement is unbiased: the true springs' model lies within its noise
        assert!((0.8..1.25).contains(&truth_z2), "{name}: {truth_z2}");
        // the identified model's magnitudes match as well as the true springs' (measured:
        // within 0.4 %), the nominal's not (20 to 200 times the cost)
        assert!(
            fit_v <= 1.1 * truth_v,
            "{name}: V {fit_v} against {truth_v}"
        );
        assert!(
            nominal_v > 5.0 * fit_v,
            "{name}: the nominal model fits as well ({nominal_v})"
        );
        // with the phase (not in the paper's cost): within the measurement's own
        // uncertainty (measured: mean z2 1.01-1.10, one pose 1.66), the nominal 1e6 off
        assert!(fit_z2 < 2.0, "{name}: mean z2 {fit_z2}");
        assert!(
            nominal_z2 > 1e4 * fit_z2,
            "{name}: z2 {fit_z2} against {nominal_z2}"
        );
    }
}

/// The benchmark's 60-start identification (`benches/manipulator_identify.rs`: the two
/// identification poses above, inverse-variance weights, the continuous form) on one
/// thread: how many starts reach the best minimum, the evaluations and the time. A
/// measurement, not a check (`cargo test --release -p flexid-core --test
/// manipulator_identification -- --ignored --nocapture`).
#[test]
#[ignore]
fn sixty_starts() {
    let r = reference_robot();
    let truth = truth(&r);
    let id = measured(&r, &truth, PoseRole::Identification);
    let poses: Vec<_> = id.iter().map(|(_, p, _)| p.clone()).collect();
    let meas: Vec<_> = id.iter().map(|(_, _, m)| m.clone()).collect();
    let cost = Cost::new(
        &meas,
        CostSpec {
            weighting: Weighting::InverseVariance,
            ..CostSpec::default()
        },
    )
    .unwrap();
    let t0 = std::time::Instant::now();
    let result = identify(
        &poses,
        &cost,
        &r.nominal,
        &IdentifyOptions {
            threads: 1,
            ..IdentifyOptions::default()
        },
    )
    .unwrap();
    let evaluations: usize = result.starts.iter().map(|s| s.evaluations).sum();
    eprintln!(
        "60 starts: {:.2} s, best V {:.9}, {} good, {evaluations} evaluations",
        t0.elapsed().as_secs_f64(),
        result.cost,
        result.good.len()
    );
    for (i, s) in result.starts.iter().enumerate() {
        eprintln!("start {i}: V {:.4}, {} evaluations", s.cost, s.evaluations);
    }
}
