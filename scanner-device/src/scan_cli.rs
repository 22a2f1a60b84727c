//! `scanner-device scan` and `scanner-device devices`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use scanner_core::pipeline::{HeadConfig, PlaneMethod};
use scanner_core::stripe::{Axis, LaserColour, Method, PixelFormat, StripeConfig};
use scanner_core::wire::Skip;

use crate::calib::file::CalibrationFile;
use crate::head::{ScanOptions, ScanReport, run_scan};
use crate::link::{Link, Target};
use crate::source::{SourceOptions, open_with};

/// Options of `scan`.
#[derive(Debug, Args)]
pub struct ScanArgs {
    /// Frame source: `rig`, `rig:WIDTHxHEIGHT`, `dir:FOLDER` (or a folder), `/dev/videoN`.
    #[arg(long, default_value = "rig")]
    pub source: String,
    /// With the virtual rig: this scene file instead of the demo scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Pixel format the pipeline reads: gray, yuyv or rgb.
    #[arg(long, default_value = "gray", value_parser = ["gray", "yuyv", "rgb"])]
    pub format: String,
    /// Camera resolution, WIDTHxHEIGHT.
    #[arg(long)]
    pub size: Option<String>,
    /// Camera frame rate.
    #[arg(long)]
    pub fps: Option<u32>,
    /// Camera pixel format FourCC (YUYV, GREY, RGB3, MJPG).
    #[arg(long)]
    pub fourcc: Option<String>,
    /// Reference (laser-off) frame from this image.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Otherwise average this many first frames, laser off.
    #[arg(long, default_value_t = 8)]
    pub reference_frames: usize,
    /// Calibration file (`calibrate board`); `rig-truth` uses the virtual rig's true camera and
    /// board (for tests).
    #[arg(long)]
    pub calibration: Option<String>,
    /// Where the stream goes: `serial:/dev/ttyUSB0@921600`, `file:PATH` (or a path), `-`.
    #[arg(long, default_value = "scan.stream")]
    pub out: String,
    /// Laser plane by least squares (default) or the paper's construction.
    #[arg(long, default_value = "lsq", value_parser = ["lsq", "paper"])]
    pub method: String,
    /// The light-intensity method (no reference needed for the stripe) instead of the
    /// difference image.
    #[arg(long)]
    pub lim: bool,
    /// The laser's colour: the stripe is found by the light it adds in that colour (difference
    /// image) or by how much more of that colour a pixel shows (light intensity); `white` goes
    /// by brightness alone. Gray frames show no colour: there it is ignored. [default: red]
    #[arg(long, value_enum)]
    pub laser: Option<LaserArg>,
    /// The stripe runs vertically (the laser sweeps sideways): scan rows.
    #[arg(long)]
    pub rows: bool,
    /// Send the stripe's board points too.
    #[arg(long)]
    pub keep_board: bool,
    /// Colour each point from the reference frame.
    #[arg(long)]
    pub colour: bool,
    /// Buffers between the camera and the link (frames dropped beyond).
    #[arg(long, default_value_t = 8)]
    pub link_depth: usize,
    /// Scan id (random without).
    #[arg(long)]
    pub scan_id: Option<u32>,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
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

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("--size {s:?}: expected WIDTHxHEIGHT"))?;
    Ok((
        w.parse().with_context(|| format!("--size {s:?}"))?,
        h.parse().with_context(|| format!("--size {s:?}"))?,
    ))
}

/// The virtual rig's true calibration as a calibration file.
pub fn rig_truth(rig: &crate::rig::Rig) -> CalibrationFile {
    let s = rig.scene();
    let mut f = CalibrationFile::from_camera(
        &s.camera,
        (s.width, s.height),
        "the virtual rig's true camera".into(),
        None,
    );
    let [l, r] = rig.board_planes();
    let sheet = |p: &scanner_core::geometry::Plane<f64>| crate::calib::file::SheetSection {
        normal: (*p.normal()).into(),
        offset: p.offset(),
        rms_px: 0.0,
        markers: Vec::new(),
    };
    let board = scanner_core::geometry::Board::new(l, r).expect("the rig's board is valid");
    f.board = Some(crate::calib::file::BoardSection {
        method: "rig-truth".into(),
        angle_deg: board.angle().to_degrees(),
        crease_point: board.crease().point().coords.into(),
        crease_direction: (*board.crease().direction()).into(),
        left: sheet(&l),
        right: sheet(&r),
        paper: None,
    });
    f
}

/// Link speeds for the README's table, bytes per second.
pub const LINKS: [(&str, f64); 3] = [
    ("115200 baud UART", 11_520.0),
    ("921600 baud UART", 92_160.0),
    ("USB CDC", 1_000_000.0),
];

/// Prints the end-of-scan summary.
pub fn print_report(r: &ScanReport) {
    let s = &r.status;
    println!(
        "scan {:08x}: {} frames, {} point packets, {} points, {} bytes in {:.2} s ({:.1} frames/s){}",
        s.scan_id,
        s.frames,
        s.packets,
        s.points,
        r.bytes,
        r.seconds,
        f64::from(s.frames) / r.seconds.max(1e-9),
        r.ended_early
            .as_ref()
            .map(|e| format!("; ended early: {e}"))
            .unwrap_or_default()
    );
    let bpp = r.bytes_per_point();
    println!("{bpp:.2} bytes per point on the link (framing and headers included)");
    for (name, bps) in LINKS {
        println!("  {name}: {:.0} points/s", bps / bpp);
    }
    for reason in Skip::ALL {
        let n = s.skipped[reason as usize];
        if n > 0 {
            println!("  skipped {n} frames: {}", reason.name());
        }
    }
}

/// Runs `scan`.
///
/// # Errors
/// Every failure, named.
pub fn scan(a: &ScanArgs) -> Result<ScanReport> {
    let format = match a.format.as_str() {
        "yuyv" => PixelFormat::Yuyv,
        "rgb" => PixelFormat::Rgb24,
        _ => PixelFormat::Gray8,
    };
    if let Some(f) = &a.fourcc {
        let b = f.as_bytes();
        if b.len() != 4
            || crate::convert::CameraFormat::from_fourcc([b[0], b[1], b[2], b[3]]).is_none()
        {
            bail!(
                "unsupported camera pixel format {f:?}: this head reads YUYV, GREY, RGB3 and MJPG"
            );
        }
    }
    let opts = SourceOptions {
        size: a.size.as_deref().map(parse_size).transpose()?,
        fps: a.fps,
        fourcc: a.fourcc.clone(),
        reference: a.reference.clone(),
        reference_frames: a.reference_frames,
    };
    let Some(cal_name) = &a.calibration else {
        bail!(
            "no calibration: give --calibration FILE (from `scanner-device calibrate board`), or --calibration rig-truth with the virtual rig"
        );
    };
    let scene_rig = match &a.scene {
        Some(path) => {
            if !a.source.starts_with("rig") {
                bail!("--scene works with the virtual rig only (--source rig)");
            }
            let scene = crate::render::load_scene(Some(path))?;
            Some(
                crate::rig::Rig::new(scene)
                    .map_err(|e| anyhow::anyhow!("building the virtual rig: {e}"))?,
            )
        }
        None => None,
    };
    let mut source: Box<dyn crate::source::FrameSource> = match &scene_rig {
        Some(rig) => Box::new(crate::source::RigSource::new(rig.clone(), format)),
        None => open_with(&a.source, format, &opts)
            .with_context(|| format!("opening the frame source {:?}", a.source))?,
    };
    let cal = if let (Some(rig), "rig-truth") = (&scene_rig, cal_name.as_str()) {
        rig_truth(rig)
    } else if cal_name == "rig-truth" {
        let spec = a
            .source
            .strip_prefix("rig")
            .filter(|_| a.source.starts_with("rig"));
        let Some(spec) = spec else {
            bail!("--calibration rig-truth works with the virtual rig only (--source rig…)");
        };
        let (w, h) = match spec.strip_prefix(':') {
            Some(s) => parse_size(s)?,
            None => (640, 480),
        };
        rig_truth(
            &crate::rig::Rig::new(crate::rig::Scene::demo(w, h))
                .map_err(|e| anyhow::anyhow!("{e}"))?,
        )
    } else {
        CalibrationFile::load(std::path::Path::new(cal_name))?
    };
    let (w, h) = source.size();
    if (w as u32, h as u32) != (cal.image.width, cal.image.height) {
        bail!(
            "calibration {cal_name} is for {}×{} images but {} gives {w}×{h}",
            cal.image.width,
            cal.image.height,
            a.source
        );
    }
    let method = if a.lim { Method::Lim } else { Method::Dim };
    let axis = if a.rows { Axis::Rows } else { Axis::Columns };
    let colour = a.laser.map_or(LaserColour::Red, LaserColour::from);
    if a.laser.is_some() && a.format == "gray" {
        eprintln!(
            "note: --laser {} has no effect on gray frames (--format gray): a gray camera sees no colour",
            colour.name()
        );
    }
    let mut head = HeadConfig::new(StripeConfig {
        colour,
        ..StripeConfig::new(method, axis)
    });
    head.method = if a.method == "paper" {
        PlaneMethod::Paper
    } else {
        PlaneMethod::LeastSquares
    };
    head.keep_board = a.keep_board;
    head.colour = a.colour;
    let scan_id = a.scan_id.unwrap_or_else(rand::random);
    let target: Target = a
        .out
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--out: {e}"))?;
    let mut link = Link::spawn(
        target.open()?,
        a.link_depth,
        scanner_core::wire::MAX_ENCODED,
    );
    if !a.quiet {
        eprintln!("source: {}", source.describe());
    }
    let quiet = a.quiet;
    let report = run_scan(
        source.as_mut(),
        &cal,
        ScanOptions {
            head,
            header_every: 30,
            status_every: 30,
            scan_id,
        },
        &mut link,
        |s| {
            if !quiet && s.frames % 30 == 0 {
                eprintln!(
                    "frames {}, packets {}, points {}",
                    s.frames, s.packets, s.points
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
    let list = crate::v4l_source::list();
    if list.is_empty() {
        println!("no V4L2 cameras found (or this build has no V4L2 support)");
    }
    for l in list {
        println!("{l}");
    }
}
