//! A scan on the head: frames from a source through [`scanner_core::pipeline::Head`] into
//! point packets on the link, with the session header repeated and status counters.

use std::time::Instant;

use crate::source::SourceError;
use scanner_core::Camera;
use scanner_core::geometry::Board;
use scanner_core::pipeline::{Head, HeadConfig};
use scanner_core::stripe::{Frame, LineStatus, Locate, PixelFormat, StripeConfig};
use scanner_wire::{
    Controls, DiscFound, DiscPose, FixedLaser, Header, Message, Notice, NoticeKind, Planes, Points,
    Skip, Status,
};

use crate::link::Link;
use crate::source::{FrameSource, OwnedFrame};

/// The binary's exit status when the laser never appeared after the reference
/// ([`SessionError::LaserNeverOn`]): a service manager told not to restart on it
/// (`RestartPreventExitStatus=3`) waits for the operator instead of looping.
pub const EXIT_NO_LASER: u8 = 3;

/// Most lines (columns or rows) per frame the head handles.
pub const MAX_LINES: usize = scanner_core::config::MAX_LINES;

/// Settings of a scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanOptions {
    /// The pipeline.
    pub head: HeadConfig,
    /// Repeat the header every this many frames.
    pub header_every: u32,
    /// Send a status every this many frames.
    pub status_every: u32,
    /// Scan id (random per scan unless given).
    pub scan_id: u32,
    /// Find which way the stripe runs from the first laser frame ([`crate::axis::stripe_axis`])
    /// instead of taking `head.stripe.axis`.
    pub find_axis: bool,
    /// Read the laser's colour as the first laser frame shows it
    /// ([`crate::laser_colour::chosen`]) instead of taking `head.stripe.colour`; when not, the
    /// colour taken must fit the frames.
    pub find_colour: bool,
    /// Look for this turntable disc in the reference frame and send its pose after each header.
    pub disc: Option<scanner_calib::disc::Disc>,
    /// A fixed laser over a turning platform (with `head.fixed_plane` its plane): the frames
    /// are dark and laser-only, so no laser-off reference is taken (the light-intensity method
    /// reads each frame alone), and this message follows each header.
    pub fixed: Option<scanner_wire::FixedLaser>,
    /// ArUco markers on the fixed laser's platform: each frame's turn is measured from them
    /// ([`crate::marker_turn`]) and sent before its points.
    pub markers: Option<crate::marker_turn::MarkerPlatform>,
    /// A shadow sweep (no laser: a rod's shadow from a small lamp): the reference is the scene
    /// lit without the shadow, each frame is read as the share of light the shadow takes
    /// ([`scanner_core::stripe::shadow`]), and each of the band's two edges gives a packet with
    /// its own plane — numbered `2 × frame` (the rising edge) and `2 × frame + 1` (the falling).
    pub shadow: bool,
    /// A shadow sweep read through time ([`crate::temporal`]): each pixel placed by the moment
    /// the shadow's edges cross it, its points sent at the sweep's end, a packet per frame and
    /// edge polarity — numbered `2 × frame + polarity`, and from `2 × frames` on where one
    /// holds more than [`scanner_wire::MAX_POINTS`]. Needs the sweep read beforehand (its
    /// brightest and darkest).
    pub temporal: bool,
}

/// Share of a shadow frame's pixels allowed brighter than the shadow-free frame by more than
/// [`BRIGHTER_DN`]: more, and the shadow-free frame held a shadow itself (or the light changed).
pub const MAX_BRIGHTER_SHARE: f64 = 0.005;

/// How much brighter than the shadow-free frame a pixel must be to count against it, DN of
/// luma (several noise σ of a webcam).
pub const BRIGHTER_DN: u8 = 24;

/// Why a scan could not start or go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// A shadow sweep's shadow-free frame is darker than a frame of the sweep over much of the
    /// picture: it holds a shadow itself, or the light changed.
    #[error(
        "frame {frame} of the shadow sweep is brighter than the shadow-free frame over {permille}‰ of the picture (at most {}‰): that frame must show the scene lit with no shadow in it — take it before the rod enters (--reference FILE) or use each pixel's brightest over the sweep (--lit max)",
        (MAX_BRIGHTER_SHARE * 1000.0) as u32
    )]
    ShadowInReference {
        /// The frame, from 0.
        frame: u32,
        /// Its share of brighter pixels, per mille.
        permille: u32,
    },
    /// The camera's frames are not the size the calibration was made at.
    #[error(
        "the calibration is for {}×{} images but the camera gives {}×{}: calibrate at this resolution or choose {}×{}",
        calibrated.0, calibrated.1, camera.0, camera.1, calibrated.0, calibrated.1
    )]
    SizeMismatch {
        /// The calibration's size.
        calibrated: (usize, usize),
        /// The camera's.
        camera: (usize, usize),
    },
    /// More lines per frame than the head's buffers hold.
    #[error("{lines} lines per frame: the head handles at most {MAX_LINES}")]
    TooManyLines {
        /// Lines asked for.
        lines: usize,
    },
    /// A side longer than the wire's `u16`.
    #[error("{0}×{1} images: the wire carries sizes up to 65535")]
    TooLarge(usize, usize),
    /// The reference frame could not be read.
    #[error("the laser-off reference frame")]
    Reference(#[source] SourceError),
    /// The wait for the laser after the reference was stopped, or the source ended or failed.
    #[error("{0}")]
    NoLaser(String),
    /// The laser did not appear within the wait after the reference (the binary's exit status
    /// is then [`EXIT_NO_LASER`], so that a service does not restart in a loop).
    #[error(
        "no laser seen within {seconds} s after the reference: switch the laser on when told, or give --wait-for-laser more seconds"
    )]
    LaserNeverOn {
        /// The wait, seconds.
        seconds: u64,
    },
    /// The first laser frame could not be read.
    #[error("the first laser frame")]
    FirstFrame(#[source] SourceError),
    /// The first laser frame does not tell which way the stripe runs.
    #[error("{0}")]
    Axis(crate::axis::AxisError),
    /// The first laser frame's stripe runs the other way than the direction given.
    #[error(
        "the first laser frame's stripe is a {} line, but {} was given (a {} line): read that way it gives nothing or a wrong model; give {} or leave both out",
        crate::axis::words(*seen).1,
        crate::axis::words(*given).0,
        crate::axis::words(*given).1,
        crate::axis::words(*seen).0
    )]
    AxisContradicts {
        /// The direction given.
        given: scanner_core::stripe::Axis,
        /// The direction the frame shows.
        seen: scanner_core::stripe::Axis,
    },
    /// The first laser frame shows another colour than the one given.
    #[error("{0}")]
    Colour(crate::laser_colour::ColourMismatch),
    /// A message did not fit its buffer (a bug: the buffers are sized for the largest).
    #[error("encoding a message")]
    Encode(#[source] scanner_wire::WireError),
    /// The link failed.
    #[error(transparent)]
    Link(#[from] crate::link::LinkError),
    /// A shadow sweep read through time from a source whose frames were not read beforehand
    /// (a live camera): each pixel's lit and shadowed values are not known.
    #[error(
        "a shadow sweep read through time needs its frames read beforehand for each pixel's lit and shadowed values: record the sweep (--record DIR) and scan the folder"
    )]
    SweepNotRead,
    /// The sweep's frames could not be read through time.
    #[error("the shadow sweep")]
    Temporal(#[from] crate::temporal::TemporalError),
}

pub(crate) type Result<T, E = SessionError> = std::result::Result<T, E>;

/// What the head needs of a calibration: the camera, the board, and the image size both were
/// calibrated at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Intrinsics.
    pub camera: Camera<f64>,
    /// Both board planes.
    pub board: Board<f64>,
    /// Image size, pixels.
    pub size: (u32, u32),
    /// The calibration's modes, when its file keeps the covariances: every point's uncertainty
    /// then carries the calibration's share.
    pub spread: Option<scanner_core::calib::spread::CalibrationSpread>,
    /// The camera's speckle share of a stripe centre's uncertainty, pixels, when measured
    /// (the head's default otherwise).
    pub speckle_px: Option<f32>,
}

/// How a scan went.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanReport {
    /// The final counters (also the last message on the link; its `bytes` counts what was sent
    /// before it).
    pub status: Status,
    /// Bytes sent, the final status included.
    pub bytes: u64,
    /// Point packets dropped because the link was busy.
    pub dropped: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Why the scan ended early, if it did (the camera failed: an error for the command line).
    pub ended_early: Option<String>,
    /// Why the operator's limit stopped it, if one did (Ctrl-C, a signal, `--frames`,
    /// `--duration`: a clean end).
    pub stopped: Option<String>,
    /// The stripe's direction the scan read: along columns (a horizontal line) or rows.
    pub axis: scanner_core::stripe::Axis,
    /// Whether that direction was found from the first laser frame (not given).
    pub axis_found: bool,
    /// The direction the first laser frame's stripe runs, where it tells.
    pub axis_seen: Option<scanner_core::stripe::Axis>,
    /// The laser's colour the scan read with.
    pub colour: scanner_core::stripe::LaserColour,
    /// Whether that colour was found from the first laser frame (not given).
    pub colour_found: bool,
    /// What the first laser frame showed of the laser's colour, where it tells.
    pub colour_seen: Option<crate::laser_colour::ColourSeen>,
    /// What was found of the turntable disc, when the scan looked for one.
    pub disc: Option<DiscOutcome>,
    /// What the platform's markers gave, when the scan measured its turns by them.
    pub markers: Option<crate::marker_turn::MarkerSummary>,
    /// The pipeline's mean time per frame, ms (the head's work on a frame, the wait for the
    /// camera left out).
    pub pipeline_ms: f64,
    /// How the camera's frames arrived, when it numbers them: the frames it made that the head
    /// never took because the pipeline was slower.
    pub pace: Option<crate::source::CameraPace>,
    /// A shadow sweep's bands, when the scan was one.
    pub shadow: Option<ShadowBands>,
    /// Lines refused because their stripe was wider than the frame's limit, and that limit
    /// (pixels: [`scanner_core::stripe::band_limit`]).
    pub beyond_limit: (u64, f32),
    /// A shadow sweep read through time: what it gave.
    pub temporal: Option<crate::temporal::TemporalReport>,
}

/// What a shadow sweep's frames showed of the shadow's band.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ShadowBands {
    /// Lines (over all frames) where a band was found.
    pub lines: u64,
    /// Of them, lines where at least one of its edges was found.
    pub edged: u64,
}

impl ShadowBands {
    /// Fewest band lines over a sweep for [`Self::blurred`] to judge.
    pub const MIN_LINES: u64 = 200;

    /// Whether the band was found but its edges almost never (fewer than one line in 20): its
    /// flanks never pass the level of half the lamp hidden — a lamp too large, or too far from
    /// the rod for the rod's width.
    pub fn blurred(&self) -> bool {
        self.lines >= Self::MIN_LINES && self.edged * 20 < self.lines
    }
}

/// How a scan ends.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ending {
    /// The source ran out of frames.
    Ran,
    /// The operator's limit stopped it (the text says which).
    Stopped(String),
    /// The source failed mid-scan (the text says how).
    Failed(String),
}

/// When a scan stops before its source ends: after a number of frames, a duration, or when a
/// flag is raised (by the Ctrl-C/SIGTERM handler of the command line).
#[derive(Debug, Clone, Default)]
pub struct StopWhen {
    /// Frames taken (after the reference).
    pub frames: Option<u32>,
    /// Time since the first frame.
    pub duration: Option<std::time::Duration>,
    /// Raised from outside (a signal handler).
    pub flag: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Before counting frames, wait up to this long for the laser to appear (a live camera:
    /// the operator switches it on after the reference); frames before it are not scanned.
    pub wait_for_laser: Option<std::time::Duration>,
}

impl StopWhen {
    /// Why to stop now, after `frames` frames and `elapsed` time; `None` to go on.
    pub fn reason(&self, frames: u32, elapsed: std::time::Duration) -> Option<String> {
        if self
            .flag
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst))
        {
            return Some("stopped by a signal (Ctrl-C or SIGTERM)".into());
        }
        if let Some(n) = self.frames
            && frames >= n
        {
            return Some(format!("stopped after {n} frames (--frames)"));
        }
        if let Some(d) = self.duration
            && elapsed >= d
        {
            return Some(format!(
                "stopped after {:.1} s (--duration)",
                d.as_secs_f64()
            ));
        }
        None
    }
}

impl ScanReport {
    /// Most frames saw the stripe on one board sheet only (a laser line that does not cross
    /// the crease, or the stripe read the wrong way).
    pub fn one_sheet_only(&self) -> bool {
        2 * self.status.skipped[scanner_wire::Skip::OnePlaneOnly as usize] > self.status.frames
    }

    /// Bytes on the link per point sent, headers and framing included; `None` when no point
    /// was sent (there is no rate to give).
    pub fn bytes_per_point(&self) -> Option<f64> {
        (self.status.points > 0).then(|| self.bytes as f64 / self.status.points as f64)
    }
}

/// Longest time between two statuses of a sweep that has frames: a slow source (the virtual
/// rig renders a frame in about half a second) still shows its progress every second.
pub const STATUS_AT_MOST_APART: std::time::Duration = std::time::Duration::from_secs(1);

/// One scan's state: the pipeline and its buffers, allocated once.
pub struct Session {
    head: Box<Head<MAX_LINES>>,
    reference: OwnedFrame,
    header: Header,
    /// The camera's controls, sent after each header (not for sources that are no camera).
    controls: Option<Controls>,
    status: Status,
    opts: ScanOptions,
    scratch: Vec<u8>,
    xyz: Vec<u8>,
    started: Instant,
    /// The latest frame's capture time, µs.
    last_us: u64,
    /// The direction the first laser frame's stripe runs, where it tells.
    axis_seen: Option<scanner_core::stripe::Axis>,
    /// What the first laser frame showed of the laser's colour, where it tells.
    colour_seen: Option<crate::laser_colour::ColourSeen>,
    frames_since_header: u32,
    frames_since_status: u32,
    /// When the last status went (the sweep's start before the first).
    last_status: Instant,
    /// The laser planes fitted since the last status: count, RMS sum and largest, mm.
    planes: (u32, f64, f32),
    /// The turntable disc's message, sent after each header, when one was looked for.
    disc: Option<DiscPose>,
    /// What was found of it, for the report.
    disc_found: Option<DiscOutcome>,
    /// A shadow sweep's shadow-free frame, its frame with the lamp's light all hidden (when
    /// known) and the contrast buffer each frame is read into.
    shadow: Option<(OwnedFrame, Option<OwnedFrame>, Vec<u8>)>,
    /// What the shadow sweep's frames showed of the band so far.
    bands: ShadowBands,
    /// The frames' turns measured by the platform's markers, when it carries them.
    marker_turns: Option<crate::marker_turn::MarkerTurns>,
    /// Lines refused as wider than the frame's limit so far, and the limit.
    beyond_limit: (u64, f32),
}

/// What the head found of the turntable disc in the reference frame.
#[derive(Debug, Clone, PartialEq)]
pub enum DiscOutcome {
    /// Found: its pose, dots used of those printed, RMS reprojection error in pixels.
    Found {
        /// Disc → camera.
        pose: scanner_core::geometry::Pose,
        /// Dots used.
        markers: usize,
        /// Dots printed.
        of: usize,
        /// RMS reprojection error, pixels.
        rms_px: f64,
    },
    /// Not found, and why.
    Missed(scanner_calib::disc::DiscMiss),
}

impl DiscOutcome {
    /// The wire message for scan `scan_id`.
    pub fn message(&self, scan_id: u32) -> DiscPose {
        use scanner_calib::disc::DiscMiss;
        match self {
            DiscOutcome::Found {
                pose,
                markers,
                of,
                rms_px,
            } => {
                let q =
                    scanner_core::nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation);
                DiscPose {
                    scan_id,
                    found: DiscFound::Found,
                    rotation: [q.i as f32, q.j as f32, q.k as f32, q.w as f32],
                    translation: pose.translation.map(|v| v as f32).into(),
                    markers: u16::try_from(*markers).unwrap_or(u16::MAX),
                    of: u16::try_from(*of).unwrap_or(u16::MAX),
                    rms_px: *rms_px as f32,
                }
            }
            DiscOutcome::Missed(m) => DiscPose {
                scan_id,
                found: match m {
                    DiscMiss::TooFewMarkers { .. } => DiscFound::TooFewMarkers,
                    DiscMiss::Ambiguous { .. } => DiscFound::Ambiguous,
                    DiscMiss::Tilted { .. } => DiscFound::Tilted,
                    DiscMiss::PoorFit(_) => DiscFound::PoorFit,
                },
                rotation: [0.0, 0.0, 0.0, 1.0],
                ..DiscPose::default()
            },
        }
    }
}

/// Sends a prompt for the operator (waiting for the link: it must arrive).
///
/// # Errors
/// The link failed.
pub(crate) fn prompt(link: &mut Link, scan_id: u32, kind: NoticeKind, seconds: u64) -> Result<()> {
    let n = Notice {
        scan_id,
        kind,
        seconds: u16::try_from(seconds).unwrap_or(u16::MAX),
    };
    encode_to_link(link, &mut [0; 64], &Message::Notice(n), true).map(|_| ())
}

/// The disc found at `pose` (disc → camera) as a known surface for the laser plane: its plane,
/// centre and a radius 3 % inside its cut line (the print's edge may curl). `None` when the pose
/// gives no plane.
fn turntable(
    pose: &scanner_core::geometry::Pose,
    printed: &scanner_calib::disc::Disc,
) -> Option<scanner_core::pipeline::Turntable> {
    let centre = scanner_core::nalgebra::Point3::from(pose.translation);
    let normal = pose.rotation * scanner_core::nalgebra::Vector3::z();
    let plane = scanner_core::geometry::Plane::from_point_normal(&centre, &normal).ok()?;
    Some(scanner_core::pipeline::Turntable {
        plane: plane.cast(),
        centre: centre.cast(),
        radius: (0.97 * printed.radius) as f32,
    })
}

/// Looks for `disc` in the laser-off reference frame (its luma).
fn find_disc(
    reference: &OwnedFrame,
    disc: &scanner_calib::disc::Disc,
    camera: &scanner_core::Camera<f64>,
) -> DiscOutcome {
    let Some(img) = reference.luma() else {
        return DiscOutcome::Missed(scanner_calib::disc::DiscMiss::TooFewMarkers {
            found: 0,
            of: disc.layout().len(),
        });
    };
    match scanner_calib::disc::find_disc(&img, disc, camera) {
        Ok(f) => DiscOutcome::Found {
            pose: f.pose,
            markers: f.used,
            of: f.of,
            rms_px: f.rms_px,
        },
        Err(m) => DiscOutcome::Missed(m),
    }
}

impl Session {
    /// A session for a calibration and the laser-off reference frame.
    ///
    /// # Errors
    /// A calibration for another image size, or more lines than the head handles.
    pub fn new(cal: &Calibration, reference: OwnedFrame, opts: ScanOptions) -> Result<Session> {
        let (w, h) = (cal.size.0 as usize, cal.size.1 as usize);
        // a shadow sweep: the reference is the lit scene; the head reads contrast frames
        // (gray) against black
        let (reference, shadow) = if opts.shadow {
            let black = OwnedFrame {
                data: vec![0; reference.width * reference.height],
                format: PixelFormat::Gray8,
                time_us: None,
                ..reference
            };
            let contrast = vec![0; reference.width * reference.height];
            (black, Some((reference, None, contrast)))
        } else {
            (reference, None)
        };
        if (reference.width, reference.height) != (w, h) {
            return Err(SessionError::SizeMismatch {
                calibrated: (w, h),
                camera: (reference.width, reference.height),
            });
        }
        let lines = match opts.head.stripe.axis {
            scanner_core::stripe::Axis::Columns => w,
            scanner_core::stripe::Axis::Rows => h,
        };
        if lines > MAX_LINES {
            return Err(SessionError::TooManyLines { lines });
        }
        let (camera, board) = (cal.camera, cal.board);
        let (Ok(w16), Ok(h16)) = (u16::try_from(w), u16::try_from(h)) else {
            return Err(SessionError::TooLarge(w, h));
        };
        let header = Header::new(
            opts.scan_id,
            (w16, h16),
            (&camera).into(),
            (&board).into(),
            opts.head.colour,
            opts.head.method,
        );
        let mut config = opts.head;
        if let (Some(s), false) = (cal.speckle_px, opts.shadow) {
            config.stripe.speckle_px = s;
        }
        let mut head = Box::new(Head::new(camera.cast(), board.cast(), config));
        head.set_spread(cal.spread);
        Ok(Session {
            head,
            reference,
            header,
            controls: None,
            status: Status {
                scan_id: opts.scan_id,
                ..Status::default()
            },
            opts,
            scratch: vec![0; scanner_wire::MAX_MESSAGE],
            xyz: vec![0; scanner_wire::MAX_XYZ_BYTES_PER_POINT * MAX_LINES],
            started: Instant::now(),
            last_us: 0,
            axis_seen: None,
            colour_seen: None,
            frames_since_header: 0,
            frames_since_status: 0,
            last_status: Instant::now(),
            planes: (0, 0.0, 0.0),
            disc: None,
            disc_found: None,
            shadow,
            bands: ShadowBands::default(),
            marker_turns: opts
                .markers
                .map(|m| crate::marker_turn::MarkerTurns::new(m, camera)),
            beyond_limit: (0, 0.0),
        })
    }

    /// The session header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The counters so far.
    pub fn status(&self) -> Status {
        let mut s = self.status;
        // By the frames' own times, so that a recording reprocessed gives the same counters.
        let secs = self.last_us as f64 / 1e6;
        s.fps_milli = if secs > 0.0 {
            (f64::from(s.frames) / secs * 1000.0) as u32
        } else {
            0
        };
        s
    }

    /// Encodes `msg` into a link buffer and queues it (`false`: the link is busy and the message
    /// is dropped).
    fn send(&mut self, link: &mut Link, msg: &Message, must: bool) -> Result<bool> {
        let sent = encode_to_link(link, &mut self.scratch, msg, must)?;
        if let Some(n) = sent {
            self.status.bytes += n as u64;
        }
        Ok(sent.is_some())
    }

    /// Sends how well the laser planes since the last status fitted (dropped if the link is
    /// busy: the next one covers its own frames), and starts the next count.
    fn send_planes(&mut self, link: &mut Link) -> Result<()> {
        let (n, sum, max) = std::mem::take(&mut self.planes);
        if n > 0 {
            let um = |mm: f64| (mm * 1000.0).round().clamp(0.0, f64::from(u32::MAX)) as u32;
            let p = Planes {
                scan_id: self.opts.scan_id,
                planes: n,
                rms_mean_um: um(sum / f64::from(n)),
                rms_max_um: um(f64::from(max)),
            };
            self.send(link, &Message::Planes(p), false)?;
        }
        Ok(())
    }

    /// Reports the camera's controls after each header from now on (a source that is no camera
    /// sends none).
    pub fn set_controls(&mut self, controls: Controls) {
        let none = controls
            .named()
            .iter()
            .all(|(_, c)| *c == scanner_wire::Control::NoCamera);
        self.controls = (!none).then_some(Controls {
            scan_id: self.opts.scan_id,
            ..controls
        });
    }

    /// Sends the session header and the camera's controls (dropped if the link is busy: they
    /// repeat).
    ///
    /// # Errors
    /// The link failed.
    pub fn send_header(&mut self, link: &mut Link) -> Result<()> {
        let h = Message::Header(self.header);
        self.send(link, &h, false)?;
        if let Some(k) = self.controls {
            self.send(link, &Message::Controls(k), false)?;
        }
        if let Some(d) = self.disc {
            self.send(link, &Message::Disc(d), false)?;
        }
        if let Some(f) = self.opts.fixed {
            self.send(
                link,
                &Message::FixedLaser(FixedLaser {
                    scan_id: self.opts.scan_id,
                    ..f
                }),
                false,
            )?;
        }
        self.frames_since_header = 0;
        Ok(())
    }

    /// Runs one frame and sends its points. `on_points` sees the frame number and the points
    /// exactly as sent. Returns the skip reason when the frame gave no packet.
    ///
    /// # Errors
    /// The link failed.
    pub fn frame(
        &mut self,
        frame: &OwnedFrame,
        link: &mut Link,
        mut on_points: impl FnMut(u32, &[[i32; 3]]),
    ) -> Result<Option<Skip>> {
        let number = self.status.frames;
        self.status.frames += 1;
        self.frames_since_header += 1;
        self.frames_since_status += 1;
        let time_us = frame
            .time_us
            .unwrap_or_else(|| self.started.elapsed().as_micros() as u64);
        self.last_us = time_us;
        // the platform's turn at this frame, before its points
        if let Some(m) = &mut self.marker_turns
            && let Some(picture) =
                crate::marker_turn::marker_picture(frame, self.opts.head.stripe.colour)
            && let Some(angle) = m.observe(number, &picture)
        {
            let markers = m.turns().last().map_or(0, |t| t.markers);
            let turn = Message::Turn(scanner_wire::MeasuredTurn {
                scan_id: self.opts.scan_id,
                frame: number,
                angle,
                markers: u8::try_from(markers).unwrap_or(u8::MAX),
            });
            self.send(link, &turn, true)?;
        }
        let ready = match &mut self.shadow {
            Some((lit, dark, buf)) => shadow_contrast(frame, (lit, dark.as_ref()), buf, number)?,
            None => true,
        };
        let shadow = self.shadow.is_some();
        let (view, reference) = match &self.shadow {
            Some((_, _, buf)) => (
                Frame::packed(buf, frame.width, frame.height, PixelFormat::Gray8),
                self.reference.view(),
            ),
            None => (frame.view(), self.reference.view()),
        };
        let mut outcome = Some(Skip::BadFrame);
        if ready && let (Ok(f), Ok(r)) = (view, reference) {
            // a laser's centre; a shadow's rising edge, then its falling edge
            for pass in 0..if shadow { 2 } else { 1 } {
                let result = if pass == 0 {
                    self.head.process(&f, Some(&r))
                } else {
                    self.head.again(Locate::FallingEdge, Some(&r))
                };
                let packet = if shadow { 2 * number + pass } else { number };
                let sent = match result {
                    Ok(out) => {
                        self.planes.0 += 1;
                        self.planes.1 += f64::from(out.plane_rms);
                        self.planes.2 = self.planes.2.max(out.plane_rms);
                        let n = scanner_wire::points::encode(out.points, &mut self.xyz)
                            .map_err(SessionError::Encode)?;
                        let msg = Message::Points(Points {
                            scan_id: self.opts.scan_id,
                            frame: packet,
                            time_us,
                            plane: out.plane,
                            count: out.points.len() as u32,
                            xyz: &self.xyz[..n],
                            rgb: out.rgb.as_flattened(),
                            uncertainty: out.uncertainty,
                        });
                        let count = out.points.len() as u64;
                        on_points(packet, out.points);
                        // The head's buffers are borrowed by `msg`: encode before they change.
                        match encode_to_link(link, &mut self.scratch, &msg, false)? {
                            None => {
                                link.count_drop();
                                Some(Skip::LinkFull)
                            }
                            Some(len) => {
                                self.status.bytes += len as u64;
                                self.status.packets += 1;
                                self.status.points += count;
                                None
                            }
                        }
                    }
                    Err(skip) => Some(skip),
                };
                // a frame counts as skipped for the first reason when none of its packets went
                outcome = match (pass, outcome, sent) {
                    (0, _, s) => s,
                    (_, None, _) | (_, _, None) => None,
                    (_, o, _) => o,
                };
            }
            if shadow {
                self.count_bands();
            }
            let ex = self.head.extraction();
            let beyond = ex
                .points
                .iter()
                .filter(|p| p.status == LineStatus::TooWide && p.width > ex.width_limit)
                .count();
            self.beyond_limit = (self.beyond_limit.0 + beyond as u64, ex.width_limit);
        }
        if let Some(s) = outcome {
            self.status.skipped[s as usize] += 1;
        }
        self.repeat_header_and_status(link)?;
        Ok(outcome)
    }

    /// The header again, and the status, when their frames have come.
    fn repeat_header_and_status(&mut self, link: &mut Link) -> Result<()> {
        if self.frames_since_header >= self.opts.header_every {
            self.send_header(link)?;
        }
        // the status every `status_every` frames, after the first frame (the host shows the
        // sweep under way at once) and at least every STATUS_AT_MOST_APART (a slow source)
        if self.frames_since_status >= self.opts.status_every
            || self.status.frames == 1
            || self.last_status.elapsed() >= STATUS_AT_MOST_APART
        {
            self.last_status = Instant::now();
            self.send_planes(link)?;
            let s = Message::Status(self.status());
            self.send(link, &s, false)?;
            self.frames_since_status = 0;
        }
        Ok(())
    }

    /// Counts a frame read by the sweep through time ([`crate::temporal`]): its points go at
    /// the sweep's end.
    fn sweep_frame(&mut self, link: &mut Link) -> Result<()> {
        self.status.frames += 1;
        self.frames_since_header += 1;
        self.frames_since_status += 1;
        self.repeat_header_and_status(link)
    }

    /// Sends points of the sweep through time as packet `number`, waiting for the link
    /// (nothing the sweep found is dropped).
    fn send_sweep_points(
        &mut self,
        link: &mut Link,
        number: u32,
        (time_us, plane): (u64, [f32; 4]),
        points: &[[f32; 3]],
        on_points: &mut impl FnMut(u32, &[[i32; 3]]),
    ) -> Result<()> {
        let q: Vec<[i32; 3]> = points
            .iter()
            .filter_map(|p| {
                Some([
                    scanner_wire::points::quantise(p[0])?,
                    scanner_wire::points::quantise(p[1])?,
                    scanner_wire::points::quantise(p[2])?,
                ])
            })
            .collect();
        let n = scanner_wire::points::encode(&q, &mut self.xyz).map_err(SessionError::Encode)?;
        let msg = Message::Points(Points {
            scan_id: self.opts.scan_id,
            frame: number,
            time_us,
            plane,
            count: q.len() as u32,
            xyz: &self.xyz[..n],
            rgb: &[],
            uncertainty: &[],
        });
        on_points(number, &q);
        if let Some(len) = encode_to_link(link, &mut self.scratch, &msg, true)? {
            self.status.bytes += len as u64;
            self.status.packets += 1;
            self.status.points += q.len() as u64;
        }
        Ok(())
    }

    /// Adds the last frame's band lines to [`ShadowBands`].
    fn count_bands(&mut self) {
        let ex = self.head.extraction();
        let lines = ex.valid().count();
        let edged = ex
            .valid()
            .filter(|(_, p)| p.edges.iter().any(|e| e.is_finite()))
            .count();
        self.bands.lines += lines as u64;
        self.bands.edged += edged as u64;
    }

    /// Sends the final status (waiting for the link) and reports.
    ///
    /// # Errors
    /// The link failed.
    pub fn finish(mut self, link: &mut Link, ending: Ending) -> Result<ScanReport> {
        let mut s = self.status();
        s.done = true;
        let (ended_early, stopped) = match ending {
            Ending::Ran => (None, None),
            Ending::Stopped(why) => {
                s.ended = scanner_wire::EndReason::Stopped;
                (None, Some(why))
            }
            Ending::Failed(why) => {
                s.ended = scanner_wire::EndReason::CameraLost;
                (Some(why), None)
            }
        };
        self.send_planes(link)?;
        let before = self.status.bytes;
        self.send(link, &Message::Status(s), true)?;
        let bytes = self.status.bytes;
        debug_assert!(bytes > before);
        Ok(ScanReport {
            status: s,
            bytes,
            dropped: link.stats().dropped,
            seconds: self.started.elapsed().as_secs_f64(),
            ended_early,
            stopped,
            axis: self.opts.head.stripe.axis,
            axis_found: self.opts.find_axis,
            axis_seen: self.axis_seen,
            colour: self.opts.head.stripe.colour,
            colour_found: self.opts.find_colour,
            colour_seen: self.colour_seen,
            disc: self.disc_found,
            markers: self.marker_turns.as_ref().map(|m| m.summary()),
            pipeline_ms: 0.0,
            pace: None,
            shadow: self.shadow.as_ref().map(|_| self.bands),
            beyond_limit: self.beyond_limit,
            temporal: None,
        })
    }
}

/// Encodes `msg` into a free link buffer (waiting for one if `must`) and queues it; its length,
/// or `None` when every buffer is busy. The one place messages become link bytes.
pub(crate) fn encode_to_link(
    link: &mut Link,
    scratch: &mut [u8],
    msg: &Message,
    must: bool,
) -> Result<Option<usize>> {
    let buf = if must {
        Some(link.buffer_blocking()?)
    } else {
        link.buffer()
    };
    let Some(mut buf) = buf else {
        return Ok(None);
    };
    let n = scanner_wire::encode(msg, scratch, &mut buf).map_err(SessionError::Encode)?;
    link.send(buf, n)?;
    Ok(Some(n))
}

/// Runs a whole scan: reference, header, every frame, final status. A source that fails
/// mid-scan ends the scan cleanly (final status, then the report says why).
///
/// # Errors
/// Calibration problems, the source failing before the first frame, the link failing.
pub fn run_scan(
    source: &mut dyn FrameSource,
    cal: &Calibration,
    opts: ScanOptions,
    link: &mut Link,
    progress: impl FnMut(&Status),
    on_points: impl FnMut(u32, &[[i32; 3]]),
) -> Result<ScanReport> {
    run_scan_until(
        source,
        cal,
        opts,
        link,
        &StopWhen::default(),
        progress,
        on_points,
    )
}

/// [`run_scan`] that also stops when `stop` says so, with a final status saying it was stopped
/// (so that a host waiting for the end, `receive --until-done`, writes its outputs).
///
/// # Errors
/// As [`run_scan`].
pub fn run_scan_until(
    source: &mut dyn FrameSource,
    cal: &Calibration,
    opts: ScanOptions,
    link: &mut Link,
    stop: &StopWhen,
    mut progress: impl FnMut(&Status),
    mut on_points: impl FnMut(u32, &[[i32; 3]]),
) -> Result<ScanReport> {
    // The prompts go to the host too (a head under systemd has no terminal anyone reads).
    let id = opts.scan_id;
    let waits = stop.wait_for_laser;
    if waits.is_some() {
        prompt(link, id, NoticeKind::TakingReference, 0)?;
    }
    let mut first = None;
    let reference = if opts.fixed.is_some() {
        // dark, laser-only frames: nothing to subtract, and a black reference says so
        let frame = source
            .next_frame()
            .map_err(SessionError::FirstFrame)?
            .ok_or_else(|| SessionError::NoLaser("the source gave no frame".into()))?;
        // black: no light, and in YUYV no colour (its chroma bytes at 128, not 0, which
        // would read as a green light added to every pixel)
        let data = match frame.format {
            PixelFormat::Yuyv => [0u8, 128].repeat(frame.data.len() / 2),
            PixelFormat::Gray8 | PixelFormat::Rgb24 => vec![0; frame.data.len()],
        };
        let black = OwnedFrame {
            data,
            time_us: None,
            ..frame.clone()
        };
        first = Some(frame);
        black
    } else {
        source.reference().map_err(SessionError::Reference)?
    };
    if opts.shadow && opts.temporal {
        let dark = source.darkest().ok_or(SessionError::SweepNotRead)?;
        return run_temporal(
            source,
            cal,
            (reference, dark),
            opts,
            link,
            stop,
            progress,
            on_points,
        );
    }
    if let (Some(limit), None, false) = (waits, opts.fixed, opts.shadow) {
        let seconds = limit.as_secs_f64().ceil() as u64;
        prompt(link, id, NoticeKind::SwitchLaserOn, seconds)?;
        match wait_for_laser(source, &reference, limit, stop) {
            Ok(frame) => {
                prompt(link, id, NoticeKind::LaserSeen, 0)?;
                first = Some(frame);
            }
            Err(Waited::TimedOut) => {
                prompt(link, id, NoticeKind::NoLaser, seconds)?;
                return Err(SessionError::LaserNeverOn { seconds });
            }
            Err(Waited::Ended(why)) => return Err(SessionError::NoLaser(why)),
        }
    }
    // a shadow sweep's frame with the lamp's light all hidden, where the source knows it
    let dark = if opts.shadow { source.darkest() } else { None };
    let mut opts = opts;
    // The first laser frame tells which way the stripe runs: the scan reads it that way when
    // asked to find it, and says so when it was told the other way.
    if first.is_none() {
        first = source.next_frame().map_err(SessionError::FirstFrame)?;
    }
    let (mut axis_seen, mut colour_seen) = (None, None);
    if let Some(frame) = &first {
        // a shadow's band shows in its contrast frame, against black
        let contrast = opts
            .shadow
            .then(|| contrast_frames(frame, (&reference, dark.as_ref())))
            .flatten();
        let (frame, reference) = match &contrast {
            Some((f, black)) => (f, black),
            None => (frame, &reference),
        };
        // the laser's colour first (the stripe's direction is found in it), as the light the
        // frame adds shows it (a shadow has none)
        if !opts.shadow {
            colour_seen = crate::laser_colour::seen(frame, reference);
            let given = (!opts.find_colour).then_some(opts.head.stripe.colour);
            let valid = |colour| {
                let stripe = StripeConfig {
                    colour,
                    ..opts.head.stripe
                };
                crate::axis::valid_shares(frame, reference, &stripe).map_or(0.0, |(c, r)| c.max(r))
            };
            opts.head.stripe.colour =
                crate::laser_colour::chosen(given, colour_seen, opts.head.stripe.method, valid)
                    .map_err(SessionError::Colour)?;
        }
        match crate::axis::stripe_axis(frame, reference, &opts.head.stripe) {
            Ok(axis) => axis_seen = Some(axis),
            Err(e) if opts.find_axis => return Err(SessionError::Axis(e)),
            Err(_) => {}
        }
        match axis_seen {
            Some(axis) if opts.find_axis => opts.head.stripe.axis = axis,
            // read across the line it runs along, a stripe gives nothing or a wrong model
            Some(seen) if seen != opts.head.stripe.axis => {
                return Err(SessionError::AxisContradicts {
                    given: opts.head.stripe.axis,
                    seen,
                });
            }
            _ => {}
        }
    }
    let disc = opts.disc.map(|d| find_disc(&reference, &d, &cal.camera));
    let mut session = Session::new(cal, reference, opts)?;
    if let (Some((_, slot, _)), Some(d)) = (&mut session.shadow, dark) {
        *slot = Some(d);
    }
    session.axis_seen = axis_seen;
    session.colour_seen = colour_seen;
    session.disc = disc.as_ref().map(|d| d.message(opts.scan_id));
    if let (Some(DiscOutcome::Found { pose, .. }), Some(printed)) = (&disc, &opts.disc) {
        session.head.set_turntable(turntable(pose, printed));
    }
    session.disc_found = disc;
    session.set_controls(source.controls());
    session.send_header(link)?;
    if let Some(frame) = first {
        session.frame(&frame, link, &mut on_points)?;
        progress(&session.status());
    }
    let (ending, working) = frame_loop(source, &mut session, stop, &mut progress, |s, frame| {
        s.frame(frame, link, &mut on_points).map(|_| ())
    })?;
    let mut report = session.finish(link, ending)?;
    report.pipeline_ms = mean_ms(working, report.status.frames);
    report.pace = source.pace();
    Ok(report)
}

/// Takes frames from `source` through `each` until the stop or the source's end, saying the
/// progress after each and the camera's dropped frames as they happen; returns how it ended and
/// the time spent in `each`.
fn frame_loop(
    source: &mut dyn FrameSource,
    session: &mut Session,
    stop: &StopWhen,
    progress: &mut impl FnMut(&Status),
    mut each: impl FnMut(&mut Session, &OwnedFrame) -> Result<()>,
) -> Result<(Ending, std::time::Duration)> {
    let started = Instant::now();
    let (mut working, mut dropped_told) = (std::time::Duration::ZERO, 0);
    let ending = loop {
        if let Some(why) = stop.reason(session.status().frames, started.elapsed()) {
            break Ending::Stopped(why);
        }
        match source.next_frame() {
            Ok(Some(frame)) => {
                let t = Instant::now();
                each(session, &frame)?;
                working += t.elapsed();
                source.give_back(frame);
                let s = session.status();
                progress(&s);
                // Frames the camera made while the pipeline was busy: said as they happen.
                if s.frames.is_multiple_of(30)
                    && let Some(pace) = source.pace()
                    && pace.dropped > dropped_told
                {
                    dropped_told = pace.dropped;
                    crate::errln!("{}", pace_line(&pace, mean_ms(working, s.frames)));
                }
            }
            Ok(None) => break Ending::Ran,
            Err(e) => break Ending::Failed(crate::error_chain(&e)),
        }
    };
    Ok((ending, working))
}

/// [`run_scan_until`] for a shadow sweep read through time ([`crate::temporal`]): every frame
/// read, then the points of the pixels it placed, a packet per frame and edge polarity.
#[allow(clippy::too_many_arguments)]
fn run_temporal(
    source: &mut dyn FrameSource,
    cal: &Calibration,
    (lit, dark): (OwnedFrame, OwnedFrame),
    opts: ScanOptions,
    link: &mut Link,
    stop: &StopWhen,
    mut progress: impl FnMut(&Status),
    mut on_points: impl FnMut(u32, &[[i32; 3]]),
) -> Result<ScanReport> {
    let size = (lit.width, lit.height);
    let luma = |f: &OwnedFrame| f.luma().map(image::GrayImage::into_raw).unwrap_or_default();
    let mut sweep = crate::temporal::TemporalSweep::new(
        cal.camera,
        cal.board,
        size,
        &luma(&lit),
        &luma(&dark),
    )?;
    let mut session = Session::new(cal, lit, opts)?;
    session.set_controls(source.controls());
    session.send_header(link)?;
    let mut times = Vec::new();
    let (ending, mut working) =
        frame_loop(source, &mut session, stop, &mut progress, |s, frame| {
            sweep.frame(&luma(frame))?;
            times.push(
                frame
                    .time_us
                    .unwrap_or_else(|| s.started.elapsed().as_micros() as u64),
            );
            s.sweep_frame(link)
        })?;
    let t = Instant::now();
    let (placed, found) = sweep.finish();
    working += t.elapsed();
    let frames = times.len() as u32;
    let mut extra = 2 * frames;
    for bucket in &placed {
        let time = (
            times.get(bucket.frame as usize).copied().unwrap_or(0),
            bucket.plane,
        );
        for (k, chunk) in bucket.points.chunks(scanner_wire::MAX_POINTS).enumerate() {
            let number = if k == 0 {
                2 * bucket.frame + u32::from(bucket.polarity)
            } else {
                extra += 1;
                extra - 1
            };
            session.send_sweep_points(link, number, time, chunk, &mut on_points)?;
        }
    }
    let mut report = session.finish(link, ending)?;
    report.pipeline_ms = mean_ms(working, report.status.frames);
    report.pace = source.pace();
    report.temporal = Some(found);
    Ok(report)
}

/// A shadow sweep's frame as its contrast frame (gray) and a black frame of its size, when the
/// two frames match.
fn contrast_frames(
    frame: &OwnedFrame,
    (lit, dark): (&OwnedFrame, Option<&OwnedFrame>),
) -> Option<(OwnedFrame, OwnedFrame)> {
    let black = OwnedFrame {
        data: vec![0; frame.width * frame.height],
        width: frame.width,
        height: frame.height,
        format: PixelFormat::Gray8,
        index: u64::MAX,
        time_us: None,
    };
    let mut buf = black.data.clone();
    let (f, l) = (frame.view().ok()?, lit.view().ok()?);
    let d = dark.map(OwnedFrame::view).transpose().ok()?;
    scanner_core::stripe::shadow::contrast(&f, (&l, d.as_ref()), &mut buf, BRIGHTER_DN).ok()?;
    let contrast = OwnedFrame {
        data: buf,
        ..black.clone()
    };
    Some((contrast, black))
}

/// Frame `number` of a shadow sweep as the share of light the shadow takes, into `buf`;
/// [`SessionError::ShadowInReference`] when the shadow-free frame `lit` is darker than it over
/// more than [`MAX_BRIGHTER_SHARE`] of the picture. A frame of another shape gives `false` (a
/// broken source: the frame is skipped).
fn shadow_contrast(
    frame: &OwnedFrame,
    (lit, dark): (&OwnedFrame, Option<&OwnedFrame>),
    buf: &mut [u8],
    number: u32,
) -> Result<bool> {
    let (Ok(f), Ok(l)) = (frame.view(), lit.view()) else {
        return Ok(false);
    };
    let Ok(d) = dark.map(OwnedFrame::view).transpose() else {
        return Ok(false);
    };
    let Ok(brighter) =
        scanner_core::stripe::shadow::contrast(&f, (&l, d.as_ref()), buf, BRIGHTER_DN)
    else {
        return Ok(false);
    };
    let share = brighter as f64 / (frame.width * frame.height).max(1) as f64;
    if share > MAX_BRIGHTER_SHARE {
        return Err(SessionError::ShadowInReference {
            frame: number,
            permille: (share * 1000.0).round() as u32,
        });
    }
    Ok(true)
}

/// The mean of `total` over `frames`, ms.
fn mean_ms(total: std::time::Duration, frames: u32) -> f64 {
    total.as_secs_f64() * 1e3 / f64::from(frames.max(1))
}

/// One line on frames the camera made that the head did not take: `pipeline 41.0 ms/frame,
/// camera 33.3 ms: 1 frame in 5 dropped (120 of 600)`.
pub fn pace_line(pace: &crate::source::CameraPace, pipeline_ms: f64) -> String {
    let camera = pace.period_ms().map_or_else(
        || "camera period unknown".to_string(),
        |p| format!("camera {p:.1} ms"),
    );
    let undecodable = match pace.undecodable {
        0 => String::new(),
        n => format!("; {n} frame(s) that did not decode, skipped"),
    };
    match pace.one_in() {
        Some(n) => format!(
            "pipeline {pipeline_ms:.1} ms/frame, {camera}: 1 frame in {n:.1} dropped ({} of {}): use a smaller --size or YUYV{undecodable}",
            pace.dropped,
            pace.dropped + pace.taken
        ),
        None => {
            format!("pipeline {pipeline_ms:.1} ms/frame, {camera}: no frame dropped{undecodable}")
        }
    }
}

/// The rig's true camera and board, as the head takes a calibration (for tests and benches that
/// want the truth, not an estimate; the command line reads `truth-calibration.toml` instead).
///
/// # Panics
/// Never for a rig built from a valid scene (its board's planes meet).
#[cfg(feature = "rig")]
pub fn truth_calibration(rig: &scanner_rig::Rig) -> Calibration {
    let s = rig.scene();
    let [l, r] = rig.board_planes();
    Calibration {
        camera: s.camera,
        board: scanner_core::geometry::Board::new(l, r).expect("the rig's board is valid"),
        size: (s.width, s.height),
        spread: None,
        speckle_px: None,
    }
}

/// Why [`wait_for_laser`] came back without the laser.
enum Waited {
    /// The wait ran out.
    TimedOut,
    /// The operator stopped it, or the source ended or failed (the text says which).
    Ended(String),
}

/// Takes frames until one shows the laser against the reference (on more than
/// [`crate::source::LASER_LINES`] of its lines, as the reference check counts), up to `limit`;
/// that frame, or why none came.
fn wait_for_laser(
    source: &mut dyn FrameSource,
    reference: &OwnedFrame,
    limit: std::time::Duration,
    stop: &StopWhen,
) -> std::result::Result<OwnedFrame, Waited> {
    crate::errln!("waiting for the laser (switch it on and sweep)…");
    let t0 = Instant::now();
    loop {
        if t0.elapsed() > limit {
            return Err(Waited::TimedOut);
        }
        if let Some(why) = stop.reason(0, std::time::Duration::ZERO) {
            return Err(Waited::Ended(why));
        }
        let frame = match source.next_frame() {
            Ok(Some(f)) => f,
            Ok(None) => {
                return Err(Waited::Ended(
                    "the source ended before the laser appeared".into(),
                ));
            }
            Err(e) => {
                return Err(Waited::Ended(format!(
                    "the source failed while waiting for the laser: {}",
                    crate::error_chain(&e)
                )));
            }
        };
        if let Some((lines, total)) = crate::source::stripe_lines(&frame, reference)
            && lines as f64 > crate::source::LASER_LINES * total as f64
        {
            crate::errln!("laser seen: scanning");
            return Ok(frame);
        }
    }
}
