//! The live view: a web page that shows the scan while it happens (`receive --view`).
//!
//! Data flows one way: the receive loop hands each frame's points and a status line to a
//! [`LiveView`] without ever waiting (a bounded channel, `try_send`: a full channel drops a view
//! update, never a frame); a hub thread gathers them into the page's history (bounded: thinned
//! by half whenever it passes [`HISTORY_POINTS`]); the `server` module sends the history and what
//! follows to each page over a WebSocket in compact binary batches, and serves the page, the
//! embedded three.js and, when the scan ends, the mesh and the output files (held in memory:
//! no path from a request reaches the file system). The server is the front's
//! ([`crate::front`]): its host allow-list, origin check, token and limits.

mod server;

pub use server::MAX_PAGES;

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use scanner_core::nalgebra::Point3;
use scanner_host::collect::{Counts, PreviewImage};
use scanner_host::mesh::{Mesh, MeshFrame};
use scanner_wire::{PreviewState, Skip};

use crate::front::{FrontError, FrontLimits, Served, read_inside, serve};

/// Most points the page's history holds; past it every batch is thinned by half (a page that
/// joins late sees the whole scan, thinner).
pub const HISTORY_POINTS: usize = 2_000_000;
/// Points gathered into one batch before it is released to the pages (or after [`BATCH_AGE`]).
const BATCH_POINTS: usize = 16_384;
/// Longest a point waits in the hub before the pages get it.
const BATCH_AGE: Duration = Duration::from_millis(100);
/// View updates queued between the receive loop and the hub; more are dropped.
const QUEUE: usize = 512;
/// Largest output file offered for download (bigger ones are named on the page, not held).
pub const MAX_DOWNLOAD: u64 = 512 << 20;

/// Why the live view cannot start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The front could not start (the address, the token, the runtime).
    #[error(transparent)]
    Front(#[from] FrontError),
    /// A thread could not be started.
    #[error("cannot start the live view's threads")]
    Thread(#[source] std::io::Error),
}

/// One batch of points for the pages, in the page's frame (the board's, y up).
#[derive(Debug, Clone, Default)]
struct Batch {
    /// Sequence number (from 1).
    seq: u64,
    /// x, y, z per point, mm.
    xyz: Vec<f32>,
    /// r, g, b per point.
    rgb: Vec<u8>,
}

impl Batch {
    fn len(&self) -> usize {
        self.xyz.len() / 3
    }

    /// Keeps every second point.
    fn thin(&mut self) {
        let n = self.len();
        let mut k = 0;
        for i in (0..n).step_by(2) {
            self.xyz.copy_within(3 * i..3 * i + 3, 3 * k);
            self.rgb.copy_within(3 * i..3 * i + 3, 3 * k);
            k += 1;
        }
        self.xyz.truncate(3 * k);
        self.rgb.truncate(3 * k);
    }
}

/// The finished scan as the pages get it.
#[derive(Debug, Default)]
pub(crate) struct Finished {
    /// `{"type":"done",…}` for the pages.
    json: String,
    /// The mesh: see [`mesh_bin`].
    mesh: Vec<u8>,
    /// Output files by their fixed names, with their media types.
    files: Vec<(&'static str, &'static str, Vec<u8>)>,
}

/// What the pages are sent (behind the mutex).
#[derive(Debug, Default)]
pub(crate) struct History {
    batches: VecDeque<Arc<Batch>>,
    stored: usize,
    next_seq: u64,
    colour: bool,
    status: Option<(u64, String)>,
    /// The latest preview picture, `{"type":"preview",…}`, numbered like the status.
    preview: Option<(u64, String)>,
    finished: Option<Arc<Finished>>,
}

/// State shared by the hub, the server and the handle.
pub(crate) struct Shared {
    history: Mutex<History>,
    /// Told when the history changes.
    news: tokio::sync::Notify,
    closing: AtomicBool,
    /// View updates the receive loop dropped because the hub was behind.
    dropped: AtomicU64,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, History> {
        // A panicking page thread leaves the history as consistent as any other moment.
        self.history
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// What the receive loop hands over.
enum Update {
    Points(Vec<f32>, Vec<u8>, bool),
    Status(String),
    Preview(String),
    Finished(Finished),
}

/// The live view's handle, held by the receive loop.
pub struct LiveView {
    tx: Option<SyncSender<Update>>,
    shared: Arc<Shared>,
    url: String,
    frame: Option<MeshFrame>,
    hub: Option<JoinHandle<()>>,
    server: Option<Served>,
    started: Instant,
}

impl LiveView {
    /// Serves the page on `addr` (port 0: a free port) behind the front: loopback names and
    /// addresses, `addr`'s own and `names` as hosts; a non-loopback address gets a random token
    /// that every request must carry (`?token=…`, in the printed URL).
    ///
    /// # Errors
    /// The address cannot be bound, no token can be drawn, a thread cannot start.
    pub fn start(addr: SocketAddr, names: &[String]) -> Result<LiveView, LiveError> {
        let shared = Arc::new(Shared {
            history: Mutex::new(History::default()),
            news: tokio::sync::Notify::new(),
            closing: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
        });
        let server = {
            let shared = shared.clone();
            serve(
                addr,
                names,
                FrontLimits::DEFAULT,
                "live-view",
                move |access| server::router(shared, access),
            )?
        };
        let url = server.url("/");
        let (tx, rx) = std::sync::mpsc::sync_channel(QUEUE);
        let hub = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("view-hub".into())
                .spawn(move || hub(&rx, &shared))
                .map_err(LiveError::Thread)?
        };
        Ok(LiveView {
            tx: Some(tx),
            shared,
            url,
            frame: None,
            hub: Some(hub),
            server: Some(server),
            started: Instant::now(),
        })
    }

    /// The page's address (with its token, if any).
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Whether the page is reachable from other machines (a token is needed).
    pub fn is_public(&self) -> bool {
        self.server
            .as_ref()
            .is_some_and(|s| s.access.token().is_some())
    }

    /// The frame the page shows the points in (the board's once a header has come).
    pub fn set_frame(&mut self, frame: MeshFrame) {
        self.frame = Some(frame);
    }

    /// Whether the page's frame is set.
    pub fn has_frame(&self) -> bool {
        self.frame.is_some()
    }

    /// View updates dropped so far because the pages were behind (frames never are).
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    fn offer(&self, u: Update) {
        let Some(tx) = &self.tx else { return };
        match tx.try_send(u) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// One frame's points (camera frame, mm) and their colours (empty: none).
    pub fn points(&self, pts: &[Point3<f32>], rgb: &[[u8; 3]]) {
        if pts.is_empty() {
            return;
        }
        let mut xyz = Vec::with_capacity(pts.len() * 3);
        for p in pts {
            let q = match self.frame {
                Some(f) => f.point(p),
                None => *p,
            };
            xyz.extend_from_slice(&[q.x, q.y, q.z]);
        }
        let colour = rgb.len() == pts.len();
        let rgb = if colour {
            rgb.as_flattened().to_vec()
        } else {
            vec![200; pts.len() * 3]
        };
        self.offer(Update::Points(xyz, rgb, colour));
    }

    /// The status panel's figures from the host's counts.
    pub fn status(&self, k: &Counts) {
        let secs = self.started.elapsed().as_secs_f64().max(1e-3);
        self.offer(Update::Status(status_json(
            k,
            secs,
            self.dropped(),
            "receiving",
        )));
    }

    /// A preview picture with what the head found in it (`scanner-device preview`).
    pub fn preview(&self, p: &PreviewImage) {
        self.offer(Update::Preview(preview_json(p)));
    }

    /// A stage of a longer job (`merge`): one line for the page's state.
    pub fn stage(&self, text: &str) {
        self.offer(Update::Status(
            serde_json::json!({"type": "status", "kind": "merge", "state": text, "colouring": "points"})
                .to_string(),
        ));
    }

    /// The job is done: the mesh (camera frame, turned into the page's; or already in the
    /// page's) and the files `names` found in `dir` replace the points on the pages. `k`: the
    /// receive's counts for the status panel (none for `merge`).
    pub fn finish(
        &self,
        k: Option<&Counts>,
        mesh: Option<Mesh>,
        dir: &std::path::Path,
        names: &[&'static str],
        ended: &str,
    ) {
        self.end(k, mesh, dir, names, ended, false);
    }

    /// The job stopped without its result (a merge refused): `why` on the page, in the colour of
    /// a failure, and the files `names` found in `dir` offered (what the refusal left to look
    /// at).
    pub fn stopped(&self, dir: &std::path::Path, names: &[&'static str], why: &str) {
        self.end(None, None, dir, names, why, true);
    }

    fn end(
        &self,
        k: Option<&Counts>,
        mesh: Option<Mesh>,
        dir: &std::path::Path,
        names: &[&'static str],
        ended: &str,
        failed: bool,
    ) {
        let secs = self.started.elapsed().as_secs_f64().max(1e-3);
        let mut files = Vec::new();
        let mut listed = Vec::new();
        for name in names {
            match read_inside(dir, &[name], MAX_DOWNLOAD) {
                Ok(bytes) => {
                    listed.push(
                        serde_json::json!({"name": name, "bytes": bytes.len(), "held": true}),
                    );
                    files.push((*name, media_type(name), bytes));
                }
                Err(crate::front::FileRefusal::TooLarge { bytes, .. }) => {
                    listed.push(serde_json::json!({"name": name, "bytes": bytes, "held": false}));
                }
                Err(_) => {}
            }
        }
        let (mesh, vertices, faces) = match mesh {
            Some(mut m) => {
                if let Some(f) = self.frame {
                    m.into_frame(f);
                }
                (mesh_bin(&m), m.vertices.len(), m.faces.len())
            }
            None => (Vec::new(), 0, 0),
        };
        let mut status = match k {
            Some(k) => serde_json::from_str(&status_json(k, secs, self.dropped(), "done"))
                .unwrap_or_default(),
            None => serde_json::json!({"kind": "merge", "state": "done"}),
        };
        status["type"] = "done".into();
        status["ended"] = ended.into();
        status["failed"] = failed.into();
        status["files"] = listed.into();
        status["vertices"] = vertices.into();
        status["faces"] = faces.into();
        self.offer(Update::Finished(Finished {
            json: status.to_string(),
            mesh,
            files,
        }));
    }

    /// Serves the finished scan until `stop` is set or `for_secs` pass.
    pub fn linger(&self, stop: &AtomicBool, for_secs: Option<f64>) {
        let t0 = Instant::now();
        while !stop.load(Ordering::SeqCst)
            && for_secs.is_none_or(|s| t0.elapsed().as_secs_f64() < s)
        {
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        self.tx = None;
        self.shared.closing.store(true, Ordering::SeqCst);
        self.shared.news.notify_waiters();
        if let Some(h) = self.hub.take() {
            let _ = h.join();
        }
        if let Some(s) = self.server.take() {
            s.stop();
        }
    }
}

/// The hub: gathers updates into batches and releases them to the pages.
fn hub(rx: &Receiver<Update>, shared: &Shared) {
    let mut forming = Batch::default();
    let mut colour = false;
    let mut since = Instant::now();
    loop {
        let update = rx.recv_timeout(BATCH_AGE);
        let closed = matches!(update, Err(RecvTimeoutError::Disconnected));
        let mut release = closed || since.elapsed() >= BATCH_AGE;
        let mut finished = None;
        let mut status = None;
        let mut preview = None;
        match update {
            Ok(Update::Points(xyz, rgb, c)) => {
                if forming.xyz.is_empty() {
                    since = Instant::now();
                }
                colour |= c;
                forming.xyz.extend_from_slice(&xyz);
                forming.rgb.extend_from_slice(&rgb);
                release |= forming.len() >= BATCH_POINTS;
            }
            Ok(Update::Status(s)) => status = Some(s),
            Ok(Update::Preview(p)) => preview = Some(p),
            Ok(Update::Finished(f)) => {
                release = true;
                finished = Some(f);
            }
            Err(_) => {}
        }
        if release || status.is_some() || preview.is_some() {
            let mut h = shared.lock();
            if release && !forming.xyz.is_empty() {
                h.next_seq += 1;
                forming.seq = h.next_seq;
                h.stored += forming.len();
                h.colour = colour;
                h.batches.push_back(Arc::new(std::mem::take(&mut forming)));
                if h.stored > HISTORY_POINTS {
                    let mut stored = 0;
                    for b in &mut h.batches {
                        Arc::make_mut(b).thin();
                        stored += b.len();
                    }
                    h.stored = stored;
                }
                since = Instant::now();
            }
            if let Some(s) = status {
                let n = h.status.as_ref().map_or(0, |(n, _)| n + 1);
                h.status = Some((n, s));
            }
            if let Some(p) = preview {
                let n = h.preview.as_ref().map_or(0, |(n, _)| n + 1);
                h.preview = Some((n, p));
            }
            if let Some(f) = finished {
                h.finished = Some(Arc::new(f));
            }
            drop(h);
            shared.news.notify_waiters();
        }
        if closed {
            return;
        }
    }
}

/// A plain hint when one reason dominates the skipped frames.
fn hint(skipped: &[u64], frames: u64) -> Option<&'static str> {
    let total: u64 = skipped.iter().sum();
    let (i, &most) = skipped.iter().enumerate().max_by_key(|(_, n)| **n)?;
    if total == 0 || most * 2 < total || most * 10 < frames.max(1) {
        return None;
    }
    Some(match Skip::ALL[i] {
        Skip::NoStripe => {
            "no stripe on the board: switch the laser on, aim it so the line crosses the board, or darken the room"
        }
        Skip::OnePlaneOnly => "stripe on one plane only: sweep so the line crosses both sheets",
        Skip::PlaneThroughCamera => {
            "the laser plane passes through the camera: hold the laser further from it (10–30 cm above)"
        }
        Skip::PoorPlane => {
            "the laser plane failed its check: keep the sheets flat and the line sharp on both"
        }
        Skip::BadFrame => "the camera delivers bad frames: check its cable and resolution",
        Skip::LinkFull => "the link is too slow: use a faster baud rate or the USB link",
    })
}

/// A preview picture for the pages: the thumbnail's luma in base64, the dots, the line, the
/// exposure and what a scan would make of the frame, with a plain hint.
fn preview_json(p: &PreviewImage) -> String {
    use base64::Engine as _;
    let (state, why) = match p.state {
        PreviewState::Points => ("points", None),
        PreviewState::Skipped => ("skipped", p.skip.map(scanner_io::words::skip_reason)),
        PreviewState::NoCalibration => ("no_calibration", None),
        PreviewState::LaserInReference => (
            "laser_in_reference",
            Some("the laser was on in the reference: switch it off until the head says so"),
        ),
    };
    let hint = match p.state {
        PreviewState::Skipped => p.skip.and_then(|s| {
            let mut skipped = [0u64; scanner_wire::SKIP_REASONS];
            skipped[s as usize] = 1;
            hint(&skipped, 1)
        }),
        _ if p.clipped_permille > 20 => {
            Some("much of the picture is clipped white: lower the exposure or the light")
        }
        _ => None,
    };
    serde_json::json!({
        "type": "preview",
        "scan": p.scan_id,
        "frame": p.frame,
        "width": p.size.0,
        "height": p.size.1,
        "scale": p.scale,
        "pixels": base64::engine::general_purpose::STANDARD.encode(&p.pixels),
        "markers": p.markers,
        "rows": p.rows,
        "stripe": p.stripe,
        "clipped_percent": f64::from(p.clipped_permille) / 10.0,
        "laser_dn": p.laser_dn,
        "state": state,
        "skip": why,
        "points": p.points,
        "hint": hint,
    })
    .to_string()
}

/// The status panel's figures as JSON.
fn status_json(k: &Counts, secs: f64, dropped: u64, state: &str) -> String {
    let skipped = k.skipped();
    let frames: u64 = k.status.values().map(|s| u64::from(s.frames)).sum();
    let fps: f64 = k
        .status
        .values()
        .map(|s| f64::from(s.fps_milli) / 1000.0)
        .sum();
    let reasons: Vec<_> = Skip::ALL
        .iter()
        .zip(skipped)
        .filter(|(_, n)| *n > 0)
        .map(
            |(s, n)| serde_json::json!({"reason": scanner_io::words::skip_reason(*s), "frames": n}),
        )
        .collect();
    let rms: Vec<f64> = k
        .planes
        .values()
        .filter(|p| p.planes > 0)
        .map(|p| f64::from(p.rms_mean_um) / 1000.0)
        .collect();
    serde_json::json!({
        "type": "status",
        "state": state,
        "frames": frames,
        "packets": k.packets,
        "fps": fps,
        "points": k.points,
        "points_per_s": k.points as f64 / secs,
        "skipped": reasons,
        "hint": hint(&skipped, frames),
        "plane_rms_mm": rms.last(),
        "link_rejected": k.decode.rejected(),
        "duplicates": k.duplicates,
        "view_dropped": dropped,
        "scans": k.scans.len(),
        "seconds": secs,
        "notice": k.notices.back().map(scanner_io::words::notice_line),
        "notice_kind": k.notices.back().map(|n| n.kind.name()),
        "previews": k.previews,
    })
    .to_string()
}

fn media_type(name: &str) -> &'static str {
    match name.rsplit('.').next() {
        Some("png") => "image/png",
        Some("txt") => "text/plain; charset=utf-8",
        Some("obj") => "model/obj",
        Some("stl") => "model/stl",
        Some("3mf") => "model/3mf",
        _ => "application/octet-stream",
    }
}

/// The mesh for the page: `u32` vertex count, `u32` face count, `u8` colour flag and three
/// zero bytes, then x, y, z as `f32` per vertex, the faces as three `u32` each, and (with
/// colour) r, g, b per vertex; little-endian.
pub fn mesh_bin(m: &Mesh) -> Vec<u8> {
    let colour = m.colours.len() == m.vertices.len() && !m.colours.is_empty();
    let mut b = Vec::with_capacity(12 + m.vertices.len() * 15 + m.faces.len() * 12);
    b.extend_from_slice(&(m.vertices.len() as u32).to_le_bytes());
    b.extend_from_slice(&(m.faces.len() as u32).to_le_bytes());
    b.extend_from_slice(&[u8::from(colour), 0, 0, 0]);
    for v in &m.vertices {
        for c in [v.x, v.y, v.z] {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for f in &m.faces {
        for i in f {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    if colour {
        b.extend_from_slice(m.colours.as_flattened());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_every_second_point_with_its_colour() {
        let mut b = Batch {
            seq: 1,
            xyz: (0..15).map(|i| i as f32).collect(),
            rgb: (0..15).map(|i| i as u8).collect(),
        };
        b.thin();
        assert_eq!(b.xyz, vec![0., 1., 2., 6., 7., 8., 12., 13., 14.]);
        assert_eq!(b.rgb, vec![0, 1, 2, 6, 7, 8, 12, 13, 14]);
    }

    #[test]
    fn a_dominant_reason_gets_its_hint_and_a_mixed_one_none() {
        let mut s = [0u64; scanner_wire::SKIP_REASONS];
        s[Skip::OnePlaneOnly as usize] = 40;
        s[Skip::NoStripe as usize] = 5;
        assert!(hint(&s, 100).unwrap().contains("both sheets"));
        s[Skip::NoStripe as usize] = 40;
        s[Skip::PoorPlane as usize] = 40;
        assert_eq!(hint(&s, 200), None);
        // A few skipped frames in a long scan are no reason to nag.
        assert_eq!(hint(&[3, 0, 0, 0, 0, 0], 1000), None);
    }

    #[test]
    fn the_mesh_for_the_page_has_its_stated_layout() {
        let m = Mesh {
            vertices: vec![Point3::new(1.0, 2.0, 3.0); 3],
            colours: vec![[1, 2, 3]; 3],
            faces: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        let b = mesh_bin(&m);
        assert_eq!(b.len(), 12 + 3 * 12 + 12 + 9);
        assert_eq!(&b[0..4], &3u32.to_le_bytes());
        assert_eq!(&b[4..8], &1u32.to_le_bytes());
        assert_eq!(b[8], 1);
        assert_eq!(&b[12..16], &1f32.to_le_bytes());
        assert_eq!(&b[b.len() - 3..], &[1, 2, 3]);
    }
}
