//! Frame sources: where the head's frames come from. The per-frame pipeline sees only the
//! [`FrameSource`] trait, so it runs the same on a V4L2 camera, image files or the virtual rig.
//!
//! Sources are opened by name, like a camera:
//! - `rig` or `rig:WIDTHxHEIGHT`: the virtual rig's demo scene (default 640×480);
//! - `dir:PATH` (or the path of a folder): the folder's PNG/JPEG images in name order;
//! - `/dev/videoN` (or `v4l:/dev/videoN`): a V4L2 camera ([`crate::v4l_source`]).
//!
//! The reference frame (laser off) is, in this order: the file given with `--reference`; for a
//! folder, its `reference.png` / `reference.jpg` if present; otherwise the average of the first
//! `reference_frames` frames (default 8), which must be taken with the laser off.

use scanner_core::stripe::{Frame, FrameError, PixelFormat};

use crate::rig::{Rig, RigError, Scene};

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
}

impl OwnedFrame {
    /// A borrowed view for the extractor.
    ///
    /// # Errors
    /// [`FrameError`] if the buffer does not match the size (a broken source).
    pub fn view(&self) -> Result<Frame<'_>, FrameError> {
        Frame::packed(&self.data, self.width, self.height, self.format)
    }
}

/// Why a source could not be opened or gave no frame.
#[derive(Debug)]
#[non_exhaustive]
pub enum SourceError {
    /// No source of that name; the text lists the names there are.
    Unknown(String),
    /// The name's parameters are malformed.
    BadSpec(String),
    /// The virtual rig failed.
    Rig(RigError),
    /// An image file or folder could not be read.
    Io(String),
    /// The camera failed or delivered a bad buffer.
    Camera(String),
}

impl std::fmt::Display for SourceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Unknown(name) => write!(
                f,
                "no frame source named {name:?} (known: rig, rig:WIDTHxHEIGHT, dir:FOLDER, /dev/videoN)"
            ),
            Self::BadSpec(what) => write!(f, "bad frame source: {what}"),
            Self::Rig(e) => write!(f, "virtual rig: {e}"),
            Self::Io(e) => write!(f, "image source: {e}"),
            Self::Camera(e) => write!(f, "camera: {e}"),
        }
    }
}

impl std::error::Error for SourceError {}

impl From<RigError> for SourceError {
    fn from(e: RigError) -> Self {
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
}

/// The virtual rig as a frame source: its reference, then each frame of its laser sweep.
#[derive(Debug)]
pub struct RigSource {
    rig: Rig,
    format: PixelFormat,
    next: usize,
}

impl RigSource {
    /// A source over a built rig, delivering `format`.
    pub fn new(rig: Rig, format: PixelFormat) -> Self {
        Self {
            rig,
            format,
            next: 0,
        }
    }

    /// The rig (for ground truth).
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    fn owned(&self, data: Vec<u8>, index: u64) -> OwnedFrame {
        let (width, height) = self.size();
        OwnedFrame {
            data,
            width,
            height,
            format: self.format,
            index,
        }
    }
}

impl FrameSource for RigSource {
    fn describe(&self) -> String {
        let (w, h) = self.size();
        format!(
            "virtual rig {w}×{h} {:?}, {} laser frames",
            self.format,
            self.rig.scene().laser.frames
        )
    }

    fn format(&self) -> PixelFormat {
        self.format
    }

    fn size(&self) -> (usize, usize) {
        (
            self.rig.scene().width as usize,
            self.rig.scene().height as usize,
        )
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let data = self.rig.reference().to_format(self.format);
        Ok(self.owned(data, u64::MAX))
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        if self.next >= self.rig.scene().laser.frames {
            return Ok(None);
        }
        let data = self.rig.frame(self.next)?.to_format(self.format);
        let frame = self.owned(data, self.next as u64);
        self.next += 1;
        Ok(Some(frame))
    }
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
    /// Otherwise average this many first frames (laser off) into the reference (0: default 8).
    pub reference_frames: usize,
}

/// Averages frames of one shape into one.
///
/// # Errors
/// [`SourceError::Camera`] when the frames differ in shape or there are none.
pub fn average(frames: &[OwnedFrame]) -> Result<OwnedFrame, SourceError> {
    let first = frames
        .first()
        .ok_or_else(|| SourceError::Camera("no frames to average into a reference".into()))?;
    if frames.iter().any(|f| {
        (f.width, f.height, f.format) != (first.width, first.height, first.format)
            || f.data.len() != first.data.len()
    }) {
        return Err(SourceError::Camera(
            "reference frames differ in size or format".into(),
        ));
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

/// Reads an image file as a frame in `format`.
///
/// # Errors
/// [`SourceError::Io`] naming the file.
pub fn load_frame(
    path: &std::path::Path,
    format: PixelFormat,
    index: u64,
) -> Result<OwnedFrame, SourceError> {
    let img = image::open(path).map_err(|e| SourceError::Io(format!("{}: {e}", path.display())))?;
    let rgb = img.to_rgb8();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let mut data = Vec::new();
    crate::convert::convert(
        crate::convert::CameraFormat::Rgb3,
        rgb.as_raw(),
        w,
        h,
        3 * w,
        format,
        &mut data,
    )
    .map_err(|e| SourceError::Io(format!("{}: {e}", path.display())))?;
    Ok(OwnedFrame {
        data,
        width: w,
        height: h,
        format,
        index,
    })
}

/// The images of a folder in name order (PNG and JPEG); `reference.*` is the reference frame.
#[derive(Debug)]
pub struct ImageDir {
    dir: std::path::PathBuf,
    files: Vec<std::path::PathBuf>,
    reference: Option<std::path::PathBuf>,
    format: PixelFormat,
    size: (usize, usize),
    next: usize,
    reference_frames: usize,
}

impl ImageDir {
    /// Lists a folder.
    ///
    /// # Errors
    /// [`SourceError::Io`] for an unreadable folder, one without images, or an unreadable first
    /// image.
    pub fn open(
        dir: &std::path::Path,
        format: PixelFormat,
        opts: &SourceOptions,
    ) -> Result<ImageDir, SourceError> {
        let io = |e: std::io::Error| SourceError::Io(format!("{}: {e}", dir.display()));
        let mut files = Vec::new();
        let mut reference = opts.reference.clone();
        for entry in std::fs::read_dir(dir).map_err(io)? {
            let path = entry.map_err(io)?.path();
            let ext = path
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if !matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")) {
                continue;
            }
            if path.file_stem().and_then(|s| s.to_str()) == Some("reference") {
                reference.get_or_insert(path);
                continue;
            }
            files.push(path);
        }
        files.sort();
        let first = files
            .first()
            .ok_or_else(|| SourceError::Io(format!("{}: no PNG or JPEG images", dir.display())))?;
        let f = load_frame(first, format, 0)?;
        Ok(ImageDir {
            dir: dir.to_path_buf(),
            files,
            reference,
            format,
            size: (f.width, f.height),
            next: 0,
            reference_frames: if opts.reference_frames == 0 {
                8
            } else {
                opts.reference_frames
            },
        })
    }
}

impl FrameSource for ImageDir {
    fn describe(&self) -> String {
        format!(
            "{} images in {} ({}×{})",
            self.files.len(),
            self.dir.display(),
            self.size.0,
            self.size.1
        )
    }

    fn format(&self) -> PixelFormat {
        self.format
    }

    fn size(&self) -> (usize, usize) {
        self.size
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let r = match &self.reference {
            Some(p) => load_frame(p, self.format, u64::MAX)?,
            None => {
                let n = self.reference_frames.min(self.files.len());
                let frames = self.files[..n]
                    .iter()
                    .map(|p| load_frame(p, self.format, u64::MAX))
                    .collect::<Result<Vec<_>, _>>()?;
                self.next = n;
                average(&frames)?
            }
        };
        if (r.width, r.height) != self.size {
            return Err(SourceError::Io(format!(
                "the reference is {}×{}, the images {}×{}",
                r.width, r.height, self.size.0, self.size.1
            )));
        }
        Ok(r)
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        let Some(path) = self.files.get(self.next) else {
            return Ok(None);
        };
        let f = load_frame(path, self.format, self.next as u64)?;
        if (f.width, f.height) != self.size {
            return Err(SourceError::Io(format!(
                "{} is {}×{}, the first image {}×{}",
                path.display(),
                f.width,
                f.height,
                self.size.0,
                self.size.1
            )));
        }
        self.next += 1;
        Ok(Some(f))
    }
}

/// Opens a frame source by name (see the module docs), delivering `format`.
///
/// # Errors
/// [`SourceError::Unknown`] for an unknown name, [`SourceError::BadSpec`] for malformed
/// parameters, or the source's own failure.
pub fn open(name: &str, format: PixelFormat) -> Result<Box<dyn FrameSource>, SourceError> {
    open_with(name, format, &SourceOptions::default())
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
        return crate::v4l_source::open(path, format, opts);
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
    let (kind, params) = name.split_once(':').unwrap_or((name, ""));
    match kind {
        "rig" => {
            let (w, h) = if params.is_empty() {
                (640, 480)
            } else {
                let (w, h) = params.split_once('x').ok_or_else(|| {
                    SourceError::BadSpec(format!("{name:?}: expected rig:WIDTHxHEIGHT"))
                })?;
                let parse = |s: &str| {
                    s.parse::<u32>().map_err(|_| {
                        SourceError::BadSpec(format!("{name:?}: {s:?} is not a size in pixels"))
                    })
                };
                (parse(w)?, parse(h)?)
            };
            if format == PixelFormat::Yuyv && w % 2 != 0 {
                return Err(SourceError::BadSpec(format!(
                    "{name:?}: YUYV needs an even width"
                )));
            }
            Ok(Box::new(RigSource::new(
                Rig::new(Scene::demo(w, h))?,
                format,
            )))
        }
        _ => Err(SourceError::Unknown(name.to_string())),
    }
}
