//! The benchmark's cases (`benches/identify_unseen.rs`, shared through `tests/unseen`)
//! through every output a user sees: no NaN, infinity or relative uncertainty above 100 %
//! is printed as a number in the text report, the JSON document or the Bode plot's SVG,
//! with the automatic order and with the true order given (which may force pairs the data
//! cannot support), on periodic and white-noise cases of 2 to 5 bodies.

mod unseen;

use flexid::analysis::{analyze, AnalysisOptions};

#[test]
fn no_output_prints_a_number_that_is_not_one() {
    let mut kinds = std::collections::BTreeSet::new();
    let mut checked = 0;
    // dev seeds of the benchmark, first ones covering both excitations and 2..5 bodies
    for seed in 1..=10u64 {
        let Some(case) = unseen::generate(seed) else {
            continue;
        };
        kinds.insert((case.chain.masses(), case.describe.contains("multisine")));
        for masses in [
            None,
            Some(case.chain.masses()),
            Some(case.chain.masses() + 1),
        ] {
            let a = analyze(
                &case.rec,
                &AnalysisOptions {
                    masses,
                    ..AnalysisOptions::default()
                },
            )
            .unwrap_or_else(|e| panic!("seed {seed} ({}): {e}", case.describe));
            let bad = unseen::bad_outputs(&a);
            assert!(
                bad.is_empty(),
                "seed {seed} ({}), masses {masses:?}:\n{}",
                case.describe,
                bad.join("\n")
            );
            checked += 1;
        }
    }
    assert!(checked >= 24, "only {checked} analyses checked");
    assert!(
        kinds.iter().any(|k| k.1) && kinds.iter().any(|k| !k.1),
        "both excitations covered: {kinds:?}"
    );
}

#[test]
fn the_checker_finds_what_it_must_refuse() {
    assert_eq!(unseen::bad_numbers("J1 1.0e-3 +- NaN", ""), 1);
    assert_eq!(unseen::bad_numbers("c1 12 +- 30 250.0 %", ""), 1);
    assert_eq!(unseen::bad_numbers("", "{\"x\": inf}"), 1);
    assert_eq!(unseen::bad_numbers("no information (SNR < 2)", ""), 0);
    assert_eq!(unseen::bad_numbers("c1 12 +- 3 25.0 %", ""), 0);
}
