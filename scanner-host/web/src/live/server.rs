//! The live view's routes on the front ([`crate::front`]): the page and its scripts (embedded),
//! the stream (a WebSocket), and the finished scan's mesh and files (held in memory). Only these
//! fixed routes exist; the front has already checked the host, the origin and the token.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use axum::Router;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

use super::{Batch, Finished, Shared};
use crate::assets;
use crate::front::{Access, refusal};

/// Pages streaming at once; more are answered 503.
pub const MAX_PAGES: usize = 8;
/// A page that takes no message for this long is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// Most points in one message to a page.
const MESSAGE_POINTS: usize = 131_072;
/// How often a page's stream looks for news when nobody says there is some.
const POLL: Duration = Duration::from_millis(100);

#[derive(Clone)]
struct Live {
    shared: Arc<Shared>,
    access: Arc<Access>,
    pages: Arc<AtomicUsize>,
}

/// The live view's routes.
pub(super) fn router(shared: Arc<Shared>, access: Arc<Access>) -> Router {
    let live = Live {
        shared,
        access,
        pages: Arc::new(AtomicUsize::new(0)),
    };
    Router::new()
        .route("/", get(page))
        .route("/index.html", get(page))
        .route("/app.js", get(|| async { assets::js(assets::LIVE_APP) }))
        .merge(assets::three_routes())
        .route("/live", get(stream))
        .route("/mesh.bin", get(mesh))
        .route("/files/{name}", get(file))
        .fallback(|| async { refusal(StatusCode::NOT_FOUND, "no_such_page", "nothing here") })
        .with_state(live)
}

async fn page(State(l): State<Live>) -> Response {
    let q = l
        .access
        .token()
        .map_or(String::new(), |t| format!("?token={t}"));
    assets::html(&assets::LIVE_PAGE.replace("{{Q}}", &q))
}

fn finished(shared: &Shared) -> Option<Arc<Finished>> {
    shared.lock().finished.clone()
}

async fn mesh(State(l): State<Live>) -> Response {
    match finished(&l.shared) {
        Some(f) if !f.mesh.is_empty() => (
            [(header::CONTENT_TYPE, "application/octet-stream")],
            f.mesh.clone(),
        )
            .into_response(),
        _ => refusal(
            StatusCode::NOT_FOUND,
            "not_finished",
            "no mesh yet: the scan has not finished",
        ),
    }
}

async fn file(State(l): State<Live>, Path(name): Path<String>) -> Response {
    let Some(f) = finished(&l.shared) else {
        return refusal(StatusCode::NOT_FOUND, "not_finished", "nothing here yet");
    };
    match f.files.iter().find(|(n, _, _)| *n == name) {
        Some((n, kind, bytes)) => (
            [
                (header::CONTENT_TYPE, (*kind).to_string()),
                (
                    header::CONTENT_DISPOSITION,
                    format!("attachment; filename=\"{n}\""),
                ),
            ],
            bytes.clone(),
        )
            .into_response(),
        None => refusal(
            StatusCode::NOT_FOUND,
            "no_such_file",
            "no such output of this scan",
        ),
    }
}

/// A page's slot among [`MAX_PAGES`], given back when dropped.
struct Slot(Arc<AtomicUsize>);

impl Slot {
    fn take(count: &Arc<AtomicUsize>) -> Option<Slot> {
        let before = count.fetch_add(1, Ordering::SeqCst);
        let slot = Slot(count.clone());
        (before < MAX_PAGES).then_some(slot)
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

async fn stream(
    State(l): State<Live>,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Response {
    let Ok(ws) = ws else {
        return refusal(
            StatusCode::BAD_REQUEST,
            "not_websocket",
            "/live is a WebSocket",
        );
    };
    let Some(slot) = Slot::take(&l.pages) else {
        return refusal(
            StatusCode::SERVICE_UNAVAILABLE,
            "too_many_pages",
            format!("{MAX_PAGES} pages are open already: close one"),
        );
    };
    // the page sends nothing but control frames: small limits
    ws.max_message_size(64 << 10)
        .max_frame_size(64 << 10)
        .on_upgrade(move |socket| async move {
            let _slot = slot;
            run_stream(socket, &l.shared).await;
        })
}

/// What a page has not seen yet.
struct News {
    batches: Vec<Arc<Batch>>,
    status: Option<(u64, String)>,
    preview: Option<(u64, String)>,
    done: Option<Arc<Finished>>,
    colour: bool,
}

/// The page's stream: the history, then what follows, until the page closes or the server does.
async fn run_stream(mut ws: WebSocket, shared: &Shared) {
    let (mut seq, mut status_seen, mut preview_seen, mut finished_sent) = (0u64, None, None, false);
    loop {
        let news = {
            let h = shared.lock();
            let batches: Vec<Arc<Batch>> =
                h.batches.iter().filter(|b| b.seq > seq).cloned().collect();
            seq = h.next_seq;
            News {
                batches,
                status: h
                    .status
                    .as_ref()
                    .filter(|(n, _)| Some(*n) != status_seen)
                    .cloned(),
                preview: h
                    .preview
                    .as_ref()
                    .filter(|(n, _)| Some(*n) != preview_seen)
                    .cloned(),
                done: h.finished.clone().filter(|_| !finished_sent),
                colour: h.colour,
            }
        };
        let mut out = points_messages(&news.batches, news.colour);
        if let Some((n, text)) = news.status {
            status_seen = Some(n);
            out.push(Message::Text(text.into()));
        }
        if let Some((n, text)) = news.preview {
            preview_seen = Some(n);
            out.push(Message::Text(text.into()));
        }
        if let Some(f) = news.done {
            finished_sent = true;
            out.push(Message::Text(f.json.clone().into()));
        }
        for m in out {
            match tokio::time::timeout(WRITE_TIMEOUT, ws.send(m)).await {
                Ok(Ok(())) => {}
                _ => return,
            }
        }
        if shared.closing.load(Ordering::SeqCst) {
            let _ = ws.send(Message::Close(None)).await;
            return;
        }
        tokio::select! {
            m = ws.recv() => match m {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                Some(Ok(_)) => {}
            },
            () = shared.news.notified() => {}
            () = tokio::time::sleep(POLL) => {}
        }
    }
}

/// Batches as binary messages of at most [`MESSAGE_POINTS`] points: `u8` kind (1), `u8` flags
/// (bit 0: the points' own colour), two zero bytes, `u32` count, then x, y, z as `f32` per
/// point and r, g, b per point; little-endian.
fn points_messages(batches: &[Arc<Batch>], colour: bool) -> Vec<Message> {
    let mut out = Vec::new();
    let mut pending: Vec<(&[f32], &[u8])> = Vec::new();
    let mut count = 0;
    for b in batches {
        let mut at = 0;
        while at < b.len() {
            let take = (b.len() - at).min(MESSAGE_POINTS - count);
            pending.push((
                &b.xyz[3 * at..3 * (at + take)],
                &b.rgb[3 * at..3 * (at + take)],
            ));
            count += take;
            at += take;
            if count == MESSAGE_POINTS {
                out.push(points_message(&mut pending, &mut count, colour));
            }
        }
    }
    if count > 0 {
        out.push(points_message(&mut pending, &mut count, colour));
    }
    out
}

fn points_message(pending: &mut Vec<(&[f32], &[u8])>, count: &mut usize, colour: bool) -> Message {
    let mut m = Vec::with_capacity(8 + *count * 15);
    m.extend_from_slice(&[1, u8::from(colour), 0, 0]);
    m.extend_from_slice(&(*count as u32).to_le_bytes());
    for (xyz, _) in pending.iter() {
        for v in *xyz {
            m.extend_from_slice(&v.to_le_bytes());
        }
    }
    for (_, rgb) in pending.iter() {
        m.extend_from_slice(rgb);
    }
    pending.clear();
    *count = 0;
    Message::Binary(m.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_split_into_messages_of_the_stated_layout() {
        let b = Arc::new(Batch {
            seq: 1,
            xyz: vec![1.0; 3 * (MESSAGE_POINTS + 5)],
            rgb: vec![7; 3 * (MESSAGE_POINTS + 5)],
        });
        let m = points_messages(&[b], true);
        assert_eq!(m.len(), 2);
        let Message::Binary(last) = &m[1] else {
            panic!("binary")
        };
        assert_eq!(&last[..4], &[1, 1, 0, 0]);
        assert_eq!(&last[4..8], &5u32.to_le_bytes());
        assert_eq!(last.len(), 8 + 5 * 15);
    }
}
