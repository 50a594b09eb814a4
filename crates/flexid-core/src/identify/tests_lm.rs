//! The fit's own Levenberg-Marquardt on the normal equations against the naive reference,
//! the `levenberg-marquardt` crate (MINPACK's QR-based trust region on the full Jacobian):
//! same optimum, same normal matrix, same covariance.

use super::fit::{fit_chain, fit_chain_coarse, invert_spd, prepare, theta_of, FitOptions};
use super::problem::ChainProblem;
use super::tests_fit::{four_mass, grid_for, perturbed, simulate, three_mass, two_mass};
use crate::lsq::lm::{minimize, LmOptions, LmWorkspace};
use crate::model::Chain;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector};

const TIGHT: LmOptions = LmOptions {
    ftol: 1e-12,
    xtol: 1e-10,
    gtol: 1e-12,
    max_evals: 400,
    damping: crate::lsq::Damping::Nielsen,
};

/// Several problems: 2/3/4 masses, noise-free and with 2 % / 5 % noise.
fn cases() -> Vec<(Chain, f64, u64)> {
    vec![
        (two_mass(), 0.0, 0),
        (two_mass(), 0.02, 5),
        (three_mass(), 0.0, 0),
        (three_mass(), 0.02, 6),
        (three_mass(), 0.05, 7),
        (four_mass(0.02), 0.02, 8),
    ]
}

#[test]
fn own_lm_reaches_the_reference_optimum() {
    for (ch, rel, seed) in cases() {
        let frf = simulate(&ch, &grid_for(&ch), rel, seed);
        let opts = FitOptions::default();
        let data = prepare(&frf, ch.masses(), &opts).unwrap();
        let start = theta_of(&perturbed(&ch));
        // reference: the crate
        let lm = LevenbergMarquardt::new()
            .with_ftol(1e-12)
            .with_xtol(1e-10)
            .with_gtol(1e-12)
            .with_patience(400);
        let (p_ref, rep) = lm.minimize(ChainProblem::new(&data, start.clone()));
        let cost_ref = 2.0 * rep.objective_function;
        let theta_ref = p_ref.params();
        // own
        let mut problem = ChainProblem::unset(&data);
        let mut ws = LmWorkspace::new(&problem, data.params());
        let out = minimize(&mut problem, start.as_slice(), &TIGHT, &mut ws).unwrap();
        let label = format!("{}-mass, noise {rel}", ch.masses());
        assert!(out.converged, "{label}: own LM did not converge");
        let scale = cost_ref.max(1e-20);
        assert!(
            (out.cost - cost_ref).abs() <= 1e-9 * scale + 1e-14,
            "{label}: cost {} vs reference {cost_ref}",
            out.cost
        );
        // parameters: within 1e-6 in the log (1 ppm), dampings of noise-free fits looser
        for (j, (a, b)) in ws.theta.iter().zip(theta_ref.iter()).enumerate() {
            let tol = if j >= 2 * ch.masses() - 1 { 1e-5 } else { 1e-6 };
            assert!(
                (a - b).abs() < tol,
                "{label}: theta[{j}] {a} vs reference {b}"
            );
        }
    }
}

#[test]
fn normal_equations_match_the_full_jacobian() {
    for (ch, rel, seed) in cases() {
        let frf = simulate(&ch, &grid_for(&ch), rel, seed);
        let data = prepare(&frf, ch.masses(), &FitOptions::default()).unwrap();
        let theta = theta_of(&perturbed(&ch));
        let np = data.params();
        let p = ChainProblem::new(&data, theta.clone());
        let jac = p.jacobian().unwrap();
        let r = p.residuals().unwrap();
        let jtj_ref = jac.transpose() * &jac;
        let jtr_ref = jac.transpose() * &r;
        let mut jtj = vec![0.0; np * np];
        let mut jtr = vec![0.0; np];
        let cost = p
            .normal_equations(&mut p.scratch(), &mut jtj, &mut jtr)
            .unwrap();
        assert!((cost - r.norm_squared()).abs() <= 1e-12 * r.norm_squared());
        let jtj = DMatrix::from_row_slice(np, np, &jtj);
        assert!((&jtj - &jtj_ref).norm() <= 1e-12 * jtj_ref.norm());
        assert!((DVector::from_vec(jtr) - &jtr_ref).norm() <= 1e-11 * jtr_ref.norm());
    }
}

/// The standard deviations of the fit, from the accumulated `J^T J`, are the ones of the
/// former path (the stored analytic Jacobian at the optimum, `(J^T J)^-1 max(1, chi2/dof)`).
#[test]
fn covariance_matches_the_full_jacobian_path() {
    for (ch, rel, seed) in [(three_mass(), 0.02, 11), (four_mass(0.02), 0.02, 12)] {
        let frf = simulate(&ch, &grid_for(&ch), rel, seed);
        let opts = FitOptions {
            starts: 3,
            ..FitOptions::default()
        };
        let fit = fit_chain(&frf, &perturbed(&ch), &opts).unwrap();
        let data = prepare(&frf, ch.masses(), &opts).unwrap();
        let theta = theta_of(&fit.chain);
        let jac = ChainProblem::new(&data, theta.clone()).jacobian().unwrap();
        let cov = invert_spd(&(jac.transpose() * &jac)) * fit.chi2_per_dof.max(1.0);
        let np = fit.params;
        for a in 0..np {
            for b in 0..np {
                let (x, y) = (fit.cov_log[a * np + b], cov[(a, b)]);
                let s = (cov[(a, a)] * cov[(b, b)]).sqrt();
                assert!((x - y).abs() <= 1e-8 * s, "cov[{a},{b}] {x} vs {y}");
            }
        }
        let sd: Vec<f64> = (0..np)
            .map(|j| theta[j].exp() * cov[(j, j)].sqrt())
            .collect();
        let got: Vec<f64> = fit
            .std
            .inertia_kgm2
            .iter()
            .chain(&fit.std.stiffness_nm_per_rad)
            .chain(&fit.std.damping_nms_per_rad)
            .copied()
            .collect();
        for (a, b) in got.iter().zip(&sd) {
            assert!((a / b - 1.0).abs() < 1e-8, "std {a} vs {b}");
        }
    }
}

/// Coarse to fine (the starts on every k-th line, merged into known optima or abandoned
/// when hopeless, refined on all lines) reaches the optimum of running every start on all
/// lines, with the same standard deviations, and the same result on 1 and 3 threads.
#[test]
fn coarse_to_fine_reaches_the_all_lines_optimum() {
    for (ch, f0, seed) in [(three_mass(), 0.5_f64, 21), (four_mass(0.02), 5.0, 22)] {
        let grid: Vec<f64> = (0..3000)
            .map(|k| f0 * (1000.0 / f0).powf(k as f64 / 2999.0))
            .collect();
        let frf = simulate(&ch, &grid, 0.02, seed);
        let opts = FitOptions {
            starts: 12,
            threads: 1,
            ..FitOptions::default()
        };
        let fast = fit_chain(&frf, &perturbed(&ch), &opts).unwrap();
        let slow = fit_chain_coarse(&frf, &perturbed(&ch), &opts, usize::MAX).unwrap();
        let label = format!("{}-mass", ch.masses());
        // the waves of the coarse phase do not depend on the number of threads
        let threaded = FitOptions {
            threads: 3,
            ..opts.clone()
        };
        assert_eq!(
            fit_chain(&frf, &perturbed(&ch), &threaded).unwrap(),
            fast,
            "{label}: 3 threads"
        );
        assert!(
            (fast.cost - slow.cost).abs() <= 1e-8 * slow.cost,
            "{label}: cost {} vs {}",
            fast.cost,
            slow.cost
        );
        for (a, b) in theta_of(&fast.chain)
            .iter()
            .zip(theta_of(&slow.chain).iter())
        {
            assert!((a - b).abs() < 1e-5, "{label}: {a} vs {b}");
        }
        assert!(fast.starts_converged >= 1 && fast.starts_converged <= opts.starts);
    }
}
