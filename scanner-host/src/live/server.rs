//! The live view's server: a bounded accept loop on a `std` listener, request heads parsed by
//! `httparse`, the page's stream by `tungstenite`. Every limit is stated below; every answer
//! closes its connection. Only fixed routes exist: the page and its scripts (embedded), the
//! stream, and the finished scan's mesh and files (held in memory).

use std::io::{self, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use tungstenite::protocol::{Role, WebSocketConfig};
use tungstenite::{Message, WebSocket};

use super::{Batch, Finished, Shared};

/// Connections open at once; more are closed at once (counted).
pub const MAX_CONNECTIONS: usize = 32;
/// Pages streaming at once; more are answered 503.
pub const MAX_PAGES: usize = 8;
/// Largest request head (request line and headers), bytes.
pub const MAX_HEAD: usize = 8 * 1024;
/// Longest request target, bytes.
pub const MAX_TARGET: usize = 2048;
/// A request head must arrive within this time.
const READ_TIMEOUT: Duration = Duration::from_secs(5);
/// A page that reads nothing for this long is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// Most points in one message to a page.
const MESSAGE_POINTS: usize = 131_072;
/// How often a page's thread looks for a closed page or a closing server.
const POLL: Duration = Duration::from_millis(100);

static INDEX: &str = include_str!("../../web/index.html");
static APP: &str = include_str!("../../web/app.js");
static THREE: &[u8] = include_bytes!("../../web/vendor/three/three.module.min.js");
static ORBIT: &[u8] = include_bytes!("../../web/vendor/three/OrbitControls.js");
static THREE_LICENSE: &[u8] = include_bytes!("../../web/vendor/three/LICENSE");

const JS: &str = "text/javascript; charset=utf-8";
const TEXT: &str = "text/plain; charset=utf-8";

/// Starts the accept loop.
pub(super) fn spawn(listener: TcpListener, shared: Arc<Shared>) -> io::Result<JoinHandle<()>> {
    listener.set_nonblocking(true)?;
    std::thread::Builder::new()
        .name("view-server".into())
        .spawn(move || accept_loop(&listener, &shared))
}

/// Decrements a counter when dropped.
struct Slot(Arc<AtomicUsize>);

impl Slot {
    /// Takes one of `max` slots, or none.
    fn take(count: &Arc<AtomicUsize>, max: usize) -> Option<Slot> {
        let before = count.fetch_add(1, Ordering::SeqCst);
        let slot = Slot(count.clone());
        (before < max).then_some(slot)
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

fn accept_loop(listener: &TcpListener, shared: &Arc<Shared>) {
    let open = Arc::new(AtomicUsize::new(0));
    let pages = Arc::new(AtomicUsize::new(0));
    while !shared.closing.load(Ordering::SeqCst) {
        let stream = match listener.accept() {
            Ok((s, _)) => s,
            Err(_) => {
                // Nothing waiting (or a connection that vanished before it was accepted).
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        let Some(slot) = Slot::take(&open, MAX_CONNECTIONS) else {
            shared.refused.fetch_add(1, Ordering::Relaxed);
            continue;
        };
        let (conn, pages) = (shared.clone(), pages.clone());
        let spawned = std::thread::Builder::new()
            .name("view-conn".into())
            .spawn(move || {
                let _slot = slot;
                handle(stream, &conn, &pages);
            });
        // A thread that cannot start drops its connection (and the slot) with the closure.
        if spawned.is_err() {
            shared.refused.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Why a request head could not be read.
enum HeadError {
    TooLarge,
    Io,
}

/// Reads up to the blank line that ends a request head.
fn read_head(s: &mut TcpStream) -> Result<Vec<u8>, HeadError> {
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 1024];
    loop {
        let n = s.read(&mut buf).map_err(|_| HeadError::Io)?;
        if n == 0 {
            return Err(HeadError::Io);
        }
        head.extend_from_slice(&buf[..n]);
        if head.windows(4).any(|w| w == b"\r\n\r\n") {
            return Ok(head);
        }
        if head.len() >= MAX_HEAD {
            return Err(HeadError::TooLarge);
        }
    }
}

fn reason(code: u16) -> &'static str {
    match code {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        413 => "Content Too Large",
        414 => "URI Too Long",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

/// Writes a whole answer and closes.
fn reply(s: &mut TcpStream, code: u16, kind: &str, extra: &str, body: &[u8]) {
    let head = format!(
        "HTTP/1.1 {code} {}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\n{extra}Connection: close\r\n\r\n",
        reason(code),
        body.len()
    );
    let _ = s.write_all(head.as_bytes());
    let _ = s.write_all(body);
    let _ = s.flush();
}

fn refuse(s: &mut TcpStream, code: u16, why: &str) {
    reply(s, code, TEXT, "", format!("{why}\n").as_bytes());
}

/// Whether `query` carries `t=token`.
fn has_token(query: &str, token: &str) -> bool {
    query.split('&').any(|kv| {
        kv.strip_prefix("t=").is_some_and(|t| {
            // Compared in full whatever the first difference.
            t.len() == token.len()
                && t.bytes()
                    .zip(token.bytes())
                    .fold(0u8, |d, (a, b)| d | (a ^ b))
                    == 0
        })
    })
}

fn header<'b>(req: &httparse::Request<'_, 'b>, name: &str) -> Option<&'b str> {
    req.headers
        .iter()
        .find(|h| h.name.eq_ignore_ascii_case(name))
        .and_then(|h| std::str::from_utf8(h.value).ok())
}

/// What a request head asks for, decided from the head alone (no I/O, no state: fuzzed in
/// `fuzz/fuzz_targets/live_request.rs`): one of the fixed routes, or a refusal with its status
/// and reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Route<'h> {
    /// The page (`/`, `/index.html`).
    Page,
    /// The page's script.
    App,
    /// three.js.
    Three,
    /// three.js's orbit controls.
    Orbit,
    /// three.js's licence.
    ThreeLicense,
    /// The stream: a WebSocket upgrade with its key.
    Live {
        /// `Sec-WebSocket-Key`.
        key: &'h str,
    },
    /// The finished scan's mesh.
    Mesh,
    /// One of the finished scan's files, by name.
    File(&'h str),
    /// Refused: the status and why.
    Refuse(u16, String),
}

/// The refusal of a request head over [`MAX_HEAD`].
fn too_large() -> Route<'static> {
    Route::Refuse(431, format!("request head over {MAX_HEAD} bytes"))
}

/// Decides what the request head `head` asks for; `token`, when set, must come as `t=` in the
/// query.
pub fn route<'h>(head: &'h [u8], token: Option<&str>) -> Route<'h> {
    let refuse = |code, why: &str| Route::Refuse(code, why.to_string());
    if head.len() > MAX_HEAD {
        return too_large();
    }
    let mut headers = [httparse::EMPTY_HEADER; 48];
    let mut req = httparse::Request::new(&mut headers);
    if !matches!(req.parse(head), Ok(httparse::Status::Complete(_))) {
        return refuse(400, "not an HTTP request");
    }
    let (Some(method), Some(target)) = (req.method, req.path) else {
        return refuse(400, "not an HTTP request");
    };
    if target.len() > MAX_TARGET {
        return Route::Refuse(414, format!("request target over {MAX_TARGET} bytes"));
    }
    if method != "GET" {
        return refuse(405, "only GET is served");
    }
    let body = header(&req, "content-length").is_some_and(|v| v.trim() != "0")
        || header(&req, "transfer-encoding").is_some();
    if body {
        return refuse(413, "requests carry no body here");
    }
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    if let Some(t) = token
        && !has_token(query, t)
    {
        return refuse(
            403,
            "this page needs the token that scanner-host printed with its address",
        );
    }
    match path {
        "/" | "/index.html" => Route::Page,
        "/app.js" => Route::App,
        "/vendor/three.module.min.js" => Route::Three,
        "/vendor/OrbitControls.js" => Route::Orbit,
        "/vendor/three-LICENSE.txt" => Route::ThreeLicense,
        "/live" => {
            let upgrade =
                header(&req, "upgrade").is_some_and(|v| v.eq_ignore_ascii_case("websocket"));
            match header(&req, "sec-websocket-key").filter(|_| upgrade) {
                Some(key) => Route::Live { key },
                None => refuse(400, "/live is a WebSocket"),
            }
        }
        "/mesh.bin" => Route::Mesh,
        p => match p.strip_prefix("/files/") {
            Some(name) => Route::File(name),
            None => refuse(404, "nothing here"),
        },
    }
}

fn handle(mut s: TcpStream, shared: &Shared, pages: &Arc<AtomicUsize>) {
    let _ = s.set_read_timeout(Some(READ_TIMEOUT));
    let _ = s.set_write_timeout(Some(WRITE_TIMEOUT));
    let head = match read_head(&mut s) {
        Ok(h) => Some(h),
        Err(HeadError::TooLarge) => None,
        Err(HeadError::Io) => return,
    };
    let q = shared
        .token
        .as_ref()
        .map_or(String::new(), |t| format!("?t={t}"));
    let asked = match head.as_deref() {
        Some(h) => route(h, shared.token.as_deref()),
        None => too_large(),
    };
    match asked {
        Route::Page => reply(
            &mut s,
            200,
            "text/html; charset=utf-8",
            "",
            INDEX.replace("{{Q}}", &q).as_bytes(),
        ),
        Route::App => reply(&mut s, 200, JS, "", APP.as_bytes()),
        Route::Three => reply(&mut s, 200, JS, "", THREE),
        Route::Orbit => reply(&mut s, 200, JS, "", ORBIT),
        Route::ThreeLicense => reply(&mut s, 200, TEXT, "", THREE_LICENSE),
        Route::Live { key } => stream(s, key, shared, pages),
        Route::Mesh => match finished(shared) {
            Some(f) if !f.mesh.is_empty() => {
                reply(&mut s, 200, "application/octet-stream", "", &f.mesh);
            }
            _ => refuse(&mut s, 404, "no mesh yet: the scan has not finished"),
        },
        Route::File(name) => match finished(shared) {
            Some(f) => match f.files.iter().find(|(n, _, _)| *n == name) {
                Some((n, kind, bytes)) => reply(
                    &mut s,
                    200,
                    kind,
                    &format!("Content-Disposition: attachment; filename=\"{n}\"\r\n"),
                    bytes,
                ),
                None => refuse(&mut s, 404, "no such output of this scan"),
            },
            None => refuse(&mut s, 404, "nothing here"),
        },
        Route::Refuse(code, why) => refuse(&mut s, code, &why),
    }
}

fn finished(shared: &Shared) -> Option<Arc<Finished>> {
    shared.lock().finished.clone()
}

/// The page's stream: the history, then what follows, until the page closes or the server does.
fn stream(mut s: TcpStream, key: &str, shared: &Shared, pages: &Arc<AtomicUsize>) {
    let Some(_page) = Slot::take(pages, MAX_PAGES) else {
        return refuse(
            &mut s,
            503,
            &format!("{MAX_PAGES} pages are open already: close one"),
        );
    };
    let accept = tungstenite::handshake::derive_accept_key(key.trim().as_bytes());
    let answer = format!(
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
    );
    if s.write_all(answer.as_bytes()).is_err() || s.set_read_timeout(Some(POLL)).is_err() {
        return;
    }
    // The page sends nothing but control frames: small limits.
    let cfg = WebSocketConfig::default()
        .read_buffer_size(4096)
        .max_message_size(Some(64 << 10))
        .max_frame_size(Some(64 << 10));
    let mut ws = WebSocket::from_raw_socket(s, Role::Server, Some(cfg));
    let (mut seq, mut status_seen, mut finished_sent) = (0u64, None, false);
    let mut preview_seen = None;
    loop {
        let (batches, status, preview, done, colour) = {
            let mut h = shared.lock();
            let fresh = |h: &super::History| {
                h.next_seq > seq
                    || h.status.as_ref().map(|(n, _)| *n) != status_seen
                    || h.preview.as_ref().map(|(n, _)| *n) != preview_seen
                    || (h.finished.is_some() && !finished_sent)
            };
            if !fresh(&h) && !shared.closing.load(Ordering::SeqCst) {
                h = shared
                    .changed
                    .wait_timeout(h, POLL)
                    .map_or_else(|e| e.into_inner().0, |(g, _)| g);
            }
            let batches: Vec<Arc<Batch>> =
                h.batches.iter().filter(|b| b.seq > seq).cloned().collect();
            seq = h.next_seq;
            let status = h
                .status
                .as_ref()
                .filter(|(n, _)| Some(*n) != status_seen)
                .cloned();
            let preview = h
                .preview
                .as_ref()
                .filter(|(n, _)| Some(*n) != preview_seen)
                .cloned();
            let done = h.finished.clone().filter(|_| !finished_sent);
            (batches, status, preview, done, h.colour)
        };
        let mut ok = send_points(&mut ws, &batches, colour);
        if let Some((n, text)) = status {
            status_seen = Some(n);
            ok = ok && ws.write(Message::text(text)).is_ok();
        }
        if let Some((n, text)) = preview {
            preview_seen = Some(n);
            ok = ok && ws.write(Message::text(text)).is_ok();
        }
        if let Some(f) = done {
            finished_sent = true;
            ok = ok && ws.write(Message::text(f.json.clone())).is_ok();
        }
        if !ok || ws.flush().is_err() {
            return;
        }
        match ws.read() {
            Ok(Message::Close(_)) => return,
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return,
        }
        if shared.closing.load(Ordering::SeqCst) {
            let _ = ws.close(None);
            let _ = ws.flush();
            return;
        }
    }
}

/// Sends batches as binary messages of at most [`MESSAGE_POINTS`] points: `u8` kind (1),
/// `u8` flags (bit 0: the points' own colour), two zero bytes, `u32` count, then x, y, z as
/// `f32` per point and r, g, b per point; little-endian.
fn send_points(ws: &mut WebSocket<TcpStream>, batches: &[Arc<Batch>], colour: bool) -> bool {
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
            if count == MESSAGE_POINTS && !flush_points(ws, &mut pending, &mut count, colour) {
                return false;
            }
        }
    }
    flush_points(ws, &mut pending, &mut count, colour)
}

fn flush_points(
    ws: &mut WebSocket<TcpStream>,
    pending: &mut Vec<(&[f32], &[u8])>,
    count: &mut usize,
    colour: bool,
) -> bool {
    if *count == 0 {
        return true;
    }
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
    ws.write(Message::binary(m)).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_must_match_in_full() {
        assert!(has_token("t=abcd", "abcd"));
        assert!(has_token("x=1&t=abcd", "abcd"));
        assert!(!has_token("t=abc", "abcd"));
        assert!(!has_token("t=abcde", "abcd"));
        assert!(!has_token("t=abce", "abcd"));
        assert!(!has_token("", "abcd"));
        assert!(!has_token("tt=abcd", "abcd"));
    }

    #[test]
    fn slots_are_bounded_and_given_back() {
        let n = Arc::new(AtomicUsize::new(0));
        let a = Slot::take(&n, 2).unwrap();
        let _b = Slot::take(&n, 2).unwrap();
        assert!(Slot::take(&n, 2).is_none());
        drop(a);
        assert!(Slot::take(&n, 2).is_some());
        assert_eq!(n.load(Ordering::SeqCst), 1);
    }

    fn get(target: &str, headers: &str) -> Vec<u8> {
        format!("GET {target} HTTP/1.1\r\nHost: x\r\n{headers}\r\n").into_bytes()
    }

    #[test]
    fn request_heads_route_or_are_refused_by_status() {
        assert_eq!(route(&get("/", ""), None), Route::Page);
        assert_eq!(route(&get("/app.js?t=ab", ""), Some("ab")), Route::App);
        assert!(matches!(
            route(&get("/", ""), Some("ab")),
            Route::Refuse(403, _)
        ));
        assert!(matches!(
            route(&get("/?t=ax", ""), Some("ab")),
            Route::Refuse(403, _)
        ));
        assert_eq!(
            route(&get("/files/scan.ply", ""), None),
            Route::File("scan.ply")
        );
        assert!(matches!(
            route(&get("/etc/passwd", ""), None),
            Route::Refuse(404, _)
        ));
        let ws = "Upgrade: websocket\r\nSec-WebSocket-Key: abc==\r\n";
        assert_eq!(route(&get("/live", ws), None), Route::Live { key: "abc==" });
        assert!(matches!(
            route(&get("/live", ""), None),
            Route::Refuse(400, _)
        ));
        let post = b"POST / HTTP/1.1\r\nHost: x\r\n\r\n";
        assert!(matches!(route(post, None), Route::Refuse(405, _)));
        let body = get("/", "Content-Length: 5\r\n");
        assert!(matches!(route(&body, None), Route::Refuse(413, _)));
        let long = get(&format!("/{}", "a".repeat(MAX_TARGET)), "");
        assert!(matches!(route(&long, None), Route::Refuse(414, _)));
        let huge = get("/", &format!("X: {}\r\n", "a".repeat(MAX_HEAD)));
        assert!(matches!(route(&huge, None), Route::Refuse(431, _)));
        for junk in [
            &b""[..],
            b"\r\n\r\n",
            b"GET",
            b"\xff\xfe / HTTP/1.1\r\n\r\n",
        ] {
            assert!(
                matches!(route(junk, None), Route::Refuse(400, _)),
                "{junk:?}"
            );
        }
    }
}
