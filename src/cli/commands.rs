//! The commands behind `flexid identify | bode | simulate | demo | import`.

use super::excite::read_excitation;
use super::plant::PlantFile;
use super::results::{
    check_band_nyquist, check_excited, load, options, run_analysis, write_json, write_svg,
};
use super::{BodeArgs, CliError, IdentifyArgs, ImportArgs, SimulateArgs};
use crate::recording::{write_recording, MotionSignal, Recording};
use crate::report::render_report;
use std::path::Path;

/// `flexid identify`.
pub fn identify(a: &IdentifyArgs) -> Result<(), CliError> {
    let opts = options(&a.model)?;
    let rec = load(&a.recording)?;
    check_band_nyquist(opts.band_hz, &rec, &a.recording)?;
    check_excited(&rec, &a.recording)?;
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
    let opts = options(&a.model)?;
    let rec = load(&a.recording)?;
    check_band_nyquist(opts.band_hz, &rec, &a.recording)?;
    check_excited(&rec, &a.recording)?;
    let an = if a.no_model {
        // the measurement alone: nothing identified, so nothing for an identification to
        // refuse (a record with too few usable lines is still drawn)
        crate::analysis::measure_only(&rec, &opts).map_err(|e| CliError::failed(e.to_string()))?
    } else {
        run_analysis(&rec, &opts)?
    };
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
    let plant = flexid_files::plant::load_plant_file(a.plant.as_deref())
        .map_err(|e| CliError::input(e.to_string()))?;
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
    write_recording(&a.out, &rec).map_err(CliError::write_recording)?;
    println!("wrote {} ({} samples)", a.out.display(), rec.len());
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
    write_recording(&out, &rec).map_err(CliError::write_recording)?;
    println!(
        "wrote {} ({} samples at {} Hz)",
        out.display(),
        rec.len(),
        rec.sample_rate_hz
    );
    Ok(())
}
