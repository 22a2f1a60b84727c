//! `scanner-device preview`: what the camera sees, as small pictures on the link with what the
//! head finds in them — the board's dots, the laser line against the reference, clipped pixels,
//! the laser's margin, and (with a calibration) what the scan would make of the frame — so that
//! the operator can aim, focus and set the exposure before a scan. About one picture a second
//! (`every` frames); the frames between are read and dropped, as a camera's queue would.

use std::time::Instant;

use scanner_calib::detect::{DetectConfig, find_markers};
use scanner_core::pipeline::{Head, HeadConfig};
use scanner_core::stripe::{Axis, Extractor, StripeConfig};
use scanner_wire::picture::{PICTURE_MAX_HEIGHT, PICTURE_MAX_WIDTH};
use scanner_wire::{
    EndReason, Message, NoticeKind, PICTURE_MAX_JPEG, PREVIEW_MAX_MARKERS, PREVIEW_MAX_PIXELS,
    PREVIEW_MAX_SIDE, Picture, Preview, PreviewState, Status,
};

use crate::link::Link;
use crate::session::{
    Calibration, MAX_LINES, Result, SessionError, StopWhen, encode_to_link, prompt,
};
use crate::source::{FrameSource, OwnedFrame, SourceError};

/// Settings of a preview.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreviewOptions {
    /// The session's id on the wire.
    pub scan_id: u32,
    /// A picture every this many frames.
    pub every: u32,
    /// The pipeline a scan would run (its stripe settings find the line).
    pub head: HeadConfig,
    /// Find which way the line runs in each picture (else `head.stripe.axis`).
    pub find_axis: bool,
    /// Camera pixels per thumbnail pixel; 0, or less than [`thumbnail_scale`] allows: the
    /// smallest within the preview's limits.
    pub scale: usize,
    /// Also send the picture (a JPEG) of this part of the frame, `x, y, width, height` in
    /// camera pixels (all 0: the whole frame).
    pub picture: Option<[u16; 4]>,
}

/// What one preview found, for the head's own terminal.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewFacts {
    /// The frame's number.
    pub frame: u32,
    /// Dark dots found.
    pub markers: usize,
    /// Lines of the frame where the laser line was found, of all.
    pub lit: (usize, usize),
    /// The laser's light over the reference, DN (median over its lines).
    pub laser_dn: u16,
    /// Clipped pixels, per mille.
    pub clipped_permille: u16,
    /// What the scan would make of the frame.
    pub state: PreviewState,
    /// Its skip reason, or its points.
    pub skip: Option<scanner_wire::Skip>,
    /// Points the frame gives.
    pub points: usize,
}

impl std::fmt::Display for PreviewFacts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "preview of frame {}: {} dots, laser line on {} of {} lines (+{} DN), {:.1} % clipped; ",
            self.frame,
            self.markers,
            self.lit.0,
            self.lit.1,
            self.laser_dn,
            f64::from(self.clipped_permille) / 10.0
        )?;
        match (self.state, self.skip) {
            (PreviewState::Points, _) => write!(f, "a scan takes {} points", self.points),
            (PreviewState::Skipped, Some(s)) => {
                write!(f, "a scan skips it: {}", scanner_io::words::skip_reason(s))
            }
            (PreviewState::Skipped, None) => f.write_str("a scan skips it"),
            (PreviewState::NoCalibration, _) => {
                f.write_str("no calibration: give --calibration to see what a scan makes of it")
            }
            (PreviewState::LaserInReference, _) => f.write_str(
                "the laser was on in the reference: switch it off (the reference is taken again)",
            ),
        }
    }
}

/// How a preview went.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewReport {
    /// Frames read.
    pub frames: u32,
    /// Pictures sent (or dropped when the link was busy).
    pub previews: u32,
    /// Pictures the busy link dropped.
    pub dropped: u32,
    /// Why it stopped, when the operator stopped it.
    pub stopped: Option<String>,
    /// The source's failure, when it failed.
    pub ended_early: Option<String>,
}

/// The reference, or the laser-off frames gathered to take it again.
enum Reference {
    /// Taken, laser off.
    Taken(OwnedFrame),
    /// The laser was on: frames gathered for the next try.
    Again(Vec<OwnedFrame>),
}

/// Runs a preview until the source ends or `stop` says so; ends with a final status.
///
/// # Errors
/// The source failing before the first frame, the link failing.
pub fn run_preview(
    source: &mut dyn FrameSource,
    cal: Option<&Calibration>,
    opts: PreviewOptions,
    link: &mut Link,
    stop: &StopWhen,
    mut each: impl FnMut(&PreviewFacts),
) -> Result<PreviewReport> {
    let camera = stop.wait_for_laser.is_some();
    if camera {
        prompt(link, opts.scan_id, NoticeKind::TakingReference, 0)?;
    }
    let mut reference = match source.reference() {
        Ok(r) => Reference::Taken(r),
        Err(SourceError::LaserInReference { .. }) => Reference::Again(Vec::new()),
        Err(e) => return Err(SessionError::Reference(e)),
    };
    if camera && matches!(reference, Reference::Taken(_)) {
        prompt(link, opts.scan_id, NoticeKind::SwitchLaserOn, 0)?;
    }
    let mut work = Work::new(cal, opts);
    let mut report = PreviewReport {
        frames: 0,
        previews: 0,
        dropped: 0,
        stopped: None,
        ended_early: None,
    };
    let started = Instant::now();
    loop {
        if let Some(why) = stop.reason(report.frames, started.elapsed()) {
            report.stopped = Some(why);
            break;
        }
        let frame = match source.next_frame() {
            Ok(Some(f)) => f,
            Ok(None) => break,
            Err(e) => {
                report.ended_early = Some(crate::error_chain(&e));
                break;
            }
        };
        let number = report.frames;
        report.frames += 1;
        if let Reference::Again(gathered) = &mut reference {
            gathered.push(frame.clone());
            if gathered.len() >= crate::source::REFERENCE_FRAMES {
                match crate::source::laser_off_reference(gathered) {
                    Ok(r) => {
                        reference = Reference::Taken(r);
                        if camera {
                            prompt(link, opts.scan_id, NoticeKind::SwitchLaserOn, 0)?;
                        }
                    }
                    Err(_) => gathered.clear(),
                }
            }
        }
        if !number.is_multiple_of(opts.every) {
            continue;
        }
        let taken = match &reference {
            Reference::Taken(r) => Some(r),
            Reference::Again(_) => None,
        };
        let Some(facts) = work.preview(&frame, taken, number, link)? else {
            report.dropped += 1;
            continue;
        };
        report.previews += 1;
        each(&facts);
    }
    let status = Status {
        scan_id: opts.scan_id,
        frames: report.frames,
        done: true,
        ended: match (&report.stopped, &report.ended_early) {
            (_, Some(_)) => EndReason::CameraLost,
            (Some(_), None) => EndReason::Stopped,
            (None, None) => EndReason::Completed,
        },
        ..Status::default()
    };
    encode_to_link(link, &mut [0; 128], &Message::Status(status), true)?;
    Ok(report)
}

/// A preview's buffers and the pipeline it asks, made once.
struct Work<'c> {
    cal: Option<&'c Calibration>,
    opts: PreviewOptions,
    axis: Axis,
    extractor: Box<Extractor<MAX_LINES>>,
    /// The pipeline a scan would run, for the stripe direction it was built for.
    head: Option<(Axis, Box<Head<MAX_LINES>>)>,
    scratch: Vec<u8>,
}

impl<'c> Work<'c> {
    fn new(cal: Option<&'c Calibration>, opts: PreviewOptions) -> Self {
        Work {
            cal,
            opts,
            axis: opts.head.stripe.axis,
            extractor: Box::new(Extractor::new()),
            head: None,
            scratch: vec![0; scanner_wire::MAX_MESSAGE],
        }
    }

    /// Makes and sends one frame's picture; what it found, or `None` when the link was busy.
    fn preview(
        &mut self,
        frame: &OwnedFrame,
        reference: Option<&OwnedFrame>,
        number: u32,
        link: &mut Link,
    ) -> Result<Option<PreviewFacts>> {
        let Some(luma) = frame.luma() else {
            return Ok(None);
        };
        let (w, h) = (frame.width, frame.height);
        let scale = thumbnail_scale(w, h).max(self.opts.scale);
        let (tw, th) = (w / scale, h / scale);
        let pixels = thumbnail(luma.as_raw(), w, scale, (tw, th));
        let clipped = luma.as_raw().iter().filter(|&&v| v >= 250).count();
        let clipped_permille = (clipped * 1000 / (w * h).max(1)) as u16;
        let markers: Vec<u8> = find_markers(&luma, &DetectConfig::default())
            .blobs
            .iter()
            .take(PREVIEW_MAX_MARKERS)
            .flat_map(|b| {
                let at = |v: f64, n: usize| (v / scale as f64).round().clamp(0.0, (n - 1) as f64);
                [at(b.centre.x, tw) as u8, at(b.centre.y, th) as u8]
            })
            .collect();
        // The line against the reference, and which way it runs.
        if let (true, Some(r)) = (self.opts.find_axis, reference)
            && let Ok(axis) = crate::axis::stripe_axis(frame, r, &self.opts.head.stripe)
        {
            self.axis = axis;
        }
        let cfg = StripeConfig {
            axis: self.axis,
            ..self.opts.head.stripe
        };
        let lines = match self.axis {
            Axis::Columns => w,
            Axis::Rows => h,
        };
        let thumb_lines = lines / scale;
        let mut stripe = Vec::new();
        let mut peaks = Vec::new();
        if let Some(r) = reference
            && let (Ok(f), Ok(rv)) = (frame.view(), r.view())
            && let Ok(found) = self.extractor.extract(&f, Some(&rv), &cfg)
        {
            stripe = vec![u8::MAX; thumb_lines];
            for (line, p) in found.valid() {
                peaks.push(scanner_core::stripe::peak_dn(frame.format, &cfg, p.peak));
                if let Some(s) = stripe.get_mut(line / scale) {
                    *s = (p.centre / scale as f32).round().clamp(0.0, 254.0) as u8;
                }
            }
        }
        peaks.sort_unstable();
        let laser_dn = peaks.get(peaks.len() / 2).copied().unwrap_or(0);
        // What a scan would make of it.
        let (state, skip, points) = match (reference, self.cal) {
            (None, _) => (PreviewState::LaserInReference, None, 0),
            (Some(_), None) => (PreviewState::NoCalibration, None, 0),
            (Some(r), Some(cal)) => {
                let axis = self.axis;
                let config = self.opts.head;
                let (_, head) = self
                    .head
                    .take()
                    .filter(|(a, _)| *a == axis)
                    .unwrap_or_else(|| {
                        let mut config = config;
                        config.stripe.axis = axis;
                        let head = Head::new(cal.camera.cast(), cal.board.cast(), config);
                        (axis, Box::new(head))
                    });
                let head = &mut self.head.insert((axis, head)).1;
                match (frame.view(), r.view()) {
                    (Ok(f), Ok(rv)) => match head.process(&f, Some(&rv)) {
                        Ok(out) => (PreviewState::Points, None, out.points.len()),
                        Err(skip) => (PreviewState::Skipped, Some(skip), 0),
                    },
                    _ => (PreviewState::Skipped, Some(scanner_wire::Skip::BadFrame), 0),
                }
            }
        };
        let msg = Message::Preview(Preview {
            scan_id: self.opts.scan_id,
            frame: number,
            width: tw as u16,
            height: th as u16,
            scale: u16::try_from(scale).unwrap_or(u16::MAX),
            pixels: &pixels,
            markers: &markers,
            axis: u8::from(self.axis == Axis::Rows),
            stripe: &stripe,
            clipped_permille,
            laser_dn,
            state,
            skip: skip.map_or(0, |s| s as u8),
            points: u16::try_from(points).unwrap_or(u16::MAX),
        });
        if encode_to_link(link, &mut self.scratch, &msg, false)?.is_none() {
            return Ok(None);
        }
        if let Some(zoom) = self.opts.picture
            && let Some(p) = picture(&luma, zoom)
        {
            let msg = Message::Picture(Picture {
                scan_id: self.opts.scan_id,
                frame: number,
                x: p.region[0],
                y: p.region[1],
                width: p.region[2],
                height: p.region[3],
                scale: p.scale,
                edge_cpx: p
                    .edge_px
                    .map_or(u16::MAX, |w| (w * 100.0).round().min(65534.0) as u16),
                jpeg: &p.jpeg,
            });
            // a busy link drops the picture, as it drops a preview
            encode_to_link(link, &mut self.scratch, &msg, false)?;
        }
        Ok(Some(PreviewFacts {
            frame: number,
            markers: markers.len() / 2,
            lit: (peaks.len(), lines),
            laser_dn,
            clipped_permille,
            state,
            skip,
            points,
        }))
    }
}

/// A part of the frame made ready to send.
struct Taken {
    /// `x, y, width, height`, camera pixels, within the frame.
    region: [u16; 4],
    scale: u8,
    edge_px: Option<f64>,
    jpeg: Vec<u8>,
}

/// The part `zoom` of a frame (all 0: the whole), averaged down to fit 640 × 480, as a JPEG
/// within [`PICTURE_MAX_JPEG`] (quality 80, else 50), with its [`edge_width`]; `None` when it
/// does not fit even so.
fn picture(luma: &image::GrayImage, zoom: [u16; 4]) -> Option<Taken> {
    let (fw, fh) = luma.dimensions();
    let [x, y, w, h] = zoom.map(u32::from);
    let (x, y) = (x.min(fw.saturating_sub(1)), y.min(fh.saturating_sub(1)));
    let (w, h) = if zoom == [0; 4] {
        (fw, fh)
    } else {
        (w.min(fw - x), h.min(fh - y))
    };
    let crop = image::imageops::crop_imm(luma, x, y, w, h).to_image();
    let scale = (w.div_ceil(u32::from(PICTURE_MAX_WIDTH)))
        .max(h.div_ceil(u32::from(PICTURE_MAX_HEIGHT)))
        .max(1);
    let (pw, ph) = (w / scale, h / scale);
    let small = if scale == 1 {
        crop.clone()
    } else {
        let px = thumbnail(
            crop.as_raw(),
            w as usize,
            scale as usize,
            (pw as usize, ph as usize),
        );
        image::GrayImage::from_raw(pw, ph, px)?
    };
    let jpeg = [80u8, 50].iter().find_map(|&q| {
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, q)
            .encode_image(&small)
            .ok()?;
        (out.len() <= PICTURE_MAX_JPEG).then_some(out)
    })?;
    Some(Taken {
        region: [x, y, w, h].map(|v| u16::try_from(v).unwrap_or(u16::MAX)),
        scale: u8::try_from(scale).ok()?,
        edge_px: edge_width(&crop),
        jpeg,
    })
}

/// How wide the picture's sharpest edges are, pixels: over the strongest 0.5 % of the
/// gradients (Sobel), each pixel's local step (the range of its 17 × 17 neighbourhood) over its
/// gradient, the median. A sharp step measures about 2.5 px (the gradient spans two pixels),
/// one blurred by a Gaussian of σ ≥ 2 px about 2.5 σ (`tests/picture.rs`). `None` on a picture without edges (a range under 24
/// DN).
pub fn edge_width(img: &image::GrayImage) -> Option<f64> {
    /// The neighbourhood's reach: the whole step of an edge blurred by σ up to 4 px.
    const R: u32 = 8;
    let (w, h) = img.dimensions();
    if w < 4 * R || h < 4 * R {
        return None;
    }
    let g = imageproc::gradients::sobel_gradients(img);
    let mut strong: Vec<(u16, u32, u32)> = g
        .enumerate_pixels()
        .filter(|(x, y, _)| *x >= R && *y >= R && *x + R < w && *y + R < h)
        .map(|(x, y, p)| (p.0[0], x, y))
        .collect();
    let n = (strong.len() / 200).clamp(1, 4000);
    if strong.len() < n {
        return None;
    }
    let at = strong.len() - n;
    strong.select_nth_unstable(at);
    let mut widths: Vec<f64> = strong[at..]
        .iter()
        .filter_map(|&(grad, x, y)| {
            let (mut lo, mut hi) = (u8::MAX, 0u8);
            for yy in y - R..=y + R {
                for xx in x - R..=x + R {
                    let v = img.get_pixel(xx, yy).0[0];
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            // the Sobel kernel weighs a one-pixel step's difference by 8 over two pixels
            let per_px = f64::from(grad) / 8.0;
            (hi - lo >= 24 && per_px > 0.0).then(|| f64::from(hi - lo) / per_px)
        })
        .collect();
    if widths.is_empty() {
        return None;
    }
    let mid = widths.len() / 2;
    Some(*widths.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// Camera pixels per thumbnail pixel: the smallest whole number that fits the frame into
/// [`PREVIEW_MAX_PIXELS`] and [`PREVIEW_MAX_SIDE`] (a 1280×960 frame: 8, giving 160×120).
pub fn thumbnail_scale(width: usize, height: usize) -> usize {
    let side = usize::from(PREVIEW_MAX_SIDE);
    (1..)
        .find(|s| {
            let (w, h) = (width / s, height / s);
            w <= side && h <= side && w * h <= PREVIEW_MAX_PIXELS
        })
        .unwrap_or(1)
}

/// The mean of each `scale`×`scale` block of `luma` (rows of `width`): a `size` thumbnail.
fn thumbnail(luma: &[u8], width: usize, scale: usize, size: (usize, usize)) -> Vec<u8> {
    let mut sums = vec![0u32; size.0 * size.1];
    for (y, row) in luma.chunks_exact(width).take(size.1 * scale).enumerate() {
        let out = &mut sums[(y / scale) * size.0..][..size.0];
        for (x, &v) in row[..size.0 * scale].iter().enumerate() {
            out[x / scale] += u32::from(v);
        }
    }
    let n = (scale * scale) as u32;
    sums.into_iter().map(|s| (s / n) as u8).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thumbnails_fit_the_wire_and_average_blocks() {
        for (w, h, s) in [
            (1280, 960, 8),
            (640, 480, 4),
            (1600, 1200, 10),
            (160, 120, 1),
        ] {
            assert_eq!(thumbnail_scale(w, h), s, "{w}×{h}");
        }
        let (w, h) = (1920, 1080);
        let s = thumbnail_scale(w, h);
        assert!((w / s) * (h / s) <= PREVIEW_MAX_PIXELS && w / s <= 255);
        // 4×2 pixels in 2×2 blocks: the blocks' means.
        let luma = [0, 10, 100, 100, 20, 30, 100, 100];
        assert_eq!(thumbnail(&luma, 4, 2, (2, 1)), vec![15, 100]);
    }
}
