//! The `flexid` command line. The binary only parses arguments and calls [`run`]; every
//! command is library code, so that tests call the same paths.
//!
//! Contract (kept stable; other tools and tests call it):
//! * `flexid identify REC.csv [--masses N] [--json OUT.json]`
//! * `flexid bode REC.csv --out bode.svg`
//! * `flexid excite multisine|chirp|stepped ... --out EXC.csv`
//! * `flexid sweep --bus udp[:GROUP[:PORT]]|vcan0|socketcan:IFACE|ethercat:IFACE|ethercat:emulated --node 5 ...` (see [`sweep::SweepArgs`])

mod commands;
pub mod daemon_client;
mod demo;
pub mod diagnose;
mod excite;
mod fit_progress;
pub mod plant;
mod results;
mod robot;
mod robot_bus;
pub mod sweep;
mod sweep_args;
mod sweep_ethercat;
#[cfg(test)]
mod sweep_tests;

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// Identification of compliant servo axes: excitation, Bode estimation and n-mass chain
/// identification.
#[derive(Debug, Parser)]
#[command(name = "flexid", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Identify the compliant chain behind a recording; print the table, optionally write JSON.
    Identify(IdentifyArgs),
    /// Draw the measured Bode plot with its uncertainty band, coherence and the identified model.
    Bode(BodeArgs),
    /// Write an excitation signal (CSV time_s,torque_cmd_nm plus a JSON description).
    Excite(excite::ExciteArgs),
    /// Simulate a recording of a plant file driven by an excitation file.
    Simulate(SimulateArgs),
    /// The whole job on the embedded default: the simulated drive (flexid-vdrive) on the
    /// user-space CAN bus, `flexid sweep` against it, identify, compare with the plant, plot.
    Demo(DemoArgs),
    /// Convert a measurement file (MAT v5, DaISy ASCII, or a named preset) to a recording.
    Import(ImportArgs),
    /// One measurement on one axis over CAN: bring-up, excite, record, identify.
    Sweep(sweep::SweepArgs),
    /// The identification service: HTTP API, results store, MQTT (runs until SIGTERM).
    Daemon(DaemonArgs),
    /// Diagnose the gap between the identified chain and the measurement: where, which
    /// unmodelled effect, and how far it shrinks with it (one recording per amplitude).
    Diagnose(diagnose::DiagnoseArgs),
    /// Identify the gear and bearing flexibilities of a multi-axis robot (URDF plus
    /// flexibility file) from orthogonal-multisine FRF matrices at several poses: simulated,
    /// or measured pose by pose through its drives on a bus (`--bus`, `--pose`, `--out`),
    /// then identified from those measurements (`--from`). Prints the parameters, the cost
    /// per pose; writes the Bode matrix.
    Robot(robot::RobotArgs),
}

#[derive(Debug, Args)]
pub struct DaemonArgs {
    /// The configuration file (TOML).
    #[arg(long, default_value = "/etc/flexid/flexid.toml")]
    pub config: PathBuf,
}

/// Options shared by the commands that identify.
#[derive(Debug, Args, Clone)]
pub struct ModelArgs {
    /// Number of bodies of the chain (motor first); chosen automatically when absent.
    #[arg(long)]
    pub masses: Option<usize>,
    /// Analysis band [Hz]: lowest and highest frequency (default: the excited band).
    #[arg(long, num_args = 2, value_names = ["LO_HZ", "HI_HZ"])]
    pub band: Option<Vec<f64>>,
    /// Starts of the Levenberg-Marquardt refinement (the detected spectra plus random ones).
    #[arg(long, default_value_t = 20)]
    pub starts: usize,
    /// Seed of the random starts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Time cap of the identification [s]: after it, the best model found so far is
    /// returned, and the report and the JSON (`time_cap`) say so.
    #[arg(long, default_value_t = DEFAULT_MAX_SECONDS)]
    pub max_seconds: f64,
}

/// Default of `--max-seconds`: a few times what an automatic-order identification of a
/// long multisine record takes on a loaded 2-core machine.
pub const DEFAULT_MAX_SECONDS: f64 = 120.0;

#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// The recording (REC.csv, with REC.json beside it if present).
    pub recording: PathBuf,
    #[command(flatten)]
    pub model: ModelArgs,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Also draw the Bode plot here (SVG).
    #[arg(long)]
    pub svg: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct BodeArgs {
    /// The recording (REC.csv).
    pub recording: PathBuf,
    /// Output SVG file.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub model: ModelArgs,
    /// Draw the measurement only, without identifying a model.
    #[arg(long)]
    pub no_model: bool,
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Plant file (TOML); the embedded default (plants/scara_shoulder.toml) when absent.
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Excitation file written by `flexid excite`.
    #[arg(long)]
    pub excitation: PathBuf,
    /// Output recording (CSV; the JSON sidecar is written beside it).
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder for the excitation, recording, result JSON and Bode plot.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Plant file (TOML); the embedded default when absent.
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Seed of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// A preset name (see --list) or a file (.mat, .dat/.txt).
    pub source: Option<String>,
    /// List the presets for the data sets in ../shared/data.
    #[arg(long)]
    pub list: bool,
    /// Variable (MAT) or 1-based column (text) holding the input (torque, current, force).
    #[arg(long)]
    pub input: Option<String>,
    /// Variable or 1-based column holding the response.
    #[arg(long)]
    pub output: Option<String>,
    /// What the response is: position, velocity or acceleration.
    #[arg(long, default_value = "position")]
    pub kind: String,
    /// Sample rate [Hz], if the file does not hold one.
    #[arg(long)]
    pub fs: Option<f64>,
    /// Samples per period of a periodic excitation.
    #[arg(long)]
    pub period_samples: Option<usize>,
    /// Leading periods to discard.
    #[arg(long, default_value_t = 1)]
    pub transient_periods: usize,
    /// Output recording (CSV; the JSON sidecar is written beside it).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Errors of the command line: a message for the user, and the exit code.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct CliError {
    pub message: String,
    /// 2 for bad arguments or input files, 1 for failures of the analysis.
    pub code: u8,
}

impl CliError {
    pub(crate) fn input(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: 2,
        }
    }
    pub(crate) fn failed(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: 1,
        }
    }
    /// A file could not be written: exit 2 when the writer refused the target (a device,
    /// a FIFO, a directory, a link out of its folder: a bad argument), 1 otherwise.
    pub(crate) fn write(message: impl Into<String>, source: Option<&std::io::Error>) -> Self {
        let refused = source.is_some_and(|e| e.kind() == std::io::ErrorKind::InvalidInput);
        CliError {
            message: message.into(),
            code: if refused { 2 } else { 1 },
        }
    }
    /// [`CliError::write`] for a recording.
    pub(crate) fn write_recording(e: crate::recording::RecordingError) -> Self {
        let source = match &e {
            crate::recording::RecordingError::Io { source, .. } => Some(source),
            _ => None,
        };
        Self::write(e.to_string(), source)
    }
}

/// Run one command; output goes to stdout, progress to stderr.
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Identify(a) => commands::identify(&a),
        Command::Bode(a) => commands::bode(&a),
        Command::Excite(a) => excite::excite(&a),
        Command::Simulate(a) => commands::simulate(&a),
        Command::Demo(a) => demo::demo(&a),
        Command::Import(a) => commands::import(&a),
        Command::Sweep(a) => match sweep_ethercat::EcatTarget::parse(&a.bus) {
            Some(target) if a.daemon.daemon.is_none() => {
                sweep_ethercat::sweep_run_ethercat(&a, &target).map(|_| ())
            }
            _ => sweep::sweep(&a),
        },
        Command::Daemon(a) => crate::daemon::run(&a.config).map_err(|e| CliError {
            message: e.to_string(),
            code: e.exit_code(),
        }),
        Command::Diagnose(a) => diagnose::diagnose(&a),
        Command::Robot(a) => robot::robot(&a),
    }
}
