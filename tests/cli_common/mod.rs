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

/// What [`flexid_measured`] saw of one run of the binary.
#[derive(Debug)]
pub struct Measured {
    /// The exit code (`None`: killed at the timeout or ended by a signal).
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    /// Wall time from the spawn to the end [s].
    pub wall_s: f64,
    /// User plus system CPU time of the child [s] (all its threads).
    pub cpu_s: f64,
    /// The child's own peak resident memory [bytes] (`ru_maxrss` of `wait4`).
    pub peak_rss_bytes: u64,
}

/// Runs `bin ARGS` in `dir` (standard input empty, the output into files) and reaps it with
/// `wait4`, which gives that child's own resource usage (not the largest of all children,
/// as `getrusage(RUSAGE_CHILDREN)` would); killed after `timeout`.
pub fn run_measured(
    bin: &Path,
    args: &[&str],
    dir: &Path,
    timeout: std::time::Duration,
) -> Measured {
    use std::process::Stdio;
    let out_dir = tempfile::tempdir().expect("temp dir");
    let (so, se) = (out_dir.path().join("stdout"), out_dir.path().join("stderr"));
    let t0 = std::time::Instant::now();
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&so).expect("stdout file"))
        .stderr(std::fs::File::create(&se).expect("stderr file"))
        .spawn()
        .expect("run the binary");
    let pid = child.id() as libc::pid_t;
    let mut status: libc::c_int = 0;
    // SAFETY: a zeroed rusage is a valid value of the plain C struct.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    let mut killed = false;
    loop {
        // SAFETY: valid pointers to locals; `pid` is our own unreaped child.
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut ru) };
        if r == pid {
            break;
        }
        assert!(r == 0, "wait4: {}", std::io::Error::last_os_error());
        if !killed && t0.elapsed() > timeout {
            let _ = child.kill();
            killed = true;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let wall_s = t0.elapsed().as_secs_f64();
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let code = (!killed && libc::WIFEXITED(status)).then(|| libc::WEXITSTATUS(status));
    Measured {
        code,
        stdout: std::fs::read_to_string(&so).unwrap_or_default(),
        stderr: std::fs::read_to_string(&se).unwrap_or_default(),
        wall_s,
        cpu_s: tv(ru.ru_utime) + tv(ru.ru_stime),
        peak_rss_bytes: ru.ru_maxrss as u64 * 1024,
    }
}

/// A multisine record `out` (with its sidecar) of the SCARA shoulder with every unmodelled
/// effect (`plants/scara_all_effects.toml`: friction, backlash, hardening, gravity, delay,
/// current loop, an extra mode, torque noise): 2 kHz, 0.5 Hz lines to 800 Hz, `peak_nm`
/// peak, 1 + `periods` periods. Its excitation is written as `E-{out}`.
pub fn all_effects_record(dir: &Path, peak_nm: &str, periods: &str, out: &str) {
    let plant = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/scara_all_effects.toml");
    let exc_file = format!("E-{out}");
    let exc = [
        "excite",
        "multisine",
        "--fs",
        "2000",
        "--period-samples",
        "4000",
        "--band",
        "0.5",
        "800",
        "--amplitude-exponent",
        "1",
        "--peak-nm",
        peak_nm,
        "--periods",
        periods,
        "--transient-periods",
        "1",
        "--out",
        exc_file.as_str(),
    ];
    expect_ok(&flexid(&exc, dir), "excite");
    let sim = [
        "simulate",
        "--plant",
        plant.to_str().expect("utf-8 path"),
        "--excitation",
        exc_file.as_str(),
        "--out",
        out,
    ];
    expect_ok(&flexid(&sim, dir), "simulate");
}
