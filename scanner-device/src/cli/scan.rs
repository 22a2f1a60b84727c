//! `scanner-device scan` and `scanner-device devices`: arguments, then a validated plan (the
//! source opened, the calibration read and checked against it, the link opened), then the run.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use scanner_calib::file::CalibrationFile;
use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, LaserColour, Method, PixelFormat, StripeConfig};
use scanner_wire::PlaneMethod;
use scanner_wire::Skip;

use crate::link::{Destination, Link};
use crate::session::{Calibration, DiscOutcome, ScanOptions, ScanReport, StopWhen, run_scan_until};
use crate::source::convert::CameraFormat;
use crate::source::{FrameSource, SourceOptions, open_with};

use super::values;

/// `--firmware` of `scan`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FirmwareArg {
    /// FabScanPi's (its HAT, or an Arduino with its firmware).
    Fabscan,
    /// Ciclop's horus-fw.
    Horus,
}

/// Options of `scan`.
#[derive(Debug, Clone, Args)]
pub struct ScanArgs {
    /// Frame source: `rig`, `rig:WIDTHxHEIGHT`, `dir:FOLDER` (or a folder), `/dev/videoN`, or
    /// `record:FOLDER` (a recording made with `--record`, reprocessed).
    #[arg(long, default_value = "rig")]
    pub source: String,
    /// With the virtual rig: this scene file instead of the demo scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// With the virtual rig: this view of a scene with `[[views]]` (a 360° scan), from 0.
    #[arg(long)]
    pub view: Option<usize>,
    /// Pixel format the pipeline reads. [default: the source's own: a camera's as it sends
    /// them (YUYV, GREY; MJPEG and RGB3 decoded to RGB), an image folder's as its first image
    /// (RGB for colour, gray for gray); the virtual rig renders gray]
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// How a camera is opened.
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Reference (laser-off) frame from this image.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Otherwise average this many first frames, laser off.
    #[arg(long, default_value_t = crate::source::REFERENCE_FRAMES)]
    pub reference_frames: usize,
    /// Calibration file (`calibrate board`; the virtual rig's truth is
    /// `render-calibration`'s `truth-calibration.toml`).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Where the stream goes: `serial:/dev/ttyUSB0@921600`, `file:PATH` (or a path), `-`.
    #[arg(long, default_value = "scan.stream")]
    pub out: String,
    /// How the laser plane is found.
    #[arg(long, value_enum, default_value_t = PlaneArg::Lsq)]
    pub method: PlaneArg,
    /// The light-intensity method (no reference needed for the stripe) instead of the
    /// difference image.
    #[arg(long)]
    pub lim: bool,
    /// The laser's colour: the stripe is found by the light it adds in that colour (difference
    /// image) or by how much more of that colour a pixel shows (light intensity); `white` goes
    /// by brightness alone. Gray frames show no colour: there it is ignored. [default: red]
    #[arg(long, value_enum)]
    pub laser: Option<LaserArg>,
    /// The stripe runs vertically (the laser sweeps sideways): scan rows. [default: the way
    /// the first laser frame shows the stripe running]
    #[arg(long, conflicts_with = "columns")]
    pub rows: bool,
    /// The stripe runs horizontally (the laser sweeps up and down): scan columns.
    #[arg(long)]
    pub columns: bool,
    /// The object stands on the printed turntable disc (`scanner-device board --turntable
    /// PAPER`, `a4` or `a3`): find it in the reference frame and send its pose, so that the
    /// host's 360° merge knows how far the object was turned.
    #[arg(long, value_name = "PAPER")]
    pub disc: Option<scanner_calib::disc::Paper>,
    /// A turntable scanner: laser N of the calibration's `[[laser]]` planes, fixed, over its
    /// `[platform]` (`scanner-device import-fabscan` writes such a file). The frames are dark
    /// and laser-only: no reference is taken. Give the platform's turn per frame with
    /// `--turn-deg`, `--steps-per-frame` or `--frames-per-turn`.
    #[arg(long, value_name = "N")]
    pub fixed_laser: Option<usize>,
    /// With --fixed-laser: the platform turns this many degrees between frames (positive:
    /// counter-clockwise seen from above, negative: clockwise).
    #[arg(long, allow_hyphen_values = true, conflicts_with_all = ["steps_per_frame", "frames_per_turn"])]
    pub turn_deg: Option<f64>,
    /// With --fixed-laser: the motor makes this many steps between frames (of the platform's
    /// `steps_per_turn`, in its `clockwise` direction).
    #[arg(long, conflicts_with = "frames_per_turn")]
    pub steps_per_frame: Option<u32>,
    /// With --fixed-laser: frames in one whole turn (FabScanPi's resolution 1 is 100), in the
    /// platform's `clockwise` direction.
    #[arg(long)]
    pub frames_per_turn: Option<u32>,
    /// With --fixed-laser: the turntable's motor board, `serial:PATH[@BAUD]`:
    /// the platform is turned `--steps-per-frame` before every frame after the first, and the
    /// laser switched on for the scan, by its firmware (`--firmware`).
    #[arg(long, value_name = "SERIAL", requires = "steps_per_frame")]
    pub motor: Option<String>,
    /// The motor board's firmware.
    #[arg(long, value_enum, default_value_t = FirmwareArg::Fabscan)]
    pub firmware: FirmwareArg,
    /// How long the motor board may take to acknowledge a command (a whole turn step for
    /// FabScanPi's), milliseconds.
    #[arg(long, default_value_t = 5000, value_parser = clap::value_parser!(u64).range(1..=600_000))]
    pub motor_timeout_ms: u64,
    /// A shadow sweep: no laser; a straight rod held in front of a small lamp casts a shadow
    /// swept over the object and both sheets of the board; each edge of the shadow's band is a
    /// plane of light (docs/shadow-scanner.md). Frames that can be read twice (a folder, a
    /// recording, the rig) are: each pixel's brightest over the sweep is its value lit without
    /// the shadow and its darkest its value in the shadow's core (Bouguet and Perona's maximum
    /// and minimum). From a camera, or with `--reference FILE`, the reference (the first frames,
    /// before the rod enters) is the lit scene and the shadow's core is taken for black.
    #[arg(long, conflicts_with_all = ["fixed_laser", "lim", "laser", "colour"])]
    pub shadow: bool,

    /// Send the stripe's board points too.
    #[arg(long)]
    pub keep_board: bool,
    /// Drop the points nearer than this many profile widths (in lines) to the end of their run
    /// of continuous points or to the board's crease: where an object's outline or its shadow
    /// ends a run, it cuts the profiles of the lines within about a width of it, and the crease
    /// bends the stripe, pulling those centres off the surface. 1 for an accuracy check
    /// (`scanner-host check`): on the rig's two-sphere bar it takes the size errors from
    /// 0.05 % to under 0.01 %. It costs points at every run's end, the more the wider the line
    /// (docs/accuracy.md). 0: off.
    #[arg(long, default_value_t = 0.0, value_parser = values::edge_reach)]
    pub edge_reach: f32,
    /// Drop the stripe's lines where it crosses the edge of print: the laser-off reference's
    /// level changes by more than this factor within two pixels under the profile, which is
    /// then the light times the print, its centre pulled towards the bright side (up to 2 mm on
    /// the rig's board dots). 1.5 for an accuracy check, or to fit the laser plane on a printed
    /// board without its marks (on the real two-plane frames: 0.072° from the independent
    /// reference instead of 0.083°). It drops the stripe wherever an object is printed or
    /// textured (docs/accuracy.md). 0: off. Difference method only.
    #[arg(long, default_value_t = 0.0, value_parser = values::print_ratio)]
    pub print_ratio: f32,
    /// Colour each point from the reference frame.
    #[arg(long)]
    pub colour: bool,
    /// Buffers between the camera and the link (frames dropped beyond), 1 to 64.
    #[arg(long, default_value_t = 8, value_parser = values::parse_link_depth)]
    pub link_depth: usize,
    /// Keep the raw frames (and the reference) in this folder, so that the scan can be
    /// reprocessed later with `--source record:FOLDER` and another calibration.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// After the reference, wait up to this many seconds for the laser before counting frames
    /// (default: 60 for a camera, none for files and the rig; 0 turns it off).
    #[arg(long, value_parser = values::parse_wait)]
    pub wait_for_laser: Option<std::time::Duration>,
    /// Stop after this many frames (after the reference), with a final status.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Stop after this many seconds of scanning, with a final status.
    #[arg(long, value_parser = values::parse_seconds)]
    pub duration: Option<std::time::Duration>,
    /// Scan id (random without).
    #[arg(long)]
    pub scan_id: Option<u32>,
    /// Also write the end-of-scan summary as JSON to this file (fields: docs/reports.md).
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
}

/// How a camera is opened, for `scan` and `capture` alike (so that calibration shots are taken
/// as the scan takes its frames).
#[derive(Debug, Clone, clap::Args)]
pub struct CameraArgs {
    /// Camera resolution, WIDTHxHEIGHT.
    #[arg(long)]
    pub size: Option<String>,
    /// Camera frame rate.
    #[arg(long)]
    pub fps: Option<u32>,
    /// The local mains frequency (50 or 60 Hz), for the camera's power-line filter.
    #[arg(long, value_parser = values::parse_mains)]
    pub mains: Option<u32>,
    /// Camera pixel format FourCC (YUYV, GREY, RGB3, MJPG). What keeps up with a 30 frames/s
    /// camera (estimated, docs/speed.md): on a Raspberry Pi 4, YUYV at any size and MJPG up to
    /// 1280x720 (1600x1200 MJPG: about 21 frames/s); on a Pi 5, MJPG up to 1600x1200 (about
    /// 50). Frames the head cannot keep up with are dropped and counted.
    #[arg(long)]
    pub fourcc: Option<String>,
}

impl CameraArgs {
    /// The source options these give (size parsed and checked).
    ///
    /// # Errors
    /// A `--size` that is not WIDTHxHEIGHT.
    pub fn options(&self) -> Result<SourceOptions> {
        Ok(SourceOptions {
            size: self
                .size
                .as_deref()
                .map(|s| crate::source::parse_size(s).with_context(|| format!("--size {s:?}")))
                .transpose()?,
            fps: self.fps,
            fourcc: self.fourcc.clone(),
            mains_hz: self.mains,
            ..SourceOptions::default()
        })
    }
}

/// `--format`: what the pipeline reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    /// 8-bit gray.
    Gray,
    /// YUYV 4:2:2, read in place.
    Yuyv,
    /// 24-bit RGB.
    Rgb,
}

impl From<FormatArg> for PixelFormat {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Gray => PixelFormat::Gray8,
            FormatArg::Yuyv => PixelFormat::Yuyv,
            FormatArg::Rgb => PixelFormat::Rgb24,
        }
    }
}

/// `--method`: how the laser plane is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PlaneArg {
    /// Least squares over all the stripe's board points (default).
    Lsq,
    /// The paper's construction: the lines MN and QR, their crossings S and T.
    Paper,
}

/// `--laser`: the laser's colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LaserArg {
    /// A red laser (635–660 nm), the common line laser.
    Red,
    /// A green laser (520–532 nm).
    Green,
    /// A blue or violet laser (405–450 nm).
    Blue,
    /// By brightness alone.
    White,
}

impl From<LaserArg> for LaserColour {
    fn from(l: LaserArg) -> Self {
        match l {
            LaserArg::Red => LaserColour::Red,
            LaserArg::Green => LaserColour::Green,
            LaserArg::Blue => LaserColour::Blue,
            LaserArg::White => LaserColour::White,
        }
    }
}

/// A scan, validated and with its resources open: what [`run`] runs.
pub struct ScanPlan {
    source: Box<dyn FrameSource>,
    calibration: Calibration,
    options: ScanOptions,
    link: Link,
    pub(super) stop: StopWhen,
    pub(super) quiet: bool,
}

/// Link speeds for the README's table, bytes per second.
pub const LINKS: [(&str, f64); 3] = [
    ("115200 baud UART", 11_520.0),
    ("921600 baud UART", 92_160.0),
    ("USB CDC", 1_000_000.0),
];

/// Counts a noun: `1 frame`, `2 frames`.
fn count(n: impl Into<u64>, noun: &str) -> String {
    let n = n.into();
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}

/// The end-of-scan summary, one line per item.
pub fn report_lines(r: &ScanReport) -> Vec<String> {
    let s = &r.status;
    let mut lines = vec![format!(
        "scan {:08x}: {}, {}, {}, {} bytes in {:.2} s ({:.1} frames/s){}",
        s.scan_id,
        count(s.frames, "frame"),
        count(s.packets, "point packet"),
        count(s.points, "point"),
        r.bytes,
        r.seconds,
        f64::from(s.frames) / r.seconds.max(1e-9),
        match (&r.ended_early, &r.stopped) {
            (Some(e), _) => format!("; ended early: {e}"),
            (None, Some(why)) => format!("; {why}"),
            (None, None) => String::new(),
        }
    )];
    match r.bytes_per_point() {
        Some(bpp) => {
            lines.push(format!(
                "{bpp:.2} bytes per point on the link (framing and headers included)"
            ));
            for (name, bps) in LINKS {
                lines.push(format!("  {name}: {:.0} points/s", bps / bpp));
            }
        }
        None => lines.push(
            "no points were sent: check the laser, the reference frame and the calibration (the skip reasons below)".into(),
        ),
    }
    for reason in Skip::ALL {
        let n = s.skipped[reason as usize];
        if n > 0 {
            lines.push(format!(
                "  skipped {}: {}",
                count(n, "frame"),
                scanner_io::words::skip_reason(reason)
            ));
        }
    }
    match &r.disc {
        Some(DiscOutcome::Found {
            pose,
            markers,
            of,
            rms_px,
        }) => lines.push(format!(
            "turntable disc: found, {markers} of {of} dots, rms {rms_px:.3} px, centre {:.1} mm from the camera",
            pose.translation.norm()
        )),
        Some(DiscOutcome::Missed(why)) => lines.push(format!(
            "turntable disc: not found: {why} (the merge registers this view by its shape)"
        )),
        None => {}
    }
    if let Some(pace) = &r.pace {
        lines.push(format!(
            "camera: {}",
            crate::session::pace_line(pace, r.pipeline_ms)
        ));
    }
    if let Some(seen) = r.axis_seen.filter(|&a| a != r.axis) {
        lines.push(format!(
            "the first laser frame's stripe is a {} line but the scan read a {} one: give {}",
            axis_words(seen).1,
            axis_words(r.axis).1,
            axis_words(seen).0
        ));
    } else if r.one_sheet_only() {
        lines.push(one_plane_hint(r));
    }
    lines
}

/// An axis's flag and the line it reads.
fn axis_words(a: Axis) -> (&'static str, &'static str) {
    match a {
        Axis::Columns => ("--columns", "horizontal"),
        Axis::Rows => ("--rows", "vertical"),
    }
}

/// What to do when most frames saw the stripe on one board sheet only.
fn one_plane_hint(r: &ScanReport) -> String {
    let (flag, line) = axis_words(r.axis);
    format!(
        "most frames showed the stripe on one sheet only: the laser line must cross the crease onto both sheets (the scan read a {line} line, {flag}, {})",
        if r.axis_found {
            "found from the first laser frame"
        } else {
            "as given"
        }
    )
}

/// Prints the end-of-scan summary: on standard output, or on standard error when standard
/// output carries the scan itself (`--out -`). A closed stream is not an error.
pub fn print_report(r: &ScanReport, to_stderr: bool) {
    use std::io::Write as _;
    for line in report_lines(r) {
        let _ = if to_stderr {
            writeln!(std::io::stderr().lock(), "{line}")
        } else {
            writeln!(std::io::stdout().lock(), "{line}")
        };
    }
}

/// Runs `scan`: [`plan`], then [`run`].
///
/// # Errors
/// Every failure, named.
pub fn scan(a: &ScanArgs) -> Result<ScanReport> {
    run(plan(a)?)
}

/// Checks the arguments and opens what the scan needs: the frame source, the calibration (read
/// and checked against the source's size), the link.
///
/// # Errors
/// A bad option, an unreadable or unsuitable calibration, a source or link that cannot open.
pub fn plan(a: &ScanArgs) -> Result<ScanPlan> {
    plan_with(a, None)
}

/// [`plan`] onto a link already open (the service's).
///
/// # Errors
/// As [`plan`].
pub(super) fn plan_on(a: &ScanArgs, link: Link) -> Result<ScanPlan> {
    plan_with(a, Some(link))
}

fn plan_with(a: &ScanArgs, link: Option<Link>) -> Result<ScanPlan> {
    if a.calibration.is_none() {
        if let Some(f) = &a.camera.fourcc {
            CameraFormat::parse(f)?;
        }
        bail!(
            "no calibration: give --calibration FILE (from `scanner-device calibrate board`; for the virtual rig, `render-calibration` writes truth-calibration.toml)"
        );
    }
    let o = open_on(a, link)?;
    let Some(calibration) = o.calibration else {
        unreachable!("a calibration was given and read");
    };
    let options = ScanOptions {
        head: o.head,
        find_axis: o.find_axis,
        fixed: o.fixed,
        shadow: a.shadow,
        disc: a.disc.map(scanner_calib::disc::Disc::new),
        header_every: 30,
        status_every: 30,
        scan_id: o.scan_id,
    };
    Ok(ScanPlan {
        stop: o.stop,
        source: o.source,
        calibration,
        options,
        link: o.link,
        quiet: a.quiet,
    })
}

/// What `scan` and `preview` open alike: the source, the calibration when given, the
/// pipeline's settings, the link and when to stop.
pub(super) struct OpenedSource {
    /// The frame source.
    pub source: Box<dyn FrameSource>,
    /// The calibration, checked against the source's size, when given.
    pub calibration: Option<Calibration>,
    /// The pipeline.
    pub head: HeadConfig,
    /// Whether the stripe's direction is to be found.
    pub find_axis: bool,
    /// The session id.
    pub scan_id: u32,
    /// The link.
    pub link: Link,
    /// When to stop.
    pub stop: StopWhen,
    /// A fixed laser's platform and turn, for its message after each header.
    pub fixed: Option<scanner_wire::FixedLaser>,
}

/// Checks the options and opens the source, the calibration (if given), the link.
///
/// # Errors
/// As [`plan`].
pub(super) fn open(a: &ScanArgs) -> Result<OpenedSource> {
    open_on(a, None)
}

/// [`open`] onto a link already open (the service's), or the one `--out` names.
///
/// # Errors
/// As [`plan`].
pub(super) fn open_on(a: &ScanArgs, link: Option<Link>) -> Result<OpenedSource> {
    if let Some(f) = &a.camera.fourcc {
        CameraFormat::parse(f)?;
    }
    let opts = SourceOptions {
        reference: a.reference.clone(),
        reference_frames: a.reference_frames,
        ..a.camera.options()?
    };
    let format = source_format(a, &opts)?;
    if a.laser.is_some() && format == PixelFormat::Gray8 {
        crate::errln!(
            "note: --laser {} has no effect on gray frames: a gray camera sees no colour",
            a.laser.map_or(LaserColour::Red, LaserColour::from).name()
        );
    }
    let mut source = open_source(a, format, &opts)?;
    // a shadow sweep that can be read twice: its brightest and darkest
    let extremes = a.shadow && a.reference.is_none() && source.frames_left().is_some();
    if extremes {
        source = sweep_extremes(a, format, &opts, source)?;
    }
    if let Some(spec) = &a.motor {
        source = turning(a, spec, source)?;
    }
    if let Some(dir) = &a.record {
        source = Box::new(
            crate::source::record::Recorder::new(source, dir)
                .with_context(|| format!("--record {}", dir.display()))?,
        );
    }
    let fixed = a
        .calibration
        .as_ref()
        .zip(a.fixed_laser)
        .map(|(p, n)| read_fixed(p, n, a))
        .transpose()?;
    let calibration = a
        .calibration
        .as_ref()
        .map(|p| read_calibration(p, source.as_ref(), &a.source, fixed.as_ref()))
        .transpose()?;
    let link = match link {
        Some(l) => l,
        None => {
            let target: Destination = a.out.parse().context("--out")?;
            Link::spawn(target.open()?, a.link_depth, scanner_wire::MAX_ENCODED)
        }
    };
    let live = a.source.starts_with("/dev/") || a.source.starts_with("v4l:");
    let stop = StopWhen {
        frames: a.frames,
        duration: a.duration,
        flag: stop_flag(),
        wait_for_laser: match a.wait_for_laser {
            Some(d) if d.is_zero() => None,
            Some(d) => Some(d),
            None if live => Some(std::time::Duration::from_secs(60)),
            None => None,
        },
    };
    let mut head = head_config(a);
    if extremes {
        // the contrast is the share of the lamp's light hidden: half of it is the edge
        head.stripe.edge_level = 127.5;
    }
    if let Some(f) = &fixed {
        head = fixed_head(head, f);
        // frames beyond one turn and its closing frame would lay the object over itself
        let per_turn = std::f64::consts::TAU / f64::from(f.message.turn).abs();
        if let Some(n) = source.frames_left()
            && n as f64 > per_turn.round() + 1.0
        {
            bail!(
                "{} holds {n} frames, but the platform turns {:.4}° a frame: {:.0} frames make a turn (and one more to close it); give the turn that was recorded (--frames-per-turn {n} if these frames make one turn)",
                a.source,
                f64::from(f.message.turn).to_degrees(),
                per_turn
            );
        }
    }
    Ok(OpenedSource {
        fixed: fixed.map(|f| f.message),
        source,
        calibration,
        head,
        find_axis: !(a.rows || a.columns),
        scan_id: a.scan_id.unwrap_or_else(rand::random),
        link,
        stop,
    })
}

/// The pixel format the pipeline reads: `--format`, else the source's own.
///
/// # Errors
/// The source cannot be opened to see its format.
pub(super) fn source_format(a: &ScanArgs, opts: &SourceOptions) -> Result<PixelFormat> {
    Ok(match a.format {
        Some(f) => PixelFormat::from(f),
        None if a.scene.is_some() || a.source.starts_with("rig") => PixelFormat::Gray8,
        // a fixed laser's dark frames: the laser's colour is wanted, and YUYV keeps it at half
        // RGB's bytes (a folder of JPEGs then decodes straight into it)
        None if a.fixed_laser.is_some() => PixelFormat::Yuyv,
        None => crate::source::native_format(&a.source, opts)
            .with_context(|| format!("opening the frame source {:?}", a.source))?,
    })
}

/// The source's frames on a platform the motor board at `spec` turns.
fn turning(a: &ScanArgs, spec: &str, source: Box<dyn FrameSource>) -> Result<Box<dyn FrameSource>> {
    let (Some(laser), Some(steps), Some(cal)) = (a.fixed_laser, a.steps_per_frame, &a.calibration)
    else {
        bail!(
            "--motor turns a fixed-laser scan's platform: give --fixed-laser, --steps-per-frame and --calibration"
        );
    };
    let file = CalibrationFile::load(cal)?;
    let Some(platform) = file.platform else {
        bail!(
            "--motor: {} has no [platform] (its steps per turn)",
            cal.display()
        );
    };
    let serial = scanner_io::link_spec::SerialSpec::parse(spec)
        .map_err(|e| anyhow::anyhow!("--motor {spec:?}: {e}"))?
        .ok_or_else(|| anyhow::anyhow!("--motor {spec:?}: give serial:PATH[@BAUD]"))?;
    let port = serialport::new(serial.path, serial.baud)
        .timeout(std::time::Duration::from_millis(20))
        .open()
        .with_context(|| format!("--motor: opening {}", serial.path))?;
    let firmware = match a.firmware {
        FirmwareArg::Fabscan => crate::motor::Firmware::FabScan,
        FirmwareArg::Horus => crate::motor::Firmware::Horus,
    };
    let controller = crate::motor::Controller::connect(
        port,
        firmware,
        platform.steps_per_turn,
        std::time::Duration::from_millis(a.motor_timeout_ms),
    )
    .with_context(|| format!("--motor {spec}"))?;
    // one turn and the frame that closes it, unless --frames says otherwise
    let per_turn = platform.steps_per_turn.div_ceil(steps.max(1));
    let frames = a.frames.unwrap_or(per_turn + 1);
    Ok(Box::new(crate::motor::Turning::new(
        source,
        controller,
        u8::try_from(laser).unwrap_or(u8::MAX),
        i64::from(steps),
        frames,
    )))
}

/// `source` with each pixel's value lit without the shadow for its reference and its value in
/// the shadow's core for [`FrameSource::darkest`], from two readings of the sweep beforehand
/// (two more openings of the same source): the brightest and the darkest of each byte, then the
/// mean of the values in the top quarter of that range and of those in the bottom quarter. The
/// extremes alone stand a few noise σ beyond the values they stand for, which would widen every
/// band by a third of a pixel on the rig; the means do not.
fn sweep_extremes(
    a: &ScanArgs,
    format: PixelFormat,
    opts: &SourceOptions,
    source: Box<dyn FrameSource>,
) -> Result<Box<dyn FrameSource>> {
    let mut first = open_source(a, format, opts)?;
    let mut both: Option<(crate::source::OwnedFrame, crate::source::OwnedFrame)> = None;
    while let Some(frame) = first.next_frame()? {
        match &mut both {
            None => both = Some((frame.clone(), frame)),
            Some((hi, lo)) => {
                for ((h, l), v) in hi.data.iter_mut().zip(&mut lo.data).zip(&frame.data) {
                    *h = (*h).max(*v);
                    *l = (*l).min(*v);
                }
            }
        }
    }
    let Some((mut hi, mut lo)) = both else {
        bail!("--shadow: {} has no frames", a.source);
    };
    let n = hi.data.len();
    let (mut sums, mut counts) = (
        [vec![0u32; n], vec![0u32; n]],
        [vec![0u32; n], vec![0u32; n]],
    );
    let mut second = open_source(a, format, opts)?;
    while let Some(frame) = second.next_frame()? {
        for (i, &v) in frame.data.iter().enumerate() {
            let (h, l) = (u32::from(hi.data[i]), u32::from(lo.data[i]));
            let quarter = (h - l) / 8;
            let v32 = u32::from(v);
            if v32 >= h - quarter {
                sums[0][i] += v32;
                counts[0][i] += 1;
            }
            if v32 <= l + quarter {
                sums[1][i] += v32;
                counts[1][i] += 1;
            }
        }
    }
    for (k, f) in [&mut hi, &mut lo].into_iter().enumerate() {
        for (i, b) in f.data.iter_mut().enumerate() {
            if let Some(mean) = (sums[k][i] + counts[k][i] / 2).checked_div(counts[k][i]) {
                *b = mean as u8;
            }
        }
        f.index = u64::MAX;
        f.time_us = None;
    }
    let depth = shadow_depth(&hi, &lo)?;
    if depth < MIN_SHADOW_DEPTH {
        bail!(
            "the shadow is too faint to scan: where it passed it took a median {:.0} % of the light (at least {:.0} % wanted) — a lamp too large, so that its edges are a blur, or too much other light: use a smaller bulb (or take the shade off the lamp), a thicker rod, hold the rod nearer the object, or darken the room (docs/shadow-scanner.md)",
            100.0 * depth,
            100.0 * MIN_SHADOW_DEPTH
        );
    }
    Ok(Box::new(crate::source::Extremes::new(source, hi, lo)))
}

/// Least share of the light a shadow sweep's shadow must take where it passes: a sharp shadow
/// takes the lamp's whole share (55 % on the rig's desk lamp, whose light is 1.2 times the
/// room's; more in a dim room), a lamp wider than the rod as the object sees it is never wholly
/// hidden (on the rig: 39 % for a 24 mm bulb 250 mm behind an 8 mm rod, 25 % for a 40 mm one)
/// and its edges are a blur; strong other light washes any shadow out.
pub const MIN_SHADOW_DEPTH: f64 = 0.4;

/// The median share of the light the shadow takes at its deepest (`1 − darkest / brightest`,
/// luma) over the pixels where it took more than 8 % (where it passed).
fn shadow_depth(hi: &crate::source::OwnedFrame, lo: &crate::source::OwnedFrame) -> Result<f64> {
    let (h, l) = (hi.view()?, lo.view()?);
    let mut depth = vec![0u8; hi.width * hi.height];
    scanner_core::stripe::shadow::contrast(&l, (&h, None), &mut depth, u8::MAX)?;
    let mut passed: Vec<u8> = depth.into_iter().filter(|&d| d > 20).collect();
    if passed.is_empty() {
        return Ok(0.0);
    }
    let mid = passed.len() / 2;
    Ok(f64::from(*passed.select_nth_unstable(mid).1) / 255.0)
}

/// The frame source: the rig with a scene file, or one opened by name.
pub(super) fn open_source(
    a: &ScanArgs,
    format: PixelFormat,
    opts: &SourceOptions,
) -> Result<Box<dyn FrameSource>> {
    if a.view.is_some() && a.scene.is_none() {
        bail!("--view needs --scene: a scene file with [[views]]");
    }
    if let Some(path) = &a.scene {
        #[cfg(feature = "rig")]
        {
            if !a.source.starts_with("rig") {
                bail!("--scene works with the virtual rig only (--source rig)");
            }
            let scene = super::render::view_of(super::render::load_scene(Some(path))?, a.view)?;
            let rig = scanner_rig::Rig::new(scene)
                .map_err(|e| anyhow::anyhow!("building the virtual rig: {e}"))?;
            return Ok(Box::new(crate::source::RigSource::new(rig, format)));
        }
        #[cfg(not(feature = "rig"))]
        bail!(
            "--scene {}: this build has no virtual rig (the `rig` feature)",
            path.display()
        );
    }
    open_with(&a.source, format, opts)
        .with_context(|| format!("opening the frame source {:?}", a.source))
}

/// A fixed laser read from a calibration file: its plane, its platform's known surfaces (what
/// is not the object) and the message that tells the host the platform and the turn.
struct Fixed {
    plane: scanner_core::geometry::Plane<f64>,
    board: scanner_core::geometry::Board<f64>,
    message: scanner_wire::FixedLaser,
    /// The part of the picture where the platform's cylinder shows (its radius and the
    /// scanner's height), when both are known.
    roi: Option<scanner_core::stripe::Roi>,
}

/// The platform's radius taken when the calibration does not know it, mm.
const UNKNOWN_RADIUS_MM: f64 = 1000.0;

/// Laser `n` of the calibration file at `path` over its platform, with the turn per frame
/// the options give.
fn read_fixed(path: &std::path::Path, n: usize, a: &ScanArgs) -> Result<Fixed> {
    let file = CalibrationFile::load(path)?;
    let name = path.display();
    let Some(laser) = file.lasers.get(n) else {
        bail!(
            "--fixed-laser {n}: {name} has {} fixed laser plane(s) ([[laser]]){}",
            file.lasers.len(),
            if file.lasers.is_empty() {
                "; calibrate them or import a scanner's own calibration (`scanner-device import-fabscan`)"
            } else {
                ""
            }
        );
    };
    let Some(section) = file.platform else {
        bail!("--fixed-laser: {name} has no [platform]: the turntable's pose is needed");
    };
    let plane = laser
        .plane()
        .with_context(|| format!("[[laser]] {n} in {name}"))?;
    let platform = section
        .platform()
        .with_context(|| format!("[platform] in {name}"))?;
    let radius = if section.radius > 0.0 {
        section.radius
    } else {
        UNKNOWN_RADIUS_MM
    };
    let board = platform
        .known_surfaces(radius)
        .with_context(|| format!("[platform] in {name}: the camera looks down its axis"))?;
    // the calibration's direction for the motor's steps and a count of frames
    let sense = if section.clockwise { -1.0 } else { 1.0 };
    let turn = match (a.turn_deg, a.steps_per_frame, a.frames_per_turn) {
        (Some(d), _, _) if d.is_finite() && d != 0.0 && d.abs() <= 180.0 => d.to_radians(),
        (Some(d), _, _) => {
            bail!("--turn-deg {d}: give a turn between frames of up to ±180°, not 0")
        }
        (_, Some(0), _) => bail!("--steps-per-frame 0: the platform would not turn"),
        (_, Some(s), _) if s <= section.steps_per_turn / 2 => {
            sense * std::f64::consts::TAU * f64::from(s) / f64::from(section.steps_per_turn)
        }
        (_, Some(s), _) => bail!(
            "--steps-per-frame {s}: more than half of the platform's {} steps per turn",
            section.steps_per_turn
        ),
        (_, _, Some(f)) if f >= 2 => sense * std::f64::consts::TAU / f64::from(f),
        (_, _, Some(f)) => bail!("--frames-per-turn {f}: a turn needs at least 2 frames"),
        _ => bail!(
            "--fixed-laser needs the platform's turn between frames: --turn-deg, --steps-per-frame or --frames-per-turn"
        ),
    };
    let r = platform.rotation();
    let o = platform.origin();
    let camera = file.camera().with_context(|| format!("camera in {name}"))?;
    let roi = (section.radius > 0.0 && section.height > 0.0).then(|| {
        platform_roi(
            &camera,
            &platform,
            (section.radius, section.height),
            (file.image.width, file.image.height),
        )
    });
    Ok(Fixed {
        roi: roi.flatten(),
        plane,
        board,
        message: scanner_wire::FixedLaser {
            scan_id: 0,
            laser: u8::try_from(n).unwrap_or(u8::MAX),
            // row-major
            rotation: std::array::from_fn(|k| r[(k / 3, k % 3)] as f32),
            origin: [o.x as f32, o.y as f32, o.z as f32],
            turn: turn as f32,
            radius: section.radius as f32,
        },
    })
}

/// The smallest rectangle of the picture that holds the cylinder of `radius` and `height` on
/// the platform (its circles at the top and bottom, 32 points each, projected), with a margin of
/// 8 px; `None` when a point does not project (behind the camera) or nothing is left.
fn platform_roi(
    camera: &scanner_core::Camera<f64>,
    platform: &scanner_core::geometry::Platform<f64>,
    (radius, height): (f64, f64),
    (w, h): (u32, u32),
) -> Option<scanner_core::stripe::Roi> {
    use scanner_core::nalgebra::Vector3;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for k in 0..32 {
        let a = std::f64::consts::TAU * f64::from(k) / 32.0;
        for z in [0.0, height] {
            let local = Vector3::new(radius * a.cos(), radius * a.sin(), z);
            let p = platform.origin() + platform.rotation() * local;
            let px = camera.project(&p).ok()?;
            lo = [lo[0].min(px.x), lo[1].min(px.y)];
            hi = [hi[0].max(px.x), hi[1].max(px.y)];
        }
    }
    let clamp = |v: f64, n: u32| (v.max(0.0) as usize).min(n as usize);
    let (x0, y0) = (clamp(lo[0] - 8.0, w), clamp(lo[1] - 8.0, h));
    let (x1, y1) = (clamp(hi[0] + 9.0, w), clamp(hi[1] + 9.0, h));
    (x1 > x0 + 1 && y1 > y0 + 1).then_some(scanner_core::stripe::Roi {
        x: x0,
        y: y0,
        width: x1 - x0,
        height: y1 - y0,
    })
}

/// The pipeline's settings for a fixed laser: its plane; the light-intensity method (the frames
/// are dark: nothing to subtract); stripes up to 64 px wide with a halo around them (a laser
/// close to a plaster or skin-like surface glows); the platform's top within 1 mm is the
/// platform.
fn fixed_head(mut head: HeadConfig, f: &Fixed) -> HeadConfig {
    head.fixed_plane = Some(scanner_core::pipeline::FixedPlane {
        plane: f.plane.cast(),
        sigma: 0.05,
    });
    head.stripe.method = Method::Lim;
    head.stripe.max_width = 64.0;
    head.stripe.max_plateau = 40;
    head.stripe.half_window = scanner_core::stripe::MAX_HALF_WINDOW;
    head.stripe.separation = 24;
    head.stripe.ambiguity = 0.8;
    head.limits.board_tol = 1.0;
    head.stripe.roi = f.roi;
    head
}

/// The calibration file's camera and board (or a fixed laser's platform), checked against the
/// source's frame size.
fn read_calibration(
    path: &std::path::Path,
    source: &dyn FrameSource,
    source_name: &str,
    fixed: Option<&Fixed>,
) -> Result<Calibration> {
    let file = CalibrationFile::load(path)?;
    let (w, h) = source.size();
    if (w as u32, h as u32) != (file.image.width, file.image.height) {
        bail!(
            "calibration {} is for {}×{} images but {source_name} gives {w}×{h}",
            path.display(),
            file.image.width,
            file.image.height,
        );
    }
    let camera = file
        .camera()
        .with_context(|| format!("camera in {}", path.display()))?;
    let board = match (fixed, file.board()) {
        (Some(f), _) => Ok(f.board),
        (None, Some(board)) => board,
        (None, None) => bail!(
            "{} has no board: run `scanner-device calibrate board` first",
            path.display()
        ),
    };
    let board = board.with_context(|| format!("board in {}", path.display()))?;
    let spread = file
        .spread()
        .transpose()
        .with_context(|| format!("the covariances in {}", path.display()))?;
    Ok(Calibration {
        camera,
        board,
        size: (file.image.width, file.image.height),
        spread,
        speckle_px: file.camera.speckle_px.map(|s| s as f32),
    })
}

/// The pipeline's settings from the options.
fn head_config(a: &ScanArgs) -> HeadConfig {
    let method = if a.lim { Method::Lim } else { Method::Dim };
    let axis = if a.rows { Axis::Rows } else { Axis::Columns };
    let colour = a.laser.map_or(LaserColour::Red, LaserColour::from);
    let mut head = HeadConfig::new(StripeConfig {
        colour,
        ..StripeConfig::new(method, axis)
    });
    head.method = match a.method {
        PlaneArg::Lsq => PlaneMethod::LeastSquares,
        PlaneArg::Paper => PlaneMethod::Paper,
    };
    head.keep_board = a.keep_board;
    head.edge_reach = a.edge_reach;
    head.stripe.print_ratio = a.print_ratio;
    head.colour = a.colour;
    if a.shadow {
        head = shadow_head(head);
    }
    head
}

/// The pipeline's settings for a shadow sweep: the light-intensity method on the contrast
/// frames (gray), the band's rising edge first, no speckle (a lamp's light is not coherent),
/// and a band much narrower than the frame's taken for one cut by an outline whatever its depth
/// (one of its edges is then the outline, not the shadow's).
fn shadow_head(mut head: HeadConfig) -> HeadConfig {
    head.stripe.method = Method::Lim;
    head.stripe.colour = LaserColour::White;
    head.stripe.speckle_px = 0.0;
    head.stripe.cut_peak = f32::INFINITY;
    head.stripe.cut_sharp = false;
    head.stripe.edges = true;
    head.locate = scanner_core::stripe::Locate::RisingEdge;
    head
}

/// Runs a planned scan to its end, with progress lines unless quiet.
///
/// # Errors
/// The source failing before the first frame, the link failing.
pub fn run(plan: ScanPlan) -> Result<ScanReport> {
    let ScanPlan {
        mut source,
        calibration,
        options,
        mut link,
        stop,
        quiet,
    } = plan;
    if !quiet {
        crate::errln!("source: {}", source.describe());
    }
    let report = run_scan_until(
        source.as_mut(),
        &calibration,
        options,
        &mut link,
        &stop,
        |s| {
            if !quiet && s.frames % 30 == 0 {
                crate::errln!(
                    "frames {}, packets {}, points {}",
                    s.frames,
                    s.packets,
                    s.points
                );
            }
        },
        |_, _| {},
    )?;
    link.finish()?;
    Ok(report)
}

/// Runs `devices`.
pub fn devices() {
    let list = crate::source::v4l2::list();
    if list.is_empty() {
        crate::outln!("no V4L2 cameras found (or this build has no V4L2 support)");
    }
    for l in list {
        crate::outln!("{l}");
    }
}

/// A flag raised by Ctrl-C (SIGINT) or SIGTERM, so that a scan ends with its final status
/// instead of being killed mid-stream. `None` when a handler cannot be installed (a second
/// scan in one process, e.g. in tests): the scan then runs without it.
fn stop_flag() -> Option<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let f = flag.clone();
    ctrlc::set_handler(move || f.store(true, std::sync::atomic::Ordering::SeqCst))
        .ok()
        .map(|()| flag)
}
