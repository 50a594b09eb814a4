//! The two-level sweep (`levels_nm` in the request): the same excitation at the low then
//! the high peak torque, each a complete sweep on the axis's backend with its own files
//! under `level1/` and `level2/`, then the gap diagnosis ([`flexid_core::diagnose::diagnose`]) on
//! the two saved recordings. Backend-agnostic: the runner starts the second sweep through
//! [`AxisBackend::start`](super::backend::AxisBackend::start) like the service started the
//! first.
//!
//! Events: `level` when a level starts, `progress`/`bode` with a `level` field, `progress`
//! with `"phase": "diagnosis"` about once a second while the diagnosis runs, `diagnosis`
//! (the report, or `{"error"}`), then `result` (the high level's model, every level's
//! outcome and the diagnosis) and `ended`. A failed diagnosis is reported; the recordings
//! are on disk before it starts.

use super::backend::{AbortSignal, Outcome, SweepEvent};
use super::follow::{follow, model_message, Follow, Measured};
use super::hub::SweepHub;
use super::job::{Job, TwoLevel};
use super::store::{
    level_dir_name, SweepState, BODE_SVG, DIAGNOSIS_JSON, FRF_CSV, RECORDING_CSV, RESULT_JSON,
};
use flexid_core::diagnose::{diagnose, json::to_json, DiagnoseError, DiagnoseOptions};
use flexid_core::identify::fit::FitBudget;
use flexid_files::recording::{read_recording, Sidecar};
use serde_json::{json, Value};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// One level as reported in `result.levels`.
struct LevelDone {
    amplitude_nm: f64,
    m: Measured,
}

/// Run the levels, then the diagnosis; finish the sweep.
pub(crate) fn run(mut job: Job, tl: TwoLevel) {
    let Some(base_status) = job.hub.status() else {
        // the hub's lock is poisoned: nothing can be reported; stop the motor
        job.hub.abort.abort("internal error");
        drain(&mut job.events);
        return;
    };
    let (id, axis) = (base_status.id.clone(), base_status.axis.clone());
    let periods_per_level = job.periods_total / 2;
    let mut done: Vec<LevelDone> = Vec::new();
    let mut first_events = Some(std::mem::replace(&mut job.events, mpsc::channel(1).1));
    let mut next = tl.next.into_iter();
    let mut sidecar_of_level = job.sidecar.clone();
    // why the sweep stopped before both levels were measured
    let mut stopped: Option<(Outcome, String)> = None;
    for (i, &amplitude_nm) in tl.levels_nm.iter().enumerate() {
        let n = i + 1;
        // the backend sweep of this level: the first was started by the service
        let (mut events, forward) = match first_events.take() {
            Some(ev) => (ev, None),
            None => {
                let Some(plan) = next.next() else {
                    stopped = Some((Outcome::Failed, format!("no plan for level {n}")));
                    break;
                };
                if job.hub.abort.is_aborted() {
                    let r = job.hub.abort.reason().unwrap_or_else(|| "abort".into());
                    stopped = Some((Outcome::Aborted, r));
                    break;
                }
                sidecar_of_level = Sidecar {
                    sample_rate_hz: Some(plan.sample_rate_hz),
                    excitation: Some(plan.info.clone()),
                    ..Default::default()
                };
                match job.svc.backend().start(&tl.axis, plan) {
                    Ok(h) => (h.events, Some(forward_abort(&job.hub, h.abort))),
                    Err(e) => {
                        stopped = Some((Outcome::Failed, format!("level {n}: {e}")));
                        break;
                    }
                }
            }
        };
        job.hub.update(|s| s.level = Some(n));
        job.hub.publish(
            "level",
            json!({"sweep_id": id, "level": n, "amplitude_nm": amplitude_nm}).to_string(),
        );
        let mut level_status = job.hub.status().unwrap_or_else(|| base_status.clone());
        level_status.state = SweepState::Running;
        let dir = job.files.dir().join(level_dir_name(n));
        let mut files = match job
            .svc
            .store()
            .begin_in(dir, &level_status, &sidecar_of_level)
        {
            Ok(f) => f,
            Err(e) => {
                // nowhere to write: stop the motor, wait for the backend to end
                tracing::error!("sweep {id}: level {n}: {e}; aborting");
                job.hub.abort.abort("results store failed");
                drain(&mut events);
                stop_forwarding(forward);
                stopped = Some((Outcome::Failed, format!("level {n}: results store: {e}")));
                break;
            }
        };
        let m = follow(
            Follow {
                id: &id,
                hub: &job.hub,
                files: &mut files,
                sample_rate_hz: job.sample_rate_hz,
                periods_total: job.periods_total,
                planned_s: job.planned_s,
                level: Some(n),
                periods_before: i * periods_per_level,
            },
            &mut events,
        );
        stop_forwarding(forward);
        // close the level's files
        let mut sc = m
            .recording
            .as_ref()
            .map_or_else(|| sidecar_of_level.clone(), |r| r.sidecar.clone());
        sc.sample_rate_hz = Some(job.sample_rate_hz);
        if m.outcome != Outcome::Completed {
            sc.ended_because = Some(m.reason.clone());
        }
        level_status.state = SweepState::from(m.outcome);
        level_status.reason = Some(m.reason.clone());
        level_status.ended_unix_s = Some(super::store::unix_now());
        level_status.samples = m.samples;
        level_status.has_result = m.has_model;
        level_status.level = Some(n);
        let level_dir = files.dir().to_path_buf();
        if let Err(e) = files.finish(&level_status, &sc) {
            tracing::error!("sweep {id}: level {n}: {e}");
        }
        // the top-level files show the last level measured
        for name in [RECORDING_CSV, FRF_CSV, BODE_SVG] {
            if let Ok(bytes) = std::fs::read(level_dir.join(name)) {
                let _ = job.files.write_file(name, &bytes);
            }
        }
        job.sidecar = sc;
        let total: usize = done.iter().map(|d| d.m.samples).sum::<usize>() + m.samples;
        job.hub.update(|s| s.samples = total);
        let outcome = m.outcome;
        let reason = m.reason.clone();
        done.push(LevelDone { amplitude_nm, m });
        if outcome != Outcome::Completed {
            stopped = Some((outcome, format!("level {n}: {reason}")));
            break;
        }
    }
    // the motor is done: free the axis before the diagnosis
    job.svc.release(&axis);

    let samples: usize = done.iter().map(|d| d.m.samples).sum();
    let high = done.last().filter(|_| done.len() == 2);
    let diagnosis: Value = if stopped.is_some() {
        Value::Null
    } else {
        let masses = tl.masses.or_else(|| {
            done.iter()
                .rev()
                .find_map(|d| d.m.model.as_ref())
                .map(|m| m.masses)
        });
        let dirs: Vec<_> = (1..=2)
            .map(|n| job.files.dir().join(level_dir_name(n)))
            .collect();
        let d = match masses {
            Some(masses) => {
                run_diagnosis(&job.hub, &id, &dirs, masses, tl.levels_nm, DIAGNOSIS_MAX)
            }
            None => json!({"error": "no model was identified at either level to take the \
                number of bodies from: give \"masses\" in the request"}),
        };
        if let Ok(text) = serde_json::to_string_pretty(&d) {
            if let Err(e) = job.files.write_file(DIAGNOSIS_JSON, text.as_bytes()) {
                tracing::error!("sweep {id}: {e}");
            }
        }
        job.hub.publish("diagnosis", d.to_string());
        d
    };
    let has_diagnosis = diagnosis.get("verdict").is_some();

    // result.json: the high level's analysis, every level, the diagnosis
    let levels: Vec<Value> = done
        .iter()
        .enumerate()
        .map(|(i, d)| {
            json!({
                "level": i + 1,
                "amplitude_nm": d.amplitude_nm,
                "outcome": d.m.outcome,
                "reason": d.m.reason,
                "samples": d.m.samples,
                "model": d.m.model,
                "dir": level_dir_name(i + 1),
            })
        })
        .collect();
    let mut result_json = high
        .and_then(|h| h.m.result_json.clone())
        .unwrap_or_else(|| json!({"model": null}));
    result_json["levels"] = Value::Array(levels.clone());
    result_json["diagnosis"] = diagnosis.clone();
    if let Ok(text) = serde_json::to_string_pretty(&result_json) {
        super::follow::save_retrying(&job.files, RESULT_JSON, text.as_bytes(), &id);
    }
    let has_model = high.is_some_and(|h| h.m.has_model);
    if let (Some(m), Some(mqtt)) = (high.and_then(|h| h.m.model.as_ref()), job.svc.mqtt()) {
        mqtt.publish(&axis, "model", &model_message(&id, &axis, m));
    }
    let (outcome, reason) = stopped.unwrap_or((Outcome::Completed, "completed".into()));
    if outcome != Outcome::Completed {
        job.sidecar.ended_because = Some(reason.clone());
    }
    job.hub.update(|s| {
        s.state = SweepState::from(outcome);
        s.reason = Some(reason.clone());
        s.ended_unix_s = Some(super::store::unix_now());
        s.samples = samples;
        s.has_result = has_model;
        s.has_diagnosis = has_diagnosis;
    });
    if let Some(st) = job.hub.status() {
        if let Err(e) = job.files.finish(&st, &job.sidecar) {
            tracing::error!("sweep {id}: {e}");
        }
    }
    if has_model {
        job.svc.set_last_result(&axis, &id);
    }
    let mut result = high.map_or_else(|| json!({"model": null}), |h| h.m.result.clone());
    result["levels"] = Value::Array(levels);
    result["diagnosis"] = diagnosis;
    job.hub.publish("result", result.to_string());
    job.hub.publish(
        "ended",
        json!({"sweep_id": id, "outcome": outcome, "reason": reason, "samples": samples})
            .to_string(),
    );
    tracing::info!("axis {axis}: two-level sweep {id} ended: {reason}");
}

/// Time cap of a two-level sweep's diagnosis (`flexid diagnose --max-seconds`'s default).
pub const DIAGNOSIS_MAX: Duration = Duration::from_secs(300);

/// How long past its cap the diagnosis's answer is waited for: the cap is checked between
/// the diagnosis's steps, so the step under way (one candidate's fit) still ends.
pub const DIAGNOSIS_GRACE: Duration = Duration::from_secs(60);

/// The diagnosis of the two saved recordings (`dirs[i]/recording.csv`) on a thread of its
/// own, with a `progress` event (`"phase": "diagnosis"`) about every second. Returns the
/// report as JSON ([`flexid_core::diagnose::json::to_json`] plus `levels_nm`) or `{"error"}`.
/// The diagnosis runs under `cap` ([`DiagnoseOptions::budget`]): at the cap it answers with
/// what it fitted, `time_cap.capped` set; an error marked so when the cap passed before
/// its nominal chain was begun, or when no answer came [`DIAGNOSIS_GRACE`] after the cap.
fn run_diagnosis(
    hub: &SweepHub,
    id: &str,
    dirs: &[std::path::PathBuf],
    masses: usize,
    levels_nm: [f64; 2],
    cap: Duration,
) -> Value {
    let recs = match dirs
        .iter()
        .map(|d| read_recording(d.join(RECORDING_CSV)))
        .collect::<Result<Vec<_>, _>>()
    {
        Ok(r) => r,
        Err(e) => return json!({"error": format!("reading the recordings: {e}")}),
    };
    let (tx, rx) = std::sync::mpsc::channel();
    let t0 = Instant::now();
    let spawned = std::thread::Builder::new()
        .name("diagnosis".into())
        .spawn(move || {
            let opts = DiagnoseOptions {
                masses,
                budget: FitBudget::with_cap_s(cap.as_secs_f64()),
                ..DiagnoseOptions::default()
            };
            let r = diagnose(&recs, &opts).map(|d| to_json(&d));
            let _ = tx.send(r.map_err(|e| {
                let capped = matches!(e, DiagnoseError::CappedBeforeNominal { .. });
                (e.to_string(), capped)
            }));
        });
    if let Err(e) = spawned {
        return json!({"error": format!("cannot start the diagnosis thread: {e}")});
    }
    hub.publish(
        "progress",
        json!({"sweep_id": id, "phase": "diagnosis", "elapsed_s": 0.0, "masses": masses})
            .to_string(),
    );
    let capped = |error: String| {
        json!({
            "error": error,
            "time_cap": {"max_seconds": cap.as_secs_f64(), "capped": true,
                         "elapsed_s": t0.elapsed().as_secs_f64()},
            "levels_nm": levels_nm,
        })
    };
    loop {
        let left = (cap + DIAGNOSIS_GRACE).saturating_sub(t0.elapsed());
        if left.is_zero() {
            tracing::warn!(
                "sweep {id}: the diagnosis did not finish within {} s (time cap)",
                cap.as_secs_f64()
            );
            return capped(format!(
                "the diagnosis did not finish within {} s (time cap); no verdict",
                cap.as_secs_f64()
            ));
        }
        match rx.recv_timeout(left.min(Duration::from_secs(1))) {
            Ok(Ok(mut d)) => {
                d["levels_nm"] = json!(levels_nm);
                tracing::info!(
                    "sweep {id}: diagnosis: {} ({:.1} s)",
                    d["verdict"],
                    t0.elapsed().as_secs_f64()
                );
                return d;
            }
            Ok(Err((e, true))) => {
                tracing::warn!("sweep {id}: {e}");
                return capped(format!("{e}; no verdict"));
            }
            Ok(Err((e, false))) => return json!({"error": e, "levels_nm": levels_nm}),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => hub.publish(
                "progress",
                json!({"sweep_id": id, "phase": "diagnosis",
                       "elapsed_s": t0.elapsed().as_secs_f64(), "masses": masses})
                .to_string(),
            ),
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return json!({"error": "the diagnosis stopped without a result (panic)",
                              "levels_nm": levels_nm})
            }
        }
    }
}

/// Forward a stop request of the sweep (operator abort, shutdown, store failure) to the
/// backend sweep of a later level, until the returned flag is set.
fn forward_abort(hub: &Arc<SweepHub>, level: AbortSignal) -> Arc<AtomicBool> {
    let done = Arc::new(AtomicBool::new(false));
    let (hub, d) = (hub.clone(), done.clone());
    let spawned = std::thread::Builder::new()
        .name("abort-forward".into())
        .spawn(move || {
            while !d.load(Ordering::Acquire) {
                if hub.abort.is_aborted() {
                    level.abort(&hub.abort.reason().unwrap_or_else(|| "abort".into()));
                    return;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        });
    if spawned.is_err() {
        tracing::error!("cannot start the abort forwarder");
    }
    done
}

fn stop_forwarding(f: Option<Arc<AtomicBool>>) {
    if let Some(f) = f {
        f.store(true, Ordering::Release);
    }
}

/// Wait for a backend sweep to end, discarding its events.
fn drain(events: &mut mpsc::Receiver<SweepEvent>) {
    while let Some(ev) = events.blocking_recv() {
        if matches!(ev, SweepEvent::Ended { .. }) {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::AbortSignal;

    /// A periodic recording (1 kHz, 100-sample period, 1 + 3 periods) of a damped body.
    fn write_level(dir: &std::path::Path) {
        std::fs::create_dir_all(dir).unwrap();
        let mut csv = String::from("time_s,torque_cmd_nm,position_rad\n");
        let (mut v, mut x) = (0.0f64, 0.0f64);
        for k in 0..400 {
            let u: f64 = (1..=20)
                .map(|l| (std::f64::consts::TAU * (l * (k % 100)) as f64 / 100.0 + l as f64).cos())
                .sum::<f64>()
                / 10.0;
            v += (u - 0.5 * v) * 0.1;
            x += v * 1e-3;
            csv.push_str(&format!("{:e},{u:e},{x:e}\n", k as f64 * 1e-3));
        }
        std::fs::write(dir.join(RECORDING_CSV), csv).unwrap();
        std::fs::write(
            dir.join("recording.json"),
            r#"{"sample_rate_hz": 1000, "excitation": {"kind": "multisine", "period_samples": 100, "periods": 3, "transient_periods": 1}}"#,
        )
        .unwrap();
    }

    /// Issue 16 item 2: the daemon's diagnosis had no time cap; a cap that passes before
    /// the nominal chain is begun answers an error marked `time_cap.capped` at once.
    #[test]
    fn the_diagnosis_stops_waiting_at_its_cap() {
        let tmp = tempfile::tempdir().unwrap();
        let dirs: Vec<_> = (1..=2)
            .map(|n| tmp.path().join(format!("level{n}")))
            .collect();
        for d in &dirs {
            write_level(d);
        }
        let status = crate::store::running_status("20261126T180000Z-000001", 3);
        let hub = SweepHub::new(status, AbortSignal::default());
        let d = run_diagnosis(&hub, "t", &dirs, 1, [0.1, 0.2], Duration::ZERO);
        assert_eq!(d["time_cap"]["capped"], true, "{d}");
        assert!(d["error"].as_str().unwrap().contains("time cap"), "{d}");
    }
}
