//! `flexid sweep`: one measurement on one axis over CAN, from bring-up to the identified
//! chain (EtherCAT: `sweep_ethercat`, chosen by the command's dispatch in `cli`). The logic is in [`crate::sweep`]; this is argument handling, the bus and files.

use super::excite::{generate, ExciteArgs, ExciteKind, MultisineArgs};
use super::{CliError, ModelArgs};
use crate::plant::PlantFile;
use crate::recording::{write_recording, DriveInfo};
use crate::sweep::{
    admission_check, realtime_setup, run_sweep, run_sweep_on_cycle_thread, Pacing, Progress,
    SimulatedPlant, SweepOutcome, SweepPlan,
};
use flexid_can::{CanBus, UdpMulticastBus};
use flexid_canopen::{bring_up, CyclicDrive, Identity, MasterConfig, Profile, ProfileSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

pub use super::sweep_args::{ClockArg, ExcitationArg, SweepArgs};

/// Set by SIGINT/SIGTERM during a sweep.
pub(super) static STOP: AtomicBool = AtomicBool::new(false);

#[cfg(unix)]
extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

pub(super) fn install_signal_handlers() {
    STOP.store(false, Ordering::Relaxed);
    #[cfg(unix)]
    // SAFETY: the handler only stores to an atomic (async-signal-safe).
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
}

/// Back to the default SIGINT/SIGTERM behaviour once the drive is off (Ctrl-C during
/// the identification ends the program).
pub(super) fn restore_signal_handlers() {
    #[cfg(unix)]
    // SAFETY: resetting to the default disposition.
    unsafe {
        libc::signal(libc::SIGINT, libc::SIG_DFL);
        libc::signal(libc::SIGTERM, libc::SIG_DFL);
    }
}

pub use flexid_can::BusSpec;

fn pacing(c: ClockArg) -> Pacing {
    match c {
        ClockArg::Realtime => Pacing::Realtime,
        ClockArg::Lockstep => Pacing::Lockstep,
    }
}

/// Checks the arguments and plans the sweep: the excitation exactly as `flexid excite`
/// designs and describes it, the limits from the flags. Exit code 2 on bad arguments.
pub fn plan(a: &SweepArgs) -> Result<SweepPlan, CliError> {
    let fs = a.cycle_hz;
    if !(fs.is_finite() && fs > 0.0) {
        return Err(CliError::input(format!(
            "--cycle-hz {fs}: must be a positive rate"
        )));
    }
    if !(a.resolution_hz.is_finite() && a.resolution_hz > 0.0 && a.resolution_hz < fs / 4.0) {
        return Err(CliError::input(format!(
            "--resolution-hz {}: must be positive and below a quarter of the cycle rate",
            a.resolution_hz
        )));
    }
    if a.periods == 0 {
        return Err(CliError::input("--periods must be at least 1"));
    }
    if !(a.peak_nm.is_finite() && a.peak_nm > 0.0) {
        return Err(CliError::input(format!(
            "--peak-nm {}: must be positive",
            a.peak_nm
        )));
    }
    if !(a.max_speed_rad_s.is_finite() && a.max_speed_rad_s > 0.0) {
        return Err(CliError::input("--max-speed-rad-s must be positive"));
    }
    let band = match &a.band {
        None => [a.resolution_hz, 0.4 * fs],
        Some(b) if b.len() == 2 && b[0] > 0.0 && b[1] > b[0] && b[1] < fs / 2.0 => [b[0], b[1]],
        Some(b) => {
            return Err(CliError::input(format!(
                "--band {b:?}: need 0 < LO_HZ < HI_HZ < cycle rate / 2"
            )))
        }
    };
    let kind = match a.excitation {
        ExcitationArg::Multisine => ExciteKind::Multisine(MultisineArgs {
            period_samples: (fs / a.resolution_hz).round() as usize,
            band: band.to_vec(),
            phases: "schroeder".into(),
            group: 4,
            seed: 1,
            amplitude_exponent: a.amplitude_exponent,
            crest_iterations: 30,
            periods: a.periods,
            transient_periods: a.transient_periods,
        }),
        ExcitationArg::Chirp => ExciteKind::Chirp(super::excite::ChirpArgs {
            f0: band[0],
            f1: band[1],
            duration_s: (a.periods + a.transient_periods) as f64 / a.resolution_hz,
            taper_s: 0.0,
        }),
    };
    let ex = generate(&ExciteArgs {
        kind,
        out: None,
        fs,
        peak_nm: a.peak_nm,
        rms_nm: a.rms_nm,
    })?;
    let mut p = SweepPlan::new(fs, ex.torque_nm, ex.info, pacing(a.clock));
    p.max_speed_rad_s = a.max_speed_rad_s;
    if let Some(d) = a.max_duration_s {
        if !(d.is_finite() && d > 0.0) {
            return Err(CliError::input(format!(
                "--max-duration-s {d}: must be positive"
            )));
        }
        p.max_duration = Some(Duration::try_from_secs_f64(d).map_err(|_| {
            CliError::input(format!(
                "--max-duration-s {d}: too large for a duration (at most about 1.8e19 s)"
            ))
        })?);
    }
    if let Some(n) = a.max_lost {
        p.max_lost_tpdos = n;
    }
    Ok(p)
}

/// The built-in firmware profiles and those of `--profiles DIR`.
pub(super) fn profiles(a: &SweepArgs) -> Result<ProfileSet, CliError> {
    let mut profiles = ProfileSet::builtin();
    if let Some(dir) = &a.profiles {
        profiles
            .load_dir(dir)
            .map_err(|e| CliError::input(e.to_string()))?;
    }
    Ok(profiles)
}

/// The admission check as the command reports it (exit code 2 when refused).
pub fn admit(cycle_hz: f64, bitrate: u32) -> Result<f64, CliError> {
    admission_check(cycle_hz, bitrate)
        .map_err(|e| CliError::input(format!("refused before touching the bus: {e}")))
}

pub(super) fn progress_line(p: &Progress) {
    let c = p.counters;
    if p.periods_total > 0 {
        eprint!(
            "flexid sweep: period {}/{}",
            p.periods_done, p.periods_total
        );
    } else {
        eprint!("flexid sweep: cycle {}/{}", p.cycle, p.total);
    }
    eprintln!(
        ", {:.2} s, {:.0} cycles/s; feedback missed {} (late {}, lost {}), clamped {}",
        p.elapsed.as_secs_f64(),
        p.cycle as f64 / p.elapsed.as_secs_f64().max(1e-9),
        c.missed,
        c.late,
        c.lost,
        c.saturated
    );
}

/// What `sweep` produced (for the demo).
pub struct SweepRun {
    /// The measurement.
    pub outcome: SweepOutcome,
    /// Where the recording was written.
    pub recording_path: PathBuf,
    /// The identification (complete sweeps only).
    pub analysis: Option<crate::analysis::Analysis>,
}

/// Brings the drive up on `bus`, runs the plan, disables the drive and saves the
/// recording. Returns the outcome whatever happened after enable; errors before
/// (bring-up, enable) are returned as errors.
fn measure<B: CanBus>(
    bus: B,
    a: &SweepArgs,
    plan: &SweepPlan,
    bus_name: &str,
    profiles: &ProfileSet,
) -> Result<(SweepOutcome, DriveInfo), CliError> {
    let cfg = MasterConfig {
        node: a.node,
        cycle_period: plan.period(),
        bitrate: a.bitrate,
        ..MasterConfig::for_node(a.node)
    };
    eprintln!(
        "flexid sweep: bringing up node {} on {bus_name} ({} Hz cycle) ...",
        a.node, a.cycle_hz
    );
    let drive = bring_up(bus, cfg, profiles)
        .map_err(|e| CliError::failed(format!("bring-up failed: {e}")))?;
    let info = drive_info(
        a,
        plan,
        bus_name,
        drive.identity(),
        drive.profile(),
        drive.scaling().rated_torque_nm,
    );
    let mut drive = drive
        .enable()
        .map_err(|e| CliError::failed(format!("enable failed: {e}")))?;
    let outcome = run_paced(&mut drive, plan);
    if let Some(e) = &outcome.ramp_error {
        eprintln!("flexid sweep: ramp to zero torque interrupted: {e}");
    }
    match drive.disable() {
        Ok(_) => eprintln!("flexid sweep: drive disabled"),
        Err(e) => eprintln!("flexid sweep: disabling the drive failed (best effort): {e}"),
    }
    Ok((outcome, info))
}

/// The recording's drive description of a drive brought up with `profile` (printed).
pub(super) fn drive_info(
    a: &SweepArgs,
    plan: &SweepPlan,
    bus_name: &str,
    id: &Identity,
    profile: &Profile,
    rated_torque_nm: f64,
) -> DriveInfo {
    let info = DriveInfo {
        bus: bus_name.to_string(),
        node: a.node,
        device_type: id.device_type,
        vendor_id: id.vendor_id,
        product_code: id.product_code,
        revision: id.revision,
        serial: id.serial,
        profile: format!("{} ({})", profile.name, profile.source),
        rated_torque_nm,
        cycle_hz: a.cycle_hz,
        clock: plan.pacing.name().into(),
    };
    eprintln!(
        "flexid sweep: node {} vendor {:#010x} product {:#x} rev {:#x}, profile {}, rated torque {} N m",
        a.node, id.vendor_id, id.product_code, id.revision, info.profile, info.rated_torque_nm
    );
    info
}

/// Runs `plan` on the enabled `drive` as it is paced: real time on a cycle thread of its
/// own, lock-step on this one.
pub(super) fn run_paced<D: CyclicDrive + Send>(drive: &mut D, plan: &SweepPlan) -> SweepOutcome {
    match plan.pacing {
        // absolute deadlines on a cycle thread of its own, SCHED_FIFO when permitted (a
        // drive simulated on the same host must answer at real-time priority too:
        // flexid-vdrive --fifo-priority; at normal priority it answers late whenever the
        // host is busy, and the sweep counts those TPDOs late or lost)
        Pacing::Realtime => {
            run_sweep_on_cycle_thread(drive, plan, &STOP, &mut progress_line, realtime_setup()).0
        }
        Pacing::Lockstep => run_sweep(drive, plan, &STOP, &mut progress_line),
    }
}

/// Saves the outcome's recording (with `info`) into `out`; prints how it ended.
fn save(outcome: &mut SweepOutcome, info: DriveInfo, out: &Path) -> Result<PathBuf, CliError> {
    outcome.recording.sidecar.drive = Some(info);
    std::fs::create_dir_all(out)
        .map_err(|e| CliError::failed(format!("{}: {e}", out.display())))?;
    let path = out.join("recording.csv");
    write_recording(&path, &outcome.recording).map_err(CliError::write_recording)?;
    let c = outcome.counters;
    eprintln!(
        "flexid sweep: {} rows in {:.2} s ({:.0} cycles/s), feedback missed {} (late {}, lost {}), clamped {}, master overruns {}; wrote {}",
        outcome.recording.len(),
        outcome.elapsed.as_secs_f64(),
        outcome.cycles_per_s(),
        c.missed,
        c.late,
        c.lost,
        c.saturated,
        outcome.overruns,
        path.display()
    );
    Ok(path)
}

/// The measurement and identification; `identify` false stops after saving.
pub fn sweep_run(a: &SweepArgs) -> Result<SweepRun, CliError> {
    let spec = BusSpec::parse(&a.bus).map_err(CliError::input)?;
    if !(1..=127).contains(&a.node) {
        return Err(CliError::input(format!(
            "--node {}: must be 1..=127",
            a.node
        )));
    }
    if let Some(m) = a.masses {
        if m == 0 {
            return Err(CliError::input("--masses must be at least 1"));
        }
    }
    let load = admit(a.cycle_hz, a.bitrate)?;
    let plan = plan(a)?;
    let profiles = profiles(a)?;
    print_plan(a, &plan, Some(load));
    install_signal_handlers();
    let name = spec.describe();
    let measured = match &spec {
        BusSpec::Udp(cfg) => UdpMulticastBus::open(cfg.clone())
            .map_err(|e| CliError::failed(format!("{name}: {e}")))
            .and_then(|bus| measure(bus, a, &plan, &name, &profiles)),
        #[cfg(target_os = "linux")]
        BusSpec::SocketCan(iface) => flexid_can::SocketCanBus::open(iface)
            .map_err(|e| CliError::failed(format!("{name}: {e}")))
            .and_then(|bus| measure(bus, a, &plan, &name, &profiles)),
        #[cfg(not(target_os = "linux"))]
        BusSpec::SocketCan(_) => Err(CliError::input("SocketCAN is Linux only")),
    };
    restore_signal_handlers();
    let (outcome, drive_info) = measured?;
    save_and_identify(outcome, drive_info, a)
}

/// The sweep of `a` on the CAN-free simulated drive in front of `plant` (noise seed
/// `seed`), in-process: the same loop, files and identification as over the bus, without
/// CANopen (the demo where no bus can be used).
pub fn sweep_run_simulated(
    a: &SweepArgs,
    plant: &PlantFile,
    seed: u64,
) -> Result<SweepRun, CliError> {
    if a.masses == Some(0) {
        return Err(CliError::input("--masses must be at least 1"));
    }
    let plan = plan(a)?;
    print_plan(a, &plan, None);
    let mut drive = SimulatedPlant::of_file(plant)
        .drive(a.cycle_hz, seed)
        .map_err(|e| CliError::failed(format!("simulated plant: {e}")))?;
    let info = DriveInfo {
        bus: "simulated".into(),
        node: a.node,
        profile: "simulated drive (in-process, no CANopen)".into(),
        rated_torque_nm: flexid_canopen::CyclicDrive::rated_torque_nm(&drive),
        cycle_hz: a.cycle_hz,
        clock: plan.pacing.name().into(),
        ..DriveInfo::default()
    };
    install_signal_handlers();
    let outcome = run_sweep(&mut drive, &plan, &STOP, &mut progress_line);
    restore_signal_handlers();
    save_and_identify(outcome, info, a)
}

/// The sweep's one-line summary on stderr: excitation, periods, rate, peak torque, and
/// the bus load where there is a bus.
fn print_plan(a: &SweepArgs, plan: &SweepPlan, bus_load: Option<f64>) {
    let bus = match bus_load {
        Some(load) => format!("bus load {:.1} % at {} bit/s", 100.0 * load, a.bitrate),
        None => "no bus (simulated drive in-process)".into(),
    };
    print_plan_on(a, plan, &bus);
}

/// [`print_plan`] with the bus described by `bus`.
pub(super) fn print_plan_on(a: &SweepArgs, plan: &SweepPlan, bus: &str) {
    let info = &plan.excitation;
    eprintln!(
        "flexid sweep: {:?} {} lines {:.3}-{:.1} Hz, {} + {} periods of {} cycles at {} Hz ({:.1} s), peak {:.3} N m; {bus}; clock {}",
        info.kind,
        info.excited_lines.len(),
        info.band_hz.map_or(0.0, |b| b[0]),
        info.band_hz.map_or(0.0, |b| b[1]),
        info.transient_periods,
        info.periods,
        info.period_samples,
        a.cycle_hz,
        plan.duration_s(),
        crate::excitation::peak_abs(&plan.torque_nm),
        plan.pacing.name()
    );
}

/// Saves the recording into `a.out` and, when the sweep completed, identifies it.
pub(super) fn save_and_identify(
    mut outcome: SweepOutcome,
    drive_info: DriveInfo,
    a: &SweepArgs,
) -> Result<SweepRun, CliError> {
    let recording_path = save(&mut outcome, drive_info, &a.out)?;
    if !outcome.complete() {
        return Err(CliError::failed(format!(
            "sweep stopped at cycle {}: {}; the {} rows measured are saved in {} (not identified)",
            outcome.end.cycle,
            outcome.end.reason,
            outcome.recording.len(),
            recording_path.display()
        )));
    }
    let analysis = identify_outcome(&outcome, &recording_path, a.masses, &a.out)?;
    Ok(SweepRun {
        outcome,
        recording_path,
        analysis: Some(analysis),
    })
}

/// The identification of `flexid identify` on a complete sweep: prints the table, writes
/// `result.json` and `bode.svg` into `out`.
pub fn identify_outcome(
    outcome: &SweepOutcome,
    recording_path: &Path,
    masses: Option<usize>,
    out: &Path,
) -> Result<crate::analysis::Analysis, CliError> {
    let opts = super::results::options(&ModelArgs {
        masses,
        band: None,
        starts: 20,
        seed: 1,
        max_seconds: super::DEFAULT_MAX_SECONDS,
    })?;
    let t = Instant::now();
    let an = super::results::run_analysis(&outcome.recording, &opts)?;
    let title = recording_path.display().to_string();
    print!("{}", crate::report::render_report(&an, &title));
    let json = out.join("result.json");
    let svg = out.join("bode.svg");
    super::results::write_json(&an, &json)?;
    super::results::write_svg(&an, &title, &svg)?;
    eprintln!(
        "flexid sweep: identified in {:.1} s; wrote {} and {}",
        t.elapsed().as_secs_f64(),
        json.display(),
        svg.display()
    );
    Ok(an)
}

/// `flexid sweep`.
pub fn sweep(a: &SweepArgs) -> Result<(), CliError> {
    if let Some(url) = &a.daemon.daemon {
        return super::daemon_client::sweep_via_daemon(a, url);
    }
    sweep_run(a).map(|_| ())
}
