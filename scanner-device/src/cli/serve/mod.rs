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

mod service;
mod shots;
mod worker;

use shots::shot_name;
use worker::Change;

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use scanner_core::stripe::PixelFormat;
use scanner_wire::{
    CommandDecoder, CommandFrame, CommandFrameError, HeadState, Message, PreviewRequest, Reply,
    SweepRequest,
};

use super::calibrate::TargetArgs;
use super::scan::{ScanArgs, open_source};

/// Target shots a calibration needs at least (the intrinsics' own minimum).
pub const MIN_TARGET_SHOTS: u16 = 3;
/// Most shots of each kind the service keeps (more are refused as out of range).
pub const MAX_SHOTS: u16 = 64;
/// Smallest preview picture side the service sends, pixels.
pub(super) const MIN_PREVIEW_SIDE: usize = 8;
/// The worker's stack: a scan's pipeline keeps its fixed buffers on the stack, as on the
/// command line's main thread (whose stack is 8 MiB).
pub(super) const WORKER_STACK: usize = 64 << 20;
/// How long a read of the link waits before looking again (a serial port's timeout).
pub(super) const READ_POLL: Duration = Duration::from_millis(100);
/// How long a command the running work would refuse waits for that work to end: the host may
/// hear a sweep's last packet and ask for the next before the worker has returned.
pub(super) const ENDING_GRACE: Duration = Duration::from_millis(500);
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
pub(super) struct SharedOut(pub(super) Arc<Mutex<Box<dyn Write + Send>>>);

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
pub(super) enum Event {
    /// A frame from the host.
    Command(Result<CommandFrame, CommandFrameError>),
    /// A worker finished (its job's number): what it came to is its thread's result.
    Ended(u64),
    /// The link's input closed (standard input ended) or Ctrl-C: the service ends.
    Quit,
}

/// What a worker's job came to: a line for the log, and what it changes.
pub(super) struct Ended {
    pub(super) what: &'static str,
    pub(super) result: Result<String>,
    pub(super) change: Change,
}

/// The work that runs.
pub(super) struct Running {
    pub(super) id: u64,
    pub(super) state: HeadState,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) thread: JoinHandle<Ended>,
}

/// A job for the worker.
pub(super) enum Work {
    Preview(PreviewRequest),
    Shot { seq: u32, board: bool },
    Calibrate { seq: u32 },
    Sweep(SweepRequest),
}

/// The service's state between commands.
pub(super) struct Service {
    pub(super) args: ServeArgs,
    pub(super) out: SharedOut,
    pub(super) events: Sender<Event>,
    pub(super) running: Option<Running>,
    pub(super) last: Option<(u32, Reply)>,
    pub(super) calibration: Option<PathBuf>,
    pub(super) target_shots: u16,
    pub(super) board_shots: u16,
    /// The rig's turntable: the view of the scene it stands at.
    pub(super) view: usize,
    pub(super) laser: Arc<AtomicBool>,
    /// Views of the rig's scene (its turntable's steps); `None`: no rig.
    pub(super) rig_views: Option<usize>,
    /// The rotation of the rig's objects in each of its views, degrees about an axis (the
    /// turntable's steps' angles are the differences).
    pub(super) rig_turns: Vec<scanner_core::nalgebra::UnitQuaternion<f64>>,
    pub(super) frame_size: (usize, usize),
    /// Jobs started.
    pub(super) jobs: u64,
    /// When the host last sent a command; `None` before the first.
    pub(super) heard: Option<std::time::Instant>,
    /// The lasers were switched off for the host's silence (its length), not yet told.
    pub(super) silenced: Option<Duration>,
    /// The running preview's settings.
    pub(super) previewing: Option<PreviewRequest>,
    /// The preview a shot interrupted, started again when the shot ends.
    pub(super) resume: Option<PreviewRequest>,
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
        rig_turns: rig_turns(&a.scan)?,
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
        previewing: None,
        resume: None,
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

/// The rotation of the rig scene's objects in each of its views (none without the rig).
fn rig_turns(a: &ScanArgs) -> Result<Vec<scanner_core::nalgebra::UnitQuaternion<f64>>> {
    if !a.source.starts_with("rig") {
        return Ok(Vec::new());
    }
    #[cfg(feature = "rig")]
    {
        let scene = super::render::load_scene(a.scene.as_deref())?;
        Ok(scene.views.iter().map(|v| v.rotation).collect())
    }
    #[cfg(not(feature = "rig"))]
    Ok(Vec::new())
}
