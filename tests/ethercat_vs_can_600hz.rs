//! The 600 Hz side by side (issue 18, done-when): the SCARA axis of Gannel & Gannel (2024),
//! AR1 2.9 Hz / R1 5 Hz and AR2 380 Hz / R2 590 Hz (`plants/scara_600hz.toml`), measured
//! with the same sweep (`flexid sweep`'s multisine design: lines every AR1 / 12, band up to
//! 1 kHz or 0.4 x the cycle rate, 2 N m peak, 1 N m RMS, amplitude rising with frequency,
//! 8 + 1 periods) through three paths, all lock-step (one exchange per drive cycle):
//!
//! * EtherCAT at 4 kHz: `EcatDrive` on the emulated servo (in process);
//! * CAN at 1 Mbit/s, one axis on the bus: the CANopen master and `flexid-vdrive` on the
//!   in-process bus with its wire timing (`Paced`, one bus clock), at the highest rate the
//!   project's admission rule (70 % bus load, `flexid_canopen::pdo::max_cycle_rate_hz`)
//!   allows for one axis, rounded down to a whole-microsecond SYNC period;
//! * CAN at 1 Mbit/s at the rate the same rule allows for the SCARA's 4 axes on one bus
//!   (4 x RPDO1 + TPDO1 + TPDO2, one SYNC, 5 heartbeats); the sweep drives one of them (the
//!   other axes' frames would take wire time, not change the data of a lock-step sweep).
//!
//! It checks the plant file against the paper's figures (closed-form derivation, spectra
//! by the core's model), identifies each recording with the project's analysis (order
//! chosen automatically), prints the table, asserts EtherCAT within 3 % of the plant file
//! and what CAN really gives, and draws both measured Bode plots and both models of the
//! 4-axis comparison into one SVG (`target/.../ethercat-vs-can-600hz.svg`; into
//! `docs/ethercat-vs-can-600hz.svg` with `FLEXID_DOCS_PICTURES=1`, as
//! `scripts/docs-pictures.sh` runs it).

use flexid::analysis::{analyze, Analysis, AnalysisOptions};
use flexid::cli::sweep::{plan, ClockArg, ExcitationArg, SweepArgs};
use flexid::model::Chain;
use flexid::plant::PlantFile;
use flexid::plot::BodePlot;
use flexid::sweep::{run_sweep, StopReason, SweepOutcome, SweepPlan};
use flexid_can::timing::{BusClock, Paced};
use flexid_can::InprocBus;
use flexid_canopen::pdo::{default_mapping, max_cycle_rate_hz, ProcessDataMapping};
use flexid_canopen::profile::ObjectMap;
use flexid_canopen::{bring_up, CyclicDrive, MasterConfig, ProfileSet};
use flexid_ecat::emulated::servo_line;
use flexid_ecat::{with_drive, EcatConfig, Link};
use flexid_vdrive::{linear_drive, ClockMode, DrivePlant, Runner};
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

const PLANT: &str = include_str!("../plants/scara_600hz.toml");
/// The paper's figures: total inertia, anti-resonances, resonances.
const J_TOTAL_KGM2: f64 = 25.9e-3;
const AR_HZ: [f64; 2] = [2.9, 380.0];
const R_HZ: [f64; 2] = [5.0, 590.0];
const ECAT_HZ: f64 = 4000.0;
const BITRATE: u32 = 1_000_000;
/// The project's admissible bus load (`MasterConfig::max_bus_load`).
fn max_load() -> f64 {
    MasterConfig::default().max_bus_load
}

fn plant() -> PlantFile {
    PlantFile::parse(PLANT, "plants/scara_600hz.toml").expect("plant file")
}

/// The 3-mass chain with total inertia `j` and these spectra, in closed form (see the
/// plant file's header).
fn derive_chain(j: f64, ar_hz: [f64; 2], r_hz: [f64; 2]) -> [f64; 5] {
    let w2 = |f: f64| (TAU * f).powi(2);
    let (pa, sa) = (w2(ar_hz[0]) * w2(ar_hz[1]), w2(ar_hz[0]) + w2(ar_hz[1]));
    let (pr, sr) = (w2(r_hz[0]) * w2(r_hz[1]), w2(r_hz[0]) + w2(r_hz[1]));
    let j1 = j * pa / pr;
    let c1 = j1 * (sr - sa);
    let j2 = c1 / (sa - pa * (j - j1) / c1);
    let j3 = j - j1 - j2;
    let c2 = pa * j2 * j3 / c1;
    [j1, j2, j3, c1, c2]
}

/// `flexid sweep`'s design at `cycle_hz`: lines every AR1 / 12, band up to 1 kHz or
/// 0.4 x the rate, lock-step.
fn sweep_plan(cycle_hz: f64) -> SweepPlan {
    let df = AR_HZ[0] / 12.0;
    let args = SweepArgs {
        bus: String::new(),
        node: 5,
        cycle_hz,
        bitrate: BITRATE,
        clock: ClockArg::Lockstep,
        excitation: ExcitationArg::Multisine,
        band: Some(vec![df, (0.4 * cycle_hz).min(1000.0)]),
        peak_nm: 2.0,
        rms_nm: Some(1.0),
        resolution_hz: df,
        periods: 8,
        transient_periods: 1,
        amplitude_exponent: 1.0,
        max_duration_s: None,
        max_speed_rad_s: 300.0,
        max_lost: None,
        profiles: None,
        generic_profile: false,
        out: PathBuf::new(),
        masses: None,
        daemon: Default::default(),
    };
    plan(&args).expect("plan")
}

/// The highest rate the admission rule allows for `axes` drives of the default mapping on
/// one 1 Mbit/s bus, rounded down to a whole-microsecond SYNC period.
fn can_rate_hz(axes: usize) -> (f64, f64) {
    let one = default_mapping(&ObjectMap::default());
    let mapping = ProcessDataMapping {
        pdos: (0..axes).flat_map(|_| one.pdos.iter().cloned()).collect(),
    };
    let c = MasterConfig::default();
    let mut heartbeats = vec![c.heartbeat_period];
    heartbeats.extend((0..axes).map(|_| c.drive_heartbeat_period));
    let limit = max_cycle_rate_hz(&mapping, &heartbeats, BITRATE, max_load());
    let period_us = (1e6 / limit).ceil();
    (limit, 1e6 / period_us)
}

fn run<D: CyclicDrive>(drive: &mut D, plan: &SweepPlan) -> SweepOutcome {
    let stop = AtomicBool::new(false);
    let outcome = run_sweep(drive, plan, &stop, &mut |_| {});
    assert_eq!(outcome.reason, StopReason::Complete, "{:?}", outcome.reason);
    outcome
}

/// The sweep over EtherCAT at 4 kHz on the emulated servo.
fn ethercat_sweep(plan: &SweepPlan) -> SweepOutcome {
    let line = servo_line(&plant(), 1, ECAT_HZ).expect("emulated line");
    with_drive(
        Link::Emulated(line),
        EcatConfig::at_hz(ECAT_HZ),
        &ProfileSet::builtin(),
        |mut d| {
            let o = run(&mut d, plan);
            d.disable().expect("disable");
            o
        },
    )
    .expect("EtherCAT session")
}

/// The sweep over CAN at 1 Mbit/s with wire timing: the master and `flexid-vdrive` on
/// one in-process bus, both paced on one bus clock.
fn can_sweep(plan: &SweepPlan, name: &str) -> SweepOutcome {
    let dp = DrivePlant::parse(PLANT, "plants/scara_600hz.toml").expect("drive plant");
    let vdrive = linear_drive(&dp, ClockMode::LockStep).expect("vdrive");
    let bus = InprocBus::new(name);
    let clock = BusClock::new();
    let slave_bus = Paced::with_clock(bus.handle(), BITRATE, clock.clone());
    let master_bus = Paced::with_clock(bus, BITRATE, clock);
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let slave = std::thread::spawn(move || Runner::new(slave_bus, vdrive).run(&s2));
    let cfg = MasterConfig {
        cycle_period: plan.period(),
        bitrate: BITRATE,
        ..MasterConfig::for_node(5)
    };
    let drive = bring_up(master_bus, cfg, &ProfileSet::builtin()).expect("bring-up");
    let mut drive = drive.enable().expect("enable");
    let o = run(&mut drive, plan);
    let _ = drive.disable();
    stop.store(true, Ordering::Relaxed);
    slave.join().expect("slave").expect("vdrive ran");
    o
}

/// One measured path: its name, rate, wall time and identification.
struct Path3 {
    name: String,
    cycle_hz: f64,
    band_hi_hz: f64,
    seconds: f64,
    analysis: Analysis,
}

impl Path3 {
    fn chain(&self) -> Option<Chain> {
        self.analysis.model.as_ref().map(|m| Chain {
            inertia_kgm2: m.inertia_kgm2.clone(),
            stiffness_nm_per_rad: m.stiffness_nm_per_rad.clone(),
            damping_nms_per_rad: m.damping_nms_per_rad.clone(),
        })
    }

    /// The identified resonance nearest 590 Hz, if any.
    fn r2_hz(&self) -> Option<f64> {
        let m = self.analysis.model.as_ref()?;
        m.resonance_hz
            .iter()
            .copied()
            .min_by(|a, b| (a - R_HZ[1]).abs().total_cmp(&(b - R_HZ[1]).abs()))
    }

    /// The largest relative error of the identified J and c against `want` (same
    /// number of bodies), else `None`.
    fn worst_error(&self, want: &Chain) -> Option<f64> {
        let got = self.chain()?;
        if got.inertia_kgm2.len() != want.inertia_kgm2.len() {
            return None;
        }
        let pairs = got.inertia_kgm2.iter().zip(&want.inertia_kgm2).chain(
            got.stiffness_nm_per_rad
                .iter()
                .zip(&want.stiffness_nm_per_rad),
        );
        Some(pairs.map(|(g, w)| ((g - w) / w).abs()).fold(0.0, f64::max))
    }

    fn row(&self, want: &Chain) -> String {
        let m = self.analysis.model.as_ref();
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.1}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "| {} | {:.1} | {:.1} | {:.0} | {} | {} | {} | {} | {:.1} |",
            self.name,
            self.cycle_hz,
            self.cycle_hz / 2.0,
            self.band_hi_hz,
            m.map_or(0, |m| m.masses),
            m.map_or(String::new(), |m| list(&m.antiresonance_hz)),
            m.map_or(String::new(), |m| list(&m.resonance_hz)),
            self.worst_error(want)
                .map_or("not a 3-mass chain".into(), |e| format!(
                    "{:.2} %",
                    100.0 * e
                )),
            self.seconds
        )
    }
}

fn measure(name: String, cycle_hz: f64, sweep: impl FnOnce(&SweepPlan) -> SweepOutcome) -> Path3 {
    let plan = sweep_plan(cycle_hz);
    let band_hi_hz = plan.excitation.band_hz.map_or(0.0, |b| b[1]);
    let t0 = Instant::now();
    let outcome = sweep(&plan);
    let seconds = t0.elapsed().as_secs_f64();
    let analysis = analyze(&outcome.recording, &AnalysisOptions::default()).expect("analysis");
    Path3 {
        name,
        cycle_hz,
        band_hi_hz,
        seconds,
        analysis,
    }
}

#[test]
fn ethercat_at_4_khz_resolves_the_590_hz_pair_that_can_for_4_axes_cannot() {
    // The plant file is the paper's axis.
    let p = plant();
    let derived = derive_chain(J_TOTAL_KGM2, AR_HZ, R_HZ);
    let file = [
        p.chain.inertia_kgm2[0],
        p.chain.inertia_kgm2[1],
        p.chain.inertia_kgm2[2],
        p.chain.stiffness_nm_per_rad[0],
        p.chain.stiffness_nm_per_rad[1],
    ];
    for (d, f) in derived.iter().zip(file) {
        assert!(((f - d) / d).abs() < 1e-4, "file {f}, derived {d}");
    }
    for (got, want) in [
        (p.chain.antiresonances_hz(), AR_HZ),
        (p.chain.resonances_hz(), R_HZ),
    ] {
        for (g, w) in got.iter().zip(want) {
            assert!(
                ((g - w) / w).abs() < 0.005,
                "spectrum {got:?}, paper {want:?}"
            );
        }
    }
    let total: f64 = p.chain.inertia_kgm2.iter().sum();
    assert!((total - J_TOTAL_KGM2).abs() < 1e-7);

    // The rates: EtherCAT 4 kHz; CAN's admission limits for 1 and 4 axes.
    assert!(
        flexid::sweep::admission_check(ECAT_HZ, BITRATE).is_err(),
        "4 kHz over CAN at 1 Mbit/s is refused by the admission rule"
    );
    let (limit1, can1_hz) = can_rate_hz(1);
    let (limit4, can4_hz) = can_rate_hz(4);
    eprintln!(
        "CAN admission at 1 Mbit/s, {:.0} % load: 1 axis {limit1:.1} Hz (run at {can1_hz:.1} \
         Hz), 4 axes {limit4:.1} Hz (run at {can4_hz:.1} Hz)",
        100.0 * max_load()
    );
    assert!(flexid::sweep::admission_check(can1_hz, BITRATE).is_ok());

    let ecat = measure(
        format!("EtherCAT, {ECAT_HZ:.0} Hz (emulated servo)"),
        ECAT_HZ,
        ethercat_sweep,
    );
    let can1 = measure("CAN 1 Mbit/s, 1 axis on the bus".into(), can1_hz, |plan| {
        can_sweep(plan, "can-1-axis")
    });
    let can4 = measure("CAN 1 Mbit/s, 4 axes on the bus".into(), can4_hz, |plan| {
        can_sweep(plan, "can-4-axes")
    });

    let want = &p.chain;
    let mut table = String::from(
        "| path | cycle (Hz) | Nyquist (Hz) | band up to (Hz) | masses | AR (Hz) | R (Hz) | \
         worst J, c error | sweep wall time (s) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for path in [&ecat, &can1, &can4] {
        table.push_str(&path.row(want));
        table.push('\n');
    }
    eprintln!("plant: AR 2.9, 380 Hz; R 5, 590 Hz\n{table}");

    // EtherCAT at 4 kHz: the whole chain within 3 %.
    let e = ecat.worst_error(want).expect("EtherCAT: a 3-mass chain");
    assert!(e < 0.03, "EtherCAT worst error {e}");
    // CAN, 4 axes: 590 Hz is above Nyquist and no identified resonance is near it.
    assert!(can4.cycle_hz / 2.0 < R_HZ[1]);
    assert!(
        can4.worst_error(want).is_none(),
        "4-axis CAN: not the 3-mass chain"
    );
    assert!(
        can4.r2_hz()
            .is_none_or(|r| ((r - R_HZ[1]) / R_HZ[1]).abs() > 0.1),
        "4-axis CAN: R2 {:?}",
        can4.r2_hz()
    );
    // CAN, 1 axis alone on the bus: Nyquist (919 Hz) is above 590 Hz and the lock-step
    // sweep resolves the pair too (measured: every J and c within 0.05 %). What CAN cannot
    // do is the same for the robot's 4 axes on one bus, nor any rate near 4 kHz.
    assert!(can1.cycle_hz / 2.0 > R_HZ[1]);
    let e1 = can1.worst_error(want).expect("1-axis CAN: a 3-mass chain");
    assert!(e1 < 0.03, "1-axis CAN worst error {e1}");
    eprintln!(
        "1-axis CAN: R2 identified at {:?} Hz, worst J/c error {e1:.5}",
        can1.r2_hz()
    );

    // Both measured Bode plots and both models of the 4-axis comparison in one picture.
    let (Some(ecat_model), Some(can4_model)) = (&ecat.analysis.model_frf, &can4.analysis.model_frf)
    else {
        panic!("models to draw");
    };
    let ecat_label = format!(
        "EtherCAT {ECAT_HZ:.0} Hz: {}-mass model",
        ecat.analysis.model.as_ref().map_or(0, |m| m.masses)
    );
    let can_label = format!(
        "CAN {:.0} Hz: {}-mass model",
        can4.cycle_hz,
        can4.analysis.model.as_ref().map_or(0, |m| m.masses)
    );
    let can_measured = format!("CAN {:.0} Hz: measured", can4.cycle_hz);
    let svg = BodePlot::new(&ecat.analysis.measured.frf)
        .model(ecat_model, ecat_label)
        .model(&can4.analysis.measured.frf, can_measured)
        .model(can4_model, can_label)
        .anti_resonances(&AR_HZ)
        .resonances(&R_HZ)
        .title("SCARA axis (AR/R 2.9/5 Hz, 380/590 Hz): EtherCAT 4 kHz against CAN 1 Mbit/s")
        .subtitle(format!(
            "measured: over EtherCAT at {ECAT_HZ:.0} Hz; CAN: 4 axes on one 1 Mbit/s bus at \
             the admission limit, band up to 0.4 x the rate (Nyquist {:.0} Hz); markers: the \
             plant file",
            can4.cycle_hz / 2.0
        ))
        .size(1300, 850)
        .render_svg()
        .expect("svg");
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ethercat-vs-can-600hz.svg");
    std::fs::write(&out, &svg).expect("write svg");
    eprintln!("wrote {}", out.display());
    if std::env::var_os("FLEXID_DOCS_PICTURES").is_some() {
        let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/ethercat-vs-can-600hz.svg");
        std::fs::write(&docs, &svg).expect("write docs svg");
        eprintln!("wrote {}", docs.display());
    }
}
