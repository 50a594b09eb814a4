//! The paper's case study and the exact inverse, each checked against an independent
//! computation (the chain's own eigenvalue spectra).

use super::exact::{chain_from_spectra, with_coupling_damping};
use super::paper::{increment_db, step_by_step};
use crate::model::Chain;

const J: f64 = 25.9e-3;
const PAIRS: [(f64, f64); 2] = [(2.9, 5.0), (380.0, 590.0)];

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn paper_case_study_reproduced_from_its_inputs() {
    let s = step_by_step(J, &PAIRS, None).unwrap();
    let j12 = s.pairs[0].inertia_above_kgm2;
    assert!(rel(j12, 8.72e-3) < 0.005, "J1+J2 = {j12}");
    assert!(rel(s.chain.inertia_kgm2[2], 17.18e-3) < 0.005, "J3");
    // From the frequencies the second increment is 7.64 dB, giving J1 = 3.61e-3, J2 = 5.10e-3.
    assert!((s.pairs[1].increment_db - 7.645).abs() < 0.01);
    assert!(rel(s.chain.inertia_kgm2[0], 3.614e-3) < 0.002);
    assert!(rel(s.chain.inertia_kgm2[1], 5.098e-3) < 0.002);
    // The paper's J1 = 3.5e-3 / J2 = 5.22e-3 follow from reading L2 off the plot as ~7.9 dB.
    let l2_paper = increment_db(j12, 3.5e-3);
    assert!((l2_paper - 7.93).abs() < 0.03, "{l2_paper}");
    let read = step_by_step(J, &PAIRS, Some(&[s.pairs[0].increment_db, l2_paper])).unwrap();
    assert!(rel(read.chain.inertia_kgm2[0], 3.5e-3) < 0.001);
    assert!(rel(read.chain.inertia_kgm2[1], 5.22e-3) < 0.002);
    // stiffnesses: c2 = J3 w_AR1^2, c1 = J2 w_AR2^2
    let w1 = 2.0 * std::f64::consts::PI * 2.9;
    let w2 = 2.0 * std::f64::consts::PI * 380.0;
    assert!(
        rel(
            s.chain.stiffness_nm_per_rad[1],
            s.chain.inertia_kgm2[2] * w1 * w1
        ) < 1e-12
    );
    assert!(
        rel(
            s.chain.stiffness_nm_per_rad[0],
            s.chain.inertia_kgm2[1] * w2 * w2
        ) < 1e-12
    );
    assert!((s.chain.stiffness_nm_per_rad[1] - 5.71).abs() < 0.02);
    assert!((s.chain.stiffness_nm_per_rad[0] - 2.906e4).abs() < 30.0);
}

#[test]
fn two_body_step_by_step_is_exact() {
    // For one pair the two-body formulas are the exact inverse.
    let ch = Chain::new(vec![2e-3, 7e-3], vec![850.0], vec![0.0]).unwrap();
    let pairs = [(ch.antiresonances_hz()[0], ch.resonances_hz()[0])];
    let s = step_by_step(ch.total_inertia(), &pairs, None).unwrap();
    for (a, b) in s.chain.inertia_kgm2.iter().zip(&ch.inertia_kgm2) {
        assert!(rel(*a, *b) < 1e-12);
    }
    assert!(rel(s.chain.stiffness_nm_per_rad[0], 850.0) < 1e-12);
}

#[test]
fn exact_inverse_round_trips_random_spectra() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for n in 2..=6 {
        for _ in 0..20 {
            // random interlaced spectra within 1 Hz .. 1 kHz (the span of real arms: the
            // paper's is 2.9 .. 590 Hz), neighbours at least 10 % apart
            let freqs = loop {
                let mut f: Vec<f64> = (0..2 * (n - 1))
                    .map(|_| 10f64.powf(rng.random_range(0.0..3.0)))
                    .collect();
                f.sort_by(f64::total_cmp);
                if f.windows(2).all(|w| w[1] / w[0] > 1.1) {
                    break f;
                }
            };
            let ar: Vec<f64> = freqs.iter().step_by(2).copied().collect();
            let r: Vec<f64> = freqs.iter().skip(1).step_by(2).copied().collect();
            let j = 10f64.powf(rng.random_range(-3.0..-1.0));
            let ch = chain_from_spectra(j, &ar, &r).unwrap();
            // independent check: the synthesised chain's eigen-spectra are the given ones
            for (a, b) in ch.antiresonances_hz().iter().zip(&ar) {
                assert!(rel(*a, *b) < 1e-8, "n={n}: AR {a} vs {b}");
            }
            for (a, b) in ch.resonances_hz().iter().zip(&r) {
                assert!(rel(*a, *b) < 1e-8, "n={n}: R {a} vs {b}");
            }
            assert!(rel(ch.total_inertia(), j) < 1e-10);
            // and synthesising again from those spectra returns the same chain
            let back = chain_from_spectra(j, &ch.antiresonances_hz(), &ch.resonances_hz()).unwrap();
            for (a, b) in back.inertia_kgm2.iter().zip(&ch.inertia_kgm2) {
                assert!(rel(*a, *b) < 1e-6, "n={n}: J {a} vs {b}");
            }
            for (a, b) in back
                .stiffness_nm_per_rad
                .iter()
                .zip(&ch.stiffness_nm_per_rad)
            {
                assert!(rel(*a, *b) < 1e-6, "n={n}: c {a} vs {b}");
            }
        }
    }
}

#[test]
fn exact_inverse_of_the_case_study_has_the_given_spectra() {
    let ar = [2.9, 380.0];
    let r = [5.0, 590.0];
    let ch = chain_from_spectra(J, &ar, &r).unwrap();
    // independent check: eigenvalues of the synthesised chain
    for (a, b) in ch.antiresonances_hz().iter().zip(ar) {
        assert!(rel(*a, b) < 1e-9, "{a} vs {b}");
    }
    for (a, b) in ch.resonances_hz().iter().zip(r) {
        assert!(rel(*a, b) < 1e-9, "{a} vs {b}");
    }
    assert!(rel(ch.total_inertia(), J) < 1e-12);
    // close to the step-by-step result because the pairs are two decades apart
    let s = step_by_step(J, &PAIRS, None).unwrap();
    for (a, b) in ch.inertia_kgm2.iter().zip(&s.chain.inertia_kgm2) {
        assert!(rel(*a, *b) < 0.01, "{a} vs {b}");
    }
}

#[test]
fn exact_inverse_differs_from_step_by_step_for_close_pairs() {
    let ch = Chain::new(vec![2e-3, 3e-3, 4e-3], vec![300.0, 500.0], vec![0.0, 0.0]).unwrap();
    let (ar, r) = (ch.antiresonances_hz(), ch.resonances_hz());
    let pairs: Vec<(f64, f64)> = ar.iter().copied().zip(r.iter().copied()).collect();
    let s = step_by_step(ch.total_inertia(), &pairs, None).unwrap();
    let worst = s
        .chain
        .inertia_kgm2
        .iter()
        .zip(&ch.inertia_kgm2)
        .map(|(a, b)| rel(*a, *b))
        .fold(0.0, f64::max);
    assert!(worst > 0.05, "step-by-step unexpectedly exact: {worst}");
    let back = chain_from_spectra(ch.total_inertia(), &ar, &r).unwrap();
    assert!(rel(back.inertia_kgm2[1], 3e-3) < 1e-8);
}

#[test]
fn non_interlaced_spectra_are_refused() {
    assert!(matches!(
        chain_from_spectra(1.0, &[10.0, 12.0], &[11.0, 11.5]),
        Err(super::exact::ExactError::NotInterlaced { .. })
    ));
    assert!(chain_from_spectra(1.0, &[10.0], &[5.0]).is_err());
    assert!(step_by_step(-1.0, &PAIRS, None).is_err());
}

#[test]
fn coupling_damping_sets_the_two_body_damping_ratio() {
    let ch = Chain::new(vec![1e-3, 1e-3], vec![1000.0], vec![0.0]).unwrap();
    let d = with_coupling_damping(ch, 0.05);
    // two-body: zeta = d / (2 sqrt(c Jr)), Jr = 0.5e-3
    assert!(
        rel(
            d.damping_nms_per_rad[0],
            2.0 * 0.05 * (1000.0f64 * 0.5e-3).sqrt()
        ) < 1e-12
    );
}
