//! Recordings: a scan's raw frames kept on disk (`scan --record DIR`) so that the scan can be
//! reprocessed later, with a new calibration, as a frame source (`--source record:DIR`).
//!
//! Layout of `DIR`: `recording.toml` (format version, size, pixel format, the camera's controls), `reference.raw` (the
//! laser-off reference's bytes) and `frames.raw`: per frame, its index and capture time (µs since
//! the source opened) as two little-endian `u64`, then its `width × height × bytes-per-pixel`
//! bytes. Frames are appended as they come; a recording cut by a crash reads up to its last
//! whole frame. Every size is checked against [`MAX_SIDE`] before anything is allocated.

use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use scanner_core::stripe::PixelFormat;
use scanner_wire::Controls;

use super::{FrameSource, OwnedFrame, SourceError};

/// The recording format's version.
pub const VERSION: u32 = 1;

/// The largest side of a recorded frame, pixels (the head's lines).
pub const MAX_SIDE: usize = scanner_core::config::MAX_LINES;

/// What `recording.toml` says.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct Meta {
    version: u32,
    width: usize,
    height: usize,
    format: String,
    /// The camera's controls as the scan set them (none: not a camera), so that a reprocessed
    /// stream reports them as the original did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    controls: Option<Controls>,
}

fn format_name(f: PixelFormat) -> &'static str {
    match f {
        PixelFormat::Gray8 => "gray",
        PixelFormat::Yuyv => "yuyv",
        PixelFormat::Rgb24 => "rgb",
    }
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> SourceError + '_ {
    move |source| SourceError::Folder {
        path: path.to_path_buf(),
        source,
    }
}

fn bad(dir: &Path, why: String) -> SourceError {
    SourceError::Images(format!("recording {}: {why}", dir.display()))
}

/// A source whose frames are written to a recording as they pass (their capture times stamped
/// now, so that the scan and its recording carry the same times).
pub struct Recorder {
    inner: Box<dyn FrameSource>,
    dir: PathBuf,
    frames: BufWriter<std::fs::File>,
    opened: Instant,
}

impl Recorder {
    /// Starts a recording of `inner` in `dir` (created; an existing recording is refused).
    ///
    /// # Errors
    /// The folder cannot be made or written, or already holds a recording.
    pub fn new(inner: Box<dyn FrameSource>, dir: &Path) -> Result<Recorder, SourceError> {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        if dir.join("recording.toml").exists() {
            return Err(SourceError::RecordingExists(dir.to_path_buf()));
        }
        let (width, height) = inner.size();
        let meta = Meta {
            version: VERSION,
            width,
            height,
            format: format_name(inner.format()).into(),
            controls: Some(inner.controls()).filter(|c| *c != Controls::default()),
        };
        let text = toml::to_string(&meta).map_err(|e| bad(dir, e.to_string()))?;
        scanner_io::write_atomic(&dir.join("recording.toml"), text.as_bytes()).map_err(io(dir))?;
        let frames = std::fs::File::create(dir.join("frames.raw")).map_err(io(dir))?;
        Ok(Recorder {
            inner,
            dir: dir.to_path_buf(),
            frames: BufWriter::with_capacity(1 << 20, frames),
            opened: Instant::now(),
        })
    }
}

impl FrameSource for Recorder {
    fn describe(&self) -> String {
        format!(
            "{}, recorded to {}",
            self.inner.describe(),
            self.dir.display()
        )
    }

    fn format(&self) -> PixelFormat {
        self.inner.format()
    }

    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }

    fn controls(&self) -> Controls {
        self.inner.controls()
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let r = self.inner.reference()?;
        scanner_io::write_atomic(&self.dir.join("reference.raw"), &r.data)
            .map_err(io(&self.dir))?;
        Ok(r)
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        let Some(mut f) = self.inner.next_frame()? else {
            self.frames.flush().map_err(io(&self.dir))?;
            return Ok(None);
        };
        let t = *f
            .time_us
            .get_or_insert_with(|| self.opened.elapsed().as_micros() as u64);
        let w = &mut self.frames;
        w.write_all(&f.index.to_le_bytes())
            .and_then(|()| w.write_all(&t.to_le_bytes()))
            .and_then(|()| w.write_all(&f.data))
            .map_err(io(&self.dir))?;
        Ok(Some(f))
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        let _ = self.frames.flush();
    }
}

/// A recording as a frame source: its reference, then its frames with their recorded times.
#[derive(Debug)]
pub struct RecordingSource {
    dir: PathBuf,
    width: usize,
    height: usize,
    format: PixelFormat,
    controls: Controls,
    frames: std::io::BufReader<std::fs::File>,
    scratch: [u8; 16],
}

impl RecordingSource {
    /// Opens a recording.
    ///
    /// # Errors
    /// A missing or unreadable file, another format version, a size beyond [`MAX_SIDE`].
    pub fn open(dir: &Path) -> Result<RecordingSource, SourceError> {
        let text = scanner_io::text_file::read(&dir.join("recording.toml")).map_err(io(dir))?;
        let meta: Meta = toml::from_str(&text).map_err(|e| bad(dir, e.to_string()))?;
        if meta.version != VERSION {
            return Err(bad(
                dir,
                format!(
                    "format version {} (this build reads {VERSION})",
                    meta.version
                ),
            ));
        }
        if !(1..=MAX_SIDE).contains(&meta.width) || !(1..=MAX_SIDE).contains(&meta.height) {
            return Err(bad(
                dir,
                format!(
                    "{}×{} frames: each side must be 1 to {MAX_SIDE}",
                    meta.width, meta.height
                ),
            ));
        }
        let format = match meta.format.as_str() {
            "gray" => PixelFormat::Gray8,
            "yuyv" => PixelFormat::Yuyv,
            "rgb" => PixelFormat::Rgb24,
            other => {
                return Err(bad(
                    dir,
                    format!("pixel format {other:?} (gray, yuyv, rgb)"),
                ));
            }
        };
        let frames = std::fs::File::open(dir.join("frames.raw")).map_err(io(dir))?;
        Ok(RecordingSource {
            dir: dir.to_path_buf(),
            width: meta.width,
            height: meta.height,
            format,
            controls: meta.controls.unwrap_or_default(),
            frames: std::io::BufReader::with_capacity(1 << 20, frames),
            scratch: [0; 16],
        })
    }

    fn frame_bytes(&self) -> usize {
        self.width * self.height * self.format.bytes_per_pixel()
    }
}

impl FrameSource for RecordingSource {
    fn describe(&self) -> String {
        format!(
            "recording {} ({}×{} {})",
            self.dir.display(),
            self.width,
            self.height,
            format_name(self.format)
        )
    }

    fn format(&self) -> PixelFormat {
        self.format
    }

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn controls(&self) -> Controls {
        self.controls
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let path = self.dir.join("reference.raw");
        let mut data = Vec::with_capacity(self.frame_bytes());
        std::fs::File::open(&path)
            .and_then(|f| f.take(self.frame_bytes() as u64 + 1).read_to_end(&mut data))
            .map_err(io(&self.dir))?;
        if data.len() != self.frame_bytes() {
            return Err(bad(
                &self.dir,
                format!(
                    "reference.raw holds {} bytes, a frame is {}",
                    data.len(),
                    self.frame_bytes()
                ),
            ));
        }
        Ok(OwnedFrame {
            data,
            width: self.width,
            height: self.height,
            format: self.format,
            index: u64::MAX,
            time_us: None,
        })
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        let mut data = vec![0u8; self.frame_bytes()];
        let whole = self
            .frames
            .read_exact(&mut self.scratch)
            .and_then(|()| self.frames.read_exact(&mut data));
        match whole {
            Ok(()) => {}
            // The end, or a frame cut by a crash: the recording ends at its last whole frame.
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
            Err(e) => return Err(io(&self.dir)(e)),
        }
        let word = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&self.scratch[i..i + 8]);
            u64::from_le_bytes(b)
        };
        Ok(Some(OwnedFrame {
            data,
            width: self.width,
            height: self.height,
            format: self.format,
            index: word(0),
            time_us: Some(word(8)),
        }))
    }
}
