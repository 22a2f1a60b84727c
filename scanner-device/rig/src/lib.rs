//! `scanner-rig`: the virtual rig — what the scanner head's camera would see, with ground truth.
//!
//! Where it sits: beside the data path, in place of the camera: `[scanner-rig] ─► frames ─► the
//! head`. It depends on `scanner-core` and on `scanner-calib` for the board file (what is
//! printed on the board); nothing but tests, benches, examples and the head's `rig` feature
//! depends on it. The reports against the paper's tables are here too ([`report`]).
//!
//! A [`Scene`] describes the camera, the two-plane board, objects in front of it, the hand-held
//! laser's sweep, ambient light and the sensor. A [`Rig`] built from it casts one ray per pixel
//! once (camera, board and objects do not move; only the laser does) into a geometry buffer, and
//! then renders each frame from it:
//! - ambient light on the surface albedo;
//! - the laser: a light plane from a source that sweeps like a hand (deterministic wobble and
//!   jitter per frame), Gaussian across its thickness, falling off with the square of the
//!   distance and with the cosine of incidence, dark where an object hides the surface from the
//!   source; pixels near the stripe are supersampled 3×3 (sub-pixel rays interpolated from the
//!   pixel centres' undistorted coordinates, each cast into the scene) so that the stripe's image
//!   is right to a small fraction of a pixel;
//! - the lens: a Gaussian point-spread function (the ambient image is blurred once, the laser
//!   light splatted through the same kernel per frame);
//! - the sensor: gain, shot and read noise, rounding and clipping to 8 bits; out as RGB, gray or
//!   YUYV like a webcam.
//!
//! [`Rig::truth`] gives, for every column, the exact row where the laser plane meets the visible
//! lit surface, the 3-D point there and the surface it lies on, found by bisection on exact rays.
//!
//! Also: laser speckle (a fixed grain on the lit surface), mains flicker of the ambient light, and
//! motion blur (the light plane moves during the exposure).
//!
//! Objects are analytic shapes or triangle meshes from OBJ files ([`mesh`]). Calibration shots —
//! the paper's cross pattern and planar targets at any pose — are in [`target`].
//!
//! The board's markers come from a board file ([`scanner_calib::board`]): discs or a chessboard
//! per sheet.
//!
//! Scenes can be read from TOML ([`Scene::from_toml`]); `scanner-device render` writes a scene's
//! frames as PNG files with their ground truth.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! report  file  compare  target
//! surface
//! mesh
//! ```

#![deny(missing_docs)]

pub mod compare;
mod file;
pub mod mesh;
pub mod report;
pub mod surface;
pub mod target;

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use scanner_core::geometry::Plane;
use scanner_core::nalgebra::{Isometry3, Point2, Point3, Rotation3, Vector3};
use scanner_core::stripe::PixelFormat;
use scanner_core::{Camera, GeomError};

pub use surface::{Hit, Shape, SurfaceId};

/// An RGB frame as a USB webcam's motion-JPEG frame: baseline JPEG with 4:2:2 chroma (what UVC
/// cameras send), standard Huffman tables, at `quality` (1–100).
///
/// # Errors
/// [`MjpegError`]: a side over 65 535 pixels, or the encoder's (a buffer of the wrong length).
pub fn mjpeg(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, MjpegError> {
    let side = |n: u32| u16::try_from(n).map_err(|_| MjpegError::TooLarge(width, height));
    let (w, h) = (side(width)?, side(height)?);
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality);
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_2);
    encoder.encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)?;
    Ok(out)
}

/// Why a frame could not be encoded as a webcam's motion-JPEG frame ([`mjpeg`]).
#[derive(Debug, thiserror::Error)]
pub enum MjpegError {
    /// A side longer than JPEG holds.
    #[error("a {0}×{1} frame: JPEG holds at most 65535 pixels a side")]
    TooLarge(u32, u32),
    /// The encoder refused the pixels.
    #[error("the JPEG encoder: {0}")]
    Encoder(#[from] jpeg_encoder::EncodingError),
}

/// The two-plane board. Lengths in mm, angles in degrees.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardSpec {
    /// Distance of the crease from the camera along the optical axis.
    pub distance: f64,
    /// Opening angle between the two planes (90 for a right angle).
    pub angle_deg: f64,
    /// Turn of the board about its crease (about the camera's y axis).
    pub yaw_deg: f64,
    /// Tilt of the crease towards the camera (about the camera's x axis).
    pub pitch_deg: f64,
    /// RGB albedo of the board's surface.
    pub albedo: [f64; 3],
    /// The printed markers.
    pub markers: Markers,
}

/// Printed circular markers on the two board sheets. Sheet coordinates in mm: `u` from the crease
/// outward along the sheet, `v` along the crease (+y down when the board is upright).
#[derive(Debug, Clone, PartialEq)]
pub struct Markers {
    /// Marker centres on the left sheet.
    pub left: Vec<[f64; 2]>,
    /// Marker centres on the right sheet.
    pub right: Vec<[f64; 2]>,
    /// Marker diameter, mm.
    pub diameter: f64,
    /// RGB albedo of the marker ink.
    pub albedo: [f64; 3],
    /// A sheet may carry a chessboard instead of discs (`[left, right]`); its inner corners are
    /// that sheet's markers.
    pub chess: [Option<Chess>; 2],
}

/// A chessboard printed on a board sheet: `cols × rows` squares of side `square` (mm), the first
/// inner corner at sheet coordinates `(u0, v0)`, the square touching it on the low-`u`, low-`v`
/// side dark.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chess {
    /// Squares along `u`.
    pub cols: usize,
    /// Squares along `v`.
    pub rows: usize,
    /// Square side, mm.
    pub square: f64,
    /// First inner corner's `u`, mm.
    pub u0: f64,
    /// First inner corner's `v`, mm.
    pub v0: f64,
}

impl Chess {
    /// Inner corners, row by row (along `u` first).
    pub fn corners(&self) -> Vec<[f64; 2]> {
        (0..self.rows.saturating_sub(1))
            .flat_map(|r| {
                (0..self.cols.saturating_sub(1)).map(move |c| {
                    [
                        self.u0 + c as f64 * self.square,
                        self.v0 + r as f64 * self.square,
                    ]
                })
            })
            .collect()
    }

    /// `Some(dark)` inside the chessboard, `None` outside.
    fn ink(&self, uv: [f64; 2]) -> Option<bool> {
        let (a, b) = (
            (uv[0] - self.u0) / self.square + 1.0,
            (uv[1] - self.v0) / self.square + 1.0,
        );
        if a < 0.0 || b < 0.0 || a >= self.cols as f64 || b >= self.rows as f64 {
            return None;
        }
        Some((a.floor() as i64 + b.floor() as i64) % 2 == 0)
    }

    /// Distance (mm) to the nearest square edge or the board's outline.
    fn edge_distance(&self, uv: [f64; 2]) -> f64 {
        let (a, b) = (
            (uv[0] - self.u0) / self.square + 1.0,
            (uv[1] - self.v0) / self.square + 1.0,
        );
        let (ca, cb) = (
            a.clamp(0.0, self.cols as f64),
            b.clamp(0.0, self.rows as f64),
        );
        let outside = ((a - ca).powi(2) + (b - cb).powi(2)).sqrt();
        if outside > 0.0 {
            return outside * self.square;
        }
        let da = (a - a.round()).abs();
        let db = (b - b.round()).abs();
        da.min(db) * self.square
    }
}

impl Markers {
    /// The paper's layout on each sheet: two lines of three markers along the sheet, `spacing`
    /// apart, the lines `2 × spacing` apart; diameter a quarter of the spacing.
    pub fn paper(spacing: f64) -> Markers {
        let sheet: Vec<[f64; 2]> = [-1.0, 1.0]
            .iter()
            .flat_map(|&v| [0.6, 1.6, 2.6].map(|u| [u * spacing, v * spacing]))
            .collect();
        Markers {
            left: sheet.clone(),
            right: sheet,
            diameter: 0.25 * spacing,
            albedo: [0.06, 0.06, 0.06],
            chess: [None, None],
        }
    }
}

/// The ground truth of one printed marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerTruth {
    /// The sheet it is on ([`SurfaceId::Left`] or [`SurfaceId::Right`]).
    pub surface: SurfaceId,
    /// Its index in that sheet's list.
    pub index: usize,
    /// Its position on the sheet, mm.
    pub sheet: [f64; 2],
    /// Its centre in camera coordinates, mm.
    pub centre: Point3<f64>,
    /// The projection of its centre, pixels.
    pub centre_px: Point2<f64>,
    /// The centroid of its projected disc (an ellipse, distorted), pixels: where an unbiased
    /// detector finds it.
    pub disc_px: Point2<f64>,
    /// `true` if the whole disc is in view and no object hides any of it.
    pub visible: bool,
}

/// An object in front of the board.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Its shape.
    pub shape: Shape,
    /// RGB albedo.
    pub albedo: [f64; 3],
    /// Optional texture: a solid 3-D checker of this cell size (mm) whose cells alternate between
    /// `albedo` and `texture_albedo`, so that colour varies over the surface.
    pub texture: Option<(f64, [f64; 3])>,
}

/// The hand-held laser and its sweep. Lengths in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserSpec {
    /// Where the laser is held, camera coordinates.
    pub source: Point3<f64>,
    /// Height (y) at the crease where the stripe's plane crosses the board's centre line, at the
    /// first and the last frame.
    pub sweep: (f64, f64),
    /// Frames in the sweep.
    pub frames: usize,
    /// Largest roll of the light plane about its direction of travel, degrees (hand wobble).
    pub wobble_deg: f64,
    /// Largest jitter of the source position, mm.
    pub jitter_mm: f64,
    /// Standard deviation of the light plane's thickness, mm.
    pub sigma_mm: f64,
    /// Irradiance at the plane's centre 1 m from the source, in units of the ambient light.
    pub power: f64,
    /// RGB colour of the laser light (red: `[1, 0.05, 0.02]`).
    pub colour: [f64; 3],
    /// Speckle contrast, 0 (none) to 1 (fully developed): a fixed grain on the lit surface.
    pub speckle: f64,
    /// Seed of the wobble.
    pub seed: u64,
}

/// The sensor: radiance to 8-bit numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// Digital numbers per unit of radiance (exposure × gain).
    pub gain: f64,
    /// Read noise, DN (standard deviation).
    pub read_noise: f64,
    /// Shot noise: variance in DN² per DN of signal.
    pub shot_noise: f64,
    /// Seed of the noise.
    pub seed: u64,
}

/// Everything the rig renders.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The camera, with distortion.
    pub camera: Camera<f64>,
    /// The board.
    pub board: BoardSpec,
    /// Objects in front of the board.
    pub objects: Vec<Object>,
    /// The laser.
    pub laser: LaserSpec,
    /// Ambient radiance on a white surface.
    pub ambient: f64,
    /// Lens blur: standard deviation of the Gaussian point-spread function, pixels (0: none).
    pub blur_px: f64,
    /// Mains flicker of the ambient light: relative amplitude at twice `mains_hz` (0: none).
    pub flicker: f64,
    /// Mains frequency, Hz.
    pub mains_hz: f64,
    /// Frames per second of the camera (the sweep's time base).
    pub fps: f64,
    /// Exposure time as a fraction of the frame period: the laser moves during it (motion blur;
    /// 0: an instant).
    pub exposure: f64,
    /// The sensor.
    pub sensor: SensorSpec,
    /// Views for a 360° scan: the objects' pose in each sweep, relative to where the scene
    /// places them (`p ↦ pose · p`); the camera, board and laser stay. Empty: one view.
    pub views: Vec<Isometry3<f64>>,
    /// The objects' pose in this scene relative to where the file placed them (identity unless
    /// the scene is one of [`Scene::view`]s): the truth of a view's registration. Textures move
    /// with the objects.
    pub object_pose: Isometry3<f64>,
    /// The turntable disc the objects stand on, if any: one of the objects, printed.
    pub turntable: Option<Turntable>,
    /// Objects that stay put in every view (indices into `objects`): the table or stand a
    /// turntable sits on, which the hand turns do not move.
    pub fixed: Vec<usize>,
}

/// The printed turntable disc ([`scanner_calib::disc`]) under the objects: a [`Shape::Disc`]
/// among the objects, rendered with the print's ink, turning with the objects in every view.
#[derive(Debug, Clone, PartialEq)]
pub struct Turntable {
    /// Its index among the scene's objects.
    pub object: usize,
    /// The disc printed.
    pub disc: scanner_calib::disc::Disc,
    /// The printed sheet (its ink is what the camera sees).
    pub sheet: std::sync::Arc<scanner_calib::print::Sheet>,
    /// Disc frame → camera, where the file places it (before a view moves it).
    pub pose: Isometry3<f64>,
    /// RGB albedo of the ink.
    pub ink: [f64; 3],
    /// Views in which the disc was taken away (the object laid on its side on the table).
    pub absent_in: Vec<usize>,
}

/// The longest side of a rendered image, pixels (the head's [`scanner_core::config::MAX_LINES`]).
pub const MAX_SCENE_SIDE: u32 = scanner_core::config::MAX_LINES as u32;
/// Most pixels of a rendered image: a 4K UHD camera, 3840×2160 (the renderer keeps about 95
/// bytes per pixel: 0.8 GB at this size).
pub const MAX_SCENE_PIXELS: u64 = 3840 * 2160;

impl Scene {
    /// Whether the rig renders images of `width`×`height`: each side 2 to [`MAX_SCENE_SIDE`],
    /// at most [`MAX_SCENE_PIXELS`] in all.
    ///
    /// # Errors
    /// [`RigError::Scene`] naming the size and the limits.
    pub fn check_size(width: u32, height: u32) -> Result<(), RigError> {
        if (2..=MAX_SCENE_SIDE).contains(&width)
            && (2..=MAX_SCENE_SIDE).contains(&height)
            && u64::from(width) * u64::from(height) <= MAX_SCENE_PIXELS
        {
            return Ok(());
        }
        Err(RigError::Scene(format!(
            "image size {width}×{height}: each side must be 2 to {MAX_SCENE_SIDE} pixels and the image at most {MAX_SCENE_PIXELS} pixels (3840×2160)"
        )))
    }

    /// The demo scene: a right-angled board 800 mm away with the default board file's markers, a sphere and a cylinder in front of it,
    /// a red laser held 150 mm above the camera sweeping down over them; f = 0.875 × width px
    /// (1400 px at 1600 wide) with mild barrel distortion; sensor noise of a webcam.
    ///
    /// # Panics
    /// For a size that [`Scene::check_size`] refuses (check it first with sizes from outside).
    pub fn demo(width: u32, height: u32) -> Scene {
        let f = 0.875 * f64::from(width);
        let camera = Camera::new(
            f,
            f,
            (f64::from(width) - 1.0) / 2.0,
            (f64::from(height) - 1.0) / 2.0,
            scanner_core::Distortion {
                k1: -0.06,
                k2: 0.02,
                ..scanner_core::Distortion::none()
            },
        )
        .expect("valid demo camera");
        let d = 800.0;
        Scene {
            width,
            height,
            camera,
            board: BoardSpec {
                distance: d,
                angle_deg: 90.0,
                yaw_deg: 0.0,
                pitch_deg: 0.0,
                albedo: [0.8, 0.8, 0.78],
                markers: Markers::paper(110.0),
            },
            objects: vec![
                Object {
                    shape: Shape::Sphere {
                        centre: Point3::new(-40.0, 10.0, d - 300.0),
                        radius: 70.0,
                    },
                    albedo: [0.7, 0.6, 0.5],
                    texture: Some((25.0, [0.35, 0.55, 0.3])),
                },
                Object {
                    shape: Shape::Cylinder {
                        base: Point3::new(110.0, 90.0, d - 330.0),
                        axis: scanner_core::nalgebra::Unit::new_normalize(Vector3::new(
                            0.0, -1.0, 0.0,
                        )),
                        radius: 35.0,
                        height: 150.0,
                    },
                    albedo: [0.5, 0.6, 0.7],
                    texture: None,
                },
            ],
            laser: LaserSpec {
                source: Point3::new(20.0, -150.0, 30.0),
                sweep: (-150.0, 230.0),
                frames: 60,
                wobble_deg: 1.5,
                jitter_mm: 2.0,
                sigma_mm: 0.6,
                power: 3.0,
                colour: [1.0, 0.05, 0.02],
                speckle: 0.2,
                seed: 2012,
            },
            ambient: 0.45,
            blur_px: 1.0,
            flicker: 0.0,
            mains_hz: 50.0,
            fps: 30.0,
            exposure: 0.0,
            sensor: SensorSpec {
                gain: 200.0,
                read_noise: 1.5,
                shot_noise: 0.05,
                seed: 7,
            },
            views: Vec::new(),
            object_pose: Isometry3::identity(),
            turntable: None,
            fixed: Vec::new(),
        }
    }

    /// How many views the scene has (1 without a list of views).
    pub fn view_count(&self) -> usize {
        self.views.len().max(1)
    }

    /// View `k` as a scene of its own: the objects moved by the view's pose, which becomes the
    /// scene's [`Scene::object_pose`] (the truth for registration); the views list is dropped.
    ///
    /// # Errors
    /// [`RigError::Scene`] for a view the scene does not have.
    pub fn view(&self, k: usize) -> Result<Scene, RigError> {
        let pose = match (self.views.get(k), k) {
            (Some(p), _) => *p,
            (None, 0) if self.views.is_empty() => Isometry3::identity(),
            _ => {
                return Err(RigError::Scene(format!(
                    "view {k}: the scene has {} view(s), numbered from 0",
                    self.view_count()
                )));
            }
        };
        let mut s = self.clone();
        for (i, o) in s.objects.iter_mut().enumerate() {
            if !self.fixed.contains(&i) {
                o.shape = o.shape.moved(&pose);
            }
        }
        if let Some(t) = &s.turntable
            && t.absent_in.contains(&k)
            && let Some(Object {
                shape: Shape::Disc { radius, .. },
                ..
            }) = s.objects.get_mut(t.object)
        {
            *radius = 0.0;
        }
        s.object_pose = pose * self.object_pose;
        s.views = Vec::new();
        Ok(s)
    }
}

/// Why a rig could not be built or a frame rendered.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// A scene value is out of range; the text names it.
    #[error("bad scene: {0}")]
    Scene(String),
    /// An object's mesh file cannot be used.
    #[error("bad scene: objects[{object}]")]
    Mesh {
        /// Index of the object.
        object: usize,
        /// Why.
        #[source]
        source: mesh::MeshError,
    },
    /// Geometry failed (degenerate board).
    #[error("scene geometry")]
    Geometry(#[source] GeomError),
    /// Frame index past the sweep.
    #[error("frame {index} asked for, the sweep has {frames}")]
    NoSuchFrame {
        /// Asked for.
        index: usize,
        /// Frames in the sweep.
        frames: usize,
    },
}

/// The board as the rig needs it: planes and half directions.
#[derive(Debug, Clone)]
struct BoardGeometry {
    crease: Point3<f64>,
    /// Unit direction of the crease (the sheets' `v`).
    along: Vector3<f64>,
    halves: [(Plane<f64>, Vector3<f64>); 2],
}

impl BoardGeometry {
    fn new(b: &BoardSpec) -> Result<Self, RigError> {
        if !(b.distance > 0.0) || !(10.0..=175.0).contains(&b.angle_deg) {
            return Err(RigError::Scene(format!(
                "board distance {} mm and angle {}° (need > 0 and 10–175°)",
                b.distance, b.angle_deg
            )));
        }
        let half = b.angle_deg.to_radians() / 2.0;
        let g = Rotation3::from_euler_angles(b.pitch_deg.to_radians(), b.yaw_deg.to_radians(), 0.0);
        let c = g * Vector3::y();
        let crease = Point3::new(0.0, 0.0, b.distance);
        let mut halves = Vec::new();
        for sign in [-1.0, 1.0] {
            let h = g * Vector3::new(sign * half.sin(), 0.0, -half.cos());
            let plane = Plane::from_point_normal(&crease, &h.cross(&c))
                .map_err(RigError::Geometry)?
                .facing_camera();
            halves.push((plane, h));
        }
        Ok(Self {
            crease,
            along: c,
            halves: [halves[0], halves[1]],
        })
    }

    /// Sheet coordinates `(u, v)` of a point on half `k`.
    fn sheet(&self, k: usize, p: &Point3<f64>) -> [f64; 2] {
        let r = p - self.crease;
        [r.dot(&self.halves[k].1), r.dot(&self.along)]
    }

    /// The point of half `k` at sheet coordinates `(u, v)`.
    fn point(&self, k: usize, uv: [f64; 2]) -> Point3<f64> {
        self.crease + self.halves[k].1 * uv[0] + self.along * uv[1]
    }

    /// The left and right planes (normals towards the camera).
    fn planes(&self) -> [Plane<f64>; 2] {
        [self.halves[0].0, self.halves[1].0]
    }

    fn hit(&self, dir: &Vector3<f64>) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (k, (plane, h)) in self.halves.iter().enumerate() {
            let Ok(p) = plane.intersect_ray(dir, 1e-9) else {
                continue;
            };
            if (p - self.crease).dot(h) < 0.0 {
                continue;
            }
            let t = p.coords.norm();
            if best.is_none_or(|b| t < b.t) {
                best = Some(Hit {
                    t,
                    point: p,
                    normal: *plane.normal(),
                    surface: if k == 0 {
                        SurfaceId::Left
                    } else {
                        SurfaceId::Right
                    },
                });
            }
        }
        best
    }
}

/// One pixel of the geometry buffer: the surface point its centre sees.
#[derive(Debug, Clone, Copy)]
struct Texel {
    point: [f32; 3],
    /// Index into the albedo table: 0, 1 board halves, 2 + n object n; `u16::MAX` nothing.
    surface: u16,
}

/// A laser source and its light plane.
pub type Laser = (Point3<f64>, Plane<f64>);

/// Ground truth of one column of one laser frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColumnTruth {
    /// Row (subpixel, pixel centres at integers) where the laser plane meets the visible surface.
    pub row: f64,
    /// The 3-D point there, camera coordinates, mm.
    pub point: Point3<f64>,
    /// The surface it lies on.
    pub surface: SurfaceId,
    /// Cosine of the laser's angle of incidence there (1 head-on, near 0 at the terminator,
    /// where part of the stripe falls in the surface's own shadow).
    pub incidence: f64,
}

/// A rendered frame in RGB, 8 bits per channel, rows packed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rgb8 {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// `width × height × 3` bytes.
    pub data: Vec<u8>,
}

impl Rgb8 {
    /// The frame's luma as an `image` gray image (what calibration reads).
    pub fn to_gray_image(&self) -> image::GrayImage {
        image::GrayImage::from_raw(
            self.width as u32,
            self.height as u32,
            self.to_format(PixelFormat::Gray8),
        )
        .expect("width × height bytes")
    }

    /// The frame in another pixel format, rows packed: gray is the luma, YUYV carries the luma
    /// of each pixel and the chroma of each pair.
    pub fn to_format(&self, format: PixelFormat) -> Vec<u8> {
        use scanner_core::colour::{luma, rgb_pair_to_yuyv};
        match format {
            PixelFormat::Rgb24 => self.data.clone(),
            PixelFormat::Gray8 => self
                .data
                .chunks_exact(3)
                .map(|p| luma([p[0], p[1], p[2]]))
                .collect(),
            PixelFormat::Yuyv => self
                .data
                .chunks_exact(6)
                .flat_map(|p| rgb_pair_to_yuyv([p[0], p[1], p[2]], [p[3], p[4], p[5]]))
                .collect(),
        }
    }
}

/// The rig: a scene with its geometry buffer.
#[derive(Debug, Clone)]
pub struct Rig {
    scene: Scene,
    board: BoardGeometry,
    /// Undistorted normalised coordinates of each pixel centre (NaN where undefined), for
    /// interpolating sub-pixel rays.
    normalised: Vec<[f32; 2]>,
    texels: Vec<Texel>,
    /// The ambient image, blurred once.
    ambient: Vec<[f32; 3]>,
    /// Normalised 1-D lens-blur kernel (odd length; `[1]` without blur).
    kernel: Vec<f64>,
}

use scanner_calib::blur::{blur, gaussian_kernel};

/// Largest footprint of a pixel across the light plane the renderer expects, mm: beyond
/// `5σ +` this from the plane a pixel is not examined further.
const FOOTPRINT_BOUND_MM: f64 = 40.0;

/// Largest distance the light plane sweeps over a surface point during one exposure the
/// renderer expects, mm (beyond it pixels are not examined).
const MOTION_BOUND_MM: f64 = 40.0;
/// Light planes averaged over an exposure with motion blur.
const MOTION_SAMPLES: usize = 5;

/// Sub-samples per pixel side near a marker's rim.
const RIM_SUPERSAMPLE: usize = 6;

/// Sub-samples per pixel side near the stripe.
const SUPERSAMPLE: usize = 3;

impl Rig {
    /// Builds the rig: one ray per pixel, cast once.
    ///
    /// # Errors
    /// [`RigError::Scene`] for out-of-range values, [`RigError::Geometry`] for a degenerate board.
    pub fn new(scene: Scene) -> Result<Rig, RigError> {
        Scene::check_size(scene.width, scene.height)?;
        if scene.laser.frames == 0 {
            return Err(RigError::Scene(
                "the laser sweep needs at least one frame".into(),
            ));
        }
        if !(scene.laser.sigma_mm > 0.0) {
            return Err(RigError::Scene(
                "laser thickness sigma_mm must be positive".into(),
            ));
        }
        if !(0.0..=10.0).contains(&scene.blur_px) {
            return Err(RigError::Scene(format!(
                "lens blur {} px (need 0–10)",
                scene.blur_px
            )));
        }
        let board = BoardGeometry::new(&scene.board)?;
        let (w, h) = (scene.width as usize, scene.height as usize);
        let scene_blur = scene.blur_px;
        let mut rig = Rig {
            scene,
            board,
            texels: vec![
                Texel {
                    point: [0.0; 3],
                    surface: u16::MAX
                };
                w * h
            ],
            normalised: vec![[f32::NAN; 2]; w * h],
            ambient: Vec::new(),
            kernel: gaussian_kernel(scene_blur),
        };
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                if let Ok(n) = rig.scene.camera.undistort(&Point2::new(u as f64, v as f64)) {
                    rig.normalised[i] = [n.x as f32, n.y as f32];
                }
                if let Some(hit) = rig.ray(u as f64, v as f64).and_then(|dir| rig.cast(&dir)) {
                    rig.texels[i] = Texel {
                        point: [hit.point.x as f32, hit.point.y as f32, hit.point.z as f32],
                        surface: surface_index(hit.surface),
                    };
                }
            }
        }
        let amb = rig.scene.ambient;
        let fx = rig.scene.camera.fx();
        let mut flat = vec![[0.0; 3]; w * h];
        for (i, t) in rig.texels.iter().enumerate() {
            if t.surface == u16::MAX {
                continue;
            }
            let p = texel_point(t);
            let surface = surface_id(t.surface);
            let k = usize::from(t.surface);
            // near a marker's rim or the turntable's ink: the pixel's coverage by sub-samples, so
            // that markers are rendered without aliasing (their centres are ground truth)
            let albedo = if rig.to_ink_edge(k, &p) < 6.0 * p.coords.norm() / fx {
                let n = RIM_SUPERSAMPLE * RIM_SUPERSAMPLE;
                let mut sum = [0.0; 3];
                for (su, sv) in subpixels(i % w, i / w, RIM_SUPERSAMPLE) {
                    let hit = rig.ray_fast(su, sv).and_then(|d| rig.cast(&d));
                    let a = hit.map_or([0.0; 3], |hit| rig.albedo_of(hit.surface, &hit.point));
                    for c in 0..3 {
                        sum[c] += a[c] / n as f64;
                    }
                }
                sum
            } else {
                rig.albedo_of(surface, &p)
            };
            flat[i] = albedo.map(|a| amb * a);
        }
        rig.ambient = blur(&flat, w, h, &rig.kernel)
            .into_iter()
            .map(|p| p.map(|v| v as f32))
            .collect();
        Ok(rig)
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The true board planes, left and right, normals towards the camera.
    pub fn board_planes(&self) -> [Plane<f64>; 2] {
        self.board.planes()
    }

    /// Unit ray through the (subpixel) image point `(u, v)`.
    fn ray(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        let r = self.scene.camera.pixel_to_ray(&Point2::new(u, v)).ok()?;
        Some(r.normalize())
    }

    /// The albedo at a surface point: the marker ink inside a marker of a board sheet.
    fn albedo_of(&self, surface: SurfaceId, p: &Point3<f64>) -> [f64; 3] {
        let k = match surface {
            SurfaceId::Left => 0,
            SurfaceId::Right => 1,
            SurfaceId::Object(n) => {
                let o = &self.scene.objects[usize::from(n)];
                // The checker is fixed to the object: evaluated where the point was before the
                // view moved it (a fixed object never moved).
                let p = if self.scene.fixed.contains(&usize::from(n)) {
                    *p
                } else {
                    self.scene.object_pose.inverse_transform_point(p)
                };
                if let Some(t) = &self.scene.turntable
                    && t.object == usize::from(n)
                {
                    let q = t.pose.inverse_transform_point(&p);
                    let (x, y) = t.disc.to_sheet(&Point2::new(q.x, q.y));
                    return if t.sheet.ink(x, y) { t.ink } else { o.albedo };
                }
                return match o.texture {
                    Some((cell, other)) if cell > 0.0 => {
                        let parity = (p.x / cell).floor() as i64
                            + (p.y / cell).floor() as i64
                            + (p.z / cell).floor() as i64;
                        if parity.rem_euclid(2) == 0 {
                            o.albedo
                        } else {
                            other
                        }
                    }
                    _ => o.albedo,
                };
            }
        };
        let m = &self.scene.board.markers;
        let uv = self.board.sheet(k, p);
        if let Some(c) = &m.chess[k] {
            return match c.ink(uv) {
                Some(true) => m.albedo,
                _ => self.scene.board.albedo,
            };
        }
        let r2 = (m.diameter / 2.0).powi(2);
        let list = if k == 0 { &m.left } else { &m.right };
        if list
            .iter()
            .any(|c| (uv[0] - c[0]).powi(2) + (uv[1] - c[1]).powi(2) <= r2)
        {
            m.albedo
        } else {
            self.scene.board.albedo
        }
    }

    /// Distance (mm) from `p` on surface `k` (its index in the geometry buffer) to the nearest
    /// edge of printed ink: a board marker's rim or the turntable's print.
    fn to_ink_edge(&self, k: usize, p: &Point3<f64>) -> f64 {
        if k < 2 {
            return self.to_rim(k, p);
        }
        match &self.scene.turntable {
            Some(t) if t.object + 2 == k => {
                let q = t
                    .pose
                    .inverse_transform_point(&self.scene.object_pose.inverse_transform_point(p));
                let (x, y) = t.disc.to_sheet(&Point2::new(q.x, q.y));
                t.sheet.ink_edge_distance(x, y)
            }
            _ => f64::INFINITY,
        }
    }

    /// The turntable disc's pose (disc frame → camera) in this scene's view: `None` without a
    /// disc or when the view took it away.
    pub fn disc_pose(&self) -> Option<Isometry3<f64>> {
        let t = self.scene.turntable.as_ref()?;
        match self.scene.objects.get(t.object)?.shape {
            Shape::Disc { radius, .. } if radius > 0.0 => Some(self.scene.object_pose * t.pose),
            _ => None,
        }
    }

    /// Distance (mm) from `p` on half `k` to the nearest marker's rim.
    fn to_rim(&self, k: usize, p: &Point3<f64>) -> f64 {
        let m = &self.scene.board.markers;
        let uv = self.board.sheet(k, p);
        if let Some(c) = &m.chess[k] {
            return c.edge_distance(uv);
        }
        let list = if k == 0 { &m.left } else { &m.right };
        list.iter()
            .map(|c| {
                (((uv[0] - c[0]).powi(2) + (uv[1] - c[1]).powi(2)).sqrt() - m.diameter / 2.0).abs()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The ground truth of every printed marker.
    pub fn markers(&self) -> Vec<MarkerTruth> {
        let m = &self.scene.board.markers;
        let cam = &self.scene.camera;
        let (w, h) = (f64::from(self.scene.width), f64::from(self.scene.height));
        let mut out = Vec::new();
        for (k, (surface, list)) in [(SurfaceId::Left, &m.left), (SurfaceId::Right, &m.right)]
            .into_iter()
            .enumerate()
        {
            if let Some(c) = &m.chess[k] {
                // Corners: seen when the camera sees the board at the corner and around it.
                for (index, sheet) in c.corners().into_iter().enumerate() {
                    let centre = self.board.point(k, sheet);
                    let Ok(centre_px) = cam.project(&centre) else {
                        continue;
                    };
                    let r = 0.3 * c.square;
                    let visible = (0..16).all(|i| {
                        let a = f64::from(i) / 16.0 * std::f64::consts::TAU;
                        let p = self
                            .board
                            .point(k, [sheet[0] + r * a.cos(), sheet[1] + r * a.sin()]);
                        cam.project(&p).is_ok_and(|px| {
                            px.x >= 0.0 && px.y >= 0.0 && px.x <= w - 1.0 && px.y <= h - 1.0
                        }) && self.cast(&p.coords.normalize()).is_some_and(|hit| {
                            hit.surface == surface
                                && (hit.point - p).norm() < 1e-6 * p.coords.norm() + 1e-9
                        })
                    });
                    out.push(MarkerTruth {
                        surface,
                        index,
                        sheet,
                        centre,
                        centre_px,
                        disc_px: centre_px,
                        visible,
                    });
                }
                continue;
            }
            for (index, &sheet) in list.iter().enumerate() {
                let centre = self.board.point(k, sheet);
                let Ok(centre_px) = cam.project(&centre) else {
                    continue;
                };
                // the rim, projected: polygon centroid (Green's theorem) of 720 points
                let rim: Vec<Option<Point2<f64>>> = (0..720)
                    .map(|i| {
                        let a = i as f64 / 720.0 * std::f64::consts::TAU;
                        let r = m.diameter / 2.0;
                        let p = self
                            .board
                            .point(k, [sheet[0] + r * a.cos(), sheet[1] + r * a.sin()]);
                        let px = cam.project(&p).ok()?;
                        // in view, and the board is what the camera sees there
                        let seen = self.cast(&p.coords.normalize()).is_some_and(|hit| {
                            hit.surface == surface
                                && (hit.point - p).norm() < 1e-6 * p.coords.norm() + 1e-9
                        });
                        (seen && px.x >= 0.0 && px.y >= 0.0 && px.x <= w - 1.0 && px.y <= h - 1.0)
                            .then_some(px)
                    })
                    .collect();
                let visible = rim.iter().all(Option::is_some);
                let pts: Vec<Point2<f64>> = rim.iter().map(|p| p.unwrap_or(centre_px)).collect();
                let disc_px = polygon_centroid(&pts).unwrap_or(centre_px);
                out.push(MarkerTruth {
                    surface,
                    index,
                    sheet,
                    centre,
                    centre_px,
                    disc_px,
                    visible,
                });
            }
        }
        out
    }

    /// Unit ray through `(u, v)` interpolated bilinearly between the stored pixel centres
    /// (distortion is smooth: the error is far below a thousandth of a pixel); for rendering.
    fn ray_fast(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let u = u.clamp(0.0, (w - 1) as f64);
        let v = v.clamp(0.0, (h - 1) as f64);
        let (u0, v0) = (
            (u.floor() as usize).min(w - 2),
            (v.floor() as usize).min(h - 2),
        );
        let (fu, fv) = (u - u0 as f64, v - v0 as f64);
        let at = |uu: usize, vv: usize| self.normalised[vv * w + uu];
        let (a, b, c, d) = (
            at(u0, v0),
            at(u0 + 1, v0),
            at(u0, v0 + 1),
            at(u0 + 1, v0 + 1),
        );
        let lerp = |k: usize| {
            let top = f64::from(a[k]) * (1.0 - fu) + f64::from(b[k]) * fu;
            let bottom = f64::from(c[k]) * (1.0 - fu) + f64::from(d[k]) * fu;
            top * (1.0 - fv) + bottom * fv
        };
        let r = Vector3::new(lerp(0), lerp(1), 1.0);
        r.iter().all(|x| x.is_finite()).then(|| r.normalize())
    }

    /// Distance from `p` to the nearest true surface (a board sheet or an object), mm: how far a
    /// measured point is from what it measured.
    pub fn surface_distance(&self, p: &Point3<f64>) -> f64 {
        let mut best = f64::INFINITY;
        for k in 0..2 {
            let (plane, h) = &self.board.halves[k];
            let u = (p - self.board.crease).dot(h);
            let d = if u >= 0.0 {
                plane.signed_distance(p).abs()
            } else {
                // Beyond the crease: the distance to the crease line.
                let r = p - self.board.crease;
                (r - self.board.along * r.dot(&self.board.along)).norm()
            };
            best = best.min(d);
        }
        for o in &self.scene.objects {
            if let Some(d) = o.shape.distance(p) {
                best = best.min(d);
            }
        }
        best
    }

    /// The nearest surface along a unit ray from the camera centre.
    pub fn cast(&self, dir: &Vector3<f64>) -> Option<Hit> {
        let mut best = self.board.hit(dir);
        for (k, o) in self.scene.objects.iter().enumerate() {
            if let Some(h) = o.shape.hit(&Point3::origin(), dir, 1e-9, k as u16)
                && best.is_none_or(|b| h.t < b.t)
            {
                best = Some(h);
            }
        }
        best
    }

    /// `true` if an object lies between `p` and the laser source `s`.
    fn shadowed(&self, p: &Point3<f64>, s: &Point3<f64>) -> bool {
        let to = s - p;
        let dist = to.norm();
        let dir = to / dist;
        self.scene.objects.iter().enumerate().any(|(k, o)| {
            o.shape
                .hit(p, &dir, 1e-6, k as u16)
                .is_some_and(|h| h.t < dist - 1e-6)
        })
    }

    /// The laser's source and light plane in frame `index` of the sweep (at the middle of its
    /// exposure).
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep.
    pub fn laser(&self, index: usize) -> Result<Laser, RigError> {
        let l = &self.scene.laser;
        if index >= l.frames {
            return Err(RigError::NoSuchFrame {
                index,
                frames: l.frames,
            });
        }
        self.laser_at(index as f64)
    }

    /// The laser at time `t` in frame periods: the aim moves linearly through the sweep, the hand's
    /// wobble and jitter are random per frame and move linearly between frames.
    fn laser_at(&self, t: f64) -> Result<Laser, RigError> {
        let l = &self.scene.laser;
        let t = t.clamp(0.0, (l.frames - 1) as f64);
        let shake = |k: usize| -> [f64; 4] {
            let mut rng =
                SmallRng::seed_from_u64(l.seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            core::array::from_fn(|_| rng.random_range(-1.0..=1.0))
        };
        let (k0, f) = (t.floor() as usize, t - t.floor());
        let (a, b) = (shake(k0), shake(k0 + 1));
        let j: [f64; 4] = core::array::from_fn(|i| a[i] * (1.0 - f) + b[i] * f);
        let frac = if l.frames > 1 {
            t / (l.frames - 1) as f64
        } else {
            0.5
        };
        let height = l.sweep.0 + (l.sweep.1 - l.sweep.0) * frac;
        let source = l.source + Vector3::new(j[0], j[1], j[2]) * l.jitter_mm;
        let roll = (j[3] * l.wobble_deg).to_radians();
        // the plane holds the (rolled) horizontal direction and the aim point on the crease line
        let along = Rotation3::from_axis_angle(&Vector3::z_axis(), roll) * Vector3::x();
        let aim = Point3::new(0.0, height, self.scene.board.distance);
        let plane = Plane::from_point_normal(&source, &along.cross(&(aim - source)))
            .map_err(RigError::Geometry)?
            .facing_camera();
        Ok((source, plane))
    }

    /// The light planes the exposure of frame `index` averages (one without motion blur).
    fn exposure_planes(&self, index: usize) -> Result<Vec<Laser>, RigError> {
        self.laser(index)?;
        let e = self.scene.exposure;
        if e == 0.0 {
            return Ok(vec![self.laser_at(index as f64)?]);
        }
        (0..MOTION_SAMPLES)
            .map(|i| {
                let s = (i as f64 + 0.5) / MOTION_SAMPLES as f64 - 0.5;
                self.laser_at(index as f64 + e * s)
            })
            .collect()
    }

    /// Laser irradiance (per unit albedo and colour) at a surface point.
    fn laser_light(
        &self,
        p: &Point3<f64>,
        n: &Vector3<f64>,
        source: &Point3<f64>,
        plane: &Plane<f64>,
    ) -> f64 {
        let l = &self.scene.laser;
        let d = plane.signed_distance(p);
        let across = (-(d * d) / (2.0 * l.sigma_mm * l.sigma_mm)).exp();
        if across < 1e-7 {
            return 0.0;
        }
        let to = source - p;
        let dist2 = to.norm_squared();
        let cos = n.dot(&to) / dist2.sqrt();
        if cos <= 0.0 || self.shadowed(p, source) {
            return 0.0;
        }
        l.power * across * cos * 1e6 / dist2 * speckle(p, l.speckle)
    }

    /// The radiance image (RGB, row-major) of the scene lit by ambient light and, if given, by the
    /// laser of frame `laser`.
    fn radiance(&self, time: f64, lasers: &[Laser]) -> Vec<[f32; 3]> {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        // mains flicker: light intensity follows |sin| of the mains, i.e. twice its frequency
        let phase = 2.0 * std::f64::consts::PI * 2.0 * self.scene.mains_hz * time / self.scene.fps;
        let level = (1.0 + self.scene.flicker * phase.sin()) as f32;
        let mut out: Vec<[f32; 3]> = self.ambient.iter().map(|p| p.map(|v| v * level)).collect();
        let Some(&(_, plane)) = lasers.get(lasers.len() / 2) else {
            return out;
        };
        // how far the plane moves during the exposure, at each pixel's surface point
        let (first, last) = (lasers[0].1, lasers[lasers.len() - 1].1);
        let colour = self.scene.laser.colour;
        let sigma = self.scene.laser.sigma_mm;
        // distance of each pixel's surface point from the light plane, and its change to the
        // neighbours (the pixel's footprint across the plane)
        let dist: Vec<f64> = self
            .texels
            .iter()
            .map(|t| {
                if t.surface == u16::MAX {
                    f64::INFINITY
                } else {
                    plane.signed_distance(&Point3::new(
                        f64::from(t.point[0]),
                        f64::from(t.point[1]),
                        f64::from(t.point[2]),
                    ))
                }
            })
            .collect();
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let d = dist[i];
                // far from the plane (or no surface): no laser light, without looking further
                if !(d.abs() <= 5.0 * sigma + FOOTPRINT_BOUND_MM + MOTION_BOUND_MM) {
                    continue;
                }
                let mut foot = 0.0f64;
                for (du, dv) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (uu, vv) = (u as i64 + du, v as i64 + dv);
                    if uu >= 0 && vv >= 0 && (uu as usize) < w && (vv as usize) < h {
                        let e = dist[vv as usize * w + uu as usize];
                        if e.is_finite() {
                            foot = foot.max((e - d).abs());
                        }
                    }
                }
                let p = texel_point(&self.texels[i]);
                let sweep = (first.signed_distance(&p) - last.signed_distance(&p)).abs();
                if d.abs() > 5.0 * sigma + foot + sweep {
                    continue;
                }
                // supersample the pixel (interpolated sub-pixel rays, each cast into the scene)
                let mut sum = [0.0; 3];
                let n = SUPERSAMPLE * SUPERSAMPLE;
                for (su, sv) in subpixels(u, v, SUPERSAMPLE) {
                    let Some(dir) = self.ray_fast(su, sv) else {
                        continue;
                    };
                    let Some(hit) = self.cast(&dir) else { continue };
                    let e = lasers
                        .iter()
                        .map(|(s, p)| self.laser_light(&hit.point, &hit.normal, s, p))
                        .sum::<f64>()
                        / lasers.len() as f64;
                    let a = self.albedo_of(hit.surface, &hit.point);
                    for c in 0..3 {
                        sum[c] += e * a[c] * colour[c];
                    }
                }
                // through the lens: splat the pixel's laser light with the blur kernel
                let r = self.kernel.len() / 2;
                for (jv, kv) in self.kernel.iter().enumerate() {
                    let Some(vv) = (v + jv).checked_sub(r).filter(|&vv| vv < h) else {
                        continue;
                    };
                    for (ju, ku) in self.kernel.iter().enumerate() {
                        let Some(uu) = (u + ju).checked_sub(r).filter(|&uu| uu < w) else {
                            continue;
                        };
                        let k = kv * ku / n as f64;
                        for c in 0..3 {
                            out[vv * w + uu][c] += (k * sum[c]) as f32;
                        }
                    }
                }
            }
        }
        out
    }

    /// Radiance → 8-bit RGB through the sensor; `noise_seed` picks the noise realisation.
    fn expose(&self, radiance: &[[f32; 3]], noise_seed: u64) -> Rgb8 {
        let s = &self.scene.sensor;
        let mut rng = SmallRng::seed_from_u64(s.seed ^ noise_seed);
        let noisy = s.read_noise > 0.0 || s.shot_noise > 0.0;
        let mut data = Vec::with_capacity(radiance.len() * 3);
        for px in radiance {
            for &r in px {
                let mut v = s.gain * f64::from(r);
                if noisy {
                    let sd = (s.read_noise * s.read_noise + s.shot_noise * v.max(0.0)).sqrt();
                    v += sd * unit_normal(rng.random::<u64>());
                }
                data.push(v.round().clamp(0.0, 255.0) as u8);
            }
        }
        Rgb8 {
            width: self.scene.width as usize,
            height: self.scene.height as usize,
            data,
        }
    }

    /// The reference frame: ambient light only, laser off.
    pub fn reference(&self) -> Rgb8 {
        self.expose(&self.radiance(-1.0, &[]), u64::MAX)
    }

    /// Laser frame `index` of the sweep.
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep.
    pub fn frame(&self, index: usize) -> Result<Rgb8, RigError> {
        let lasers = self.exposure_planes(index)?;
        Ok(self.expose(&self.radiance(index as f64, &lasers), index as u64))
    }

    /// The ground truth of laser frame `index`: per column, where the light plane meets the
    /// visible, lit surface — `None` where it does not, or where it does at more than one place
    /// (the stripe broken by an occluding edge).
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep.
    pub fn truth(&self, index: usize) -> Result<Vec<Option<ColumnTruth>>, RigError> {
        let (source, plane) = self.laser(index)?;
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let signed = |u: f64, v: f64| -> Option<(f64, Hit)> {
            let hit = self.cast(&self.ray(u, v)?)?;
            Some((plane.signed_distance(&hit.point), hit))
        };
        let mut out = vec![None; w];
        for (u, slot) in out.iter_mut().enumerate() {
            let mut found = Vec::new();
            for v in 0..h - 1 {
                let (a, b) = (&self.texels[v * w + u], &self.texels[(v + 1) * w + u]);
                if a.surface == u16::MAX || a.surface != b.surface {
                    continue;
                }
                let da = plane.signed_distance(&texel_point(a));
                let db = plane.signed_distance(&texel_point(b));
                if da == 0.0 || da.signum() != db.signum() {
                    found.push(v);
                }
            }
            // refine each crossing by bisection on exact rays; keep the lit ones
            let mut lit = Vec::new();
            for &v0 in &found {
                let (mut lo, mut hi) = (v0 as f64, v0 as f64 + 1.0);
                let Some((dlo, _)) = signed(u as f64, lo) else {
                    continue;
                };
                for _ in 0..50 {
                    let mid = (lo + hi) / 2.0;
                    let Some((dm, _)) = signed(u as f64, mid) else {
                        break;
                    };
                    if dm.signum() == dlo.signum() {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let row = (lo + hi) / 2.0;
                let Some((_, hit)) = signed(u as f64, row) else {
                    continue;
                };
                // on the plane (d ≈ 0): lit unless shadowed or facing away from the source
                if self.laser_light(&hit.point, &hit.normal, &source, &plane) > 0.0 {
                    lit.push(ColumnTruth {
                        row,
                        point: hit.point,
                        surface: hit.surface,
                        incidence: hit.normal.dot(&(source - hit.point).normalize()),
                    });
                }
            }
            if let [only] = lit[..] {
                *slot = Some(only);
            }
        }
        Ok(out)
    }
}

/// An approximately standard-normal number from 64 random bits: the sum of four 16-bit
/// uniforms, centred and scaled to unit variance (Irwin–Hall; tails end at ±3.46σ, which is
/// immaterial for sensor noise and four times cheaper than an exact sampler).
#[inline]
fn unit_normal(bits: u64) -> f64 {
    let sum = (bits & 0xFFFF) + ((bits >> 16) & 0xFFFF) + ((bits >> 32) & 0xFFFF) + (bits >> 48);
    // four uniforms on [0, 1): mean 2, variance 4/12
    (sum as f64 / 65536.0 - 2.0) * 3f64.sqrt()
}

/// Speckle: a fixed grain of mean 1 on the lit surface, from a hash of the 0.25 mm cell that holds
/// `p`: `(1 − c) + c · E` with `E` exponential (fully developed speckle) and contrast `c`.
fn speckle(p: &Point3<f64>, contrast: f64) -> f64 {
    if contrast == 0.0 {
        return 1.0;
    }
    let cell = |v: f64| (v / 0.25).floor() as i64 as u64;
    let mut x = cell(p.x).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ cell(p.y).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ cell(p.z).wrapping_mul(0x1656_67B1_9E37_79F9);
    // splitmix64 finaliser
    x ^= x >> 30;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^= x >> 31;
    let u = ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    (1.0 - contrast) + contrast * -u.ln()
}

/// The centres of an `n × n` grid of sub-samples of pixel `(u, v)`, pixel centres at integers.
pub(crate) fn subpixels(u: usize, v: usize, n: usize) -> impl Iterator<Item = (f64, f64)> {
    let step = 1.0 / n as f64;
    (0..n * n).map(move |k| {
        let (sx, sy) = (k % n, k / n);
        (
            u as f64 + (sx as f64 + 0.5) * step - 0.5,
            v as f64 + (sy as f64 + 0.5) * step - 0.5,
        )
    })
}

/// Area centroid of a closed polygon (Green's theorem); `None` for a degenerate one.
fn polygon_centroid(pts: &[Point2<f64>]) -> Option<Point2<f64>> {
    let (mut a2, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..pts.len() {
        let (p, q) = (pts[i], pts[(i + 1) % pts.len()]);
        let cross = p.x * q.y - q.x * p.y;
        a2 += cross;
        cx += (p.x + q.x) * cross;
        cy += (p.y + q.y) * cross;
    }
    (a2.abs() > 1e-12).then(|| Point2::new(cx / (3.0 * a2), cy / (3.0 * a2)))
}

fn texel_point(t: &Texel) -> Point3<f64> {
    Point3::new(
        f64::from(t.point[0]),
        f64::from(t.point[1]),
        f64::from(t.point[2]),
    )
}

fn surface_id(index: u16) -> SurfaceId {
    match index {
        0 => SurfaceId::Left,
        1 => SurfaceId::Right,
        n => SurfaceId::Object(n - 2),
    }
}

fn surface_index(s: SurfaceId) -> u16 {
    match s {
        SurfaceId::Left => 0,
        SurfaceId::Right => 1,
        SurfaceId::Object(n) => 2 + n,
    }
}

impl From<&scanner_calib::board::Chessboard> for Chess {
    fn from(c: &scanner_calib::board::Chessboard) -> Self {
        Chess {
            cols: c.cols,
            rows: c.rows,
            square: c.square,
            u0: c.u0,
            v0: c.v0,
        }
    }
}

impl From<&scanner_calib::board::BoardFile> for Markers {
    /// The markers a board file prints (for rendering it).
    fn from(b: &scanner_calib::board::BoardFile) -> Self {
        let discs = |s: &scanner_calib::board::SheetLayout| {
            if s.chessboard.is_some() {
                Vec::new()
            } else {
                s.points().iter().map(|p| [p.x, p.y]).collect()
            }
        };
        Markers {
            left: discs(&b.left),
            right: discs(&b.right),
            diameter: b.marker_diameter,
            albedo: [0.06, 0.06, 0.06],
            chess: [
                b.left.chessboard.as_ref().map(Chess::from),
                b.right.chessboard.as_ref().map(Chess::from),
            ],
        }
    }
}

impl Rig {
    /// The laser speckle's share of a stripe centre's uncertainty on this rig, pixels, as
    /// [`scanner_calib::speckle::stripe_scatter`] measures it with `camera` and `board` on frames
    /// of the scene's bare board (objects taken away) at a quarter, half and three quarters of
    /// the sweep; `None` when no frame shows the stripe across a sheet.
    pub fn speckle(
        &self,
        camera: &Camera<f64>,
        board: &scanner_core::geometry::Board<f64>,
    ) -> Option<f64> {
        use scanner_core::stripe::{Axis, Frame, Method, PixelFormat, StripeConfig};
        let mut bare = self.scene.clone();
        bare.objects.clear();
        let rig = Rig::new(bare).ok()?;
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let reference = rig.reference().to_format(PixelFormat::Gray8);
        let rf = Frame::packed(&reference, w, h, PixelFormat::Gray8).ok()?;
        let n = self.scene.laser.frames;
        let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
        let sq: Vec<f64> = [n / 4, n / 2, 3 * n / 4]
            .into_iter()
            .filter_map(|k| {
                let data = rig.frame(k).ok()?.to_format(PixelFormat::Gray8);
                let f = Frame::packed(&data, w, h, PixelFormat::Gray8).ok()?;
                let s =
                    scanner_calib::speckle::stripe_scatter(&f, &rf, camera, board, &cfg).ok()?;
                Some(s.speckle_px * s.speckle_px)
            })
            .collect();
        (!sq.is_empty()).then(|| (sq.iter().sum::<f64>() / sq.len() as f64).sqrt())
    }

    /// The rig's true camera and board as a calibration file (what a perfect calibration
    /// would give; for tests and benches that want the truth, not an estimate), with the rig's
    /// speckle measured ([`Rig::speckle`]).
    ///
    /// # Panics
    /// Never for a rig built from a valid scene (its board's planes meet).
    pub fn truth_calibration(&self) -> scanner_calib::file::CalibrationFile {
        use scanner_calib::file::{BoardSection, CalibrationFile, SheetSection};
        let s = self.scene();
        let mut f = CalibrationFile::from_camera(
            &s.camera,
            (s.width, s.height),
            "the virtual rig's true camera".into(),
            None,
        );
        let [l, r] = self.board_planes();
        let board = scanner_core::geometry::Board::new(l, r).expect("the rig's board is valid");
        f.camera.speckle_px = self.speckle(&s.camera, &board);
        let [l, r] = self.board_planes();
        let sheet = |p: &Plane<f64>| SheetSection {
            normal: (*p.normal()).into(),
            offset: p.offset(),
            rms_px: 0.0,
            plane_covariance: None,
            plane_from_intrinsics: None,
            markers: Vec::new(),
        };
        let board = scanner_core::geometry::Board::new(l, r).expect("the rig's board is valid");
        f.board = Some(BoardSection {
            method: "rig-truth".into(),
            angle_deg: board.angle().to_degrees(),
            crease_point: board.crease().point().coords.into(),
            crease_direction: (*board.crease().direction()).into(),
            left: sheet(&l),
            right: sheet(&r),
            paper: None,
        });
        f
    }

    /// `n` rendered shots of a dot grid in front of the rig's camera
    /// ([`target::TargetPose::sweep`] poses), gray.
    pub fn dot_grid_shots(&self, grid: &scanner_calib::DotGrid, n: usize) -> Vec<image::GrayImage> {
        let pattern = target::Pattern::from(grid);
        (0..n)
            .map(|i| {
                self.shot(&pattern, &target::TargetPose::sweep(i, n), i as u64)
                    .image
                    .to_gray_image()
            })
            .collect()
    }
}
