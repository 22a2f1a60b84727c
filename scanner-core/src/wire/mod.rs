//! The wire between the scanner head and the host: message types and their framing. Shared by
//! both ends; `no_std`, no heap (encoding writes into the caller's buffers, decoding borrows from
//! them). The format is written down in `docs/wire.md`.
//!
//! A frame on the wire:
//! ```text
//! 0x00 ‖ COBS( version:u8 ‖ postcard(Message) ‖ crc32(version ‖ postcard(Message)):u32 LE ) ‖ 0x00
//! ```
//! COBS removes every zero byte, so `0x00` delimits frames: a reader that joins mid-stream or
//! after garbage resynchronises at the next zero, and the leading zero cuts off any garbage just
//! before a frame (empty frames between two zeros are ignored). The CRC is CRC-32/ISO-HDLC (the zlib one).
//!
//! Messages: a [`Header`] (image size, units, the calibration summary, scan id; repeated
//! periodically so that a host that joins late can decode), one [`Points`] per frame
//! (self-contained: losing one loses only that frame), a [`Status`] (counters) and the camera's
//! [`Controls`] (sent with each header).

pub mod points;

use core::fmt;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::geometry::{Board, Plane};
use crate::{Camera, Distortion, GeomError, Real};

/// Protocol version, the first byte of every frame. Version 2 added
/// [`Points::uncertainty`]; frames of version 1 are still read (their points carry none).
pub const VERSION: u8 = 2;
/// Size of one wire unit of length, mm (0.01 mm).
pub const UNIT_MM: f32 = 0.01;
/// Largest frame before COBS, bytes ([`crate::config::MAX_FRAME`]).
pub const MAX_FRAME: usize = crate::config::MAX_FRAME;
/// Largest encoded frame including COBS overhead and both delimiters.
pub const MAX_ENCODED: usize = cobs::max_encoding_length(MAX_FRAME) + 2;
/// Number of reasons a frame can be skipped.
pub const SKIP_REASONS: usize = 6;

const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Why a frame produced no points, in [`Status::skipped`] order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[repr(u8)]
pub enum Skip {
    /// Too few stripe pixels on the board (laser off, out of view, too faint).
    NoStripe = 0,
    /// The stripe was on one board plane only.
    OnePlaneOnly = 1,
    /// The laser plane (nearly) contains the camera centre.
    PlaneThroughCamera = 2,
    /// The laser plane failed its quality check (e.g. the stripe's board parts disagree).
    PoorPlane = 3,
    /// The camera delivered a bad frame (size, format).
    BadFrame = 4,
    /// The link was too slow: the frame was dropped whole.
    LinkFull = 5,
}

impl Skip {
    /// Every reason, in order.
    pub const ALL: [Skip; SKIP_REASONS] = [
        Skip::NoStripe,
        Skip::OnePlaneOnly,
        Skip::PlaneThroughCamera,
        Skip::PoorPlane,
        Skip::BadFrame,
        Skip::LinkFull,
    ];

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            Skip::NoStripe => "no stripe on the board",
            Skip::OnePlaneOnly => "stripe on one plane only",
            Skip::PlaneThroughCamera => "laser plane through the camera",
            Skip::PoorPlane => "laser plane failed its check",
            Skip::BadFrame => "bad camera frame",
            Skip::LinkFull => "link too slow (frame dropped)",
        }
    }
}

/// How the head finds each frame's laser plane (the pipeline's setting; the header says it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum PlaneMethod {
    /// Least squares over all of the stripe's board points, with outlier rejection (default).
    LeastSquares = 0,
    /// The paper's construction (lines MN and QR, crossings S and T).
    Paper = 1,
}

/// Why a scan ended (the last status says it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum EndReason {
    /// It has not ended, or it ran to its end.
    #[default]
    Completed = 0,
    /// The camera failed or vanished mid-scan.
    CameraLost = 1,
    /// The operator stopped it (Ctrl-C, a signal, a frame or time limit).
    Stopped = 2,
}

/// A `u8` that names no variant of a wire enum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadEnum(pub u8);

impl fmt::Display for BadEnum {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} names no value of this field", self.0)
    }
}

macro_rules! wire_enum {
    ($t:ty, $($v:ident = $n:literal),+) => {
        impl From<$t> for u8 {
            fn from(v: $t) -> u8 {
                v as u8
            }
        }
        impl TryFrom<u8> for $t {
            type Error = BadEnum;
            fn try_from(n: u8) -> Result<Self, BadEnum> {
                match n {
                    $($n => Ok(<$t>::$v),)+
                    _ => Err(BadEnum(n)),
                }
            }
        }
    };
}
wire_enum!(PlaneMethod, LeastSquares = 0, Paper = 1);
wire_enum!(EndReason, Completed = 0, CameraLost = 1, Stopped = 2);

/// The camera on the wire: its nine intrinsics as `f32`, in this order (the same bytes as
/// `[f32; 9]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraBlock {
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Radial distortion k1.
    pub k1: f32,
    /// Radial distortion k2.
    pub k2: f32,
    /// Tangential distortion p1.
    pub p1: f32,
    /// Tangential distortion p2.
    pub p2: f32,
    /// Radial distortion k3.
    pub k3: f32,
}

impl<T: Real> From<&Camera<T>> for CameraBlock {
    fn from(c: &Camera<T>) -> Self {
        let c: Camera<f32> = c.cast();
        let (d, pp) = (c.distortion(), c.principal_point());
        CameraBlock {
            fx: c.fx(),
            fy: c.fy(),
            cx: pp.x,
            cy: pp.y,
            k1: d.k1,
            k2: d.k2,
            p1: d.p1,
            p2: d.p2,
            k3: d.k3,
        }
    }
}

impl TryFrom<CameraBlock> for Camera<f32> {
    type Error = GeomError;
    /// The camera, checked as [`Camera::new`] checks it.
    fn try_from(b: CameraBlock) -> Result<Self, GeomError> {
        Camera::new(
            b.fx,
            b.fy,
            b.cx,
            b.cy,
            Distortion {
                k1: b.k1,
                k2: b.k2,
                p1: b.p1,
                p2: b.p2,
                k3: b.k3,
            },
        )
    }
}

/// A board plane on the wire: unit normal and offset (mm), `n · x + d = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlaneBlock {
    /// Unit normal, toward the camera.
    pub normal: [f32; 3],
    /// Offset, mm.
    pub offset: f32,
}

impl<T: Real> From<&Plane<T>> for PlaneBlock {
    fn from(p: &Plane<T>) -> Self {
        let n = p.normal();
        PlaneBlock {
            normal: [n.x, n.y, n.z].map(|v| v.to_f64() as f32),
            offset: p.offset().to_f64() as f32,
        }
    }
}

impl TryFrom<PlaneBlock> for Plane<f32> {
    type Error = GeomError;
    fn try_from(b: PlaneBlock) -> Result<Self, GeomError> {
        Plane::new(
            Vector3::new(b.normal[0], b.normal[1], b.normal[2]),
            b.offset,
        )
    }
}

/// The session header.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Scan id (random per scan): frames of different scans are not mixed.
    pub scan_id: u32,
    /// Image width, pixels.
    pub width: u16,
    /// Image height, pixels.
    pub height: u16,
    /// Length of one wire unit, micrometres (10: 0.01 mm).
    pub unit_um: u16,
    /// Camera intrinsics.
    pub camera: CameraBlock,
    /// Board planes, left and right.
    pub board: [PlaneBlock; 2],
    /// Whether points carry colour.
    pub colour: bool,
    /// How the laser plane is found.
    pub method: PlaneMethod,
}

impl Header {
    /// The header of a scan: its id, the image size, the calibration, whether points carry
    /// colour and how the laser plane is found; units of [`UNIT_MM`].
    pub fn new<T: Real>(
        scan_id: u32,
        (width, height): (u16, u16),
        camera: &Camera<T>,
        board: &Board<T>,
        colour: bool,
        method: PlaneMethod,
    ) -> Header {
        Header {
            scan_id,
            width,
            height,
            unit_um: (UNIT_MM * 1000.0) as u16,
            camera: camera.into(),
            board: [board.left().into(), board.right().into()],
            colour,
            method,
        }
    }

    /// The camera, checked.
    ///
    /// # Errors
    /// [`GeomError`] for intrinsics no camera has (a head sending garbage).
    pub fn camera(&self) -> Result<Camera<f32>, GeomError> {
        self.camera.try_into()
    }

    /// The board, checked.
    ///
    /// # Errors
    /// [`GeomError`] for planes that are not planes or do not meet.
    pub fn board(&self) -> Result<Board<f32>, GeomError> {
        Board::new(self.board[0].try_into()?, self.board[1].try_into()?)
    }

    /// Length of one wire unit, mm.
    pub fn unit_mm(&self) -> f32 {
        f32::from(self.unit_um) / 1000.0
    }
}

/// One frame's points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Points<'a> {
    /// Scan id.
    pub scan_id: u32,
    /// Frame number in the scan (gaps: skipped or lost frames).
    pub frame: u32,
    /// Capture time since the scan started, microseconds.
    pub time_us: u64,
    /// The laser plane `[nx, ny, nz, d]` of this frame.
    pub plane: [f32; 4],
    /// Number of points.
    pub count: u32,
    /// Coordinates: [`points`] coding of the quantised points.
    #[serde(borrow)]
    pub xyz: &'a [u8],
    /// Colour, 3 bytes (RGB) per point, or empty.
    #[serde(borrow)]
    pub rgb: &'a [u8],
    /// Standard uncertainty, one byte per point ([`points::uncertainty_code`]), or empty.
    #[serde(borrow)]
    pub uncertainty: &'a [u8],
}

/// Counters of the head.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Status {
    /// Scan id.
    pub scan_id: u32,
    /// Frames captured.
    pub frames: u32,
    /// Point packets sent.
    pub packets: u32,
    /// Points sent.
    pub points: u64,
    /// Bytes sent (framing included).
    pub bytes: u64,
    /// Frames skipped, by [`Skip`] reason.
    pub skipped: [u32; SKIP_REASONS],
    /// Frames per second processed, × 1000.
    pub fps_milli: u32,
    /// `true` in the last status of a scan.
    pub done: bool,
    /// Why the scan ended (in the last status; [`EndReason::Completed`] before).
    pub ended: EndReason,
}

/// What the head did with one camera control the scan needs fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Control {
    /// The frames do not come from a camera (the virtual rig, image files).
    #[default]
    NoCamera,
    /// The camera does not offer the control (it may drift).
    NotOffered,
    /// Set to this value (the V4L2 value: for the power line 1 is 50 Hz, 2 is 60 Hz, 3 automatic;
    /// for the others the value that fixes the control).
    Set(i32),
    /// The camera refused the value.
    Refused,
}

/// The camera controls a difference image needs fixed between the reference and the laser
/// frames, as the head left them (sent after each [`Header`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Controls {
    /// Scan id.
    pub scan_id: u32,
    /// Automatic exposure (set: manual).
    pub exposure: Control,
    /// Automatic white balance (set: off).
    pub white_balance: Control,
    /// Automatic gain (set: off).
    pub gain: Control,
    /// Automatic focus (set: off).
    pub focus: Control,
    /// Power-line frequency.
    pub power_line: Control,
}

impl Controls {
    /// The controls by name, in message order.
    pub fn named(&self) -> [(&'static str, Control); 5] {
        [
            ("exposure", self.exposure),
            ("white balance", self.white_balance),
            ("gain", self.gain),
            ("focus", self.focus),
            ("power line", self.power_line),
        ]
    }
}

impl fmt::Display for Controls {
    /// One line for people: `exposure fixed, white balance fixed, …, power line 50 Hz`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.named().iter().all(|(_, c)| *c == Control::NoCamera) {
            return f.write_str("no camera (nothing to fix)");
        }
        for (i, (name, c)) in self.named().into_iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            match (name, c) {
                (_, Control::NoCamera) => write!(f, "{name} not a camera's"),
                (_, Control::NotOffered) => write!(f, "{name} not offered"),
                (_, Control::Refused) => write!(f, "{name} REFUSED by the camera"),
                ("power line", Control::Set(1)) => f.write_str("power line 50 Hz"),
                ("power line", Control::Set(2)) => f.write_str("power line 60 Hz"),
                ("power line", Control::Set(_)) => f.write_str("power line automatic"),
                (_, Control::Set(_)) => write!(f, "{name} fixed"),
            }?;
        }
        Ok(())
    }
}

/// How well the laser planes of the frames since the last status fitted the board's stripe
/// (sent before each [`Status`]): the operator's check that the sweep is clean.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Planes {
    /// Scan id.
    pub scan_id: u32,
    /// Laser planes fitted (frames whose plane passed its check).
    pub planes: u32,
    /// Their mean RMS of the board's stripe points about the plane, µm.
    pub rms_mean_um: u32,
    /// The largest of those RMS, µm.
    pub rms_max_um: u32,
}

/// What the head found of the turntable disc in the sweep's laser-off reference frame (after
/// each header, when the head was asked to look for a disc).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct DiscPose {
    /// Scan id.
    pub scan_id: u32,
    /// What was found ([`DiscFound`] as its number).
    pub found: u8,
    /// Disc → camera rotation as a unit quaternion `i, j, k, w` (identity when not found).
    pub rotation: [f32; 4],
    /// The disc's centre in camera coordinates, mm.
    pub translation: [f32; 3],
    /// Dots used for the pose.
    pub markers: u16,
    /// Dots printed.
    pub of: u16,
    /// RMS reprojection error of the used dots, pixels.
    pub rms_px: f32,
}

/// What the head found of the turntable disc ([`DiscPose::found`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum DiscFound {
    /// Found: the pose is good.
    Found = 0,
    /// Too few of its dots were seen (not in view, or hidden).
    TooFewMarkers = 1,
    /// Two turns of the disc fit its visible dots nearly as well.
    Ambiguous = 2,
    /// Seen too nearly edge-on.
    Tilted = 3,
    /// Its dots fit no pose.
    PoorFit = 4,
}

impl DiscFound {
    /// The value of a [`DiscPose::found`] byte; `None` for a value no head sends.
    pub fn from_u8(v: u8) -> Option<DiscFound> {
        [
            DiscFound::Found,
            DiscFound::TooFewMarkers,
            DiscFound::Ambiguous,
            DiscFound::Tilted,
            DiscFound::PoorFit,
        ]
        .into_iter()
        .find(|d| *d as u8 == v)
    }
}

/// What the head tells its operator, as it happens (the host shows it): the prompts of a scan
/// from a camera, which would otherwise reach only the head's own terminal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Notice {
    /// Scan id.
    pub scan_id: u32,
    /// What happened.
    pub kind: NoticeKind,
    /// For [`NoticeKind::SwitchLaserOn`] and [`NoticeKind::NoLaser`]: how long the head waits
    /// for the laser, seconds; 0 otherwise.
    pub seconds: u16,
}

/// What a [`Notice`] says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum NoticeKind {
    /// The head is taking its laser-off reference: keep the laser off.
    TakingReference = 0,
    /// The reference is taken: switch the laser on now.
    SwitchLaserOn = 1,
    /// The laser was seen: the scan counts frames from here.
    LaserSeen = 2,
    /// No laser was seen within the wait: the head stopped (exit status 3).
    NoLaser = 3,
}
wire_enum!(
    NoticeKind,
    TakingReference = 0,
    SwitchLaserOn = 1,
    LaserSeen = 2,
    NoLaser = 3
);

impl NoticeKind {
    /// Its name in reports: `taking_reference`, `switch_laser_on`, `laser_seen`, `no_laser`.
    pub fn name(self) -> &'static str {
        match self {
            NoticeKind::TakingReference => "taking_reference",
            NoticeKind::SwitchLaserOn => "switch_laser_on",
            NoticeKind::LaserSeen => "laser_seen",
            NoticeKind::NoLaser => "no_laser",
        }
    }
}

impl fmt::Display for Notice {
    /// One line for the operator.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            NoticeKind::TakingReference => {
                f.write_str("keep the laser OFF: the head is taking its reference")
            }
            NoticeKind::SwitchLaserOn => write!(
                f,
                "reference taken: switch the laser ON now and sweep (the head waits {} s)",
                self.seconds
            ),
            NoticeKind::LaserSeen => f.write_str("laser seen: scanning"),
            NoticeKind::NoLaser => write!(
                f,
                "no laser seen within {} s after the reference: the head stopped; start it again",
                self.seconds
            ),
        }
    }
}

/// Largest thumbnail a [`Preview`] carries, pixels (160 × 120).
pub const PREVIEW_MAX_PIXELS: usize = 160 * 120;
/// Largest thumbnail side, pixels.
pub const PREVIEW_MAX_SIDE: u16 = 255;
/// Most markers a [`Preview`] carries.
pub const PREVIEW_MAX_MARKERS: usize = 256;

/// What the head would make of a preview's frame ([`Preview::state`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum PreviewState {
    /// The frame gives points ([`Preview::points`] of them).
    Points = 0,
    /// The frame would be skipped, for [`Preview::skip`].
    Skipped = 1,
    /// The head has no calibration: it cannot tell.
    NoCalibration = 2,
    /// The reference shows the laser: switch it off (the head takes the reference again).
    LaserInReference = 3,
}
wire_enum!(
    PreviewState,
    Points = 0,
    Skipped = 1,
    NoCalibration = 2,
    LaserInReference = 3
);

/// A small picture of what the camera sees, with what the head found in it (`scanner-device
/// preview`, about once a second): for aiming, focus and exposure before a scan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Preview<'a> {
    /// Scan (preview session) id.
    pub scan_id: u32,
    /// The frame's number in the session.
    pub frame: u32,
    /// Thumbnail width, pixels (at most [`PREVIEW_MAX_SIDE`]).
    pub width: u16,
    /// Thumbnail height, pixels.
    pub height: u16,
    /// Camera pixels per thumbnail pixel.
    pub scale: u16,
    /// The thumbnail's luma, row by row: `width · height` bytes, at most [`PREVIEW_MAX_PIXELS`].
    #[serde(borrow)]
    pub pixels: &'a [u8],
    /// The dark dots found (board markers, the turntable disc's dots): `x, y` pairs of bytes in
    /// thumbnail pixels, at most [`PREVIEW_MAX_MARKERS`].
    #[serde(borrow)]
    pub markers: &'a [u8],
    /// Which way [`Preview::stripe`] runs: 0 one entry per thumbnail column (a horizontal
    /// line), 1 per row.
    pub axis: u8,
    /// The laser line as found against the reference: its position along each thumbnail column
    /// (or row), thumbnail pixels, 255 where none; empty without a reference.
    #[serde(borrow)]
    pub stripe: &'a [u8],
    /// Pixels at 250 or brighter (clipped), per mille of the frame.
    pub clipped_permille: u16,
    /// The light the laser adds over the reference where its line was found, DN (the median
    /// over its lines; 0: no line found).
    pub laser_dn: u16,
    /// What the head would make of the frame.
    pub state: PreviewState,
    /// With [`PreviewState::Skipped`]: the [`Skip`] reason's number.
    pub skip: u8,
    /// With [`PreviewState::Points`]: the points the frame gives.
    pub points: u16,
}

impl Preview<'_> {
    /// Whether the message keeps its own limits (a reader checks before using it).
    pub fn is_consistent(&self) -> bool {
        let pixels = usize::from(self.width) * usize::from(self.height);
        let lines = if self.axis == 0 {
            self.width
        } else {
            self.height
        };
        pixels <= PREVIEW_MAX_PIXELS
            && self.width <= PREVIEW_MAX_SIDE
            && self.height <= PREVIEW_MAX_SIDE
            && self.pixels.len() == pixels
            && self.markers.len().is_multiple_of(2)
            && self.markers.len() <= 2 * PREVIEW_MAX_MARKERS
            && self.axis <= 1
            && (self.stripe.is_empty() || self.stripe.len() == usize::from(lines))
            && usize::from(self.skip) < SKIP_REASONS
    }
}

/// A message.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Message<'a> {
    /// The session header.
    Header(Header),
    /// A frame's points.
    #[serde(borrow)]
    Points(Points<'a>),
    /// Counters.
    Status(Status),
    /// The camera controls (after each header).
    Controls(Controls),
    /// The laser planes' fit since the last status (before each status).
    Planes(Planes),
    /// The turntable disc in the reference frame (after each header, when asked for).
    Disc(DiscPose),
    /// A prompt or an event for the operator.
    Notice(Notice),
    /// A thumbnail of the camera's picture with what the head found in it.
    #[serde(borrow)]
    Preview(Preview<'a>),
}

impl Message<'_> {
    /// The scan the message belongs to.
    pub fn scan_id(&self) -> u32 {
        match self {
            Message::Header(h) => h.scan_id,
            Message::Points(p) => p.scan_id,
            Message::Status(s) => s.scan_id,
            Message::Controls(k) => k.scan_id,
            Message::Planes(p) => p.scan_id,
            Message::Disc(d) => d.scan_id,
            Message::Notice(n) => n.scan_id,
            Message::Preview(p) => p.scan_id,
        }
    }
}

/// Why encoding or decoding failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// The output buffer is too small.
    BufferFull,
    /// The bytes end before the message does.
    Truncated,
    /// Not valid COBS.
    BadCobs,
    /// The CRC does not match.
    BadCrc,
    /// A protocol version this build does not read.
    UnknownVersion(u8),
    /// The payload is not a message of this version.
    BadPayload,
    /// The point data is inconsistent with its count.
    BadPoints,
    /// A frame longer than [`MAX_ENCODED`].
    Oversize,
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BufferFull => f.write_str("output buffer too small"),
            Self::Truncated => f.write_str("data ends inside a message"),
            Self::BadCobs => f.write_str("bad COBS framing"),
            Self::BadCrc => f.write_str("CRC mismatch"),
            Self::UnknownVersion(v) => write!(
                f,
                "unknown protocol version {v} (this build reads 1 and {VERSION})"
            ),
            Self::BadPayload => f.write_str("payload is not a valid message"),
            Self::BadPoints => f.write_str("point data inconsistent with its count"),
            Self::Oversize => write!(f, "frame longer than {MAX_ENCODED} bytes"),
        }
    }
}

impl core::error::Error for WireError {}

/// Encodes `msg` as one delimited frame into `out`, using `scratch` for the unframed bytes;
/// returns the number of bytes written to `out`.
///
/// # Errors
/// [`WireError::BufferFull`] if `scratch` or `out` is too small.
pub fn encode(msg: &Message, scratch: &mut [u8], out: &mut [u8]) -> Result<usize, WireError> {
    let first = scratch.first_mut().ok_or(WireError::BufferFull)?;
    *first = VERSION;
    let body = postcard::to_slice(msg, &mut scratch[1..])
        .map_err(|_| WireError::BufferFull)?
        .len();
    let n = 1 + body;
    let crc = CRC.checksum(&scratch[..n]);
    scratch
        .get_mut(n..n + 4)
        .ok_or(WireError::BufferFull)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = &scratch[..n + 4];
    if out.len() < cobs::max_encoding_length(raw.len()) + 2 {
        return Err(WireError::BufferFull);
    }
    out[0] = 0;
    let len = cobs::encode(raw, &mut out[1..]);
    out[len + 1] = 0;
    Ok(len + 2)
}

/// Decodes one frame's bytes (between delimiters, without the `0x00`) in place.
///
/// # Errors
/// Every [`WireError`] but [`WireError::BufferFull`].
pub fn decode_frame(frame: &mut [u8]) -> Result<Message<'_>, WireError> {
    let n = cobs::decode_in_place(frame).map_err(|_| WireError::BadCobs)?;
    if n < 5 {
        return Err(WireError::Truncated);
    }
    let (body, crc) = frame[..n].split_at(n - 4);
    let want = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if CRC.checksum(body) != want {
        return Err(WireError::BadCrc);
    }
    let body_len = body.len();
    let message = match body[0] {
        VERSION => &frame[1..body_len],
        // Version 1's messages are version 2's but for `Points`, which ended after `rgb`: an
        // empty `uncertainty` (one zero byte, written over the checked CRC) makes it one.
        1 if frame.get(1) == Some(&1) => {
            frame[body_len] = 0;
            &frame[1..=body_len]
        }
        1 => &frame[1..body_len],
        v => return Err(WireError::UnknownVersion(v)),
    };
    let (msg, rest): (Message, _) =
        postcard::take_from_bytes(message).map_err(|_| WireError::BadPayload)?;
    if !rest.is_empty() {
        return Err(WireError::BadPayload);
    }
    if let Message::Preview(p) = &msg
        && !p.is_consistent()
    {
        return Err(WireError::BadPayload);
    }
    if let Message::Points(p) = &msg {
        if !(p.rgb.is_empty() || p.rgb.len() == 3 * p.count as usize) {
            return Err(WireError::BadPoints);
        }
        if !(p.uncertainty.is_empty() || p.uncertainty.len() == p.count as usize) {
            return Err(WireError::BadPoints);
        }
        // Every coordinate takes at least one byte.
        if p.xyz.len() < 3 * p.count as usize {
            return Err(WireError::BadPoints);
        }
    }
    Ok(msg)
}

/// Counts of what a [`Decoder`] saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecodeStats {
    /// Frames decoded.
    pub frames: u64,
    /// Bytes consumed.
    pub bytes: u64,
    /// Frames rejected: bad COBS.
    pub bad_cobs: u64,
    /// Frames rejected: CRC mismatch.
    pub bad_crc: u64,
    /// Frames rejected: unknown version.
    pub bad_version: u64,
    /// Frames rejected: payload not a message, or inconsistent points.
    pub bad_payload: u64,
    /// Frames rejected: longer than the buffer.
    pub oversize: u64,
    /// Frames rejected: too short.
    pub truncated: u64,
}

impl DecodeStats {
    /// All rejected frames.
    pub fn rejected(&self) -> u64 {
        self.bad_cobs
            + self.bad_crc
            + self.bad_version
            + self.bad_payload
            + self.oversize
            + self.truncated
    }
}

/// A streaming decoder with a fixed buffer of `N` bytes: feed it bytes in any chunks; it calls
/// back with every complete frame (decoded, or the reason it was rejected) and resynchronises at
/// the next delimiter after garbage. Never panics on any input.
pub struct Decoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
    stats: DecodeStats,
}

impl<const N: usize> Default for Decoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Decoder<N> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Decoder {
            buf: [0; N],
            len: 0,
            overflow: false,
            stats: DecodeStats {
                frames: 0,
                bytes: 0,
                bad_cobs: 0,
                bad_crc: 0,
                bad_version: 0,
                bad_payload: 0,
                oversize: 0,
                truncated: 0,
            },
        }
    }

    /// What it has seen so far.
    pub fn stats(&self) -> DecodeStats {
        self.stats
    }

    /// Bytes of an unfinished frame held.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Ends the input: an unfinished frame (bytes after the last delimiter, a stream cut
    /// mid-frame) is counted as truncated and dropped. Returns whether there was one.
    pub fn finish(&mut self) -> bool {
        let cut = self.len > 0 || self.overflow;
        if cut {
            self.stats.truncated += 1;
        }
        self.len = 0;
        self.overflow = false;
        cut
    }

    /// Feeds bytes; `f` gets each complete frame in order.
    pub fn feed(&mut self, bytes: &[u8], mut f: impl FnMut(Result<Message<'_>, WireError>)) {
        for &b in bytes {
            self.stats.bytes += 1;
            if b != 0 {
                if self.len < N {
                    self.buf[self.len] = b;
                    self.len += 1;
                } else {
                    self.overflow = true;
                }
                continue;
            }
            // A delimiter: a frame ends (empty ones are ignored).
            let (len, overflow) = (self.len, self.overflow);
            self.len = 0;
            self.overflow = false;
            if overflow {
                self.stats.oversize += 1;
                f(Err(WireError::Oversize));
                continue;
            }
            if len == 0 {
                continue;
            }
            let res = decode_frame(&mut self.buf[..len]);
            match &res {
                Ok(_) => self.stats.frames += 1,
                Err(WireError::BadCobs) => self.stats.bad_cobs += 1,
                Err(WireError::BadCrc) => self.stats.bad_crc += 1,
                Err(WireError::UnknownVersion(_)) => self.stats.bad_version += 1,
                Err(WireError::Truncated) => self.stats.truncated += 1,
                Err(_) => self.stats.bad_payload += 1,
            }
            f(res);
        }
    }
}
