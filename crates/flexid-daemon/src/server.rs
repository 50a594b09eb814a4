//! Starting and stopping the daemon: load the token, open the store, start MQTT, bind the
//! API, notify systemd, serve until the injected shutdown future resolves, then abort the
//! running sweeps (torque ramped to zero, recordings kept) and stop.

use super::api;
use super::backend::AxisBackend;
use super::config::{BackendKind, Config, ConfigError};
use super::connections;
use super::mqtt::Mqtt;
use super::notify;
use super::service::Service;
use super::sim_backend::SimBackend;
use super::store::{Store, StoreError};
use super::token::{Token, TokenError};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// Errors of starting or running the daemon.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("{0}")]
    Config(#[from] ConfigError),
    #[error("{0}")]
    Token(#[from] TokenError),
    #[error("data_dir: {0}")]
    Store(#[from] StoreError),
    #[error("backend: {0}")]
    Backend(String),
    #[error("api.listen {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("serving the API: {0}")]
    Serve(std::io::Error),
}

impl DaemonError {
    /// Exit code: 2 for bad configuration (the file, the token file, the backend choice),
    /// 1 for failures while running.
    pub fn exit_code(&self) -> u8 {
        match self {
            DaemonError::Config(_) | DaemonError::Token(_) | DaemonError::Backend(_) => 2,
            _ => 1,
        }
    }
}

/// Time the shutdown waits for running sweeps to ramp down and save.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(10);

/// The backend the configuration asks for.
pub fn backend_from_config(cfg: &Config) -> Result<Arc<dyn AxisBackend>, DaemonError> {
    match cfg.backend.kind {
        BackendKind::Simulated => {
            let b = SimBackend::from_plant_file(cfg.backend.plant.as_deref())
                .map_err(|e| DaemonError::Backend(format!("backend.plant: {e}")))?;
            tracing::warn!("backend: simulated ({}); no motor is driven", b.name);
            Ok(Arc::new(b))
        }
        BackendKind::Canopen => {
            for (i, a) in cfg.axis.iter().enumerate() {
                // an EtherCAT line's cycle is checked against the drive's firmware profile
                // at bring-up (the CAN admission counts CAN frames)
                let bus = cfg
                    .bus
                    .iter()
                    .find(|b| b.name == a.bus && b.kind != super::config::BusKind::Ethercat);
                if let Some(b) = bus {
                    flexid_sweep::admission_check(a.cycle_hz, b.bitrate)
                        .map_err(|e| DaemonError::Backend(format!("axis[{i}].cycle_hz: {e}")))?;
                }
            }
            let b =
                super::fieldbus_backend::FieldbusBackend::new(cfg).map_err(DaemonError::Backend)?;
            Ok(Arc::new(b))
        }
    }
}

/// A started daemon.
pub struct Running {
    /// The bound API address (the real port when `listen` had port 0).
    pub addr: SocketAddr,
    /// The shared state (for tests).
    pub service: Arc<Service>,
    task: tokio::task::JoinHandle<Result<(), DaemonError>>,
}

impl Running {
    /// Wait until the daemon has stopped (after the shutdown future resolved).
    pub async fn wait(self) -> Result<(), DaemonError> {
        self.task
            .await
            .map_err(|e| DaemonError::Serve(std::io::Error::other(e.to_string())))?
    }
}

/// Start the daemon on the current tokio runtime with `backend`; it stops when `shutdown`
/// resolves. Returns once the API is bound (and `READY=1` sent).
pub async fn start(
    config: Config,
    backend: Arc<dyn AxisBackend>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<Running, DaemonError> {
    let token = Token::load(&config.api.token_file)?;
    let store = Store::open(&config.data_dir)?;
    let (stop_tx, stop_rx) = watch::channel(false);
    let mqtt = config
        .mqtt
        .as_ref()
        .map(|m| Mqtt::start(m, stop_rx.clone()));
    let listen = config.api.listen;
    let listener = connections::bind(listen).map_err(|source| DaemonError::Bind {
        addr: listen,
        source,
    })?;
    let addr = listener.local_addr().map_err(|source| DaemonError::Bind {
        addr: listen,
        source,
    })?;
    if let Some(w) = exposure_warning(addr) {
        tracing::warn!("{w}");
    }
    let nofile = connections::raise_nofile();
    let limits = connections::Limits::for_nofile(nofile);
    let robot = match &config.robot {
        Some(r) => Some(
            crate::robot::RobotService::new(r.clone(), &config.data_dir)
                .map_err(|e| DaemonError::Backend(e.to_string()))?,
        ),
        None => None,
    };
    let svc = Service::new(config, token, backend, store, mqtt, robot);
    let app = api::router(svc.clone()).merge(super::web::router());
    notify::ready(&format!("API on {addr}"));
    notify::spawn_watchdog(stop_rx.clone());
    tracing::info!(
        "API listening on {addr} (at most {} connections, {} per client, request headers within {} s; RLIMIT_NOFILE {nofile})",
        limits.max_connections,
        limits.max_per_client,
        connections::HEADER_READ_TIMEOUT.as_secs()
    );
    let svc2 = svc.clone();
    let task = tokio::spawn(async move {
        let (graceful_tx, graceful_rx) = watch::channel(false);
        let server = connections::serve(listener, app, limits, graceful_rx);
        let mut server = std::pin::pin!(server);
        let result = tokio::select! {
            r = &mut server => r,
            _ = shutdown => {
                tracing::info!("shutting down");
                notify::stopping();
                // stop the sweeps first: their event streams end with `ended`
                let s = svc2.clone();
                let _ = tokio::task::spawn_blocking(move || s.shutdown(SHUTDOWN_GRACE)).await;
                let _ = graceful_tx.send(true);
                match tokio::time::timeout(Duration::from_secs(5), &mut server).await {
                    Ok(r) => r,
                    Err(_) => Ok(()),
                }
            }
        };
        let _ = stop_tx.send(true);
        result.map_err(DaemonError::Serve)
    });
    Ok(Running {
        addr,
        service: svc,
        task,
    })
}

/// The warning for an API bound beyond loopback (issue 16: binding 0.0.0.0 said
/// nothing): the daemon speaks plain HTTP, so the bearer token and the results cross the
/// network unencrypted. `None` for a loopback address.
pub fn exposure_warning(addr: SocketAddr) -> Option<String> {
    let ip = addr.ip();
    if ip.is_loopback() {
        return None;
    }
    let which = if ip.is_unspecified() {
        format!("{addr}, every network interface of this machine")
    } else {
        format!("{addr}, not a loopback address")
    };
    Some(format!(
        "api.listen: the API is reachable on {which}, over plain HTTP without TLS: the \
         bearer token and the results cross the network unencrypted; listen on 127.0.0.1 \
         and reach it through an SSH tunnel or a TLS reverse proxy"
    ))
}

/// Resolves on SIGTERM or SIGINT.
pub async fn termination() {
    use tokio::signal::unix::{signal, SignalKind};
    let term = signal(SignalKind::terminate());
    let int = signal(SignalKind::interrupt());
    match (term, int) {
        (Ok(mut t), Ok(mut i)) => {
            tokio::select! {
                _ = t.recv() => {}
                _ = i.recv() => {}
            }
        }
        _ => {
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}

/// `flexid daemon --config PATH`: load, start, print the bound address on stdout, serve
/// until SIGTERM/SIGINT.
pub fn run(config_path: &std::path::Path) -> Result<(), DaemonError> {
    let config = Config::load(config_path)?;
    let backend = backend_from_config(&config)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(DaemonError::Serve)?;
    rt.block_on(async move {
        let running = start(config, backend, termination()).await?;
        {
            use std::io::Write;
            let mut out = std::io::stdout();
            let _ = writeln!(out, "flexid daemon: listening on {}", running.addr);
            let _ = out.flush();
        }
        running.wait().await
    })
}

#[cfg(test)]
mod tests {
    use super::exposure_warning;

    /// Issue 16: binding 0.0.0.0 gave no warning.
    #[test]
    fn a_non_loopback_address_is_warned_about() {
        assert!(exposure_warning("127.0.0.1:8642".parse().unwrap()).is_none());
        assert!(exposure_warning("[::1]:8642".parse().unwrap()).is_none());
        let w = exposure_warning("0.0.0.0:8642".parse().unwrap()).unwrap();
        assert!(
            w.contains("every network interface") && w.contains("without TLS"),
            "{w}"
        );
        let w = exposure_warning("192.168.1.20:8642".parse().unwrap()).unwrap();
        assert!(w.contains("not a loopback address"), "{w}");
    }
}
