//! Bad input, tried as an unfriendly user would (issue 16): recordings, sidecars, plant
//! files, the daemon's configuration, API requests and output targets. Each kind of bad
//! input must get a clear error naming what is wrong, the documented exit status (2 for a
//! bad argument or input file, 1 when the analysis fails) or HTTP status, no panic, no
//! unbounded memory, and must leave what is on disk as it was.
//!
//! * [`cases`]: the harness (the real `flexid` binary, a timeout, the input files' bytes
//!   compared before and after, the children's peak memory);
//! * [`recordings`]: `REC.csv` and `REC.json`, and the commands reading them;
//! * [`plants`], [`config`]: plant files (`flexid simulate --plant`) and the daemon's
//!   configuration (`flexid daemon --config`);
//! * [`api`]: request bodies, queries, methods, headers of the HTTP API (in-process daemon);
//! * [`targets`]: output files that are devices, FIFOs or links out of their folder;
//! * [`props`]: property tests (proptest) over the recording reader, the sidecar parser,
//!   the plant file, the configuration and every API request body, with a bounded number
//!   of cases, and all of them for `FLEXID_FUZZ_SECONDS` (CI: 70 s); inputs that once
//!   failed are kept in `tests/bad_input/props.proptest-regressions`.
//!
//! Each child's peak memory on bad inputs of 1, 8 and 32 MB against a small multiple of the
//! input is `tests/memory_bound.rs` (a test binary of its own: a child's peak as the kernel
//! counts it includes its parent's at the spawn, so the parent must stay small).
//!
//! `FLEXID_BIN_UNDER_TEST=/path/to/flexid` runs the command-line cases against another
//! build (how the cases were seen to fail before their fixes).

#[path = "daemon_common/mod.rs"]
mod daemon_common;

#[path = "bad_input/api.rs"]
mod api;
#[path = "bad_input/cases.rs"]
mod cases;
#[path = "bad_input/config.rs"]
mod config;
#[path = "bad_input/plants.rs"]
mod plants;
#[path = "bad_input/props.rs"]
mod props;
#[path = "bad_input/recordings.rs"]
mod recordings;
#[path = "bad_input/targets.rs"]
mod targets;

/// The "done when": at least 50 kinds of bad input.
#[test]
fn at_least_fifty_kinds_of_bad_input() {
    let kinds = recordings::KINDS
        + plants::KINDS
        + plants::EXCITATION_KINDS
        + config::KINDS
        + api::KINDS
        + targets::KINDS;
    assert!(kinds >= 50, "{kinds} kinds of bad input");
    eprintln!(
        "bad input kinds: recordings {}, plants {}, configuration {}, API {}, targets {}: {kinds}",
        recordings::KINDS,
        plants::KINDS,
        config::KINDS,
        api::KINDS,
        targets::KINDS
    );
}
