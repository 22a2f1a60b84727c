//! The calibration file the scanner head loads: TOML, written atomically.
//!
//! ```toml
//! version = 1
//! [image]                  # the size everything below refers to
//! width = 1280
//! height = 960
//! [camera]                 # pinhole + Brown–Conrady (OpenCV order), pixels
//! fx = 1119.84 ...         # fy, cx, cy, k1, k2, p1, p2, k3
//! source = "intrinsics from 12 dot-grid images"
//! rms_px = 0.023
//! noise_px = 0.015         # the corners' noise the fit saw
//! cross_validation_ratio = 0.77  # halves' difference over what the noise explains
//! covariance = [[...], ...] # 9×9, fx … k3 (scaled by the ratio² above 2)
//! [board]                  # camera coordinates, mm; planes n·x + d = 0, n towards the camera
//! method = "layout-pose"   # or "paper-lines"
//! angle_deg = 89.99
//! crease_point = [...]     # L_c
//! crease_direction = [...]
//! [board.left]             # normal, offset, rms_px, plane_covariance (4×4 of n, offset),
//!                          # plane_from_intrinsics (4×9), and every marker:
//! [[board.left.markers]]   # index, sheet [u, v] mm, pixel, residual_px (predicted − found),
//!                          # status "used" | "missing" | "dropped"
//! [board.paper]            # the paper's construction, where it applies (for comparison)
//! [regions]                # image polygons, pixels: each sheet's outline, and the object's
//!                          # region between the marker lines
//! [[laser]]                # a turntable scanner's fixed laser planes: normal, offset
//! [platform]               # its platform: rotation (rows; columns x, y, axis), origin,
//!                          # radius, steps_per_turn, clockwise, height
//! ```

use scanner_core::config::MAX_PLANE_OFFSET_MM;

use crate::short;
use std::path::Path;

use scanner_core::calib::bundle::Covariance;
use scanner_core::calib::model::predict;
use scanner_core::calib::spread::{CalibrationSpread, SheetSpread};
use scanner_core::geometry::{Board, Plane, Platform, Pose};
use scanner_core::nalgebra::{Matrix3, Point2, Point3, Vector3};
use scanner_core::{Camera, Distortion};
use serde::{Deserialize, Serialize};

use super::board::BoardFile;
use super::{BoardFit, BoardMethod, MarkerFit, SheetFit};

/// Version of the file format.
pub const VERSION: u32 = 1;

/// Image size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSize {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
}

/// The camera's intrinsics and where they came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Radial distortion.
    pub k1: f64,
    /// Radial distortion.
    pub k2: f64,
    /// Tangential distortion.
    pub p1: f64,
    /// Tangential distortion.
    pub p2: f64,
    /// Radial distortion.
    pub k3: f64,
    /// How they were obtained.
    pub source: String,
    /// RMS reprojection error of the calibration, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_px: Option<f64>,
    /// The laser speckle's share of a stripe centre's uncertainty with this camera, pixels
    /// (`scanner_calib::speckle` measures it on a stripe across the bare board); the head takes
    /// `scanner_core::stripe::SPECKLE_PX` without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speckle_px: Option<f64>,
    /// A feature's position noise per coordinate the fit saw, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_px: Option<f64>,
    /// How much more two calibrations from disjoint halves of the images differed than the
    /// noise explains (`covariance` is scaled by its square where above the self-check's
    /// warning ratio).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cross_validation_ratio: Option<f64>,
    /// Covariance of `fx, fy, cx, cy, k1, k2, p1, p2, k3` from the fit (rows; zero for a
    /// parameter held fixed), scaled up where the cross-validation showed more scatter than
    /// chance gives: what the head's per-point uncertainty takes the calibration's share from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Vec<[f64; 9]>>,
}

/// A plane `normal · x + offset = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneEq {
    /// Unit normal, towards the camera.
    pub normal: [f64; 3],
    /// Offset, mm.
    pub offset: f64,
}

/// A turntable scanner's platform: where it stands at turn 0, camera coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlatformSection {
    /// Rotation platform → camera, rows; its columns are the platform's `x`, `y` and `z` (up
    /// the turning axis).
    pub rotation: [[f64; 3]; 3],
    /// The platform's origin: the axis at its top, mm.
    pub origin: [f64; 3],
    /// The platform's radius, mm (0: not known): nothing farther from the axis is the object.
    pub radius: f64,
    /// Motor steps in one turn of the platform.
    pub steps_per_turn: u32,
    /// The platform turns clockwise seen from above (its motor's direction for positive
    /// steps); counter-clockwise without.
    #[serde(default)]
    pub clockwise: bool,
    /// The tallest object the scanner takes, mm (0: not known): the head reads only the part
    /// of the picture where the cylinder of the platform's radius and this height shows.
    #[serde(default)]
    pub height: f64,
}

/// Longest platform radius, mm.
pub const MAX_PLATFORM_RADIUS_MM: f64 = 2000.0;

/// Most motor steps in one turn (a 200-step motor at 256 microsteps through a 100:1 gear).
pub const MAX_STEPS_PER_TURN: u32 = 5_120_000;

impl PlatformSection {
    /// The platform.
    ///
    /// # Errors
    /// [`scanner_core::GeomError`] for numbers that are not a platform's pose.
    pub fn platform(&self) -> Result<Platform<f64>, scanner_core::GeomError> {
        let r = self.rotation;
        Platform::new(
            Matrix3::new(
                r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
            ),
            Point3::from(self.origin),
        )
    }
}

impl PlaneEq {
    /// The plane.
    ///
    /// # Errors
    /// [`scanner_core::GeomError`] for a normal of zero or numbers that are not finite.
    pub fn plane(&self) -> Result<Plane<f64>, scanner_core::GeomError> {
        Plane::new(Vector3::from(self.normal), self.offset)
    }
}

/// Why a file's fixed lasers or platform are unusable (its `[[laser]]` and `[platform]`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FixedUnusable {
    /// A laser's numbers are not a plane.
    #[error("[[laser]] {index}: {error} (normal {normal:?}, offset {offset})")]
    NotAPlane {
        /// The laser, from 0.
        index: usize,
        /// Why.
        error: scanner_core::GeomError,
        /// The normal written.
        normal: [f64; 3],
        /// The offset written, mm (rounded for the message).
        offset: String,
    },
    /// A laser plane through the camera, or too far from it.
    #[error(
        "[[laser]] {index}: the plane passes {distance} mm from the camera: a laser plane through the camera (or beyond {MAX_PLANE_OFFSET_MM} mm) triangulates nothing"
    )]
    ThroughCamera {
        /// The laser, from 0.
        index: usize,
        /// Its distance from the camera, mm (rounded).
        distance: String,
    },
    /// The platform's numbers are not a pose.
    #[error("[platform]: {0}")]
    Platform(scanner_core::GeomError),
    /// A step count out of range.
    #[error("[platform] steps_per_turn {0} is not a turntable's (1 to {MAX_STEPS_PER_TURN})")]
    Steps(u32),
    /// A height out of range.
    #[error("[platform] height {0} mm is not a scanner's (0 to {MAX_PLATFORM_RADIUS_MM} mm)")]
    Height(String),
    /// A radius out of range.
    #[error("[platform] radius {0} mm is not a platform's (0 to {MAX_PLATFORM_RADIUS_MM} mm)")]
    Radius(String),
    /// An origin far from the camera.
    #[error("[platform] origin {0:?} is not within {MAX_PLANE_OFFSET_MM} mm of the camera")]
    Origin([f64; 3]),
}

/// The fixed lasers and the platform of a file checked: planes that are planes and miss the
/// camera, a platform that is a pose, a radius and a step count in range.
fn check_fixed(f: &CalibrationFile) -> Result<(), FixedUnusable> {
    for (k, l) in f.lasers.iter().enumerate() {
        let plane = l.plane().map_err(|error| FixedUnusable::NotAPlane {
            index: k,
            error,
            normal: l.normal,
            offset: short(l.offset),
        })?;
        if !(plane.offset().abs() >= 1.0 && plane.offset().abs() <= MAX_PLANE_OFFSET_MM) {
            return Err(FixedUnusable::ThroughCamera {
                index: k,
                distance: short(plane.offset().abs()),
            });
        }
    }
    if let Some(p) = &f.platform {
        p.platform().map_err(FixedUnusable::Platform)?;
        if p.steps_per_turn == 0 || p.steps_per_turn > MAX_STEPS_PER_TURN {
            return Err(FixedUnusable::Steps(p.steps_per_turn));
        }
        if !(0.0..=MAX_PLATFORM_RADIUS_MM).contains(&p.height) {
            return Err(FixedUnusable::Height(short(p.height)));
        }
        if !(0.0..=MAX_PLATFORM_RADIUS_MM).contains(&p.radius) {
            return Err(FixedUnusable::Radius(short(p.radius)));
        }
        if !(p.origin.iter().all(|v| v.is_finite())
            && Vector3::from(p.origin).norm() <= MAX_PLANE_OFFSET_MM)
        {
            return Err(FixedUnusable::Origin(p.origin));
        }
    }
    Ok(())
}

/// One marker's record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerEntry {
    /// Index in the sheet's layout.
    pub index: usize,
    /// Position on the sheet, mm.
    pub sheet: [f64; 2],
    /// Where it was found, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel: Option<[f64; 2]>,
    /// Predicted − found, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual_px: Option<[f64; 2]>,
    /// "used", "missing" or "dropped".
    pub status: String,
}

/// A board sheet's plane and markers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SheetSection {
    /// Unit normal, towards the camera.
    pub normal: [f64; 3],
    /// Offset, mm.
    pub offset: f64,
    /// RMS reprojection error of the used markers, pixels.
    pub rms_px: f64,
    /// Covariance of `(n_x, n_y, n_z, offset)` from the markers' noise (layout pose only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plane_covariance: Option<[[f64; 4]; 4]>,
    /// How `(n_x, n_y, n_z, offset)` moves per unit change of `fx, fy, cx, cy, k1, k2, p1, p2,
    /// k3` (the sheet refitted with the changed camera; layout pose only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plane_from_intrinsics: Option<[[f64; 9]; 4]>,
    /// Every layout marker.
    pub markers: Vec<MarkerEntry>,
}

/// The paper's construction, for comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PaperSection {
    /// Left plane by the three-point lines.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left: Option<PlaneEq>,
    /// Right plane.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right: Option<PlaneEq>,
}

/// The board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardSection {
    /// "layout-pose" or "paper-lines": which planes `left` and `right` are.
    pub method: String,
    /// Opening angle between the planes as built, degrees.
    pub angle_deg: f64,
    /// A point of the crease `L_c`, mm.
    pub crease_point: [f64; 3],
    /// Direction of the crease (unit).
    pub crease_direction: [f64; 3],
    /// Left sheet.
    pub left: SheetSection,
    /// Right sheet.
    pub right: SheetSection,
    /// The paper's construction where the layout is the paper's and all markers were found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paper: Option<PaperSection>,
}

/// Image regions, polygons in pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Regions {
    /// The left sheet's outline.
    pub left: Vec<[f64; 2]>,
    /// The right sheet's outline.
    pub right: Vec<[f64; 2]>,
    /// Where the object stands: both sheets between the upper and lower marker lines.
    pub object: Vec<[f64; 2]>,
}

/// The calibration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// Format version ([`VERSION`]).
    pub version: u32,
    /// Image size of the calibration.
    pub image: ImageSize,
    /// The camera.
    pub camera: CameraSection,
    /// The board, once calibrated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<BoardSection>,
    /// Image regions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regions: Option<Regions>,
    /// A turntable scanner's fixed laser planes, camera coordinates (`[[laser]]`, laser 0
    /// first).
    #[serde(default, skip_serializing_if = "Vec::is_empty", rename = "laser")]
    pub lasers: Vec<PlaneEq>,
    /// A turntable scanner's platform.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform: Option<PlatformSection>,
}

/// Why a calibration file is unusable.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// Not readable.
    #[error("cannot read the calibration file {path}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        #[source]
        source: std::io::Error,
    },
    /// Cannot be written (a missing folder, no permission, a full disk).
    #[error("cannot write the calibration file {path} (does its folder exist?)")]
    Write {
        /// The file.
        path: String,
        /// What went wrong.
        #[source]
        source: std::io::Error,
    },
    /// Not TOML of this shape.
    #[error("calibration file {path}")]
    Toml {
        /// The file.
        path: String,
        /// What is wrong.
        #[source]
        source: toml::de::Error,
    },
    /// Cannot be written as TOML (a value TOML cannot hold).
    #[error("calibration file {path}: cannot be written as TOML")]
    Serialize {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: toml::ser::Error,
    },
    /// Readable, but the fixed lasers or the platform are unusable.
    #[error("calibration file {path}")]
    Fixed {
        /// The file.
        path: String,
        /// What is wrong.
        #[source]
        reason: FixedUnusable,
    },
    /// Readable, but the numbers are unusable.
    #[error("calibration file {path}: {why}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
}

fn plane_eq(p: &Plane<f64>) -> PlaneEq {
    PlaneEq {
        normal: (*p.normal()).into(),
        offset: p.offset(),
    }
}

/// Pixel of a sheet point, with distortion.
fn sheet_pixel(camera: &Camera<f64>, pose: &Pose, u: f64, v: f64) -> Option<[f64; 2]> {
    predict(camera, pose, &Point2::new(u, v), 0.0)
        .ok()
        .map(|p| [p.x, p.y])
}

/// A sheet's rectangle `[u0, u1] × [v0, v1]` as an image polygon (8 points per edge).
fn outline(camera: &Camera<f64>, pose: &Pose, u: (f64, f64), v: (f64, f64)) -> Vec<[f64; 2]> {
    let corners = [(u.0, v.0), (u.1, v.0), (u.1, v.1), (u.0, v.1)];
    let mut out = Vec::new();
    for k in 0..4 {
        let (a, b) = (corners[k], corners[(k + 1) % 4]);
        for s in 0..8 {
            let t = f64::from(s) / 8.0;
            if let Some(p) = sheet_pixel(camera, pose, a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
            {
                out.push(p);
            }
        }
    }
    out
}

impl CalibrationFile {
    /// A file holding only a camera.
    pub fn from_camera(
        camera: &Camera<f64>,
        size: (u32, u32),
        source: String,
        rms_px: Option<f64>,
    ) -> Self {
        let d = camera.distortion();
        let pp = camera.principal_point();
        CalibrationFile {
            version: VERSION,
            image: ImageSize {
                width: size.0,
                height: size.1,
            },
            camera: CameraSection {
                fx: camera.fx(),
                fy: camera.fy(),
                cx: pp.x,
                cy: pp.y,
                k1: d.k1,
                k2: d.k2,
                p1: d.p1,
                p2: d.p2,
                k3: d.k3,
                source,
                rms_px,
                speckle_px: None,
                noise_px: None,
                cross_validation_ratio: None,
                covariance: None,
            },
            board: None,
            regions: None,
            lasers: Vec::new(),
            platform: None,
        }
    }

    /// Keeps the intrinsics' covariance scaled by `scale` (the cross-validation's
    /// [`Halves::covariance_scale`](crate::selfcheck::Halves::covariance_scale)) and the
    /// cross-validation's `ratio`.
    pub fn set_covariance(&mut self, c: &Covariance, ratio: Option<f64>, scale: f64) {
        self.camera.noise_px = Some(c.noise_px);
        self.camera.cross_validation_ratio = ratio;
        self.camera.covariance = Some(c.matrix.map(|row| row.map(|v| v * scale)).to_vec());
    }

    /// The intrinsics' covariance, if the file keeps one.
    pub fn covariance(&self) -> Option<[[f64; 9]; 9]> {
        let rows = self.camera.covariance.as_ref()?;
        rows.as_slice().try_into().ok()
    }

    /// The camera.
    ///
    /// # Errors
    /// [`scanner_core::GeomError`] for unusable numbers.
    pub fn camera(&self) -> Result<Camera<f64>, scanner_core::GeomError> {
        let c = &self.camera;
        Camera::new(
            c.fx,
            c.fy,
            c.cx,
            c.cy,
            Distortion {
                k1: c.k1,
                k2: c.k2,
                p1: c.p1,
                p2: c.p2,
                k3: c.k3,
            },
        )
    }

    /// Adds the board from a fit, by `method`, with the image regions; returns the method used
    /// (the layout pose when the paper's lines are asked for but a sheet lacks them).
    pub fn set_board(
        &mut self,
        fit: &BoardFit,
        board: &BoardFile,
        camera: &Camera<f64>,
        method: BoardMethod,
    ) -> BoardMethod {
        let (planes, used) = match (method, fit.paper) {
            (BoardMethod::PaperLines, [Some(l), Some(r)]) => ([l, r], BoardMethod::PaperLines),
            _ => (
                [fit.sheets[0].plane, fit.sheets[1].plane],
                BoardMethod::LayoutPose,
            ),
        };
        let crease = fit.board.crease();
        let paper = (fit.paper.iter().any(Option::is_some)).then(|| PaperSection {
            left: fit.paper[0].as_ref().map(plane_eq),
            right: fit.paper[1].as_ref().map(plane_eq),
        });
        let board_geom = Board::new(planes[0], planes[1]).unwrap_or(fit.board);
        let spread = match used {
            BoardMethod::LayoutPose => crate::spread::board_spread(fit, board, camera).ok(),
            BoardMethod::PaperLines => None,
        };
        let mut sections = [&fit.sheets[0], &fit.sheets[1]]
            .iter()
            .zip(&planes)
            .map(|(s, p)| sheet_section(s, p))
            .collect::<Vec<_>>();
        if let Some(spread) = spread {
            for (sec, sp) in sections.iter_mut().zip(spread) {
                sec.plane_covariance = Some(sp.noise);
                sec.plane_from_intrinsics = Some(sp.from_intrinsics);
            }
        }
        let right = sections.pop().expect("two sheets");
        let left = sections.pop().expect("two sheets");
        self.board = Some(BoardSection {
            method: used.name().into(),
            angle_deg: board_geom.angle().to_degrees(),
            crease_point: crease.point().coords.into(),
            crease_direction: (*crease.direction()).into(),
            left,
            right,
            paper,
        });
        self.regions = Some(regions(fit, board, camera));
        used
    }

    /// The calibration's modes for the head ([`CalibrationSpread`]), when the file keeps the
    /// intrinsics' covariance and both sheets' spreads.
    ///
    /// # Errors
    /// As [`CalibrationSpread::new`] for covariances that are not numbers or move the camera
    /// out of what is a camera.
    pub fn spread(&self) -> Option<Result<CalibrationSpread, scanner_core::GeomError>> {
        let cov = self.covariance()?;
        let b = self.board.as_ref()?;
        let sheet = |s: &SheetSection| {
            Some(SheetSpread {
                noise: s.plane_covariance?,
                from_intrinsics: s.plane_from_intrinsics?,
            })
        };
        let sheets = [sheet(&b.left)?, sheet(&b.right)?];
        Some(self.camera().and_then(|camera| {
            CalibrationSpread::new(
                &camera,
                (self.image.width, self.image.height),
                &cov,
                &sheets,
            )
        }))
    }

    /// The board planes, if calibrated.
    pub fn board(&self) -> Option<Result<Board<f64>, scanner_core::GeomError>> {
        let b = self.board.as_ref()?;
        let plane = |s: &SheetSection| Plane::new(Vector3::from(s.normal), s.offset);
        Some(plane(&b.left).and_then(|l| Board::new(l, plane(&b.right)?)))
    }

    /// Reads a calibration file.
    ///
    /// # Errors
    /// [`FileError`] naming the file and the problem.
    pub fn load(path: &Path) -> Result<Self, FileError> {
        let text = scanner_io::text_file::read(path).map_err(|source| FileError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses and checks a calibration file's text; `name` names it in errors.
    ///
    /// # Errors
    /// [`FileError`] naming the file and the problem.
    pub fn parse(text: &str, name: &str) -> Result<Self, FileError> {
        let f: CalibrationFile = toml::from_str(text).map_err(|source| FileError::Toml {
            path: name.to_string(),
            source,
        })?;
        let invalid = |why: String| FileError::Invalid {
            path: name.to_string(),
            why,
        };
        if f.version != VERSION {
            return Err(invalid(format!(
                "version {} (this build reads {VERSION})",
                f.version
            )));
        }
        let (w, h) = (f.image.width, f.image.height);
        let c = &f.camera;
        let values = format!(
            "fx {}, fy {}, cx {}, cy {}, k1 {}, k2 {}, p1 {}, p2 {}, k3 {} for a {w}×{h} image",
            short(c.fx),
            short(c.fy),
            short(c.cx),
            short(c.cy),
            short(c.k1),
            short(c.k2),
            short(c.p1),
            short(c.p2),
            short(c.k3)
        );
        f.camera()
            .and_then(|cam| cam.check_plausible(w, h))
            .map_err(|e| invalid(format!("[camera]: {e} ({values})")))?;
        if let Some(sp) = c.speckle_px
            && !(0.0..=10.0).contains(&sp)
        {
            return Err(invalid(format!(
                "[camera] speckle_px {} is not a stripe centre's uncertainty (0 to 10 px)",
                short(sp)
            )));
        }
        if let Some(rows) = &c.covariance {
            check_covariance(rows).map_err(|why| invalid(format!("[camera] covariance: {why}")))?;
        }
        if let Some(b) = &f.board {
            for (name, s) in [("left", &b.left), ("right", &b.right)] {
                if !(s.offset.abs() <= MAX_PLANE_OFFSET_MM) {
                    return Err(invalid(format!(
                        "[board.{name}]: offset {} mm is not a board's distance (at most {MAX_PLANE_OFFSET_MM} mm)",
                        short(s.offset)
                    )));
                }
            }
        }
        if let Some(b) = f.board() {
            b.map_err(|e| invalid(format!("[board]: {e}")))?;
        }
        check_fixed(&f).map_err(|reason| FileError::Fixed {
            path: name.to_string(),
            reason,
        })?;
        Ok(f)
    }

    /// Writes the file atomically (a temporary file beside it, then a rename).
    ///
    /// # Errors
    /// [`FileError::Serialize`] or [`FileError::Write`].
    pub fn save(&self, path: &Path) -> Result<(), FileError> {
        let text = toml::to_string(self).map_err(|source| FileError::Serialize {
            path: path.display().to_string(),
            source,
        })?;
        write_atomic(path, text.as_bytes()).map_err(|source| FileError::Write {
            path: path.display().to_string(),
            source,
        })
    }
}

pub use scanner_io::write_atomic;

/// Why a calibration file's covariance is not one the head can use (its `[camera] covariance`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CovarianceError {
    /// Not 9 rows.
    #[error("{0} rows, 9 expected (fx, fy, cx, cy, k1, k2, p1, p2, k3)")]
    Rows(usize),
    /// An entry that is not a number (row and column from 1).
    #[error("row {row}, column {column}: {value} is not a number")]
    NotANumber {
        /// Its row, from 1.
        row: usize,
        /// Its column, from 1.
        column: usize,
        /// What was there.
        value: String,
    },
    /// An entry unlike its mirror across the diagonal.
    #[error("not symmetric at row {row}, column {column}")]
    NotSymmetric {
        /// Its row, from 1.
        row: usize,
        /// Its column, from 1.
        column: usize,
    },
    /// A negative variance on the diagonal.
    #[error("negative variance in row {0}")]
    NegativeVariance(usize),
}

/// A covariance the head can use: 9 rows, finite, symmetric, no negative variance.
fn check_covariance(rows: &[[f64; 9]]) -> Result<(), CovarianceError> {
    if rows.len() != 9 {
        return Err(CovarianceError::Rows(rows.len()));
    }
    for (i, row) in rows.iter().enumerate() {
        for (j, &a) in row.iter().enumerate() {
            let b = rows[j][i];
            if !a.is_finite() {
                return Err(CovarianceError::NotANumber {
                    row: i + 1,
                    column: j + 1,
                    value: short(a),
                });
            }
            if (a - b).abs() > 1e-9 * (a.abs() + b.abs()).max(1e-300) {
                return Err(CovarianceError::NotSymmetric {
                    row: i + 1,
                    column: j + 1,
                });
            }
        }
        if row[i] < 0.0 {
            return Err(CovarianceError::NegativeVariance(i + 1));
        }
    }
    Ok(())
}

/// A sheet's plane and its markers as the file records them.
fn sheet_section(s: &SheetFit, plane: &Plane<f64>) -> SheetSection {
    let marker = |(i, m): (usize, &MarkerFit)| MarkerEntry {
        index: i,
        sheet: [m.sheet.x, m.sheet.y],
        pixel: m.pixel.map(|p| [p.x, p.y]),
        residual_px: m.residual.map(|r| [r.x, r.y]),
        status: if m.residual.is_some() {
            "used"
        } else if m.dropped {
            "dropped"
        } else {
            "missing"
        }
        .into(),
    };
    SheetSection {
        normal: (*plane.normal()).into(),
        offset: plane.offset(),
        rms_px: s.rms_px,
        plane_covariance: None,
        plane_from_intrinsics: None,
        markers: s.markers.iter().enumerate().map(marker).collect(),
    }
}

/// The image regions: each sheet's paper outline; the object's region between the marker lines.
fn regions(fit: &BoardFit, board: &BoardFile, camera: &Camera<f64>) -> Regions {
    let (w, h) = (board.sheet.width, board.sheet.height);
    let poses = [fit.sheets[0].pose, fit.sheets[1].pose];
    // Per sheet: the lowest and highest marker line (v) and the farthest marker from the crease (u).
    let lines = [board.left.points(), board.right.points()].map(|p| {
        let (lo, hi) = p
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q.y), hi.max(q.y))
            });
        let umax = p.iter().fold(0.0f64, |m, q| m.max(q.x));
        (lo, hi, umax)
    });
    let (l, r) = (lines[0], lines[1]);
    let (vt, vb) = (l.0.max(r.0), l.1.min(r.1));
    let object = [
        sheet_pixel(camera, &poses[0], l.2, vt),
        sheet_pixel(camera, &poses[0], 0.0, vt),
        sheet_pixel(camera, &poses[1], r.2, vt),
        sheet_pixel(camera, &poses[1], r.2, vb),
        sheet_pixel(camera, &poses[1], 0.0, vb),
        sheet_pixel(camera, &poses[0], l.2, vb),
    ]
    .into_iter()
    .flatten()
    .collect();
    Regions {
        left: outline(camera, &poses[0], (0.0, w), (-h / 2.0, h / 2.0)),
        right: outline(camera, &poses[1], (0.0, w), (-h / 2.0, h / 2.0)),
        object,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn files_get_the_mode_of_any_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let ours = dir.path().join("calibration.toml");
        write_atomic(&ours, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&ours), mode(&plain));
    }
}
