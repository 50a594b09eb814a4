//! The daemon's shared state and operations, independent of HTTP: list axes, start and
//! abort sweeps, look sweeps up. The API handlers are thin wrappers around these.

use super::backend::{AxisBackend, BackendError};
use super::config::Config;
use super::hub::SweepHub;
use super::job::{AxisOwner, Job, TwoLevel};
use super::mqtt::Mqtt;
use super::request::{parse_request, plan_levels, RequestError};
use super::runner;
use super::store::{new_sweep_id, unix_now, Store, SweepState, SweepStatus};
use super::token::Token;
use serde::Serialize;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// Errors of the service operations, each with its HTTP status.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    #[error("no axis named {0:?}")]
    UnknownAxis(String),
    #[error("no sweep with id {0:?}")]
    UnknownSweep(String),
    #[error("{0}")]
    Request(#[from] RequestError),
    #[error("axis {axis} is busy with sweep {sweep}")]
    Busy { axis: String, sweep: String },
    #[error("sweep {0} is not running")]
    NotRunning(String),
    #[error("{0}")]
    Backend(#[from] BackendError),
    #[error("results store: {0}")]
    Store(#[from] super::store::StoreError),
    #[error("internal error: {0}")]
    Internal(String),
}

/// The state of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisState {
    Idle,
    Sweeping,
    Aborting,
}

/// An axis as listed by `GET /api/v1/axes`.
#[derive(Debug, Clone, Serialize)]
pub struct AxisView {
    pub name: String,
    pub bus: String,
    /// The kind of the axis's bus (`udp`, `socketcan`, `ethercat`).
    pub bus_kind: Option<super::config::BusKind>,
    pub node: u8,
    pub cycle_hz: f64,
    pub state: AxisState,
    /// The running sweep, if any.
    pub sweep_id: Option<String>,
    /// The latest sweep that ended with an identified model.
    pub last_result_id: Option<String>,
    /// The latest sweep.
    pub last_sweep_id: Option<String>,
}

#[derive(Debug, Default)]
pub(crate) struct AxisRuntime {
    pub state: Option<(AxisState, String)>,
    pub last_result: Option<(f64, String)>,
    pub last_sweep: Option<(f64, String)>,
}

/// Everything the handlers share.
pub struct Service {
    pub config: Config,
    pub token: Token,
    pub backend: Arc<dyn AxisBackend>,
    pub store: Store,
    pub mqtt: Option<Mqtt>,
    /// The configuration's `[robot]`, if any (multi-axis sweeps and identification).
    pub robot: Option<Arc<crate::robot::RobotService>>,
    pub(crate) axes: Mutex<HashMap<String, AxisRuntime>>,
    /// Sweeps run by this process (live hubs).
    pub(crate) hubs: Mutex<HashMap<String, Arc<SweepHub>>>,
    /// Every known sweep id -> axis (from disk at start, plus new ones).
    pub(crate) index: Mutex<HashMap<String, String>>,
    pub(crate) runners: Mutex<Vec<std::thread::JoinHandle<()>>>,
}

impl Service {
    /// Build the service: recover interrupted sweeps and index the store.
    pub fn new(
        config: Config,
        token: Token,
        backend: Arc<dyn AxisBackend>,
        store: Store,
        mqtt: Option<Mqtt>,
        robot: Option<Arc<crate::robot::RobotService>>,
    ) -> Arc<Service> {
        store.recover();
        let mut axes: HashMap<String, AxisRuntime> = config
            .axis
            .iter()
            .map(|a| (a.name.clone(), AxisRuntime::default()))
            .collect();
        let mut index = HashMap::new();
        for (id, st) in store.scan() {
            if let Some(rt) = axes.get_mut(&st.axis) {
                let t = st.started_unix_s;
                if rt.last_sweep.as_ref().is_none_or(|(t0, _)| t > *t0) {
                    rt.last_sweep = Some((t, id.clone()));
                }
                if st.has_result && rt.last_result.as_ref().is_none_or(|(t0, _)| t > *t0) {
                    rt.last_result = Some((t, id.clone()));
                }
            }
            index.insert(id, st.axis);
        }
        let svc = Arc::new(Service {
            config,
            token,
            backend,
            store,
            mqtt,
            robot,
            axes: Mutex::new(axes),
            hubs: Mutex::new(HashMap::new()),
            index: Mutex::new(index),
            runners: Mutex::new(Vec::new()),
        });
        for a in &svc.config.axis {
            svc.publish_state(&a.name);
        }
        svc
    }

    /// The axes, in configuration order.
    pub fn axes(&self) -> Vec<AxisView> {
        let g = self.axes.lock().unwrap_or_else(|e| e.into_inner());
        self.config
            .axis
            .iter()
            .map(|a| {
                let rt = g.get(&a.name);
                let st = rt.and_then(|r| r.state.clone());
                AxisView {
                    name: a.name.clone(),
                    bus: a.bus.clone(),
                    bus_kind: self
                        .config
                        .bus
                        .iter()
                        .find(|b| b.name == a.bus)
                        .map(|b| b.kind),
                    node: a.node,
                    cycle_hz: a.cycle_hz,
                    state: st.as_ref().map_or(AxisState::Idle, |s| s.0),
                    sweep_id: st.map(|s| s.1),
                    last_result_id: rt.and_then(|r| r.last_result.as_ref().map(|x| x.1.clone())),
                    last_sweep_id: rt.and_then(|r| r.last_sweep.as_ref().map(|x| x.1.clone())),
                }
            })
            .collect()
    }

    /// Validate, plan and start a sweep on `axis`; returns its id. The backend is called
    /// only after the request passed every check and the axis was reserved.
    pub async fn start_sweep(
        self: &Arc<Self>,
        axis: &str,
        body: &[u8],
    ) -> Result<String, ServiceError> {
        let ax = self
            .config
            .axis(axis)
            .ok_or_else(|| ServiceError::UnknownAxis(axis.into()))?
            .clone();
        let req = parse_request(body, &ax)?;
        if let Some(sweep) = self.busy_with(axis) {
            return Err(ServiceError::Busy {
                axis: axis.into(),
                sweep,
            });
        }
        let id = new_sweep_id();
        let (req2, ax2, id2) = (req.clone(), ax.clone(), id.clone());
        let mut plans = tokio::task::spawn_blocking(move || plan_levels(&req2, &ax2, &id2))
            .await
            .map_err(|e| ServiceError::Internal(e.to_string()))??;
        // a two-level sweep starts with the low level; the runner starts the high one
        let plan = plans.remove(0);
        let two_level = req.levels_nm.is_some();
        // reserve the axis (a concurrent request may have won meanwhile)
        {
            let mut g = self.axes.lock().unwrap_or_else(|e| e.into_inner());
            let rt = g.entry(axis.to_string()).or_default();
            if let Some((_, sweep)) = &rt.state {
                return Err(ServiceError::Busy {
                    axis: axis.into(),
                    sweep: sweep.clone(),
                });
            }
            rt.state = Some((AxisState::Sweeping, id.clone()));
            rt.last_sweep = Some((unix_now(), id.clone()));
        }
        let status = SweepStatus {
            id: id.clone(),
            axis: axis.into(),
            state: SweepState::Running,
            reason: None,
            started_unix_s: unix_now(),
            ended_unix_s: None,
            periods_done: 0,
            samples: 0,
            request: req,
            has_result: false,
            level: two_level.then_some(1),
            has_diagnosis: false,
        };
        let sidecar = flexid_files::recording::Sidecar {
            sample_rate_hz: Some(plan.sample_rate_hz),
            excitation: Some(plan.info.clone()),
            ..Default::default()
        };
        let files = match self.store.begin(&status, &sidecar) {
            Ok(f) => f,
            Err(e) => {
                self.release(axis);
                return Err(e.into());
            }
        };
        let levels = 1 + plans.len();
        let planned = (
            plan.total_periods() * levels,
            plan.duration_s() * levels as f64,
            plan.sample_rate_hz,
        );
        let handle = match self.backend.start(&ax, plan) {
            Ok(h) => h,
            Err(e) => {
                let mut st = status.clone();
                st.state = SweepState::Failed;
                st.reason = Some(e.to_string());
                st.ended_unix_s = Some(unix_now());
                let _ = files.finish(&st, &sidecar);
                self.index_insert(&id, axis);
                self.release(axis);
                return Err(e.into());
            }
        };
        let hub = Arc::new(SweepHub::new(status.clone(), handle.abort.clone()));
        self.hubs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(id.clone(), hub.clone());
        self.index_insert(&id, axis);
        self.publish_state(axis);
        tracing::info!(
            "axis {axis}: sweep {id} started ({:?}, {} periods, {:.1} s)",
            status.request.excitation,
            planned.0,
            planned.1
        );
        let svc = self.clone();
        let job = Job {
            svc: svc.clone(),
            hub,
            files,
            sidecar,
            events: handle.events,
            periods_total: planned.0,
            planned_s: planned.1,
            sample_rate_hz: planned.2,
            two_level: two_level.then(|| TwoLevel {
                axis: ax.clone(),
                next: plans,
                levels_nm: status.request.levels_nm.unwrap_or_default(),
                masses: status.request.masses,
            }),
        };
        let t = std::thread::Builder::new()
            .name(format!("sweep-{axis}"))
            .spawn(move || runner::run(job))
            .map_err(|e| ServiceError::Internal(format!("cannot start the sweep thread: {e}")))?;
        let mut runners = self.runners.lock().unwrap_or_else(|e| e.into_inner());
        runners.retain(|h| !h.is_finished());
        runners.push(t);
        Ok(id)
    }

    /// Operator abort of a running sweep.
    pub fn abort(&self, id: &str) -> Result<(), ServiceError> {
        let hub = self.hub(id).ok_or_else(|| {
            if self.axis_of(id).is_some() {
                ServiceError::NotRunning(id.into())
            } else {
                ServiceError::UnknownSweep(id.into())
            }
        })?;
        let st = hub.status().map(|s| s.state);
        if st != Some(SweepState::Running) {
            return Err(ServiceError::NotRunning(id.into()));
        }
        hub.abort.abort("operator abort");
        if let Some(axis) = self.axis_of(id) {
            let mut g = self.axes.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(rt) = g.get_mut(&axis) {
                if let Some(s) = rt.state.as_mut().filter(|s| s.1 == id) {
                    s.0 = AxisState::Aborting;
                }
            }
            drop(g);
            self.publish_state(&axis);
        }
        tracing::info!("sweep {id}: operator abort");
        Ok(())
    }

    /// Abort every running sweep (daemon shutdown) and wait for their runners (at most
    /// `timeout`).
    pub fn shutdown(&self, timeout: std::time::Duration) {
        for hub in self.hubs.lock().unwrap_or_else(|e| e.into_inner()).values() {
            hub.abort.abort("daemon shutdown");
        }
        if let Some(r) = &self.robot {
            r.shutdown();
        }
        let t0 = std::time::Instant::now();
        let runners: Vec<_> =
            std::mem::take(&mut *self.runners.lock().unwrap_or_else(|e| e.into_inner()));
        for r in runners {
            while !r.is_finished() && t0.elapsed() < timeout {
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            if r.is_finished() {
                let _ = r.join();
            }
        }
    }

    /// The live hub of a sweep run by this process.
    pub fn hub(&self, id: &str) -> Option<Arc<SweepHub>> {
        self.hubs.lock().ok()?.get(id).cloned()
    }

    /// The axis a sweep belongs to.
    pub fn axis_of(&self, id: &str) -> Option<String> {
        self.index.lock().ok()?.get(id).cloned()
    }

    /// The sweep's directory.
    pub fn sweep_dir(&self, id: &str) -> Option<PathBuf> {
        self.axis_of(id).map(|a| self.store.dir(&a, id))
    }

    /// The sweep's status: live, or from `status.json`.
    pub fn status(&self, id: &str) -> Result<SweepStatus, ServiceError> {
        if let Some(s) = self.hub(id).and_then(|h| h.status()) {
            return Ok(s);
        }
        let dir = self
            .sweep_dir(id)
            .ok_or_else(|| ServiceError::UnknownSweep(id.into()))?;
        for f in [super::store::STATUS, super::store::RUNNING] {
            if let Ok(text) = std::fs::read_to_string(dir.join(f)) {
                return serde_json::from_str(&text)
                    .map_err(|e| ServiceError::Internal(format!("{f}: {e}")));
            }
        }
        Err(ServiceError::UnknownSweep(id.into()))
    }

    fn busy_with(&self, axis: &str) -> Option<String> {
        let g = self.axes.lock().unwrap_or_else(|e| e.into_inner());
        g.get(axis)
            .and_then(|r| r.state.as_ref().map(|s| s.1.clone()))
    }

    fn index_insert(&self, id: &str, axis: &str) {
        self.index
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(id.into(), axis.into());
    }

    /// Mark the axis idle again.
    pub(crate) fn release(&self, axis: &str) {
        if let Some(rt) = self
            .axes
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get_mut(axis)
        {
            rt.state = None;
        }
        self.publish_state(axis);
    }

    /// Record that `id` ended with a model.
    pub(crate) fn set_last_result(&self, axis: &str, id: &str) {
        if let Some(rt) = self
            .axes
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get_mut(axis)
        {
            rt.last_result = Some((unix_now(), id.into()));
        }
    }

    /// Publish the axis state (retained) when MQTT is configured.
    pub(crate) fn publish_state(&self, axis: &str) {
        let Some(m) = &self.mqtt else { return };
        let view = self.axes().into_iter().find(|a| a.name == axis);
        if let Some(v) = view {
            m.publish(
                axis,
                "state",
                &serde_json::json!({
                    "axis": v.name,
                    "state": v.state,
                    "sweep_id": v.sweep_id,
                    "last_result_id": v.last_result_id,
                    "time_unix_s": unix_now(),
                }),
            );
        }
    }
}

impl AxisOwner for Service {
    fn mqtt(&self) -> Option<&Mqtt> {
        self.mqtt.as_ref()
    }

    fn backend(&self) -> &dyn AxisBackend {
        self.backend.as_ref()
    }

    fn store(&self) -> &Store {
        &self.store
    }

    fn set_last_result(&self, axis: &str, id: &str) {
        Service::set_last_result(self, axis, id)
    }

    fn release(&self, axis: &str) {
        Service::release(self, axis)
    }
}
