//! The robot's routes: `/api/v1/robot...` (multi-axis sweeps at the poses of its
//! flexibility file, identification of its flexibilities, their files).

use super::ApiError;
use crate::robot::files::{BODE_MATRIX_SVG, FRF_MATRIX_JSON, IDENTIFICATION_JSON};
use crate::robot::service::{IdentifyRequest, RobotError, SweepRequest};
use crate::robot::RobotService;
use crate::service::Service;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::json;
use std::sync::Arc;

type Svc = State<Arc<Service>>;

impl From<RobotError> for ApiError {
    fn from(e: RobotError) -> Self {
        let (status, field) = match &e {
            RobotError::UnknownJob(_) => (StatusCode::NOT_FOUND, None),
            RobotError::Request { field, .. } => {
                (StatusCode::UNPROCESSABLE_ENTITY, Some(field.to_string()))
            }
            RobotError::Busy(_) => (StatusCode::CONFLICT, None),
            RobotError::Load { .. } | RobotError::Io(_) => {
                tracing::error!("{e}");
                (StatusCode::INTERNAL_SERVER_ERROR, None)
            }
        };
        ApiError {
            status,
            error: e.to_string(),
            field,
        }
    }
}

fn robot(svc: &Service) -> Result<Arc<RobotService>, ApiError> {
    svc.robot.clone().ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "no robot is configured (a [robot] section in the daemon's configuration)",
        )
    })
}

fn body_json<T: serde::de::DeserializeOwned + Default>(body: &[u8]) -> Result<T, ApiError> {
    if body.iter().all(u8::is_ascii_whitespace) {
        return Ok(T::default());
    }
    serde_json::from_slice(body).map_err(|e| {
        ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("request body: {e}"),
        )
    })
}

/// `GET /api/v1/robot`: the robot, its poses, parameters and jobs.
pub async fn view(State(svc): Svc) -> Result<Response, ApiError> {
    Ok(Json(robot(&svc)?.view()).into_response())
}

fn accepted(job: crate::robot::RobotJob) -> Response {
    let status = format!("/api/v1/robot/jobs/{}", job.id);
    (
        StatusCode::ACCEPTED,
        [(header::LOCATION, status.clone())],
        Json(json!({ "job_id": job.id, "kind": job.kind, "status": status })),
    )
        .into_response()
}

/// `POST /api/v1/robot/sweeps` `{"pose": NAME}` -> 202 `{"job_id", "status"}`.
pub async fn start_sweep(State(svc): Svc, body: Bytes) -> Result<Response, ApiError> {
    let r = robot(&svc)?;
    let req: SweepRequest = serde_json::from_slice(&body).map_err(|e| ApiError {
        status: StatusCode::UNPROCESSABLE_ENTITY,
        error: format!("request body: {e} (expected {{\"pose\": NAME}})"),
        field: Some("pose".into()),
    })?;
    let job = tokio::task::spawn_blocking(move || r.start_sweep(req))
        .await
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))??;
    Ok(accepted(job))
}

/// `POST /api/v1/robot/identifications` `{"sweeps"?: [...], "starts"?: N}` -> 202.
pub async fn start_identification(State(svc): Svc, body: Bytes) -> Result<Response, ApiError> {
    let r = robot(&svc)?;
    let req: IdentifyRequest = body_json(&body)?;
    let job = tokio::task::spawn_blocking(move || r.start_identification(req))
        .await
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))??;
    Ok(accepted(job))
}

/// `GET /api/v1/robot/jobs/{id}`: the job (state, progress, message).
pub async fn job(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    Ok(Json(robot(&svc)?.job(&id)?).into_response())
}

/// `POST /api/v1/robot/jobs/{id}/abort` -> 202.
pub async fn abort(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    robot(&svc)?.abort(&id)?;
    Ok((
        StatusCode::ACCEPTED,
        Json(json!({"job_id": id, "aborting": true})),
    )
        .into_response())
}

async fn job_file(
    svc: &Service,
    id: &str,
    name: &str,
    mime: &'static str,
) -> Result<Response, ApiError> {
    let dir = robot(svc)?.job_dir(id)?;
    match tokio::fs::read(dir.join(name)).await {
        Ok(bytes) => Ok(([(header::CONTENT_TYPE, mime)], bytes).into_response()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(ApiError::new(
            StatusCode::NOT_FOUND,
            format!("job {id} has no {name} (yet)"),
        )),
        Err(e) => Err(ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("{name}: {e}"),
        )),
    }
}

/// `GET /api/v1/robot/jobs/{id}/frf_matrix.json`: a sweep's measured FRF matrix.
pub async fn frf_matrix(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    job_file(&svc, &id, FRF_MATRIX_JSON, "application/json").await
}

/// `GET /api/v1/robot/jobs/{id}/bode_matrix.svg`: a sweep's N x N Bode matrix.
pub async fn bode_matrix(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    job_file(&svc, &id, BODE_MATRIX_SVG, "image/svg+xml").await
}

/// `GET /api/v1/robot/jobs/{id}/identification.json`: an identification's parameters and
/// model FRF matrices.
pub async fn identification(State(svc): Svc, Path(id): Path<String>) -> Result<Response, ApiError> {
    job_file(&svc, &id, IDENTIFICATION_JSON, "application/json").await
}
