//! All effects off: the exact ZOH simulation is reproduced, with fourth-order convergence.

use super::*;
use crate::sim::{simulate_position, SimOptions};

fn exact(chain: &Chain, torque: &[f64], fs: f64, delay: u32) -> Vec<f64> {
    let opts = SimOptions {
        sample_rate_hz: fs,
        delay_samples: delay,
        ..Default::default()
    };
    simulate_position(chain, torque, &opts).unwrap()
}

#[test]
fn linear_plant_reproduces_the_exact_zoh_simulation() {
    let fs = 1000.0;
    let torque = multisine(1000, &[3, 17, 40, 81, 150, 333, 470], 3);
    for chain in [chain2(), chain3()] {
        let want = exact(&chain, &torque, fs, 0);
        let got =
            simulate_positions(&PlantSpec::linear(chain.clone()), &torque, fs, 64, 1).unwrap();
        let e = rel_err(&got, &want);
        eprintln!("{} masses, 64 substeps: rel err {e:.3e}", chain.masses());
        assert!(e < 1e-7, "{} masses: rel err {e:e}", chain.masses());
    }
}

#[test]
fn linear_error_converges_at_fourth_order() {
    let fs = 1000.0;
    let torque = multisine(1000, &[3, 17, 40, 81, 150, 333, 470], 2);
    let chain = chain3();
    let want = exact(&chain, &torque, fs, 0);
    let errs: Vec<f64> = [4u32, 8, 16]
        .iter()
        .map(|&s| {
            let got =
                simulate_positions(&PlantSpec::linear(chain.clone()), &torque, fs, s, 1).unwrap();
            rel_err(&got, &want)
        })
        .collect();
    eprintln!("errors at 4, 8, 16 substeps: {errs:?}");
    for w in errs.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (11.0..24.0).contains(&ratio),
            "ratio {ratio} (errors {errs:?})"
        );
    }
}

/// Whole-cycle delay in the effects equals the exact simulation's `delay_samples`.
#[test]
fn whole_cycle_delay_matches_delay_samples() {
    let fs = 1000.0;
    let torque = multisine(500, &[2, 9, 31, 77], 3);
    let chain = chain3();
    let want = exact(&chain, &torque, fs, 2);
    let mut spec = PlantSpec::linear(chain);
    spec.effects.time_delay = Some(TimeDelay { delay_s: 2e-3 });
    let got = simulate_positions(&spec, &torque, fs, 64, 1).unwrap();
    let e = rel_err(&got, &want);
    assert!(e < 1e-7, "rel err {e:e}");
}
