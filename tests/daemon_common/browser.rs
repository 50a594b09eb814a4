//! The daemon's web page in a real headless browser: Debian's chromium driven by
//! playwright-core from the scripts in `tests/browser/` (their shared part is
//! `tests/browser/harness.mjs`). Each script prints one `browser: ...` line per observation,
//! `browser: result NAME=value ...` with what the page showed, and `browser: ok` at the end.

use super::TOKEN;
use std::path::{Path, PathBuf};
use std::process::Command;

pub fn browser_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser")
}

/// Why the browser test cannot run here, if it cannot.
pub fn missing_tools() -> Option<String> {
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        return Some(format!(
            "{chromium} is absent (apt-get install -y chromium)"
        ));
    }
    if Command::new("node").arg("--version").output().is_err() {
        return Some("node is absent (apt-get install -y nodejs npm)".into());
    }
    if !browser_dir()
        .join("node_modules/playwright-core/package.json")
        .exists()
    {
        return Some("tests/browser/node_modules is absent (npm ci in tests/browser)".into());
    }
    None
}

/// Whether the browser test can run: `false` (with a message) when a tool is missing, a
/// panic instead under `CI=true`, where the tools are installed by scripts/test.sh.
pub fn browser_available() -> bool {
    match missing_tools() {
        None => true,
        Some(why) if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("browser test needs: {why}")
        }
        Some(why) => {
            eprintln!("skipped: browser test: {why}");
            false
        }
    }
}

/// What a script run left: its standard output and the path of its first screenshot.
pub struct ScriptRun {
    pub stdout: String,
    pub screenshot: PathBuf,
}

/// Runs `tests/browser/SCRIPT` against the daemon at `url` (`extra_env` beside the URL, the
/// token and the screenshot path `target/browser/SHOT`) and asserts that it passed and left
/// a PNG screenshot.
pub async fn run_script(
    script: &str,
    url: &str,
    shot: &str,
    extra_env: &[(&str, &str)],
) -> ScriptRun {
    let shots = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/browser");
    std::fs::create_dir_all(&shots).unwrap();
    let screenshot = shots.join(shot);
    let _ = std::fs::remove_file(&screenshot);
    let mut cmd = Command::new("node");
    cmd.arg(script)
        .current_dir(browser_dir())
        .env("FLEXID_URL", url)
        .env("FLEXID_TOKEN", TOKEN)
        .env("FLEXID_SCREENSHOT", &screenshot);
    for (k, v) in extra_env {
        cmd.env(k, v);
    }
    let out = tokio::task::spawn_blocking(move || cmd.output())
        .await
        .unwrap()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    eprintln!("{stderr}");
    assert!(
        out.status.success(),
        "the browser script {script} failed:\n{stderr}"
    );
    assert!(stdout.contains("browser: ok"), "{stdout}");
    let png = std::fs::read(&screenshot).expect("screenshot written");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{}: {} bytes",
        screenshot.display(),
        png.len()
    );
    println!("screenshot: {}", screenshot.display());
    ScriptRun { stdout, screenshot }
}

/// A `NAME=value` number from the script's `browser: result ...` line.
pub fn result_value(out: &str, name: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with("browser: result "))
        .unwrap_or_else(|| panic!("no result line in:\n{out}"));
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(&format!("{name}=")))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {name} in {line}"))
}
