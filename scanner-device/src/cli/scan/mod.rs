//! `scanner-device scan` and `scanner-device devices`: arguments, then a validated plan (the
//! source opened, the calibration read and checked against it, the link opened), then the run.

mod args;
mod fixed;
mod refusal;
mod shadow;

use anyhow::{Context, Result};
use scanner_calib::file::CalibrationFile;
use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, LaserColour, Method, PixelFormat, StripeConfig};
use scanner_wire::PlaneMethod;

use crate::link::{Destination, Link};
use crate::scan::ScanPlan;
use crate::session::{Calibration, ScanOptions, ScanReport, StopWhen};
use crate::source::convert::CameraFormat;
use crate::source::{FrameSource, SourceOptions, open_with};

pub use args::{CameraArgs, FirmwareArg, FormatArg, LaserArg, PlaneArg, ScanArgs};
use fixed::{Fixed, fixed_head, read_fixed, turning};
pub use refusal::{ScanFailed, ScanRefusal};
use shadow::sweep_extremes;

/// Runs `scan`: [`plan`], then [`run`].
///
/// # Errors
/// Every failure, named.
pub fn scan(a: &ScanArgs) -> Result<ScanReport> {
    run(plan(a)?, a.quiet)
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
        return Err(ScanRefusal::NoCalibration.into());
    }
    let o = open_on(a, link)?;
    let Some(calibration) = o.calibration else {
        unreachable!("a calibration was given and read");
    };
    let options = ScanOptions {
        head: o.head,
        find_axis: o.find_axis,
        find_colour: o.find_colour,
        fixed: o.fixed,
        markers: o.markers,
        shadow: a.shadow,
        temporal: a.temporal,
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
    /// Whether the laser's colour is to be found (none was given).
    pub find_colour: bool,
    /// The session id.
    pub scan_id: u32,
    /// The link.
    pub link: Link,
    /// When to stop.
    pub stop: StopWhen,
    /// A fixed laser's platform and turn, for its message after each header.
    pub fixed: Option<scanner_wire::FixedLaser>,
    /// The markers on its platform each frame's turn is measured by.
    pub markers: Option<crate::marker_turn::MarkerPlatform>,
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
        series: a.series.clone(),
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
    if let Some(f) = &fixed
        && f.message.turn != 0.0
    {
        // frames beyond one turn and its closing frame would lay the object over itself
        let per_turn = std::f64::consts::TAU / f64::from(f.message.turn).abs();
        if let Some(n) = source.frames_left()
            && n as f64 > per_turn.round() + 1.0
        {
            return Err(ScanRefusal::BeyondOneTurn {
                given_by: a.source.clone(),
                frames: n,
                turn_deg: f64::from(f.message.turn).to_degrees(),
                per_turn,
            }
            .into());
        }
    }
    if let Some(f) = &fixed {
        head = fixed_head(head, f);
    }
    Ok(OpenedSource {
        markers: fixed.as_ref().and_then(|f| f.markers),
        fixed: fixed.map(|f| f.message),
        source,
        calibration,
        head,
        find_axis: !(a.rows || a.columns),
        find_colour: a.laser.is_none(),
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

/// The frame source: the rig with a scene file, or one opened by name.
pub(super) fn open_source(
    a: &ScanArgs,
    format: PixelFormat,
    opts: &SourceOptions,
) -> Result<Box<dyn FrameSource>> {
    if a.view.is_some() && a.scene.is_none() {
        return Err(ScanRefusal::ViewWithoutScene.into());
    }
    if let Some(path) = &a.scene {
        #[cfg(feature = "rig")]
        {
            if !a.source.starts_with("rig") {
                return Err(ScanRefusal::SceneNotRig.into());
            }
            let scene = super::render::view_of(super::render::load_scene(Some(path))?, a.view)?;
            let rig = scanner_rig::Rig::new(scene)
                .map_err(|e| anyhow::anyhow!("building the virtual rig: {e}"))?;
            let mut source = crate::source::RigSource::new(rig, format);
            source.adjust(&opts.adjust)?;
            return Ok(Box::new(source));
        }
        #[cfg(not(feature = "rig"))]
        return Err(ScanRefusal::NoRig(path.clone()).into());
    }
    open_with(&a.source, format, opts)
        .with_context(|| format!("opening the frame source {:?}", a.source))
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
        return Err(ScanRefusal::CalibrationSize {
            path: path.to_path_buf(),
            calibration: (file.image.width, file.image.height),
            given_by: source_name.to_string(),
            frames: (w, h),
        }
        .into());
    }
    let camera = file
        .camera()
        .with_context(|| format!("camera in {}", path.display()))?;
    let board = match (fixed, file.board()) {
        (Some(f), _) => Ok(f.board),
        (None, Some(board)) => board,
        (None, None) => return Err(ScanRefusal::NoBoard(path.to_path_buf()).into()),
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

/// Runs a planned scan to its end, with the source's line and a progress line every 30 frames
/// on standard error unless `quiet`.
///
/// # Errors
/// The source failing before the first frame, the link failing.
pub fn run(plan: ScanPlan, quiet: bool) -> Result<ScanReport> {
    if !quiet {
        crate::errln!("source: {}", plan.source.describe());
    }
    crate::scan::run(plan, |s| {
        if !quiet && s.frames % 30 == 0 {
            crate::errln!(
                "frames {}, packets {}, points {}",
                s.frames,
                s.packets,
                s.points
            );
        }
    })
    // the session's own error (`main` reads a laser never seen from it), not its wrapper's
    .map_err(|e| match e {
        crate::scan::RunError::Session(s) => anyhow::Error::from(s),
        crate::scan::RunError::Link(l) => anyhow::Error::from(l),
    })
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
