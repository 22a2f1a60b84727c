//! What the rig shows: the camera, the two-plane board, the objects, the laser's sweep, the
//! light and the sensor ([`Scene`]), read from TOML or built in code.

use scanner_core::Camera;
use scanner_core::geometry::Plane;
use scanner_core::nalgebra::{Isometry3, Point2, Point3, Rotation3, Vector3};

use crate::error::RigError;
use crate::surface::{Hit, Shape, SurfaceId};

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
    pub(crate) fn ink(&self, uv: [f64; 2]) -> Option<bool> {
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
    pub(crate) fn edge_distance(&self, uv: [f64; 2]) -> f64 {
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
    /// A fixed laser (a turntable scanner's): the light plane through `source` with this normal
    /// in every frame, no sweep, wobble or jitter. `None`: the hand-held sweep.
    pub fixed: Option<Vector3<f64>>,
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
    pub turntable: Option<TurntableSpec>,
    /// Objects that stay put in every view (indices into `objects`): the table or stand a
    /// turntable sits on, which the hand turns do not move.
    pub fixed: Vec<usize>,
    /// A shadow sweep instead of a laser's: a lamp at the laser's source lights the scene and a
    /// rod held in front of it casts its shadow, swept as the laser would be (its `sweep`,
    /// `frames`, wobble and jitter); the reference frame is the scene lit without the rod.
    pub shadow: Option<ShadowSpec>,
    /// Where the virtual operator holds the intrinsics target for the first calibration shots,
    /// in order; later shots take [`TargetPose::guided`]'s poses.
    pub shots: Vec<TargetPose>,
}

/// The lamp and the rod of a shadow sweep ([`Scene::shadow`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowSpec {
    /// Radius of the lamp's bulb, mm: a disc of light seen from each point (its penumbra).
    pub lamp_radius_mm: f64,
    /// The lamp's irradiance 1 m away, in units of the ambient light.
    pub power: f64,
    /// Radius of the rod, mm.
    pub rod_radius_mm: f64,
    /// Distance from the lamp to the rod's axis, mm, towards where the laser would aim.
    pub rod_distance_mm: f64,
}

impl ShadowSpec {
    /// A desk lamp with a 3 mm bulb of power 0.25, and a rod of 4 mm radius 250 mm in front of it.
    pub const DESK: ShadowSpec = ShadowSpec {
        lamp_radius_mm: 3.0,
        power: 0.25,
        rod_radius_mm: 4.0,
        rod_distance_mm: 250.0,
    };

    /// Whether the values make a lamp and a rod in front of it.
    ///
    /// # Errors
    /// [`RigError::Scene`] naming the value.
    pub fn check(&self) -> Result<(), RigError> {
        let bad = |why: String| Err(RigError::Scene(format!("shadow: {why}")));
        if !(self.lamp_radius_mm >= 0.0 && self.lamp_radius_mm <= 100.0) {
            return bad(format!(
                "lamp_radius_mm {} (need 0–100)",
                self.lamp_radius_mm
            ));
        }
        if !(self.power > 0.0 && self.power.is_finite()) {
            return bad(format!("power {} must be positive", self.power));
        }
        if !(self.rod_radius_mm > 0.0 && self.rod_radius_mm <= 100.0) {
            return bad(format!("rod_radius_mm {} (need 0–100)", self.rod_radius_mm));
        }
        if !(self.rod_distance_mm > self.rod_radius_mm + self.lamp_radius_mm
            && self.rod_distance_mm.is_finite())
        {
            return bad(format!(
                "rod_distance_mm {} must clear the lamp and the rod",
                self.rod_distance_mm
            ));
        }
        Ok(())
    }
}

/// The printed turntable disc ([`scanner_calib::disc`]) under the objects: a [`Shape::Disc`]
/// among the objects, rendered with the print's ink, turning with the objects in every view.
#[derive(Debug, Clone, PartialEq)]
pub struct TurntableSpec {
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
                fixed: None,
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
            shadow: None,
            shots: Vec::new(),
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

/// The board as the rig needs it: planes and half directions.
#[derive(Debug, Clone)]
pub(crate) struct BoardGeometry {
    pub(crate) crease: Point3<f64>,
    /// Unit direction of the crease (the sheets' `v`).
    pub(crate) along: Vector3<f64>,
    pub(crate) halves: [(Plane<f64>, Vector3<f64>); 2],
}

impl BoardGeometry {
    pub(crate) fn new(b: &BoardSpec) -> Result<Self, RigError> {
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
    pub(crate) fn sheet(&self, k: usize, p: &Point3<f64>) -> [f64; 2] {
        let r = p - self.crease;
        [r.dot(&self.halves[k].1), r.dot(&self.along)]
    }

    /// The point of half `k` at sheet coordinates `(u, v)`.
    pub(crate) fn point(&self, k: usize, uv: [f64; 2]) -> Point3<f64> {
        self.crease + self.halves[k].1 * uv[0] + self.along * uv[1]
    }

    /// The left and right planes (normals towards the camera).
    pub(crate) fn planes(&self) -> [Plane<f64>; 2] {
        [self.halves[0].0, self.halves[1].0]
    }

    pub(crate) fn hit(&self, dir: &Vector3<f64>) -> Option<Hit> {
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

/// Where the target sheet is: the pattern's centre in camera coordinates and the sheet's turn
/// (degrees about the camera's x, y, z axes, applied in that order) from facing the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetPose {
    /// Pattern centre, mm.
    pub centre: Point3<f64>,
    /// Turns about x, y, z, degrees.
    pub turn_deg: [f64; 3],
}

impl TargetPose {
    /// Pose `i` of `n` for an intrinsics calibration: the target 550–850 mm away, spread over the
    /// image and turned up to ±35° in every direction (what a user waving a printed target in
    /// front of the camera does, evenly).
    pub fn sweep(i: usize, n: usize) -> TargetPose {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        let z = 550.0 + 300.0 * ((i * 7) % n) as f64 / n as f64;
        TargetPose {
            centre: Point3::new(0.22 * z * a.cos(), 0.15 * z * a.sin(), z),
            turn_deg: [
                35.0 * a.sin(),
                -35.0 * a.cos(),
                10.0 * (i as f64 - n as f64 / 2.0) / n as f64,
            ],
        }
    }
}

/// The picture's nine regions, the corners first, as the studio's guide asks for them: each
/// region's column and row (0, 1, 2).
const GUIDED: [(u8, u8); 9] = [
    (0, 0),
    (2, 0),
    (0, 2),
    (2, 2),
    (1, 0),
    (0, 1),
    (2, 1),
    (1, 2),
    (1, 1),
];

impl TargetPose {
    /// Pose `k` of a maker who follows the studio's guide: the target (`size_mm`, its width
    /// and height) held two fifths of the picture wide or farther in each of its nine regions in
    /// turn, the corners first, tilted 25° alternately each way about both axes; after the
    /// nine, [`TargetPose::sweep`]'s twelve poses. `camera` is the rig's (`width × height`).
    pub fn guided(
        k: usize,
        camera: &Camera<f64>,
        (width, height): (u32, u32),
        size_mm: [f64; 2],
    ) -> TargetPose {
        let Some(&(col, row)) = GUIDED.get(k) else {
            return TargetPose::sweep((k - GUIDED.len()) % 12, 12);
        };
        let (w, h) = (f64::from(width), f64::from(height));
        // two fifths of the picture wide at most (a target small in the picture pins the
        // focal length down poorly), and farther every other shot
        let z = (size_mm[0] * camera.fx() / (0.4 * w)).max(size_mm[1] * camera.fy() / (0.4 * h))
            * [1.0, 1.15, 1.3][k % 3];
        let at = |band: u8, side: f64| side * [0.27, 0.5, 0.73][usize::from(band)];
        let c = camera.principal_point();
        let sign = |odd: bool| if odd { -30.0 } else { 30.0 };
        TargetPose {
            centre: Point3::new(
                (at(col, w) - c.x) / camera.fx() * z,
                (at(row, h) - c.y) / camera.fy() * z,
                z,
            ),
            turn_deg: [sign(k % 2 == 1), sign((k / 2) % 2 == 1), 0.0],
        }
    }
}
