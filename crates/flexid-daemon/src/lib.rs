//! `flexid daemon`: the identification service.
//!
//! A tokio service that runs sweeps on the configured axes on request, streams their
//! progress and Bode estimates to HTTP clients (server-sent events), stores every result
//! under `data_dir/<axis>/<sweep-id>/`, and publishes identified models over MQTT.
//!
//! * [`config`]: the TOML configuration, validated at start (errors name the key);
//! * [`token`]: the bearer token file (mode 0600/0400, owner) and constant-time compare;
//! * [`request`]: sweep requests, validated against the axis limits, and their plan;
//! * [`backend`]: the [`AxisBackend`] seam to what drives the motor;
//!   [`sim_backend`] simulates a chain behind it, [`canopen_backend`] drives CiA 402
//!   drives on CAN with the sweep library, [`ecat_backend`] on EtherCAT,
//!   [`fieldbus_backend`] picks one by the axis's bus kind;
//! * [`store`]: the results store (atomic files, per-period fsynced recording,
//!   `interrupted` after a crash);
//! * [`service`], [`runner`], [`hub`]: the sweeps' life cycle and event fan-out;
//! * [`two_level`]: the two-level sweep and the gap diagnosis after it;
//! * [`api`]: the HTTP routes (axum); [`web`]: the embedded web page; [`connections`]:
//!   the accept loop, header-read timeout and connection limits;
//! * [`mqtt`], [`notify`], [`logging`]: MQTT, systemd notifications, journald;
//! * [`server`]: start/stop ([`server::start`] with an injected shutdown, for tests).

pub mod api;
pub mod backend;
pub mod canopen_backend;
mod canopen_tap;
pub mod config;
pub mod connections;
mod drive_sweep;
pub mod ecat_backend;
pub mod fieldbus_backend;
mod follow;
pub mod hub;
mod job;
pub mod logging;
pub mod mqtt;
pub mod notify;
pub mod period_relay;
pub mod request;
pub mod robot;
pub mod runner;
pub mod server;
pub mod service;
pub mod sim_backend;
pub mod store;
pub mod token;
pub mod two_level;
pub mod web;

pub use backend::{
    AbortSignal, AxisBackend, BackendError, Counters, Outcome, SampleBlock, SweepEvent,
    SweepHandle, SweepPlan,
};
pub use config::{AxisConfig, Config, ConfigError};
pub use server::{run, start, DaemonError, Running};
pub use sim_backend::SimBackend;
