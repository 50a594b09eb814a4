//! The arguments of `flexid sweep` (also read by the daemon client, which sends them to a
//! daemon instead of opening the bus here).

use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// Pacing of the cycles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClockArg {
    /// Absolute deadlines at the cycle rate (a real drive).
    Realtime,
    /// Next cycle as soon as the feedback is in (a simulated drive in lock-step).
    Lockstep,
}

/// The excitation signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExcitationArg {
    /// Periodic Schroeder multisine (as `flexid excite multisine`).
    Multisine,
    /// Logarithmic swept sine (as `flexid excite chirp`).
    Chirp,
}

/// `flexid sweep` (a contract: a daemon accepts the same flags).
#[derive(Debug, Args, Clone)]
pub struct SweepArgs {
    /// The bus: `udp[:GROUP[:PORT]]` (user-space UDP multicast), `vcan0`,
    /// `socketcan:IFACE`, or EtherCAT: `ethercat:IFACE` (root or CAP_NET_RAW) or
    /// `ethercat:emulated[:PLANT.toml]` (emulated servos in process) (not with `--daemon`:
    /// the daemon owns its buses).
    #[arg(
        long,
        required_unless_present = "daemon",
        default_value = "",
        hide_default_value = true
    )]
    pub bus: String,
    /// The drive's CANopen node-id; on EtherCAT the SubDevice's position (1 = first).
    #[arg(long, default_value_t = 5)]
    pub node: u8,
    /// Cycle (SYNC) rate [Hz]; the recording's sample rate.
    #[arg(long, default_value_t = 1000.0)]
    pub cycle_hz: f64,
    /// Bus bitrate [bit/s], for the bus-load admission check.
    #[arg(long, default_value_t = 1_000_000)]
    pub bitrate: u32,
    /// Pacing: realtime (absolute deadlines) or lockstep (simulated drive).
    #[arg(long, value_enum, default_value = "realtime")]
    pub clock: ClockArg,
    /// Excitation signal.
    #[arg(long, value_enum, default_value = "multisine")]
    pub excitation: ExcitationArg,
    /// Excited band [Hz] (default: from the resolution up to 0.4 x the cycle rate).
    #[arg(long, num_args = 2, value_names = ["LO_HZ", "HI_HZ"])]
    pub band: Option<Vec<f64>>,
    /// Peak torque [N m].
    #[arg(long, default_value_t = 0.5)]
    pub peak_nm: f64,
    /// RMS torque limit [N m] (default: no tighter than the peak allows).
    #[arg(long)]
    pub rms_nm: Option<f64>,
    /// Frequency resolution [Hz]: the multisine's line spacing (period = cycle rate /
    /// resolution); for a chirp, 1 / resolution is the duration of one "period".
    #[arg(long, default_value_t = 0.5)]
    pub resolution_hz: f64,
    /// Steady periods recorded (averaged).
    #[arg(long, default_value_t = 8)]
    pub periods: usize,
    /// Leading periods discarded (transient).
    #[arg(long, default_value_t = 1)]
    pub transient_periods: usize,
    /// Multisine amplitude grows as f^exponent over the band (0 = flat, as `flexid excite`).
    #[arg(long, default_value_t = 0.0)]
    pub amplitude_exponent: f64,
    /// Stop after this many seconds of wall time (default: 3 x the planned duration + 10 s).
    #[arg(long)]
    pub max_duration_s: Option<f64>,
    /// Stop when the motor speed exceeds this [rad/s].
    #[arg(long, default_value_t = 100.0)]
    pub max_speed_rad_s: f64,
    /// Stop when more feedback messages (TPDOs) than this are lost, i.e. not there before
    /// the next SYNC (default: 0.5 % of the cycles, at least 20). Raise it on a host
    /// without a real-time kernel, whose scheduling stalls of several milliseconds lose
    /// feedback; the counts are in the recording's sidecar either way.
    #[arg(long)]
    pub max_lost: Option<u64>,
    /// More firmware profiles (a directory of TOML files) besides the built-in ones.
    #[arg(long)]
    pub profiles: Option<PathBuf>,
    /// EtherCAT: run a drive no profile knows with the generic CiA 402 profile (units
    /// read from the drive) instead of refusing it.
    #[arg(long)]
    pub generic_profile: bool,
    /// Output folder: recording.csv/.json, result.json, bode.svg.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
    /// Number of bodies of the chain (motor first); chosen automatically when absent.
    #[arg(long)]
    pub masses: Option<usize>,
    /// Run through a daemon instead (`--daemon URL --token-file PATH [--axis NAME]`).
    #[command(flatten)]
    pub daemon: DaemonClientArgs,
}

/// The daemon to use for `flexid sweep`.
#[derive(Debug, Args, Clone, Default)]
pub struct DaemonClientArgs {
    /// Run the sweep through a running daemon at this URL (e.g. `http://127.0.0.1:8642`)
    /// instead of opening the bus here; `--bus` is then not needed.
    #[arg(long, value_name = "URL")]
    pub daemon: Option<String>,
    /// The daemon's token file (`api.token_file` of its configuration).
    #[arg(long, default_value = "/etc/flexid/token")]
    pub token_file: PathBuf,
    /// The daemon's axis (default: the one axis with `--node`).
    #[arg(long)]
    pub axis: Option<String>,
}
