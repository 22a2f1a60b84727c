//! V4L2 cameras through the `v4l` crate: list devices and formats, choose format, resolution
//! and frame rate, set the controls the scan needs ([`super::controls`]: exposure, gain, white
//! balance, focus, power-line frequency — the difference image needs the reference and the laser
//! frames taken alike; what was set, refused and missing is printed), memory-mapped streaming. Buffers are converted by
//! [`super::convert`], which is tested on recorded buffers; this file needs a camera and is
//! exercised only by the ignored hardware test.

use scanner_core::stripe::PixelFormat;

use crate::source::{FrameSource, SourceError, SourceOptions};

#[cfg(feature = "v4l")]
mod imp {
    use std::time::{Duration, Instant};

    use scanner_core::stripe::PixelFormat;
    use scanner_wire as wire;
    use v4l::buffer::Type;
    use v4l::control::{Control, Value};
    use v4l::io::mmap::Stream;
    use v4l::io::traits::CaptureStream;
    use v4l::video::Capture;
    use v4l::{Device, FourCC};

    use crate::source::controls;
    use crate::source::convert::{CameraFormat, Converter};
    use crate::source::{
        CameraPace, FrameSource, OwnedFrame, SourceError, SourceOptions, Verdict,
        laser_off_reference,
    };

    fn cam(path: &str, what: &str, e: std::io::Error) -> SourceError {
        SourceError::Camera {
            device: path.to_string(),
            what: what.to_string(),
            source: Some(e),
        }
    }

    fn refused(path: &str, what: String) -> SourceError {
        SourceError::Camera {
            device: path.to_string(),
            what,
            source: None,
        }
    }

    /// The camera format asked for (`fourcc`), or the first the camera offers of those this head
    /// reads, in order of preference.
    pub(super) fn choose_format(
        path: &str,
        dev: &Device,
        fourcc: Option<&str>,
    ) -> Result<CameraFormat, SourceError> {
        let offered: Vec<[u8; 4]> = dev
            .enum_formats()
            .map_err(|e| cam(path, "cannot list formats", e))?
            .into_iter()
            .map(|d| d.fourcc.repr)
            .collect();
        let wanted = match fourcc {
            Some(s) => {
                Some(CameraFormat::parse(s).map_err(|e| SourceError::BadSpec(e.to_string()))?)
            }
            None => [*b"YUYV", *b"GREY", *b"RGB3", *b"MJPG"]
                .into_iter()
                .filter(|c| offered.contains(c))
                .find_map(CameraFormat::from_fourcc),
        };
        let Some(camera) = wanted else {
            let list: Vec<String> = offered
                .iter()
                .map(|c| String::from_utf8_lossy(c).into_owned())
                .collect();
            return Err(refused(
                path,
                format!(
                    "offers {} but none this head reads (YUYV, GREY, RGB3, MJPG)",
                    list.join(", ")
                ),
            ));
        };
        if !offered.contains(&camera.fourcc()) {
            return Err(refused(
                path,
                format!(
                    "does not offer {}",
                    String::from_utf8_lossy(&camera.fourcc())
                ),
            ));
        }
        Ok(camera)
    }

    /// Sets the format and, if given, the size; refuses a camera that picks something else.
    fn set_format(
        path: &str,
        dev: &Device,
        code: [u8; 4],
        size: Option<(u32, u32)>,
    ) -> Result<v4l::Format, SourceError> {
        let mut fmt = dev
            .format()
            .map_err(|e| cam(path, "cannot read the format", e))?;
        fmt.fourcc = FourCC::new(&code);
        if let Some((w, h)) = size {
            fmt.width = w;
            fmt.height = h;
        }
        let fmt = dev
            .set_format(&fmt)
            .map_err(|e| cam(path, "cannot set the format", e))?;
        if fmt.fourcc.repr != code || size.is_some_and(|(w, h)| (fmt.width, fmt.height) != (w, h)) {
            return Err(refused(
                path,
                format!(
                    "asked for {} {:?}, the camera chose {} {}×{}",
                    String::from_utf8_lossy(&code),
                    size,
                    String::from_utf8_lossy(&fmt.fourcc.repr),
                    fmt.width,
                    fmt.height
                ),
            ));
        }
        Ok(fmt)
    }

    /// The camera's controls as [`controls::Control`]s.
    fn offered(dev: &Device) -> Vec<controls::CameraControl> {
        use v4l::control::{Flags, MenuItem, Type as CType};
        dev.query_controls()
            .unwrap_or_default()
            .into_iter()
            .map(|d| controls::CameraControl {
                id: d.id,
                name: d.name.clone(),
                kind: match d.typ {
                    CType::Integer | CType::Integer64 => controls::ControlKind::Integer,
                    CType::Boolean => controls::ControlKind::Boolean,
                    CType::Menu | CType::IntegerMenu => controls::ControlKind::Menu,
                    _ => controls::ControlKind::Other,
                },
                min: d.minimum,
                max: d.maximum,
                menu: d
                    .items
                    .unwrap_or_default()
                    .into_iter()
                    .map(|(i, item)| {
                        let name = match item {
                            MenuItem::Name(n) => n,
                            MenuItem::Value(v) => v.to_string(),
                        };
                        (i64::from(i), name)
                    })
                    .collect(),
                read_only: d.flags.intersects(Flags::READ_ONLY | Flags::DISABLED),
            })
            .collect()
    }

    /// Sets what the scan needs ([`controls::plan`]) and says what was set, refused and missing:
    /// the report line and the stream's form.
    fn lock_controls(dev: &Device, mains_hz: Option<u32>) -> (String, wire::Controls) {
        let plan = controls::plan(&offered(dev), mains_hz);
        let refused: Vec<(String, String)> = plan
            .settings
            .iter()
            .filter_map(|s| {
                let value = match s.kind {
                    controls::ControlKind::Boolean => Value::Boolean(s.value != 0),
                    _ => Value::Integer(s.value),
                };
                dev.set_control(Control { id: s.id, value })
                    .err()
                    .map(|e| (s.control.clone(), e.to_string()))
            })
            .collect();
        (
            controls::report(&plan, &refused),
            controls::on_wire(&plan, &refused),
        )
    }

    /// The device at `path`, opened.
    pub(super) fn device(path: &str) -> Result<Device, SourceError> {
        Device::with_path(path).map_err(|e| cam(path, "cannot open the device", e))
    }

    /// Sets the controls `settings` by hand ([`controls::by_hand`]), in order.
    pub(super) fn set_by_hand(
        path: &str,
        dev: &Device,
        settings: &wire::ByHand,
    ) -> Result<(), SourceError> {
        if settings.each().next().is_none() {
            return Ok(());
        }
        let offered = offered(dev);
        for (control, value) in settings.each() {
            let s = controls::by_hand(&offered, control, value)?;
            dev.set_control(Control {
                id: s.id,
                value: Value::Integer(s.value),
            })
            .map_err(|e| cam(path, &format!("refused {} {}", s.control, s.value), e))?;
            crate::errln!("{path}: {} set to {} by hand", s.control, s.value);
        }
        Ok(())
    }

    /// A streaming V4L2 camera.
    pub struct V4lSource {
        path: String,
        // Declared before the device: the stream unmaps its buffers first.
        stream: Stream<'static>,
        _device: Device,
        camera: CameraFormat,
        format: PixelFormat,
        size: (usize, usize),
        stride: usize,
        next: u64,
        reference: Option<std::path::PathBuf>,
        reference_frames: usize,
        controls: String,
        locked: wire::Controls,
        /// The camera's sequence numbers and times of the frames taken.
        pace: CameraPace,
        /// Kept across frames: the JPEG decoder.
        converter: Converter,
        /// A frame's buffer given back, reused for the next one.
        spare: Vec<u8>,
    }

    impl V4lSource {
        pub fn open(
            path: &str,
            format: PixelFormat,
            opts: &SourceOptions,
        ) -> Result<Self, SourceError> {
            let dev = device(path)?;
            let camera = choose_format(path, &dev, opts.fourcc.as_deref())?;
            let fmt = set_format(path, &dev, camera.fourcc(), opts.size)?;
            if let Some(fps) = opts.fps {
                dev.set_params(&v4l::video::capture::Parameters::with_fps(fps))
                    .map_err(|e| cam(path, "cannot set the frame rate", e))?;
            }
            let (controls, locked) = lock_controls(&dev, opts.mains_hz);
            crate::errln!("{path}: {controls}");
            set_by_hand(path, &dev, &opts.adjust)?;
            let stream = Stream::with_buffers(&dev, Type::VideoCapture, 4)
                .map_err(|e| cam(path, "cannot start streaming", e))?;
            Ok(V4lSource {
                path: path.to_string(),
                stream,
                _device: dev,
                camera,
                format,
                size: (fmt.width as usize, fmt.height as usize),
                stride: fmt.stride as usize,
                next: 0,
                reference: opts.reference.clone(),
                reference_frames: opts.reference_frames(),
                controls,
                locked,
                pace: CameraPace::default(),
                converter: Converter::new(),
                spare: Vec::new(),
            })
        }

        /// The next frame the camera sends that converts; a frame that does not (a corrupt
        /// MJPEG frame) is skipped and counted, too many in a row fail ([`CameraPace::judge`]).
        fn grab(&mut self, index: u64) -> Result<OwnedFrame, SourceError> {
            let mut data = std::mem::take(&mut self.spare);
            loop {
                let t0 = Instant::now();
                let (buf, meta) = CaptureStream::next(&mut self.stream)
                    .map_err(|e| cam(&self.path, "the camera stopped", e))?;
                if t0.elapsed() > Duration::from_secs(5) {
                    return Err(refused(&self.path, "no frame for more than 5 s".into()));
                }
                let time_us = u64::try_from(meta.timestamp.sec).unwrap_or(0) * 1_000_000
                    + u64::try_from(meta.timestamp.usec).unwrap_or(0);
                self.pace.saw(meta.sequence, time_us);
                let used = (meta.bytesused as usize).min(buf.len());
                let converted = self.converter.convert(
                    self.camera,
                    &buf[..used],
                    self.size.0,
                    self.size.1,
                    self.stride,
                    self.format,
                    &mut data,
                );
                match (self.pace.judge(&converted), converted) {
                    (Verdict::Take, _) => break,
                    (Verdict::Skip { say }, Err(e)) => {
                        if say {
                            crate::errln!(
                                "{}: {} frame(s) skipped so far: {e}",
                                self.path,
                                self.pace.undecodable
                            );
                        }
                    }
                    (_, Err(source)) => {
                        return Err(SourceError::Convert {
                            what: format!("camera {}: a bad buffer", self.path),
                            source,
                        });
                    }
                    (_, Ok(())) => break,
                }
            }
            Ok(OwnedFrame {
                time_us: None,
                data,
                width: self.size.0,
                height: self.size.1,
                format: self.format,
                index,
            })
        }
    }

    impl FrameSource for V4lSource {
        fn describe(&self) -> String {
            format!(
                "{} {}×{} {:?} → {:?}; {}",
                self.path, self.size.0, self.size.1, self.camera, self.format, self.controls
            )
        }
        fn format(&self) -> PixelFormat {
            self.format
        }
        fn controls(&self) -> wire::Controls {
            self.locked
        }
        fn size(&self) -> (usize, usize) {
            self.size
        }
        fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
            if let Some(p) = self.reference.clone() {
                return crate::source::load_frame(&p, self.format, u64::MAX);
            }
            crate::errln!(
                "keep the laser OFF: taking {} reference frames of the scene without it…",
                self.reference_frames
            );
            let frames = (0..self.reference_frames)
                .map(|_| self.grab(u64::MAX))
                .collect::<Result<Vec<_>, _>>()?;
            let reference = laser_off_reference(&frames)?;
            crate::errln!("reference taken: switch the laser ON now and sweep it over the object");
            Ok(reference)
        }
        fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
            let i = self.next;
            self.next += 1;
            self.grab(i).map(Some)
        }
        fn pace(&self) -> Option<CameraPace> {
            Some(self.pace)
        }
        fn give_back(&mut self, frame: OwnedFrame) {
            self.spare = frame.data;
        }
    }

    /// Every V4L2 device with its formats and sizes, one line each.
    pub fn list() -> Vec<String> {
        let mut out = Vec::new();
        for node in v4l::context::enum_devices() {
            let path = node.path().display().to_string();
            let name = node.name().unwrap_or_default();
            let formats = Device::with_path(node.path())
                .and_then(|d| {
                    let fs = d.enum_formats()?;
                    Ok(fs
                        .iter()
                        .map(|f| {
                            let sizes = d
                                .enum_framesizes(f.fourcc)
                                .map(|v| {
                                    v.iter()
                                        .map(|s| s.size.to_string())
                                        .collect::<Vec<_>>()
                                        .join(" ")
                                })
                                .unwrap_or_default();
                            format!("{} [{sizes}]", f.fourcc)
                        })
                        .collect::<Vec<_>>()
                        .join("; "))
                })
                .unwrap_or_else(|e| format!("(cannot query: {e})"));
            out.push(format!("{path}: {name}: {formats}"));
        }
        out
    }
}

/// Opens a V4L2 camera.
///
/// # Errors
/// [`SourceError::Camera`] naming the device and what failed (also when built without V4L2).
pub fn open(
    path: &str,
    format: PixelFormat,
    opts: &SourceOptions,
) -> Result<Box<dyn FrameSource>, SourceError> {
    #[cfg(feature = "v4l")]
    {
        Ok(Box::new(imp::V4lSource::open(path, format, opts)?))
    }
    #[cfg(not(feature = "v4l"))]
    {
        let _ = (format, opts);
        Err(SourceError::Camera {
            device: path.to_string(),
            what: "this build has no V4L2 support (built without the `v4l` feature)".into(),
            source: None,
        })
    }
}

/// Sets a control of the camera at `path` by hand, now (the device opened beside a stream
/// that may run: V4L2 controls are the device's, not the stream's).
///
/// # Errors
/// [`SourceError::Control`]: the camera has no such control or not this value;
/// [`SourceError::Camera`]: the device cannot be opened or refused it.
pub fn adjust(
    path: &str,
    control: scanner_wire::Adjustable,
    value: i32,
) -> Result<(), SourceError> {
    #[cfg(feature = "v4l")]
    {
        let dev = imp::device(path)?;
        let mut one = scanner_wire::ByHand::default();
        one.set(control, value);
        imp::set_by_hand(path, &dev, &one)
    }
    #[cfg(not(feature = "v4l"))]
    {
        let _ = value;
        Err(SourceError::Camera {
            device: path.to_string(),
            what: format!(
                "cannot set its {}: this build has no V4L2 support (built without the `v4l` feature)",
                control.name()
            ),
            source: None,
        })
    }
}

/// The pixel format a camera's frames are read in when none is asked: that of the camera format
/// it would be opened with ([`super::convert::CameraFormat::native`]).
///
/// # Errors
/// As [`open`].
pub fn native_format(path: &str, opts: &SourceOptions) -> Result<PixelFormat, SourceError> {
    #[cfg(feature = "v4l")]
    {
        let dev = imp::device(path)?;
        Ok(imp::choose_format(path, &dev, opts.fourcc.as_deref())?.native())
    }
    #[cfg(not(feature = "v4l"))]
    {
        open(path, PixelFormat::Gray8, opts).map(|s| s.format())
    }
}

/// Every V4L2 device with its formats, one line each (empty without V4L2 support or devices).
pub fn list() -> Vec<String> {
    #[cfg(feature = "v4l")]
    {
        imp::list()
    }
    #[cfg(not(feature = "v4l"))]
    {
        Vec::new()
    }
}
