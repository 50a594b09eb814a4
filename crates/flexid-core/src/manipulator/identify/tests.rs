use super::*;
use crate::manipulator::cost::{CostSpec, PoseMeasurement, Weighting};
use crate::manipulator::tests_support::two_axis_pose;

/// Lines from 1 to 150 Hz, log-spaced.
fn lines() -> Vec<f64> {
    (0..120)
        .map(|i| 1.0 * 150f64.powf(i as f64 / 119.0))
        .collect()
}

/// Two poses of the made-up 2-axis arm (two random mass matrices and gravity
/// stiffnesses: the same springs seen from two configurations) and their exact FRFs.
fn two_poses() -> (Vec<RigidPose>, Flexibilities, Vec<PoseMeasurement>) {
    let (a, theta) = two_axis_pose(11);
    let (b, _) = two_axis_pose(12);
    let poses = vec![a, b];
    let f = lines();
    let meas = poses
        .iter()
        .map(|p| PoseMeasurement {
            f_hz: f.clone(),
            g: FrfPlan::new(p).frf(&f, &theta).unwrap().g,
            var: None,
            var_sym: None,
        })
        .collect();
    (poses, theta, meas)
}

fn max_rel_error(a: &Flexibilities, b: &Flexibilities) -> f64 {
    a.to_log()
        .iter()
        .zip(b.to_log())
        .map(|(x, y)| (x - y).exp() - 1.0)
        .fold(0.0, |m, e: f64| m.max(e.abs()))
}

/// From exact FRFs of two poses, the multi-start fit recovers every stiffness and
/// damping from starts up to 3x off, and the good starts all agree.
#[test]
fn exact_frfs_give_back_the_parameters() {
    let (poses, truth, meas) = two_poses();
    let cost = Cost::new(&meas, CostSpec::default()).unwrap();
    // the nominal 1.8x / 0.6x off the truth, alternating
    let nominal = Flexibilities::from_log(
        &truth
            .to_log()
            .iter()
            .enumerate()
            .map(|(i, x)| x + if i % 2 == 0 { 1.8f64.ln() } else { 0.6f64.ln() })
            .collect::<Vec<_>>(),
    );
    let opts = IdentifyOptions {
        starts: 8,
        ..IdentifyOptions::default()
    };
    let id = identify(&poses, &cost, &nominal, &opts).unwrap();
    assert_eq!(id.starts.len(), 8);
    let e = max_rel_error(&id.best, &truth);
    assert!(e < 1e-6, "relative error {e:e}, cost {}", id.cost);
    assert!(id.cost < 1e-6, "{}", id.cost);
    assert!(
        id.good.len() >= 4,
        "{:?}",
        id.starts.iter().map(|s| s.cost).collect::<Vec<_>>()
    );
    assert!(id.spread.iter().all(|s| *s < 1e-5), "{:?}", id.spread);
    assert_eq!(id.cost_per_pose.len(), 2);
}

/// On a measurement with noise, the fit ends at a stationary point of the paper's cost
/// itself (not only of the reweighted sum of squares): central differences of `V` in
/// the logarithms vanish there, for `p = 2` and `p = 1.5`.
#[test]
fn the_reweighted_fit_ends_at_a_stationary_point_of_v() {
    let (poses, truth, mut meas) = two_poses();
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for m in &mut meas {
        for g in &mut m.g {
            for x in g.iter_mut() {
                *x *= Complex64::new(
                    1.0 + 0.03 * rng.random_range(-1.0..1.0),
                    0.03 * rng.random_range(-1.0..1.0),
                );
            }
        }
    }
    for p in [2.0, 1.5] {
        let cost = Cost::new(
            &meas,
            CostSpec {
                p,
                ..CostSpec::default()
            },
        )
        .unwrap();
        let opts = IdentifyOptions {
            starts: 1,
            threads: 1,
            ..IdentifyOptions::default()
        };
        let id = identify(&poses, &cost, &truth, &opts).unwrap();
        let v = |t: &[f64]| {
            cost.value(
                &model_frf(
                    &poses,
                    &cost,
                    &Flexibilities::from_log(t),
                    FrfForm::Continuous,
                )
                .unwrap(),
            )
        };
        let at = id.best.to_log();
        let v0 = v(&at);
        assert!((v0 - id.cost).abs() < 1e-9 * v0);
        // a noisy measurement: the truth is not the minimum, the fit is below it
        assert!(v0 < v(&truth.to_log()), "p = {p}");
        let h = 1e-4;
        for j in 0..at.len() {
            let mut t = at.clone();
            t[j] += h;
            let up = v(&t);
            t[j] -= 2.0 * h;
            let down = v(&t);
            let slope = (up - down) / (2.0 * h);
            let curvature = (up - 2.0 * v0 + down) / (h * h);
            // the step to the minimum along j, Newton's, is a tiny fraction of the parameter
            let step = if curvature > 0.0 {
                slope / curvature
            } else {
                slope
            };
            assert!(
                step.abs() < 1e-4,
                "p = {p}, parameter {j}: slope {slope:e}, step {step:e}"
            );
        }
    }
}

/// The start design: start 0 is the nominal; every parameter's other starts fill each
/// stratum of the log range once, within `[nominal / spread, nominal * spread]`.
#[test]
fn the_starts_are_a_latin_hypercube() {
    let nominal = Flexibilities::new(vec![1e5, 2e6, 4e5], vec![10.0, 50.0, 3.0]).unwrap();
    let opts = IdentifyOptions {
        starts: 11,
        spread: 3.0,
        ..IdentifyOptions::default()
    };
    let starts = start_design(&nominal, &opts);
    assert_eq!(starts.len(), 11);
    let base = nominal.to_log();
    assert_eq!(starts[0], base);
    for j in 0..base.len() {
        let mut strata: Vec<usize> = starts[1..]
            .iter()
            .map(|s| {
                let u = ((s[j] - base[j]) / 3f64.ln() + 1.0) / 2.0;
                assert!((0.0..1.0).contains(&u));
                (u * 10.0).floor() as usize
            })
            .collect();
        strata.sort();
        assert_eq!(strata, (0..10).collect::<Vec<_>>());
    }
}

/// The result does not depend on the number of worker threads.
#[test]
fn threads_do_not_change_the_result() {
    let (poses, truth, meas) = two_poses();
    let cost = Cost::new(
        &meas,
        CostSpec {
            weighting: Weighting::Uniform,
            ..CostSpec::default()
        },
    )
    .unwrap();
    let run = |threads| {
        identify(
            &poses,
            &cost,
            &truth,
            &IdentifyOptions {
                starts: 4,
                threads,
                ..IdentifyOptions::default()
            },
        )
        .unwrap()
    };
    assert_eq!(run(1), run(2));
}

/// The normal equations from the error pass's kept solves and errors (after a cost pass
/// at the same `theta`) are those of a fresh pass to the bit: on the reference robot's
/// two poses (the benchmark's problem), at the nominal springs and at a start.
#[test]
fn normal_equations_from_the_kept_solve_are_the_fresh_ones() {
    let robot = crate::manipulator::reference::robot();
    let truth = crate::manipulator::reference::perturbed_truth(&robot);
    let mut poses = Vec::new();
    let mut meas = Vec::new();
    let f: Vec<f64> = (0..60)
        .map(|i| 2.0 * 150f64.powf(i as f64 / 59.0))
        .collect();
    for (_, q) in robot.poses_of(crate::manipulator::flex_file::PoseRole::Identification) {
        let pose = robot.pose(&q).unwrap();
        let g = FrfPlan::new(&pose).frf(&f, &truth).unwrap().g;
        // a made-up variance: 1 % of each element's magnitude squared plus a floor
        let var = g
            .iter()
            .map(|g| g.map(|x| 1e-4 * x.norm_sqr() + 1e-12))
            .collect();
        meas.push(PoseMeasurement {
            f_hz: f.clone(),
            g,
            var: Some(var),
            var_sym: None,
        });
        poses.push(pose);
    }
    let spec = CostSpec {
        weighting: Weighting::InverseVariance,
        ..CostSpec::default()
    };
    let cost = Cost::new(&meas, spec).unwrap();
    let starts = start_design(&robot.nominal, &IdentifyOptions::default());
    for theta in [&starts[0], &starts[5]] {
        let np = theta.len();
        let mut fit = Fit::new(&poses, &cost);
        fit.set_theta(theta);
        fit.errors().unwrap();
        fit.reweight();
        assert!(fit.kept);
        let (mut jtj_kept, mut jtr_kept) = (vec![0.0; np * np], vec![0.0; np]);
        assert!(fit.normal_after_cost(&mut (), &mut jtj_kept, &mut jtr_kept));
        fit.kept = false;
        let (mut jtj, mut jtr) = (vec![0.0; np * np], vec![0.0; np]);
        assert!(fit.normal_after_cost(&mut (), &mut jtj, &mut jtr));
        assert_eq!(jtj_kept, jtj);
        assert_eq!(jtr_kept, jtr);
        // a different theta forgets the kept solves
        let mut other = theta.clone();
        other[0] += 0.1;
        fit.kept = true;
        fit.set_theta(&other);
        assert!(!fit.kept);
    }
}
