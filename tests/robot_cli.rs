//! `flexid robot`: the multi-axis identification of issue 17 on the simulated reference arm
//! from the command line: the table, the cost per pose, the JSON with units and
//! uncertainties, the N x N Bode matrix as SVG; and clear errors for bad input.

mod cli_common;

use cli_common::{expect_code, flexid};

#[test]
fn the_reference_arm_is_identified_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = flexid(
        &[
            "robot",
            "--starts",
            "2",
            "--json",
            "robot.json",
            "--svg",
            "robot.svg",
        ],
        dir.path(),
    );
    let (stdout, stderr) = expect_code(&out, 0, "flexid robot");
    assert!(
        stdout.contains("k_g1") && stdout.contains("val-12"),
        "{stdout}"
    );
    assert!(stderr.contains("identified in"), "{stderr}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("robot.json")).unwrap())
            .unwrap();
    let params = json["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 24);
    // the simulated robot is the file's: every stiffness back within 5 % from a start
    // 1.5 x off (measured: 0.03 %)
    let flex = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/robots/flexid-arm6.flex.toml"
    ))
    .unwrap();
    let file = flexid_core::manipulator::FlexFile::parse(&flex, "flexid-arm6.flex.toml").unwrap();
    let gears: Vec<f64> = file.axes.iter().map(|a| a.gear.stiffness).collect();
    for (i, g) in gears.iter().enumerate() {
        let p = params
            .iter()
            .find(|p| p["name"] == format!("k_g{}", i + 1))
            .unwrap();
        assert_eq!(p["unit"], "N m/rad");
        let v = p["value"].as_f64().unwrap();
        assert!((v / g - 1.0).abs() < 0.05, "k_g{}: {v} for {g}", i + 1);
        assert_eq!(p["identifiable"], true);
    }
    assert_eq!(json["poses"].as_array().unwrap().len(), 14);
    let svg = std::fs::read_to_string(dir.path().join("robot.svg")).unwrap();
    assert_eq!(svg.matches("(speed ").count(), 36);
    assert!(!svg.contains("NaN"));
}

#[test]
fn bad_robot_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = flexid(&["robot", "--robot", "missing.flex.toml"], dir.path());
    let (_, stderr) = expect_code(&out, 2, "a missing file");
    assert!(stderr.contains("missing.flex.toml"), "{stderr}");
    std::fs::write(dir.path().join("bad.flex.toml"), "urdf = \"x.urdf\"\n").unwrap();
    let out = flexid(&["robot", "--robot", "bad.flex.toml"], dir.path());
    let (_, stderr) = expect_code(&out, 2, "no conventions");
    assert!(
        stderr.contains("bad.flex.toml") && stderr.contains("conventions"),
        "{stderr}"
    );
    let out = flexid(&["robot", "--start-scale", "0"], dir.path());
    expect_code(&out, 2, "a zero start scale");
}
