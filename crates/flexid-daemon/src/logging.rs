//! Logging of the daemon: to the journal (tracing-journald) when started by systemd with
//! its output connected to the journal (`JOURNAL_STREAM` set), else to stderr. The level
//! comes from `FLEXID_LOG` (default `info`); colour only on a terminal, never with
//! `NO_COLOR`.

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
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter())
        .with_ansi(stderr_wants_colour())
        .with_writer(std::io::stderr)
        .try_init();
}

/// Colour (ANSI codes) on stderr only when it is a terminal and `NO_COLOR` is unset or
/// empty (<https://no-color.org>).
pub fn stderr_wants_colour() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}
