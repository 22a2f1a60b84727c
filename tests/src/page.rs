//! A web page's requests from a test, over loopback: raw HTTP/1.1 (one request a connection, as
//! the front answers), the status and the JSON answer; the studio's job read until a condition.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// `host:port` of a page's address (`http://host:port/…`).
pub fn addr_of(url: &str) -> String {
    url.trim_start_matches("http://")
        .split('/')
        .next()
        .unwrap_or_default()
        .to_string()
}

/// Sends `request` (`HOST` replaced by `addr`) and reads the answer: its status (0: closed
/// unanswered) and its body as JSON (null when it is none).
///
/// # Panics
/// When nothing listens at `addr` (a test helper).
pub fn raw(addr: &str, request: &str) -> (u16, serde_json::Value) {
    let mut s = TcpStream::connect(addr).expect("the page's server");
    let _ = s.set_read_timeout(Some(Duration::from_secs(30)));
    let _ = s.write_all(request.replace("HOST", addr).as_bytes());
    let mut bytes = Vec::new();
    let _ = s.read_to_end(&mut bytes);
    let text = String::from_utf8_lossy(&bytes);
    let status = text.get(9..12).and_then(|c| c.parse().ok()).unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    (status, serde_json::from_str(body).unwrap_or_default())
}

/// A `GET` as the page sends it.
pub fn get(addr: &str, path: &str) -> (u16, serde_json::Value) {
    raw(
        addr,
        &format!("GET {path} HTTP/1.1\r\nHost: HOST\r\nConnection: close\r\n\r\n"),
    )
}

/// A `POST` of JSON as the page sends it (its own origin).
pub fn post(addr: &str, path: &str, body: &str) -> (u16, serde_json::Value) {
    raw(
        addr,
        &format!(
            "POST {path} HTTP/1.1\r\nHost: HOST\r\nOrigin: http://HOST\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        ),
    )
}

/// The studio's job (`/api/state`).
pub fn state(addr: &str) -> serde_json::Value {
    get(addr, "/api/state").1
}

/// Reads the studio's job until `f` holds.
///
/// # Panics
/// When it does not within `secs` (a test helper), with the job.
pub fn wait(addr: &str, secs: u64, what: &str, f: impl Fn(&serde_json::Value) -> bool) {
    let t0 = Instant::now();
    loop {
        let s = state(addr);
        if f(&s) {
            return;
        }
        assert!(t0.elapsed() < Duration::from_secs(secs), "{what}: {s}");
        std::thread::sleep(Duration::from_millis(200));
    }
}
