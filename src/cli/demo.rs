//! `flexid demo`: the whole job on the embedded default, over the bus. Starts the sibling
//! `flexid-vdrive` (a CANopen CiA 402 drive in front of the plant) on the user-space UDP
//! multicast bus in lock-step, runs `flexid sweep` against it, and compares the identified
//! chain with the plant file. When the bus cannot be used (no sibling binary, multicast
//! not kept on loopback and not root), it says so and measures the in-process simulation
//! instead.

use super::excite::{write_excitation, Excitation};
use super::plant::PlantFile;
use super::sweep::{plan, sweep_run, ClockArg, ExcitationArg, SweepArgs};
use super::{CliError, DemoArgs};
use crate::analysis::Analysis;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

const GROUP: std::net::Ipv4Addr = std::net::Ipv4Addr::new(239, 74, 163, 2);

/// The demo's highest cycle rate over the bus [Hz]: 68.5 % of a 1 Mbit/s bus with the
/// default PDO mapping (within the 70 % admission limit, 1838 Hz) and overrun-free in the
/// cycle-rate benchmark (`drivers/flexid-vdrive/benches/cycle_rate.rs`). A plant file with
/// a faster cycle (the default's 2 kHz) is measured at this rate over the bus.
pub const DEMO_MAX_CYCLE_HZ: f64 = 1800.0;

/// The sweep the demo runs on `plant` at 1 Mbit/s: the plant's cycle rate capped at
/// [`DEMO_MAX_CYCLE_HZ`], line spacing a twelfth of the lowest anti-resonance, band up to
/// 2.5 x the highest resonance (at most 0.4 x the cycle rate), amplitude rising as f
/// (level velocity response), 8 + 1 periods, peak 2 N m, RMS 1 N m.
pub fn demo_sweep_args(plant: &PlantFile, bus: String, out: PathBuf) -> SweepArgs {
    let fs = plant.measurement.sample_rate_hz.min(DEMO_MAX_CYCLE_HZ);
    let ar = plant.chain.antiresonances_hz();
    let r = plant.chain.resonances_hz();
    let df = ar.first().map_or(1.0, |f| f / 12.0);
    let period = ((fs / df).ceil() as usize).max(64);
    let df = fs / period as f64;
    let hi = r.last().map_or(0.4 * fs, |f| (2.5 * f).min(0.4 * fs));
    SweepArgs {
        bus,
        node: 5,
        cycle_hz: fs,
        bitrate: 1_000_000,
        clock: ClockArg::Lockstep,
        excitation: ExcitationArg::Multisine,
        band: Some(vec![df, hi]),
        peak_nm: 2.0,
        rms_nm: Some(1.0),
        resolution_hz: df,
        periods: 8,
        transient_periods: 1,
        amplitude_exponent: 1.0,
        max_duration_s: None,
        max_speed_rad_s: 200.0,
        max_lost: None,
        profiles: None,
        generic_profile: false,
        out,
        masses: None,
        daemon: Default::default(),
    }
}

/// The `flexid-vdrive` next to this executable.
fn sibling_vdrive() -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| format!("current_exe: {e}"))?;
    let dir = exe.parent().ok_or("no directory of the executable")?;
    let bin = dir.join(format!("flexid-vdrive{}", std::env::consts::EXE_SUFFIX));
    if bin.is_file() {
        Ok(bin)
    } else {
        Err(format!(
            "{} not found (build it: `cargo build --release --workspace`)",
            bin.display()
        ))
    }
}

/// A started `flexid-vdrive`, stopped (SIGTERM, then kill) on drop.
struct VDrive(Child);

impl Drop for VDrive {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: plain kill(2) of our own child.
        unsafe {
            libc::kill(self.0.id() as libc::pid_t, libc::SIGTERM);
        }
        for _ in 0..100 {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_vdrive(bin: &PathBuf, bus: &str, plant: Option<&PathBuf>) -> Result<VDrive, String> {
    let mut cmd = Command::new(bin);
    cmd.args(["--bus", bus, "--node", "5", "--clock", "lockstep"]);
    if let Some(p) = plant {
        cmd.arg("--plant").arg(p);
    }
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| format!("{}: {e}", bin.display()))?;
    let stdout = child.stdout.take().expect("piped");
    let vd = VDrive(child);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut lines = BufReader::new(stdout).lines();
        if let Some(Ok(l)) = lines.next() {
            let _ = tx.send(l);
        }
        for _ in lines {}
    });
    match rx.recv_timeout(Duration::from_secs(10)) {
        Ok(l) if l.contains("ready on") => {
            eprintln!("flexid demo: {l}");
            Ok(vd)
        }
        Ok(l) => Err(format!("flexid-vdrive: unexpected output: {l}")),
        Err(_) => Err("flexid-vdrive did not report ready within 10 s".into()),
    }
}

/// The identified inertias and stiffnesses next to the plant file's (the truth of a
/// simulation), in the demo's output.
pub(super) fn print_truth(an: &Analysis, plant: &PlantFile) {
    let Some(m) = &an.model else { return };
    println!("\nAgainst the plant file (the truth in this simulation):");
    let truth = &plant.chain;
    if let Some(errors) = crate::model::truth::against_truth(
        (&m.inertia_kgm2, &m.stiffness_nm_per_rad),
        (&truth.inertia_kgm2, &truth.stiffness_nm_per_rad),
    ) {
        for e in errors {
            println!("  {e}");
        }
    } else {
        println!(
            "  identified {} bodies, the plant has {}",
            m.masses,
            truth.masses()
        );
    }
    // the spectra, each plant frequency against the nearest identified one (also when the
    // orders differ)
    for (name, got, want) in [
        ("AR", &m.antiresonance_hz, truth.antiresonances_hz()),
        ("R", &m.resonance_hz, truth.resonances_hz()),
    ] {
        for (i, w) in want.iter().enumerate() {
            let near = got
                .iter()
                .min_by(|a, b| ((*a - w).abs()).total_cmp(&(*b - w).abs()));
            match near {
                Some(g) => println!(
                    "  {name}{} [Hz]: identified {g:.3}, true {w:.3}, error {:+.2} %",
                    i + 1,
                    100.0 * (g - w) / w
                ),
                None => println!("  {name}{} [Hz]: not identified, true {w:.3}", i + 1),
            }
        }
    }
}

/// `flexid demo`: the sweep over the bus (CANopen to `flexid-vdrive`) when possible,
/// else the same sweep on the in-process simulated drive; then the identified table next
/// to the plant's true values. Both run the one sweep loop (`flexid_sweep::run_sweep`).
pub fn demo(a: &DemoArgs) -> Result<(), CliError> {
    let plant = flexid_files::plant::load_plant_file(a.plant.as_deref())
        .map_err(|e| CliError::input(e.to_string()))?;
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::failed(format!("{}: {e}", a.out.display())))?;
    let ready = sibling_vdrive()
        .and_then(|bin| flexid_can::keep_multicast_on_loopback(GROUP).map(|()| bin));
    let vdrive = match ready {
        Ok(bin) => Some(bin),
        Err(why) => {
            eprintln!(
                "flexid demo: the CAN bus cannot be used here: {why}.\n\
                 flexid demo: falling back to the simulated drive in-process (no CANopen)."
            );
            None
        }
    };
    // Its own port, so that demos and tests can run side by side.
    let port = 43300 + (std::process::id() % 600) as u16;
    let bus = format!("udp:{GROUP}:{port}");
    let args = demo_sweep_args(&plant, bus.clone(), a.out.clone());
    if args.cycle_hz < plant.measurement.sample_rate_hz {
        eprintln!(
            "flexid demo: measuring at {} Hz as on a 1 Mbit/s bus (the plant file's {} Hz cycle \
             is above the demo's rate: 2 kHz would need 76 % of the bus, 70 % is admitted)",
            args.cycle_hz, plant.measurement.sample_rate_hz
        );
    }
    // refused with the highest admissible rate if a plant's cycle does not fit
    super::sweep::admit(args.cycle_hz, args.bitrate)?;
    let p = plan(&args)?;
    let exc_path = a.out.join("excitation.csv");
    write_excitation(
        &exc_path,
        args.cycle_hz,
        &Excitation {
            torque_nm: p.torque_nm.clone(),
            info: p.excitation.clone(),
        },
    )?;
    let name = plant.name.as_deref().unwrap_or("plant");
    let started = vdrive.map(|bin| start_vdrive(&bin, &bus, a.plant.as_ref()));
    let (run, how) = match started {
        Some(Ok(vd)) => {
            eprintln!(
                "flexid demo: {name} — flexid-vdrive (CiA 402 over CANopen) on {bus}, lock-step"
            );
            let run = sweep_run(&args);
            drop(vd);
            (run?, "over CANopen")
        }
        other => {
            if let Some(Err(why)) = other {
                eprintln!(
                    "flexid demo: the simulated drive could not be started: {why}.\n\
                     flexid demo: falling back to the simulated drive in-process (no CANopen)."
                );
            }
            eprintln!("flexid demo: {name} — the simulated drive in-process, lock-step");
            (
                super::sweep::sweep_run_simulated(&args, &plant, a.seed)?,
                "in-process (no CANopen)",
            )
        }
    };
    if let Some(an) = &run.analysis {
        print_truth(an, &plant);
    }
    println!(
        "\nmeasured {how} in lock-step: {} cycles at {:.0} cycles/s\nwrote {}, {}, {} and {}",
        run.outcome.recording.len(),
        run.outcome.cycles_per_s(),
        exc_path.display(),
        run.recording_path.display(),
        a.out.join("result.json").display(),
        a.out.join("bode.svg").display()
    );
    Ok(())
}
