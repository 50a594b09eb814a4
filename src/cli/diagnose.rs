//! `flexid diagnose REC1.csv [REC2.csv ...] --masses N [--json OUT.json] [--svg gap.svg]`.

use super::CliError;
use crate::analysis::{to_json as analysis_json, AnalysisOptions};
use crate::diagnose::{diagnose as run_diagnosis, json::to_json, DiagnoseError, DiagnoseOptions};
use crate::identify::fit::{FitBudget, FitOptions};
use crate::recording::Recording;
use crate::recording::{read_recording, write_bytes_atomic};
use crate::report::diagnosis::render;
use crate::report::render_report;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// The recordings, usually one per excitation amplitude (REC.csv with REC.json beside).
    #[arg(required = true)]
    pub recordings: Vec<PathBuf>,
    /// Bodies of the nominal chain (motor first).
    #[arg(long)]
    pub masses: usize,
    /// Write the diagnosis as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Draw the measured FRF, the nominal model, the model with the effect and the
    /// localised bands here (SVG).
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Analysis band [Hz] (default: the excited band).
    #[arg(long, num_args = 2, value_names = ["LO_HZ", "HI_HZ"])]
    pub band: Option<Vec<f64>>,
    /// Simulate the amplitude-dependent candidates even when no amplitude dependence or
    /// distortion is seen.
    #[arg(long)]
    pub all_effects: bool,
    /// The nominal chain's last body has a spring to the ground (a Duffing oscillator's
    /// linear spring, a structure on its suspension): its stiffness is fitted with the chain,
    /// and `gravity` is no candidate.
    #[arg(long)]
    pub ground_spring: bool,
    /// Time cap of the diagnosis [s], checked between its steps (the nominal fit's starts,
    /// each candidate effect, each forward-selection step): once reached, no further
    /// candidate is tried and the verdict is made from what was fitted, marked `TIME CAP`
    /// in the report and `time_cap.capped` (with `not_tried`) in the JSON. When even the
    /// nominal chain could not be begun in time, the nominal chain of the first recording
    /// is identified instead (in at most a quarter of the cap more, at least 1 s) and
    /// returned without a verdict.
    #[arg(long, default_value_t = DEFAULT_DIAGNOSE_MAX_SECONDS)]
    pub max_seconds: f64,
}

/// Default of `flexid diagnose --max-seconds`: what a technician waits at the axis; the
/// diagnoses of the tests and benchmarks take seconds to a minute.
pub const DEFAULT_DIAGNOSE_MAX_SECONDS: f64 = 300.0;

pub fn diagnose(a: &DiagnoseArgs) -> Result<(), CliError> {
    if a.masses == 0 || a.masses > 8 {
        return Err(CliError::input(format!(
            "--masses {}: need 1 to 8",
            a.masses
        )));
    }
    let band_hz = match &a.band {
        None => None,
        Some(b) if b.len() == 2 && b[0] >= 0.0 && b[1] > b[0] && b[1].is_finite() => {
            Some([b[0], b[1]])
        }
        Some(b) => return Err(CliError::input(format!("--band {b:?}: need LO_HZ < HI_HZ"))),
    };
    if !(a.max_seconds.is_finite() && a.max_seconds > 0.0 && a.max_seconds < 1e9) {
        return Err(CliError::input(format!(
            "--max-seconds {}: must be a positive number of seconds (below 1e9)",
            a.max_seconds
        )));
    }
    let recs = a
        .recordings
        .iter()
        .map(|p| read_recording(p).map_err(|e| CliError::input(e.to_string())))
        .collect::<Result<Vec<_>, _>>()?;
    for (rec, path) in recs.iter().zip(&a.recordings) {
        super::results::check_band_nyquist(band_hz, rec, path)?;
        super::results::check_excited(rec, path)?;
    }
    eprintln!(
        "flexid diagnose: {} recording(s), nominal {} masses ...",
        recs.len(),
        a.masses
    );
    let t0 = Instant::now();
    let opts = DiagnoseOptions {
        masses: a.masses,
        band_hz,
        force_nonlinear: a.all_effects,
        // checked inside the diagnosis between its steps: at the cap it answers with what
        // it fitted, marked capped (no thread is left running)
        budget: FitBudget::with_cap_s(a.max_seconds),
        ground_spring: a.ground_spring,
        ..DiagnoseOptions::default()
    };
    let d = match run_diagnosis(&recs, &opts) {
        Ok(d) => d,
        Err(DiagnoseError::CappedBeforeNominal { .. }) => return capped(a, &recs[0], band_hz, t0),
        Err(e) => return Err(CliError::failed(e.to_string())),
    };
    if d.time_cap.capped {
        eprintln!("flexid diagnose: {}", d.time_cap.words());
    }
    print!("{}", render(&d));
    if let Some(j) = &a.json {
        let v = to_json(&d);
        let text = serde_json::to_string_pretty(&v).map_err(|e| CliError::failed(e.to_string()))?;
        write_bytes_atomic(j, text.as_bytes())
            .map_err(|e| CliError::write(format!("{}: {e}", j.display()), Some(&e)))?;
        eprintln!("flexid: wrote {}", j.display());
    }
    if let Some(s) = &a.svg {
        let svg = crate::plot::gap_svg(&d);
        write_bytes_atomic(s, svg.as_bytes())
            .map_err(|e| CliError::write(format!("{}: {e}", s.display()), Some(&e)))?;
        eprintln!("flexid: wrote {}", s.display());
    }
    Ok(())
}

/// The diagnosis reached `--max-seconds` before its nominal chain was begun: the best
/// answer is the nominal chain of the first recording, identified under a cap of its own (a quarter of
/// the diagnosis's, at least 1 s), reported without a verdict and marked as capped.
fn capped(
    a: &DiagnoseArgs,
    rec: &Recording,
    band_hz: Option<[f64; 2]>,
    t0: Instant,
) -> Result<(), CliError> {
    let waited_s = t0.elapsed().as_secs_f64();
    let note = format!(
        "TIME CAP: {} s (--max-seconds) passed before the diagnosis's nominal chain was \
         begun; no verdict: the nominal {}-mass chain of {} instead",
        a.max_seconds,
        a.masses,
        a.recordings[0].display()
    );
    eprintln!("flexid diagnose: {note}");
    let opts = AnalysisOptions {
        masses: Some(a.masses),
        band_hz,
        fit: FitOptions {
            budget: FitBudget::with_cap_s((0.25 * a.max_seconds).max(1.0)),
            ..AnalysisOptions::default().fit
        },
        ..AnalysisOptions::default()
    };
    let an = super::results::run_analysis(rec, &opts)?;
    let title = a.recordings[0].display().to_string();
    println!("{note}\n");
    print!("{}", render_report(&an, &title));
    if let Some(j) = &a.json {
        let v = serde_json::json!({
            "time_cap": {
                "max_seconds": a.max_seconds,
                "capped": true,
                "elapsed_s": waited_s,
                "not_tried": ["the diagnosis (the cap passed before its nominal chain was begun)"],
            },
            "verdict": null,
            "note": note,
            "nominal": analysis_json(&an),
        });
        let text = serde_json::to_string_pretty(&v).map_err(|e| CliError::failed(e.to_string()))?;
        write_bytes_atomic(j, text.as_bytes())
            .map_err(|e| CliError::write(format!("{}: {e}", j.display()), Some(&e)))?;
        eprintln!("flexid: wrote {}", j.display());
    }
    if let Some(s) = &a.svg {
        super::results::write_svg(&an, &title, s)?;
        eprintln!(
            "flexid: wrote {} (the nominal chain's Bode plot)",
            s.display()
        );
    }
    Ok(())
}
