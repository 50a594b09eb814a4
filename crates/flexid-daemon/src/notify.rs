//! systemd notifications (`Type=notify`): `READY=1` once the API is bound, `WATCHDOG=1`
//! every half of `WATCHDOG_USEC`, `STOPPING=1` on shutdown. Without `NOTIFY_SOCKET` (not
//! under systemd) every call does nothing.

use sd_notify::NotifyState;
use std::time::Duration;
use tokio::sync::watch;

/// Tell systemd the service is ready, with a status line.
pub fn ready(status: &str) {
    if let Err(e) = sd_notify::notify(&[NotifyState::Ready, NotifyState::Status(status)]) {
        tracing::warn!("sd_notify READY: {e}");
    }
}

/// Tell systemd the service is stopping.
pub fn stopping() {
    let _ = sd_notify::notify(&[NotifyState::Stopping]);
}

/// The watchdog ping interval: half of `WATCHDOG_USEC` when the watchdog is enabled for
/// this process.
pub fn watchdog_interval() -> Option<Duration> {
    sd_notify::watchdog_enabled().map(|d| d / 2)
}

/// Ping the watchdog at [`watchdog_interval`] until `shutdown` turns true. The pings come
/// from the runtime, so a wedged runtime stops them and systemd restarts the service.
pub fn spawn_watchdog(mut shutdown: watch::Receiver<bool>) {
    let Some(every) = watchdog_interval() else {
        return;
    };
    tracing::info!("systemd watchdog: ping every {every:?}");
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(every.max(Duration::from_millis(10)));
        loop {
            tokio::select! {
                _ = tick.tick() => {
                    let _ = sd_notify::notify(&[NotifyState::Watchdog]);
                }
                _ = shutdown.changed() => {
                    if *shutdown.borrow() { break; }
                }
            }
        }
    });
}
