//! The results store: `data_dir/<axis>/<sweep-id>/` holds
//!
//! | file | written |
//! |---|---|
//! | `running` | at the start (the status as JSON); removed when the sweep ends: a marker left behind means the daemon died during the sweep |
//! | `request.json` | at the start |
//! | `recording.json` | the sidecar: at the start, again at the end (with `ended_because`) |
//! | `recording.csv` | appended after every period and fsynced (the columns of `flexid sweep`: `time_s,torque_cmd_nm,position_rad,velocity_rad_s,torque_actual_nm`): a crash loses at most the last period |
//! | `frf.csv` | after every period: `freq_hz,magnitude_db,phase_deg,coherence,std` |
//! | `status.json` | at the end: outcome, reason, times |
//! | `result.json` | at the end: the analysis as `flexid identify --json` writes it |
//! | `bode.svg` | at the end |
//! | `diagnosis.json` | two-level sweeps, at the end: the gap diagnosis (or `{"error"}`) |
//! | `level1/`, `level2/` | two-level sweeps: each level's own `running`, `recording.*`, `frf.csv`, `status.json`, `result.json`, `bode.svg`; the top-level `recording.csv`, `frf.csv`, `bode.svg` are copied from the last level measured |
//!
//! Every file except `recording.csv` is replaced atomically (temporary file, fsync,
//! rename, fsync of the directory).

use super::backend::{Outcome, SampleBlock};
use super::request::SweepRequest;
use flexid_core::frf::Frf;
use flexid_files::recording::{write_bytes_atomic, Sidecar};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Errors of the results store (the path names the file).
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("{}: {message}", path.display())]
    Corrupt { path: PathBuf, message: String },
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The state of a sweep as stored and reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepState {
    Running,
    Completed,
    Aborted,
    Failed,
    Interrupted,
}

impl From<Outcome> for SweepState {
    fn from(o: Outcome) -> Self {
        match o {
            Outcome::Completed => SweepState::Completed,
            Outcome::Aborted => SweepState::Aborted,
            Outcome::Failed => SweepState::Failed,
            Outcome::Interrupted => SweepState::Interrupted,
        }
    }
}

/// `status.json` (and the `running` marker).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepStatus {
    pub id: String,
    pub axis: String,
    pub state: SweepState,
    /// Why it ended (`"completed"`, `"operator abort"`, ...); `None` while running.
    pub reason: Option<String>,
    /// Start and end, seconds since the Unix epoch.
    pub started_unix_s: f64,
    pub ended_unix_s: Option<f64>,
    /// Completed periods (transient included) and samples on disk.
    pub periods_done: usize,
    pub samples: usize,
    /// The validated request.
    pub request: SweepRequest,
    /// Whether `result.json` holds an identified model.
    #[serde(default)]
    pub has_result: bool,
    /// Two-level sweeps: the level (1 = low, 2 = high) measured now or last.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<usize>,
    /// Two-level sweeps: whether `diagnosis.json` holds a diagnosis.
    #[serde(default)]
    pub has_diagnosis: bool,
}

/// Seconds since the Unix epoch.
pub fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// A new sweep id: UTC time and a random suffix, `20261122T201810Z-3fa2c1`.
pub fn new_sweep_id() -> String {
    let secs = unix_now() as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // civil-from-days (H. Hinnant)
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    let r: u32 = rand::random::<u32>() & 0xff_ffff;
    format!(
        "{y:04}{m:02}{d:02}T{:02}{:02}{:02}Z-{r:06x}",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// Is `id` a well-formed sweep id (safe as a path component)?
pub fn valid_sweep_id(id: &str) -> bool {
    !id.is_empty()
        && id.len() <= 64
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

/// The whole excitation periods (transient included) in the first `samples` rows of a
/// recording described by `sidecar`; `None` when its excitation is not periodic.
pub fn whole_periods(samples: usize, sidecar: &Sidecar) -> Option<usize> {
    let n = sidecar.excitation.as_ref()?.period_samples;
    (n > 0).then(|| samples / n)
}

/// The store under `data_dir`.
#[derive(Debug, Clone)]
pub struct Store {
    root: PathBuf,
}

/// The header of `recording.csv`: the columns `flexid sweep` writes.
pub const RECORDING_HEADER: &str =
    "time_s,torque_cmd_nm,position_rad,velocity_rad_s,torque_actual_nm\n";

/// Files of one sweep directory.
pub const RUNNING: &str = "running";
pub const STATUS: &str = "status.json";
pub const REQUEST: &str = "request.json";
pub const RECORDING_CSV: &str = "recording.csv";
pub const RECORDING_JSON: &str = "recording.json";
pub const FRF_CSV: &str = "frf.csv";
pub const RESULT_JSON: &str = "result.json";
pub const BODE_SVG: &str = "bode.svg";
pub const DIAGNOSIS_JSON: &str = "diagnosis.json";

/// The sub-directory of level `n` (1-based) of a two-level sweep.
pub fn level_dir_name(n: usize) -> String {
    format!("level{n}")
}

impl Store {
    /// Open (create) the store at `root`.
    pub fn open(root: &Path) -> Result<Store, StoreError> {
        fs::create_dir_all(root).map_err(io_err(root))?;
        Ok(Store { root: root.into() })
    }

    /// Directory of a sweep.
    pub fn dir(&self, axis: &str, id: &str) -> PathBuf {
        self.root.join(axis).join(id)
    }

    /// Every stored sweep: id -> status (the marker's content for interrupted ones that
    /// [`recover`](Self::recover) has not seen yet). Unreadable entries are skipped with a
    /// warning.
    pub fn scan(&self) -> HashMap<String, SweepStatus> {
        let mut out = HashMap::new();
        let Ok(axes) = fs::read_dir(&self.root) else {
            return out;
        };
        for axis in axes.flatten() {
            let Ok(sweeps) = fs::read_dir(axis.path()) else {
                continue;
            };
            for s in sweeps.flatten() {
                let dir = s.path();
                for f in [STATUS, RUNNING] {
                    let p = dir.join(f);
                    if p.exists() {
                        match read_status(&p) {
                            Ok(st) => {
                                out.insert(st.id.clone(), st);
                            }
                            Err(e) => tracing::warn!("skipping {}: {e}", dir.display()),
                        }
                        break;
                    }
                }
            }
        }
        out
    }

    /// Find sweeps that were running when the daemon died (their `running` marker is still
    /// there) and close them as [`SweepState::Interrupted`]: the recording is cut after
    /// its last complete line, the sidecar says why it ended, `status.json` is written
    /// and the marker removed. Returns the recovered statuses.
    pub fn recover(&self) -> Vec<SweepStatus> {
        let mut out = Vec::new();
        let Ok(axes) = fs::read_dir(&self.root) else {
            return out;
        };
        for axis in axes.flatten() {
            let Ok(sweeps) = fs::read_dir(axis.path()) else {
                continue;
            };
            for s in sweeps.flatten() {
                let marker = s.path().join(RUNNING);
                if !marker.exists() {
                    continue;
                }
                match self.recover_one(&s.path()) {
                    Ok(st) => out.push(st),
                    Err(e) => tracing::error!("recovering {}: {e}", s.path().display()),
                }
                // the levels of a two-level sweep
                for n in 1..=2 {
                    let d = s.path().join(level_dir_name(n));
                    if d.join(RUNNING).exists() {
                        if let Err(e) = self.recover_one(&d) {
                            tracing::error!("recovering {}: {e}", d.display());
                        }
                    }
                }
            }
        }
        out
    }

    fn recover_one(&self, dir: &Path) -> Result<SweepStatus, StoreError> {
        let mut st = read_status(&dir.join(RUNNING))?;
        let csv = dir.join(RECORDING_CSV);
        let samples = truncate_to_last_line(&csv)?;
        let side = dir.join(RECORDING_JSON);
        if let Ok(text) = fs::read_to_string(&side) {
            if let Ok(mut sc) = serde_json::from_str::<Sidecar>(&text) {
                sc.ended_because = Some("interrupted: the daemon stopped during the sweep".into());
                write_json(&side, &sc)?;
                // the marker holds the status of the start: count what is on disk
                if let Some(p) = whole_periods(samples, &sc) {
                    st.periods_done = p;
                }
            }
        }
        st.state = SweepState::Interrupted;
        st.reason = Some("the daemon stopped during the sweep".into());
        st.samples = samples;
        st.ended_unix_s = Some(unix_now());
        write_json(&dir.join(STATUS), &st)?;
        fs::remove_file(dir.join(RUNNING)).map_err(io_err(&dir.join(RUNNING)))?;
        tracing::warn!(
            "sweep {} on axis {} was interrupted; {} samples saved",
            st.id,
            st.axis,
            samples
        );
        Ok(st)
    }

    /// Begin a sweep: create its directory, write the marker, the request and the sidecar,
    /// and open the recording for appending.
    pub fn begin(&self, status: &SweepStatus, sidecar: &Sidecar) -> Result<SweepFiles, StoreError> {
        self.begin_in(self.dir(&status.axis, &status.id), status, sidecar)
    }

    /// [`begin`](Self::begin) in another directory (the levels of a two-level sweep).
    pub fn begin_in(
        &self,
        dir: PathBuf,
        status: &SweepStatus,
        sidecar: &Sidecar,
    ) -> Result<SweepFiles, StoreError> {
        fs::create_dir_all(&dir).map_err(io_err(&dir))?;
        write_json(&dir.join(RUNNING), status)?;
        write_json(&dir.join(REQUEST), &status.request)?;
        write_json(&dir.join(RECORDING_JSON), sidecar)?;
        let csv_path = dir.join(RECORDING_CSV);
        let mut csv = OpenOptions::new()
            .create(true)
            .truncate(true)
            .write(true)
            .open(&csv_path)
            .map_err(io_err(&csv_path))?;
        csv.write_all(RECORDING_HEADER.as_bytes())
            .and_then(|_| csv.sync_all())
            .map_err(io_err(&csv_path))?;
        sync_dir(&dir)?;
        Ok(SweepFiles { dir, csv })
    }
}

/// The open files of a running sweep.
#[derive(Debug)]
pub struct SweepFiles {
    dir: PathBuf,
    csv: File,
}

impl SweepFiles {
    /// The sweep's directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Append one period's samples to `recording.csv` and fsync (round-trip precision).
    /// A block whose columns differ in length is refused (nothing written).
    pub fn append(&mut self, block: &SampleBlock, sample_rate_hz: f64) -> Result<(), StoreError> {
        use std::fmt::Write as _;
        let path = self.dir.join(RECORDING_CSV);
        let n = block.torque_cmd_nm.len();
        let lens = [
            block.position_rad.len(),
            block.velocity_rad_s.len(),
            block.torque_actual_nm.len(),
        ];
        if lens.iter().any(|&l| l != n) {
            return Err(StoreError::Corrupt {
                path,
                message: format!(
                    "a block of {n} set-points with {lens:?} positions, velocities, torques"
                ),
            });
        }
        let mut s = String::with_capacity(n * 120);
        for i in 0..n {
            let t = (block.first_sample + i) as f64 / sample_rate_hz;
            let (u, p) = (block.torque_cmd_nm[i], block.position_rad[i]);
            let (v, a) = (block.velocity_rad_s[i], block.torque_actual_nm[i]);
            let _ = writeln!(s, "{t:e},{u:e},{p:e},{v:e},{a:e}");
        }
        self.csv
            .write_all(s.as_bytes())
            .and_then(|_| self.csv.sync_data())
            .map_err(io_err(&path))
    }

    /// Replace `frf.csv` with `frf`.
    pub fn write_frf(&self, frf: &Frf) -> Result<(), StoreError> {
        let p = self.dir.join(FRF_CSV);
        write_bytes_atomic(&p, frf_csv(frf).as_bytes()).map_err(io_err(&p))
    }

    /// Replace any file of the sweep directory atomically.
    pub fn write_file(&self, name: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let p = self.dir.join(name);
        write_bytes_atomic(&p, bytes).map_err(io_err(&p))
    }

    /// Close the sweep: write the final sidecar and `status.json`, then remove the marker.
    pub fn finish(self, status: &SweepStatus, sidecar: &Sidecar) -> Result<(), StoreError> {
        let csv_path = self.dir.join(RECORDING_CSV);
        self.csv.sync_all().map_err(io_err(&csv_path))?;
        write_json(&self.dir.join(RECORDING_JSON), sidecar)?;
        write_json(&self.dir.join(STATUS), status)?;
        let m = self.dir.join(RUNNING);
        fs::remove_file(&m).map_err(io_err(&m))?;
        sync_dir(&self.dir)
    }
}

/// `frf.csv`: `freq_hz,magnitude_db,phase_deg,coherence,std` with `std` the one-sigma
/// standard deviation of `|H|` in the FRF's units (empty coherence when not estimated).
pub fn frf_csv(frf: &Frf) -> String {
    use std::fmt::Write as _;
    let mag = frf.magnitude_db();
    let ph = frf.phase_deg_unwrapped();
    let mut s = String::from("freq_hz,magnitude_db,phase_deg,coherence,std\n");
    for i in 0..frf.len() {
        let coh = frf
            .coherence
            .as_ref()
            .and_then(|c| c.get(i))
            .map_or(String::new(), |c| format!("{c:e}"));
        let _ = writeln!(
            s,
            "{:e},{:e},{:e},{coh},{:e}",
            frf.freq_hz[i],
            mag[i],
            ph[i],
            frf.var[i].sqrt()
        );
    }
    s
}

fn read_status(p: &Path) -> Result<SweepStatus, StoreError> {
    let text = fs::read_to_string(p).map_err(io_err(p))?;
    serde_json::from_str(&text).map_err(|e| StoreError::Corrupt {
        path: p.into(),
        message: e.to_string(),
    })
}

/// Write `v` as pretty JSON atomically.
pub fn write_json<T: Serialize>(p: &Path, v: &T) -> Result<(), StoreError> {
    let mut text = serde_json::to_string_pretty(v).map_err(|e| StoreError::Corrupt {
        path: p.into(),
        message: e.to_string(),
    })?;
    text.push('\n');
    write_bytes_atomic(p, text.as_bytes()).map_err(io_err(p))
}

/// Cut a CSV after its last newline; returns the number of data rows kept.
fn truncate_to_last_line(p: &Path) -> Result<usize, StoreError> {
    let bytes = match fs::read(p) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io_err(p)(e)),
    };
    let keep = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    if keep < bytes.len() {
        let f = OpenOptions::new().write(true).open(p).map_err(io_err(p))?;
        f.set_len(keep as u64)
            .and_then(|_| f.sync_all())
            .map_err(io_err(p))?;
    }
    let lines = bytes[..keep].iter().filter(|&&b| b == b'\n').count();
    Ok(lines.saturating_sub(1))
}

fn sync_dir(dir: &Path) -> Result<(), StoreError> {
    File::open(dir)
        .and_then(|f| f.sync_all())
        .map_err(io_err(dir))
}

/// A running multisine sweep on axis `a1` with `periods` periods, nothing done yet (tests).
#[cfg(test)]
pub(crate) fn running_status(id: &str, periods: usize) -> SweepStatus {
    let request: SweepRequest = serde_json::from_str(&format!(
        r#"{{"excitation":"multisine","band_hz":[2,300],"amplitude_nm":0.5,"periods":{periods},"duration_s":5}}"#
    ))
    .unwrap();
    SweepStatus {
        id: id.into(),
        axis: "a1".into(),
        state: SweepState::Running,
        reason: None,
        started_unix_s: 0.0,
        ended_unix_s: None,
        periods_done: 0,
        samples: 0,
        request,
        has_result: false,
        level: None,
        has_diagnosis: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_safe_and_dated() {
        let id = new_sweep_id();
        assert!(valid_sweep_id(&id), "{id}");
        assert_eq!(id.len(), "20261122T201810Z-3fa2c1".len(), "{id}");
        assert!(!valid_sweep_id("../etc"));
    }

    /// Issue 16, item 2: a sweep the daemon did not live to finish is recovered with the
    /// whole periods on disk counted, not the 0 of the marker written at its start.
    #[test]
    fn a_recovered_sweep_counts_the_whole_periods_on_disk() {
        let d = tempfile::tempdir().unwrap();
        let store = Store::open(d.path()).unwrap();
        let status = running_status("20261126T180000Z-000001", 4);
        let sidecar: Sidecar = serde_json::from_str(
            r#"{"sample_rate_hz": 100.0, "excitation": {"kind": "multisine", "period_samples": 10,
                "periods": 4, "transient_periods": 1, "excited_lines": [1, 2]}}"#,
        )
        .unwrap();
        let mut files = store.begin(&status, &sidecar).unwrap();
        for first in [0, 10, 20] {
            let block = SampleBlock {
                first_sample: first,
                torque_cmd_nm: vec![0.1; 10],
                position_rad: vec![0.2; 10],
                velocity_rad_s: vec![0.3; 10],
                torque_actual_nm: vec![0.4; 10],
            };
            files.append(&block, 100.0).unwrap();
        }
        drop(files); // the daemon dies: the marker stays
        let got = store.recover();
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].state, SweepState::Interrupted);
        assert_eq!(got[0].samples, 30);
        assert_eq!(got[0].periods_done, 3, "whole periods on disk");
        let on_disk = read_status(&store.dir("a1", &status.id).join(STATUS)).unwrap();
        assert_eq!(on_disk.periods_done, 3);
    }

    /// Issue 16, item 3: the daemon's `recording.csv` has the columns `flexid sweep` writes
    /// (the sweep loop's rows: set-point, position, velocity, torque actual).
    #[test]
    fn the_recording_has_the_columns_of_the_command_line() {
        use flexid_sweep::{RecordedRows, Row, RowSink};
        let mut rows = RecordedRows::with_capacity(1);
        rows.push(
            0,
            &Row {
                torque_setpoint_nm: 0.1,
                position_rad: 0.2,
                velocity_rad_s: 0.3,
                torque_actual_nm: 0.4,
            },
        );
        let cli = rows.into_recording(100.0, Sidecar::default());
        let mut text = Vec::new();
        flexid_core::recording::write_csv(&mut text, &cli).unwrap();
        let text = String::from_utf8(text).unwrap();
        let cli_header = text.lines().find(|l| !l.starts_with('#')).unwrap();

        let d = tempfile::tempdir().unwrap();
        let store = Store::open(d.path()).unwrap();
        let status = running_status("20261126T180000Z-000002", 4);
        let mut files = store.begin(&status, &Sidecar::default()).unwrap();
        let block = SampleBlock {
            first_sample: 0,
            torque_cmd_nm: vec![0.1; 3],
            position_rad: vec![0.2; 3],
            velocity_rad_s: vec![0.3; 3],
            torque_actual_nm: vec![0.4; 3],
        };
        files.append(&block, 100.0).unwrap();
        let daemon = fs::read_to_string(files.dir().join(RECORDING_CSV)).unwrap();
        assert_eq!(daemon.lines().next().unwrap(), cli_header);
        assert!(daemon.lines().skip(1).all(|l| l.split(',').count() == 5));
        let rec = flexid_files::recording::read_recording(files.dir().join(RECORDING_CSV)).unwrap();
        assert_eq!(rec.velocity_rad_s, Some(vec![0.3; 3]));
        assert_eq!(rec.torque_actual_nm, Some(vec![0.4; 3]));
        // a block short of a column is refused, not written half
        let short = SampleBlock {
            velocity_rad_s: Vec::new(),
            ..block
        };
        assert!(files.append(&short, 100.0).is_err());
    }

    #[test]
    fn truncates_a_torn_line() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("r.csv");
        fs::write(&p, "a,b\n1,2\n3,4\n5,").unwrap();
        assert_eq!(truncate_to_last_line(&p).unwrap(), 2);
        assert_eq!(fs::read_to_string(&p).unwrap(), "a,b\n1,2\n3,4\n");
    }
}
