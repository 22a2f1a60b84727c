//! The front every page stands behind: who may ask ([`Access`]: the host allow-list, the origin
//! check, the token), how much a client may send and for how long ([`FrontLimits`]), and the server
//! that applies both to an `axum` router ([`serve`]). Built on hyper's HTTP/1 connection (its
//! header size and count limits, its header read deadline) under a bounded accept loop.
//!
//! Why these rules: a page that drives a laser must not be reachable from another site's page.
//! A browser lets any page send requests to `127.0.0.1`, and a name the attacker owns can be
//! pointed at `127.0.0.1` (DNS rebinding), so the `Host` a request names must be one of ours, and
//! the `Origin` of anything that changes state or opens a stream must be our own page's, checked
//! against the same allow-list (never against the request's own `Host`, which the attacker
//! chooses). Beyond loopback every request also carries the token printed with the address.

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use axum::Router;
use axum::extract::Request;
use axum::http::{HeaderMap, Method, StatusCode, header};
use axum::response::{IntoResponse, Response};
use hyper_util::rt::{TokioIo, TokioTimer};
use subtle::ConstantTimeEq;
use tower::ServiceExt;

/// What a client may send and for how long. Every figure is a bound the server holds to.
#[derive(Debug, Clone, Copy)]
pub struct FrontLimits {
    /// Connections open at once; past it a new connection is closed unanswered (counted).
    pub connections: usize,
    /// Largest request head (request line and headers), bytes: 431 past it.
    pub header_bytes: usize,
    /// Most header lines in a request: 431 past it.
    pub header_lines: usize,
    /// Largest request body, bytes: 413 past it.
    pub body_bytes: usize,
    /// A request head must be whole within this time from when the connection opens (a
    /// deadline, not restarted by each byte). Each connection carries one request.
    pub head_within: Duration,
    /// A request body must be whole within this time.
    pub body_within: Duration,
    /// Longest life of a connection that is not a page's stream (a download included).
    pub connection_life: Duration,
}

impl FrontLimits {
    /// The limits both pages use.
    pub const DEFAULT: FrontLimits = FrontLimits {
        connections: 256,
        header_bytes: 16 << 10,
        header_lines: 64,
        body_bytes: 4096,
        head_within: Duration::from_secs(5),
        body_within: Duration::from_secs(5),
        connection_life: Duration::from_secs(600),
    };
}

/// Why a request was refused at the front, before any page saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AccessRefusal {
    /// No `Host`, or one that is not ours (a rebound name, another site): 421.
    #[error("this page answers only to its own addresses: open the address it printed")]
    ForeignHost,
    /// An `Origin` that is not our own page's: 403.
    #[error("a request from another site's page")]
    ForeignOrigin,
    /// The token is missing or wrong (beyond loopback): 403.
    #[error("this page needs the token printed with its address")]
    NoToken,
}

impl AccessRefusal {
    /// The kind, as reports and tests name it.
    pub fn kind(self) -> &'static str {
        match self {
            AccessRefusal::ForeignHost => "foreign_host",
            AccessRefusal::ForeignOrigin => "foreign_origin",
            AccessRefusal::NoToken => "no_token",
        }
    }

    /// The status answered.
    pub fn status(self) -> StatusCode {
        match self {
            AccessRefusal::ForeignHost => StatusCode::MISDIRECTED_REQUEST,
            AccessRefusal::ForeignOrigin | AccessRefusal::NoToken => StatusCode::FORBIDDEN,
        }
    }
}

/// A refusal as the pages get it: its status and `{"refused": kind, "words": …}`.
pub fn refusal(status: StatusCode, kind: &str, words: impl std::fmt::Display) -> Response {
    (
        status,
        [(header::CACHE_CONTROL, "no-store")],
        axum::Json(serde_json::json!({"refused": kind, "words": words.to_string()})),
    )
        .into_response()
}

/// Who may ask: the names a `Host` or an `Origin` may carry, the port, the token.
#[derive(Debug, Clone)]
pub struct Access {
    /// Names allowed beside the loopback ones and the connection's own address (lower case).
    names: Vec<String>,
    /// The port the pages are served on (an `Origin` must name it).
    port: u16,
    /// Needed on every request when set.
    token: Option<String>,
}

impl Access {
    /// The rules for a server bound to `bound`: loopback names and addresses, `bound`'s address
    /// and `names` (more names of this machine, e.g. `scanner.local`) as hosts; a token drawn
    /// when `bound` is not a loopback address.
    ///
    /// # Errors
    /// No random token could be drawn.
    pub fn new(bound: SocketAddr, names: &[String]) -> Result<Access, FrontError> {
        let token = if bound.ip().is_loopback() {
            None
        } else {
            let mut b = [0u8; 16];
            getrandom::fill(&mut b).map_err(|e| FrontError::Token(e.to_string()))?;
            Some(b.iter().map(|x| format!("{x:02x}")).collect::<String>())
        };
        let mut names: Vec<String> = names.iter().map(|n| n.to_ascii_lowercase()).collect();
        if !bound.ip().is_unspecified() {
            names.push(bound.ip().to_string());
        }
        Ok(Access {
            names,
            port: bound.port(),
            token,
        })
    }

    /// The token every request must carry, if any.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// Whether `name` (a host without its port, lower case, IPv6 without brackets) is ours for
    /// a connection that arrived on `local`.
    fn ours(&self, name: &str, local: IpAddr) -> bool {
        if name == "localhost" || self.names.iter().any(|n| n == name) {
            return true;
        }
        match name.parse::<IpAddr>() {
            Ok(ip) => ip.is_loopback() || ip == local,
            Err(_) => false,
        }
    }

    /// Decides whether a request may reach a page, from its parts alone (no I/O: fuzzed in
    /// `fuzz/fuzz_targets/front_access.rs`). `local`: the address the connection arrived on;
    /// `query`: the target's query string.
    ///
    /// # Errors
    /// The [`AccessRefusal`].
    pub fn admit(
        &self,
        method: &Method,
        headers: &HeaderMap,
        query: Option<&str>,
        local: IpAddr,
    ) -> Result<(), AccessRefusal> {
        let host = headers
            .get(header::HOST)
            .and_then(|h| h.to_str().ok())
            .and_then(|h| split_host(h).map(|(n, _)| n.to_ascii_lowercase()))
            .ok_or(AccessRefusal::ForeignHost)?;
        if !self.ours(&host, local) {
            return Err(AccessRefusal::ForeignHost);
        }
        let upgrade = headers.contains_key(header::UPGRADE);
        let changes = method != Method::GET && method != Method::HEAD || upgrade;
        if changes && let Some(origin) = headers.get(header::ORIGIN) {
            let ok = origin
                .to_str()
                .ok()
                .and_then(|o| o.strip_prefix("http://"))
                .and_then(split_host)
                .is_some_and(|(n, port)| {
                    port.unwrap_or(80) == self.port && self.ours(&n.to_ascii_lowercase(), local)
                });
            if !ok {
                return Err(AccessRefusal::ForeignOrigin);
            }
        }
        if let Some(t) = &self.token {
            let in_header = headers
                .get("x-scanner-token")
                .is_some_and(|v| same(v.as_bytes(), t.as_bytes()));
            let in_query = query.is_some_and(|q| {
                q.split('&')
                    .filter_map(|kv| kv.strip_prefix("token="))
                    .any(|v| same(v.as_bytes(), t.as_bytes()))
            });
            if !(in_header || in_query) {
                return Err(AccessRefusal::NoToken);
            }
        }
        Ok(())
    }
}

/// Compares in time that does not depend on where the two differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && bool::from(a.ct_eq(b))
}

/// `name[:port]` or `[v6]:port` into the name (brackets taken off) and the port; `None` for
/// anything else (a path, user info, an empty name, a port that is no number).
fn split_host(h: &str) -> Option<(&str, Option<u16>)> {
    if h.is_empty() || h.contains(['/', '@', ' ', '?', '#']) {
        return None;
    }
    let (name, port) = if let Some(rest) = h.strip_prefix('[') {
        let (name, after) = rest.split_once(']')?;
        // brackets hold an IPv6 address and nothing else (`[scanner.local]` is no host)
        name.parse::<std::net::Ipv6Addr>().ok()?;
        match after {
            "" => (name, None),
            p => (name, Some(p.strip_prefix(':')?)),
        }
    } else {
        match h.rsplit_once(':') {
            Some((n, p)) if !n.contains(':') => (n, Some(p)),
            Some(_) => return None,
            None => (h, None),
        }
    };
    if name.is_empty() {
        return None;
    }
    let port = match port {
        Some(p) => Some(p.parse::<u16>().ok()?),
        None => None,
    };
    Some((name, port))
}

/// The address a connection arrived on, for [`Access::admit`].
#[derive(Debug, Clone, Copy)]
pub struct Local(pub IpAddr);

/// Why the front cannot start.
#[derive(Debug, thiserror::Error)]
pub enum FrontError {
    /// The address cannot be bound.
    #[error("cannot serve on {addr}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// No random token could be drawn for a non-loopback address.
    #[error("cannot draw a random token: {0}")]
    Token(String),
    /// The server's runtime or thread could not be started.
    #[error("cannot start the server")]
    Start(#[source] std::io::Error),
}

/// A running front: its address; stops when dropped or by [`Served::stop`].
pub struct Served {
    /// The address it listens on.
    pub addr: SocketAddr,
    /// The access rules (its token).
    pub access: Arc<Access>,
    /// Connections closed unanswered because [`FrontLimits::connections`] were open.
    pub refused: Arc<AtomicU64>,
    stop: Option<tokio::sync::watch::Sender<bool>>,
    thread: Option<JoinHandle<()>>,
}

impl Served {
    /// The page's address for people: the host (`<this-computer's-address>` for an unspecified
    /// one), the port, `path` and the token.
    pub fn url(&self, path: &str) -> String {
        let ip = self.addr.ip();
        let host = if ip.is_unspecified() {
            "<this-computer's-address>".to_string()
        } else if ip.is_ipv6() {
            format!("[{ip}]")
        } else {
            ip.to_string()
        };
        match self.access.token() {
            Some(t) => format!("http://{host}:{}{path}?token={t}", self.addr.port()),
            None => format!("http://{host}:{}{path}", self.addr.port()),
        }
    }

    /// Stops accepting, ends every connection and waits for the server's thread.
    pub fn stop(mut self) {
        self.shut();
    }

    fn shut(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(true);
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        self.shut();
    }
}

/// Binds `addr` and serves `app` behind `Access` (built for the bound address and `names`) and
/// `limits`, on a runtime of its own in a thread named `name`.
///
/// # Errors
/// [`FrontError`]: the address, the token, the runtime.
pub fn serve(
    addr: SocketAddr,
    names: &[String],
    limits: FrontLimits,
    name: &str,
    app: impl FnOnce(Arc<Access>) -> Router,
) -> Result<Served, FrontError> {
    let listener =
        std::net::TcpListener::bind(addr).map_err(|source| FrontError::Bind { addr, source })?;
    let bound = listener
        .local_addr()
        .map_err(|source| FrontError::Bind { addr, source })?;
    listener
        .set_nonblocking(true)
        .map_err(|source| FrontError::Bind { addr, source })?;
    let access = Arc::new(Access::new(bound, names)?);
    let router = guarded(app(access.clone()), access.clone());
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name(format!("{name}-io"))
        .enable_all()
        .build()
        .map_err(FrontError::Start)?;
    let (stop, stopped) = tokio::sync::watch::channel(false);
    let refused = Arc::new(AtomicU64::new(0));
    let counted = refused.clone();
    let listener = {
        let _enter = runtime.enter();
        tokio::net::TcpListener::from_std(listener).map_err(FrontError::Start)?
    };
    let thread = std::thread::Builder::new()
        .name(name.to_string())
        .spawn(move || {
            runtime.block_on(accept_loop(listener, router, limits, stopped, counted));
            runtime.shutdown_timeout(Duration::from_millis(200));
        })
        .map_err(FrontError::Start)?;
    Ok(Served {
        addr: bound,
        access,
        refused,
        stop: Some(stop),
        thread: Some(thread),
    })
}

/// Every request through [`Access::admit`] first.
fn guarded(app: Router, access: Arc<Access>) -> Router {
    app.layer(axum::middleware::from_fn(
        move |req: Request, next: axum::middleware::Next| {
            let access = access.clone();
            async move {
                let local = req
                    .extensions()
                    .get::<Local>()
                    .map_or(IpAddr::from([127, 0, 0, 1]), |l| l.0);
                match access.admit(req.method(), req.headers(), req.uri().query(), local) {
                    Ok(()) => next.run(req).await,
                    Err(r) => refusal(r.status(), r.kind(), r),
                }
            }
        },
    ))
}

async fn accept_loop(
    listener: tokio::net::TcpListener,
    router: Router,
    limits: FrontLimits,
    mut stopped: tokio::sync::watch::Receiver<bool>,
    refused: Arc<AtomicU64>,
) {
    let slots = Arc::new(tokio::sync::Semaphore::new(limits.connections));
    loop {
        let accepted = tokio::select! {
            _ = stopped.changed() => return,
            a = listener.accept() => a,
        };
        let Ok((tcp, _peer)) = accepted else {
            // a connection that vanished before it was accepted, or no descriptors left
            tokio::time::sleep(Duration::from_millis(10)).await;
            continue;
        };
        let Ok(slot) = slots.clone().try_acquire_owned() else {
            refused.fetch_add(1, Ordering::Relaxed);
            continue;
        };
        let local = Local(
            tcp.local_addr()
                .map_or(IpAddr::from([127, 0, 0, 1]), |a| a.ip()),
        );
        let router = router.clone();
        let mut stopped = stopped.clone();
        tokio::spawn(async move {
            let _slot = slot;
            let service = hyper::service::service_fn(move |mut req: hyper::Request<_>| {
                req.extensions_mut().insert(local);
                router.clone().oneshot(req.map(axum::body::Body::new))
            });
            let mut b = hyper::server::conn::http1::Builder::new();
            // one request a connection: every answer closes it, so that a connection's life is
            // one head's deadline, one body's and the answer
            b.timer(TokioTimer::new())
                .keep_alive(false)
                .header_read_timeout(limits.head_within)
                .max_header_size(limits.header_bytes)
                .max_headers(limits.header_lines)
                .max_buf_size(limits.header_bytes.max(8192) * 2);
            let conn = b
                .serve_connection(TokioIo::new(tcp), service)
                .with_upgrades();
            tokio::pin!(conn);
            tokio::select! {
                _ = conn.as_mut() => {}
                _ = tokio::time::sleep(limits.connection_life) => {}
                _ = stopped.changed() => {
                    conn.as_mut().graceful_shutdown();
                    let _ = tokio::time::timeout(Duration::from_secs(1), conn).await;
                }
            }
        });
    }
}

/// Why a file of a folder is not served.
#[derive(Debug, thiserror::Error)]
pub enum FileRefusal {
    /// Not there (yet).
    #[error("{0} is not there")]
    Missing(String),
    /// A symbolic link on the way (the file, or a folder above it): never followed.
    #[error("{0} is a link: links are not followed")]
    Link(String),
    /// A FIFO, a device, a folder: only regular files are served.
    #[error("{0} is no regular file")]
    NotRegular(String),
    /// Larger than the stated limit.
    #[error("{name} has {bytes} bytes, more than {limit}")]
    TooLarge {
        /// The file.
        name: String,
        /// Its size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// Another failure to open or read it.
    #[error("cannot read {0}")]
    Io(String, #[source] std::io::Error),
}

impl FileRefusal {
    /// The kind, as reports and tests name it.
    pub fn kind(&self) -> &'static str {
        match self {
            FileRefusal::Missing(_) => "missing",
            FileRefusal::Link(_) => "link",
            FileRefusal::NotRegular(_) => "not_regular",
            FileRefusal::TooLarge { .. } => "too_large",
            FileRefusal::Io(..) => "io",
        }
    }
}

/// Opens `root/parts…` for reading: only a regular file, of at most `limit` bytes, none of
/// whose parts below `root` is a symbolic link (the last one opened with `O_NOFOLLOW`, and
/// without blocking, so that a FIFO cannot hold the server). The parts are fixed names chosen by
/// the page's code, never a path from a request.
///
/// # Errors
/// [`FileRefusal`].
pub fn open_inside(
    root: &std::path::Path,
    parts: &[&str],
    limit: u64,
) -> Result<(std::fs::File, u64), FileRefusal> {
    use std::os::unix::fs::OpenOptionsExt;
    let shown = parts.join("/");
    let mut path = root.to_path_buf();
    for (k, part) in parts.iter().enumerate() {
        if part.is_empty() || *part == "." || *part == ".." || part.contains('/') {
            return Err(FileRefusal::Missing(shown));
        }
        path.push(part);
        if k + 1 < parts.len() {
            match std::fs::symlink_metadata(&path) {
                Ok(m) if m.file_type().is_symlink() => return Err(FileRefusal::Link(shown)),
                Ok(m) if m.is_dir() => {}
                Ok(_) => return Err(FileRefusal::NotRegular(shown)),
                Err(_) => return Err(FileRefusal::Missing(shown)),
            }
        }
    }
    let f = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(&path)
        .map_err(|e| match e.raw_os_error() {
            Some(libc::ELOOP) => FileRefusal::Link(shown.clone()),
            _ if e.kind() == std::io::ErrorKind::NotFound => FileRefusal::Missing(shown.clone()),
            _ => FileRefusal::Io(shown.clone(), e),
        })?;
    let meta = f
        .metadata()
        .map_err(|e| FileRefusal::Io(shown.clone(), e))?;
    if !meta.is_file() {
        return Err(FileRefusal::NotRegular(shown));
    }
    if meta.len() > limit {
        return Err(FileRefusal::TooLarge {
            name: shown,
            bytes: meta.len(),
            limit,
        });
    }
    Ok((f, meta.len()))
}

/// Reads a whole file with [`open_inside`]'s rules.
///
/// # Errors
/// [`FileRefusal`].
pub fn read_inside(
    root: &std::path::Path,
    parts: &[&str],
    limit: u64,
) -> Result<Vec<u8>, FileRefusal> {
    use std::io::Read;
    let (f, len) = open_inside(root, parts, limit)?;
    let mut out = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    f.take(limit)
        .read_to_end(&mut out)
        .map_err(|e| FileRefusal::Io(parts.join("/"), e))?;
    Ok(out)
}

/// A file of a folder as a download (streamed, with its length and media type), or the
/// refusal with its kind.
pub fn download(root: &std::path::Path, parts: &[&str], limit: u64, media: &str) -> Response {
    match open_inside(root, parts, limit) {
        Ok((f, len)) => {
            let name = parts.last().copied().unwrap_or("file");
            let stream = tokio_util::io::ReaderStream::new(tokio::fs::File::from_std(f));
            (
                [
                    (header::CONTENT_TYPE, media.to_string()),
                    (header::CONTENT_LENGTH, len.to_string()),
                    (
                        header::CONTENT_DISPOSITION,
                        format!("attachment; filename=\"{name}\""),
                    ),
                    (header::CACHE_CONTROL, "no-store".to_string()),
                ],
                axum::body::Body::from_stream(stream),
            )
                .into_response()
        }
        Err(e) => {
            let status = match e {
                FileRefusal::Missing(_) => StatusCode::NOT_FOUND,
                FileRefusal::TooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
                FileRefusal::Link(_) | FileRefusal::NotRegular(_) => StatusCode::FORBIDDEN,
                FileRefusal::Io(..) => StatusCode::INTERNAL_SERVER_ERROR,
            };
            refusal(status, e.kind(), e)
        }
    }
}

/// A request body of at most [`FrontLimits::body_bytes`], whole within [`FrontLimits::body_within`], as
/// JSON; anything else refused with its status and kind (`Content-Type` must be JSON: a form on
/// another site cannot send it without the browser asking first).
///
/// # Errors
/// The refusal, ready to answer.
pub async fn json_body(req: Request, limits: &FrontLimits) -> Result<serde_json::Value, Response> {
    let is_json = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if !is_json {
        return Err(refusal(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "not_json",
            "send JSON (Content-Type: application/json)",
        ));
    }
    let read = axum::body::to_bytes(req.into_body(), limits.body_bytes);
    let bytes = match tokio::time::timeout(limits.body_within, read).await {
        Err(_) => {
            return Err(refusal(
                StatusCode::REQUEST_TIMEOUT,
                "body_too_slow",
                format!("the body did not come within {:?}", limits.body_within),
            ));
        }
        Ok(Err(_)) => {
            return Err(refusal(
                StatusCode::PAYLOAD_TOO_LARGE,
                "body_too_large",
                format!("a body of at most {} bytes", limits.body_bytes),
            ));
        }
        Ok(Ok(b)) => b,
    };
    serde_json::from_slice(&bytes).map_err(|e| {
        refusal(
            StatusCode::BAD_REQUEST,
            "not_json",
            format!("the body is no JSON: {e}"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn access(bound: &str, names: &[&str]) -> Access {
        let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        Access::new(bound.parse().unwrap(), &names).unwrap()
    }

    fn ask(
        a: &Access,
        method: Method,
        pairs: &[(&str, &str)],
        query: Option<&str>,
    ) -> Result<(), AccessRefusal> {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(
                axum::http::HeaderName::from_bytes(k.as_bytes()).unwrap(),
                v.parse().unwrap(),
            );
        }
        a.admit(&method, &h, query, IpAddr::from([127, 0, 0, 1]))
    }

    #[test]
    fn hosts_split_into_name_and_port_or_are_refused() {
        assert_eq!(split_host("localhost:80"), Some(("localhost", Some(80))));
        assert_eq!(split_host("[::1]:8080"), Some(("::1", Some(8080))));
        assert_eq!(split_host("[::1]"), Some(("::1", None)));
        assert_eq!(split_host("127.0.0.1"), Some(("127.0.0.1", None)));
        for bad in [
            "", ":80", "a:b", "a:99999", "x/y", "u@h", "::1", "[::1]x", "[]:1",
        ] {
            assert_eq!(split_host(bad), None, "{bad}");
        }
    }

    #[test]
    fn a_rebound_name_or_another_sites_origin_is_refused_by_kind() {
        let a = access("127.0.0.1:8080", &[]);
        let get = |host: &str| ask(&a, Method::GET, &[("host", host)], None);
        assert_eq!(get("127.0.0.1:8080"), Ok(()));
        assert_eq!(get("localhost:8080"), Ok(()));
        assert_eq!(get("LOCALHOST"), Ok(()));
        assert_eq!(get("[::1]:8080"), Ok(()));
        assert_eq!(get("evil.example:8080"), Err(AccessRefusal::ForeignHost));
        assert_eq!(
            get("127.0.0.1.evil.example"),
            Err(AccessRefusal::ForeignHost)
        );
        assert_eq!(
            ask(&a, Method::GET, &[], None),
            Err(AccessRefusal::ForeignHost)
        );
        let post = |origin: &str| {
            ask(
                &a,
                Method::POST,
                &[("host", "127.0.0.1:8080"), ("origin", origin)],
                None,
            )
        };
        assert_eq!(post("http://127.0.0.1:8080"), Ok(()));
        assert_eq!(post("http://localhost:8080"), Ok(()));
        assert_eq!(
            post("http://evil.example:8080"),
            Err(AccessRefusal::ForeignOrigin)
        );
        assert_eq!(
            post("http://127.0.0.1:3000"),
            Err(AccessRefusal::ForeignOrigin),
            "another local site"
        );
        assert_eq!(post("null"), Err(AccessRefusal::ForeignOrigin));
        assert_eq!(
            post("https://127.0.0.1:8080"),
            Err(AccessRefusal::ForeignOrigin)
        );
        // an upgrade is checked as a change is, a plain GET keeps its Origin unchecked
        let up = ask(
            &a,
            Method::GET,
            &[
                ("host", "127.0.0.1:8080"),
                ("origin", "http://evil.example"),
                ("upgrade", "websocket"),
            ],
            None,
        );
        assert_eq!(up, Err(AccessRefusal::ForeignOrigin));
        // the origin is checked against the allow-list, not against the request's own Host
        let same_as_host = ask(
            &a,
            Method::POST,
            &[("host", "evil.example"), ("origin", "http://evil.example")],
            None,
        );
        assert_eq!(same_as_host, Err(AccessRefusal::ForeignHost));
    }

    #[test]
    fn beyond_loopback_every_request_needs_the_whole_token() {
        let a = access("0.0.0.0:8080", &["scanner.local"]);
        let t = a.token().unwrap().to_string();
        assert_eq!(t.len(), 32);
        let h = [("host", "scanner.local:8080")];
        assert_eq!(ask(&a, Method::GET, &h, None), Err(AccessRefusal::NoToken));
        assert_eq!(
            ask(&a, Method::GET, &h, Some(&format!("token={t}"))),
            Ok(())
        );
        assert_eq!(
            ask(&a, Method::GET, &h, Some(&format!("a=1&token={t}"))),
            Ok(())
        );
        assert_eq!(
            ask(&a, Method::GET, &h, Some(&format!("token={}", &t[..31]))),
            Err(AccessRefusal::NoToken)
        );
        assert_eq!(
            ask(
                &a,
                Method::GET,
                &[("host", "scanner.local"), ("x-scanner-token", &t)],
                None
            ),
            Ok(())
        );
        assert_eq!(
            ask(
                &a,
                Method::GET,
                &[("host", "other.local")],
                Some(&format!("token={t}"))
            ),
            Err(AccessRefusal::ForeignHost)
        );
    }

    #[test]
    fn links_fifos_and_folders_are_not_opened() {
        let d = tempfile::tempdir().unwrap();
        let root = d.path();
        std::fs::create_dir(root.join("model")).unwrap();
        std::fs::write(root.join("model/a.obj"), b"v 0 0 0\n").unwrap();
        std::fs::write(d.path().join("secret"), b"no").unwrap();
        std::os::unix::fs::symlink(root.join("secret"), root.join("model/b.obj")).unwrap();
        std::os::unix::fs::symlink(root.join("model"), root.join("linked")).unwrap();
        let made = std::process::Command::new("mkfifo")
            .arg(root.join("model/c.obj"))
            .status()
            .unwrap();
        assert!(made.success());
        assert_eq!(
            read_inside(root, &["model", "a.obj"], 100).unwrap(),
            b"v 0 0 0\n"
        );
        let kind = |parts: &[&str]| read_inside(root, parts, 100).unwrap_err().kind();
        assert_eq!(kind(&["model", "b.obj"]), "link");
        assert_eq!(kind(&["linked", "a.obj"]), "link");
        assert_eq!(kind(&["model", "c.obj"]), "not_regular");
        assert_eq!(kind(&["model"]), "not_regular");
        assert_eq!(kind(&["model", "none.obj"]), "missing");
        assert_eq!(kind(&["..", "secret"]), "missing");
        assert_eq!(
            read_inside(root, &["model", "a.obj"], 3)
                .unwrap_err()
                .kind(),
            "too_large"
        );
    }
}
