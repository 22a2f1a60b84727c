//! The virtual rig as a frame source (the `rig` feature).

use scanner_core::stripe::PixelFormat;
use scanner_rig::{Rig, Scene};

use super::{FrameSource, OwnedFrame, SourceError};

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
            time_us: None,
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

    fn frames_left(&self) -> Option<usize> {
        Some(self.rig.scene().laser.frames.saturating_sub(self.next))
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

/// `rig` or `rig:WIDTHxHEIGHT`: the demo scene at that size (640×480 by default).
pub(super) fn open(
    name: &str,
    params: &str,
    format: PixelFormat,
) -> Result<Box<dyn FrameSource>, SourceError> {
    let (w, h) = if params.is_empty() {
        (640, 480)
    } else {
        super::parse_size(params).map_err(|e| SourceError::BadSpec(format!("{name:?}: {e}")))?
    };
    if format == PixelFormat::Yuyv && w % 2 != 0 {
        return Err(SourceError::BadSpec(format!(
            "{name:?}: YUYV needs an even width"
        )));
    }
    Scene::check_size(w, h).map_err(|e| SourceError::BadSpec(format!("{name:?}: {e}")))?;
    Ok(Box::new(RigSource::new(
        Rig::new(Scene::demo(w, h))?,
        format,
    )))
}
