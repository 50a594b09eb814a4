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

/// The SCARA shoulder (590 Hz gear mode) at a 4 kHz drive cycle with 10 sub-steps, the
/// drive's setting: samples within 1e-7 of the exact ZOH response's peak.
#[test]
fn scara_at_4_khz_with_10_substeps_is_accurate() {
    let plant = PlantFile::parse(DEFAULT_PLANT, "embedded default plant").unwrap();
    let fs = 4000.0;
    let torque = multisine(4000, &[1, 3, 17, 40, 150, 590, 1000, 1500], 2);
    let want = exact(&plant.chain, &torque, fs, 0);
    let got =
        simulate_positions(&PlantSpec::linear(plant.chain.clone()), &torque, fs, 10, 1).unwrap();
    let e = rel_err(&got, &want);
    // differenced velocity, the quantity the FRF is formed of
    let dv = |p: &[f64]| -> Vec<f64> { p.windows(2).map(|w| (w[1] - w[0]) * fs).collect() };
    let ev = rel_err(&dv(&got), &dv(&want));
    eprintln!("SCARA 4 kHz, 10 substeps: position {e:.2e}, velocity {ev:.2e}");
    assert!(e < 1e-7 && ev < 1e-5, "position {e:e}, velocity {ev:e}");
}
