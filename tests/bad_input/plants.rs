//! Bad plant files, through `flexid simulate --plant`: exit 2, the file and the key.

use super::cases::{assert_all_held, run_cases, Case};

pub const KINDS: usize = 12;

pub const GOOD: &str = r#"name = "two masses"
[chain]
inertia_kgm2 = [2e-3, 4e-3]
stiffness_nm_per_rad = [200.0]
damping_nms_per_rad = [0.02]
[measurement]
sample_rate_hz = 1000.0
"#;

/// `flexid excite` output for the plant's rate (written by the case itself).
fn excitation() -> (String, String) {
    let mut csv = String::from("time_s,torque_cmd_nm\n");
    for k in 0..200 {
        csv.push_str(&format!(
            "{:e},{:e}\n",
            k as f64 / 1000.0,
            ((k % 100) as f64 * 0.3).sin()
        ));
    }
    let json = r#"{"sample_rate_hz": 1000.0, "excitation": {"kind": "multisine", "period_samples": 100, "periods": 1, "transient_periods": 1, "excited_lines": [1]}}"#;
    (csv, json.to_string())
}

fn plant(name: &'static str, text: &str, says: &[&str]) -> Case {
    let (csv, json) = excitation();
    Case::new(
        name,
        &[
            "simulate",
            "--plant",
            "P.toml",
            "--excitation",
            "E.csv",
            "--out",
            "R.csv",
        ],
        2,
        says,
    )
    .file("P.toml", text.as_bytes().to_vec())
    .file("E.csv", csv)
    .file("E.json", json)
}

pub fn cases() -> Vec<Case> {
    vec![
        plant("not TOML", "name = \"x\n[chain", &["P.toml"]),
        plant("an empty file", "", &["P.toml", "chain"]),
        plant(
            "an unknown key",
            &GOOD.replace("[measurement]", "[measurement]\nsample_rate = 5"),
            &["P.toml", "sample_rate"],
        ),
        plant(
            "a negative inertia",
            &GOOD.replace("[2e-3, 4e-3]", "[2e-3, -4e-3]"),
            &["P.toml", "inertia"],
        ),
        plant(
            "a zero stiffness",
            &GOOD.replace("[200.0]", "[0.0]"),
            &["P.toml", "stiffness"],
        ),
        plant(
            "one stiffness too many",
            &GOOD.replace("[200.0]", "[200.0, 300.0]"),
            &["P.toml", "stiffness"],
        ),
        plant(
            "an inertia that is a word",
            &GOOD.replace("[2e-3, 4e-3]", "[\"heavy\", 4e-3]"),
            &["P.toml", "inertia_kgm2"],
        ),
        plant(
            "a NaN damping",
            &GOOD.replace("[0.02]", "[nan]"),
            &["P.toml", "damping"],
        ),
        plant(
            "a zero sample rate",
            &GOOD.replace("1000.0", "0.0"),
            &["P.toml", "sample_rate_hz"],
        ),
        plant(
            "a backlash on a coupling that is not there",
            &format!("{GOOD}[effects.backlash]\ncoupling = 4\nhalf_gap_rad = 1e-3\n"),
            &["P.toml", "coupling = 4"],
        ),
        plant(
            "zero substeps",
            &GOOD.replace(
                "sample_rate_hz = 1000.0",
                "sample_rate_hz = 1000.0\nsubsteps = 0",
            ),
            &["P.toml", "substeps"],
        ),
        plant(
            "a 2 MB plant file",
            &format!("{GOOD}{}", "#".repeat(2 << 20)),
            &["P.toml", "larger than"],
        ),
    ]
}

#[test]
fn bad_plant_files() {
    let cases = cases();
    assert_eq!(cases.len(), KINDS);
    assert_all_held("plant files", &run_cases(&cases));
}

/// Kinds of bad excitation files below (`flexid simulate --excitation`).
pub const EXCITATION_KINDS: usize = 4;

/// Bad excitation files: exit 2 and the file, line or key.
#[test]
fn bad_excitation_files() {
    let (csv, json) = excitation();
    let sim = |name: &'static str, csv: &str, json: &str, says: &[&str]| {
        Case::new(
            name,
            &[
                "simulate",
                "--plant",
                "P.toml",
                "--excitation",
                "E.csv",
                "--out",
                "R.csv",
            ],
            2,
            says,
        )
        .file("P.toml", GOOD.as_bytes().to_vec())
        .file("E.csv", csv.as_bytes().to_vec())
        .file("E.json", json.as_bytes().to_vec())
    };
    let with_row = |k: usize, row: &str| {
        let mut lines: Vec<String> = csv.lines().map(|l| l.to_string()).collect();
        lines[k] = row.to_string();
        lines.join("\n") + "\n"
    };
    let nan_csv = with_row(5, "4e-3,NaN");
    let word_csv = with_row(4, "3e-3,lots");
    let cases = vec![
        sim(
            "a NaN torque",
            &nan_csv,
            &json,
            &["E.csv", "line 6", "not finite"],
        ),
        sim(
            "a torque that is a word",
            &word_csv,
            &json,
            &["E.csv", "line 5", "torque_cmd_nm"],
        ),
        sim(
            "a description with a period longer than the samples",
            &csv,
            &json.replace("\"period_samples\": 100", "\"period_samples\": 1500000000"),
            &["E.json", "period_samples 1500000000"],
        ),
        sim("a description that is no JSON", &csv, "{", &["E.json"]),
    ];
    assert_eq!(cases.len(), EXCITATION_KINDS);
    assert_all_held("excitation files", &run_cases(&cases));
}
