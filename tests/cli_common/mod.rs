//! Running the real `flexid` binary from a test (`mod cli_common;` in the test file):
//! the command, and its exit code checked with the whole output shown on failure.

#![allow(dead_code)] // each test binary uses a part

use std::path::Path;
use std::process::{Command, Output};

/// Runs `flexid ARGS` in `dir` and waits for it.
pub fn flexid(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_flexid"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run flexid")
}

/// The bytes as text (lossy).
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Asserts the exit code `code` and that nothing panicked, showing stdout and stderr on
/// failure; returns (stdout, stderr).
pub fn expect_code(out: &Output, code: i32, what: &str) -> (String, String) {
    let (so, se) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(
        out.status.code(),
        Some(code),
        "{what}: exit status {:?}\n--- stdout\n{so}\n--- stderr\n{se}",
        out.status
    );
    assert!(!se.contains("panicked"), "{what}: panic\n{se}");
    (so, se)
}

/// [`expect_code`] with exit code 0.
pub fn expect_ok(out: &Output, what: &str) -> (String, String) {
    expect_code(out, 0, what)
}
