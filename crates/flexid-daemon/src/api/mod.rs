//! The HTTP API (axum). Every route needs `Authorization: Bearer <token>`; bodies are
//! limited to [`BODY_LIMIT`] bytes; errors are JSON `{"error", "field"}`. Documented in
//! `docs/openapi.yaml` (a test checks that every route of [`ROUTES`] is in it).

mod error;
mod handlers;
mod robot;
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
    ("get", "/api/v1/sweeps/{id}/diagnosis"),
    ("get", "/api/v1/robot"),
    ("post", "/api/v1/robot/sweeps"),
    ("post", "/api/v1/robot/identifications"),
    ("get", "/api/v1/robot/jobs/{id}"),
    ("post", "/api/v1/robot/jobs/{id}/abort"),
    ("get", "/api/v1/robot/jobs/{id}/frf_matrix.json"),
    ("get", "/api/v1/robot/jobs/{id}/bode_matrix.svg"),
    ("get", "/api/v1/robot/jobs/{id}/identification.json"),
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
        .route("/api/v1/sweeps/{id}/recording.csv", get(h::recording_csv))
        .route("/api/v1/sweeps/{id}/recording.json", get(h::recording_json))
        .route("/api/v1/sweeps/{id}/frf.csv", get(h::frf_csv))
        .route("/api/v1/sweeps/{id}/bode.svg", get(h::bode_svg))
        .route("/api/v1/sweeps/{id}/diagnosis", get(h::diagnosis))
        .route("/api/v1/robot", get(robot::view))
        .route("/api/v1/robot/sweeps", post(robot::start_sweep))
        .route(
            "/api/v1/robot/identifications",
            post(robot::start_identification),
        )
        .route("/api/v1/robot/jobs/{id}", get(robot::job))
        .route("/api/v1/robot/jobs/{id}/abort", post(robot::abort))
        .route(
            "/api/v1/robot/jobs/{id}/frf_matrix.json",
            get(robot::frf_matrix),
        )
        .route(
            "/api/v1/robot/jobs/{id}/bode_matrix.svg",
            get(robot::bode_matrix),
        )
        .route(
            "/api/v1/robot/jobs/{id}/identification.json",
            get(robot::identification),
        )
        .fallback(|| async { ApiError::new(StatusCode::NOT_FOUND, "no such route") })
        .layer(axum::extract::DefaultBodyLimit::max(BODY_LIMIT))
        .layer(tower_http::limit::RequestBodyLimitLayer::new(BODY_LIMIT))
        .layer(middleware::map_response(json_errors))
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

/// Every error answer in the JSON error shape (issue 16: `?level=abc` was answered in
/// plain text by the query extractor): an error status whose body is not JSON (axum's
/// extractor rejections, the body-limit layer's 413, a 405) gets `{"error"}` with the
/// original text.
async fn json_errors(r: Response) -> Response {
    let status = r.status();
    let is_json = r
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return r;
    }
    if status == StatusCode::PAYLOAD_TOO_LARGE {
        return ApiError::new(
            status,
            format!("the request body is larger than {BODY_LIMIT} bytes"),
        )
        .into_response();
    }
    let (parts, body) = r.into_parts();
    let text = axum::body::to_bytes(body, 4096)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .unwrap_or_default();
    let message = if text.is_empty() {
        status
            .canonical_reason()
            .unwrap_or("request refused")
            .to_string()
    } else {
        text
    };
    let mut out = ApiError::new(status, message).into_response();
    // keep what the status needs (Allow of a 405, WWW-Authenticate of a 401)
    for name in [header::ALLOW, header::WWW_AUTHENTICATE] {
        if let Some(v) = parts.headers.get(&name) {
            out.headers_mut().insert(name, v.clone());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::ROUTES;

    /// The `.route(PATH, METHOD(...))` calls of [`super::router`], from this file's source.
    fn routes_in_router() -> Vec<(String, String)> {
        let src = include_str!("mod.rs");
        let body = &src[src.find("pub fn router").unwrap()..src.find("async fn auth").unwrap()];
        // rustfmt may break a long call after `.route(`
        body.split(".route(")
            .skip(1)
            .map(|r| {
                let r = r.trim_start().strip_prefix('"').expect("a path literal");
                let path = r[..r.find('"').unwrap()].to_string();
                let rest = r[r.find(',').unwrap() + 1..].trim_start();
                let method = rest[..rest.find('(').unwrap()].to_string();
                (method, path)
            })
            .collect()
    }

    #[test]
    fn every_route_is_listed_and_documented() {
        let router = routes_in_router();
        assert_eq!(router.len(), ROUTES.len(), "{router:?}");
        for (m, p) in &router {
            assert!(
                ROUTES.contains(&(m.as_str(), p.as_str())),
                "{m} {p} not in ROUTES"
            );
        }
        let spec = include_str!("../../../../docs/openapi.yaml");
        assert!(spec.starts_with("openapi: 3.1"));
        for (method, path) in ROUTES {
            let start = spec
                .find(&format!("\n  {path}:\n"))
                .unwrap_or_else(|| panic!("{path} is not in docs/openapi.yaml"));
            let block = &spec[start + path.len() + 4..];
            let end = block.find("\n  /").unwrap_or(block.len());
            assert!(
                block[..end].contains(&format!("\n    {method}:")),
                "{method} {path} is not in docs/openapi.yaml"
            );
        }
    }
}
