//! The virtual rig as a frame source (the `rig` feature).

use scanner_core::stripe::PixelFormat;
use scanner_rig::{Rig, Scene};

use super::{FrameSource, OwnedFrame, SourceError};

/// The exposure (V4L2 units of 100 µs) and gain at which the rig renders a scene as written;
/// other values scale every pixel's signal in proportion.
pub const RIG_CONTROLS: [(scanner_wire::Adjustable, i32); 2] = [
    (scanner_wire::Adjustable::Exposure, 100),
    (scanner_wire::Adjustable::Gain, 100),
];

/// The controls the rig offers, as a camera lists them: exposure 1–5000 (0.1–500 ms), gain
/// 10–1000.
pub fn offered() -> Vec<super::controls::CameraControl> {
    use super::controls::{CameraControl, ControlKind, id};
    let c = |id, name: &str, min, max| CameraControl {
        id,
        name: name.into(),
        kind: ControlKind::Integer,
        min,
        max,
        menu: Vec::new(),
        read_only: false,
    };
    vec![
        c(id::EXPOSURE_ABSOLUTE, "exposure_time_absolute", 1, 5000),
        c(id::GAIN, "gain", 10, 1000),
    ]
}

/// The virtual rig as a frame source: its reference, then each frame of its laser sweep.
#[derive(Debug)]
pub struct RigSource {
    rig: Rig,
    format: PixelFormat,
    next: usize,
    /// The scene's sensor gain, before any control set by hand.
    base_gain: f64,
}

impl RigSource {
    /// A source over a built rig, delivering `format`.
    pub fn new(rig: Rig, format: PixelFormat) -> Self {
        Self {
            base_gain: rig.scene().sensor.gain,
            rig,
            format,
            next: 0,
        }
    }

    /// Sets the controls `settings` (by hand, [`RIG_CONTROLS`]' units): the sensor's gain
    /// scales by each one's ratio to the rig's own.
    ///
    /// # Errors
    /// A control the rig has not got, or a value outside its range ([`offered`]).
    pub fn adjust(&mut self, settings: &scanner_wire::ByHand) -> Result<(), SourceError> {
        let mut scale = 1.0;
        for (control, value) in settings.each() {
            super::controls::by_hand(&offered(), control, value)?;
            if let Some((_, own)) = RIG_CONTROLS.iter().find(|(c, _)| *c == control) {
                scale *= f64::from(value) / f64::from(*own);
            }
        }
        let gain = self.base_gain * scale;
        self.rig.set_sensor_gain(gain);
        Ok(())
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
    opts: &super::SourceOptions,
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
    let mut source = RigSource::new(Rig::new(Scene::demo(w, h))?, format);
    source.adjust(&opts.adjust)?;
    Ok(Box::new(source))
}
