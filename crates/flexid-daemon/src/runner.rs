//! The thread that follows one running sweep to its end ([`run`]): a single-level sweep
//! through [`follow`], a two-level one through [`super::two_level`]; then the files are
//! finished, the model published and the axis freed.

use super::backend::Outcome;
use super::follow::{follow, model_message, Follow};
use super::job::Job;
use super::store::SweepState;
use serde_json::json;

/// Follow the sweep to its end (blocking; runs on its own thread).
pub(crate) fn run(mut job: Job) {
    if let Some(tl) = job.two_level.take() {
        return super::two_level::run(job, tl);
    }
    let status = job.hub.status();
    let (id, axis) = status
        .as_ref()
        .map(|s| (s.id.clone(), s.axis.clone()))
        .unwrap_or_default();
    let m = follow(
        Follow {
            id: &id,
            hub: &job.hub,
            files: &mut job.files,
            sample_rate_hz: job.sample_rate_hz,
            periods_total: job.periods_total,
            planned_s: job.planned_s,
            level: None,
            periods_before: 0,
        },
        &mut job.events,
    );
    if let (Some(m), Some(mqtt)) = (&m.model, job.svc.mqtt()) {
        mqtt.publish(&axis, "model", &model_message(&id, &axis, m));
    }
    if let Some(rec) = &m.recording {
        job.sidecar = rec.sidecar.clone();
    }
    job.sidecar.sample_rate_hz = Some(job.sample_rate_hz);
    if m.outcome != Outcome::Completed {
        job.sidecar.ended_because = Some(m.reason.clone());
    }
    job.hub.update(|s| {
        s.state = SweepState::from(m.outcome);
        s.reason = Some(m.reason.clone());
        s.ended_unix_s = Some(super::store::unix_now());
        s.samples = m.samples;
        // rows a backend did not stream came with its final recording: count them too
        if let Some(p) = super::store::whole_periods(m.samples, &job.sidecar) {
            s.periods_done = s.periods_done.max(p);
        }
        s.has_result = m.has_model;
    });
    if let Some(st) = job.hub.status() {
        if let Err(e) = job.files.finish(&st, &job.sidecar) {
            tracing::error!("sweep {id}: {e}");
        }
    }
    if m.has_model {
        job.svc.set_last_result(&axis, &id);
    }
    // free the axis before the last events: a client acting on "ended" (a new sweep, the
    // axes list) finds it idle, as the two-level runner does
    job.svc.release(&axis);
    job.hub.publish("result", m.result.to_string());
    job.hub.publish(
        "ended",
        json!({"sweep_id": id, "outcome": m.outcome, "reason": m.reason, "samples": m.samples})
            .to_string(),
    );
    tracing::info!("axis {axis}: sweep {id} ended: {}", m.reason);
}
