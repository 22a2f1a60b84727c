//! `serve`: the head as a service on a two-way link. It waits for the host's commands
//! (docs/wire.md, "Commands"), answers each with a [`Reply`] (accepted, or refused and why), and
//! runs what they ask: the preview, calibration shots and the calibration, sweeps, the camera's
//! controls, the laser and the turntable where it has them. One thing runs at a time, in a
//! worker thread, so that commands are answered while it runs; a Pi's unit starts the service
//! once and it takes one job after another.
//!
//! Threads: the reader decodes commands from the link; the dispatcher (the caller's thread)
//! answers them and starts the work; a worker runs it. Every frame reaches the link whole,
//! through one lock (`SharedOut`).

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use scanner_core::nalgebra::{Point2, Vector2, Vector3};
use scanner_core::stripe::PixelFormat;
use scanner_wire::calibration::{COVER_COLS, Calibrated, ShotTaken};
use scanner_wire::{
    Command, CommandDecoder, CommandError, CommandFrame, CommandFrameError, HeadState, MAX_ENCODED,
    Message, Outcome, PreviewRequest, Reply, SweepRequest, WireError,
};

use super::calibrate::TargetArgs;
use super::scan::{ScanArgs, open_on, open_source, source_format};
use crate::calibrate::load_board;
use crate::link::Link;
use crate::preview::{PreviewOptions, run_preview};
use crate::source::{FrameSource, OwnedFrame, SourceError};

/// Target shots a calibration needs at least (the intrinsics' own minimum).
pub const MIN_TARGET_SHOTS: u16 = 3;
/// Most shots of each kind the service keeps (more are refused as out of range).
pub const MAX_SHOTS: u16 = 64;
/// Smallest preview picture side the service sends, pixels.
const MIN_PREVIEW_SIDE: usize = 8;
/// The worker's stack: a scan's pipeline keeps its fixed buffers on the stack, as on the
/// command line's main thread (whose stack is 8 MiB).
const WORKER_STACK: usize = 64 << 20;
/// How long a read of the link waits before looking again (a serial port's timeout).
const READ_POLL: Duration = Duration::from_millis(100);
/// Once a host has spoken, silence this long switches every laser the head drives off: the
/// studio says hello every 500 ms, so this is four missed in a row (a closed page, a crashed
/// studio, a pulled or silent cable). The laser stays off until a command switches it on.
pub const LASER_SAFE_AFTER: Duration = Duration::from_secs(2);

/// `serve`'s options.
#[derive(Debug, Clone, clap::Args)]
pub struct ServeArgs {
    /// The source, calibration (optional: the service can make one) and sweep settings, as for
    /// `scan`; `--out` is the two-way link: `serial:PATH[@BAUD]` (a USB gadget's port, a
    /// cable, a pseudo-terminal) or `-` (standard input and output: a pipe, SSH).
    #[command(flatten)]
    pub scan: ScanArgs,
    /// The intrinsics target the shots show.
    #[command(flatten)]
    pub target: TargetArgs,
    /// Board file of the printed board (its shots); the default board without one.
    #[arg(long)]
    pub board_file: Option<PathBuf>,
    /// Folder for the shots, the calibration made from them and the calibration's log.
    #[arg(long, default_value = "head")]
    pub work: PathBuf,
}

/// The link's write end, shared: each `write` puts the whole buffer out under one lock, so
/// the frames of the worker's link and the dispatcher's replies never interleave.
#[derive(Clone)]
struct SharedOut(Arc<Mutex<Box<dyn Write + Send>>>);

impl Write for SharedOut {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut w = self
            .0
            .lock()
            .map_err(|_| std::io::Error::other("the link's lock was poisoned"))?;
        w.write_all(buf)?;
        w.flush()?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl SharedOut {
    /// One message as one frame.
    fn send(&mut self, msg: &Message) -> std::io::Result<()> {
        let mut scratch = [0u8; 512];
        let mut out = [0u8; 600];
        let n = scanner_wire::encode(msg, &mut scratch, &mut out)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        self.write(&out[..n]).map(|_| ())
    }
}

/// What the dispatcher waits for.
enum Event {
    /// A frame from the host.
    Command(Result<CommandFrame, CommandFrameError>),
    /// A worker finished (its job's number, and what it came to).
    Ended(u64, Ended),
    /// The link's input closed (standard input ended) or Ctrl-C: the service ends.
    Quit,
}

/// What a worker's job came to: a line for the log, and what it changes.
struct Ended {
    what: &'static str,
    result: Result<String>,
    change: Change,
}

/// The work that runs.
struct Running {
    id: u64,
    state: HeadState,
    stop: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

/// A job for the worker.
enum Job {
    Preview(PreviewRequest),
    Shot { seq: u32, board: bool },
    Calibrate { seq: u32 },
    Sweep(SweepRequest),
}

/// The service's state between commands.
struct Service {
    args: ServeArgs,
    out: SharedOut,
    events: Sender<Event>,
    running: Option<Running>,
    last: Option<(u32, Reply)>,
    calibration: Option<PathBuf>,
    target_shots: u16,
    board_shots: u16,
    /// The rig's turntable: the view of the scene it stands at.
    view: usize,
    laser: Arc<AtomicBool>,
    /// Views of the rig's scene (its turntable's steps); `None`: no rig.
    rig_views: Option<usize>,
    frame_size: (usize, usize),
    /// Jobs started.
    jobs: u64,
    /// When the host last sent a command; `None` before the first.
    heard: Option<std::time::Instant>,
    /// The lasers were switched off for the host's silence (its length), not yet told.
    silenced: Option<Duration>,
}

/// Runs the service until its input closes or Ctrl-C.
///
/// # Errors
/// A link that cannot open (or is no two-way link), a work folder that cannot be made, a
/// source that cannot open at the start.
pub fn serve(a: &ServeArgs) -> Result<()> {
    let (input, output) = open_two_way(&a.scan.out)?;
    std::fs::create_dir_all(a.work.join("shots"))
        .with_context(|| format!("cannot create the work folder {}", a.work.display()))?;
    let (tx, rx) = channel();
    {
        let tx = tx.clone();
        // Ctrl-C or SIGTERM ends the service (and what runs, with its final message)
        let _ = ctrlc::set_handler(move || {
            let _ = tx.send(Event::Quit);
        });
    }
    spawn_reader(input, tx.clone())?;
    let probe = open_source(
        &a.scan,
        PixelFormat::Gray8,
        &a.scan.camera.options().context("camera options")?,
    )?;
    let frame_size = probe.size();
    let describe = probe.describe();
    drop(probe);
    // a service started again on its work folder goes on where it stopped: its shots and the
    // calibration made from them
    let count = |board: bool| {
        (0..MAX_SHOTS)
            .take_while(|&k| a.work.join("shots").join(shot_name(board, k)).exists())
            .count() as u16
    };
    let made = a.work.join("calibration.toml");
    let calibration = a
        .scan
        .calibration
        .clone()
        .or_else(|| made.exists().then_some(made));
    let mut s = Service {
        rig_views: rig_views(&a.scan)?,
        args: a.clone(),
        out: SharedOut(Arc::new(Mutex::new(output))),
        events: tx,
        running: None,
        last: None,
        calibration,
        target_shots: count(false),
        board_shots: count(true),
        view: a.scan.view.unwrap_or(0),
        laser: Arc::new(AtomicBool::new(true)),
        frame_size,
        jobs: 0,
        heard: None,
        silenced: None,
    };
    crate::errln!("serving {describe} on {}; waiting for commands", a.scan.out);
    s.dispatch(&rx);
    Ok(())
}

/// The link's two ends: a serial port (read with a short timeout) or standard input and
/// output.
fn open_two_way(name: &str) -> Result<(Box<dyn Read + Send>, Box<dyn Write + Send>)> {
    if name.trim() == "-" {
        return Ok((Box::new(std::io::stdin()), Box::new(std::io::stdout())));
    }
    let spec = scanner_io::link_spec::SerialSpec::parse(name)
        .map_err(|e| anyhow::anyhow!("--out {name:?}: {e}"))?;
    let Some(spec) = spec else {
        bail!(
            "--out {name:?}: the service needs a two-way link: serial:PATH[@BAUD] or - (standard input and output), not a file"
        );
    };
    let port = serialport::new(spec.path, spec.baud)
        .timeout(READ_POLL)
        .open_native()
        .with_context(|| {
            format!(
                "cannot open serial port {} at {} baud",
                spec.path, spec.baud
            )
        })?;
    let writer = port
        .try_clone_native()
        .with_context(|| format!("cannot share serial port {}", spec.path))?;
    Ok((Box::new(port), Box::new(writer)))
}

/// Reads the link and hands every command frame to the dispatcher. A read that times out or
/// fails (a cable pulled) is tried again; standard input's end ends the service.
fn spawn_reader(mut input: Box<dyn Read + Send>, tx: Sender<Event>) -> Result<()> {
    std::thread::Builder::new()
        .name("commands".into())
        .spawn(move || {
            let mut d = CommandDecoder::new();
            let mut buf = [0u8; 256];
            loop {
                match input.read(&mut buf) {
                    Ok(0) => {
                        let _ = tx.send(Event::Quit);
                        return;
                    }
                    Ok(n) => {
                        let mut gone = false;
                        d.feed(&buf[..n], |r| gone |= tx.send(Event::Command(r)).is_err());
                        if gone {
                            return;
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(_) => std::thread::sleep(READ_POLL),
                }
            }
        })
        .context("cannot start the command reader")?;
    Ok(())
}

/// The scene's views (the rig's turntable), or `None` without the rig.
fn rig_views(a: &ScanArgs) -> Result<Option<usize>> {
    if !a.source.starts_with("rig") {
        return Ok(None);
    }
    #[cfg(feature = "rig")]
    {
        let scene = super::render::load_scene(a.scene.as_deref())?;
        Ok(Some(scene.view_count()))
    }
    #[cfg(not(feature = "rig"))]
    Ok(None)
}

impl Service {
    fn state(&self) -> HeadState {
        self.running.as_ref().map_or(HeadState::Idle, |r| r.state)
    }

    fn reply(&self, seq: u32, outcome: Outcome, field: u8, detail: i32) -> Reply {
        Reply {
            seq,
            outcome,
            state: self.state(),
            field,
            detail,
        }
    }

    fn dispatch(&mut self, rx: &Receiver<Event>) {
        loop {
            let ev = match rx.recv_timeout(READ_POLL) {
                Ok(ev) => ev,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    self.watch();
                    continue;
                }
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            };
            match ev {
                Event::Command(r) => {
                    self.heard = Some(std::time::Instant::now());
                    if let Some(quiet) = self.silenced.take() {
                        self.tell_silenced(quiet);
                    }
                    self.command(r);
                }
                Event::Ended(id, e) => {
                    // a job replaced before it ended (the preview's new settings) was joined
                    // then
                    if self.running.as_ref().is_some_and(|r| r.id == id)
                        && let Some(r) = self.running.take()
                    {
                        let _ = r.thread.join();
                    }
                    self.settle(e.change);
                    match e.result {
                        Ok(line) => crate::errln!("{}: {line}", e.what),
                        Err(err) => crate::errln!("{} failed: {err:#}", e.what),
                    }
                }
                Event::Quit => break,
            }
            self.watch();
        }
        if let Some(r) = self.running.take() {
            r.stop.store(true, Ordering::SeqCst);
            let _ = r.thread.join();
        }
        crate::errln!("service ended");
    }

    /// Switches the lasers off once the host has been silent for [`LASER_SAFE_AFTER`].
    fn watch(&mut self) {
        let Some(at) = self.heard else { return };
        let quiet = at.elapsed();
        if quiet < LASER_SAFE_AFTER || self.silenced.is_some() {
            return;
        }
        let was_on = self.laser.swap(false, Ordering::SeqCst);
        self.silenced = Some(quiet);
        crate::errln!(
            "no word from the host for {:.1} s: every laser this head drives is off{}",
            quiet.as_secs_f64(),
            if was_on { "" } else { " (it was)" }
        );
    }

    /// Tells the host that came back that the lasers were switched off for its silence.
    fn tell_silenced(&mut self, quiet: Duration) {
        let n = scanner_wire::Notice {
            scan_id: 0,
            kind: scanner_wire::NoticeKind::LaserOffUnheard,
            seconds: u16::try_from(quiet.as_secs()).unwrap_or(u16::MAX),
        };
        if let Err(e) = self.out.send(&Message::Notice(n)) {
            crate::errln!("could not tell the host the laser is off: {e}");
        }
    }

    fn send(&mut self, r: Reply) {
        if let Err(e) = self.out.send(&Message::Reply(r)) {
            crate::errln!("could not answer command {}: {e}", r.seq);
        }
    }

    fn command(&mut self, r: Result<CommandFrame, CommandFrameError>) {
        let frame = match r {
            Ok(f) => f,
            Err(e) => {
                let reply = match e {
                    CommandFrameError::Command(CommandError::Unknown(seq, v)) => self.reply(
                        seq,
                        Outcome::Unknown,
                        0,
                        i32::try_from(v).unwrap_or(i32::MAX),
                    ),
                    CommandFrameError::Command(CommandError::Malformed(seq)) => {
                        self.reply(seq, Outcome::Malformed, 0, 0)
                    }
                    CommandFrameError::Command(CommandError::Unreadable) => {
                        self.reply(0, Outcome::Malformed, 0, 0)
                    }
                    CommandFrameError::Frame(WireError::Oversize) => {
                        self.reply(0, Outcome::Oversized, 0, scanner_wire::MAX_COMMAND as i32)
                    }
                    CommandFrameError::Frame(WireError::UnknownVersion(v)) => {
                        self.reply(0, Outcome::Version, 0, i32::from(v))
                    }
                    // a damaged frame: its number cannot be trusted; the host sends it again
                    CommandFrameError::Frame(_) => return,
                };
                self.send(reply);
                return;
            }
        };
        if let Some((seq, mut reply)) = self.last
            && seq == frame.seq
        {
            reply.state = self.state();
            self.send(reply);
            return;
        }
        let (reply, job) = match frame.command.check() {
            Err((field, limit)) => (
                self.reply(frame.seq, Outcome::OutOfRange, field, limit),
                None,
            ),
            Ok(()) => self.decide(frame),
        };
        let started = job.is_some();
        if let Some(job) = job {
            self.start(job);
        }
        // the state the reply tells is the one the command leaves
        let reply = Reply {
            state: if started { self.state() } else { reply.state },
            ..reply
        };
        self.send(reply);
        self.last = Some((frame.seq, reply));
    }

    /// What to answer, and the job to start.
    fn decide(&mut self, f: CommandFrame) -> (Reply, Option<Job>) {
        let seq = f.seq;
        let ok = |s: &Self| s.reply(seq, Outcome::Accepted, 0, 0);
        let busy = self.running.is_some();
        match f.command {
            Command::Hello => (ok(self), None),
            Command::Stop => match &self.running {
                Some(r) => {
                    r.stop.store(true, Ordering::SeqCst);
                    (ok(self), None)
                }
                None => (self.reply(seq, Outcome::NothingToStop, 0, 0), None),
            },
            Command::Preview(p) if !p.on => match &self.running {
                Some(r) if r.state == HeadState::Previewing => {
                    r.stop.store(true, Ordering::SeqCst);
                    (ok(self), None)
                }
                _ => (self.reply(seq, Outcome::NothingToStop, 0, 0), None),
            },
            // the camera, the laser and the turntable may change while the preview runs
            Command::Camera { .. } => {
                // the rig and image folders have no camera; a camera's controls are set as
                // the scan fixes them (`--exposure` and the like) until this sets them live
                (self.reply(seq, Outcome::NotHere, 0, 0), None)
            }
            Command::Laser { on } => {
                if self.rig_views.is_none() {
                    return (self.reply(seq, Outcome::NotHere, 0, 0), None);
                }
                self.laser.store(on, Ordering::SeqCst);
                (ok(self), None)
            }
            Command::Turn { .. } if self.state() == HeadState::Sweeping => {
                (self.reply(seq, Outcome::Busy, 0, 0), None)
            }
            Command::Turn { steps } => match self.rig_views {
                Some(views) if views > 1 => {
                    let n = views as i64;
                    self.view = (self.view as i64 + i64::from(steps)).rem_euclid(n) as usize;
                    (ok(self), None)
                }
                _ => (self.reply(seq, Outcome::NotHere, 0, 0), None),
            },
            // the preview's new settings (a zoom): the running preview makes way
            Command::Preview(_)
                if self
                    .running
                    .as_ref()
                    .is_some_and(|r| r.state == HeadState::Previewing) =>
            {
                if let Some(r) = self.running.take() {
                    r.stop.store(true, Ordering::SeqCst);
                    let _ = r.thread.join();
                }
                self.decide(f)
            }
            _ if busy => (self.reply(seq, Outcome::Busy, 0, 0), None),
            Command::Preview(p) => {
                let (w, h) = self.frame_size;
                let largest = (w.min(h) / MIN_PREVIEW_SIDE).max(1);
                if usize::from(p.scale) > largest {
                    return (
                        self.reply(seq, Outcome::OutOfRange, 3, largest as i32),
                        None,
                    );
                }
                (ok(self), Some(Job::Preview(p)))
            }
            Command::Shot { board } => {
                let kept = if board {
                    self.board_shots
                } else {
                    self.target_shots
                };
                if kept >= MAX_SHOTS {
                    return (
                        self.reply(seq, Outcome::OutOfRange, 1, i32::from(MAX_SHOTS)),
                        None,
                    );
                }
                (ok(self), Some(Job::Shot { seq, board }))
            }
            Command::Calibrate => {
                if self.target_shots < MIN_TARGET_SHOTS {
                    return (
                        self.reply(seq, Outcome::TooFewShots, 1, i32::from(MIN_TARGET_SHOTS)),
                        None,
                    );
                }
                if self.board_shots == 0 {
                    return (self.reply(seq, Outcome::TooFewShots, 2, 1), None);
                }
                (ok(self), Some(Job::Calibrate { seq }))
            }
            Command::Sweep(s) => {
                if self.calibration.is_none() {
                    return (self.reply(seq, Outcome::NotCalibrated, 0, 0), None);
                }
                (ok(self), Some(Job::Sweep(s)))
            }
        }
    }

    fn start(&mut self, job: Job) {
        let stop = Arc::new(AtomicBool::new(false));
        let state = match job {
            Job::Preview(_) => HeadState::Previewing,
            Job::Sweep(_) => HeadState::Sweeping,
            Job::Shot { .. } | Job::Calibrate { .. } => HeadState::Calibrating,
        };
        let mut scan = self.args.scan.clone();
        scan.calibration = self.calibration.clone();
        if self.rig_views.is_some_and(|v| v > 1) {
            scan.view = Some(self.view);
        }
        let w = Worker {
            scan,
            args: self.args.clone(),
            out: self.out.clone(),
            stop: stop.clone(),
            laser: self.laser.clone(),
        };
        let shots = (self.target_shots, self.board_shots);
        let tx = self.events.clone();
        self.jobs += 1;
        let id = self.jobs;
        let spawned = std::thread::Builder::new()
            .name("worker".into())
            .stack_size(WORKER_STACK)
            .spawn(move || {
                let ended = w.run(job, shots);
                let _ = tx.send(Event::Ended(id, ended));
            });
        match spawned {
            Ok(thread) => {
                self.running = Some(Running {
                    id,
                    state,
                    stop,
                    thread,
                })
            }
            Err(e) => crate::errln!("cannot start the worker: {e}"),
        }
    }

    /// What an ended job changes: a shot kept, a calibration made.
    fn settle(&mut self, change: Change) {
        match change {
            Change::Nothing => {}
            Change::Kept { board: true } => self.board_shots += 1,
            Change::Kept { board: false } => self.target_shots += 1,
            Change::Calibrated(path) => self.calibration = Some(path),
        }
    }
}

/// What a worker's job leaves for the next commands.
enum Change {
    Nothing,
    Kept { board: bool },
    Calibrated(PathBuf),
}

/// A job's thread: the service's settings and its share of the link.
struct Worker {
    scan: ScanArgs,
    args: ServeArgs,
    out: SharedOut,
    stop: Arc<AtomicBool>,
    laser: Arc<AtomicBool>,
}

impl Worker {
    fn run(self, job: Job, shots: (u16, u16)) -> Ended {
        match job {
            Job::Preview(p) => Ended {
                what: "preview",
                result: self.preview(p),
                change: Change::Nothing,
            },
            Job::Sweep(s) => Ended {
                what: "sweep",
                result: self.sweep(s),
                change: Change::Nothing,
            },
            Job::Shot { seq, board } => {
                let kept = if board { shots.1 } else { shots.0 };
                match self.shot(seq, board, kept) {
                    Ok((line, keep)) => Ended {
                        what: "shot",
                        result: Ok(line),
                        change: if keep {
                            Change::Kept { board }
                        } else {
                            Change::Nothing
                        },
                    },
                    Err(e) => Ended {
                        what: "shot",
                        result: Err(e),
                        change: Change::Nothing,
                    },
                }
            }
            Job::Calibrate { seq } => match self.calibrate(seq, shots) {
                Ok((line, path)) => Ended {
                    what: "calibration",
                    result: Ok(line),
                    change: path.map_or(Change::Nothing, Change::Calibrated),
                },
                Err(e) => Ended {
                    what: "calibration",
                    result: Err(e),
                    change: Change::Nothing,
                },
            },
        }
    }

    fn link(&self) -> Link {
        Link::spawn(
            Box::new(self.out.clone()),
            self.scan.link_depth,
            MAX_ENCODED,
        )
    }

    fn sweep(&self, s: SweepRequest) -> Result<String> {
        let mut a = self.scan.clone();
        a.disc = match s.disc {
            1 => Some(scanner_calib::disc::Paper::A4),
            2 => Some(scanner_calib::disc::Paper::A3),
            _ => None,
        };
        a.rows = s.axis == 1;
        a.columns = s.axis == 2;
        a.colour = s.colour;
        a.keep_board = s.keep_board;
        a.frames = (s.frames > 0).then_some(s.frames);
        a.scan_id = None;
        let mut plan = super::scan::plan_on(&a, self.link())?;
        plan.stop.flag = Some(self.stop.clone());
        let report = crate::scan::run(plan, |_| {})?;
        Ok(format!(
            "{} frames, {} points{}",
            report.status.frames,
            report.status.points,
            report
                .ended_early
                .as_ref()
                .map(|e| format!("; {e}"))
                .unwrap_or_default()
        ))
    }

    fn preview(&self, p: PreviewRequest) -> Result<String> {
        let mut a = self.scan.clone();
        a.scan_id = None;
        let mut o = open_on(&a, Some(self.link()))?;
        let options = PreviewOptions {
            scan_id: o.scan_id,
            every: u32::from(p.every),
            head: o.head,
            find_axis: o.find_axis,
            scale: usize::from(p.scale),
            picture: p.picture.then_some(p.zoom),
        };
        o.stop.flag = Some(self.stop.clone());
        let reopen = {
            let a = a.clone();
            move || -> Result<Box<dyn FrameSource>, SourceError> {
                let opts = a
                    .camera
                    .options()
                    .map_err(|e| SourceError::BadSpec(e.to_string()))?;
                let format =
                    source_format(&a, &opts).map_err(|e| SourceError::BadSpec(format!("{e:#}")))?;
                open_source(&a, format, &opts).map_err(|e| SourceError::BadSpec(format!("{e:#}")))
            }
        };
        let mut source = Endless {
            inner: o.source,
            reopen: Box::new(reopen),
            laser: self.laser.clone(),
            reference: None,
            count: 0,
        };
        let cal = o.calibration.as_ref();
        let report = run_preview(&mut source, cal, options, &mut o.link, &o.stop, |_| {})?;
        o.link.finish()?;
        Ok(format!(
            "{} frames, {} pictures",
            report.frames, report.previews
        ))
    }
}

impl Worker {
    /// Takes a calibration shot, checks it, keeps it when usable and tells the host; the log's
    /// line and whether it was kept.
    fn shot(&self, seq: u32, board: bool, kept: u16) -> Result<(String, bool)> {
        let gray = self.shot_image(board, kept)?;
        let (w, h) = gray.dimensions();
        let mut msg = ShotTaken {
            seq,
            board,
            found: 1,
            kept,
            points: 0,
            cover: 0,
            tilt_deg: [0, 0],
        };
        let line = if board {
            // both sheets identified: the planes themselves are fitted with the camera the
            // calibration finds first (a guessed one would fail the fit's plausibility check)
            let b = load_board(self.args.board_file.as_deref())?;
            let outcome = scanner_calib::board_planes(&gray, &b, &guessed_camera(w, h)?);
            let mut seen = 0;
            for (k, a) in outcome.assignments.iter().enumerate() {
                let Some(a) = a else { continue };
                seen += 1;
                let features = outcome.features(&b, k);
                for i in a.blob_of.iter().flatten() {
                    if let Some(f) = features.get(*i) {
                        let p = f.centre;
                        let (c, r) = ShotTaken::cell(p.x, p.y, w, h);
                        msg.cover |= 1u64 << (r * COVER_COLS + c);
                        msg.points += 1;
                    }
                }
            }
            if seen == 2 {
                msg.found = 0;
                format!("board: {} markers on both sheets", msg.points)
            } else {
                msg.found = if seen == 0 { 1 } else { 2 };
                format!("board not usable: {seen} of its 2 sheets identified")
            }
        } else {
            let target = self.args.target.target()?;
            match scanner_calib::find_grid(&gray, &target) {
                Ok(g) => {
                    msg.found = 0;
                    msg.points = g.found.len() as u16;
                    for (_, p) in &g.found {
                        let (c, r) = ShotTaken::cell(p.x, p.y, w, h);
                        msg.cover |= 1u64 << (r * COVER_COLS + c);
                    }
                    msg.tilt_deg = tilt(&target.points(), &g.found, w, h);
                    format!("target: {} points", msg.points)
                }
                Err(e) => {
                    msg.found = 2;
                    format!("target not usable: {e}")
                }
            }
        };
        let keep = msg.found == 0;
        if keep {
            msg.kept = kept + 1;
            let name = shot_name(board, kept);
            let path = self.args.work.join("shots").join(&name);
            gray.save(&path)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        let mut out = self.out.clone();
        out.send(&Message::Shot(msg)).context("the link failed")?;
        Ok((line, keep))
    }

    /// A shot's picture: the rig's (the target at the next of its poses, or the board), or
    /// the source's next frame.
    fn shot_image(&self, board: bool, kept: u16) -> Result<image::GrayImage> {
        #[cfg(feature = "rig")]
        if self.scan.source.starts_with("rig") {
            use scanner_rig::target::{Pattern, TargetPose};
            let mut scene = super::render::view_of(
                super::render::load_scene(self.scan.scene.as_deref())?,
                self.scan.view,
            )?;
            if board {
                // the board's shot is taken before the object and the disc go in front of it
                scene.objects.clear();
                scene.fixed.clear();
                scene.turntable = None;
            }
            let rig = scanner_rig::Rig::new(scene)
                .map_err(|e| anyhow::anyhow!("building the virtual rig: {e}"))?;
            if board {
                return Ok(rig.reference().to_gray_image());
            }
            let scanner_calib::Target::Dots(grid) = self.args.target.target()? else {
                bail!(
                    "the virtual rig's shots show a dot grid: leave out --chessboard-* and --charuco"
                );
            };
            let k = usize::from(kept);
            let pose = TargetPose::sweep(k % RIG_POSES, RIG_POSES);
            return Ok(rig
                .shot(&Pattern::from(&grid), &pose, k as u64)
                .image
                .to_gray_image());
        }
        let opts = self.scan.camera.options()?;
        let mut source = crate::source::open_with(&self.scan.source, PixelFormat::Rgb24, &opts)
            .with_context(|| format!("source {}", self.scan.source))?;
        // a source that numbers its frames: the next picture for each shot
        for _ in 0..(if self.scan.source.starts_with("/dev/") {
            0
        } else {
            kept
        }) {
            source.next_frame()?;
        }
        let Some(frame) = source.next_frame()? else {
            bail!("the source {} has no more pictures", self.scan.source);
        };
        let rgb = super::capture::to_image(&frame)?;
        Ok(image::DynamicImage::ImageRgb8(rgb).to_luma8())
    }

    /// Calibrates from the kept shots in this process (the camera, then the board's planes;
    /// their lines into `calibrate.log`), then tells the host; the log's line and the new
    /// calibration file when it passed.
    fn calibrate(&self, seq: u32, shots: (u16, u16)) -> Result<(String, Option<PathBuf>)> {
        use crate::calibrate::{BoardPlan, IntrinsicsPlan, Said};
        let work = &self.args.work;
        let log_path = work.join("calibrate.log");
        let mut log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .with_context(|| format!("cannot write {}", log_path.display()))?;
        let mut say = |said: Said| {
            let line = match said {
                Said::Line(l) => l,
                Said::Warning(w) => format!("warning: {w}"),
            };
            // the log is for reading later: a line that cannot be written is not worth a refusal
            let _ = writeln!(log, "{line}");
        };
        let camera = work.join("camera.toml");
        let calibration = work.join("calibration.toml");
        let mut msg = Calibrated {
            seq,
            result: 1,
            shots: 0,
            rms_px: f32::NAN,
            halves_px: f32::NAN,
            board_rms_px: f32::NAN,
            board_angle_deg: f32::NAN,
        };
        let intrinsics = IntrinsicsPlan {
            target: self.args.target.target()?,
            images: (0..shots.0)
                .map(|k| work.join("shots").join(shot_name(false, k)))
                .collect(),
            out: camera.clone(),
            overlays: None,
        };
        let mut done = None;
        match crate::calibrate::intrinsics(&intrinsics, &mut say) {
            Ok(r) => {
                msg.shots = u16::try_from(r.used).unwrap_or(u16::MAX);
                msg.rms_px = r.rms_px.map_or(f32::NAN, |v| v as f32);
                msg.halves_px = r
                    .self_check
                    .as_ref()
                    .and_then(|c| c.halves.as_ref())
                    .map_or(f32::NAN, |h| h.image_rms_px as f32);
                msg.result = 2;
                let board = BoardPlan {
                    board: self.args.board_file.clone(),
                    camera,
                    image: work.join("shots").join(shot_name(true, shots.1 - 1)),
                    out: calibration.clone(),
                    overlay: work.join("calibration-overlay.png"),
                    method: scanner_calib::BoardMethod::LayoutPose,
                };
                match crate::calibrate::board(&board, &mut say) {
                    Ok(b) => {
                        msg.board_rms_px =
                            b.sheets.iter().map(|s| s.rms_px).fold(f64::NAN, f64::max) as f32;
                        msg.board_angle_deg = b.angle_deg.map_or(f32::NAN, |a| a as f32);
                        msg.result = 0;
                        done = Some(calibration);
                    }
                    Err(e) => say(Said::Line(format!("error: {}", crate::error_chain(&e)))),
                }
            }
            Err(e) => say(Said::Line(format!("error: {}", crate::error_chain(&e)))),
        }
        let mut out = self.out.clone();
        out.send(&Message::Calibrated(msg))
            .context("the link failed")?;
        Ok((
            format!(
                "result {} from {} shots, rms {:.3} px (lines in {})",
                msg.result,
                msg.shots,
                msg.rms_px,
                log_path.display()
            ),
            done,
        ))
    }
}

/// Poses the rig's virtual operator holds the target at, in turn.
#[cfg(feature = "rig")]
const RIG_POSES: usize = 12;

/// A shot's file name in the work folder's `shots/`.
fn shot_name(board: bool, k: u16) -> String {
    if board {
        format!("board-{k:02}.png")
    } else {
        format!("grid-{k:02}.png")
    }
}

/// A camera for checking a board shot before any calibration: a focal length of the picture's
/// larger side, the principal point at its centre, no distortion. Good enough to find the
/// sheets; the planes themselves come from the calibration.
fn guessed_camera(w: u32, h: u32) -> Result<scanner_core::Camera<f64>> {
    let f = f64::from(w.max(h));
    scanner_core::Camera::new(
        f,
        f,
        f64::from(w) / 2.0,
        f64::from(h) / 2.0,
        scanner_core::camera::Distortion::none(),
    )
    .map_err(|e| anyhow::anyhow!("a {w}×{h} picture: {e}"))
}

/// The target's tilt about the picture's horizontal and vertical axes, degrees, from the
/// homography of its found points with the [`guessed_camera`].
fn tilt(layout: &[Point2<f64>], found: &[(usize, Point2<f64>)], w: u32, h: u32) -> [i8; 2] {
    let f = f64::from(w.max(h));
    let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
    let (sheet, image): (Vec<Point2<f64>>, Vec<Vector2<f64>>) = found
        .iter()
        .filter_map(|(i, p)| {
            Some((
                *layout.get(*i)?,
                Vector2::new((p.x - cx) / f, (p.y - cy) / f),
            ))
        })
        .unzip();
    let Ok(hm) = scanner_core::geometry::pose::homography(&sheet, &image) else {
        return [0, 0];
    };
    let r1 = Vector3::new(hm[(0, 0)], hm[(1, 0)], hm[(2, 0)]).normalize();
    let r2 = Vector3::new(hm[(0, 1)], hm[(1, 1)], hm[(2, 1)]).normalize();
    let mut n = r1.cross(&r2);
    if n.z > 0.0 {
        n = -n;
    }
    let deg = |v: f64| v.asin().to_degrees().round().clamp(-90.0, 90.0) as i8;
    [deg(-n.y), deg(-n.x)]
}

/// The source forever: a source that ends (the rig, a folder) starts again; with the laser
/// switched off (the rig), each frame is the laser-off picture.
struct Endless {
    inner: Box<dyn FrameSource>,
    reopen: Box<dyn FnMut() -> Result<Box<dyn FrameSource>, SourceError> + Send>,
    laser: Arc<AtomicBool>,
    reference: Option<OwnedFrame>,
    count: u64,
}

impl FrameSource for Endless {
    fn describe(&self) -> String {
        self.inner.describe()
    }

    fn format(&self) -> PixelFormat {
        self.inner.format()
    }

    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }

    fn controls(&self) -> scanner_wire::Controls {
        self.inner.controls()
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let r = self.inner.reference()?;
        self.reference = Some(r.clone());
        Ok(r)
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        self.count += 1;
        if !self.laser.load(Ordering::SeqCst)
            && let Some(r) = &self.reference
        {
            return Ok(Some(OwnedFrame {
                index: self.count,
                ..r.clone()
            }));
        }
        if let Some(f) = self.inner.next_frame()? {
            return Ok(Some(f));
        }
        self.inner = (self.reopen)()?;
        self.inner.next_frame()
    }

    fn pace(&self) -> Option<crate::source::CameraPace> {
        self.inner.pace()
    }

    fn give_back(&mut self, frame: OwnedFrame) {
        self.inner.give_back(frame);
    }
}
