//! A headless Chromium driven over the DevTools protocol (a WebSocket): load a page, read what
//! it shows (a JavaScript expression), take a screenshot. For the live view's tests.
//!
//! The browser is Debian's `chromium` (`scripts/setup` installs it; `CHROMIUM=path` names
//! another). Without one, [`chromium`] panics naming what is missing, unless
//! `SCANNER_SKIP_BROWSER=1` is set (`scripts/test` sets it, and says so loudly, when no Chromium
//! could be installed).

use std::io::{BufRead, BufReader, Read};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tungstenite::stream::MaybeTlsStream;

/// A browser with one page.
pub struct Browser {
    child: Child,
    ws: tungstenite::WebSocket<MaybeTlsStream<TcpStream>>,
    session: String,
    next: u64,
    _profile: tempfile::TempDir,
}

/// The browser, or `None` when the run says it may go without one (printed loudly).
pub fn chromium() -> Option<PathBuf> {
    let named = std::env::var_os("CHROMIUM").map(PathBuf::from);
    let path = std::env::var_os("PATH").unwrap_or_default();
    let dirs: Vec<PathBuf> = std::env::split_paths(&path).collect();
    let found = named.or_else(|| {
        ["chromium", "chromium-browser", "google-chrome"]
            .iter()
            .flat_map(|n| dirs.iter().map(move |d| d.join(n)))
            .find(|p| p.exists())
    });
    match found {
        Some(p) => Some(p),
        None if std::env::var_os("SCANNER_SKIP_BROWSER").is_some() => {
            eprintln!(
                "!!! NOT CHECKED: no Chromium on this machine (SCANNER_SKIP_BROWSER set): the live view was not tested in a browser"
            );
            None
        }
        None => panic!(
            "the live-view tests need a headless Chromium: run scripts/setup (installs Debian's chromium), set CHROMIUM=/path/to/chromium, or set SCANNER_SKIP_BROWSER=1 to go without (reported)"
        ),
    }
}

impl Browser {
    /// Starts a headless browser (1000×700 window) with one blank page.
    ///
    /// # Panics
    /// The browser does not start or answer (a test helper).
    pub fn launch(exe: &Path) -> Browser {
        let profile = tempfile::tempdir().unwrap();
        let mut child = Command::new(exe)
            .args([
                "--headless=new",
                "--no-sandbox",
                "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-quic",
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--window-size=1000,700",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("Chromium starts");
        let lines = lines_of(child.stderr.take().unwrap());
        let url = wait_line(&lines, "DevTools listening on ", Duration::from_secs(60))
            .expect("Chromium printed its DevTools address");
        let (mut ws, _) = tungstenite::connect(url.trim()).expect("DevTools WebSocket");
        if let MaybeTlsStream::Plain(s) = ws.get_mut() {
            s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        }
        let mut b = Browser {
            child,
            ws,
            session: String::new(),
            next: 0,
            _profile: profile,
        };
        let target = b.call("Target.createTarget", json!({"url": "about:blank"}));
        let id = target["targetId"].as_str().unwrap().to_string();
        let attached = b.call(
            "Target.attachToTarget",
            json!({"targetId": id, "flatten": true}),
        );
        b.session = attached["sessionId"].as_str().unwrap().to_string();
        b
    }

    /// Calls a DevTools method on the page; its result.
    ///
    /// # Panics
    /// The call fails.
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        self.next += 1;
        let id = self.next;
        let mut m = json!({"id": id, "method": method, "params": params});
        if !self.session.is_empty() {
            m["sessionId"] = self.session.clone().into();
        }
        self.ws
            .send(tungstenite::Message::text(m.to_string()))
            .unwrap();
        loop {
            let msg = self.ws.read().expect("DevTools answers");
            let Ok(text) = msg.to_text() else { continue };
            let v: Value = serde_json::from_str(text).unwrap();
            if v["id"] == id {
                assert!(v["error"].is_null(), "{method}: {}", v["error"]);
                return v["result"].clone();
            }
        }
    }

    /// Opens `url`.
    pub fn navigate(&mut self, url: &str) {
        self.call("Page.navigate", json!({"url": url}));
    }

    /// The value of a JavaScript expression on the page.
    pub fn eval(&mut self, expr: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expr, "returnByValue": true}),
        );
        r["result"]["value"].clone()
    }

    /// The value a JavaScript expression's promise resolves to.
    pub fn eval_await(&mut self, expr: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expr, "returnByValue": true, "awaitPromise": true}),
        );
        r["result"]["value"].clone()
    }

    /// Polls `expr` until it is true (`true`), or `timeout` passes (`false`).
    pub fn wait_for(&mut self, expr: &str, timeout: Duration) -> bool {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            if self.eval(expr) == Value::Bool(true) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        false
    }

    /// The page as it is drawn.
    pub fn screenshot(&mut self) -> image::RgbImage {
        use base64::Engine as _;
        let r = self.call("Page.captureScreenshot", json!({"format": "png"}));
        let png = base64::engine::general_purpose::STANDARD
            .decode(r["data"].as_str().unwrap())
            .unwrap();
        image::load_from_memory(&png).unwrap().to_rgb8()
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A reader's lines, as they come.
pub fn lines_of(r: impl Read + Send + 'static) -> Receiver<String> {
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(r).lines() {
            let Ok(line) = line else { return };
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    rx
}

/// The rest of the first line that starts with `prefix`.
pub fn wait_line(lines: &Receiver<String>, prefix: &str, timeout: Duration) -> Option<String> {
    let t0 = Instant::now();
    while let Some(left) = timeout.checked_sub(t0.elapsed()) {
        let line = lines.recv_timeout(left).ok()?;
        if let Some(rest) = line.find(prefix).map(|i| &line[i + prefix.len()..]) {
            return Some(rest.to_string());
        }
    }
    None
}
