//! Frame sources: where the head's frames come from. The per-frame pipeline sees only the
//! [`FrameSource`] trait, so it runs the same on a V4L2 camera, image files or the virtual rig.
//!
//! Sources are opened by name, like a camera: `rig` or `rig:WIDTHxHEIGHT` is the virtual rig's
//! demo scene (default 640×480). V4L2 devices and image folders come with issue 6.

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
}

impl std::fmt::Display for SourceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Unknown(name) => write!(
                f,
                "no frame source named {name:?} (known: rig, rig:WIDTHxHEIGHT)"
            ),
            Self::BadSpec(what) => write!(f, "bad frame source: {what}"),
            Self::Rig(e) => write!(f, "virtual rig: {e}"),
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

/// Opens a frame source by name (see the module docs), delivering `format`.
///
/// # Errors
/// [`SourceError::Unknown`] for an unknown name, [`SourceError::BadSpec`] for malformed
/// parameters, or the source's own failure.
pub fn open(name: &str, format: PixelFormat) -> Result<Box<dyn FrameSource>, SourceError> {
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
