//! The `flexid` binary: parses the command line and calls the library.

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = flexid::cli::Cli::parse();
    if matches!(cli.command, flexid::cli::Command::Daemon(_)) {
        flexid::daemon::logging::init();
    } else {
        init_stderr_log();
    }
    match flexid::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("flexid: error: {e}");
            ExitCode::from(e.code)
        }
    }
}

fn init_stderr_log() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("FLEXID_LOG")
                .unwrap_or_else(|_| "warn".into()),
        )
        .with_ansi(flexid::daemon::logging::stderr_wants_colour())
        .with_writer(std::io::stderr)
        .init();
}
