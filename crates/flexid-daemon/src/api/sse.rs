//! `GET /api/v1/sweeps/{id}/events`: server-sent events `progress`, `bode`, `result`,
//! `ended` (two-level sweeps also `level` and `diagnosis`). A live sweep replays its history and then streams; a stored sweep (e.g. after a
//! restart) sends `result` (if any) and `ended` from its files. The stream closes after
//! `ended`.

use super::handlers::check_id;
use super::ApiError;
use crate::hub::HubEvent;
use crate::service::Service;
use crate::store::{self, SweepState};
use axum::extract::{Path, State};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use futures_util::stream::{self, StreamExt};
use serde_json::json;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::broadcast::error::RecvError;

fn to_event(e: &HubEvent) -> Result<Event, Infallible> {
    Ok(Event::default().event(e.name).data(e.data.clone()))
}

/// The handler.
pub async fn events(
    State(svc): State<Arc<Service>>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    check_id(&id)?;
    let keep = KeepAlive::new().interval(Duration::from_secs(15));
    if let Some(hub) = svc.hub(&id) {
        let sub = hub.subscribe();
        let ended_in_history = sub.history.iter().any(|e| e.name == "ended");
        let history = stream::iter(sub.history.into_iter().map(|e| to_event(&e)));
        let live = match (ended_in_history, sub.live) {
            (false, Some(rx)) => stream::unfold(Some(rx), |rx| async move {
                let mut rx = rx?;
                loop {
                    match rx.recv().await {
                        Ok(e) => {
                            let last = e.name == "ended";
                            return Some((to_event(&e), (!last).then_some(rx)));
                        }
                        Err(RecvError::Lagged(_)) => continue,
                        Err(RecvError::Closed) => return None,
                    }
                }
            })
            .boxed(),
            _ => stream::empty().boxed(),
        };
        return Ok(Sse::new(history.chain(live))
            .keep_alive(keep)
            .into_response());
    }
    // a stored sweep
    let st = svc.status(&id)?;
    let mut evs = Vec::new();
    if st.state != SweepState::Running {
        let result = svc
            .sweep_dir(&id)
            .and_then(|d| std::fs::read_to_string(d.join(store::RESULT_JSON)).ok())
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
        let field = |k: &str| {
            result
                .as_ref()
                .and_then(|r| r.get(k).cloned())
                .unwrap_or(serde_json::Value::Null)
        };
        let mut data = json!({"model": field("model")});
        // a two-level sweep: its levels and the diagnosis
        if !field("levels").is_null() {
            let diagnosis = field("diagnosis");
            if !diagnosis.is_null() {
                evs.push(HubEvent {
                    name: "diagnosis",
                    data: diagnosis.to_string(),
                });
            }
            data["levels"] = field("levels");
            data["diagnosis"] = diagnosis;
        }
        evs.push(HubEvent {
            name: "result",
            data: data.to_string(),
        });
        evs.push(HubEvent {
            name: "ended",
            data: json!({
                "sweep_id": st.id,
                "outcome": st.state,
                "reason": st.reason,
                "samples": st.samples,
            })
            .to_string(),
        });
    }
    let s = stream::iter(evs.into_iter().map(|e| to_event(&e)));
    Ok(Sse::new(s).keep_alive(keep).into_response())
}
