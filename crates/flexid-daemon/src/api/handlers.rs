//! The request handlers: thin wrappers around [`Service`].

use super::ApiError;
use crate::service::Service;
use crate::store::{self, valid_sweep_id};
use axum::body::Bytes;
use axum::extract::{Path, Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};
use std::sync::Arc;

type Svc = State<Arc<Service>>;

/// `GET /api/v1/axes`: the axes, and the configured robot's name (`null` without one).
pub async fn list_axes(State(svc): Svc) -> Response {
    let robot = svc.robot.as_ref().map(|r| r.cfg.name.clone());
    Json(json!({ "axes": svc.axes(), "robot": robot })).into_response()
}

/// `POST /api/v1/axes/{axis}/sweeps` -> 202 `{"sweep_id", "axis", "events", "status"}`.
pub async fn start_sweep(
    State(svc): Svc,
    Path(axis): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let id = svc.start_sweep(&axis, &body).await?;
    let status = format!("/api/v1/sweeps/{id}");
    Ok((
        StatusCode::ACCEPTED,
        [(header::LOCATION, status.clone())],
        Json(json!({
            "sweep_id": id,
            "axis": axis,
            "status": status,
            "events": format!("/api/v1/sweeps/{id}/events"),
        })),
    )
        .into_response())
}

pub(super) fn check_id(id: &str) -> Result<(), ApiError> {
    if valid_sweep_id(id) {
        Ok(())
    } else {
        Err(ApiError::new(
            StatusCode::NOT_FOUND,
            format!("no sweep with id {id:?}"),
        ))
    }
}

/// `GET /api/v1/sweeps/{id}`: the status, and `result` as `flexid identify --json` writes
/// it (`null` while running or when the analysis failed).
pub async fn sweep_status(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    check_id(&id)?;
    let st = svc.status(&id)?;
    let result: Value = svc
        .sweep_dir(&id)
        .and_then(|d| std::fs::read_to_string(d.join(store::RESULT_JSON)).ok())
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or(Value::Null);
    let mut v = serde_json::to_value(&st)
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    v["result"] = result;
    Ok(Json(v).into_response())
}

/// `POST /api/v1/sweeps/{id}/abort` -> 202.
pub async fn abort(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    check_id(&id)?;
    svc.abort(&id)?;
    Ok((
        StatusCode::ACCEPTED,
        Json(json!({"sweep_id": id, "aborting": true})),
    )
        .into_response())
}

/// `?level=N` on the file routes: the file of level N (1 = low, 2 = high) of a two-level
/// sweep instead of the top-level one.
#[derive(Debug, Default, serde::Deserialize)]
pub struct LevelQuery {
    pub level: Option<usize>,
}

/// `GET /api/v1/sweeps/{id}/recording.csv[?level=N]`.
pub async fn recording_csv(
    s: Svc,
    id: Path<String>,
    q: Query<LevelQuery>,
) -> Result<Response, ApiError> {
    sweep_file(s, id, q.0.level, store::RECORDING_CSV, "text/csv").await
}

/// `GET /api/v1/sweeps/{id}/recording.json[?level=N]`.
pub async fn recording_json(
    s: Svc,
    id: Path<String>,
    q: Query<LevelQuery>,
) -> Result<Response, ApiError> {
    sweep_file(s, id, q.0.level, store::RECORDING_JSON, "application/json").await
}

/// `GET /api/v1/sweeps/{id}/frf.csv[?level=N]`.
pub async fn frf_csv(s: Svc, id: Path<String>, q: Query<LevelQuery>) -> Result<Response, ApiError> {
    sweep_file(s, id, q.0.level, store::FRF_CSV, "text/csv").await
}

/// `GET /api/v1/sweeps/{id}/bode.svg[?level=N]`.
pub async fn bode_svg(
    s: Svc,
    id: Path<String>,
    q: Query<LevelQuery>,
) -> Result<Response, ApiError> {
    sweep_file(s, id, q.0.level, store::BODE_SVG, "image/svg+xml").await
}

/// `GET /api/v1/sweeps/{id}/diagnosis`: the gap diagnosis of a two-level sweep
/// (`diagnosis.json`: the report, or `{"error"}` when the diagnosis failed); 404 before it
/// is done or for a one-level sweep.
pub async fn diagnosis(s: Svc, id: Path<String>) -> Result<Response, ApiError> {
    sweep_file(s, id, None, store::DIAGNOSIS_JSON, "application/json").await
}

async fn sweep_file(
    State(svc): Svc,
    Path(id): Path<String>,
    level: Option<usize>,
    name: &str,
    mime: &'static str,
) -> Result<Response, ApiError> {
    check_id(&id)?;
    let mut dir = svc
        .sweep_dir(&id)
        .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, format!("no sweep with id {id:?}")))?;
    if let Some(n) = level {
        if !(1..=2).contains(&n) {
            return Err(ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                format!("level {n}: a two-level sweep has levels 1 (low) and 2 (high)"),
            ));
        }
        dir = dir.join(store::level_dir_name(n));
    }
    match tokio::fs::read(dir.join(name)).await {
        Ok(bytes) => Ok(([(header::CONTENT_TYPE, mime)], bytes).into_response()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(ApiError::new(
            StatusCode::NOT_FOUND,
            format!("sweep {id} has no {name} (yet)"),
        )),
        Err(e) => Err(ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("{name}: {e}"),
        )),
    }
}
