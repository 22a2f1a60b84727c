//! The studio's HTTP server (`tiny_http`): the page, the job as JSON, the head's commands, the
//! merge, the preview picture and the model's files. Every limit is stated here.
//!
//! Who may ask: on a loopback address, the machine's own user; beyond it, only requests that
//! carry the token printed at the start (`?token=` on the page's address, then the
//! `x-studio-token` header). Requests that change anything are `POST`s with a JSON body, from
//! the studio's own page: another site's page cannot send them (a cross-site `Origin` is
//! refused, and a form cannot send JSON without the browser asking first).

use std::io::Read;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use tiny_http::{Header, Method, Request, Response, Server};

use super::job::Merge;
use super::{MODEL_FILES, REPLY_WITHIN, Studio, command_of, words};

/// Largest request body, bytes (a command is a few fields).
pub const MAX_BODY: usize = 4096;
/// Threads answering requests.
const WORKERS: usize = 4;
/// Largest file offered for download, bytes.
const MAX_FILE: u64 = 512 << 20;

static PAGE: &str = include_str!("../../web/studio.html");
static SCRIPT: &str = include_str!("../../web/studio.js");

/// The running server.
pub struct StudioServer {
    /// The page's address (with the token when one is needed).
    pub url: String,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl StudioServer {
    /// Serves `studio` on `addr` (a token is drawn when it is not a loopback address).
    ///
    /// # Errors
    /// The address cannot be bound, no token can be drawn.
    pub fn start(addr: SocketAddr, studio: Arc<Studio>) -> Result<StudioServer, String> {
        let server = Server::http(addr).map_err(|e| format!("cannot serve on {addr}: {e}"))?;
        let bound = server
            .server_addr()
            .to_ip()
            .ok_or_else(|| format!("{addr} is no IP address"))?;
        let token = if addr.ip().is_loopback() {
            None
        } else {
            let mut b = [0u8; 16];
            getrandom::fill(&mut b).map_err(|e| format!("cannot draw a token: {e}"))?;
            Some(b.iter().map(|x| format!("{x:02x}")).collect::<String>())
        };
        let url = match &token {
            Some(t) => format!("http://{bound}/?token={t}"),
            None => format!("http://{bound}/"),
        };
        let server = Arc::new(server);
        let stop = Arc::new(AtomicBool::new(false));
        let mut threads = Vec::new();
        for k in 0..WORKERS {
            let (server, studio, stop, token) =
                (server.clone(), studio.clone(), stop.clone(), token.clone());
            let t = std::thread::Builder::new()
                .name(format!("studio-http-{k}"))
                .spawn(move || {
                    while !stop.load(Ordering::SeqCst) {
                        match server.recv_timeout(Duration::from_millis(100)) {
                            Ok(Some(req)) => handle(req, &studio, token.as_deref()),
                            Ok(None) => {}
                            Err(_) => std::thread::sleep(Duration::from_millis(10)),
                        }
                    }
                })
                .map_err(|e| format!("cannot start the server's threads: {e}"))?;
            threads.push(t);
        }
        Ok(StudioServer { url, stop, threads })
    }

    /// Stops answering.
    pub fn stop(self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads {
            let _ = t.join();
        }
    }
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("a valid header")
}

fn text(status: u16, body: impl Into<String>) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_string(body.into())
        .with_status_code(status)
        .with_header(header("Content-Type", "text/plain; charset=utf-8"))
}

fn json(status: u16, v: &serde_json::Value) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_string(v.to_string())
        .with_status_code(status)
        .with_header(header("Content-Type", "application/json"))
        .with_header(header("Cache-Control", "no-store"))
}

fn value_of<'r>(req: &'r Request, name: &'static str) -> Option<&'r str> {
    req.headers()
        .iter()
        .find(|h| h.field.equiv(name))
        .map(|h| h.value.as_str())
}

/// Whether the request carries the token, where one is needed.
fn allowed(req: &Request, token: Option<&str>) -> bool {
    let Some(t) = token else { return true };
    let in_query = req
        .url()
        .split_once('?')
        .is_some_and(|(_, q)| q.split('&').any(|kv| kv == format!("token={t}")));
    in_query || value_of(req, "x-studio-token") == Some(t)
}

/// Whether a `POST` comes from the studio's own page: JSON, and no other site's origin.
fn same_site(req: &Request) -> Result<(), &'static str> {
    let json = value_of(req, "Content-Type").is_some_and(|v| v.starts_with("application/json"));
    if !json {
        return Err("send JSON (Content-Type: application/json)");
    }
    if let Some(origin) = value_of(req, "Origin") {
        let host = value_of(req, "Host").unwrap_or("");
        if origin != format!("http://{host}") {
            return Err("a request from another site's page");
        }
    }
    Ok(())
}

fn handle(mut req: Request, studio: &Arc<Studio>, token: Option<&str>) {
    if !allowed(&req, token) {
        let _ = req.respond(text(
            403,
            "this studio needs its token: open the address it printed",
        ));
        return;
    }
    let path = req.url().split('?').next().unwrap_or("").to_string();
    let method = req.method().clone();
    let response = match (&method, path.as_str()) {
        (Method::Get, "/") => Response::from_string(PAGE)
            .with_header(header("Content-Type", "text/html; charset=utf-8")),
        (Method::Get, "/studio.js") => Response::from_string(SCRIPT)
            .with_header(header("Content-Type", "text/javascript; charset=utf-8")),
        (Method::Get, "/api/state") => state(studio),
        (Method::Get, "/api/preview.png") => preview_png(studio),
        (Method::Get, "/api/picture.jpg") => picture_jpg(studio),
        (Method::Get, "/api/points") => points(studio, req.url()),
        (Method::Get, "/api/overlay.png") => {
            let _ = req.respond(overlay(studio));
            return;
        }
        (Method::Get, p) if p.starts_with("/files/") => {
            let _ = req.respond(file(studio, &p["/files/".len()..]));
            return;
        }
        (Method::Post, "/api/command" | "/api/merge" | "/api/view") => {
            if let Err(why) = same_site(&req) {
                text(403, why)
            } else {
                match body(&mut req) {
                    Err(r) => r,
                    Ok(v) if path == "/api/command" => command(studio, &v),
                    Ok(v) if path == "/api/view" => view(studio, &v),
                    Ok(v) => merge(studio, &v),
                }
            }
        }
        (Method::Get | Method::Post, _) => text(404, "no such page"),
        _ => text(405, "GET or POST"),
    };
    let _ = req.respond(response);
}

fn body(req: &mut Request) -> Result<serde_json::Value, Response<std::io::Cursor<Vec<u8>>>> {
    if req.body_length().is_some_and(|n| n > MAX_BODY) {
        return Err(text(413, format!("a body of at most {MAX_BODY} bytes")));
    }
    let mut bytes = Vec::new();
    req.as_reader()
        .take(MAX_BODY as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|_| text(400, "the body could not be read"))?;
    if bytes.len() > MAX_BODY {
        return Err(text(413, format!("a body of at most {MAX_BODY} bytes")));
    }
    serde_json::from_slice(&bytes).map_err(|e| text(400, format!("the body is no JSON: {e}")))
}

fn state(studio: &Studio) -> Response<std::io::Cursor<Vec<u8>>> {
    let job = studio.link.shared.job();
    let mut v = serde_json::to_value(&*job).unwrap_or_default();
    v["cover"] = job.cover().into();
    v["link_closed"] = studio.link.shared.closed.load(Ordering::SeqCst).into();
    json(200, &v)
}

fn preview_png(studio: &Studio) -> Response<std::io::Cursor<Vec<u8>>> {
    let picture = studio.link.shared.job().picture.clone();
    let Some((w, h, pixels)) = picture else {
        return text(404, "no preview yet: switch the preview on");
    };
    let Some(img) = image::GrayImage::from_raw(u32::from(w), u32::from(h), pixels) else {
        return text(500, "a preview of the wrong size");
    };
    let mut png = Vec::new();
    if img
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .is_err()
    {
        return text(500, "the preview could not be encoded");
    }
    Response::from_data(png)
        .with_header(header("Content-Type", "image/png"))
        .with_header(header("Cache-Control", "no-store"))
}

/// Most points one answer carries (the page asks again for the rest).
const POINTS_PER_ANSWER: usize = 20_000;

/// The open view's points from `?from=N` of generation `&gen=G` (a page of another generation
/// starts again from 0): `{"view", "generation", "from", "points": [x, y, z, …]}`.
fn points(studio: &Studio, url: &str) -> Response<std::io::Cursor<Vec<u8>>> {
    let arg = |name: &str| -> u64 {
        url.split_once('?')
            .and_then(|(_, q)| {
                q.split('&')
                    .find_map(|kv| kv.strip_prefix(name)?.strip_prefix('='))
            })
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    let job = studio.link.shared.job();
    let live = &job.live;
    let from = if arg("gen") == u64::from(live.generation) {
        usize::try_from(arg("from"))
            .unwrap_or(usize::MAX)
            .min(live.xyz.len())
    } else {
        0
    };
    let to = (from + POINTS_PER_ANSWER).min(live.xyz.len());
    let flat: Vec<f32> = live.xyz[from..to].iter().flatten().copied().collect();
    json(
        200,
        &serde_json::json!({
            "view": live.view,
            "generation": live.generation,
            "from": from,
            "points": flat,
        }),
    )
}

fn picture_jpg(studio: &Studio) -> Response<std::io::Cursor<Vec<u8>>> {
    let (jpeg, frame) = {
        let job = studio.link.shared.job();
        (
            job.jpeg.clone(),
            job.sharpness.as_ref().map_or(0, |s| s.frame),
        )
    };
    match jpeg {
        Some(j) => Response::from_data(j)
            .with_header(header("Content-Type", "image/jpeg"))
            .with_header(header("Cache-Control", "no-store"))
            .with_header(header("X-Frame", &frame.to_string())),
        None => text(404, "no picture yet: switch the preview on"),
    }
}

fn command(studio: &Studio, v: &serde_json::Value) -> Response<std::io::Cursor<Vec<u8>>> {
    let cmd = match command_of(v) {
        Ok(c) => c,
        Err(why) => {
            return json(
                400,
                &serde_json::json!({"outcome": "bad_request", "words": why}),
            );
        }
    };
    if let scanner_wire::Command::Sweep(_) = cmd {
        studio.link.shared.job().awaiting_sweep = true;
    }
    match studio.link.ask(cmd, REPLY_WITHIN) {
        Ok(r) => {
            let said = words(&cmd, &r);
            let mut job = studio.link.shared.job();
            if r.outcome != scanner_wire::Outcome::Accepted {
                job.awaiting_sweep = false;
                job.say(said.clone());
            }
            json(
                200,
                &serde_json::json!({
                    "outcome": r.outcome.name(),
                    "field": r.field,
                    "detail": r.detail,
                    "words": said,
                }),
            )
        }
        Err(e) => json(
            504,
            &serde_json::json!({"outcome": "no_answer", "words": e.to_string()}),
        ),
    }
}

/// Leaves a view out of the merge, or takes it back (`{"view": N, "left_out": true}`, from 1).
fn view(studio: &Studio, v: &serde_json::Value) -> Response<std::io::Cursor<Vec<u8>>> {
    let mut job = studio.link.shared.job();
    let n = v["view"].as_u64().unwrap_or(0) as usize;
    let Some(view) = n.checked_sub(1).and_then(|k| job.views.get_mut(k)) else {
        return text(400, "no such view");
    };
    view.left_out = v["left_out"].as_bool().unwrap_or(false);
    let _ = job.save(studio.project());
    json(200, &serde_json::json!({"outcome": "accepted"}))
}

/// Starts the merge (`{"min_overlap": 0.4}`: the least share of a view's points another
/// must bring close, 0.1–0.9).
fn merge(studio: &Arc<Studio>, v: &serde_json::Value) -> Response<std::io::Cursor<Vec<u8>>> {
    let overlap = v["min_overlap"].as_f64().unwrap_or(0.4);
    if !(0.1..=0.9).contains(&overlap) {
        return json(
            400,
            &serde_json::json!({"outcome": "out_of_range", "words": "the least overlap is 0.1 to 0.9"}),
        );
    }
    let views = {
        let mut job = studio.link.shared.job();
        if job.merge.as_ref().is_some_and(|m| m.state == "running") {
            return text(409, "a merge runs");
        }
        let views = job.merge_views(studio.project());
        if views.len() < 2 {
            return json(
                409,
                &serde_json::json!({"outcome": "too_few_views", "words": "a merge needs two views or more: turn the disc and take another"}),
            );
        }
        job.merge = Some(Merge {
            state: "running".into(),
            error: None,
            report: None,
            files: Vec::new(),
        });
        job.say(format!("merging {} views", views.len()));
        views
    };
    let s = studio.clone();
    let started = std::thread::Builder::new()
        .name("studio-merge".into())
        .spawn(move || {
            let out = s.project().join("model");
            let result = (s.merge)(&views, &out, overlap);
            let report = std::fs::read(out.join("merge-report.json"))
                .ok()
                .and_then(|b| serde_json::from_slice(&b).ok());
            let mut job = s.link.shared.job();
            let files = MODEL_FILES
                .iter()
                .filter(|f| out.join(f).exists())
                .map(|f| (*f).to_string())
                .collect();
            job.merge = Some(match result {
                Ok(()) => Merge {
                    state: "merged".into(),
                    error: None,
                    report,
                    files,
                },
                Err(e) => Merge {
                    state: if report.is_some() {
                        "refused"
                    } else {
                        "failed"
                    }
                    .into(),
                    error: Some(e),
                    report,
                    files,
                },
            });
            let line = match job.merge.as_ref().map(|m| m.state.as_str()) {
                Some("merged") => "merged: the model is ready to download".to_string(),
                _ => "the merge was refused: see its report".to_string(),
            };
            job.say(line);
            let _ = job.save(s.project());
        });
    match started {
        Ok(_) => json(202, &serde_json::json!({"outcome": "accepted"})),
        Err(e) => text(500, format!("cannot start the merge: {e}")),
    }
}

/// The board's calibration overlay (what `calibrate board` found), where a child head left it
/// in the project folder (a Pi head keeps its own).
fn overlay(studio: &Studio) -> Response<Box<dyn Read + Send>> {
    let path = studio
        .project()
        .join("head")
        .join("calibration-overlay.png");
    match std::fs::File::open(&path) {
        Ok(f) => {
            let len = f
                .metadata()
                .ok()
                .and_then(|m| usize::try_from(m.len()).ok());
            Response::new(
                200.into(),
                vec![
                    header("Content-Type", "image/png"),
                    header("Cache-Control", "no-store"),
                ],
                Box::new(f) as Box<dyn Read + Send>,
                len,
                None,
            )
        }
        Err(_) => text(404, "no overlay: calibrate first (a Pi head keeps its own)").boxed(),
    }
}

fn file(studio: &Studio, name: &str) -> Response<Box<dyn Read + Send>> {
    let boxed = |r: Response<std::io::Cursor<Vec<u8>>>| r.boxed();
    let Some(name) = MODEL_FILES.iter().find(|f| **f == name) else {
        return boxed(text(404, "no such file"));
    };
    let path = studio.project().join("model").join(name);
    let Ok(f) = std::fs::File::open(&path) else {
        return boxed(text(404, "not written yet: merge first"));
    };
    let len = f.metadata().map_or(0, |m| m.len());
    if len > MAX_FILE {
        return boxed(text(
            413,
            "too large to offer here: take it from the project folder",
        ));
    }
    let kind = match name.rsplit('.').next() {
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("3mf") => "model/3mf",
        _ => "application/octet-stream",
    };
    Response::new(
        200.into(),
        vec![
            header("Content-Type", kind),
            header(
                "Content-Disposition",
                &format!("attachment; filename=\"{name}\""),
            ),
        ],
        Box::new(f) as Box<dyn Read + Send>,
        usize::try_from(len).ok(),
        None,
    )
}
