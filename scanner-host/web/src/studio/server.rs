//! The studio's routes on the front ([`crate::front`]): the page, the job as JSON, the head's
//! commands, the merge, the pictures, the 3-D viewer's model and views, and the model's files.
//! Only fixed routes exist; files are fixed names in the project folder, opened with the
//! front's rules (regular files only, no link followed). The front has already checked the
//! host, the origin and the token; every request that changes anything is a `POST` of JSON.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering;

use axum::Router;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;

use super::job::{MAX_VIEWS, Merge};
use super::{MODEL_FILES, MergeFailed, PageCommand, Studio, merge_verdict};
use crate::assets;
use crate::front::{
    Access, FrontError, FrontLimits, Served, download, json_body, read_inside, refusal, serve,
};

/// Largest file offered for download, bytes.
const MAX_FILE: u64 = 512 << 20;
/// Largest model the 3-D viewer is sent, bytes of binary STL (about 1.3 million triangles).
const MAX_VIEWER_MODEL: u64 = 64 << 20;
/// Most points of one view the 3-D viewer is sent.
const VIEWER_POINTS: usize = 200_000;
/// Most points one answer of the open view carries (the page asks again for the rest).
const POINTS_PER_ANSWER: usize = 20_000;

/// The running server.
pub struct StudioServer {
    /// The page's address (with the token when one is needed).
    pub url: String,
    served: Served,
}

impl StudioServer {
    /// Serves `studio` on `addr` behind the front: loopback names and addresses, `addr`'s own
    /// and `names` as hosts; a token is drawn when `addr` is not a loopback address.
    ///
    /// # Errors
    /// [`FrontError`]: the address cannot be bound, no token can be drawn.
    pub fn start(
        addr: SocketAddr,
        names: &[String],
        studio: Arc<Studio>,
    ) -> Result<StudioServer, FrontError> {
        let served = serve(
            addr,
            names,
            FrontLimits::DEFAULT,
            "studio-http",
            move |access| router(studio, &access),
        )?;
        Ok(StudioServer {
            url: served.url("/"),
            served,
        })
    }

    /// The address served.
    pub fn addr(&self) -> SocketAddr {
        self.served.addr
    }

    /// Stops answering.
    pub fn stop(self) {
        self.served.stop();
    }
}

fn router(studio: Arc<Studio>, access: &Access) -> Router {
    let page = assets::STUDIO_PAGE.replace(
        "{{Q}}",
        &access
            .token()
            .map_or(String::new(), |t| format!("?token={t}")),
    );
    Router::new()
        .route("/", get(move || async move { assets::html(&page) }))
        .route(
            "/studio.js",
            get(|| async { assets::js(assets::STUDIO_SCRIPT) }),
        )
        .route(
            "/viewer.js",
            get(|| async { assets::js(assets::STUDIO_VIEWER) }),
        )
        .merge(assets::three_routes())
        .route("/api/state", get(state))
        .route("/api/preview.png", get(preview_png))
        .route("/api/picture.jpg", get(picture_jpg))
        .route("/api/points", get(points))
        .route("/api/overlay.png", get(overlay))
        .route("/api/model.stl", get(model_stl))
        .route("/api/view/{n}/points", get(view_points))
        .route("/files/{name}", get(file))
        .route("/files/view/{n}/{name}", get(view_file))
        .route("/api/view-model", post(view_model))
        .route("/api/command", post(command))
        .route("/api/merge", post(merge))
        .route("/api/view", post(view))
        .fallback(|| async { refusal(StatusCode::NOT_FOUND, "no_such_page", "no such page") })
        .with_state(studio)
}

fn json(status: StatusCode, v: &serde_json::Value) -> Response {
    (
        status,
        [(header::CACHE_CONTROL, "no-store")],
        axum::Json(v.clone()),
    )
        .into_response()
}

async fn state(State(studio): State<Arc<Studio>>) -> Response {
    let job = studio.link.shared.job();
    let mut v = serde_json::to_value(&*job).unwrap_or_default();
    // the coverage map as 64 characters, cell i (row by row) the i-th: a 64-bit number
    // would lose its last rows as a JavaScript number
    v["cover"] = format!("{:064b}", job.cover().reverse_bits()).into();
    let guide = super::guide::guide(&job);
    if let Some(c) = &job.calibration {
        v["verdicts"] =
            serde_json::to_value(super::guide::verdicts(c, &guide, job.preview.as_ref()))
                .unwrap_or_default();
    }
    v["guide"] = serde_json::to_value(guide).unwrap_or_default();
    // a sweep asked for whose first frame has not come: the head takes its reference
    v["sweep_starting"] = job.awaiting_sweep.into();
    if let Some(p) = &job.preview {
        v["camera_advice"] =
            serde_json::to_value(super::camera::advice(p, &job.camera)).unwrap_or_default();
    }
    v["link_closed"] = studio.link.shared.closed.load(Ordering::SeqCst).into();
    json(StatusCode::OK, &v)
}

async fn preview_png(State(studio): State<Arc<Studio>>) -> Response {
    let picture = studio.link.shared.job().picture.clone();
    let Some((w, h, pixels)) = picture else {
        return refusal(
            StatusCode::NOT_FOUND,
            "no_preview",
            "no preview yet: press Preview on",
        );
    };
    let Some(img) = image::GrayImage::from_raw(u32::from(w), u32::from(h), pixels) else {
        return refusal(
            StatusCode::INTERNAL_SERVER_ERROR,
            "bad_preview",
            "a preview of the wrong size",
        );
    };
    let mut png = Vec::new();
    if img
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .is_err()
    {
        return refusal(
            StatusCode::INTERNAL_SERVER_ERROR,
            "bad_preview",
            "the preview could not be encoded",
        );
    }
    (
        [
            (header::CONTENT_TYPE, "image/png"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        png,
    )
        .into_response()
}

#[derive(Deserialize)]
struct From {
    #[serde(default)]
    from: u64,
    #[serde(default)]
    r#gen: u64,
}

/// The open view's points from `?from=N` of generation `&gen=G` (a page of another generation
/// starts again from 0): `{"view", "generation", "from", "points": [x, y, z, …]}`.
async fn points(
    State(studio): State<Arc<Studio>>,
    q: Result<Query<From>, QueryRejection>,
) -> Response {
    let (from, generation) = q.map_or((0, 0), |Query(f)| (f.from, f.r#gen));
    let job = studio.link.shared.job();
    let live = &job.live;
    let from = if generation == u64::from(live.generation) {
        usize::try_from(from)
            .unwrap_or(usize::MAX)
            .min(live.xyz.len())
    } else {
        0
    };
    let to = (from + POINTS_PER_ANSWER).min(live.xyz.len());
    let flat: Vec<f32> = live.xyz[from..to].iter().flatten().copied().collect();
    json(
        StatusCode::OK,
        &serde_json::json!({
            "view": live.view,
            "generation": live.generation,
            "from": from,
            "points": flat,
        }),
    )
}

async fn picture_jpg(State(studio): State<Arc<Studio>>) -> Response {
    let (jpeg, frame) = {
        let job = studio.link.shared.job();
        (
            job.jpeg.clone(),
            job.sharpness.as_ref().map_or(0, |s| s.frame),
        )
    };
    match jpeg {
        Some(j) => (
            [
                (header::CONTENT_TYPE, "image/jpeg".to_string()),
                (header::CACHE_CONTROL, "no-store".to_string()),
                (
                    header::HeaderName::from_static("x-frame"),
                    frame.to_string(),
                ),
            ],
            j,
        )
            .into_response(),
        None => refusal(
            StatusCode::NOT_FOUND,
            "no_picture",
            "no picture yet: press Preview on",
        ),
    }
}

/// The head's answer to a command from the page, in words and by kind.
async fn command(State(studio): State<Arc<Studio>>, req: Request) -> Response {
    let v = match json_body(req, &FrontLimits::DEFAULT).await {
        Ok(v) => v,
        Err(r) => return r,
    };
    let cmd: scanner_wire::Command = match serde_json::from_value::<PageCommand>(v) {
        Ok(c) => c.into(),
        Err(why) => {
            return json(
                StatusCode::BAD_REQUEST,
                &serde_json::json!({"outcome": "bad_request", "words": why.to_string()}),
            );
        }
    };
    let asked = tokio::task::spawn_blocking(move || studio.send(cmd)).await;
    match asked {
        Ok(Ok((r, said))) => json(
            StatusCode::OK,
            &serde_json::json!({
                "outcome": r.outcome.name(),
                "field": r.field,
                "detail": r.detail,
                "words": said,
            }),
        ),
        Ok(Err(e)) => {
            let mut v = serde_json::json!({"outcome": e.kind(), "words": e.to_string()});
            if let super::SendError::NotReady(asks) = &e {
                v["asks"] = serde_json::to_value(asks).unwrap_or_default();
            }
            json(e.status(), &v)
        }
        Err(_) => refusal(
            StatusCode::INTERNAL_SERVER_ERROR,
            "failed",
            "the command's thread failed",
        ),
    }
}

/// The answer to work started in its own thread: accepted, or why it could not start.
fn accepted<T>(started: std::io::Result<std::thread::JoinHandle<T>>, what: &str) -> Response {
    match started {
        Ok(_) => json(
            StatusCode::ACCEPTED,
            &serde_json::json!({"outcome": "accepted"}),
        ),
        Err(e) => refusal(
            StatusCode::INTERNAL_SERVER_ERROR,
            "failed",
            format!("cannot start {what}: {e}"),
        ),
    }
}

/// Makes the model of one view alone (`{"view": N}`, from 1): the host's outputs of its
/// journal in `views/view-N/` — a fixed-laser turntable's whole model, or one view's surface.
async fn view_model(State(studio): State<Arc<Studio>>, req: Request) -> Response {
    let v = match json_body(req, &FrontLimits::DEFAULT).await {
        Ok(v) => v,
        Err(r) => return r,
    };
    let n = usize::try_from(v["view"].as_u64().unwrap_or(0)).unwrap_or(0);
    let journal = {
        let mut job = studio.link.shared.job();
        let Some(view) = n.checked_sub(1).and_then(|k| job.views.get_mut(k)) else {
            return refusal(StatusCode::BAD_REQUEST, "no_such_view", "no such view");
        };
        if !view.done {
            return json(
                StatusCode::CONFLICT,
                &serde_json::json!({"outcome": "busy", "words": "its sweep runs: wait for it to end, or press Stop"}),
            );
        }
        if view.model.as_ref().is_some_and(|m| m.state == "running") {
            return json(
                StatusCode::CONFLICT,
                &serde_json::json!({"outcome": "busy", "words": "its model is being made already"}),
            );
        }
        if view.points == 0 {
            return json(
                StatusCode::CONFLICT,
                &serde_json::json!({"outcome": "no_points", "words": "this view has no points: sweep again"}),
            );
        }
        view.model = Some(super::job::ViewModel {
            state: "running".into(),
            error: None,
            files: Vec::new(),
            summary: None,
        });
        let journal = studio.project().join(&view.journal);
        job.say(format!("view {n}: making its model"));
        journal
    };
    let s = studio.clone();
    let started = std::thread::Builder::new()
        .name("studio-view-model".into())
        .spawn(move || {
            let dir = format!("view-{n}");
            let out = s.project().join("views").join(&dir);
            let made = scanner_host::outputs::replay(
                scanner_host::collect::CollectOptions::default(),
                &journal,
                0.0,
            )
            .and_then(|c| {
                scanner_host::write_outputs(&c, &out, &scanner_host::OutputOptions::default())
            });
            let summary = read_inside(s.project(), &["views", &dir, "summary.json"], 16 << 20)
                .ok()
                .and_then(|b| serde_json::from_slice(&b).ok());
            let files = scanner_host::outputs::OUTPUT_FILES
                .iter()
                .filter(|f| out.join(f).is_file())
                .map(|f| (*f).to_string())
                .collect();
            let mut job = s.link.shared.job();
            let line = match &made {
                Ok(_) => format!("view {n}: its model is ready to download"),
                Err(e) => format!("view {n}: no model: {e}"),
            };
            if let Some(view) = job.views.get_mut(n - 1) {
                view.model = Some(super::job::ViewModel {
                    state: if made.is_ok() { "made" } else { "failed" }.into(),
                    error: made.err().map(|e| e.to_string()),
                    files,
                    summary,
                });
            }
            job.say(line);
            if let Err(e) = job.save(s.project()) {
                job.say(e.to_string());
            }
        });
    accepted(started, "the view's model")
}

/// A file of one view's model, by the view's number (from 1) and a name from the host's fixed
/// list of outputs.
async fn view_file(
    State(studio): State<Arc<Studio>>,
    Path((n, name)): Path<(usize, String)>,
) -> Response {
    let Some(name) = scanner_host::outputs::OUTPUT_FILES
        .iter()
        .find(|f| **f == name)
    else {
        return refusal(StatusCode::NOT_FOUND, "no_such_file", "no such file");
    };
    if n == 0 || n > MAX_VIEWS {
        return refusal(StatusCode::NOT_FOUND, "no_such_view", "no such view");
    }
    download(
        studio.project(),
        &["views", &format!("view-{n}"), name],
        MAX_FILE,
        media_type(name),
    )
}

/// A download's media type, by its file's extension.
fn media_type(name: &str) -> &'static str {
    match name.rsplit('.').next() {
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("3mf") => "model/3mf",
        Some("stl") => "model/stl",
        Some("obj") => "model/obj",
        Some("txt") => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

/// Leaves a view out of the merge, or takes it back (`{"view": N, "left_out": true}`, from 1).
async fn view(State(studio): State<Arc<Studio>>, req: Request) -> Response {
    let v = match json_body(req, &FrontLimits::DEFAULT).await {
        Ok(v) => v,
        Err(r) => return r,
    };
    let mut job = studio.link.shared.job();
    let n = v["view"].as_u64().unwrap_or(0);
    let Some(view) = usize::try_from(n)
        .ok()
        .and_then(|n| n.checked_sub(1))
        .and_then(|k| job.views.get_mut(k))
    else {
        return refusal(StatusCode::BAD_REQUEST, "no_such_view", "no such view");
    };
    view.left_out = v["left_out"].as_bool().unwrap_or(false);
    if let Err(e) = job.save(studio.project()) {
        job.say(e.to_string());
    }
    json(StatusCode::OK, &serde_json::json!({"outcome": "accepted"}))
}

/// Starts the merge (`{"min_overlap": 0.4}`: the least share of a view's points another
/// must bring close, 0.1–0.9).
async fn merge(State(studio): State<Arc<Studio>>, req: Request) -> Response {
    let v = match json_body(req, &FrontLimits::DEFAULT).await {
        Ok(v) => v,
        Err(r) => return r,
    };
    let overlap = v["min_overlap"].as_f64().unwrap_or(0.4);
    if !(0.1..=0.9).contains(&overlap) {
        return json(
            StatusCode::BAD_REQUEST,
            &serde_json::json!({"outcome": "out_of_range", "words": "the least overlap is 0.1 to 0.9"}),
        );
    }
    let views = {
        let mut job = studio.link.shared.job();
        if job.merge.as_ref().is_some_and(|m| m.state == "running") {
            return json(
                StatusCode::CONFLICT,
                &serde_json::json!({"outcome": "busy", "words": "a merge runs already"}),
            );
        }
        if job.views.iter().any(|v| !v.done) || job.awaiting_sweep {
            return json(
                StatusCode::CONFLICT,
                &serde_json::json!({"outcome": "busy", "words": "a sweep runs: wait for it to end, or press Stop"}),
            );
        }
        let (views, left) = job.merge_views(studio.project());
        if views.len() < 2 {
            return json(
                StatusCode::CONFLICT,
                &serde_json::json!({"outcome": "too_few_views", "words": "a merge needs two views or more: turn the disc and take another"}),
            );
        }
        for (n, why) in &left {
            job.say(format!("view {n} is left out of the merge: {why}"));
        }
        let papers: Vec<Option<String>> = job
            .views
            .iter()
            .filter(|v| v.done && !v.left_out && v.points > 0)
            .map(|v| v.disc_paper.clone())
            .collect();
        job.merge = Some(Merge {
            state: "running".into(),
            error: None,
            refusal: None,
            report: None,
            files: Vec::new(),
            left_out: left
                .iter()
                .map(|(n, why)| super::job::LeftOut {
                    view: *n,
                    why: (*why).to_string(),
                })
                .collect(),
            problems: Vec::new(),
        });
        job.say(format!("merging {} views", views.len()));
        (views, papers)
    };
    let (taken, papers) = views;
    let (numbers, views): (Vec<usize>, Vec<std::path::PathBuf>) = taken.into_iter().unzip();
    let s = studio.clone();
    let started = std::thread::Builder::new()
        .name("studio-merge".into())
        .spawn(move || {
            let out = s.project().join("model");
            let result = (s.merge)(&views, &out, overlap);
            let report: Option<serde_json::Value> =
                read_inside(s.project(), &["model", "merge-report.json"], 64 << 20)
                    .ok()
                    .and_then(|b| serde_json::from_slice(&b).ok());
            let mut job = s.link.shared.job();
            let files = MODEL_FILES
                .iter()
                .filter(|f| out.join(f).is_file())
                .map(|f| (*f).to_string())
                .collect();
            let left_out = job
                .merge
                .as_mut()
                .map(|m| std::mem::take(&mut m.left_out))
                .unwrap_or_default();
            let problems = merge_verdict(report.as_ref(), &papers);
            let refusal = match &result {
                Err(MergeFailed::Refused(e)) => {
                    Some(super::merge_words::merge_refusal(e, &numbers))
                }
                _ => None,
            };
            let (state, error) = match result {
                Ok(()) if problems.is_empty() => ("merged", None),
                Ok(()) => ("refused", None),
                Err(e) => (
                    if report.is_some() || refusal.is_some() {
                        "refused"
                    } else {
                        "failed"
                    },
                    Some(
                        refusal
                            .as_ref()
                            .map_or_else(|| e.to_string(), |r| r.words.clone()),
                    ),
                ),
            };
            job.merge = Some(Merge {
                state: state.into(),
                error,
                refusal,
                report,
                files,
                left_out,
                problems,
            });
            let line = match state {
                "merged" => "merged: the model is ready to download".to_string(),
                _ => {
                    let problems = job.merge.as_ref().map_or(Vec::new(), |m| {
                        m.problems.iter().map(|p| p.words.clone()).collect()
                    });
                    if problems.is_empty() {
                        "the merge was refused: see its report".to_string()
                    } else {
                        format!("the merge was refused: {}", problems.join("; "))
                    }
                }
            };
            job.say(line);
            if let Err(e) = job.save(s.project()) {
                job.say(e.to_string());
            }
        });
    accepted(started, "the merge")
}

/// The board's calibration overlay (what `calibrate board` found), where a child head left it
/// in the project folder (a Pi head keeps its own).
async fn overlay(State(studio): State<Arc<Studio>>) -> Response {
    match read_inside(
        studio.project(),
        &["head", "calibration-overlay.png"],
        MAX_FILE,
    ) {
        Ok(png) => (
            [
                (header::CONTENT_TYPE, "image/png"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            png,
        )
            .into_response(),
        Err(e) => refusal(StatusCode::NOT_FOUND, e.kind(), e),
    }
}

/// The merged model as binary STL, for the 3-D viewer.
async fn model_stl(State(studio): State<Arc<Studio>>) -> Response {
    match read_inside(studio.project(), &["model", "model.stl"], MAX_VIEWER_MODEL) {
        Ok(stl) => (
            [
                (header::CONTENT_TYPE, "model/stl"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            stl,
        )
            .into_response(),
        Err(e) => refusal(StatusCode::NOT_FOUND, e.kind(), e),
    }
}

/// One view's points (from 1), read from its journal and thinned to at most
/// [`VIEWER_POINTS`]: `{"view", "points": [x, y, z, …], "total"}`, mm, camera coordinates.
async fn view_points(State(studio): State<Arc<Studio>>, Path(n): Path<usize>) -> Response {
    let journal = {
        let job = studio.link.shared.job();
        match n
            .checked_sub(1)
            .filter(|k| *k < MAX_VIEWS)
            .and_then(|k| job.views.get(k))
        {
            Some(v) => v.journal.clone(),
            None => return refusal(StatusCode::NOT_FOUND, "no_such_view", "no such view"),
        }
    };
    let project = studio.project().to_path_buf();
    let read = tokio::task::spawn_blocking(move || {
        super::job::read_journal(&project, &journal, VIEWER_POINTS)
    })
    .await;
    match read {
        Ok(Ok(r)) => json(
            StatusCode::OK,
            &serde_json::json!({
                "view": n,
                "total": r.points,
                "points": r.xyz.iter().flatten().collect::<Vec<_>>(),
            }),
        ),
        Ok(Err(e)) => refusal(StatusCode::NOT_FOUND, e.kind(), e),
        Err(_) => refusal(
            StatusCode::INTERNAL_SERVER_ERROR,
            "failed",
            "the reading thread failed",
        ),
    }
}

async fn file(State(studio): State<Arc<Studio>>, Path(name): Path<String>) -> Response {
    let Some(name) = MODEL_FILES.iter().find(|f| **f == name) else {
        return refusal(StatusCode::NOT_FOUND, "no_such_file", "no such file");
    };
    download(
        studio.project(),
        &["model", name],
        MAX_FILE,
        media_type(name),
    )
}
