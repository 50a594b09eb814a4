//! The web page of the daemon: `GET /` (and `/index.html`), `/app.js`, `/bode.js`, `/matrix.js`, `/robot.js`,
//! `/style.css`, embedded in the binary (no build step, nothing fetched from elsewhere).
//!
//! The files are static and served without a token: they hold no configuration, no axis and
//! no result. The page asks the operator for the token and sends it as
//! `Authorization: Bearer` on every API request itself (the API's rules are unchanged). A
//! strict content-security policy keeps the page to its own scripts and to this origin.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

/// The static files: (URL path, content type, content).
pub const FILES: &[(&str, &str, &str)] = &[
    ("/", HTML, include_str!("web/index.html")),
    ("/index.html", HTML, include_str!("web/index.html")),
    ("/app.js", JS, include_str!("web/app.js")),
    ("/bode.js", JS, include_str!("web/bode.js")),
    ("/matrix.js", JS, include_str!("web/matrix.js")),
    ("/robot.js", JS, include_str!("web/robot.js")),
    (
        "/style.css",
        "text/css; charset=utf-8",
        include_str!("web/style.css"),
    ),
];

const HTML: &str = "text/html; charset=utf-8";
const JS: &str = "text/javascript; charset=utf-8";

/// The content-security policy of every static file: own scripts, styles and API only; no
/// inline script, no framing, no form posts elsewhere.
pub const CSP: &str = "default-src 'none'; script-src 'self'; style-src 'self'; \
img-src 'self' data: blob:; connect-src 'self'; base-uri 'none'; form-action 'none'; \
frame-ancestors 'none'";

/// The static routes (no state, no token).
pub fn router<S: Clone + Send + Sync + 'static>() -> Router<S> {
    FILES.iter().fold(Router::new(), |r, &(path, mime, body)| {
        r.route(path, get(move || async move { file(body, mime) }))
    })
}

fn file(body: &'static str, mime: &'static str) -> Response {
    let mut r = (StatusCode::OK, body).into_response();
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(mime));
    for (name, value) in [
        (header::CONTENT_SECURITY_POLICY, CSP),
        (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        (header::X_FRAME_OPTIONS, "DENY"),
        (header::REFERRER_POLICY, "no-referrer"),
        (header::CACHE_CONTROL, "no-cache"),
    ] {
        h.insert(name, HeaderValue::from_static(value));
    }
    r
}
