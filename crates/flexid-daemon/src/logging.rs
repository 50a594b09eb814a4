//! Logging of the daemon: to the journal (tracing-journald) when started by systemd with
//! its output connected to the journal (`JOURNAL_STREAM` set), else to stderr. The level
//! comes from `FLEXID_LOG` (default `info`).

use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::EnvFilter;

/// Install the global subscriber (once; later calls do nothing).
pub fn init() {
    let filter = || EnvFilter::try_from_env("FLEXID_LOG").unwrap_or_else(|_| "info".into());
    if std::env::var_os("JOURNAL_STREAM").is_some() {
        match tracing_journald::layer() {
            Ok(j) => {
                let _ = tracing_subscriber::registry()
                    .with(filter())
                    .with(j.with_syslog_identifier("flexid".into()))
                    .try_init();
                return;
            }
            Err(e) => eprintln!("flexid: journald unavailable ({e}); logging to stderr"),
        }
    }
    use std::io::IsTerminal;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter())
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}
