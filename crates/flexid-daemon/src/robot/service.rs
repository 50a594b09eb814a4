//! The daemon's robot: multi-axis sweeps at the poses of its flexibility file and the
//! identification of its flexibilities from them, as jobs (one at a time, on a thread of
//! their own), each with a directory under `data_dir/.robot/<name>/<job-id>/`.
//!
//! A sweep job moves the simulated robot to the pose (its drives are built there), brings
//! the drives up over the bus, runs the orthogonal multisines under the holding loop,
//! estimates the FRF matrix and writes `frf_matrix.json` and `bode_matrix.svg`. An
//! identification job reads the latest sweep of every identification pose (or the sweeps
//! named), fits the flexibilities from the file's values and writes
//! `identification.json` with the model's FRF matrix at each sweep's pose.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use flexid_canopen::MasterConfig;
use flexid_core::manipulator::measure::MeasureOptions;
use flexid_core::manipulator::{Flexibilities, FlexibleRobot, PoseRole};
use flexid_sweep::Pacing;
use flexid_vdrive::robot::RobotDriveOptions;
use flexid_vdrive::ClockMode;
use serde::{Deserialize, Serialize};

use super::files::{
    identify_files, write_json, write_pose_files, FrfMatrixFile, FRF_MATRIX_JSON,
    IDENTIFICATION_JSON, JOB_JSON,
};
use super::measure::{measure_pose, plan_pose};
use super::sim::SimulatedRobot;
use crate::config::{ClockKind, RobotConfig};
use crate::store::{new_sweep_id, unix_now, valid_sweep_id};

/// Errors of the robot's operations (each maps to an HTTP status in the API).
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The configuration's robot could not be loaded.
    #[error("robot.flex_file {path}: {detail}")]
    Load { path: String, detail: String },
    /// A request field is wrong.
    #[error("{field}: {reason}")]
    Request { field: &'static str, reason: String },
    /// Another job is running.
    #[error("the robot is busy with job {0}")]
    Busy(String),
    /// No such job.
    #[error("no robot job with id {0:?}")]
    UnknownJob(String),
    /// Files.
    #[error("{0}")]
    Io(String),
}

/// The state of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Running,
    Completed,
    Failed,
    Aborted,
}

/// What a job does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JobKind {
    Sweep,
    Identification,
}

/// A job as the API shows it (and `job.json` keeps it).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RobotJob {
    pub id: String,
    pub kind: JobKind,
    pub state: JobState,
    /// Sweep: the pose measured.
    pub pose: Option<String>,
    /// Identification: the sweeps used.
    pub sweeps: Vec<String>,
    /// Cycles done and planned; experiment running and how many (sweep).
    pub cycle: u64,
    pub cycles: u64,
    pub experiment: usize,
    pub experiments: usize,
    /// What happened, in words (the error when failed).
    pub message: String,
    pub started_unix_s: f64,
    pub elapsed_s: f64,
}

/// A sweep request: `{"pose": "id-1"}`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepRequest {
    pub pose: String,
}

/// An identification request: `{"sweeps": [...], "starts": 8}` (both optional).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentifyRequest {
    #[serde(default)]
    pub sweeps: Option<Vec<String>>,
    #[serde(default)]
    pub starts: Option<usize>,
}

/// Starts of an identification when the request names none.
pub const DEFAULT_STARTS: usize = 8;

/// The robot of the configuration and its jobs.
pub struct RobotService {
    pub cfg: RobotConfig,
    pub robot: FlexibleRobot,
    /// The simulated robot's springs (the file's values, each off by its seeded factor).
    simulated: Flexibilities,
    dir: PathBuf,
    jobs: Mutex<BTreeMap<String, RobotJob>>,
    running: Mutex<Option<String>>,
    abort: Arc<AtomicBool>,
    threads: Mutex<Vec<std::thread::JoinHandle<()>>>,
}

/// The robot of a flexibility file (the embedded reference arm without one).
pub fn load_robot(path: Option<&Path>) -> Result<FlexibleRobot, RobotError> {
    flexid_vdrive::robot::load_robot(path).map_err(|e| RobotError::Load {
        path: path.map_or_else(|| "embedded".into(), |p| p.display().to_string()),
        detail: e,
    })
}

impl RobotService {
    /// The robot of `cfg`, its jobs under `data_dir/.robot/<name>/` (earlier runs' jobs
    /// listed; one that was running when the daemon stopped is marked failed).
    pub fn new(cfg: RobotConfig, data_dir: &Path) -> Result<Arc<Self>, RobotError> {
        let robot = load_robot(cfg.flex_file.as_deref())?;
        let simulated = robot
            .nominal
            .deviated(cfg.simulated_deviation, cfg.simulated_seed);
        let dir = data_dir.join(".robot").join(&cfg.name);
        std::fs::create_dir_all(&dir)
            .map_err(|e| RobotError::Io(format!("{}: {e}", dir.display())))?;
        let mut jobs = BTreeMap::new();
        if let Ok(entries) = std::fs::read_dir(&dir) {
            for e in entries.flatten() {
                let p = e.path().join(JOB_JSON);
                let Some(mut job) = std::fs::read_to_string(&p)
                    .ok()
                    .and_then(|t| serde_json::from_str::<RobotJob>(&t).ok())
                else {
                    continue;
                };
                if job.state == JobState::Running {
                    job.state = JobState::Failed;
                    job.message = "interrupted: the daemon stopped during the job".into();
                    let _ = write_json(&p, &job);
                }
                jobs.insert(job.id.clone(), job);
            }
        }
        Ok(Arc::new(RobotService {
            cfg,
            robot,
            simulated,
            dir,
            jobs: Mutex::new(jobs),
            running: Mutex::new(None),
            abort: Arc::new(AtomicBool::new(false)),
            threads: Mutex::new(Vec::new()),
        }))
    }

    /// The simulated robot's springs (what an identification should find).
    pub fn simulated_springs(&self) -> &Flexibilities {
        &self.simulated
    }

    /// The robot as `GET /api/v1/robot` shows it.
    pub fn view(&self) -> serde_json::Value {
        let poses: Vec<_> = self
            .robot
            .poses
            .iter()
            .map(|p| {
                serde_json::json!({
                    "name": p.name,
                    "role": match p.role { PoseRole::Identification => "identification", PoseRole::Validation => "validation" },
                    "q_deg": p.q_deg,
                })
            })
            .collect();
        let nodes: Vec<u8> = (0..self.robot.axes())
            .map(|i| self.cfg.first_node + i as u8)
            .collect();
        let jobs: Vec<RobotJob> = self.lock_jobs().values().cloned().collect();
        serde_json::json!({
            "name": self.cfg.name,
            "model": self.robot.name,
            "axes": self.robot.axes(),
            "nodes": nodes,
            "cycle_hz": self.cfg.cycle_hz,
            "backend": "simulated",
            "poses": poses,
            "parameters": self.robot.parameter_names(),
            "running": self.running.lock().unwrap_or_else(|e| e.into_inner()).clone(),
            "jobs": jobs,
        })
    }

    fn lock_jobs(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, RobotJob>> {
        self.jobs.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A job.
    pub fn job(&self, id: &str) -> Result<RobotJob, RobotError> {
        self.lock_jobs()
            .get(id)
            .cloned()
            .ok_or_else(|| RobotError::UnknownJob(id.to_string()))
    }

    /// A job's directory (the job must exist).
    pub fn job_dir(&self, id: &str) -> Result<PathBuf, RobotError> {
        if !valid_sweep_id(id) {
            return Err(RobotError::UnknownJob(id.to_string()));
        }
        self.job(id)?;
        Ok(self.dir.join(id))
    }

    /// Asks the running job to stop (a sweep ramps its torques down).
    pub fn abort(&self, id: &str) -> Result<(), RobotError> {
        let job = self.job(id)?;
        if job.state != JobState::Running {
            return Err(RobotError::Request {
                field: "id",
                reason: format!("job {id} is not running"),
            });
        }
        self.abort.store(true, Ordering::Relaxed);
        Ok(())
    }

    /// Stops the running job and waits for its thread.
    pub fn shutdown(&self) {
        self.abort.store(true, Ordering::Relaxed);
        let threads: Vec<_> =
            std::mem::take(&mut *self.threads.lock().unwrap_or_else(|e| e.into_inner()));
        for t in threads {
            let _ = t.join();
        }
    }

    /// Reserves the robot for a new job of `kind`; its id.
    fn begin(
        &self,
        kind: JobKind,
        pose: Option<String>,
        sweeps: Vec<String>,
    ) -> Result<RobotJob, RobotError> {
        let mut running = self.running.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(id) = running.as_ref() {
            return Err(RobotError::Busy(id.clone()));
        }
        let job = RobotJob {
            id: new_sweep_id(),
            kind,
            state: JobState::Running,
            pose,
            sweeps,
            cycle: 0,
            cycles: 0,
            experiment: 0,
            experiments: 0,
            message: String::new(),
            started_unix_s: unix_now(),
            elapsed_s: 0.0,
        };
        let d = self.dir.join(&job.id);
        std::fs::create_dir_all(&d).map_err(|e| RobotError::Io(format!("{}: {e}", d.display())))?;
        write_json(&d.join(JOB_JSON), &job).map_err(RobotError::Io)?;
        *running = Some(job.id.clone());
        self.abort.store(false, Ordering::Relaxed);
        self.lock_jobs().insert(job.id.clone(), job.clone());
        Ok(job)
    }

    /// Updates job `id` with `f`.
    fn update(&self, id: &str, f: impl FnOnce(&mut RobotJob)) {
        if let Some(j) = self.lock_jobs().get_mut(id) {
            f(j);
        }
    }

    /// Ends job `id` in `state` with `message`; `job.json` written; the robot free.
    fn finish(&self, id: &str, state: JobState, message: String, t0: Instant) {
        let mut out = None;
        self.update(id, |j| {
            j.state = state;
            j.message = message;
            j.elapsed_s = t0.elapsed().as_secs_f64();
            out = Some(j.clone());
        });
        if let Some(j) = out {
            if let Err(e) = write_json(&self.dir.join(id).join(JOB_JSON), &j) {
                tracing::error!("robot job {id}: {e}");
            }
        }
        *self.running.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }

    fn spawn(
        self: &Arc<Self>,
        id: &str,
        work: impl FnOnce(&Arc<Self>, &str) + Send + 'static,
    ) -> Result<(), RobotError> {
        let me = Arc::clone(self);
        let id2 = id.to_string();
        let t = std::thread::Builder::new()
            .name(format!("robot-{id}"))
            .spawn(move || work(&me, &id2))
            .map_err(|e| {
                self.finish(id, JobState::Failed, format!("thread: {e}"), Instant::now());
                RobotError::Io(format!("thread: {e}"))
            })?;
        let mut threads = self.threads.lock().unwrap_or_else(|e| e.into_inner());
        threads.retain(|t| !t.is_finished());
        threads.push(t);
        Ok(())
    }

    /// Starts a multi-axis sweep at pose `req.pose` of the file; its job.
    pub fn start_sweep(self: &Arc<Self>, req: SweepRequest) -> Result<RobotJob, RobotError> {
        let Some(spec) = self
            .robot
            .poses
            .iter()
            .find(|p| p.name == req.pose)
            .cloned()
        else {
            let names: Vec<_> = self.robot.poses.iter().map(|p| p.name.as_str()).collect();
            return Err(RobotError::Request {
                field: "pose",
                reason: format!(
                    "no pose {:?} in the robot's file (it has {})",
                    req.pose,
                    names.join(", ")
                ),
            });
        };
        let job = self.begin(JobKind::Sweep, Some(spec.name.clone()), Vec::new())?;
        self.spawn(&job.id, move |me, id| {
            let t0 = Instant::now();
            match me.run_sweep(id, &spec.name, &spec.q_deg) {
                Ok(msg) => me.finish(id, JobState::Completed, msg, t0),
                Err((state, msg)) => me.finish(id, state, msg, t0),
            }
        })?;
        Ok(job)
    }

    fn run_sweep(
        &self,
        id: &str,
        pose_name: &str,
        q_deg: &[f64],
    ) -> Result<String, (JobState, String)> {
        let failed = |e: String| (JobState::Failed, e);
        let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
        let pose = self.robot.pose(&q).map_err(|e| failed(e.to_string()))?;
        let realtime = self.cfg.clock == ClockKind::Monotonic;
        let opts = RobotDriveOptions {
            first_node: self.cfg.first_node,
            cycle_hz: self.cfg.cycle_hz,
            clock: if realtime {
                ClockMode::RealTime
            } else {
                ClockMode::LockStep
            },
            ..RobotDriveOptions::default()
        };
        let sim = SimulatedRobot::start(
            &format!("robot-{id}"),
            &self.robot,
            &q,
            &self.simulated,
            &opts,
        )
        .map_err(|e| failed(e.to_string()))?;
        let master = MasterConfig {
            cycle_period: std::time::Duration::from_secs_f64(1.0 / self.cfg.cycle_hz),
            ..MasterConfig::for_node(self.cfg.first_node)
        };
        let mut group = sim
            .enable_group(&master)
            .map_err(|e| failed(e.to_string()))?;
        let mo = MeasureOptions {
            transient_periods: self.cfg.transient_periods,
            periods: self.cfg.periods,
            ..MeasureOptions::for_axes(self.robot.axes(), self.cfg.cycle_hz, 100)
        };
        let pacing = if realtime {
            Pacing::Realtime
        } else {
            Pacing::Lockstep
        };
        let plan = plan_pose(pose_name, &pose, &mo, pacing).map_err(|e| failed(e.to_string()))?;
        self.update(id, |j| {
            j.cycles = plan.cycles() as u64;
            j.experiments = plan.excitation.experiments();
        });
        let result = measure_pose(pose_name, &mut group, &plan, &self.abort, &mut |p| {
            self.update(id, |j| {
                j.cycle = p.cycle;
                j.experiment = p.experiment;
                j.elapsed_s = p.elapsed.as_secs_f64();
            })
        });
        if let Err(e) = group.disable() {
            tracing::warn!("robot job {id}: disabling the drives: {e}");
        }
        let (outcome, frf) = match result {
            Ok(x) => x,
            Err(e) => {
                let aborted = self.abort.load(Ordering::Relaxed);
                return Err((
                    if aborted {
                        JobState::Aborted
                    } else {
                        JobState::Failed
                    },
                    e.to_string(),
                ));
            }
        };
        write_pose_files(
            &self.dir.join(id),
            &self.cfg.name,
            pose_name,
            q_deg,
            sim.nodes(),
            &frf,
            &outcome,
        )
        .map_err(failed)
    }

    /// The completed sweeps an identification uses: those named, or the latest of every
    /// identification pose.
    fn sweeps_for(&self, named: Option<Vec<String>>) -> Result<Vec<String>, RobotError> {
        let jobs = self.lock_jobs();
        let done = |j: &&RobotJob| j.kind == JobKind::Sweep && j.state == JobState::Completed;
        let ids = match named {
            Some(ids) => {
                for id in &ids {
                    if !jobs.get(id).is_some_and(|j| done(&j)) {
                        return Err(RobotError::Request {
                            field: "sweeps",
                            reason: format!("{id} is not a completed sweep of this robot"),
                        });
                    }
                }
                ids
            }
            None => self
                .robot
                .poses_of(PoseRole::Identification)
                .iter()
                .filter_map(|(name, _)| {
                    jobs.values()
                        .filter(done)
                        .filter(|j| j.pose.as_deref() == Some(name))
                        .max_by(|a, b| a.started_unix_s.total_cmp(&b.started_unix_s))
                        .map(|j| j.id.clone())
                })
                .collect(),
        };
        if ids.is_empty() {
            return Err(RobotError::Request {
                field: "sweeps",
                reason: "no completed sweep to identify from: sweep the identification poses first"
                    .into(),
            });
        }
        Ok(ids)
    }

    /// Starts an identification; its job.
    pub fn start_identification(
        self: &Arc<Self>,
        req: IdentifyRequest,
    ) -> Result<RobotJob, RobotError> {
        let starts = req.starts.unwrap_or(DEFAULT_STARTS);
        if !(1..=120).contains(&starts) {
            return Err(RobotError::Request {
                field: "starts",
                reason: format!("{starts}: must be 1..=120"),
            });
        }
        let sweeps = self.sweeps_for(req.sweeps)?;
        let job = self.begin(JobKind::Identification, None, sweeps.clone())?;
        self.spawn(&job.id, move |me, id| {
            let t0 = Instant::now();
            match me.run_identification(id, &sweeps, starts) {
                Ok(msg) => me.finish(id, JobState::Completed, msg, t0),
                Err(e) => me.finish(id, JobState::Failed, e, t0),
            }
        })?;
        Ok(job)
    }

    fn run_identification(
        &self,
        id: &str,
        sweeps: &[String],
        starts: usize,
    ) -> Result<String, String> {
        let mut files = Vec::new();
        for s in sweeps {
            let p = self.dir.join(s).join(FRF_MATRIX_JSON);
            let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
            let f: FrfMatrixFile =
                serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))?;
            files.push((s.clone(), f));
        }
        self.update(id, |j| {
            j.message = format!("identifying from {starts} starts")
        });
        let (doc, summary) = identify_files(
            &self.robot,
            &self.cfg.name,
            &files,
            starts,
            self.cfg.cycle_hz,
        )?;
        write_json(&self.dir.join(id).join(IDENTIFICATION_JSON), &doc)?;
        Ok(summary)
    }
}
