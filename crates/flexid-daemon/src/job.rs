//! A running sweep's job: what its thread owns, and what it needs of the service that
//! started it ([`AxisOwner`]).

use crate::backend::{AxisBackend, SweepEvent, SweepPlan};
use crate::config::AxisConfig;
use crate::hub::SweepHub;
use crate::mqtt::Mqtt;
use crate::store::{Store, SweepFiles};
use flexid_files::recording::Sidecar;
use std::sync::Arc;
use tokio::sync::mpsc;

/// What a sweep's thread needs of the service that started it: implemented by
/// [`crate::service::Service`], so that the runner knows the service only through this.
pub(crate) trait AxisOwner: Send + Sync {
    /// The MQTT publisher, if configured.
    fn mqtt(&self) -> Option<&Mqtt>;
    /// The backend that starts sweeps (the two-level runner starts its second level).
    fn backend(&self) -> &dyn AxisBackend;
    /// The results store (the two-level runner writes each level's files into it).
    fn store(&self) -> &Store;
    /// Remember `id` as the axis's last sweep with a model.
    fn set_last_result(&self, axis: &str, id: &str);
    /// The axis is free again.
    fn release(&self, axis: &str);
}

/// Everything the runner owns.
pub(crate) struct Job {
    /// The service that owns the axis (releases it, keeps its last result, MQTT).
    pub svc: Arc<dyn AxisOwner>,
    pub hub: Arc<SweepHub>,
    pub files: SweepFiles,
    pub sidecar: Sidecar,
    pub events: mpsc::Receiver<SweepEvent>,
    pub periods_total: usize,
    pub planned_s: f64,
    pub sample_rate_hz: f64,
    /// A two-level sweep: what the runner needs to start the high level and diagnose.
    pub two_level: Option<TwoLevel>,
}

/// What the runner needs beyond the first level's sweep.
pub(crate) struct TwoLevel {
    /// The axis (to start the next level on).
    pub axis: AxisConfig,
    /// The plans of the levels still to run (the high one).
    pub next: Vec<SweepPlan>,
    /// `[low, high]` peak torques [N m].
    pub levels_nm: [f64; 2],
    /// Bodies of the nominal chain for the diagnosis (`None`: the high level's model's).
    pub masses: Option<usize>,
}
