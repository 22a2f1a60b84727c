//! A calibration shot, judged and kept, and the calibration from the kept shots, in the
//! worker's thread.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use scanner_core::nalgebra::{Point2, Vector2, Vector3};
use scanner_core::stripe::PixelFormat;
use scanner_wire::Message;
use scanner_wire::calibration::{COVER_COLS, Calibrated, ShotTaken};

use crate::calibrate::load_board;

use super::worker::Worker;

impl Worker {
    /// Takes a calibration shot, checks it, keeps it when usable and tells the host; the log's
    /// line and whether it was kept.
    pub(super) fn shot(&self, seq: u32, board: bool, kept: u16) -> Result<(String, bool)> {
        let gray = self.shot_image(board, kept)?;
        let (w, h) = gray.dimensions();
        let mut msg = ShotTaken {
            seq,
            board,
            found: 1,
            kept,
            points: 0,
            cover: 0,
            tilt_deg: [0, 0],
        };
        let line = if board {
            // both sheets identified: the planes themselves are fitted with the camera the
            // calibration finds first (a guessed one would fail the fit's plausibility check)
            let b = load_board(self.args.board_file.as_deref())?;
            let outcome = scanner_calib::board_planes(&gray, &b, &guessed_camera(w, h)?);
            let mut seen = 0;
            for (k, a) in outcome.assignments.iter().enumerate() {
                let Some(a) = a else { continue };
                seen += 1;
                let features = outcome.features(&b, k);
                for i in a.blob_of.iter().flatten() {
                    if let Some(f) = features.get(*i) {
                        let p = f.centre;
                        let (c, r) = ShotTaken::cell(p.x, p.y, w, h);
                        msg.cover |= 1u64 << (r * COVER_COLS + c);
                        msg.points += 1;
                    }
                }
            }
            if seen == 2 {
                msg.found = 0;
                format!("board: {} markers on both sheets", msg.points)
            } else {
                msg.found = if seen == 0 { 1 } else { 2 };
                format!("board not usable: {seen} of its 2 sheets identified")
            }
        } else {
            let target = self.args.target.target()?;
            match scanner_calib::find_grid(&gray, &target) {
                Ok(g) => {
                    msg.found = 0;
                    msg.points = g.found.len() as u16;
                    for (_, p) in &g.found {
                        let (c, r) = ShotTaken::cell(p.x, p.y, w, h);
                        msg.cover |= 1u64 << (r * COVER_COLS + c);
                    }
                    msg.tilt_deg = tilt(&target.points(), &g.found, w, h);
                    format!("target: {} points", msg.points)
                }
                Err(e) => {
                    msg.found = 2;
                    format!("target not usable: {e}")
                }
            }
        };
        let keep = msg.found == 0;
        if keep {
            msg.kept = kept + 1;
            let name = shot_name(board, kept);
            let path = self.args.work.join("shots").join(&name);
            gray.save(&path)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        let mut out = self.out.clone();
        out.send(&Message::Shot(msg)).context("the link failed")?;
        Ok((line, keep))
    }

    /// A shot's picture: the rig's (the target at the next of its poses, or the board), or
    /// the source's next frame.
    pub(super) fn shot_image(&self, board: bool, kept: u16) -> Result<image::GrayImage> {
        // a camera's shot is its next frame whatever it shows: only the rig renders the board
        #[cfg(not(feature = "rig"))]
        let _ = board;
        #[cfg(feature = "rig")]
        if self.scan.source.starts_with("rig") {
            use scanner_rig::target::{Pattern, TargetPose};
            let mut scene = super::super::render::view_of(
                super::super::render::load_scene(self.scan.scene.as_deref())?,
                self.scan.view,
            )?;
            if board {
                // the board's shot is taken before the object and the disc go in front of it
                scene.objects.clear();
                scene.fixed.clear();
                scene.turntable = None;
            }
            let poses = std::mem::take(&mut scene.shots);
            let (camera, width, height) = (scene.camera, scene.width, scene.height);
            let rig = scanner_rig::Rig::new(scene)
                .map_err(|e| anyhow::anyhow!("building the virtual rig: {e}"))?;
            if board {
                return Ok(rig.reference().to_gray_image());
            }
            let scanner_calib::Target::Dots(grid) = self.args.target.target()? else {
                bail!(
                    "the virtual rig's shots show a dot grid: leave out --chessboard-* and --charuco"
                );
            };
            let k = usize::from(kept);
            // the scene's own poses first (a maker's first shots), then the regions the
            // studio's guide asks for, in its order
            let size = [
                (grid.cols - 1) as f64 * grid.pitch + grid.dot,
                (grid.rows - 1) as f64 * grid.pitch + grid.dot,
            ];
            let pose = poses.get(k).copied().unwrap_or_else(|| {
                TargetPose::guided(k - poses.len(), &camera, (width, height), size)
            });
            return Ok(rig
                .shot(&Pattern::from(&grid), &pose, k as u64)
                .image
                .to_gray_image());
        }
        let opts = self.scan.camera.options()?;
        let mut source = crate::source::open_with(&self.scan.source, PixelFormat::Rgb24, &opts)
            .with_context(|| format!("source {}", self.scan.source))?;
        // a source that numbers its frames: the next picture for each shot
        for _ in 0..(if self.scan.source.starts_with("/dev/") {
            0
        } else {
            kept
        }) {
            source.next_frame()?;
        }
        let Some(frame) = source.next_frame()? else {
            bail!("the source {} has no more pictures", self.scan.source);
        };
        let rgb = super::super::capture::to_image(&frame)?;
        Ok(image::DynamicImage::ImageRgb8(rgb).to_luma8())
    }

    /// Calibrates from the kept shots in this process (the camera, then the board's planes;
    /// their lines into `calibrate.log`), then tells the host; the log's line and the new
    /// calibration file when it passed.
    pub(super) fn calibrate(
        &self,
        seq: u32,
        shots: (u16, u16),
    ) -> Result<(String, Option<PathBuf>)> {
        use crate::calibrate::{BoardPlan, IntrinsicsPlan, Said};
        let work = &self.args.work;
        let log_path = work.join("calibrate.log");
        let mut log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .with_context(|| format!("cannot write {}", log_path.display()))?;
        let mut say = |said: Said| {
            let line = match said {
                Said::Line(l) => l,
                Said::Warning(w) => format!("warning: {w}"),
            };
            // the log is for reading later: a line that cannot be written is not worth a refusal
            let _ = writeln!(log, "{line}");
        };
        let camera = work.join("camera.toml");
        let calibration = work.join("calibration.toml");
        let mut msg = Calibrated {
            seq,
            result: 1,
            shots: 0,
            rms_px: f32::NAN,
            halves_px: f32::NAN,
            board_rms_px: f32::NAN,
            board_angle_deg: f32::NAN,
        };
        let intrinsics = IntrinsicsPlan {
            target: self.args.target.target()?,
            images: (0..shots.0)
                .map(|k| work.join("shots").join(shot_name(false, k)))
                .collect(),
            out: camera.clone(),
            overlays: None,
        };
        let mut done = None;
        match guarded(|| crate::calibrate::intrinsics(&intrinsics, &mut say)) {
            Ok(r) => {
                msg.shots = u16::try_from(r.used).unwrap_or(u16::MAX);
                msg.rms_px = r.rms_px.map_or(f32::NAN, |v| v as f32);
                msg.halves_px = r
                    .self_check
                    .as_ref()
                    .and_then(|c| c.halves.as_ref())
                    .map_or(f32::NAN, |h| h.image_rms_px as f32);
                msg.result = 2;
                let board = BoardPlan {
                    board: self.args.board_file.clone(),
                    camera,
                    image: work.join("shots").join(shot_name(true, shots.1 - 1)),
                    out: calibration.clone(),
                    overlay: work.join("calibration-overlay.png"),
                    method: scanner_calib::BoardMethod::LayoutPose,
                };
                match guarded(|| crate::calibrate::board(&board, &mut say)) {
                    Ok(b) => {
                        msg.board_rms_px =
                            b.sheets.iter().map(|s| s.rms_px).fold(f64::NAN, f64::max) as f32;
                        msg.board_angle_deg = b.angle_deg.map_or(f32::NAN, |a| a as f32);
                        msg.result = 0;
                        done = Some(calibration);
                    }
                    Err(e) => say(Said::Line(format!("error: {e:#}"))),
                }
            }
            Err(e) => say(Said::Line(format!("error: {e:#}"))),
        }
        let mut out = self.out.clone();
        out.send(&Message::Calibrated(msg))
            .context("the link failed")?;
        Ok((
            format!(
                "result {} from {} shots, rms {:.3} px (lines in {})",
                msg.result,
                msg.shots,
                msg.rms_px,
                log_path.display()
            ),
            done,
        ))
    }
}

/// A calibration step run so that a panic inside it (a bug) is an error like any other: the
/// host still hears the calibration's outcome, and the service stays up.
fn guarded<T>(step: impl FnOnce() -> Result<T, crate::calibrate::CalibrateError>) -> Result<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(step)) {
        Ok(r) => Ok(r?),
        Err(_) => {
            bail!("the calibration stopped on an internal error (a bug; its message is above)")
        }
    }
}

/// A shot's file name in the work folder's `shots/`.
pub(super) fn shot_name(board: bool, k: u16) -> String {
    if board {
        format!("board-{k:02}.png")
    } else {
        format!("grid-{k:02}.png")
    }
}

/// A camera for checking a board shot before any calibration: a focal length of the picture's
/// larger side, the principal point at its centre, no distortion. Good enough to find the
/// sheets; the planes themselves come from the calibration.
pub(super) fn guessed_camera(w: u32, h: u32) -> Result<scanner_core::Camera<f64>> {
    let f = f64::from(w.max(h));
    scanner_core::Camera::new(
        f,
        f,
        f64::from(w) / 2.0,
        f64::from(h) / 2.0,
        scanner_core::camera::Distortion::none(),
    )
    .map_err(|e| anyhow::anyhow!("a {w}×{h} picture: {e}"))
}

/// The target's tilt about the picture's horizontal and vertical axes, degrees, from the
/// homography of its found points with the [`guessed_camera`].
pub(super) fn tilt(
    layout: &[Point2<f64>],
    found: &[(usize, Point2<f64>)],
    w: u32,
    h: u32,
) -> [i8; 2] {
    let f = f64::from(w.max(h));
    let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
    let (sheet, image): (Vec<Point2<f64>>, Vec<Vector2<f64>>) = found
        .iter()
        .filter_map(|(i, p)| {
            Some((
                *layout.get(*i)?,
                Vector2::new((p.x - cx) / f, (p.y - cy) / f),
            ))
        })
        .unzip();
    let Ok(hm) = scanner_core::geometry::pose::homography(&sheet, &image) else {
        return [0, 0];
    };
    let r1 = Vector3::new(hm[(0, 0)], hm[(1, 0)], hm[(2, 0)]).normalize();
    let r2 = Vector3::new(hm[(0, 1)], hm[(1, 1)], hm[(2, 1)]).normalize();
    let mut n = r1.cross(&r2);
    if n.z > 0.0 {
        n = -n;
    }
    let deg = |v: f64| v.asin().to_degrees().round().clamp(-90.0, 90.0) as i8;
    [deg(-n.y), deg(-n.x)]
}
