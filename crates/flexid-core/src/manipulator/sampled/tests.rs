use super::*;
use crate::manipulator::frf::FrfPlan;
use crate::manipulator::tests_support::two_axis_pose;

/// Below a tenth of the sample rate the sampled plant's FRF is the continuous model's
/// times the hold and the backward difference, `e^(-j w T) sinc(w T / 2)^2`-like: within
/// a few percent of it; far below, within a fraction of a percent.
#[test]
fn the_sampled_frf_approaches_the_continuous_one() {
    let (pose, theta) = two_axis_pose(4);
    let fs = 4000.0;
    let sampled = SampledPose::new(&pose, &theta, fs).unwrap();
    let mut plan = FrfPlan::new(&pose);
    for (f, tol) in [(1.0, 2e-3), (10.0, 1e-2), (100.0, 0.1)] {
        let c = plan.frf(&[f], &theta).unwrap().g.remove(0);
        let s = sampled.frf(f).unwrap();
        // the delay of one sample (half for the hold, half for the difference) removed
        let d = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f / fs);
        let scale = c.iter().map(|x| x.norm()).fold(0.0, f64::max);
        for (a, b) in s.iter().zip(c.iter()) {
            assert!((a * d - b).norm() < tol * scale, "{f} Hz: {a} vs {b}");
        }
    }
}

/// Simulating the sampled plant under a sine on one axis (with the position loop, which
/// leaves the plant's FRF from the total torque unchanged) gives, at the sine's
/// frequency, the ratio of speed to total torque the FRF predicts: `G(z) U = Y`, checked
/// per column on a pure tone with the plant in steady state.
#[test]
fn simulation_and_frf_agree() {
    let (pose, theta) = two_axis_pose(6);
    let fs = 1000.0;
    let mut plant = SampledPose::new(&pose, &theta, fs).unwrap();
    let pl = PositionLoop::for_pose(&pose, 2.0);
    let axes = plant.axes();
    let period = 1000; // 1 s
    let line = 37; // 37 Hz
    let f = line as f64 * fs / period as f64;
    for col in 0..axes {
        let mut x = vec![0.0; plant.states()];
        let (mut p, mut p_prev) = (vec![0.0; axes], vec![0.0; axes]);
        let mut u = vec![0.0; axes];
        let mut fb = vec![0.0; axes];
        // the DFT line of the last of 8 periods (transients die: motor damping, the loop)
        let mut yu = vec![Complex64::new(0.0, 0.0); 2 * axes];
        let periods = 8;
        for k in 0..periods * period {
            plant.motor_positions(&x, &mut p);
            pl.torque(&p, &p_prev, fs, &mut fb);
            let speed: Vec<f64> = p.iter().zip(&p_prev).map(|(a, b)| (a - b) * fs).collect();
            let phase = 2.0 * std::f64::consts::PI * (line * (k % period)) as f64 / period as f64;
            for i in 0..axes {
                u[i] = fb[i] + if i == col { 0.2 * phase.sin() } else { 0.0 };
            }
            if k >= (periods - 1) * period {
                let w = Complex64::from_polar(1.0, -phase);
                for i in 0..axes {
                    yu[i] += speed[i] * w;
                    yu[axes + i] += u[i] * w;
                }
            }
            plant.step(&mut x, &u);
            p_prev.copy_from_slice(&p);
        }
        // the speed at sample k is the difference ending at k: it follows the torque held
        // over the sample before, one sample of delay the FRF's 1 - z^-1 carries
        let g = plant.frf(f).unwrap();
        for i in 0..axes {
            let predicted: Complex64 = (0..axes).map(|j| g[(i, j)] * yu[axes + j]).sum();
            let err = (predicted - yu[i]).norm() / yu[i].norm().max(1e-300);
            assert!(
                err < 1e-6,
                "column {col}, row {i}: {predicted} vs {}",
                yu[i]
            );
        }
    }
}

/// The FRF matrix estimated from orthogonal random-phase multisines on the sampled plant
/// under its position loop (noisy encoders: the loop feeds the noise back into the
/// torque, the estimate uses the total torque) equals the plant's own FRF matrix within
/// the estimate's own uncertainty: `|G^ - G|^2 / var` averages one over every line and
/// element, the weak off-diagonal ones included.
#[test]
fn orthogonal_multisines_measure_the_plants_frf_within_its_uncertainty() {
    use crate::excitation::OrthogonalMultisineDesign;
    use crate::frf::MimoEstimator;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let (pose, theta) = two_axis_pose(8);
    let fs = 1000.0;
    let mut plant = SampledPose::new(&pose, &theta, fs).unwrap();
    let pl = PositionLoop::for_pose(&pose, 2.0);
    let axes = plant.axes();
    let design = OrthogonalMultisineDesign {
        blocks: 2,
        seed: 3,
        ..OrthogonalMultisineDesign::new(axes, fs, 1000, [3.0, 200.0], 0.05)
    };
    let ms = design.generate().unwrap();
    let (transient, periods) = (2, 8);
    let mut est = MimoEstimator::from_multisine(&ms)
        .unwrap()
        .with_transient_periods(transient);
    let noise = Normal::new(0.0, 2e-6).unwrap(); // encoder noise [rad, motor side]
    let mut rng = rand::rngs::StdRng::seed_from_u64(21);
    let n = ms.period_samples();
    for e in 0..ms.experiments() {
        let mut x = vec![0.0; plant.states()];
        let mut p = vec![0.0; axes];
        let mut meas_prev = vec![0.0; axes];
        let mut meas = vec![0.0; axes];
        let mut fb = vec![0.0; axes];
        let mut u = vec![vec![0.0; n]; axes];
        let mut y = vec![vec![0.0; n]; axes];
        let mut uk = vec![0.0; axes];
        for period in 0..transient + periods {
            for k in 0..n {
                plant.motor_positions(&x, &mut p);
                for i in 0..axes {
                    meas[i] = p[i] + noise.sample(&mut rng);
                }
                pl.torque(&meas, &meas_prev, fs, &mut fb);
                for i in 0..axes {
                    uk[i] = fb[i] + ms.period(e, i)[k];
                    u[i][k] = uk[i];
                    y[i][k] = (meas[i] - meas_prev[i]) * fs;
                }
                plant.step(&mut x, &uk);
                meas_prev.copy_from_slice(&meas);
            }
            let us: Vec<&[f64]> = u.iter().map(|v| v.as_slice()).collect();
            let ys: Vec<&[f64]> = y.iter().map(|v| v.as_slice()).collect();
            est.push_period(e, &us, &ys).unwrap();
            let _ = period;
        }
    }
    let frf = est.estimate().unwrap();
    let (mut sum, mut count) = (0.0, 0usize);
    let mut per_element = vec![(0.0, 0usize); axes * axes];
    for (k, f) in frf.freq_hz.iter().enumerate() {
        let g = plant.frf(*f).unwrap();
        for i in 0..axes {
            for j in 0..axes {
                let z2 = (frf.g[k][(i, j)] - g[(i, j)]).norm_sqr() / frf.var[k][(i, j)];
                sum += z2;
                count += 1;
                per_element[i * axes + j].0 += z2;
                per_element[i * axes + j].1 += 1;
            }
        }
    }
    let mean = sum / count as f64;
    // the variance is itself estimated from 8 periods: its inverse averages 8/6 x
    assert!((0.8..1.5).contains(&mean), "mean z2 {mean}");
    for (e, (s, c)) in per_element.iter().enumerate() {
        let m = s / *c as f64;
        assert!((0.7..1.7).contains(&m), "element {e}: mean z2 {m}");
    }
}
