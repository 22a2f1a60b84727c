//! The job the studio's page shows and keeps: what the head said (its replies, the preview, the
//! shots, the calibration, each sweep as a view with its own journal), the merge's outcome, in
//! a project folder. `job.json` is rewritten (atomically) at every step that matters, so that a
//! reload, a closed tab or a crash of the studio loses nothing, and a job can be opened again.

use std::path::{Path, PathBuf};

use scanner_host::journal::{Journal, JournalError};
use scanner_wire::{DiscFound, MAX_ENCODED, Message, NoticeKind, PreviewState, Reply};
use serde::{Deserialize, Serialize};

use crate::front::{FileRefusal, read_inside};

/// Most lines the page's log keeps.
const LOG_LINES: usize = 40;
/// Most views one job takes (as the merge).
pub const MAX_VIEWS: usize = 32;
/// Most shots the job lists.
const MAX_SHOTS: usize = 256;

/// The job, as the page reads it (`/api/state`) and `job.json` keeps it.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Job {
    /// The head's last answer.
    pub head: HeadView,
    /// The last preview picture's facts.
    pub preview: Option<SetupCheck>,
    /// Every calibration shot, in order.
    pub shots: Vec<ShotRecord>,
    /// The calibration, once made.
    pub calibration: Option<CalibrationResult>,
    /// The sweeps, each a view.
    pub views: Vec<SweepRecord>,
    /// A sweep asked for whose header has not come yet.
    #[serde(skip)]
    pub awaiting_sweep: bool,
    /// The head accepted the sweep asked for (its header has not come yet): a head idle then
    /// has failed it before its first frame.
    #[serde(skip)]
    pub sweep_accepted: bool,
    /// Why the last sweep asked for failed before its first frame (the head's own words where
    /// the studio started it and reads its log); `None`: it did not.
    #[serde(default)]
    pub sweep_failed: Option<String>,
    /// The disc the last sweep asked for (`a4`, `a3`), for the view it opens.
    #[serde(skip)]
    pub asked_disc: Option<String>,
    /// The camera's controls set by hand on the page.
    #[serde(default)]
    pub camera: scanner_wire::ByHand,
    /// The merge, once asked for.
    pub merge: Option<Merge>,
    /// What happened, newest last.
    pub log: Vec<String>,
    /// Picture of the last preview (thumbnail luma and its size), not kept on disk.
    #[serde(skip)]
    pub picture: Option<(u16, u16, Vec<u8>)>,
    /// The last full-resolution picture (a JPEG), not kept on disk.
    #[serde(skip)]
    pub jpeg: Option<Vec<u8>>,
    /// What that picture shows.
    pub sharpness: Option<Sharpness>,
    /// The open view's points as they arrive, thinned, for the page; not kept on disk (the
    /// journal has them all).
    #[serde(skip)]
    pub live: LivePoints,
}

/// Most points the page's live picture of a sweep holds; past it every second one goes.
pub const LIVE_POINTS: usize = 60_000;

/// A sweep's points as they arrive, thinned to at most [`LIVE_POINTS`].
#[derive(Debug, Clone, Default)]
pub struct LivePoints {
    /// The view they belong to (from 1; 0: none yet).
    pub view: usize,
    /// Bumped whenever the list is thinned or restarted: a reader starts again from 0.
    pub generation: u32,
    /// x, y, z per point, mm, camera coordinates.
    pub xyz: Vec<[f32; 3]>,
    unit_mm: f32,
    stride: u32,
    seen: u32,
}

impl LivePoints {
    fn start(&mut self, view: usize, unit_um: u16) {
        self.view = view;
        self.generation += 1;
        self.xyz.clear();
        self.unit_mm = f32::from(unit_um) / 1000.0;
        self.stride = 1;
        self.seen = 0;
    }

    fn push(&mut self, q: [i32; 3]) {
        self.seen = self.seen.wrapping_add(1);
        if !self.seen.is_multiple_of(self.stride.max(1)) {
            return;
        }
        self.xyz.push(q.map(|v| v as f32 * self.unit_mm));
        if self.xyz.len() > LIVE_POINTS {
            let mut k = 0;
            self.xyz.retain(|_| {
                k += 1;
                k % 2 == 0
            });
            self.stride = self.stride.saturating_mul(2);
            self.generation += 1;
        }
    }
}

/// The last full-resolution picture's region and focus figure.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sharpness {
    /// Its frame number.
    pub frame: u32,
    /// `x, y, width, height` of the camera's picture it shows.
    pub region: [u16; 4],
    /// Camera pixels per picture pixel.
    pub scale: u8,
    /// The width of its sharpest edges, camera pixels (about 2.5 sharp; 8 or more: out of
    /// focus); `None`: no edge to tell by.
    pub edge_px: Option<f64>,
}

/// Edges wider than this, camera pixels, read as out of focus (a blur of σ ≈ 3 px).
pub const OUT_OF_FOCUS_PX: f64 = 8.0;

/// What the head last said of itself.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct HeadView {
    /// Whether it has answered at all.
    pub heard: bool,
    /// What it is doing: `idle`, `previewing`, `sweeping`, `calibrating`.
    pub state: String,
    /// The head switched its lasers off because it heard nothing from the studio for this
    /// many seconds (told when the studio was heard again); `None`: it has not.
    #[serde(default)]
    pub laser_off_unheard_s: Option<u16>,
}

/// A preview picture's facts, for the set-up's verdict.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SetupCheck {
    /// Its number in the preview session.
    pub frame: u32,
    /// Thumbnail size.
    pub width: u16,
    /// …
    pub height: u16,
    /// Camera pixels per thumbnail pixel.
    pub scale: u16,
    /// Clipped pixels, per mille.
    pub clipped_permille: u16,
    /// Dark dots found (the board's, the disc's).
    pub markers: usize,
    /// Share of the lines where the laser line was found, per cent.
    pub laser_lines_pct: f64,
    /// The light the laser adds, DN.
    pub laser_dn: u16,
    /// What a scan would do with the frame: `points`, `skipped`, `no_calibration`,
    /// `laser_in_reference`.
    pub state: String,
    /// The verdict: `good`, or what to fix first.
    pub verdict: String,
}

/// A calibration shot.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ShotRecord {
    /// A board shot (else the intrinsics target).
    pub board: bool,
    /// Kept for the calibration.
    pub kept: bool,
    /// `kept`, `not_found`, `not_usable`.
    pub found: String,
    /// Points placed.
    pub points: u16,
    /// Cells of the 8 × 8 coverage map it covers.
    pub cover: u64,
    /// Tilt about the picture's horizontal and vertical axes, degrees.
    pub tilt_deg: [i8; 2],
}

/// The calibration's figures.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CalibrationResult {
    /// `calibrated`, `intrinsics_failed`, `board_failed`.
    pub result: String,
    /// Target shots used.
    pub shots: u16,
    /// RMS reprojection error, pixels.
    pub rms_px: Option<f32>,
    /// The halves' RMS difference over the picture, pixels.
    pub halves_px: Option<f32>,
    /// The board's fit, RMS pixels.
    pub board_rms_px: Option<f32>,
    /// The angle between the sheets, degrees.
    pub board_angle_deg: Option<f32>,
}

/// A sweep: one view of the object.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepRecord {
    /// Its scan id.
    pub scan_id: u32,
    /// Its journal, relative to the project folder.
    pub journal: PathBuf,
    /// Frames captured (last status).
    pub frames: u32,
    /// Points received.
    pub points: u64,
    /// The sweep has ended.
    pub done: bool,
    /// How: `completed`, `stopped`, `camera_lost`; `end_lost`: the head had ended it but its
    /// last status was lost on the link; `interrupted`: the studio stopped first.
    pub ended: Option<String>,
    /// The turntable disc: `found`, or why not (`too_few_dots`, `ambiguous_turn`, `edge_on`,
    /// `no_pose`); `None`: not looked for.
    pub disc: Option<String>,
    /// Left out of the merge (by the maker).
    pub left_out: bool,
    /// The disc asked for: `a4`, `a3`; `None`: no disc.
    #[serde(default)]
    pub disc_paper: Option<String>,
    /// Rebuilt from its journal when the job was opened again (the studio stopped during the
    /// sweep): its points and frames are the journal's.
    #[serde(default)]
    pub rebuilt: bool,
    /// The model of this view alone (a fixed-laser turntable's whole model, or one view's
    /// surface), once asked for.
    #[serde(default)]
    pub model: Option<ViewModel>,
}

/// A view's own model: what the host's `receive` makes of its journal, in `views/view-N/`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ViewModel {
    /// `running`, `made`, `failed`.
    pub state: String,
    /// Why it failed, as words.
    pub error: Option<String>,
    /// Files to download.
    pub files: Vec<String>,
    /// Its `summary.json`, when written.
    pub summary: Option<serde_json::Value>,
}

/// A view the merge did not take, and why.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LeftOut {
    /// The view, from 1 (as the page's table numbers them).
    pub view: usize,
    /// `left_out` (by the maker), `no_points`, `not_ended`.
    pub why: String,
}

/// What a merge's report says against calling its model merged.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Problem {
    /// `pieces`, `disc_size`, …
    pub kind: String,
    /// What is wrong and what to do, in the page's terms.
    pub words: String,
}

/// A view the merge leaves out: its number in the table (from 1) and why.
pub type LeftOutView = (usize, &'static str);

/// The merge's outcome.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Merge {
    /// `running`, `merged`, `refused`, `failed`.
    pub state: String,
    /// Its error, as words.
    pub error: Option<String>,
    /// A refusal's kind and the views it names, as the table numbers them.
    #[serde(default)]
    pub refusal: Option<super::merge_words::PageRefusal>,
    /// The report (`merge-report.json`), when written.
    pub report: Option<serde_json::Value>,
    /// Files to download.
    pub files: Vec<String>,
    /// The views it did not take, and why.
    #[serde(default)]
    pub left_out: Vec<LeftOut>,
    /// Why a model the merge wrote is not called merged.
    #[serde(default)]
    pub problems: Vec<Problem>,
}

/// Why a job cannot be opened or kept.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// `job.json` is not a job.
    #[error("{path} is no job: {source}")]
    NotAJob {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// `job.json` could not be read or written.
    #[error("cannot {doing} {path}")]
    Io {
        /// `read`, `write`.
        doing: &'static str,
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A view's journal could not be read or written.
    #[error("the journal of a view: {0}")]
    Journal(#[from] JournalError),
    /// A job takes at most [`MAX_VIEWS`] views.
    #[error("a job takes at most {MAX_VIEWS} views")]
    TooManyViews,
}

/// What a view's journal holds.
#[derive(Debug, Clone, Default)]
pub struct JournalRead {
    /// Its scan id (the first header's).
    pub scan_id: Option<u32>,
    /// Points of that scan.
    pub points: u64,
    /// Frames by its last status.
    pub frames: u32,
    /// Its last status said it had ended.
    pub ended: bool,
    /// Up to the asked-for number of its points, evenly thinned, mm, camera frame.
    pub xyz: Vec<[f32; 3]>,
}

/// Largest view journal read, bytes.
const MAX_JOURNAL: u64 = 1 << 30;

/// Reads the journal `rel` of the project folder: its points counted, up to `keep` of them kept
/// (evenly thinned), its frames and whether it ended. A journal cut mid-frame (a crash) is read
/// up to its last whole frame.
///
/// # Errors
/// The file is not there, is no regular file, or is too large.
pub fn read_journal(project: &Path, rel: &Path, keep: usize) -> Result<JournalRead, FileRefusal> {
    let parts: Vec<&str> = rel.iter().filter_map(|p| p.to_str()).collect();
    let bytes = read_inside(project, &parts, MAX_JOURNAL)?;
    let mut out = JournalRead::default();
    let mut unit_mm = 0.0f32;
    let mut all: Vec<[f32; 3]> = Vec::new();
    let mut stride = 1u64;
    let mut seen = 0u64;
    let mut d = Box::new(scanner_wire::Decoder::<MAX_ENCODED>::new());
    d.feed(&bytes, |m| {
        let Ok(msg) = m else { return };
        if out.scan_id.is_none()
            && let Message::Header(h) = &msg
        {
            out.scan_id = Some(h.scan_id);
            unit_mm = f32::from(h.unit_um) / 1000.0;
        }
        if msg.scan_id() != out.scan_id || out.scan_id.is_none() {
            return;
        }
        match &msg {
            Message::Points(p) => {
                out.points += u64::from(p.count);
                let _ = scanner_wire::points::decode(p.xyz, p.count as usize, |q| {
                    seen += 1;
                    if keep > 0 && seen.is_multiple_of(stride) {
                        all.push(q.map(|v| v as f32 * unit_mm));
                        if all.len() > keep {
                            let mut k = 0;
                            all.retain(|_| {
                                k += 1;
                                k % 2 == 0
                            });
                            stride *= 2;
                        }
                    }
                });
            }
            Message::Status(st) => {
                out.frames = st.frames;
                out.ended |= st.done;
            }
            _ => {}
        }
    });
    out.xyz = all;
    Ok(out)
}

impl Job {
    /// Reads `job.json` of a project folder, or a new job. A view cut by a crash (its sweep
    /// not ended in the job) is rebuilt from its journal: its points and frames are the
    /// journal's, and the log says so. The log is cut to its last lines.
    ///
    /// # Errors
    /// [`JobError`]: the file exists but cannot be read as a job.
    pub fn open(project: &Path) -> Result<Job, JobError> {
        let path = project.join("job.json");
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Job::default()),
            Err(source) => {
                return Err(JobError::Io {
                    doing: "read",
                    path,
                    source,
                });
            }
        };
        let mut job: Job =
            serde_json::from_slice(&bytes).map_err(|source| JobError::NotAJob { path, source })?;
        let keep = job.log.len().saturating_sub(LOG_LINES);
        job.log.drain(..keep);
        job.views.truncate(MAX_VIEWS);
        let mut lines = Vec::new();
        for (k, v) in job.views.iter_mut().enumerate() {
            if v.done {
                continue;
            }
            v.done = true;
            v.ended.get_or_insert_with(|| "interrupted".into());
            match read_journal(project, &v.journal, 0) {
                Ok(r) => {
                    v.points = v.points.max(r.points);
                    v.frames = v.frames.max(r.frames);
                    v.rebuilt = true;
                    lines.push(format!(
                        "view {}: cut when the studio stopped; rebuilt from its journal: {} points, {} frames",
                        k + 1,
                        v.points,
                        v.frames
                    ));
                }
                Err(e) => lines.push(format!(
                    "view {}: cut when the studio stopped, and its journal cannot be read: {e}",
                    k + 1
                )),
            }
        }
        for l in lines {
            job.say(l);
        }
        if job.merge.as_ref().is_some_and(|m| m.state == "running") {
            job.merge = None;
        }
        for v in &mut job.views {
            if v.model.as_ref().is_some_and(|m| m.state == "running") {
                v.model = None;
            }
        }
        Ok(job)
    }

    /// Writes `job.json` whole or not at all.
    ///
    /// # Errors
    /// [`JobError::Io`]: the file cannot be written.
    pub fn save(&self, project: &Path) -> Result<(), JobError> {
        let path = project.join("job.json");
        let bytes = serde_json::to_vec_pretty(self).map_err(|source| JobError::NotAJob {
            path: path.clone(),
            source,
        })?;
        scanner_host::export::write_atomic(&path, &bytes).map_err(|e| JobError::Io {
            doing: "write",
            path,
            source: std::io::Error::other(e.to_string()),
        })
    }

    /// Adds a line to the log.
    pub fn say(&mut self, line: impl Into<String>) {
        let over = (self.log.len() + 1).saturating_sub(LOG_LINES);
        self.log.drain(..over);
        self.log.push(line.into());
    }

    /// The views the merge takes (their number in the table, from 1, and their journals), and
    /// every view it leaves out (from 1) with why: `left_out` (by the maker), `no_points`,
    /// `not_ended`.
    pub fn merge_views(&self, project: &Path) -> (Vec<(usize, PathBuf)>, Vec<LeftOutView>) {
        let mut taken = Vec::new();
        let mut left = Vec::new();
        for (k, v) in self.views.iter().enumerate() {
            let why = if v.left_out {
                Some("left_out")
            } else if !v.done {
                Some("not_ended")
            } else if v.points == 0 {
                Some("no_points")
            } else {
                None
            };
            match why {
                Some(w) => left.push((k + 1, w)),
                None => taken.push((k + 1, project.join(&v.journal))),
            }
        }
        (taken, left)
    }

    /// Union of the target shots' coverage.
    pub fn cover(&self) -> u64 {
        self.shots
            .iter()
            .filter(|s| s.kept && !s.board)
            .fold(0, |c, s| c | s.cover)
    }
}

/// What a message from the head changes, and whether `job.json` should be written.
pub struct Update {
    /// Write `job.json` now.
    pub save: bool,
}

/// Where a sweep's messages go: its view's journal.
#[derive(Default)]
pub struct Journals {
    open: Option<(u32, Journal)>,
}

impl Journals {
    /// Closes the open journal (synced).
    pub fn close(&mut self) {
        if let Some((_, mut j)) = self.open.take() {
            let _ = j.sync();
        }
    }
}

/// Takes one message from the head into the job (and the sweep's journal).
///
/// # Errors
/// [`JobError`]: the view's journal cannot be opened or written, too many views.
pub fn take(
    job: &mut Job,
    journals: &mut Journals,
    project: &Path,
    msg: &Message,
) -> Result<Update, JobError> {
    let mut save = false;
    match msg {
        Message::Reply(r) => {
            take_reply(job, r);
            // the sweep accepted, and the head idle with no header: it failed at its start
            if job.awaiting_sweep && job.sweep_accepted && r.state == scanner_wire::HeadState::Idle
            {
                job.awaiting_sweep = false;
                job.sweep_accepted = false;
                let why = head_failure(project, "sweep failed: ")
                    .unwrap_or_else(|| "see the head's log".into());
                job.say(format!("the sweep failed before its first frame: {why}"));
                job.sweep_failed = Some(why);
                save = true;
            }
            // the head answers after everything of an ended sweep is on the link: a view
            // still open then lost its last status to the link (its points stay)
            if r.state != scanner_wire::HeadState::Sweeping && !job.awaiting_sweep {
                let mut lines = Vec::new();
                for (k, v) in job.views.iter_mut().enumerate().filter(|(_, v)| !v.done) {
                    v.done = true;
                    v.ended = Some("end_lost".into());
                    lines.push(format!(
                        "view {}: {} points; its last status was lost on the link",
                        k + 1,
                        v.points
                    ));
                }
                if !lines.is_empty() {
                    journals.close();
                    save = true;
                    lines.into_iter().for_each(|l| job.say(l));
                }
            }
        }
        Message::Notice(n) if n.kind == NoticeKind::LaserOffUnheard => {
            job.head.laser_off_unheard_s = Some(n.seconds);
            job.say(format!(
                "the head switched the laser off: it heard nothing from the studio for {} s (press Laser on to go on)",
                n.seconds
            ));
            save = true;
        }
        Message::Preview(p) => {
            let lit = p.stripe.iter().filter(|&&s| s != 255).count();
            let facts = SetupCheck {
                frame: p.frame,
                width: p.width,
                height: p.height,
                scale: p.scale,
                clipped_permille: p.clipped_permille,
                markers: p.markers.len() / 2,
                laser_lines_pct: if p.stripe.is_empty() {
                    0.0
                } else {
                    100.0 * lit as f64 / p.stripe.len() as f64
                },
                laser_dn: p.laser_dn,
                state: match p.state {
                    PreviewState::Points => "points",
                    PreviewState::Skipped => "skipped",
                    PreviewState::NoCalibration => "no_calibration",
                    PreviewState::LaserInReference => "laser_in_reference",
                }
                .into(),
                verdict: String::new(),
            };
            job.preview = Some(SetupCheck {
                verdict: verdict(&facts),
                ..facts
            });
            job.picture = Some((p.width, p.height, p.pixels.to_vec()));
        }
        Message::Picture(p) => {
            job.jpeg = Some(p.jpeg.to_vec());
            job.sharpness = Some(Sharpness {
                frame: p.frame,
                region: [p.x, p.y, p.width, p.height],
                scale: p.scale,
                edge_px: (p.edge_cpx != u16::MAX).then(|| f64::from(p.edge_cpx) / 100.0),
            });
            if let Some(f) = job.preview.as_mut()
                && f.verdict == "good"
                && job
                    .sharpness
                    .as_ref()
                    .and_then(|s| s.edge_px)
                    .is_some_and(|w| w > OUT_OF_FOCUS_PX)
            {
                f.verdict = "out_of_focus".into();
            }
        }
        Message::Shot(s) => {
            if job.shots.len() < MAX_SHOTS {
                job.shots.push(ShotRecord {
                    board: s.board,
                    kept: s.found == 0,
                    found: ["kept", "not_found", "not_usable"]
                        .get(usize::from(s.found))
                        .unwrap_or(&"not_usable")
                        .to_string(),
                    points: s.points,
                    cover: s.cover,
                    tilt_deg: s.tilt_deg,
                });
            }
            job.say(format!(
                "{} shot: {}",
                if s.board { "board" } else { "target" },
                if s.found == 0 {
                    format!("kept ({} points)", s.points)
                } else {
                    "not usable: hold it in view, lit and in focus".into()
                }
            ));
            save = true;
        }
        Message::Calibrated(c) => {
            let f = |v: f32| v.is_finite().then_some(v);
            job.calibration = Some(CalibrationResult {
                result: ["calibrated", "intrinsics_failed", "board_failed"]
                    .get(usize::from(c.result))
                    .unwrap_or(&"failed")
                    .to_string(),
                shots: c.shots,
                rms_px: f(c.rms_px),
                halves_px: f(c.halves_px),
                board_rms_px: f(c.board_rms_px),
                board_angle_deg: f(c.board_angle_deg),
            });
            job.say(match c.result {
                0 => format!(
                    "calibrated from {} shots: {:.3} px RMS; the board's sheets meet at {:.1}°",
                    c.shots, c.rms_px, c.board_angle_deg
                ),
                1 => "the intrinsics failed their checks: take more target shots, tilted and in every corner".into(),
                _ => "the board was not found in its shot: take the board's shot again, laser off, both sheets in view".into(),
            });
            save = true;
        }
        // every sweep the head runs is a view of the job: asked for by this page, by another,
        // or before the studio restarted
        Message::Header(h) => {
            let known = job.views.iter().any(|v| v.scan_id == h.scan_id);
            if !known {
                if job.views.len() >= MAX_VIEWS {
                    return Err(JobError::TooManyViews);
                }
                job.awaiting_sweep = false;
                job.sweep_accepted = false;
                job.sweep_failed = None;
                let n = job.views.len() + 1;
                let rel = PathBuf::from(format!("views/view-{n}.stream"));
                let path = project.join(&rel);
                std::fs::create_dir_all(project.join("views")).map_err(|source| JobError::Io {
                    doing: "create",
                    path: project.join("views"),
                    source,
                })?;
                journals.close();
                let j = Journal::open(&path)?;
                journals.open = Some((h.scan_id, j));
                job.live.start(n, h.unit_um);
                job.views.push(SweepRecord {
                    scan_id: h.scan_id,
                    journal: rel,
                    frames: 0,
                    points: 0,
                    done: false,
                    ended: None,
                    disc: None,
                    left_out: false,
                    disc_paper: job.asked_disc.clone(),
                    rebuilt: false,
                    model: None,
                });
                job.say(format!("view {n}: sweeping"));
                save = true;
            }
        }
        _ => {}
    }
    // a sweep's messages go into its view's journal
    if let (Some(id), Some((open, j))) = (msg.scan_id(), journals.open.as_mut())
        && id == *open
    {
        j.append(msg)?;
    }
    let Some(view) = msg
        .scan_id()
        .and_then(|id| job.views.iter_mut().find(|v| v.scan_id == id))
    else {
        return Ok(Update { save });
    };
    match msg {
        Message::Points(p) => {
            view.points += u64::from(p.count);
            if journals
                .open
                .as_ref()
                .is_some_and(|(id, _)| *id == p.scan_id)
            {
                let live = &mut job.live;
                // a packet that does not decode was journaled as it came; the picture skips it
                let _ = scanner_wire::points::decode(p.xyz, p.count as usize, |q| live.push(q));
            }
        }
        Message::Disc(d) => {
            view.disc = Some(
                match d.found {
                    DiscFound::Found => "found",
                    DiscFound::TooFewMarkers => "too_few_dots",
                    DiscFound::Ambiguous => "ambiguous_turn",
                    DiscFound::Tilted => "edge_on",
                    DiscFound::PoorFit => "no_pose",
                }
                .into(),
            );
            save = true;
        }
        Message::Status(s) => {
            view.frames = s.frames;
            if s.done {
                view.done = true;
                view.ended = Some(
                    match s.ended {
                        scanner_wire::EndReason::Completed => "completed",
                        scanner_wire::EndReason::CameraLost => "camera_lost",
                        scanner_wire::EndReason::Stopped => "stopped",
                    }
                    .into(),
                );
                let line = format!(
                    "view {}: {} points{}",
                    job.views.len(),
                    job.views.last().map_or(0, |v| v.points),
                    match job.views.last().and_then(|v| v.disc.as_deref()) {
                        Some("found") =>
                            ", the disc found: turn the disc and take the next view".to_string(),
                        Some(why) => format!(", the disc not found ({why})"),
                        None => String::new(),
                    }
                );
                job.say(line);
                journals.close();
                save = true;
            }
        }
        Message::Notice(n) if n.kind == NoticeKind::NoLaser => {
            job.say("no laser seen: switch the laser on");
        }
        _ => {}
    }
    Ok(Update { save })
}

/// Largest tail of the head's log read for its last failure, bytes.
const HEAD_LOG_TAIL: u64 = 64 << 10;

/// The head's own words for its last failure of `what` (a line of `head.log` starting with
/// it), where the studio started the head and keeps its log in the project folder.
fn head_failure(project: &Path, what: &str) -> Option<String> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(project.join("head.log")).ok()?;
    let len = f.metadata().ok()?.len();
    f.seek(SeekFrom::Start(len.saturating_sub(HEAD_LOG_TAIL)))
        .ok()?;
    let mut tail = Vec::new();
    f.read_to_end(&mut tail).ok()?;
    String::from_utf8_lossy(&tail)
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix(what).map(str::to_string))
}

fn take_reply(job: &mut Job, r: &Reply) {
    job.head.heard = true;
    job.head.state = match r.state {
        scanner_wire::HeadState::Idle => "idle",
        scanner_wire::HeadState::Previewing => "previewing",
        scanner_wire::HeadState::Sweeping => "sweeping",
        scanner_wire::HeadState::Calibrating => "calibrating",
    }
    .into();
}

/// The set-up's verdict on a preview: `good`, or what to fix first.
fn verdict(f: &SetupCheck) -> String {
    if f.clipped_permille > 20 {
        return "too_bright".into();
    }
    if f.markers < 6 {
        return "board_not_seen".into();
    }
    match f.state.as_str() {
        "laser_in_reference" => "laser_in_reference".into(),
        "skipped" => "laser_not_across_board".into(),
        _ if f.laser_lines_pct < 5.0 => "laser_not_seen".into(),
        _ => "good".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::{Job, Journals, take};
    use scanner_wire::{
        CameraBlock, HeadState, Header, Message, Outcome, PlaneBlock, PlaneMethod, Reply,
    };

    fn header(scan_id: u32) -> Header {
        Header {
            scan_id,
            width: 640,
            height: 480,
            unit_um: 10,
            camera: CameraBlock {
                fx: 700.0,
                fy: 700.0,
                cx: 320.0,
                cy: 240.0,
                k1: 0.0,
                k2: 0.0,
                p1: 0.0,
                p2: 0.0,
                k3: 0.0,
            },
            board: [
                PlaneBlock {
                    normal: [0.7, 0.0, -0.7],
                    offset: 565.0,
                },
                PlaneBlock {
                    normal: [-0.7, 0.0, -0.7],
                    offset: 565.0,
                },
            ],
            colour: false,
            method: PlaneMethod::LeastSquares,
        }
    }

    /// The merge takes every ended view with points, and names each other with why.
    #[test]
    fn the_merge_names_every_view_it_leaves_out() {
        let view = |points, done, left_out| super::SweepRecord {
            scan_id: 1,
            journal: "views/v.stream".into(),
            frames: 0,
            points,
            done,
            ended: None,
            disc: None,
            left_out,
            disc_paper: None,
            rebuilt: false,
            model: None,
        };
        let job = Job {
            views: vec![
                view(10, true, false),
                view(10, true, true),
                view(0, true, false),
                view(10, false, false),
            ],
            ..Job::default()
        };
        let (taken, left) = job.merge_views(std::path::Path::new("p"));
        assert_eq!(taken, [(1, std::path::PathBuf::from("p/views/v.stream"))]);
        assert_eq!(
            left,
            vec![(2, "left_out"), (3, "no_points"), (4, "not_ended")]
        );
    }

    fn reply(state: HeadState) -> Message<'static> {
        Message::Reply(Reply {
            seq: 1,
            outcome: Outcome::Accepted,
            state,
            field: 0,
            detail: 0,
        })
    }

    /// The head's replies "sweeping", then "idle"; the update of the second.
    fn sweeping_then_idle(
        job: &mut Job,
        journals: &mut Journals,
        dir: &std::path::Path,
    ) -> super::Update {
        take(job, journals, dir, &reply(HeadState::Sweeping)).unwrap();
        take(job, journals, dir, &reply(HeadState::Idle)).unwrap()
    }

    /// A sweep the head accepted and then failed before its first frame (no header; the head
    /// idle): the studio stops waiting for it and gives the head's own words from its log.
    #[test]
    fn a_sweep_that_failed_at_its_start_is_told_with_the_heads_words() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("head.log"),
            "serving\nsweep failed: the first laser frame does not tell which way\n",
        )
        .unwrap();
        let (mut job, mut journals) = (Job::default(), Journals::default());
        job.awaiting_sweep = true;
        // idle before the head accepted it: not yet a failure
        take(&mut job, &mut journals, dir.path(), &reply(HeadState::Idle)).unwrap();
        assert!(job.awaiting_sweep && job.sweep_failed.is_none());
        job.sweep_accepted = true;
        let u = sweeping_then_idle(&mut job, &mut journals, dir.path());
        assert!(u.save && !job.awaiting_sweep && job.views.is_empty());
        assert_eq!(
            job.sweep_failed.as_deref(),
            Some("the first laser frame does not tell which way")
        );
        // the next sweep's header clears it
        job.awaiting_sweep = true;
        take(
            &mut job,
            &mut journals,
            dir.path(),
            &Message::Header(header(9)),
        )
        .unwrap();
        assert!(job.sweep_failed.is_none() && job.views.len() == 1);
    }

    /// A sweep whose last status the link lost is closed when the head says it is idle, and
    /// not before; a scan's header opens one view, however often it comes.
    #[test]
    fn a_view_whose_last_status_was_lost_ends_when_the_head_is_idle() {
        let dir = tempfile::tempdir().unwrap();
        let (mut job, mut journals) = (Job::default(), Journals::default());
        take(
            &mut job,
            &mut journals,
            dir.path(),
            &Message::Header(header(7)),
        )
        .unwrap();
        assert_eq!(job.views.len(), 1, "every sweep of the head is a view");
        take(
            &mut job,
            &mut journals,
            dir.path(),
            &Message::Header(header(7)),
        )
        .unwrap();
        assert_eq!(
            job.views.len(),
            1,
            "a header once more opens no second view"
        );
        let u = sweeping_then_idle(&mut job, &mut journals, dir.path());
        assert!(u.save);
        assert!(job.views[0].done);
        assert_eq!(job.views[0].ended.as_deref(), Some("end_lost"));
        assert!(dir.path().join("views/view-1.stream").exists());
        // opened again as after a crash: the view is the journal's
        job.views[0].done = false;
        job.views[0].points = 0;
        job.save(dir.path()).unwrap();
        let again = Job::open(dir.path()).unwrap();
        assert!(again.views[0].done && again.views[0].rebuilt);
    }
}
