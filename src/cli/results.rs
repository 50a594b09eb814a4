//! The steps shared by the commands that identify a recording (`identify`, `bode`,
//! `sweep`, `demo`): options from the arguments, the analysis, its JSON and its Bode plot.

use super::{CliError, ModelArgs};
use crate::analysis::{analyze, to_json, Analysis, AnalysisError, AnalysisOptions};
use crate::identify::fit::{FitBudget, FitOptions};
use crate::plot::BodePlot;
use crate::recording::{read_recording, write_bytes_atomic, Recording};
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

pub(crate) fn load(path: &Path) -> Result<Recording, CliError> {
    read_recording(path).map_err(|e| CliError::input(e.to_string()))
}

/// A recording whose torque never changes excites nothing (issue 16: a constant
/// recording was diagnosed and exited 0): exit 2, naming the file and the column.
pub(crate) fn check_excited(rec: &Recording, path: &Path) -> Result<(), CliError> {
    let (lo, hi) = rec
        .torque_cmd_nm
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
    if rec.len() >= 2 && lo == hi {
        return Err(CliError::input(format!(
            "{}: column torque_cmd_nm is {lo} N m in every row: nothing excites the axis",
            path.display()
        )));
    }
    Ok(())
}

/// `--band LO HI` against the recording's rate: a band above the Nyquist frequency holds
/// no line of the recording (issue 16: it was accepted), exit 2.
pub(crate) fn check_band_nyquist(
    band_hz: Option<[f64; 2]>,
    rec: &Recording,
    path: &Path,
) -> Result<(), CliError> {
    let nyquist_hz = rec.sample_rate_hz / 2.0;
    match band_hz {
        Some([lo, hi]) if hi > nyquist_hz => Err(CliError::input(format!(
            "--band {lo} {hi}: above the Nyquist frequency {nyquist_hz} Hz of {} ({} Hz)",
            path.display(),
            rec.sample_rate_hz
        ))),
        _ => Ok(()),
    }
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
    super::fit_progress::with_progress(&budget, "flexid identify", || analyze(rec, &opts)).map_err(
        |e| match e {
            // the command line's own wording: which flag was out of range
            AnalysisError::Masses { .. } => CliError::failed(format!("--masses: {e}")),
            e => CliError::failed(e.to_string()),
        },
    )
}

pub(crate) fn bode_plot<'a>(a: &'a Analysis, title: &str) -> BodePlot<'a> {
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
    if let Some(b) = a.supported_band_hz {
        plot = plot.band_used(b);
    }
    plot.subtitle(format!(
        "{} estimator, {} averages, band {:.3}-{:.1} Hz, fs {} Hz; shaded: +-2 sigma",
        a.measured.method, a.measured.averages, lo, hi, a.sample_rate_hz
    ))
}

pub(crate) fn write_svg(a: &Analysis, title: &str, out: &Path) -> Result<(), CliError> {
    bode_plot(a, title).write_svg(out).map_err(|e| {
        let source = match &e {
            crate::plot::PlotError::Io { source, .. } => Some(source),
            _ => None,
        };
        CliError::write(format!("{}: {e}", out.display()), source)
    })
}

pub(crate) fn write_json(a: &Analysis, out: &Path) -> Result<(), CliError> {
    let text =
        serde_json::to_string_pretty(&to_json(a)).map_err(|e| CliError::failed(e.to_string()))?;
    write_bytes_atomic(out, text.as_bytes())
        .map_err(|e| CliError::write(format!("{}: {e}", out.display()), Some(&e)))
}
