//! Output targets that are not regular files (item 5): `flexid excite --out`,
//! `flexid simulate --out` and `flexid identify --json` into a FIFO, a folder, a link out
//! of the output folder and a link to a device. Each is refused with exit 2 and left as it
//! was; what a link points to is not touched. The real devices are only ever reached
//! through a link in a temporary folder (a regression then replaces the link, never
//! `/dev/full` itself).

use super::cases::run_flexid;
use std::os::unix::fs::FileTypeExt;
use std::path::Path;

pub const KINDS: usize = 6;

fn mkfifo(p: &Path) {
    let ok = std::process::Command::new("mkfifo")
        .arg(p)
        .status()
        .unwrap()
        .success();
    assert!(ok, "mkfifo {}", p.display());
}

fn args(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// `flexid excite multisine --out OUT` in `dir`: (exit code, stderr).
fn excite_into(dir: &Path, out: &str) -> (Option<i32>, String) {
    let (code, _, err) = run_flexid(
        dir,
        &args(&[
            "excite",
            "multisine",
            "--fs",
            "2000",
            "--period-samples",
            "400",
            "--band",
            "5",
            "200",
            "--periods",
            "2",
            "--out",
            out,
        ]),
    );
    (code, err)
}

#[test]
fn outputs_that_are_no_regular_files_are_refused_and_kept() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let outside = tempfile::tempdir().unwrap();
    let precious = outside.path().join("precious.csv");
    std::fs::write(&precious, b"keep me").unwrap();
    let mut failed = Vec::new();
    let mut check = |name: &str, (code, err): (Option<i32>, String), says: &str| {
        if code != Some(2) || !err.contains(says) || err.contains("panicked") {
            failed.push(format!("{name}: exit {code:?}, stderr {}", err.trim()));
        }
    };

    // 1. a FIFO as the excitation file
    mkfifo(&d.join("fifo.csv"));
    check("a FIFO", excite_into(d, "fifo.csv"), "FIFO");
    assert!(std::fs::symlink_metadata(d.join("fifo.csv"))
        .unwrap()
        .file_type()
        .is_fifo());

    // 2. a folder
    std::fs::create_dir(d.join("folder.csv")).unwrap();
    check("a folder", excite_into(d, "folder.csv"), "directory");
    assert!(d.join("folder.csv").is_dir());

    // 3. a link to a file outside the output folder
    std::os::unix::fs::symlink(&precious, d.join("link.csv")).unwrap();
    check(
        "a link out of the folder",
        excite_into(d, "link.csv"),
        "outside",
    );
    assert_eq!(std::fs::read(&precious).unwrap(), b"keep me");
    assert!(std::fs::symlink_metadata(d.join("link.csv"))
        .unwrap()
        .file_type()
        .is_symlink());

    // 4. a link to a device
    std::os::unix::fs::symlink("/dev/full", d.join("full.csv")).unwrap();
    check("a link to /dev/full", excite_into(d, "full.csv"), "outside");
    assert!(std::fs::symlink_metadata(d.join("full.csv"))
        .unwrap()
        .file_type()
        .is_symlink());

    // 5. the sidecar beside a good CSV name is a FIFO: nothing is written, not even the CSV
    mkfifo(&d.join("side.json"));
    check("a FIFO as the sidecar", excite_into(d, "side.csv"), "FIFO");
    assert!(
        !d.join("side.csv").exists(),
        "the CSV was written beside a refused sidecar"
    );

    // 6. identify --json into a FIFO
    assert_eq!(excite_into(d, "E.csv").0, Some(0));
    let (code, _, err) = run_flexid(
        d,
        &args(&["simulate", "--excitation", "E.csv", "--out", "R.csv"]),
    );
    assert_eq!(code, Some(0), "{err}");
    mkfifo(&d.join("result.json"));
    let (code, _, err) = run_flexid(
        d,
        &args(&[
            "identify",
            "R.csv",
            "--masses",
            "1",
            "--json",
            "result.json",
        ]),
    );
    check("identify --json into a FIFO", (code, err), "FIFO");
    assert!(std::fs::symlink_metadata(d.join("result.json"))
        .unwrap()
        .file_type()
        .is_fifo());

    assert!(failed.is_empty(), "{}", failed.join("\n"));
}
