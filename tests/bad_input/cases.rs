//! The harness: one bad input is a [`Case`]: files written into a fresh folder, a
//! `flexid` command line run there, the exit status and the words its error must hold.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Longest a command may take on bad input.
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// One kind of bad input for the command line.
pub struct Case {
    /// What is wrong, in a few words.
    pub name: String,
    /// Files to write (name, bytes) before the run.
    pub files: Vec<(String, Vec<u8>)>,
    /// The arguments after `flexid`.
    pub args: Vec<String>,
    /// The exit status the contract promises.
    pub code: i32,
    /// Words the error message must hold (what is wrong, where).
    pub says: Vec<String>,
}

impl Case {
    pub fn new(name: impl Into<String>, args: &[&str], code: i32, says: &[&str]) -> Case {
        Case {
            name: name.into(),
            files: Vec::new(),
            args: args.iter().map(|s| s.to_string()).collect(),
            code,
            says: says.iter().map(|s| s.to_string()).collect(),
        }
    }

    pub fn file(mut self, name: &str, bytes: impl Into<Vec<u8>>) -> Case {
        self.files.push((name.to_string(), bytes.into()));
        self
    }
}

/// The binary under test: `flexid` of this build, or `FLEXID_BIN_UNDER_TEST`.
pub fn flexid_bin() -> PathBuf {
    std::env::var_os("FLEXID_BIN_UNDER_TEST")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_flexid")))
}

/// Run `flexid args` in `dir` with [`TIMEOUT`]: (exit code, stdout, stderr); `None` as
/// the code when killed at the timeout or ended by a signal.
pub fn run_flexid(dir: &Path, args: &[String]) -> (Option<i32>, String, String) {
    let mut child = Command::new(flexid_bin())
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run flexid");
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break Some(s);
        }
        if t0.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let out = child.wait_with_output().expect("output");
    (
        status.and_then(|s| s.code()),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Every file of `dir` (not recursing into folders) and its bytes; FIFOs and other
/// special files by their type only.
pub fn snapshot(dir: &Path) -> Vec<(String, Option<Vec<u8>>)> {
    let mut v: Vec<(String, Option<Vec<u8>>)> = std::fs::read_dir(dir)
        .expect("read dir")
        .map(|e| {
            let e = e.expect("entry");
            let name = e.file_name().to_string_lossy().into_owned();
            let t = e.file_type().expect("type");
            let bytes = t.is_file().then(|| std::fs::read(e.path()).expect("read"));
            (name, bytes)
        })
        .collect();
    v.sort();
    v
}

/// Run every case, each in a fresh folder: the status, the words, no panic, no input file
/// changed or removed. Returns one line per failed case (empty when all held).
pub fn run_cases(cases: &[Case]) -> Vec<String> {
    let mut failed = Vec::new();
    for c in cases {
        let dir = tempfile::tempdir().expect("temp dir");
        for (name, bytes) in &c.files {
            std::fs::write(dir.path().join(name), bytes).expect("write input");
        }
        let before = snapshot(dir.path());
        let (code, out, err) = run_flexid(dir.path(), &c.args);
        let mut why = Vec::new();
        if code != Some(c.code) {
            why.push(format!("exit status {code:?}, want {}", c.code));
        }
        if err.contains("panicked") {
            why.push("panicked".to_string());
        }
        for w in &c.says {
            if !err.contains(w.as_str()) {
                why.push(format!("the message does not say {w:?}"));
            }
        }
        let after = snapshot(dir.path());
        for (name, bytes) in &before {
            match after.iter().find(|(n, _)| n == name) {
                Some((_, b)) if b == bytes => {}
                Some(_) => why.push(format!("{name} was changed")),
                None => why.push(format!("{name} was removed")),
            }
        }
        if !why.is_empty() {
            failed.push(format!(
                "{}: {}\n    flexid {}\n    stderr: {}\n    stdout: {}",
                c.name,
                why.join("; "),
                c.args.join(" "),
                err.trim().lines().last().unwrap_or(""),
                out.trim().lines().next().unwrap_or("")
            ));
        }
    }
    failed
}

/// Peak resident memory of the largest child so far [bytes].
pub fn children_peak_rss_bytes() -> u64 {
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: a valid pointer to a local rusage.
    unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut ru) };
    ru.ru_maxrss as u64 * 1024
}

/// Assert no failure, listing them all.
pub fn assert_all_held(what: &str, failed: &[String]) {
    assert!(
        failed.is_empty(),
        "{what}: {} case(s) failed:\n{}",
        failed.len(),
        failed.join("\n")
    );
}
