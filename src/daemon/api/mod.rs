//! The HTTP API (axum). Every route needs `Authorization: Bearer <token>`; bodies are
//! limited to [`BODY_LIMIT`] bytes; errors are JSON `{"error", "field"}`. Documented in
//! `docs/openapi.yaml` (a test checks that every route of [`ROUTES`] is in it).

mod error;
mod handlers;
mod sse;

pub use error::ApiError;

use super::service::Service;
use axum::extract::{Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use std::sync::Arc;

/// Largest request body [bytes].
pub const BODY_LIMIT: usize = 64 * 1024;

/// Every route: (method, path in OpenAPI notation).
pub const ROUTES: &[(&str, &str)] = &[
    ("get", "/api/v1/axes"),
    ("post", "/api/v1/axes/{axis}/sweeps"),
    ("get", "/api/v1/sweeps/{id}"),
    ("get", "/api/v1/sweeps/{id}/events"),
    ("post", "/api/v1/sweeps/{id}/abort"),
    ("get", "/api/v1/sweeps/{id}/recording.csv"),
    ("get", "/api/v1/sweeps/{id}/recording.json"),
    ("get", "/api/v1/sweeps/{id}/frf.csv"),
    ("get", "/api/v1/sweeps/{id}/bode.svg"),
];

/// The router over `svc`.
pub fn router(svc: Arc<Service>) -> Router {
    use handlers as h;
    Router::new()
        .route("/api/v1/axes", get(h::list_axes))
        .route("/api/v1/axes/{axis}/sweeps", post(h::start_sweep))
        .route("/api/v1/sweeps/{id}", get(h::sweep_status))
        .route("/api/v1/sweeps/{id}/events", get(sse::events))
        .route("/api/v1/sweeps/{id}/abort", post(h::abort))
        .route("/api/v1/sweeps/{id}/{file}", get(h::sweep_file))
        .fallback(|| async { ApiError::new(StatusCode::NOT_FOUND, "no such route") })
        .layer(axum::extract::DefaultBodyLimit::max(BODY_LIMIT))
        .layer(tower_http::limit::RequestBodyLimitLayer::new(BODY_LIMIT))
        .layer(middleware::map_response(json_413))
        .layer(middleware::from_fn_with_state(svc.clone(), auth))
        .with_state(svc)
}

/// Bearer-token check, before anything else (the body is not read).
async fn auth(State(svc): State<Arc<Service>>, req: Request, next: Next) -> Response {
    let ok = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.as_bytes().strip_prefix(b"Bearer "))
        .is_some_and(|t| svc.token.matches(t));
    if !ok {
        let mut r = ApiError::new(StatusCode::UNAUTHORIZED, "missing or wrong bearer token")
            .into_response();
        r.headers_mut().insert(
            header::WWW_AUTHENTICATE,
            header::HeaderValue::from_static("Bearer"),
        );
        return r;
    }
    next.run(req).await
}

/// The body-limit layer answers 413 in plain text; give it the JSON error shape.
async fn json_413(r: Response) -> Response {
    if r.status() == StatusCode::PAYLOAD_TOO_LARGE
        && r.headers()
            .get(header::CONTENT_TYPE)
            .is_none_or(|v| v != "application/json")
    {
        return ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("the request body is larger than {BODY_LIMIT} bytes"),
        )
        .into_response();
    }
    r
}
