//! Workspace-level end-to-end tests live in `tests/tests/`; this library holds what tests across
//! the workspace share: finding and checking the workspace's binaries, the accuracy harness
//! ([`accuracy`]), the browser driver ([`browser`]) and a page's requests without one
//! ([`page`]).
//!
//! # Layers
//! ```text
//! accuracy  browser  page
//! ```
#![deny(missing_docs)]

use std::process::Command;

pub mod accuracy;
pub mod browser;
pub mod page;

/// Checks a binary of the workspace from the outside: `--info` succeeds and starts with its name
/// and the unit convention, and an unknown flag is a usage error (exit code 2) that names the
/// flag. `exe` is the binary's path (`env!("CARGO_BIN_EXE_…")` in the calling test).
///
/// # Panics
/// When a check fails: this is a test helper.
pub fn check_cli(exe: &str, name: &str) {
    let out = Command::new(exe)
        .arg("--info")
        .output()
        .expect("binary runs");
    assert!(out.status.success(), "{name} --info failed");
    let text = String::from_utf8(out.stdout).expect("UTF-8 output");
    assert!(text.starts_with(&format!("{name} ")), "{text}");
    assert!(text.contains("units mm"), "{text}");

    let out = Command::new(exe)
        .arg("--no-such-flag")
        .output()
        .expect("binary runs");
    assert_eq!(
        out.status.code(),
        Some(2),
        "{name}: a bad flag is a usage error"
    );
    let err = String::from_utf8(out.stderr).expect("UTF-8 output");
    assert!(err.contains("--no-such-flag"), "{err}");
}

/// A JSON report a command wrote.
///
/// # Panics
/// When it is missing or no JSON: this is a test helper.
pub fn json(path: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The summary (`summary.json`) a receive or a replay wrote into `dir`.
///
/// # Panics
/// When it is missing or no JSON: this is a test helper.
pub fn summary(dir: &std::path::Path) -> serde_json::Value {
    json(&dir.join("summary.json"))
}

/// Frames the link rejected or lost, by kind, from a summary ([`summary`]): every count of its
/// `link` that is not 0.
///
/// # Panics
/// When the summary has no link counts: this is a test helper.
pub fn link_losses(summary: &serde_json::Value) -> Vec<(String, u64)> {
    summary["link"]
        .as_object()
        .expect("the link's counts")
        .iter()
        .filter(|(k, _)| *k != "bytes")
        .filter_map(|(k, v)| v.as_u64().filter(|&n| n > 0).map(|n| (k.clone(), n)))
        .collect()
}

/// Runs a binary with arguments: (success, stdout, stderr). A failing command's stderr ends with
/// its error as data ([`error_kinds`] reads it).
///
/// # Panics
/// When the binary cannot be started: this is a test helper.
pub fn run(exe: &str, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(exe)
        .args(args)
        .env(scanner_io::ERRORS_ENV, "json")
        .output()
        .expect("binary runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs a binary with arguments in the folder `dir`: (success, stdout, stderr).
///
/// # Panics
/// When the binary cannot be started: this is a test helper.
pub fn run_in(
    exe: &std::path::Path,
    dir: &std::path::Path,
    args: &[&str],
) -> (bool, String, String) {
    let out = Command::new(exe)
        .args(args)
        .current_dir(dir)
        .env(scanner_io::ERRORS_ENV, "json")
        .output()
        .expect("binary runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Scans a rig scene through the head's binary, as a user would: writes `scene` (TOML) to
/// `dir/scene.toml` and the rig's true calibration to `dir/cal.toml`, then runs `scanner-device
/// scan --source rig` with `extra` arguments, its stream to `dir/out`.
///
/// # Panics
/// When the scene is not a scene or the scan fails: this is a test helper.
pub fn scan_rig(dir: &std::path::Path, scene: &str, extra: &[&str], out: &str) {
    std::fs::write(dir.join("scene.toml"), scene).expect("scene written");
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::from_toml_in(scene, dir).expect("a scene"))
        .expect("a rig");
    rig.truth_calibration()
        .save(&dir.join("cal.toml"))
        .expect("calibration written");
    let mut args = vec![
        "scan",
        "--source",
        "rig",
        "--scene",
        "scene.toml",
        "--calibration",
        "cal.toml",
    ];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--out", out, "-q"]);
    let (ok, _, err) = run_in(&workspace_bin("scanner-device"), dir, &args);
    assert!(ok, "scanner-device scan: {err}");
}

/// The head scans view `k` of `dir/s.toml` with the calibration `dir/cal.toml` and `extra`
/// options into `dir/vK.stream`, and the host receives it (with `receive_extra`) into `dir/vK`.
///
/// # Panics
/// When either fails: this is a test helper.
pub fn scan_rig_view(dir: &std::path::Path, k: &str, extra: &[&str], receive_extra: &[&str]) {
    let stream = format!("v{k}.stream");
    let mut args = vec![
        "scan",
        "--source",
        "rig",
        "--scene",
        "s.toml",
        "--view",
        k,
        "--calibration",
        "cal.toml",
        "--out",
        &stream,
        "-q",
    ];
    args.extend(extra);
    let (ok, _, err) = run_in(&workspace_bin("scanner-device"), dir, &args);
    assert!(ok, "scan view {k}: {err}");
    let out = format!("v{k}");
    let mut args = vec!["receive", &stream, "--out", &out, "-q"];
    args.extend(receive_extra);
    let (ok, _, err) = run_in(&workspace_bin("scanner-host"), dir, &args);
    assert!(ok, "receive view {k}: {err}");
}

/// Records a scan of `source` into `out` as the head streams it (headers, point packets,
/// statuses), through the link's deepest queue: a recording for a test to read, not a test of
/// the link, so a writer that falls behind on a busy machine must drop nothing.
///
/// # Panics
/// When the scan fails or the link dropped a packet all the same: this is a test helper.
pub fn record_scan(
    source: &mut dyn scanner_device::source::FrameSource,
    cal: &scanner_device::session::Calibration,
    opts: scanner_device::session::ScanOptions,
    out: Box<dyn std::io::Write + Send>,
) {
    let mut link = scanner_device::link::Link::spawn(
        out,
        scanner_device::link::MAX_DEPTH,
        scanner_wire::MAX_ENCODED,
    );
    scanner_device::session::run_scan(source, cal, opts, &mut link, |_| {}, |_, _| {})
        .expect("the scan runs");
    let stats = link.finish().expect("the link writes");
    assert_eq!(stats.dropped, 0, "the link dropped point packets");
}

/// A workspace binary next to the running test (`cargo test --workspace` builds them all).
///
/// Cargo does not build another package's binaries for a single test target, so after an edit
/// `cargo test -p scanner-tests --test merge` would run the binary of the last build: a binary
/// older than a source file of its package or of `scanner-core` is refused as stale.
///
/// # Panics
/// When the binary is not built or is stale: this is a test helper.
pub fn workspace_bin(name: &str) -> std::path::PathBuf {
    let mut p = std::env::current_exe().expect("test path");
    p.pop(); // deps
    p.pop(); // the profile's folder
    let exe = p.join(name);
    assert!(
        exe.exists(),
        "{} not built: run the workspace's tests (`cargo test --workspace`)",
        exe.display()
    );
    // Checked once per binary and test process: the walk reads every source file's time.
    static FRESH: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let mut fresh = FRESH
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if fresh.iter().any(|n| n == name) {
        return exe;
    }
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the workspace");
    let built = std::fs::metadata(&exe)
        .and_then(|m| m.modified())
        .expect("the binary's time");
    for dir in [root.join(name), root.join("scanner-core")] {
        if let Some(newer) = newer_source(&dir, built) {
            panic!(
                "{} is older than {}: rebuild it (`cargo build -p {name}`, or run the workspace's tests)",
                exe.display(),
                newer.display()
            );
        }
    }
    fresh.push(name.to_string());
    exe
}

/// Folders under a package that are not compiled into its binaries.
const NOT_BUILT: [&str; 7] = [
    "target", "tests", "benches", "examples", "scenes", "data", "fuzz",
];

/// A Rust source or manifest under `dir` (outside the folders in [`NOT_BUILT`]) changed after
/// `time`.
fn newer_source(dir: &std::path::Path, time: std::time::SystemTime) -> Option<std::path::PathBuf> {
    let entries = std::fs::read_dir(dir).ok()?;
    for e in entries.flatten() {
        let path = e.path();
        let Ok(kind) = e.file_type() else { continue };
        let built = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| !NOT_BUILT.contains(&n));
        if kind.is_dir() {
            if built && let Some(p) = newer_source(&path, time) {
                return Some(p);
            }
        } else if path.extension().is_some_and(|x| x == "rs" || x == "toml")
            && e.metadata()
                .and_then(|m| m.modified())
                .is_ok_and(|m| m > time)
        {
            return Some(path);
        }
    }
    None
}

/// A studio (`scanner-host studio`) started in `dir` with `args` after its own, ended when
/// dropped.
pub struct StudioProcess {
    child: std::process::Child,
    /// The page's address it printed.
    pub url: String,
}

impl StudioProcess {
    /// Starts the studio and reads the address it prints.
    ///
    /// # Panics
    /// It does not start or print an address (a test helper).
    pub fn start(dir: &std::path::Path, args: &[&str]) -> StudioProcess {
        use std::io::BufRead;
        let mut child = std::process::Command::new(workspace_bin("scanner-host"))
            .arg("studio")
            .args(args)
            .current_dir(dir)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::inherit())
            .spawn()
            .expect("the studio starts");
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().expect("its output"))
            .read_line(&mut line)
            .expect("its first line");
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .unwrap_or_else(|| panic!("the studio printed its address: {line:?}"))
            .to_string();
        StudioProcess { child, url }
    }

    /// The studio on loopback (a free port) with its project in `dir/project` and a child head
    /// on the virtual rig, given `head_args` (`--scene job.toml`, …).
    ///
    /// # Panics
    /// As [`StudioProcess::start`].
    pub fn on_rig(dir: &std::path::Path, head_args: &str) -> StudioProcess {
        StudioProcess::on_source(dir, "rig", head_args)
    }

    /// The studio as [`StudioProcess::on_rig`], its head reading `source` (a camera, a folder
    /// of frames).
    ///
    /// # Panics
    /// As [`StudioProcess::start`].
    pub fn on_source(dir: &std::path::Path, source: &str, head_args: &str) -> StudioProcess {
        StudioProcess::start(
            dir,
            &[
                "--listen",
                "127.0.0.1:0",
                "--project",
                "project",
                "--source",
                source,
                "--head-args",
                head_args,
            ],
        )
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Kills it with SIGKILL, as a crash or a power cut would end it: nothing of it runs after.
    pub fn kill(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for StudioProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Stops a child the way Ctrl-C does (SIGINT) and checks that it ends well within 20 s.
///
/// # Panics
/// When it does not (a test helper).
pub fn interrupt(mut child: std::process::Child) {
    let pid = child.id().to_string();
    let sent = Command::new("kill").args(["-INT", &pid]).status();
    assert!(sent.is_ok_and(|s| s.success()), "kill -INT {pid}");
    let t0 = std::time::Instant::now();
    loop {
        if let Some(st) = child.try_wait().expect("the child's status") {
            assert!(st.success(), "the child ended with {st}");
            return;
        }
        assert!(
            t0.elapsed() < std::time::Duration::from_secs(20),
            "the child did not stop on Ctrl-C"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// The kinds of a failed command's error and its causes, outermost first (a wrapped variant's
/// names one by one), from the line of JSON
/// its stderr ends with ([`scanner_io::error_record`]); empty when there is none.
pub fn error_kinds(stderr: &str) -> Vec<String> {
    stderr
        .lines()
        .rev()
        .find(|l| l.starts_with("{\"program\":"))
        .and_then(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .and_then(|v| v["error"].as_array().cloned())
        .unwrap_or_default()
        .iter()
        .filter_map(|c| c["kind"].as_str().map(String::from))
        .flat_map(|k| k.split("::").map(String::from).collect::<Vec<_>>())
        .collect()
}

/// Whether a failed command's error (from its stderr, [`error_kinds`]) has a cause of `kind`.
pub fn has_kind(stderr: &str, kind: &str) -> bool {
    error_kinds(stderr).iter().any(|k| k == kind)
}

/// Reads a binary little-endian PLY back by its header (float and uchar vertex properties in any
/// order): vertices, faces and the `quality` property (empty without).
///
/// # Panics
/// On a file that is not such a PLY: this is a test helper.
pub fn read_ply(bytes: &[u8]) -> (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<f32>) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let count = |el: &str| -> usize {
        header
            .lines()
            .find(|l| l.starts_with(&format!("element {el} ")))
            .unwrap()
            .rsplit(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    // the vertex element's properties: (name, offset, size)
    let mut props = Vec::new();
    let mut stride = 0;
    let mut in_vertex = false;
    for l in header.lines() {
        if l.starts_with("element ") {
            in_vertex = l.starts_with("element vertex ");
        } else if in_vertex && let Some(rest) = l.strip_prefix("property ") {
            let (ty, name) = rest.split_once(' ').unwrap();
            let size = match ty {
                "float" => 4,
                "uchar" => 1,
                other => panic!("vertex property type {other}"),
            };
            props.push((name.to_string(), stride, size));
            stride += size;
        }
    }
    let at = |name: &str| props.iter().find(|p| p.0 == name).map(|p| p.1);
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let (x, y, z) = (at("x").unwrap(), at("y").unwrap(), at("z").unwrap());
    let q = at("quality");
    let mut p = end;
    let mut quality = Vec::new();
    let verts = (0..nv)
        .map(|_| {
            let v = [f(&bytes[p + x..]), f(&bytes[p + y..]), f(&bytes[p + z..])];
            if let Some(q) = q {
                quality.push(f(&bytes[p + q..]));
            }
            p += stride;
            v
        })
        .collect();
    let faces = (0..nf)
        .map(|_| {
            assert_eq!(bytes[p], 3);
            let i = |k: usize| {
                i32::from_le_bytes(bytes[p + 1 + 4 * k..p + 5 + 4 * k].try_into().unwrap()) as u32
            };
            let face = [i(0), i(1), i(2)];
            p += 13;
            face
        })
        .collect();
    assert_eq!(p, bytes.len());
    (verts, faces, quality)
}

/// Renders every frame of a rig's turntable scan into `folder` (created) as `000.png`, `001.png`,
/// …, RGB, as a turntable scanner's recording holds them.
///
/// # Panics
/// When a frame cannot be rendered or written: this is a test helper.
pub fn write_turning_frames(scan: &scanner_rig::TurningScan, folder: &std::path::Path) {
    std::fs::create_dir_all(folder).expect("the frames' folder");
    for k in 0..scan.frames {
        let f = scan.render(k).expect("a rendered frame");
        image::RgbImage::from_raw(f.width as u32, f.height as u32, f.data)
            .expect("a frame of its size")
            .save(folder.join(format!("{k:03}.png")))
            .expect("a written frame");
    }
}
