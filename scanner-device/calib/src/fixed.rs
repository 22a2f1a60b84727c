//! A turntable scanner with fixed lasers (FabScanPi, Ciclop): its laser planes and platform
//! from the scanner's own calibration frames, and any calibration made in turned frames
//! re-expressed for the frames as the camera stores them.
//!
//! FabScanPi and Horus turn and flip every frame before they read it (`rotate`, `hflip`, `vflip`)
//! and calibrate in that orientation. Rather than turn each frame (a pass over every pixel), an
//! import ([`crate::import`]) turns the calibration ([`unturn`]): the camera, the laser planes
//! and the platform are given in the stored frame's camera coordinates, and the head reads the
//! frames as they are.

use scanner_core::Camera;
use scanner_core::geometry::Plane;
use scanner_core::nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

use crate::file::{CalibrationFile, PlaneEq, PlatformSection};

/// Why a fixed-laser calibration step cannot give its result: a frame turn that mirrors, a
/// calibration of another size, a stripe, a laser plane or a platform that the shots do not
/// give.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FixedError {
    /// One flip without the other, or with a transpose.
    #[error("the orientation {0:?} mirrors the frames; only turns are supported")]
    Mirrors(FrameTurn),
    /// The calibration is for frames of another size.
    #[error(
        "the calibration is for {}×{} frames, the turned frames are {}×{}",
        calibration.0,
        calibration.1,
        turned.0,
        turned.1
    )]
    OtherSize {
        /// The calibration's frame size.
        calibration: (u32, u32),
        /// The turned frames' size.
        turned: (u32, u32),
    },
    /// The tangential distortion has no counterpart in the stored frames.
    #[error("the tangential distortion cannot be turned")]
    Tangential,
    /// A flag of the config that is neither true nor false.
    #[error("camera.{name} is {value:?}, not \"True\" or \"False\"")]
    Flag {
        /// The flag.
        name: &'static str,
        /// What it holds.
        value: String,
    },
    /// A frame that is no frame (a size of 0).
    #[error("the frame: {0}")]
    Frame(scanner_core::stripe::FrameError),
    /// The pattern's pose gives no plane.
    #[error("the pattern's plane: {0}")]
    PatternPlane(scanner_core::GeomError),
    /// The stripe's points give no plane (too few, or on one line).
    #[error("{points} points{}: {error}", if *.kept { " kept" } else { "" })]
    LaserPlane {
        /// Points fitted.
        points: usize,
        /// Whether these are the points kept after dropping outliers.
        kept: bool,
        /// Why.
        error: scanner_core::GeomError,
    },
    /// Fewer than three poses of the pattern on the platform.
    #[error("{0} pattern pose(s): the platform's axis needs three turns at least")]
    TooFewPoses(usize),
    /// The pattern's centre does not run on a circle.
    #[error("the pattern's centre does not run on a circle: {0}")]
    NoCircle(scanner_core::GeomError),
    /// The poses do not turn the pattern about an axis.
    #[error("the pattern's poses do not turn it about an axis")]
    NoAxis,
    /// The corners lie off circles about one axis.
    #[error(
        "the pattern's corners lie {0:.2} mm (RMS) off circles about one axis: did the pattern move on the platform?"
    )]
    OffCircle(f64),
    /// The platform found is not a pose.
    #[error("the platform found is not a pose: {0}")]
    NotAPose(scanner_core::GeomError),
}

/// How a scanner turns its stored frames before reading them: transposed first (`rotate`),
/// then flipped left–right (`hflip`), then top–bottom (`vflip`), FabScanPi's order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameTurn {
    /// Transposed.
    pub rotate: bool,
    /// Flipped left–right.
    pub hflip: bool,
    /// Flipped top–bottom.
    pub vflip: bool,
}

impl FrameTurn {
    /// The map of a stored pixel to the turned one, `p′ = P p + b`, for a stored frame of
    /// `width` × `height`; and the turned frame's size.
    pub(crate) fn map(
        self,
        (width, height): (u32, u32),
    ) -> (Matrix2<f64>, Vector2<f64>, (u32, u32)) {
        let (mut p, mut b, mut size) = (Matrix2::identity(), Vector2::zeros(), (width, height));
        if self.rotate {
            p = Matrix2::new(0.0, 1.0, 1.0, 0.0) * p;
            b = Vector2::new(b.y, b.x);
            size = (size.1, size.0);
        }
        if self.hflip {
            p = Matrix2::new(-1.0, 0.0, 0.0, 1.0) * p;
            b = Vector2::new(f64::from(size.0) - 1.0 - b.x, b.y);
        }
        if self.vflip {
            p = Matrix2::new(1.0, 0.0, 0.0, -1.0) * p;
            b = Vector2::new(b.x, f64::from(size.1) - 1.0 - b.y);
        }
        (p, b, size)
    }
}

/// The pixel map's `P` on the camera's axes: `X′ = M X` for a point `X` in the stored frame's
/// camera coordinates (the camera's `x` and `y` run along the pixel axes, `z` stays).
fn camera_axes(p: &Matrix2<f64>) -> Matrix3<f64> {
    let mut m = Matrix3::identity();
    m.fixed_view_mut::<2, 2>(0, 0).copy_from(p);
    m
}

/// A calibration made in the turned frames (camera, laser planes, platform) re-expressed for
/// the stored frames of `stored` size.
///
/// # Errors
/// A mirroring orientation (one flip without the other, or with a transpose): the stored frames
/// would show the world mirrored, which no camera pose reproduces; turn the frames instead.
pub fn unturn(
    turned: &CalibrationFile,
    orientation: FrameTurn,
    stored: (u32, u32),
) -> Result<CalibrationFile, FixedError> {
    let (p, b, size) = orientation.map(stored);
    if p.determinant() < 0.0 {
        return Err(FixedError::Mirrors(orientation));
    }
    if size != (turned.image.width, turned.image.height) {
        return Err(FixedError::OtherSize {
            calibration: (turned.image.width, turned.image.height),
            turned: size,
        });
    }
    let m = camera_axes(&p);
    let c = &turned.camera;
    let f = p.transpose() * Matrix2::new(c.fx, 0.0, 0.0, c.fy) * p;
    let centre = p.transpose() * (Vector2::new(c.cx, c.cy) - b);
    // the tangential terms are linear in (p1, p2): solve for the stored frame's pair at two
    // normalised points (exact for a signed permutation)
    let tangential = |p1: f64, p2: f64, n: Vector2<f64>| {
        let r2 = n.norm_squared();
        Vector2::new(
            2.0 * p1 * n.x * n.y + p2 * (r2 + 2.0 * n.x * n.x),
            p1 * (r2 + 2.0 * n.y * n.y) + 2.0 * p2 * n.x * n.y,
        )
    };
    let probe = Vector2::new(0.3, 0.2);
    let want = p.transpose() * tangential(c.p1, c.p2, p * probe);
    let (a1, a2) = (tangential(1.0, 0.0, probe), tangential(0.0, 1.0, probe));
    let (p1, p2) = Matrix2::new(a1.x, a2.x, a1.y, a2.y)
        .try_inverse()
        .map(|inv| {
            let s = inv * want;
            (s.x, s.y)
        })
        .ok_or(FixedError::Tangential)?;
    let mut out = turned.clone();
    out.image.width = stored.0;
    out.image.height = stored.1;
    out.camera.fx = f[(0, 0)].abs();
    out.camera.fy = f[(1, 1)].abs();
    out.camera.cx = centre.x;
    out.camera.cy = centre.y;
    out.camera.p1 = p1;
    out.camera.p2 = p2;
    out.camera.covariance = None;
    out.camera.source = format!("{}, turned back to the stored frames", c.source);
    let back = |v: [f64; 3]| -> [f64; 3] { (m.transpose() * Vector3::from(v)).into() };
    out.lasers = turned
        .lasers
        .iter()
        .map(|l| PlaneEq {
            normal: back(l.normal),
            offset: l.offset,
        })
        .collect();
    if let Some(pl) = &turned.platform {
        let r = Matrix3::from_fn(|i, j| pl.rotation[i][j]);
        let rs = m.transpose() * r;
        out.platform = Some(PlatformSection {
            rotation: [0, 1, 2].map(|i| [rs[(i, 0)], rs[(i, 1)], rs[(i, 2)]]),
            origin: back(pl.origin),
            ..*pl
        });
    }
    out.board = None;
    out.regions = None;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanner_core::Distortion;
    use scanner_core::nalgebra::{Point2, Point3};

    /// A point seen in the turned frame and in the stored frame lands on the pixels that the
    /// turn maps onto each other.
    #[test]
    fn unturned_camera_sees_the_same_pixels() {
        let cam = Camera::new(
            1319.6,
            1322.35,
            625.54,
            808.36,
            Distortion {
                k1: 0.145,
                k2: 0.154,
                p1: -0.006,
                p2: 0.006,
                k3: -1.15,
            },
        )
        .unwrap();
        for orientation in [
            FrameTurn::default(),
            FrameTurn {
                rotate: true,
                hflip: true,
                vflip: false,
            },
            FrameTurn {
                rotate: true,
                hflip: false,
                vflip: true,
            },
            FrameTurn {
                rotate: false,
                hflip: true,
                vflip: true,
            },
        ] {
            let stored = if orientation.rotate {
                (1640, 1232)
            } else {
                (1232, 1640)
            };
            let turned = CalibrationFile::from_camera(&cam, (1232, 1640), "t".into(), None);
            let back = unturn(&turned, orientation, stored).unwrap();
            let cs = back.camera().unwrap();
            let (p, b, _) = orientation.map(stored);
            let m = camera_axes(&p);
            for x in [
                Point3::new(10.0, -20.0, 150.0),
                Point3::new(-40.0, 35.0, 120.0),
            ] {
                let ps = cs.project(&x).unwrap();
                let pt = cam.project(&Point3::from(m * x.coords)).unwrap();
                let mapped: Point2<f64> = Point2::from(p * ps.coords + b);
                assert!(
                    (mapped - pt).norm() < 1e-6,
                    "{orientation:?}: {mapped} vs {pt}"
                );
            }
        }
    }

    #[test]
    fn a_mirroring_orientation_is_refused() {
        let cam = Camera::new(1000.0, 1000.0, 320.0, 240.0, Distortion::none()).unwrap();
        let turned = CalibrationFile::from_camera(&cam, (640, 480), "t".into(), None);
        let hflip = FrameTurn {
            hflip: true,
            ..FrameTurn::default()
        };
        assert!(unturn(&turned, hflip, (640, 480)).is_err());
    }
}

/// Most lines (columns or rows) of a laser frame the calibration reads.
const MAX_LINES: usize = scanner_core::config::MAX_LINES;

/// A laser's stripe is taken on the pattern only this far inside its printed edge, mm (the
/// edge's own light and shadow stay out).
const PATTERN_INSET_MM: f64 = 2.0;

/// A laser's points farther from the first fit than this many of its RMS are dropped, and the
/// plane fitted again (a glint beside the pattern, a stripe on the platform seen through it).
const OUTLIER_RMS: f64 = 3.0;

/// The stripe of a dark laser frame where it crosses the chessboard at `pose`: every line's
/// centre whose ray meets the pattern inside its printed squares, as a point on the pattern's
/// plane (camera coordinates, mm). The stripe is read along whichever axis gives more points on
/// the pattern.
///
/// # Errors
/// A frame that is no frame (a size of 0).
pub fn laser_points(
    camera: &Camera<f64>,
    target: (usize, usize, f64),
    pose: &scanner_core::geometry::Pose,
    frame: &image::RgbImage,
) -> Result<Vec<scanner_core::nalgebra::Point3<f64>>, FixedError> {
    use scanner_core::nalgebra::{Point2, Point3};
    use scanner_core::stripe::{Axis, Extractor, Frame, Method, PixelFormat, StripeConfig};
    let (w, h) = (frame.width() as usize, frame.height() as usize);
    let view =
        Frame::packed(frame.as_raw(), w, h, PixelFormat::Rgb24).map_err(FixedError::Frame)?;
    let black = vec![0u8; frame.as_raw().len()];
    let reference = Frame::packed(&black, w, h, PixelFormat::Rgb24).map_err(FixedError::Frame)?;
    let plane = pose.plane().map_err(FixedError::PatternPlane)?;
    let (cols, rows, square) = target;
    let (half_u, half_v) = (
        cols as f64 / 2.0 * square - PATTERN_INSET_MM,
        rows as f64 / 2.0 * square - PATTERN_INSET_MM,
    );
    let inverse = pose.rotation.inverse();
    let on_pattern = |px: Point2<f64>| -> Option<Point3<f64>> {
        let ray = camera.pixel_to_ray(&px).ok()?;
        let p = plane.intersect_ray(&ray, 0.05).ok()?;
        let uv = inverse * (p.coords - pose.translation);
        (uv.x.abs() <= half_u && uv.y.abs() <= half_v).then_some(p)
    };
    let mut extractor = Box::new(Extractor::<MAX_LINES>::new());
    let mut best = Vec::new();
    for axis in [Axis::Columns, Axis::Rows] {
        let mut cfg = StripeConfig::new(Method::Lim, axis);
        cfg.max_width = 64.0;
        cfg.max_plateau = 40;
        cfg.half_window = scanner_core::stripe::MAX_HALF_WINDOW;
        cfg.separation = 24;
        cfg.ambiguity = 0.8;
        let Ok(ex) = extractor.extract(&view, Some(&reference), &cfg) else {
            continue;
        };
        let points: Vec<Point3<f64>> = ex
            .valid()
            .filter_map(|(line, s)| {
                let c = f64::from(s.centre);
                let px = match axis {
                    Axis::Columns => Point2::new(line as f64, c),
                    Axis::Rows => Point2::new(c, line as f64),
                };
                on_pattern(px)
            })
            .collect();
        if points.len() > best.len() {
            best = points;
        }
    }
    Ok(best)
}

/// A fixed laser's plane fitted to its stripe's points on the pattern at several poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserFit {
    /// The plane, camera coordinates, normal towards the camera.
    pub plane: Plane<f64>,
    /// Points used.
    pub points: usize,
    /// Points dropped as outliers.
    pub dropped: usize,
    /// RMS distance of the used points from the plane, mm.
    pub rms_mm: f64,
}

/// The plane through `points` (from [`laser_points`] at two or more poses), refitted without
/// the points three RMS off the first fit.
///
/// # Errors
/// Too few points, or points on one line (one pose only, or poses that do not turn the
/// pattern).
pub fn fit_laser(points: &[scanner_core::nalgebra::Point3<f64>]) -> Result<LaserFit, FixedError> {
    let first = scanner_core::geometry::fit_plane(points.iter().copied()).map_err(|error| {
        FixedError::LaserPlane {
            points: points.len(),
            kept: false,
            error,
        }
    })?;
    let keep: Vec<_> = points
        .iter()
        .copied()
        .filter(|p| first.plane.signed_distance(p).abs() <= OUTLIER_RMS * first.rms.max(0.01))
        .collect();
    let fit = scanner_core::geometry::fit_plane(keep.iter().copied()).map_err(|error| {
        FixedError::LaserPlane {
            points: keep.len(),
            kept: true,
            error,
        }
    })?;
    Ok(LaserFit {
        plane: fit.plane,
        points: keep.len(),
        dropped: points.len() - keep.len(),
        rms_mm: fit.rms,
    })
}

/// A turntable's platform found from a pattern standing on it, seen at several turns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformFit {
    /// The platform (its top `origin_distance` below the pattern's lowest row of corners).
    pub platform: scanner_core::geometry::Platform<f64>,
    /// Poses used.
    pub poses: usize,
    /// RMS distance of the pattern's centre from the circle the axis turns it on, mm.
    pub circle_rms_mm: f64,
    /// The turn the poses span, degrees (the widest angle between two of them about the axis).
    pub span_deg: f64,
    /// Consecutive shots turned clockwise seen from above, and counter-clockwise (a
    /// calibration may turn the platform the other way than a scan: FabScanPi's does).
    pub turns: (usize, usize),
}

/// The platform's axis and top from the poses of a pattern standing on it as it turned: its
/// centre runs on a circle about the axis. The axis is the normal of that circle's plane
/// through its centre; up is the side the camera is on (a turntable is
/// looked at from above its top, or level with the object); the top lies `origin_distance` mm
/// below the pattern's lowest row of corners (FabScanPi's `origin_distance`), and the platform's
/// `x` points from the axis towards the camera.
///
/// # Errors
/// Fewer than three poses, or poses that do not turn about one axis (a circle fit that fails,
/// or a centre more than 2 mm off its circle, RMS).
pub fn fit_platform(
    target: (usize, usize, f64),
    poses: &[scanner_core::geometry::Pose],
    origin_distance: f64,
) -> Result<PlatformFit, FixedError> {
    use scanner_core::nalgebra::{Point2, Point3};
    if poses.len() < 3 {
        return Err(FixedError::TooFewPoses(poses.len()));
    }
    let (cols, rows, square) = target;
    let corners: Vec<Point2<f64>> = (1..rows)
        .flat_map(|r| {
            (1..cols).map(move |c| {
                Point2::new(
                    (c as f64 - cols as f64 / 2.0) * square,
                    (r as f64 - rows as f64 / 2.0) * square,
                )
            })
        })
        .collect();
    // A chessboard reads the same turned by half a turn about its centre, so a corner's
    // pose may come from either of two corners; its centre is the same for both. The centre
    // runs on one circle about the axis.
    let track: Vec<Point3<f64>> = poses
        .iter()
        .map(|p| p.transform(&Point2::origin()))
        .collect();
    let plane =
        scanner_core::geometry::fit_plane(track.iter().copied()).map_err(FixedError::NoCircle)?;
    let axis = *plane.plane.normal();
    let (e1, e2) = {
        let a = if axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = axis.cross(&a).normalize();
        (e1, axis.cross(&e1))
    };
    // algebraic circle fit in (e1, e2): x² + y² + D x + E y + F = 0
    let mut ata = scanner_core::nalgebra::Matrix3::<f64>::zeros();
    let mut atb = Vector3::zeros();
    for p in &track {
        let (x, y) = (p.coords.dot(&e1), p.coords.dot(&e2));
        let row = Vector3::new(x, y, 1.0);
        ata += row * row.transpose();
        atb += row * -(x * x + y * y);
    }
    let s = ata
        .try_inverse()
        .map(|inv| inv * atb)
        .ok_or(FixedError::NoAxis)?;
    let (cx, cy) = (-s.x / 2.0, -s.y / 2.0);
    let r = (cx * cx + cy * cy - s.z).max(0.0).sqrt();
    let height = plane.centroid.coords.dot(&axis);
    let residuals: Vec<f64> = track
        .iter()
        .map(|p| {
            let (x, y) = (p.coords.dot(&e1), p.coords.dot(&e2));
            let off_plane = p.coords.dot(&axis) - height;
            ((x - cx).hypot(y - cy) - r).hypot(off_plane)
        })
        .collect();
    let centres = [Point3::from(e1 * cx + e2 * cy + axis * height)];
    let circle_rms_mm =
        (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64).sqrt();
    if !(circle_rms_mm <= 2.0) {
        return Err(FixedError::OffCircle(circle_rms_mm));
    }
    // a point of the axis: the centres' mean, moved along the axis
    let centre = Point3::from(
        centres.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / centres.len() as f64,
    );
    // up: the camera's side
    let up = if (-centre.coords).dot(&axis) >= 0.0 {
        axis
    } else {
        -axis
    };
    let lowest = poses
        .iter()
        .flat_map(|p| corners.iter().map(move |c| p.transform(c).coords.dot(&up)))
        .fold(f64::INFINITY, f64::min);
    let origin = centre + up * (lowest - origin_distance - centre.coords.dot(&up));
    let toward = -origin.coords - up * up.dot(&-origin.coords);
    let x = toward.normalize();
    let y = up.cross(&x);
    let rotation = Matrix3::from_columns(&[x, y, up]);
    let platform =
        scanner_core::geometry::Platform::new(rotation, origin).map_err(FixedError::NotAPose)?;
    // the widest turn between two poses, seen along the axis (the pattern's normal: the same
    // for both readings of a chessboard)
    let dir = |p: &scanner_core::geometry::Pose| {
        let v = p.rotation * Vector3::z();
        let v = v - up * up.dot(&v);
        v.normalize()
    };
    let mut span: f64 = 0.0;
    for a in poses {
        for b in poses {
            span = span.max(dir(a).dot(&dir(b)).clamp(-1.0, 1.0).acos());
        }
    }
    // the direction it turned: the pattern's normal about the axis, shot after shot
    let (mut cw, mut ccw) = (0, 0);
    for w in poses.windows(2) {
        let s = dir(&w[0]).cross(&dir(&w[1])).dot(&up);
        if s > 1e-6 {
            ccw += 1;
        } else if s < -1e-6 {
            cw += 1;
        }
    }
    Ok(PlatformFit {
        platform,
        poses: poses.len(),
        circle_rms_mm,
        span_deg: span.to_degrees(),
        turns: (cw, ccw),
    })
}
