//! `flexid diagnose REC1.csv [REC2.csv ...] --masses N [--json OUT.json] [--svg gap.svg]`.

use super::CliError;
use crate::diagnose::{diagnose as run_diagnosis, json::to_json, DiagnoseOptions};
use crate::recording::{read_recording, write_bytes_atomic};
use crate::report::diagnosis::render;
use clap::Args;
use std::path::PathBuf;

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
}

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
    let recs = a
        .recordings
        .iter()
        .map(|p| read_recording(p).map_err(|e| CliError::input(e.to_string())))
        .collect::<Result<Vec<_>, _>>()?;
    eprintln!(
        "flexid diagnose: {} recording(s), nominal {} masses ...",
        recs.len(),
        a.masses
    );
    let d = run_diagnosis(
        &recs,
        &DiagnoseOptions {
            masses: a.masses,
            band_hz,
            force_nonlinear: a.all_effects,
            ..DiagnoseOptions::default()
        },
    )
    .map_err(|e| CliError::failed(e.to_string()))?;
    print!("{}", render(&d));
    if let Some(j) = &a.json {
        let text = serde_json::to_string_pretty(&to_json(&d))
            .map_err(|e| CliError::failed(e.to_string()))?;
        write_bytes_atomic(j, text.as_bytes())
            .map_err(|e| CliError::failed(format!("{}: {e}", j.display())))?;
        eprintln!("flexid: wrote {}", j.display());
    }
    if let Some(s) = &a.svg {
        let svg = crate::plot::gap_svg(&d);
        write_bytes_atomic(s, svg.as_bytes())
            .map_err(|e| CliError::failed(format!("{}: {e}", s.display())))?;
        eprintln!("flexid: wrote {}", s.display());
    }
    Ok(())
}
