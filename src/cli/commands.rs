//! The commands behind `flexid identify | bode | simulate | demo | import`.

use super::excite::{read_excitation, write_excitation, Excitation};
use super::plant::PlantFile;
use super::{BodeArgs, CliError, DemoArgs, IdentifyArgs, ImportArgs, ModelArgs, SimulateArgs};
use crate::analysis::{analyze, to_json, Analysis, AnalysisOptions};
use crate::excitation::MultisineDesign;
use crate::identify::fit::{FitBudget, FitOptions};
use crate::plot::BodePlot;
use crate::recording::{
    read_recording, write_bytes_atomic, write_recording, MotionSignal, Recording,
};
use crate::report::render_report;
use std::path::Path;

pub(crate) fn options(m: &ModelArgs) -> Result<AnalysisOptions, CliError> {
    let band_hz = match &m.band {
        None => None,
        Some(b) if b.len() == 2 && b[0] >= 0.0 && b[1] > b[0] && b[1].is_finite() => {
            Some([b[0], b[1]])
        }
        Some(b) => return Err(CliError::input(format!("--band {b:?}: need LO_HZ < HI_HZ"))),
    };
    if m.starts == 0 {
        return Err(CliError::input("--starts must be at least 1"));
    }
    if !(m.max_seconds.is_finite() && m.max_seconds > 0.0) {
        return Err(CliError::input(format!(
            "--max-seconds {}: must be a positive number of seconds",
            m.max_seconds
        )));
    }
    Ok(AnalysisOptions {
        masses: m.masses,
        band_hz,
        fit: FitOptions {
            starts: m.starts,
            seed: m.seed,
            budget: FitBudget::with_cap_s(m.max_seconds),
            ..AnalysisOptions::default().fit
        },
        ..AnalysisOptions::default()
    })
}

fn load(path: &Path) -> Result<Recording, CliError> {
    read_recording(path).map_err(|e| CliError::input(e.to_string()))
}

pub(crate) fn run_analysis(rec: &Recording, opts: &AnalysisOptions) -> Result<Analysis, CliError> {
    eprintln!(
        "flexid: {} samples at {} Hz; estimating the FRF and identifying ({} starts per order) ...",
        rec.len(),
        rec.sample_rate_hz,
        opts.fit.starts
    );
    // the cap counts from here, not from parsing the arguments
    let mut opts = opts.clone();
    opts.fit.budget = opts.fit.budget.restarted();
    let budget = opts.fit.budget.clone();
    super::fit_progress::with_progress(&budget, "flexid identify", || analyze(rec, &opts))
        .map_err(|e| CliError::failed(e.to_string()))
}

fn bode_plot<'a>(a: &'a Analysis, title: &str) -> BodePlot<'a> {
    let mut plot = BodePlot::new(&a.measured.frf).title(title);
    if let Some(m) = &a.model_frf {
        let label = format!(
            "identified {}-mass chain",
            a.model.as_ref().map_or(0, |m| m.masses)
        );
        plot = plot.model(m, &label);
    }
    let (ar, r): (Vec<f64>, Vec<f64>) = match &a.model {
        Some(m) => (m.antiresonance_hz.clone(), m.resonance_hz.clone()),
        None => (
            a.detection
                .pairs
                .iter()
                .filter(|p| !p.ar_below_band)
                .map(|p| p.ar_hz)
                .collect(),
            a.detection
                .pairs
                .iter()
                .filter(|p| !p.r_above_band)
                .map(|p| p.r_hz)
                .collect(),
        ),
    };
    let lo = a.measured.frf.freq_hz.first().copied().unwrap_or(0.0);
    let hi = a
        .measured
        .frf
        .freq_hz
        .last()
        .copied()
        .unwrap_or(f64::INFINITY);
    let inside =
        |v: Vec<f64>| -> Vec<f64> { v.into_iter().filter(|f| *f >= lo && *f <= hi).collect() };
    plot = plot.anti_resonances(&inside(ar)).resonances(&inside(r));
    plot.subtitle(format!(
        "{} estimator, {} averages, band {:.3}-{:.1} Hz, fs {} Hz; shaded: +-2 sigma",
        a.measured.method, a.measured.averages, lo, hi, a.sample_rate_hz
    ))
}

pub(crate) fn write_svg(a: &Analysis, title: &str, out: &Path) -> Result<(), CliError> {
    bode_plot(a, title)
        .write_svg(out)
        .map_err(|e| CliError::failed(format!("{}: {e}", out.display())))
}

pub(crate) fn write_json(a: &Analysis, out: &Path) -> Result<(), CliError> {
    let text =
        serde_json::to_string_pretty(&to_json(a)).map_err(|e| CliError::failed(e.to_string()))?;
    write_bytes_atomic(out, text.as_bytes())
        .map_err(|e| CliError::failed(format!("{}: {e}", out.display())))
}

/// `flexid identify`.
pub fn identify(a: &IdentifyArgs) -> Result<(), CliError> {
    let opts = options(&a.model)?;
    let rec = load(&a.recording)?;
    let an = run_analysis(&rec, &opts)?;
    let title = a.recording.display().to_string();
    print!("{}", render_report(&an, &title));
    if let Some(j) = &a.json {
        write_json(&an, j)?;
        eprintln!("flexid: wrote {}", j.display());
    }
    if let Some(s) = &a.svg {
        write_svg(&an, &title, s)?;
        eprintln!("flexid: wrote {}", s.display());
    }
    Ok(())
}

/// `flexid bode`.
pub fn bode(a: &BodeArgs) -> Result<(), CliError> {
    let mut opts = options(&a.model)?;
    let rec = load(&a.recording)?;
    if a.no_model {
        opts.fit.starts = 1;
    }
    let mut an = run_analysis(&rec, &opts)?;
    if a.no_model {
        an.model = None;
        an.model_frf = None;
    }
    write_svg(&an, &a.recording.display().to_string(), &a.out)?;
    println!("wrote {}", a.out.display());
    Ok(())
}

fn simulate_to(
    plant: &PlantFile,
    torque: &[f64],
    sidecar: crate::recording::Sidecar,
    seed: u64,
) -> Result<Recording, CliError> {
    let mut sc = sidecar;
    sc.source = Some(format!(
        "simulated: {} (exact ZOH sampling{}{})",
        plant.name.as_deref().unwrap_or("plant file"),
        plant
            .spec()
            .effects
            .encoder_counts_per_rev
            .map(|c| format!(", {c}-count encoder"))
            .unwrap_or_default(),
        if plant.measurement.velocity_noise_rel > 0.0 {
            format!(
                ", {:.1} % velocity noise",
                100.0 * plant.measurement.velocity_noise_rel
            )
        } else {
            String::new()
        }
    ));
    if !plant.has_effects() {
        // purely linear plant: the exact ZOH path (bit-identical to earlier versions)
        return crate::sim::simulate_recording(&plant.chain, torque, &plant.sim_options(seed), sc)
            .map_err(|e| CliError::failed(format!("simulation: {e}")));
    }
    let position = crate::plant::simulate_file_positions(plant, torque, seed)
        .map_err(|e| CliError::failed(format!("simulation: {e}")))?;
    let fs = plant.measurement.sample_rate_hz;
    if let Some(src) = sc.source.as_mut() {
        *src = src.replacen(
            "exact ZOH sampling",
            &format!(
                "RK4 with {} sub-steps, with unmodelled effects",
                plant.substeps()
            ),
            1,
        );
    }
    sc.sample_rate_hz = Some(fs);
    sc.io_delay_samples = Some(plant.measurement.delay_samples);
    Ok(Recording {
        time_s: (0..torque.len()).map(|k| k as f64 / fs).collect(),
        torque_cmd_nm: torque.to_vec(),
        position_rad: Some(position),
        velocity_rad_s: None,
        acceleration_rad_s2: None,
        torque_actual_nm: None,
        sample_rate_hz: fs,
        sidecar: sc,
    })
}

/// `flexid simulate`.
pub fn simulate(a: &SimulateArgs) -> Result<(), CliError> {
    let plant =
        flexid_files::plant::load_plant_file(a.plant.as_deref()).map_err(CliError::input)?;
    let (torque, sidecar) = read_excitation(&a.excitation)?;
    if let Some(fs) = sidecar.sample_rate_hz {
        if (fs - plant.measurement.sample_rate_hz).abs() > 1e-9 * fs {
            return Err(CliError::input(format!(
                "the excitation is sampled at {fs} Hz but the plant is measured at {} Hz",
                plant.measurement.sample_rate_hz
            )));
        }
    }
    let rec = simulate_to(&plant, &torque, sidecar, a.seed)?;
    write_recording(&a.out, &rec).map_err(|e| CliError::failed(e.to_string()))?;
    println!("wrote {} ({} samples)", a.out.display(), rec.len());
    Ok(())
}

/// A multisine that resolves the plant: line spacing a twelfth of the lowest anti-resonance,
/// band up to 2.5 x the highest resonance (at most 0.4 fs).
fn demo_excitation(plant: &PlantFile) -> Result<Excitation, CliError> {
    let fs = plant.measurement.sample_rate_hz;
    let ar = plant.chain.antiresonances_hz();
    let r = plant.chain.resonances_hz();
    let df = ar.first().map_or(1.0, |f| f / 12.0);
    let period = ((fs / df).ceil() as usize).max(64);
    let df = fs / period as f64;
    let hi = r.last().map_or(0.4 * fs, |f| (2.5 * f).min(0.4 * fs));
    let mut d = MultisineDesign::new(fs, period, [df, hi], 2.0, 1.0);
    d.crest_iterations = 30;
    // amplitude rising with frequency: the mobility falls as 1/f, so the velocity (and the
    // signal-to-quantisation ratio of the differenced encoder) stays level over the band
    d.amplitude = crate::excitation::AmplitudeShape::PowerLaw { exponent: 1.0 };
    let ms = d
        .generate()
        .map_err(|e| CliError::failed(format!("excitation: {e}")))?;
    Ok(Excitation {
        torque_nm: ms.repeat(9),
        info: ms.info(8, 1),
    })
}

/// `flexid demo` without a bus: the plant simulated in-process (`flexid::sim`: exact ZOH,
/// encoder quantisation, noise), measured and identified.
pub(crate) fn demo_simulated(a: &DemoArgs) -> Result<(), CliError> {
    let plant =
        flexid_files::plant::load_plant_file(a.plant.as_deref()).map_err(CliError::input)?;
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::failed(format!("{}: {e}", a.out.display())))?;
    let fs = plant.measurement.sample_rate_hz;
    let ex = demo_excitation(&plant)?;
    let exc_path = a.out.join("excitation.csv");
    write_excitation(&exc_path, fs, &ex)?;
    eprintln!(
        "flexid demo: {} — multisine {} lines {:.3}-{:.1} Hz, {} periods of {} samples at {} Hz ({:.1} s)",
        plant.name.as_deref().unwrap_or("plant"),
        ex.info.excited_lines.len(),
        ex.info.band_hz.map_or(0.0, |b| b[0]),
        ex.info.band_hz.map_or(0.0, |b| b[1]),
        ex.info.periods + ex.info.transient_periods,
        ex.info.period_samples,
        fs,
        ex.torque_nm.len() as f64 / fs
    );
    let sidecar = crate::recording::Sidecar {
        excitation: Some(ex.info.clone()),
        ..Default::default()
    };
    let rec = simulate_to(&plant, &ex.torque_nm, sidecar, a.seed)?;
    let rec_path = a.out.join("recording.csv");
    write_recording(&rec_path, &rec).map_err(|e| CliError::failed(e.to_string()))?;
    let an = run_analysis(&rec, &AnalysisOptions::default())?;
    print!("{}", render_report(&an, &rec_path.display().to_string()));
    super::demo::print_truth(&an, &plant);
    write_json(&an, &a.out.join("result.json"))?;
    write_svg(
        &an,
        "flexid demo: simulated SCARA shoulder",
        &a.out.join("bode.svg"),
    )?;
    println!(
        "\nwrote {}, {}, {} and {}",
        exc_path.display(),
        rec_path.display(),
        a.out.join("result.json").display(),
        a.out.join("bode.svg").display()
    );
    Ok(())
}

/// `flexid import`.
pub fn import(a: &ImportArgs) -> Result<(), CliError> {
    use crate::import::{import_file, preset, shared_data_dir, MatSpec, PRESET_NAMES};
    if a.list || a.source.is_none() {
        println!("presets (files under {}):", shared_data_dir().display());
        for name in PRESET_NAMES {
            if let Some((file, spec)) = preset(name) {
                println!(
                    "  {name:<28} {file}: {} -> {} ({:?})",
                    spec.input, spec.output, spec.output_kind
                );
            }
        }
        return Ok(());
    }
    let source = a.source.as_deref().unwrap_or_default();
    let rec = if let Some((file, spec)) = preset(source) {
        let path = shared_data_dir().join(file);
        import_file(&path, &spec).map_err(|e| CliError::input(e.to_string()))?
    } else {
        let (input, output) = match (&a.input, &a.output) {
            (Some(i), Some(o)) => (i.clone(), o.clone()),
            _ => {
                return Err(CliError::input(format!(
                    "{source}: not a preset; give --input and --output"
                )))
            }
        };
        let kind = match a.kind.as_str() {
            "position" => MotionSignal::Position,
            "velocity" => MotionSignal::Velocity,
            "acceleration" => MotionSignal::Acceleration,
            k => {
                return Err(CliError::input(format!(
                    "--kind {k}: expected position, velocity or acceleration"
                )))
            }
        };
        let mut spec = MatSpec::new(&input, &output, kind);
        spec.sample_rate_hz = a.fs;
        spec.period_samples = a.period_samples;
        spec.transient_periods = a.transient_periods;
        import_file(Path::new(source), &spec).map_err(|e| CliError::input(e.to_string()))?
    };
    let out = a.out.clone().unwrap_or_else(|| "recording.csv".into());
    write_recording(&out, &rec).map_err(|e| CliError::failed(e.to_string()))?;
    println!(
        "wrote {} ({} samples at {} Hz)",
        out.display(),
        rec.len(),
        rec.sample_rate_hz
    );
    Ok(())
}
