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
