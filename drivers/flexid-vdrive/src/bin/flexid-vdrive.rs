//! `flexid-vdrive`: the simulated CiA 402 servo drive on a CAN bus.
//!
//! ```text
//! flexid-vdrive --bus udp[:GROUP[:PORT]] | socketcan:IFACE [--node 5] [--plant P.toml]
//!               [--clock lockstep|realtime] [--bitrate 1000000] [--fifo-priority 1..=99]
//! flexid-vdrive --robot [FLEX.toml] [--pose NAME] [--first-node 2] [--deviation 0.3] ...
//! flexid-vdrive --ethercat IFACE [--plant P.toml] [--axes 1] [--cycle-hz HZ]
//!               [--clock lockstep|realtime] [--fault-after-missed 100] [--fifo-priority 1..=99]
//! ```
//!
//! With `--ethercat`, emulated EtherCAT SubDevices (CiA 402 servos in CST, one per
//! `--axes`, each in front of the plant's linear chain discretised at `--cycle-hz`,
//! default the plant file's sample rate) answer a MainDevice on the interface (an
//! `AF_PACKET` socket: needs `CAP_NET_RAW`); `--clock realtime` runs the servos on their
//! SYNC0 clock (one cycle per SYNC0 pulse, a frame-less pulse a missed cycle), `lockstep`
//! one cycle per process-data frame. Prints `flexid-vdrive: N EtherCAT SubDevice(s) ready
//! on IFACE` once the socket is open, and on exit its counters on stderr.
//!
//! With `--robot`, a whole robot: one drive per axis (nodes `--first-node ..`), all in front
//! of one coupled plant, the robot's flexible model linearised at the pose (see
//! `flexid_vdrive::robot`); without a file, the reference arm `robots/flexid-arm6`.
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
use flexid_vdrive::robot::{self, CoupledAxis};
use flexid_vdrive::{
    plant_drive, BusNode, ClockMode, DrivePlant, DriveSet, Physics, Runner, VirtualDrive,
};

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
    /// Simulate a whole robot from its flexibility file (TOML naming its URDF); without a
    /// value, the embedded reference arm. `--plant` and `--node` do not apply.
    #[arg(long, num_args = 0..=1, default_missing_value = "reference")]
    robot: Option<String>,
    /// The robot's pose: a pose name of its file (default: the first one).
    #[arg(long, requires = "robot")]
    pose: Option<String>,
    /// Node id of the robot's axis 1 (axis i is first-node + i - 1).
    #[arg(long, default_value_t = 2, requires = "robot")]
    first_node: u8,
    /// The simulated robot's springs deviate from the file's by up to this fraction, each
    /// by its own factor seeded by `--seed` (0: the file's values).
    #[arg(long, default_value_t = 0.0, requires = "robot")]
    deviation: f64,
    /// Serve emulated EtherCAT SubDevices (CiA 402 servos) on this network interface
    /// instead of a CAN drive (Linux, CAP_NET_RAW).
    #[arg(long, conflicts_with_all = ["robot", "bus", "node", "bitrate"])]
    ethercat: Option<String>,
    /// EtherCAT: servos in the line.
    #[arg(long, default_value_t = 1, requires = "ethercat")]
    axes: usize,
    /// EtherCAT: the cycle the plant is discretised at [Hz] (the MainDevice's SYNC0
    /// rate); default: the plant file's sample rate.
    #[arg(long, requires = "ethercat")]
    cycle_hz: Option<f64>,
    /// EtherCAT, `--clock realtime`: consecutive missed cycles that fault a servo (0:
    /// never).
    #[arg(long, default_value_t = 100, requires = "ethercat")]
    fault_after_missed: u32,
}

/// What this process simulates.
enum Simulated {
    /// One drive of a plant file.
    Axis(VirtualDrive<Box<dyn Physics>>),
    /// A robot's drives, one coupled plant.
    Robot {
        set: DriveSet<CoupledAxis>,
        what: String,
    },
}

/// The drive(s) of the command line; exit code 2 and a message on stderr when they
/// cannot be built.
fn build(cli: &Cli, plant: &DrivePlant, clock: ClockMode) -> Result<Simulated, ExitCode> {
    let fail = |e: String| {
        eprintln!("flexid-vdrive: {e}");
        ExitCode::from(2)
    };
    let Some(which) = &cli.robot else {
        return plant_drive(plant, clock, cli.seed)
            .map(Simulated::Axis)
            .map_err(|e| fail(e.to_string()));
    };
    let path = (which != "reference").then(|| std::path::Path::new(which));
    let robot = robot::load_robot(path).map_err(fail)?;
    let (name, q_deg) = match &cli.pose {
        None => robot
            .poses
            .first()
            .map(|p| (p.name.clone(), p.q_deg.clone()))
            .ok_or_else(|| fail(format!("robot {}: its file has no pose", robot.name)))?,
        Some(n) => robot
            .poses
            .iter()
            .find(|p| &p.name == n)
            .map(|p| (p.name.clone(), p.q_deg.clone()))
            .ok_or_else(|| {
                let names: Vec<_> = robot.poses.iter().map(|p| p.name.as_str()).collect();
                fail(format!(
                    "--pose {n}: the robot's file has {}",
                    names.join(", ")
                ))
            })?,
    };
    if !(cli.deviation.is_finite() && (0.0..=0.9).contains(&cli.deviation)) {
        return Err(fail(format!(
            "--deviation {}: must be 0..=0.9",
            cli.deviation
        )));
    }
    let theta = robot.nominal.deviated(cli.deviation, cli.seed);
    let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
    let opts = robot::RobotDriveOptions {
        first_node: cli.first_node,
        clock,
        ..robot::RobotDriveOptions::default()
    };
    let (set, _plant) =
        robot::robot_drives(&robot, &q, &theta, &opts).map_err(|e| fail(e.to_string()))?;
    let ids = set.node_ids();
    Ok(Simulated::Robot {
        what: format!(
            "nodes {}-{} (robot {} at pose {name})",
            ids.first().copied().unwrap_or(0),
            ids.last().copied().unwrap_or(0),
            robot.name
        ),
        set,
    })
}

fn serve<B: CanBus>(
    bus: B,
    sim: Simulated,
    clock: ClockMode,
    fifo_priority: Option<u8>,
) -> ExitCode {
    if let Some(p) = fifo_priority {
        let granted = flexid_rt::RtSetup::realtime(p).apply();
        for r in &granted.refused {
            eprintln!("flexid-vdrive: {r}");
        }
    }
    match sim {
        Simulated::Axis(drive) => {
            let what = format!("node {}", drive.config().node_id);
            run(Runner::new(bus, drive), &what, clock)
        }
        Simulated::Robot { set, what } => run(Runner::new(bus, set), &what, clock),
    }
}

fn run<B: CanBus, N: BusNode>(mut runner: Runner<B, N>, what: &str, clock: ClockMode) -> ExitCode {
    runner.power_on();
    println!("flexid-vdrive: {what} ready on {}", runner.interface());
    use std::io::Write;
    let _ = std::io::stdout().flush();
    tracing::info!(what, bus = runner.interface(), ?clock, "ready");
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

/// `--ethercat IFACE`: the servos of the plant file on the interface until SIGTERM/SIGINT.
#[cfg(target_os = "linux")]
fn serve_ethercat(cli: &Cli, plant: &DrivePlant, iface: &str) -> ExitCode {
    use flexid_vdrive::ethercat::{self, EthercatOptions};
    let cycle_hz = cli
        .cycle_hz
        .unwrap_or(plant.plant.measurement.sample_rate_hz);
    if !(cycle_hz.is_finite() && (1.0..=100_000.0).contains(&cycle_hz)) {
        eprintln!("flexid-vdrive: --cycle-hz {cycle_hz}: must be 1..=100000");
        return ExitCode::from(2);
    }
    if plant.plant.effects.any() {
        eprintln!(
            "flexid-vdrive: note: the plant's [effects] are not simulated on EtherCAT (its \
             linear chain is)"
        );
    }
    let options = EthercatOptions {
        axes: cli.axes,
        cycle_hz,
        clock: match cli.clock {
            Clock::Lockstep => flexid_ecat::ServoClock::LockStep,
            Clock::Realtime => flexid_ecat::ServoClock::Sync0,
        },
        fault_after_missed_cycles: cli.fault_after_missed,
    };
    let segment = match ethercat::servo_segment(plant, &options) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("flexid-vdrive: {e}");
            return ExitCode::from(2);
        }
    };
    let clock = flexid_ecat::sync0_clock::SegmentClock::start();
    let mut link = match flexid_ecat::socket_link::SocketLink::open(iface, segment.clone(), clock) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("flexid-vdrive: {e}");
            return ExitCode::from(1);
        }
    };
    // The serving thread (this one) runs the frames and the SYNC0 pulses.
    if let Some(p) = cli.fifo_priority {
        for r in &flexid_rt::RtSetup::realtime(p).apply().refused {
            eprintln!("flexid-vdrive: {r}");
        }
    }
    println!(
        "flexid-vdrive: {} EtherCAT SubDevice(s) ready on {iface} ({cycle_hz} Hz, {:?} clock)",
        options.axes, options.clock
    );
    use std::io::Write;
    let _ = std::io::stdout().flush();
    match ethercat::serve(&mut link, &segment, &STOP) {
        Ok(s) => {
            eprintln!(
                "flexid-vdrive: frames received {}, returned {}, rejected {}; SYNC0 pulses {}, \
                 cycles {}, missed cycles {} (longest run {}), overwritten set-points {}; \
                 SYNC0 wake-up lateness max {:.1} us",
                s.link.received,
                s.link.returned,
                s.link.rejected,
                s.servos.pulses,
                s.servos.cycles,
                s.servos.missed,
                s.servos.longest_missed_run,
                s.servos.overwritten,
                s.clock.max_late_ns as f64 / 1e3
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("flexid-vdrive: {e}");
            ExitCode::from(1)
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn serve_ethercat(_: &Cli, _: &DrivePlant, _: &str) -> ExitCode {
    eprintln!("flexid-vdrive: --ethercat is Linux only");
    ExitCode::from(2)
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
    if let Some(iface) = &cli.ethercat {
        return serve_ethercat(&cli, &plant, iface);
    }
    let clock = match cli.clock {
        Clock::Lockstep => ClockMode::LockStep,
        Clock::Realtime => ClockMode::RealTime,
    };
    let sim = match build(&cli, &plant, clock) {
        Ok(s) => s,
        Err(code) => return code,
    };
    match spec {
        BusSpec::Udp(cfg) => match UdpMulticastBus::open(cfg) {
            Ok(bus) => match cli.bitrate {
                Some(b) if b > 0 => serve(Paced::new(bus, b), sim, clock, cli.fifo_priority),
                _ => serve(bus, sim, clock, cli.fifo_priority),
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
                serve(bus, sim, clock, cli.fifo_priority)
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
