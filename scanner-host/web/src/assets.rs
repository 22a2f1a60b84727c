//! The pages' files, embedded in the binary: both pages, their scripts and three.js (the 3-D
//! viewer both use), with the answers that carry them.

use axum::Router;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::get;

/// The live view's page (`{{Q}}`: the token's query, or nothing).
pub static LIVE_PAGE: &str = include_str!("../assets/index.html");
/// The live view's script.
pub static LIVE_APP: &str = include_str!("../assets/app.js");
/// The studio's page.
pub static STUDIO_PAGE: &str = include_str!("../assets/studio.html");
/// The studio's script.
pub static STUDIO_SCRIPT: &str = include_str!("../assets/studio.js");
/// The studio's 3-D viewer (a module on three.js).
pub static STUDIO_VIEWER: &str = include_str!("../assets/viewer.js");
static THREE: &str = include_str!("../assets/vendor/three/three.module.min.js");
static ORBIT: &str = include_str!("../assets/vendor/three/OrbitControls.js");
static THREE_LICENSE: &str = include_str!("../assets/vendor/three/LICENSE");

/// An HTML page, not kept by the browser (a new build's page is read again).
pub fn html(body: &str) -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body.to_string(),
    )
        .into_response()
}

/// A script.
pub fn js(body: &'static str) -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        body,
    )
        .into_response()
}

/// three.js, its orbit controls and its licence, at `/vendor/…`.
pub fn three_routes<S: Clone + Send + Sync + 'static>() -> Router<S> {
    Router::new()
        .route("/vendor/three.module.min.js", get(|| async { js(THREE) }))
        .route("/vendor/OrbitControls.js", get(|| async { js(ORBIT) }))
        .route(
            "/vendor/three-LICENSE.txt",
            get(|| async {
                (
                    [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
                    THREE_LICENSE,
                )
            }),
        )
}
