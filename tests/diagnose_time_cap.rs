//! `flexid diagnose --max-seconds` (issue 16, "a time cap ... returns the best result so
//! far"): the cap is checked inside the diagnosis between its steps, so at the cap it
//! answers with what it fitted (the verdict, ranking and gap of the candidates done),
//! marked `time_cap.capped` with the steps not tried, and nothing keeps running: the
//! command returns within the cap plus one step, on one core. Before, the command line
//! stopped waiting at the cap, identified the nominal chain instead, and the diagnosis
//! thread ran on beside it until the process ended.
//!
//! The case: two levels (1 and 2 N m peak) of the SCARA shoulder with every unmodelled
//! effect (`plants/scara_all_effects.toml`), 2 kHz, 1 + 3 periods of 4000 samples; with
//! the amplitude-dependent candidates simulated it takes about 1.5 s of CPU uncapped, its
//! longest single step (backlash) under 1 s.

mod cli_common;
use cli_common::{all_effects_record, run_measured, Measured};

use serde_json::Value;
use std::path::Path;
use std::time::{Duration, Instant};

/// The cap of the capped runs [s]: past the reading, the FRFs and the nominal chain
/// (about 0.15 s here), well short of the whole diagnosis.
const CAP_S: f64 = 0.5;

/// Most the command may take past the cap [s]: the step under way when the cap passes
/// ends (the longest here, backlash, takes about 0.9 s on an idle core), plus the start,
/// the reading and the writing, with room for a loaded machine. The old thread-and-
/// fallback design also stopped in about this time; the CPU check below is what tells
/// them apart.
const MARGIN_S: f64 = 3.0;

fn two_levels(dir: &Path) {
    all_effects_record(dir, "1", "3", "R1.csv");
    all_effects_record(dir, "2", "3", "R2.csv");
}

fn diagnose(dir: &Path, cap: Option<f64>, json: &str) -> (Measured, Value) {
    let cap = cap.map(|c| c.to_string());
    let mut args = vec![
        "diagnose",
        "R1.csv",
        "R2.csv",
        "--masses",
        "2",
        "--all-effects",
        "--json",
        json,
    ];
    if let Some(c) = &cap {
        args.extend(["--max-seconds", c.as_str()]);
    }
    let bin = Path::new(env!("CARGO_BIN_EXE_flexid"));
    let m = run_measured(bin, &args, dir, Duration::from_secs(300));
    assert_eq!(m.code, Some(0), "{args:?}: {:?}\n{}", m.code, m.stderr);
    assert!(!m.stderr.contains("panicked"), "{}", m.stderr);
    let text = std::fs::read_to_string(dir.join(json)).expect("the JSON");
    (m, serde_json::from_str(&text).expect("JSON"))
}

#[test]
fn a_small_cap_answers_from_inside_with_what_was_fitted() {
    let dir = tempfile::tempdir().expect("temp dir");
    two_levels(dir.path());
    let (full, fj) = diagnose(dir.path(), None, "full.json");
    let (capped, cj) = diagnose(dir.path(), Some(CAP_S), "capped.json");
    let ranked = |j: &Value| j["ranking"].as_array().map_or(0, |r| r.len());
    let not_tried = |j: &Value| j["time_cap"]["not_tried"].as_array().map_or(0, |r| r.len());
    eprintln!(
        "uncapped: {:.2} s wall, {:.2} s CPU, {} candidates ranked; capped at {CAP_S} s: \
         {:.2} s wall ({:+.2} s over the cap; the diagnosis's own elapsed_s {:.2}), {:.2} s CPU, \
         {} ranked, not tried: {}",
        full.wall_s,
        full.cpu_s,
        ranked(&fj),
        capped.wall_s,
        capped.wall_s - CAP_S,
        cj["time_cap"]["elapsed_s"].as_f64().unwrap_or(f64::NAN),
        capped.cpu_s,
        ranked(&cj),
        cj["time_cap"]["not_tried"]
    );
    // uncapped: the whole diagnosis, said so
    assert_eq!(fj["time_cap"]["capped"], false, "{}", fj["time_cap"]);
    assert_eq!(fj["time_cap"]["max_seconds"].as_f64(), Some(300.0));
    assert_eq!(not_tried(&fj), 0, "{}", fj["time_cap"]);
    assert!(!full.stdout.contains("TIME CAP"), "{}", full.stdout);
    // capped: a diagnosis of its own (not the nominal-chain fallback) with fewer
    // candidates tried, the ones left out named, and the contract's fields there
    let cap = &cj["time_cap"];
    assert_eq!(cap["capped"], true, "{cap}");
    assert_eq!(cap["max_seconds"].as_f64(), Some(CAP_S), "{cap}");
    assert!(not_tried(&cj) > 0, "{cap}");
    assert!(
        ranked(&cj) < ranked(&fj),
        "capped ranking {} not shorter than {}",
        cj["ranking"],
        fj["ranking"]
    );
    let verdict = cj["verdict"].as_str().expect("a verdict");
    assert!(verdict == "none" || verdict == "unexplained" || ranked(&cj) > 0);
    for key in ["before_rms_db", "after_rms_db"] {
        assert!(
            cj["gap"][key].as_f64().is_some(),
            "gap.{key}: {}",
            cj["gap"]
        );
    }
    assert!(
        cj["gap"]["bands"].is_array() && cj["effects"].is_array(),
        "{cj}"
    );
    assert!(
        capped.stdout.contains("TIME CAP") && capped.stdout.contains("not tried"),
        "the report does not say it was capped:\n{}",
        capped.stdout
    );
    // it returned within the cap plus one step, and sooner than the whole diagnosis
    assert!(
        capped.wall_s <= CAP_S + MARGIN_S,
        "{:.2} s for a cap of {CAP_S} s",
        capped.wall_s
    );
    assert!(
        capped.wall_s < full.wall_s,
        "capped {:.2} s, uncapped {:.2} s",
        capped.wall_s,
        full.wall_s
    );
    // one thread worked, and no other ran beside it: the CPU time is not more than the wall
    // time (the old design burnt a second core with the abandoned diagnosis thread while it
    // identified the nominal chain)
    assert!(
        capped.cpu_s <= capped.wall_s * 1.1 + 0.05,
        "{:.2} s CPU in {:.2} s wall: a second thread ran",
        capped.cpu_s,
        capped.wall_s
    );
}

/// The library call: the diagnosis returns at the cap on the calling thread and leaves no
/// thread of its own behind (the process's thread count is the same after as before).
#[test]
fn the_library_call_returns_at_the_cap_with_no_thread_left() {
    use flexid::diagnose::{diagnose, DiagnoseOptions};
    use flexid::identify::fit::FitBudget;
    let dir = tempfile::tempdir().expect("temp dir");
    two_levels(dir.path());
    let recs: Vec<_> = ["R1.csv", "R2.csv"]
        .iter()
        .map(|f| flexid::recording::read_recording(dir.path().join(f)).expect("recording"))
        .collect();
    let threads = || {
        std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find_map(|l| l.strip_prefix("Threads:"))
                    .and_then(|n| n.trim().parse::<usize>().ok())
            })
    };
    let before = threads();
    let t0 = Instant::now();
    let opts = DiagnoseOptions {
        masses: 2,
        force_nonlinear: true,
        budget: FitBudget::with_cap_s(CAP_S),
        ..DiagnoseOptions::default()
    };
    let d = diagnose(&recs, &opts).expect("a diagnosis");
    let took = t0.elapsed().as_secs_f64();
    eprintln!(
        "library call capped at {CAP_S} s: returned after {took:.2} s, not tried: {:?}",
        d.time_cap.not_tried
    );
    assert!(d.time_cap.capped && !d.time_cap.not_tried.is_empty());
    assert!(took <= CAP_S + MARGIN_S, "{took:.2} s");
    // the other test of this binary started on its own thread before (the harness starts
    // both at once) and starts no thread of its own, only child processes
    if let (Some(b), Some(a)) = (before, threads()) {
        assert!(
            a <= b,
            "threads before {b}, after {a}: one was left running"
        );
    }
}
