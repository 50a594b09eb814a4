//! `flexid identify --max-seconds`: on a messy record (the SCARA shoulder with every
//! unmodelled effect: friction, backlash, hardening, gravity, delay, current loop, an extra
//! mode, torque noise) the automatic model order tries several orders of many starts; a
//! small cap stops it, the best model so far is returned (exit 0) and the report, the JSON
//! (`time_cap`) and the stderr progress say that it was capped. No timing assertion beyond
//! "it stopped and said so".

mod cli_common;
use cli_common::{all_effects_record, expect_ok, flexid};

use serde_json::Value;
use std::path::Path;

/// A multisine record of `plants/scara_all_effects.toml` (2 kHz, 0.5 Hz lines to 800 Hz,
/// 1 + 4 periods).
fn messy_record(dir: &Path) {
    all_effects_record(dir, "2", "4", "REC.csv");
}

#[test]
fn a_small_cap_stops_an_automatic_order_run_and_says_so() {
    let dir = tempfile::tempdir().expect("temp dir");
    messy_record(dir.path());
    let args = [
        "identify",
        "REC.csv",
        "--starts",
        "60",
        "--max-seconds",
        "0.05",
        "--json",
        "OUT.json",
    ];
    let (so, se) = expect_ok(&flexid(&args, dir.path()), "identify --max-seconds 0.05");
    let text = std::fs::read_to_string(dir.path().join("OUT.json")).expect("OUT.json");
    let j: Value = serde_json::from_str(&text).expect("JSON");
    let cap = &j["time_cap"];
    assert_eq!(cap["capped"], Value::Bool(true), "time_cap: {cap}");
    assert_eq!(cap["max_seconds"].as_f64(), Some(0.05));
    let skipped =
        cap["starts_skipped"].as_u64().unwrap_or(0) + cap["orders_skipped"].as_u64().unwrap_or(0);
    assert!(skipped > 0, "nothing skipped: {cap}");
    // the best model so far is there, and the orders not tried say why
    assert!(
        j["model"]["masses"].as_u64().is_some(),
        "no model: {}",
        j["model"]
    );
    let not_tried = j["orders"]
        .as_array()
        .expect("orders")
        .iter()
        .filter(|o| o["error"].as_str().is_some_and(|e| e.contains("time cap")))
        .count();
    assert_eq!(
        not_tried as u64,
        cap["orders_skipped"].as_u64().unwrap_or(0),
        "orders: {}",
        j["orders"]
    );
    assert!(
        so.contains("TIME CAP"),
        "report does not say it was capped:\n{so}"
    );
    assert!(
        se.contains("time cap of 0.05 s reached"),
        "stderr does not say it was capped:\n{se}"
    );
}

#[test]
fn without_reaching_the_cap_the_result_says_not_capped() {
    let dir = tempfile::tempdir().expect("temp dir");
    messy_record(dir.path());
    let args = ["identify", "REC.csv", "--json", "OUT.json"];
    let (so, se) = expect_ok(&flexid(&args, dir.path()), "identify");
    let text = std::fs::read_to_string(dir.path().join("OUT.json")).expect("OUT.json");
    let j: Value = serde_json::from_str(&text).expect("JSON");
    assert_eq!(
        j["time_cap"]["capped"],
        Value::Bool(false),
        "{}",
        j["time_cap"]
    );
    assert_eq!(j["time_cap"]["max_seconds"].as_f64(), Some(120.0));
    assert!(!so.contains("TIME CAP"));
    // plain progress (stderr is not a terminal here) ends with a summary line
    assert!(
        se.contains("flexid identify: done in"),
        "no progress lines:\n{se}"
    );
}
