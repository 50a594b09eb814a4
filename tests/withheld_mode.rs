//! The extra-body fit of the diagnosis on the withheld-effect case where the start of
//! lowest cost lies in the wrong basin (seed 1614 of `benches/withheld_effect.rs`): the
//! starts ranked by their cost as given led the joint fit to a pair at 2.5/3.0 Hz and left
//! 0.80 of the gap; ranked after a short fit of the appended body alone they reach the true
//! pair (5.8/7.3 Hz).

mod common;

use common::withheld::{diagnose_case, generate};
use flexid::model::Chain;

#[test]
fn unmodelled_mode_seed_1614_finds_the_true_pair() {
    let dir = tempfile::tempdir().unwrap();
    let case = generate("unmodelled_mode", 1614, dir.path());
    let d = diagnose_case(&case);
    assert_eq!(d.verdict, "unmodelled_mode");
    let ratio = d.gap.after_rms_db / d.gap.before_rms_db;
    assert!(
        ratio <= 0.5,
        "gap {:.3} -> {:.3} dB (ratio {ratio:.3})",
        d.gap.before_rms_db,
        d.gap.after_rms_db
    );
    // the true 4-mass chain: the truth's 3-mass chain with the extra body appended
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&case.truth_path).unwrap()).unwrap();
    let mut ch: Chain = serde_json::from_value(truth["chain"].clone()).unwrap();
    let (je, ce) = (
        truth["inertia_kgm2"].as_f64().unwrap(),
        truth["stiffness_nm_per_rad"].as_f64().unwrap(),
    );
    ch.inertia_kgm2.push(je);
    ch.stiffness_nm_per_rad.push(ce);
    ch.damping_nms_per_rad.push(2.0 * 0.02 * (ce * je).sqrt());
    let (ar_true_hz, r_true_hz) = (ch.antiresonances_hz()[0], ch.resonances_hz()[0]);
    let p = |name: &str| {
        d.ranking[0]
            .params
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("no {name}"))
            .value
    };
    let (ar_hz, r_hz) = (p("pair1_ar_hz"), p("pair1_r_hz"));
    println!("pair 1: {ar_hz:.2}/{r_hz:.2} Hz, true {ar_true_hz:.2}/{r_true_hz:.2} Hz");
    assert!(
        (ar_hz / ar_true_hz - 1.0).abs() < 0.05,
        "{ar_hz} vs {ar_true_hz}"
    );
    assert!(
        (r_hz / r_true_hz - 1.0).abs() < 0.05,
        "{r_hz} vs {r_true_hz}"
    );
}
