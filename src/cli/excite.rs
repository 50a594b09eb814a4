//! `flexid excite`: write an excitation signal and its description.

use super::CliError;
use crate::excitation::{
    AmplitudeShape, ChirpDesign, ExcitationInfo, MultisineDesign, PhaseDesign, SteppedSineDesign,
};
use crate::recording::{write_atomic, Sidecar};
use clap::{Args, Subcommand};
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct ExciteArgs {
    #[command(subcommand)]
    pub kind: ExciteKind,
    /// Output CSV (time_s,torque_cmd_nm); the description goes beside it as .json.
    #[arg(long, global = true)]
    pub out: Option<PathBuf>,
    /// Sample rate [Hz].
    #[arg(long, global = true, default_value_t = 2000.0)]
    pub fs: f64,
    /// Peak torque limit [N m].
    #[arg(long, global = true, default_value_t = 1.0)]
    pub peak_nm: f64,
    /// RMS torque limit [N m] (default: no tighter than the peak allows).
    #[arg(long, global = true)]
    pub rms_nm: Option<f64>,
}

#[derive(Debug, Subcommand)]
pub enum ExciteKind {
    /// Periodic multisine over a band.
    Multisine(MultisineArgs),
    /// Logarithmic swept sine.
    Chirp(ChirpArgs),
    /// Stepped sine at spot frequencies.
    Stepped(SteppedArgs),
}

#[derive(Debug, Args)]
pub struct MultisineArgs {
    /// Samples per period (sets the line spacing fs/N).
    #[arg(long, default_value_t = 8000)]
    pub period_samples: usize,
    /// Excited band [Hz].
    #[arg(long, num_args = 2, value_names = ["LO_HZ", "HI_HZ"], default_values_t = [0.5, 800.0])]
    pub band: Vec<f64>,
    /// Phase design: schroeder, random, odd-random (detection lines for nonlinear distortion).
    #[arg(long, default_value = "schroeder")]
    pub phases: String,
    /// Odd lines per group of which one is left out (odd-random).
    #[arg(long, default_value_t = 4)]
    pub group: usize,
    /// Seed of the random phases.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Amplitude grows as f^exponent over the band (0 = flat).
    #[arg(long, default_value_t = 0.0)]
    pub amplitude_exponent: f64,
    /// Crest-factor reduction iterations.
    #[arg(long, default_value_t = 30)]
    pub crest_iterations: usize,
    /// Steady periods to record.
    #[arg(long, default_value_t = 8)]
    pub periods: usize,
    /// Leading periods to discard (transient).
    #[arg(long, default_value_t = 1)]
    pub transient_periods: usize,
}

#[derive(Debug, Args)]
pub struct ChirpArgs {
    /// Start frequency [Hz].
    #[arg(long)]
    pub f0: f64,
    /// End frequency [Hz].
    #[arg(long)]
    pub f1: f64,
    /// Sweep duration [s].
    #[arg(long)]
    pub duration_s: f64,
    /// Raised-cosine fade in/out [s].
    #[arg(long, default_value_t = 0.0)]
    pub taper_s: f64,
}

#[derive(Debug, Args)]
pub struct SteppedArgs {
    /// Spot frequencies [Hz], comma separated.
    #[arg(long, value_delimiter = ',')]
    pub freqs: Vec<f64>,
    /// Minimum samples per block period (frequency resolution).
    #[arg(long, default_value_t = 200)]
    pub min_period_samples: usize,
    /// Steady periods per block.
    #[arg(long, default_value_t = 20)]
    pub periods: usize,
    /// Settling periods per block.
    #[arg(long, default_value_t = 5)]
    pub settle_periods: usize,
}

/// A generated excitation: samples [N m] and description.
pub struct Excitation {
    pub torque_nm: Vec<f64>,
    pub info: ExcitationInfo,
}

/// Generate the excitation the arguments describe.
pub(crate) fn generate(a: &ExciteArgs) -> Result<Excitation, CliError> {
    let rms = a.rms_nm.unwrap_or(a.peak_nm);
    let bad = |e: crate::excitation::ExcitationError| CliError::input(format!("excitation: {e}"));
    Ok(match &a.kind {
        ExciteKind::Multisine(m) => {
            let phases = match m.phases.as_str() {
                "schroeder" => PhaseDesign::Schroeder,
                "random" => PhaseDesign::Random { seed: m.seed },
                "odd-random" | "odd_random" => PhaseDesign::OddRandom {
                    seed: m.seed,
                    group: m.group,
                },
                other => {
                    return Err(CliError::input(format!(
                        "--phases {other}: expected schroeder, random or odd-random"
                    )))
                }
            };
            let mut d = MultisineDesign::new(
                a.fs,
                m.period_samples,
                [m.band[0], m.band[1]],
                a.peak_nm,
                rms,
            );
            d.phases = phases;
            d.crest_iterations = m.crest_iterations;
            if m.amplitude_exponent != 0.0 {
                d.amplitude = AmplitudeShape::PowerLaw {
                    exponent: m.amplitude_exponent,
                };
            }
            let ms = d.generate().map_err(bad)?;
            Excitation {
                torque_nm: ms.repeat(m.periods + m.transient_periods),
                info: ms.info(m.periods, m.transient_periods),
            }
        }
        ExciteKind::Chirp(c) => {
            let mut d = ChirpDesign::new(a.fs, c.f0, c.f1, c.duration_s, a.peak_nm);
            d.taper_s = c.taper_s;
            d.rms_limit_nm = a.rms_nm;
            let ch = d.generate().map_err(bad)?;
            Excitation {
                info: ch.info(),
                torque_nm: ch.signal,
            }
        }
        ExciteKind::Stepped(s) => {
            let d = SteppedSineDesign {
                sample_rate_hz: a.fs,
                frequencies_hz: s.freqs.clone(),
                min_period_samples: s.min_period_samples,
                periods: s.periods,
                settle_periods: s.settle_periods,
                peak_limit_nm: a.peak_nm,
                rms_limit_nm: rms,
            };
            let st = d.generate().map_err(bad)?;
            Excitation {
                info: st.info(),
                torque_nm: st.signal,
            }
        }
    })
}

/// Write an excitation as `time_s,torque_cmd_nm` CSV plus its JSON description.
pub fn write_excitation(path: &Path, fs: f64, ex: &Excitation) -> Result<(), CliError> {
    let io = |e: std::io::Error| CliError::write(format!("{}: {e}", path.display()), Some(&e));
    // both targets checked before either is written
    let side = crate::recording::sidecar_path(path);
    for p in [path, side.as_path()] {
        crate::recording::writable_target(p)
            .map_err(|e| CliError::write(format!("{}: {e}", p.display()), Some(&e)))?;
    }
    write_atomic(path, |w: &mut dyn Write| {
        writeln!(w, "time_s,torque_cmd_nm")?;
        for (k, t) in ex.torque_nm.iter().enumerate() {
            writeln!(w, "{:e},{:e}", k as f64 / fs, t)?;
        }
        Ok(())
    })
    .map_err(io)?;
    let sidecar = Sidecar {
        sample_rate_hz: Some(fs),
        excitation: Some(ex.info.clone()),
        ..Default::default()
    };
    let json =
        serde_json::to_string_pretty(&sidecar).map_err(|e| CliError::failed(e.to_string()))?;
    crate::recording::write_bytes_atomic(&side, json.as_bytes()).map_err(io)
}

/// Largest excitation file [bytes] (a 10^7-sample excitation is about 400 MB of text).
const MAX_EXCITATION_BYTES: u64 = 1 << 30;

/// Read an excitation file written by [`write_excitation`]: the `torque_cmd_nm` column and
/// the description beside it.
pub fn read_excitation(path: &Path) -> Result<(Vec<f64>, Sidecar), CliError> {
    let text = flexid_files::bounded_read::read_text_bounded(path, MAX_EXCITATION_BYTES)
        .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'));
    let (_, header) = lines
        .next()
        .ok_or_else(|| CliError::input(format!("{}: empty file", path.display())))?;
    let col = header
        .split(',')
        .position(|h| h.trim() == "torque_cmd_nm")
        .ok_or_else(|| {
            CliError::input(format!(
                "{}: line 1: no column torque_cmd_nm",
                path.display()
            ))
        })?;
    let mut torque = Vec::new();
    for (i, line) in lines {
        let field = line.split(',').nth(col).unwrap_or("").trim();
        let v: f64 = field.parse().map_err(|_| {
            CliError::input(format!(
                "{}: line {}, column torque_cmd_nm: cannot parse {field:?}",
                path.display(),
                i + 1
            ))
        })?;
        if !v.is_finite() {
            return Err(CliError::input(format!(
                "{}: line {}, column torque_cmd_nm: value {field:?} is not finite",
                path.display(),
                i + 1
            )));
        }
        torque.push(v);
    }
    let sc_path = crate::recording::sidecar_path(path);
    let sidecar = if sc_path.exists() {
        let t = flexid_files::bounded_read::read_text_bounded(
            &sc_path,
            crate::recording::MAX_SIDECAR_BYTES,
        )
        .map_err(|e| CliError::input(format!("{}: {e}", sc_path.display())))?;
        let sc = crate::recording::parse_sidecar(&t, &sc_path)
            .map_err(|e| CliError::input(e.to_string()))?;
        // the description against the samples (as the recording reader does)
        crate::recording::check_excitation_fits(&sc, torque.len(), &sc_path)
            .map_err(|e| CliError::input(e.to_string()))?;
        sc
    } else {
        Sidecar::default()
    };
    Ok((torque, sidecar))
}

/// `flexid excite`.
pub fn excite(a: &ExciteArgs) -> Result<(), CliError> {
    let ex = generate(a)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("excitation.csv"));
    write_excitation(&out, a.fs, &ex)?;
    let info = &ex.info;
    println!(
        "wrote {} ({} samples at {} Hz, {:.3} s): {:?}{}, peak {:.4} N m, RMS {:.4} N m, {} excited lines",
        out.display(),
        ex.torque_nm.len(),
        a.fs,
        ex.torque_nm.len() as f64 / a.fs,
        info.kind,
        info.design.as_deref().map(|d| format!(" ({d})")).unwrap_or_default(),
        crate::excitation::peak_abs(&ex.torque_nm),
        crate::excitation::rms(&ex.torque_nm),
        info.excited_lines.len()
    );
    Ok(())
}
