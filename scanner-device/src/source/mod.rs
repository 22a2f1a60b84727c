//! Frame sources: where the head's frames come from. The per-frame pipeline sees only the
//! [`FrameSource`] trait, so it runs the same on a V4L2 camera, image files or the virtual rig.
//!
//! Sources are opened by name, like a camera:
//! - `rig` or `rig:WIDTHxHEIGHT`: the virtual rig's demo scene (default 640×480);
//! - `dir:PATH` (or the path of a folder): the folder's PNG/JPEG images in name order;
//! - `/dev/videoN` (or `v4l:/dev/videoN`): a V4L2 camera ([`v4l2`], Linux, the `v4l` feature).
//!
//! The reference frame (laser off) is, in this order: the file given with `--reference`; for a
//! folder, its `reference.png` / `reference.jpg` if present; otherwise the average of the first
//! `reference_frames` frames (default 8), which must be taken with the laser off.

pub mod controls;
pub mod convert;
mod images;
pub mod record;
#[cfg(feature = "rig")]
pub mod rig;
pub mod v4l2;

use scanner_core::stripe::{Frame, FrameError, PixelFormat};

pub use images::{ImageDir, load_frame, native_format as image_format};
#[cfg(feature = "rig")]
pub use rig::RigSource;

/// A frame owned by the caller, rows packed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OwnedFrame {
    /// Pixel bytes.
    pub data: Vec<u8>,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Pixel format.
    pub format: PixelFormat,
    /// Index in the stream (the reference is `u64::MAX`).
    pub index: u64,
    /// When it was captured, µs since the source opened, if the source knows (a recording
    /// replays its frames' times; the scan stamps the others as they arrive).
    pub time_us: Option<u64>,
}

impl OwnedFrame {
    /// Its luma as an image (the first byte of a gray or YUYV pixel, BT.601 of an RGB one);
    /// `None` for a buffer that does not match its size.
    pub fn luma(&self) -> Option<image::GrayImage> {
        let bpp = self.format.bytes_per_pixel();
        let luma: Vec<u8> = self
            .data
            .chunks_exact(bpp)
            .map(|p| match self.format {
                PixelFormat::Rgb24 => scanner_core::colour::luma([p[0], p[1], p[2]]),
                _ => p[0],
            })
            .collect();
        image::GrayImage::from_raw(self.width as u32, self.height as u32, luma)
    }

    /// A borrowed view for the extractor.
    ///
    /// # Errors
    /// [`FrameError`] if the buffer does not match the size (a broken source).
    pub fn view(&self) -> Result<Frame<'_>, FrameError> {
        Frame::packed(&self.data, self.width, self.height, self.format)
    }
}

/// Why a source could not be opened or gave no frame.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SourceError {
    /// No source of that name.
    #[error(
        "no frame source named {0:?} (known: rig, rig:WIDTHxHEIGHT, dir:FOLDER, record:FOLDER, /dev/videoN)"
    )]
    Unknown(String),
    /// The name's parameters are malformed (the text says how).
    #[error("bad frame source: {0}")]
    BadSpec(String),
    /// A recording read in another pixel format than it was recorded in.
    #[error(
        "{name:?} was recorded as {recorded:?}: leave --format out (a recording is read in its own format) or give the same --format"
    )]
    RecordedFormat {
        /// The source's name.
        name: String,
        /// The recording's format.
        recorded: PixelFormat,
    },
    /// A folder of frames without a PNG or JPEG image.
    #[error("{}: no PNG or JPEG images", .0.display())]
    NoImages(std::path::PathBuf),
    /// A folder of frames without a laser-off reference, and too few images to average one.
    #[error(
        "{}: {images} image(s) and no reference: without a laser-off photo the first {averaged} images are averaged into the reference, which leaves none to scan; give --reference FILE (a photo of the same view with the laser off) or put it in the folder as reference.png",
        dir.display()
    )]
    NoReference {
        /// The folder.
        dir: std::path::PathBuf,
        /// Its images.
        images: usize,
        /// Images a reference averages.
        averaged: usize,
    },
    /// A recording into a folder that already holds one.
    #[error("recording {}: already holds a recording: give another folder", .0.display())]
    RecordingExists(std::path::PathBuf),
    /// The virtual rig failed.
    #[cfg(feature = "rig")]
    #[error("virtual rig")]
    Rig(#[source] scanner_rig::RigError),
    /// An image file could not be read or decoded, or is too large.
    #[error(transparent)]
    Image(scanner_io::image_file::ImageFileError),
    /// A folder could not be listed.
    #[error("image folder {}", path.display())]
    Folder {
        /// The folder.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A folder of frames holding several series (names that differ other than by their frame
    /// number: two lasers' frames, or frames and other pictures).
    #[error(
        "{} holds {} series of frames: {}; read one with --series PATTERN",
        dir.display(),
        found.len(),
        images::series_list(found)
    )]
    Series {
        /// The folder.
        dir: std::path::PathBuf,
        /// Each series' pattern and its frames.
        found: Vec<(String, usize)>,
    },
    /// `--series` names no series of the folder.
    #[error(
        "--series {given:?}: {} holds no such series; it holds {}",
        dir.display(),
        images::series_list(found)
    )]
    NoSuchSeries {
        /// The folder.
        dir: std::path::PathBuf,
        /// The pattern given.
        given: String,
        /// Each series' pattern and its frames.
        found: Vec<(String, usize)>,
    },
    /// Images that do not make a scan (none, of different sizes, a reference of another size).
    #[error("{0}")]
    Images(String),
    /// The turntable's motor board failed (its words: `crate::motor::MotorError`).
    #[error("{0}")]
    Motor(String),
    /// A buffer could not be converted to the pipeline's format.
    #[error("{what}")]
    Convert {
        /// Which frame.
        what: String,
        /// Why.
        #[source]
        source: convert::ConvertError,
    },
    /// A camera control set by hand cannot be set (the camera has none, or not this value).
    #[error(transparent)]
    Control(#[from] controls::AdjustError),
    /// The camera failed or delivered a bad buffer.
    #[error("camera {device}: {what}")]
    Camera {
        /// The device.
        device: String,
        /// What failed.
        what: String,
        /// The driver's error, if any.
        #[source]
        source: Option<std::io::Error>,
    },
    /// Reference frames that cannot be averaged.
    #[error("reference frames: {0}")]
    Reference(&'static str),
    /// The laser was on while the reference frames were taken.
    #[error(
        "the laser was on while the laser-off reference was taken: frame {frame} of the {frames} averaged shows a stripe on {lines} of {total} lines; switch the laser off for the reference (or give --reference FILE, a photo without the laser)"
    )]
    LaserInReference {
        /// Which of the averaged frames (from 1).
        frame: usize,
        /// Frames averaged.
        frames: usize,
        /// Its lines with a stripe.
        lines: usize,
        /// Its lines.
        total: usize,
    },
}

#[cfg(feature = "rig")]
impl From<scanner_rig::RigError> for SourceError {
    fn from(e: scanner_rig::RigError) -> Self {
        Self::Rig(e)
    }
}

/// Where frames come from.
pub trait FrameSource {
    /// A short description for logs and the session header.
    fn describe(&self) -> String;
    /// Pixel format of the frames.
    fn format(&self) -> PixelFormat;
    /// Frame size, pixels.
    fn size(&self) -> (usize, usize);
    /// What was done with the camera's controls (a source that is no camera: nothing).
    fn controls(&self) -> scanner_wire::Controls {
        scanner_wire::Controls::default()
    }
    /// The laser-off reference frame.
    ///
    /// # Errors
    /// The source's failure, named.
    fn reference(&mut self) -> Result<OwnedFrame, SourceError>;
    /// The next laser frame, or `None` when the stream has ended.
    ///
    /// # Errors
    /// The source's failure, named.
    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError>;
    /// How a camera's frames arrived (a source that is no camera, or one that does not number
    /// its frames: `None`).
    fn pace(&self) -> Option<CameraPace> {
        None
    }
    /// A frame done with: a source that keeps buffers reuses its memory for the next frame
    /// (a camera then allocates nothing per frame); others drop it.
    fn give_back(&mut self, frame: OwnedFrame) {
        drop(frame);
    }
    /// A shadow sweep's frame with the lamp's light all hidden (each pixel's darkest over the
    /// sweep), where the source knows it; taken once.
    fn darkest(&mut self) -> Option<OwnedFrame> {
        None
    }
    /// How many frames are left, where the source knows (a folder of images, the rig); `None`
    /// for a camera.
    fn frames_left(&self) -> Option<usize> {
        None
    }
}

/// A shadow sweep's source with each pixel's brightest over its frames for the reference (the
/// scene lit without the shadow) and its darkest for [`FrameSource::darkest`] (the lamp's light
/// all hidden); its frames are the ones read beforehand where they were kept, else the
/// source's own, as is everything else.
pub struct Extremes {
    source: Box<dyn FrameSource>,
    brightest: Option<OwnedFrame>,
    darkest: Option<OwnedFrame>,
    kept: Option<std::collections::VecDeque<OwnedFrame>>,
}

/// Most bytes of a sweep's frames kept in memory when it is read beforehand (a sweep beyond it
/// is read from its source again): 256 MiB, a 640×480 colour sweep of 290 frames, a quarter of
/// the smallest Raspberry Pi's memory.
pub const MAX_KEPT_SWEEP: usize = 256 << 20;

impl Extremes {
    /// `source` with the brightest and darkest of its frames (read beforehand), and those
    /// frames in order where they were `kept`.
    pub fn new(
        source: Box<dyn FrameSource>,
        brightest: OwnedFrame,
        darkest: OwnedFrame,
        kept: Option<Vec<OwnedFrame>>,
    ) -> Self {
        Self {
            source,
            brightest: Some(brightest),
            darkest: Some(darkest),
            kept: kept.map(Into::into),
        }
    }
}

impl FrameSource for Extremes {
    fn describe(&self) -> String {
        self.source.describe()
    }
    fn format(&self) -> PixelFormat {
        self.source.format()
    }
    fn size(&self) -> (usize, usize) {
        self.source.size()
    }
    fn controls(&self) -> scanner_wire::Controls {
        self.source.controls()
    }
    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        match self.brightest.take() {
            Some(r) => Ok(r),
            None => self.source.reference(),
        }
    }
    fn darkest(&mut self) -> Option<OwnedFrame> {
        self.darkest.take()
    }
    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        match &mut self.kept {
            Some(kept) => Ok(kept.pop_front()),
            None => self.source.next_frame(),
        }
    }
    fn pace(&self) -> Option<CameraPace> {
        self.source.pace()
    }
    fn give_back(&mut self, frame: OwnedFrame) {
        if self.kept.is_none() {
            self.source.give_back(frame);
        }
    }
    fn frames_left(&self) -> Option<usize> {
        match &self.kept {
            Some(kept) => Some(kept.len()),
            None => self.source.frames_left(),
        }
    }
}

/// How a camera's frames arrived: its sequence numbers tell the frames it made that the head
/// never took (its queue overflowed: the pipeline was slower than the camera), its timestamps
/// its frame period.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CameraPace {
    /// Frames the head took.
    pub taken: u64,
    /// Frames the camera made between them that the head never took.
    pub dropped: u64,
    /// Frames the camera sent that did not decode (a corrupt MJPEG frame): skipped.
    pub undecodable: u64,
    /// Undecodable frames since the last one that decoded.
    undecodable_in_a_row: u32,
    /// The first frame's sequence number and time, µs.
    first: Option<(u32, u64)>,
    /// The latest frame's.
    last: Option<(u32, u64)>,
}

impl CameraPace {
    /// Notes a frame taken: the camera's sequence number and timestamp (µs).
    pub fn saw(&mut self, sequence: u32, time_us: u64) {
        if let Some((seq, _)) = self.last {
            // A sequence that goes back (the camera restarted its count) drops nothing.
            self.dropped += u64::from(sequence.saturating_sub(seq).saturating_sub(1));
        }
        self.taken += 1;
        self.first.get_or_insert((sequence, time_us));
        self.last = Some((sequence, time_us));
    }

    /// The camera's frame period, ms: its timestamps over its sequence numbers (`None` before
    /// two frames, or from a camera whose clock does not move).
    pub fn period_ms(&self) -> Option<f64> {
        let ((s0, t0), (s1, t1)) = (self.first?, self.last?);
        let frames = s1.checked_sub(s0).filter(|&n| n > 0)?;
        let us = t1.checked_sub(t0).filter(|&t| t > 0)?;
        Some(us as f64 / 1000.0 / f64::from(frames))
    }

    /// What to do with a frame that did or did not convert: take it; skip a frame that did
    /// not decode (counted; `say` for the first and every hundredth, to be told), unless it is
    /// the [`MAX_UNDECODABLE_IN_A_ROW`]th in a row; fail on any other error.
    pub fn judge(&mut self, converted: &Result<(), convert::ConvertError>) -> Verdict {
        match converted {
            Ok(()) => {
                self.undecodable_in_a_row = 0;
                Verdict::Take
            }
            Err(convert::ConvertError::Jpeg(_))
                if self.undecodable_in_a_row + 1 < MAX_UNDECODABLE_IN_A_ROW =>
            {
                self.undecodable_in_a_row += 1;
                self.undecodable += 1;
                Verdict::Skip {
                    say: self.undecodable == 1 || self.undecodable.is_multiple_of(100),
                }
            }
            Err(_) => Verdict::Fail,
        }
    }

    /// One frame in how many was dropped (`None`: none was).
    pub fn one_in(&self) -> Option<f64> {
        (self.dropped > 0).then(|| (self.taken + self.dropped) as f64 / self.dropped as f64)
    }
}

/// What [`CameraPace::judge`] says of a camera frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// It converted: use it.
    Take,
    /// It did not decode: skip it, and say so when `say`.
    Skip {
        /// Whether to tell the user (the first, then every hundredth).
        say: bool,
    },
    /// Stop: a buffer of the wrong size, or too many bad frames in a row.
    Fail,
}

/// Undecodable camera frames in a row after which the camera is taken as broken (about a
/// second at 30 frames/s): one bad frame is skipped, a stream of them is an error.
pub const MAX_UNDECODABLE_IN_A_ROW: u32 = 30;

/// Laser-off frames averaged into the reference when no reference image is given.
pub const REFERENCE_FRAMES: usize = 8;

/// Largest width or height the head takes, pixels (the wire's `u16`).
pub const MAX_SIDE: u32 = 65_535;

/// A `WIDTHxHEIGHT` (or `COLSxROWS`) that is not one.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{text:?}: expected WIDTHxHEIGHT with both between 1 and {MAX_SIDE}, like 640x480")]
pub struct SizeError {
    /// What was given.
    pub text: String,
}

/// Parses `WIDTHxHEIGHT` (`x` or `X`), both between 1 and [`MAX_SIDE`]: the one parser of sizes
/// and counts given on the command line or in a source name.
///
/// # Errors
/// [`SizeError`] naming the text.
pub fn parse_size(s: &str) -> Result<(u32, u32), SizeError> {
    let err = || SizeError {
        text: s.chars().take(40).collect(),
    };
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let side = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| (1..=MAX_SIDE).contains(&v))
            .ok_or_else(err)
    };
    Ok((side(w)?, side(h)?))
}

/// How a source is opened (beyond its name and the pixel format).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SourceOptions {
    /// Requested resolution (cameras).
    pub size: Option<(u32, u32)>,
    /// Requested frame rate (cameras).
    pub fps: Option<u32>,
    /// Requested camera format FourCC (`YUYV`, `GREY`, `RGB3`, `MJPG`); the camera's own choice
    /// among these otherwise.
    pub fourcc: Option<String>,
    /// Reference frame from this image file.
    pub reference: Option<std::path::PathBuf>,
    /// Otherwise average this many first frames (laser off) into the reference (0: the
    /// default, [`REFERENCE_FRAMES`]).
    pub reference_frames: usize,
    /// The local mains frequency, Hz (50 or 60), for the camera's power-line filter; the
    /// camera's automatic choice without it.
    pub mains_hz: Option<u32>,
    /// Camera controls set by hand, applied as the source opens (after the automatic modes
    /// are switched off).
    pub adjust: scanner_wire::ByHand,
    /// A folder's frames: only the series of this pattern (the names with their frame number
    /// as `*`: `laser0_*.jpg`), for a folder that holds several ([`SourceError::Series`]).
    pub series: Option<String>,
}

impl SourceOptions {
    /// Frames averaged into the reference.
    pub fn reference_frames(&self) -> usize {
        if self.reference_frames == 0 {
            REFERENCE_FRAMES
        } else {
            self.reference_frames
        }
    }
}

/// Share of a frame's lines on which a stripe means the laser was on.
pub const LASER_LINES: f64 = 0.2;

/// Averages laser-off frames into the reference, after checking that the laser was off: each
/// frame against the average, by the difference method with a white laser (any laser adds
/// light), must not show a stripe on more than [`LASER_LINES`] of its lines (columns or rows). A laser moving
/// over the scene while the frames were taken shows in the frames it lit.
///
/// # Errors
/// [`SourceError::LaserInReference`] naming the frame; as [`average`].
pub fn laser_off_reference(frames: &[OwnedFrame]) -> Result<OwnedFrame, SourceError> {
    let avg = average(frames)?;
    for (i, f) in frames.iter().enumerate() {
        if let Some((lines, total)) = stripe_lines(f, &avg)
            && lines as f64 > LASER_LINES * total as f64
        {
            return Err(SourceError::LaserInReference {
                frame: i + 1,
                frames: frames.len(),
                lines,
                total,
            });
        }
    }
    Ok(avg)
}

/// Lines of `frame` on which the difference method (white laser) finds a peak against
/// `reference`, and the lines, along whichever axis shows more of it (a stripe may run either
/// way across the image); `None` for frames the extractor does not take.
pub fn stripe_lines(frame: &OwnedFrame, reference: &OwnedFrame) -> Option<(usize, usize)> {
    use scanner_core::stripe::{Axis, Extractor, LaserColour, Method, StripeConfig};
    fn view(f: &OwnedFrame) -> Option<scanner_core::stripe::Frame<'_>> {
        scanner_core::stripe::Frame::packed(&f.data, f.width, f.height, f.format).ok()
    }
    let (f, r) = (view(frame)?, view(reference)?);
    let mut ex = Box::new(Extractor::<{ scanner_core::config::MAX_LINES }>::new());
    let mut best: Option<(usize, usize)> = None;
    for (axis, total) in [(Axis::Columns, frame.width), (Axis::Rows, frame.height)] {
        let cfg = StripeConfig {
            colour: LaserColour::White,
            ..StripeConfig::new(Method::Dim, axis)
        };
        let Ok(found) = ex.extract(&f, Some(&r), &cfg) else {
            continue;
        };
        // Any peak above the threshold counts (two lasers make every line "ambiguous").
        let lines = found
            .points
            .iter()
            .filter(|p| p.status != scanner_core::stripe::LineStatus::NoStripe)
            .count();
        if best.is_none_or(|(l, t)| lines * t > l * total) {
            best = Some((lines, total));
        }
    }
    best
}

/// The pixel format a source's frames are read in when none is asked: a camera's as it sends
/// them, an image folder's as its first image (see [`convert::CameraFormat::native`],
/// [`images::native_format`]), a recording's as it was recorded.
///
/// # Errors
/// The source cannot be opened or its first image read.
pub fn native_format(name: &str, opts: &SourceOptions) -> Result<PixelFormat, SourceError> {
    if name.starts_with("/dev/video") || name.starts_with("v4l:") {
        return v4l2::native_format(name.strip_prefix("v4l:").unwrap_or(name), opts);
    }
    if let Some(dir) = name.strip_prefix("record:") {
        return Ok(record::RecordingSource::open(std::path::Path::new(dir))?.format());
    }
    let dir = name.strip_prefix("dir:").unwrap_or(name);
    if std::path::Path::new(dir).is_dir() {
        return ImageDir::native_format(std::path::Path::new(dir), opts.series.as_deref());
    }
    // the virtual rig and unknown names: gray, and `open` names a wrong one
    Ok(PixelFormat::Gray8)
}

/// Averages frames of one shape into one.
///
/// # Errors
/// [`SourceError::Reference`] when the frames differ in shape or there are none.
pub fn average(frames: &[OwnedFrame]) -> Result<OwnedFrame, SourceError> {
    let first = frames.first().ok_or(SourceError::Reference(
        "no frames to average into a reference",
    ))?;
    if frames.iter().any(|f| {
        (f.width, f.height, f.format) != (first.width, first.height, first.format)
            || f.data.len() != first.data.len()
    }) {
        return Err(SourceError::Reference("they differ in size or format"));
    }
    let n = frames.len() as u32;
    let data = (0..first.data.len())
        .map(|i| ((frames.iter().map(|f| u32::from(f.data[i])).sum::<u32>() + n / 2) / n) as u8)
        .collect();
    Ok(OwnedFrame {
        data,
        index: u64::MAX,
        ..first.clone()
    })
}

/// Opens a frame source by name (see the module docs), delivering `format`.
///
/// # Errors
/// [`SourceError::Unknown`] for an unknown name, [`SourceError::BadSpec`] for malformed
/// parameters, or the source's own failure.
pub fn open(name: &str, format: PixelFormat) -> Result<Box<dyn FrameSource>, SourceError> {
    open_with(name, format, &SourceOptions::default())
}

/// Sets a camera control of the source `name` by hand, now where it is a camera (V4L2), or
/// checks it against what the source offers (the virtual rig: exposure and gain, applied as
/// its frames are rendered, [`rig::RIG_CONTROLS`]).
///
/// # Errors
/// [`SourceError::Control`]: no such control, or not this value; [`SourceError::Camera`]: the
/// device cannot be opened or refused the value.
pub fn adjust_control(
    name: &str,
    control: scanner_wire::Adjustable,
    value: i32,
) -> Result<(), SourceError> {
    if name.starts_with("/dev/video") || name.starts_with("v4l:") {
        let path = name.strip_prefix("v4l:").unwrap_or(name);
        return v4l2::adjust(path, control, value);
    }
    #[cfg(feature = "rig")]
    if name.starts_with("rig") {
        return controls::by_hand(&rig::offered(), control, value)
            .map(|_| ())
            .map_err(SourceError::from);
    }
    Err(controls::AdjustError::NotOffered(control.name()).into())
}

/// [`open`] with options.
///
/// # Errors
/// As [`open`].
pub fn open_with(
    name: &str,
    format: PixelFormat,
    opts: &SourceOptions,
) -> Result<Box<dyn FrameSource>, SourceError> {
    if name.starts_with("/dev/video") || name.starts_with("v4l:") {
        let path = name.strip_prefix("v4l:").unwrap_or(name);
        return v4l2::open(path, format, opts);
    }
    if let Some(dir) = name.strip_prefix("record:") {
        let r = record::RecordingSource::open(std::path::Path::new(dir))?;
        if r.format() != format {
            return Err(SourceError::RecordedFormat {
                name: name.to_string(),
                recorded: r.format(),
            });
        }
        return Ok(Box::new(r));
    }
    if let Some(dir) = name.strip_prefix("dir:") {
        return Ok(Box::new(ImageDir::open(
            std::path::Path::new(dir),
            format,
            opts,
        )?));
    }
    if std::path::Path::new(name).is_dir() {
        return Ok(Box::new(ImageDir::open(
            std::path::Path::new(name),
            format,
            opts,
        )?));
    }
    match name.split_once(':').unwrap_or((name, "")) {
        #[cfg(feature = "rig")]
        ("rig", params) => rig::open(name, params, format, opts),
        _ => Err(SourceError::Unknown(name.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::convert::ConvertError;
    use super::{CameraPace, MAX_UNDECODABLE_IN_A_ROW, Verdict};
    use scanner_jpeg::JpegError;

    /// A corrupt MJPEG frame is skipped and counted, never fatal; only a run of them is.
    #[test]
    fn frames_that_do_not_decode_are_skipped_and_counted_until_too_many_in_a_row() {
        let mut p = CameraPace::default();
        let bad = Err(ConvertError::Jpeg(JpegError::NotJpeg));
        assert_eq!(p.judge(&bad), Verdict::Skip { say: true });
        assert_eq!(p.judge(&bad), Verdict::Skip { say: false });
        assert_eq!(p.judge(&Ok(())), Verdict::Take);
        assert_eq!(p.undecodable, 2);
        for _ in 0..MAX_UNDECODABLE_IN_A_ROW - 1 {
            assert!(matches!(p.judge(&bad), Verdict::Skip { .. }));
        }
        assert_eq!(p.judge(&bad), Verdict::Fail);
        // Any other error stops at once.
        let short = Err(ConvertError::OddWidth(3));
        assert_eq!(CameraPace::default().judge(&short), Verdict::Fail);
    }

    /// A 30 frames/s camera (33 333 µs apart) whose frames 3, 4 and 8 the head never took.
    #[test]
    fn a_cameras_sequence_gaps_are_the_frames_dropped_and_its_times_its_period() {
        let mut p = CameraPace::default();
        assert_eq!((p.period_ms(), p.one_in()), (None, None));
        for seq in [0u32, 1, 2, 5, 6, 7, 9] {
            p.saw(seq, 1_000_000 + u64::from(seq) * 33_333);
        }
        assert_eq!((p.taken, p.dropped), (7, 3));
        let period = p.period_ms().unwrap();
        assert!((period - 33.333).abs() < 0.01, "{period}");
        assert!((p.one_in().unwrap() - 10.0 / 3.0).abs() < 1e-9);
        // A camera that restarts its count drops nothing by it.
        p.saw(0, 2_000_000);
        assert_eq!(p.dropped, 3);
    }
}
