//! The identification of a chain whose motor has viscous friction to the ground, from a
//! single log sweep that starts well below the friction's corner frequency `b / (2 pi J)`:
//! simulated by the fine-step plant (not the fit's sampled model), the sweep starting
//! from rest, a disturbance torque and a 20-bit encoder.

use super::tests_support::simulated;
use super::{analyze, AnalysisOptions};
use crate::excitation::ChirpDesign;
use crate::model::Chain;
use crate::plant::{Friction, PlantSpec};
use crate::recording::Recording;

/// The 4-body chain of a world case that a free-chain fit turned into a 65 kg m^2 body on
/// a 0.05 N m/rad spring (its damper standing in for the ground's).
fn chain4() -> Chain {
    Chain::new(
        vec![9.8225e-3, 1.39491e-2, 1.29709e-2, 1.21030e-2],
        vec![16340.9, 9709.9, 781.47],
        vec![0.769, 0.504, 0.165],
    )
    .unwrap()
}

/// A sweep 0.5 Hz .. 1.6 kHz over 14 s at 4 kHz on `chain` with viscous friction `b`.
fn sweep_recording(chain: &Chain, b: f64) -> Recording {
    let fs = 4000.0;
    let mut design = ChirpDesign::new(fs, 0.5, 1600.0, 14.0, 5.0);
    design.taper_s = 0.2;
    let chirp = design.generate().unwrap();
    let mut spec = PlantSpec::linear(chain.clone());
    spec.effects.friction = Some(Friction {
        coulomb_nm: 0.0,
        viscous_nms_per_rad: b,
    });
    spec.effects.torque_noise_nm = 2e-3;
    spec.effects.encoder_counts_per_rev = Some(1 << 20);
    simulated(&spec, &chirp.signal, chirp.info(), fs, 8, 7)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// With a damper to the ground (corner 2.3 Hz, the sweep from 0.5 Hz) the four bodies are
/// found (automatic order), every inertia and stiffness within 2 %, and the damper within
/// 2 % and within 4 of its standard deviations. (A free chain fitted to the same record
/// chose 4 bodies with J4 = 65 kg m^2 and c2 = 0.05 N m/rad.)
#[test]
fn a_chain_with_viscous_friction_to_the_ground_is_identified_with_it() {
    let chain = chain4();
    let b = 0.724;
    let a = analyze(&sweep_recording(&chain, b), &AnalysisOptions::default()).unwrap();
    let g = a
        .ground_damper
        .as_ref()
        .expect("the damper is seen")
        .damping;
    assert!(rel(g.b_nms_per_rad, b) < 0.02, "b {g:?} vs {b}");
    assert!(
        (g.b_nms_per_rad - b).abs() < 4.0 * g.std_nms_per_rad + 1e-3 * b,
        "{g:?}"
    );
    let fit = a.fit.as_ref().unwrap();
    assert_eq!(fit.chain.masses(), 4, "{:?}", fit.chain);
    for (e, t) in fit.chain.inertia_kgm2.iter().zip(&chain.inertia_kgm2) {
        assert!(rel(*e, *t) < 0.02, "J {:?}", fit.chain.inertia_kgm2);
    }
    for (e, t) in fit
        .chain
        .stiffness_nm_per_rad
        .iter()
        .zip(&chain.stiffness_nm_per_rad)
    {
        assert!(rel(*e, *t) < 0.02, "c {:?}", fit.chain.stiffness_nm_per_rad);
    }
    // the model's FRF has the damper back: it follows the measurement below and around
    // the damper's corner (where the free chain's response is 1.7 times larger)
    let (model, measured) = (a.model_frf.as_ref().unwrap(), &a.measured.frf);
    for i in 1..8 {
        let (m, h) = (model.h[i], measured.h[i]);
        assert!(
            (m - h).norm() < 5e-3 * h.norm(),
            "{} Hz: model {m} measured {h}",
            measured.freq_hz[i]
        );
    }
    assert_eq!(a.model.as_ref().unwrap().ground_damping, Some(g));
}

/// Without friction to the ground nothing is taken out: the chain is fitted as measured.
#[test]
fn a_free_chain_has_no_ground_damper_taken_out() {
    let chain = chain4();
    let a = analyze(&sweep_recording(&chain, 0.0), &AnalysisOptions::default()).unwrap();
    assert!(
        a.ground_damper.is_none(),
        "{:?}",
        a.ground_damper.map(|g| g.damping)
    );
    assert_eq!(a.fit.as_ref().unwrap().chain.masses(), 4);
}
