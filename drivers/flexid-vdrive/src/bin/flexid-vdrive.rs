//! `flexid-vdrive`: the simulated CiA 402 servo drive on a CAN bus.
//!
//! ```text
//! flexid-vdrive --bus udp[:GROUP[:PORT]] | socketcan:IFACE [--node 5] [--plant P.toml]
//!               [--clock lockstep|realtime] [--bitrate 1000000] [--fifo-priority 1..=99]
//! ```
//!
//! The drive answers every SYNC from its receive path (it has no cycle timer of its own);
//! `--fifo-priority` serves the bus under `SCHED_FIFO` with locked memory, as a drive's
//! firmware answers within microseconds whatever the host runs (refused rights are logged
//! and the drive runs at normal priority).
//!
//! Prints `flexid-vdrive: node N ready on BUS` on stdout once the boot-up frame is sent;
//! exits 0 on SIGTERM/SIGINT, 2 on bad arguments or a bad plant file, 1 on a bus failure.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, ValueEnum};
use flexid_can::timing::Paced;
use flexid_can::{BusSpec, CanBus, UdpMulticastBus};
use flexid_vdrive::{plant_drive, ClockMode, DrivePlant, Runner};

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Clock {
    /// Each SYNC advances the plant by exactly one cycle.
    Lockstep,
    /// The plant follows the wall clock (whole cycles elapsed at each SYNC).
    Realtime,
}

/// Simulated CiA 402 servo drive (CANopen slave) in front of a compliant-axis plant.
#[derive(Debug, Parser)]
#[command(name = "flexid-vdrive", version)]
struct Cli {
    /// `udp[:GROUP[:PORT]]` (python-can udp_multicast compatible) or `socketcan:IFACE`.
    #[arg(long, default_value = "udp")]
    bus: String,
    /// Node id 1..=127 (default: the plant file's [drive] node_id, else 5).
    #[arg(long)]
    node: Option<u8>,
    /// Plant file (TOML, with an optional [drive] section); default: the embedded
    /// plants/scara_shoulder.toml.
    #[arg(long)]
    plant: Option<PathBuf>,
    /// How the plant advances.
    #[arg(long, value_enum, default_value = "lockstep")]
    clock: Clock,
    /// Emulate this bit rate [bit/s] on a virtual (UDP) bus; ignored on SocketCAN (set it
    /// with `ip link`).
    #[arg(long)]
    bitrate: Option<u32>,
    /// Seed of the plant's noise (nonlinear plant with [effects] only).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Serve the bus under `SCHED_FIFO` at this priority (1..=99) with locked memory.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=99))]
    fifo_priority: Option<u8>,
    /// SYNC-loss supervision: this many communication cycle periods (0x1006) without
    /// SYNC in Operation enabled fault the drive (EMCY 0x8700); 0 turns it off. Overrides
    /// the plant file's `[drive] sync_loss_cycles` (default 3).
    #[arg(long)]
    sync_loss_cycles: Option<u16>,
}

fn serve<B: CanBus>(
    bus: B,
    plant: &DrivePlant,
    clock: ClockMode,
    seed: u64,
    fifo_priority: Option<u8>,
) -> ExitCode {
    if let Some(p) = fifo_priority {
        let granted = flexid_rt::RtSetup::realtime(p).apply();
        for r in &granted.refused {
            eprintln!("flexid-vdrive: {r}");
        }
    }
    let drive = match plant_drive(plant, clock, seed) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("flexid-vdrive: {e}");
            return ExitCode::from(2);
        }
    };
    let node = drive.config().node_id;
    let mut runner = Runner::new(bus, drive);
    runner.power_on();
    println!("flexid-vdrive: node {node} ready on {}", runner.interface());
    use std::io::Write;
    let _ = std::io::stdout().flush();
    tracing::info!(node, bus = runner.interface(), ?clock, "ready");
    match runner.serve(&STOP) {
        Ok(()) => {
            let s = runner.drive().stats();
            tracing::info!(frames = s.frames, syncs = s.syncs, "stopped");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("flexid-vdrive: {e}");
            ExitCode::from(1)
        }
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("FLEXID_LOG")
                .unwrap_or_else(|_| "warn".into()),
        )
        // colour only on a terminal and without NO_COLOR (https://no-color.org)
        .with_ansi(
            std::io::IsTerminal::is_terminal(&std::io::stderr())
                && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    let mut plant = match DrivePlant::load(cli.plant.as_deref()) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("flexid-vdrive: bad plant file: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(n) = cli.node {
        if !(1..=127).contains(&n) {
            eprintln!("flexid-vdrive: --node {n}: must be 1..=127");
            return ExitCode::from(2);
        }
        plant.drive.node_id = n;
    }
    if let Some(n) = cli.sync_loss_cycles {
        plant.drive.sync_loss_cycles = n;
    }
    let spec = match BusSpec::parse(&cli.bus) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("flexid-vdrive: {e}");
            return ExitCode::from(2);
        }
    };
    // SAFETY: the handler only stores to an atomic (async-signal-safe).
    unsafe {
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
    }
    let clock = match cli.clock {
        Clock::Lockstep => ClockMode::LockStep,
        Clock::Realtime => ClockMode::RealTime,
    };
    match spec {
        BusSpec::Udp(cfg) => match UdpMulticastBus::open(cfg) {
            Ok(bus) => match cli.bitrate {
                Some(b) if b > 0 => serve(
                    Paced::new(bus, b),
                    &plant,
                    clock,
                    cli.seed,
                    cli.fifo_priority,
                ),
                _ => serve(bus, &plant, clock, cli.seed, cli.fifo_priority),
            },
            Err(e) => {
                eprintln!("flexid-vdrive: {e}");
                ExitCode::from(1)
            }
        },
        #[cfg(target_os = "linux")]
        BusSpec::SocketCan(iface) => match flexid_can::SocketCanBus::open(&iface) {
            Ok(bus) => {
                if cli.bitrate.is_some() {
                    tracing::info!("--bitrate ignored on SocketCAN (set it with ip link)");
                }
                serve(bus, &plant, clock, cli.seed, cli.fifo_priority)
            }
            Err(e) => {
                eprintln!("flexid-vdrive: {e}");
                ExitCode::from(1)
            }
        },
        #[cfg(not(target_os = "linux"))]
        BusSpec::SocketCan(_) => {
            eprintln!("flexid-vdrive: SocketCAN is Linux only");
            ExitCode::from(2)
        }
    }
}
