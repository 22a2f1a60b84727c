//! `scan`'s options as clap reads them; [`super::plan`] turns them into a [`crate::scan::ScanPlan`].

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use scanner_core::stripe::{LaserColour, PixelFormat};

use crate::source::SourceOptions;

use super::super::values;

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
    /// A folder that holds several series of frames (two lasers' frames side by side): read
    /// the series of this pattern, the names with their frame number as `*`
    /// (`laser0_*.jpg`; the refusal without it lists the folder's).
    #[arg(long, value_name = "PATTERN")]
    pub series: Option<String>,
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
    /// With --fixed-laser: the platform carries ArUco markers of this dictionary
    /// (`DICT_4X4_50` … `DICT_7X7_1000`) printed on its top, in a lit room: each frame's turn is
    /// measured from them (no step count needed; frames that turned otherwise than the rest
    /// are reported, frames that show none of them left out).
    #[arg(long, value_name = "DICT", requires = "fixed_laser")]
    pub markers: Option<String>,
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
    /// With --shadow: read the sweep through time (Bouguet and Perona): each pixel placed by
    /// the moment the shadow's edges cross it, each moment's planes from the edges on the two
    /// sheets; one point per pixel and edge, the way the band moves found from the frames. For
    /// soft shadows on real objects. Needs frames that can be read twice (a folder, a
    /// recording, the rig).
    #[arg(long, requires = "shadow", conflicts_with_all = ["reference", "rows", "columns"])]
    pub temporal: bool,

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
    /// Exposure time set by hand, the camera's units (V4L2: 100 µs); the camera's own
    /// exposure, locked for the scan, without it. The virtual rig renders its scenes at 100.
    #[arg(long)]
    pub exposure: Option<i32>,
    /// Gain set by hand, the camera's units (the virtual rig: 100 as written).
    #[arg(long)]
    pub gain: Option<i32>,
    /// Focus set by hand, the camera's units (V4L2 `focus_absolute`).
    #[arg(long)]
    pub focus: Option<i32>,
    /// White balance set by hand, kelvin.
    #[arg(long)]
    pub white_balance: Option<i32>,
}

impl CameraArgs {
    /// The controls set by hand.
    pub fn by_hand(&self) -> scanner_wire::ByHand {
        scanner_wire::ByHand {
            exposure: self.exposure,
            gain: self.gain,
            focus: self.focus,
            white_balance: self.white_balance,
        }
    }

    /// Sets the controls set by hand (the service's camera command).
    pub fn set_by_hand(&mut self, b: scanner_wire::ByHand) {
        (self.exposure, self.gain, self.focus, self.white_balance) =
            (b.exposure, b.gain, b.focus, b.white_balance);
    }

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
            adjust: self.by_hand(),
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
