//! Following one backend sweep to its end: every period's samples streamed to disk,
//! progress and Bode estimates forwarded to the hub, the recording analysed and the
//! results written. The single-level runner and the two-level runner both use it.

use super::backend::{Outcome, SweepEvent};
use super::hub::SweepHub;
use super::store::{SweepFiles, BODE_SVG, RESULT_JSON};
use flexid_core::analysis::{analyze, to_json, Analysis, AnalysisOptions, ModelSummary};
use flexid_core::frf::Frf;
use flexid_files::plot::BodePlot;
use flexid_files::recording::Recording;
use serde_json::{json, Value};
use std::sync::Arc;
use tokio::sync::mpsc;

/// What following one backend sweep to its end gave.
pub(crate) struct Measured {
    pub outcome: Outcome,
    pub reason: String,
    pub recording: Option<Recording>,
    /// Rows on disk.
    pub samples: usize,
    /// Whether `result.json` holds an identified model.
    pub has_model: bool,
    /// The identified model, if any.
    pub model: Option<ModelSummary>,
    /// The `result` event's data for this sweep: `{"model", "notes"}` or `{"model": null,
    /// "error"}`.
    pub result: Value,
    /// `result.json` as written (the analysis), if the analysis ran.
    pub result_json: Option<Value>,
}

/// Where the events of one backend sweep go.
pub(crate) struct Follow<'a> {
    pub id: &'a str,
    pub hub: &'a SweepHub,
    pub files: &'a mut SweepFiles,
    pub sample_rate_hz: f64,
    pub periods_total: usize,
    pub planned_s: f64,
    /// Two-level sweeps: the level (1-based) and the periods of the levels before.
    pub level: Option<usize>,
    pub periods_before: usize,
}

/// Follow one backend sweep to its end: stream its rows into `f.files`, forward progress
/// and Bode estimates, then analyse the recording and write `result.json`, `frf.csv` and
/// `bode.svg`. Does not finish the files.
pub(crate) fn follow(f: Follow<'_>, events: &mut mpsc::Receiver<SweepEvent>) -> Measured {
    let Follow {
        id,
        hub,
        files,
        sample_rate_hz,
        periods_total,
        planned_s,
        level,
        periods_before,
    } = f;
    let mut samples = 0usize;
    let mut last_frf: Option<Arc<Frf>> = None;
    let mut store_failed: Option<String> = None;
    let ended = loop {
        match events.blocking_recv() {
            Some(SweepEvent::Period {
                index,
                samples: block,
                frf_so_far,
                elapsed_s,
                counters,
            }) => {
                let appended = if block.torque_cmd_nm.is_empty() || block.first_sample != samples {
                    // a backend that does not stream rows (or skipped some): the rows come
                    // with the final recording
                    Ok(())
                } else {
                    samples = block.first_sample + block.torque_cmd_nm.len();
                    files.append(&block, sample_rate_hz)
                };
                if let Err(e) = appended {
                    // the data cannot be kept: stop the motor rather than run blind
                    tracing::error!("sweep {id}: {e}; aborting");
                    hub.abort.abort("results store failed");
                    store_failed.get_or_insert(e.to_string());
                }
                hub.update(|s| {
                    s.periods_done = periods_before + index + 1;
                    s.samples = samples;
                });
                let mut p = json!({
                    "sweep_id": id,
                    "period": periods_before + index + 1,
                    "periods_total": periods_total,
                    "elapsed_s": elapsed_s,
                    "planned_s": planned_s,
                    "samples": samples,
                    "counters": counters,
                });
                if let Some(n) = level {
                    p["level"] = n.into();
                }
                hub.publish("progress", p.to_string());
                if let Some(frf) = frf_so_far {
                    let mut b = bode_json(&frf, index + 1);
                    if let Some(n) = level {
                        b["level"] = n.into();
                    }
                    // published before frf.csv is replaced (a file write and fsync): the
                    // estimate is in memory, the rows are already on disk
                    hub.publish("bode", b.to_string());
                    let _ = files.write_frf(&frf);
                    last_frf = Some(frf);
                }
            }
            Some(SweepEvent::Ended {
                outcome,
                reason,
                recording,
            }) => break (outcome, reason, recording),
            None => {
                break (
                    Outcome::Failed,
                    "the backend stopped without reporting an end".into(),
                    None,
                )
            }
        }
    };
    let (outcome, mut reason, recording) = ended;
    // rows the backend did not stream: append them from the final recording
    if let Some(rec) = &recording {
        if let (Some(pos), Some(vel), Some(ta)) = (
            &rec.position_rad,
            &rec.velocity_rad_s,
            &rec.torque_actual_nm,
        ) {
            let n = rec.len().min(pos.len()).min(vel.len()).min(ta.len());
            if n > samples {
                let block = super::backend::SampleBlock {
                    first_sample: samples,
                    torque_cmd_nm: rec.torque_cmd_nm[samples..n].to_vec(),
                    position_rad: pos[samples..n].to_vec(),
                    velocity_rad_s: vel[samples..n].to_vec(),
                    torque_actual_nm: ta[samples..n].to_vec(),
                };
                match files.append(&block, sample_rate_hz) {
                    Ok(()) => samples = n,
                    Err(e) => tracing::error!("sweep {id}: {e}"),
                }
            }
        }
    }
    if let Some(e) = store_failed {
        reason = format!("{reason} (results store: {e})");
    }
    // analyse what was measured (also a partial recording: it may still hold periods)
    let mut m = Measured {
        outcome,
        reason,
        recording: None,
        samples,
        has_model: false,
        model: None,
        result: json!({"model": null}),
        result_json: None,
    };
    if let Some(rec) = &recording {
        match analyze(rec, &analysis_options()) {
            Ok(an) => {
                let j = to_json(&an);
                m.has_model = an.model.is_some();
                // the result first, before the FRF and the plot, and retried: a moment
                // without a free descriptor (issue 16: idle connections) must not lose it
                if let Ok(text) = serde_json::to_string_pretty(&j) {
                    save_retrying(files, RESULT_JSON, text.as_bytes(), id);
                }
                let _ = files.write_frf(&an.measured.frf);
                write_bode(files, &an, id);
                m.result = json!({
                    "model": an.model,
                    "model_bode": an.model_frf.as_ref().map(model_bode_json),
                    "notes": an.notes,
                });
                m.result_json = Some(j);
                m.model = an.model.clone();
            }
            Err(e) => {
                m.result = json!({"model": null, "error": e.to_string()});
                if let Some(frf) = &last_frf {
                    if let Ok(svg) = BodePlot::new(frf)
                        .title(format!("sweep {id} (no model)"))
                        .render_svg()
                    {
                        let _ = files.write_file(BODE_SVG, svg.as_bytes());
                    }
                }
            }
        }
    }
    m.recording = recording;
    m
}

/// The `bode` event: the estimate after `period` periods.
pub fn bode_json(frf: &Frf, period: usize) -> Value {
    let rel: Vec<f64> = (0..frf.len())
        .map(|i| finite(frf.relative_std(i)))
        .collect();
    json!({
        "period": period,
        "freq_hz": frf.freq_hz,
        "magnitude_db": frf.magnitude_db().into_iter().map(finite).collect::<Vec<_>>(),
        "phase_deg": frf.phase_deg_unwrapped().into_iter().map(finite).collect::<Vec<_>>(),
        "coherence": frf.coherence,
        "relative_std": rel,
    })
}

/// The identified model's response on the measured lines (`model_bode` of the `result`
/// event): `{freq_hz[], magnitude_db[], phase_deg[]}`.
pub fn model_bode_json(frf: &Frf) -> Value {
    json!({
        "freq_hz": frf.freq_hz,
        "magnitude_db": frf.magnitude_db().into_iter().map(finite).collect::<Vec<_>>(),
        "phase_deg": frf.phase_deg_unwrapped().into_iter().map(finite).collect::<Vec<_>>(),
    })
}

fn finite(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        f64::MAX
    }
}

/// The retained `<prefix>/<axis>/model` message.
/// The values come from the model's honest serialisation: `null` where a parameter is
/// not identifiable, with the `identifiable` flags.
pub fn model_message(id: &str, axis: &str, m: &flexid_core::analysis::ModelSummary) -> Value {
    let v = serde_json::to_value(m).unwrap_or(Value::Null);
    json!({
        "axis": axis,
        "sweep_id": id,
        "time_unix_s": super::store::unix_now(),
        "masses": m.masses,
        "inertia_kgm2": v["inertia_kgm2"],
        "inertia_std_kgm2": v["inertia_std_kgm2"],
        "stiffness_nm_per_rad": v["stiffness_nm_per_rad"],
        "stiffness_std_nm_per_rad": v["stiffness_std_nm_per_rad"],
        "damping_nms_per_rad": v["damping_nms_per_rad"],
        "damping_std_nms_per_rad": v["damping_std_nms_per_rad"],
        "resonance_hz": v["resonance_hz"],
        "antiresonance_hz": v["antiresonance_hz"],
        "identifiable": v["identifiable"],
    })
}

fn write_bode(files: &SweepFiles, an: &Analysis, id: &str) {
    let mut plot = BodePlot::new(&an.measured.frf).title(format!("sweep {id}"));
    if let Some(m) = &an.model_frf {
        plot = plot.model(m, "identified chain");
    }
    if let Some(b) = an.supported_band_hz {
        plot = plot.band_used(b);
    }
    if let Some(m) = &an.model {
        let (lo, hi) = (
            an.measured.frf.freq_hz.first().copied().unwrap_or(0.0),
            an.measured.frf.freq_hz.last().copied().unwrap_or(0.0),
        );
        let inside = |v: &[f64]| {
            v.iter()
                .copied()
                .filter(|f| *f >= lo && *f <= hi)
                .collect::<Vec<_>>()
        };
        plot = plot
            .anti_resonances(&inside(&m.antiresonance_hz))
            .resonances(&inside(&m.resonance_hz));
    }
    match plot.render_svg() {
        Ok(svg) => {
            let _ = files.write_file(BODE_SVG, svg.as_bytes());
        }
        Err(e) => tracing::warn!("sweep {id}: bode plot: {e}"),
    }
}

/// Tries of [`save_retrying`] and the pause before the first retry (doubling, ~6 s in all).
const SAVE_TRIES: u32 = 7;
const SAVE_FIRST_PAUSE: std::time::Duration = std::time::Duration::from_millis(50);

/// Write `name` into the sweep's folder, retrying a failed write (no free descriptor, a
/// full disk freed meanwhile) with doubling pauses; the last failure is logged.
pub(crate) fn save_retrying(files: &SweepFiles, name: &str, bytes: &[u8], id: &str) -> bool {
    let mut pause = SAVE_FIRST_PAUSE;
    for attempt in 1..=SAVE_TRIES {
        match files.write_file(name, bytes) {
            Ok(()) => return true,
            Err(e) if attempt == SAVE_TRIES => {
                tracing::error!("sweep {id}: {name} not saved after {attempt} tries: {e}");
            }
            Err(e) => {
                tracing::warn!(
                    "sweep {id}: {name}: {e}; retrying in {} ms",
                    pause.as_millis()
                );
                std::thread::sleep(pause);
                pause *= 2;
            }
        }
    }
    false
}

/// Time cap of a sweep's identification [s]: the command line's default
/// (`flexid identify --max-seconds`); at the cap the best model so far is kept and
/// `result.json` says so (`time_cap.capped`).
pub const ANALYSIS_MAX_SECONDS: f64 = 120.0;

/// The analysis of a sweep's recording: the defaults, under [`ANALYSIS_MAX_SECONDS`].
fn analysis_options() -> AnalysisOptions {
    let mut opts = AnalysisOptions::default();
    opts.fit.budget = flexid_core::identify::fit::FitBudget::with_cap_s(ANALYSIS_MAX_SECONDS);
    opts
}
