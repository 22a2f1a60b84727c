//! The scene file: TOML, every section optional. What a file leaves out is taken from
//! [`Scene::demo`] at the file's `width` × `height` (default 640×480); a listed `[[objects]]`
//! replaces the demo's objects. Lengths in mm, angles in degrees, camera coordinates (+z forward,
//! +y down). The README has a full example (`scanner-device/scenes/demo.toml`).

use scanner_core::nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use scanner_core::{Camera, Distortion};
use serde::Deserialize;

use super::{BoardSpec, LaserSpec, Markers, Object, RigError, Scene, Shape};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    width: Option<u32>,
    height: Option<u32>,
    ambient: Option<f64>,
    blur_px: Option<f64>,
    flicker: Option<f64>,
    mains_hz: Option<f64>,
    fps: Option<f64>,
    exposure: Option<f64>,
    camera: Option<CameraFile>,
    board: Option<BoardFile>,
    objects: Option<Vec<ObjectEntry>>,
    laser: Option<LaserFile>,
    /// A shadow sweep: the laser's source is the lamp (see [`crate::ShadowSpec`]).
    shadow: Option<ShadowFile>,
    sensor: Option<SensorFile>,
    views: Option<Vec<ViewFile>>,
    /// The set-up seen from a camera tilted down by this many degrees: the objects (written
    /// upright, +y down) and the views' turns tilt about the camera's x axis through
    /// `tilt_pivot` (default: the objects' mean centre). The board keeps its own pitch.
    tilt_deg: Option<f64>,
    tilt_pivot: Option<[f64; 3]>,
    /// Where the virtual operator holds the intrinsics target for the first calibration
    /// shots, in order (then those of [`crate::TargetPose::guided`]).
    shots: Option<Vec<ShotFile>>,
}

/// A calibration shot's target pose: its centre (mm, camera coordinates) and its turns about
/// x, y and z (degrees).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShotFile {
    centre: [f64; 3],
    turn_deg: Option<[f64; 3]>,
}

/// Most calibration shot poses a scene may list.
pub const MAX_SHOT_POSES: usize = 64;

/// One view of a 360° scan: the objects turned by `angle_deg` about `axis` through `pivot`
/// (default: the mean of the objects' centres), then moved by `translate` (mm).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewFile {
    axis: Option<[f64; 3]>,
    angle_deg: Option<f64>,
    pivot: Option<[f64; 3]>,
    translate: Option<[f64; 3]>,
    /// `false`: the turntable disc was taken away for this view.
    disc: Option<bool>,
}

/// Most views a scene may list.
pub const MAX_VIEWS: usize = 64;

impl ViewFile {
    fn pose(&self, k: usize, centre: Point3<f64>) -> Result<Isometry3<f64>, RigError> {
        let bad = |why: &str| Err(RigError::Scene(format!("views[{k}]: {why}")));
        let axis = Vector3::from(self.axis.unwrap_or([0.0, 1.0, 0.0]));
        let angle = self.angle_deg.unwrap_or(0.0);
        let pivot = self.pivot.map_or(centre, Point3::from);
        let t = Vector3::from(self.translate.unwrap_or([0.0; 3]));
        if !(axis.iter().all(|v| v.is_finite()) && axis.norm() > 1e-9) {
            return bad("axis must be a non-zero vector");
        }
        if !(angle.is_finite() && pivot.coords.iter().chain(t.iter()).all(|v| v.is_finite())) {
            return bad("angle_deg, pivot and translate must be numbers");
        }
        if t.norm() > 1000.0 {
            return bad("translate moves the objects more than 1 m");
        }
        let r = UnitQuaternion::from_axis_angle(&Unit::new_normalize(axis), angle.to_radians());
        // Turn about the pivot, then move: p ↦ R (p − pivot) + pivot + t.
        Ok(Isometry3::from_parts(
            Translation3::from(pivot.coords + t - r * pivot.coords),
            r,
        ))
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    fx: Option<f64>,
    fy: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    k1: Option<f64>,
    k2: Option<f64>,
    p1: Option<f64>,
    p2: Option<f64>,
    k3: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BoardFile {
    distance: Option<f64>,
    angle_deg: Option<f64>,
    yaw_deg: Option<f64>,
    pitch_deg: Option<f64>,
    albedo: Option<[f64; 3]>,
    markers: Option<MarkersFile>,
    /// A board file (`scanner-device board`) whose layout the rig prints, relative to the scene
    /// file's folder; instead of `[board.markers]`.
    layout: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkersFile {
    left: Vec<[f64; 2]>,
    right: Vec<[f64; 2]>,
    diameter: f64,
    albedo: Option<[f64; 3]>,
}

/// An object entry: its shape (tagged by `shape`) and the optional texture keys.
#[derive(Debug, Deserialize)]
struct ObjectEntry {
    #[serde(flatten)]
    shape: ObjectFile,
    /// Checker cell size, mm.
    texture_cell: Option<f64>,
    /// Albedo of the checker's other cells.
    texture_albedo: Option<[f64; 3]>,
    /// `true`: the object stays put in every view (a table or a stand under the turntable).
    #[serde(default)]
    fixed: bool,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase")]
enum ObjectFile {
    Sphere {
        centre: [f64; 3],
        radius: f64,
        albedo: Option<[f64; 3]>,
    },
    Cylinder {
        base: [f64; 3],
        axis: [f64; 3],
        radius: f64,
        height: f64,
        albedo: Option<[f64; 3]>,
    },
    /// A box turned by `yaw_deg` about the camera's y axis.
    Box {
        centre: [f64; 3],
        size: [f64; 3],
        #[serde(default)]
        yaw_deg: f64,
        albedo: Option<[f64; 3]>,
    },
    /// A triangle mesh from an OBJ file (path relative to the scene file), scaled to a height,
    /// turned upright and about the vertical, centred.
    Mesh {
        path: String,
        centre: [f64; 3],
        height_mm: f64,
        #[serde(default)]
        yaw_deg: f64,
        albedo: Option<[f64; 3]>,
    },
    /// The printed turntable disc (`scanner-device board --turntable`) lying flat under the
    /// objects: its centre, its print's `x` axis turned by `turn_deg` from the camera's x about
    /// the vertical.
    Turntable {
        /// `a4` or `a3`.
        paper: String,
        centre: [f64; 3],
        #[serde(default)]
        turn_deg: f64,
        albedo: Option<[f64; 3]>,
    },
    /// A tilted rectangle: centre, size, normal tilt from facing the camera about x and y.
    Plane {
        centre: [f64; 3],
        size: [f64; 2],
        #[serde(default)]
        tilt_x_deg: f64,
        #[serde(default)]
        tilt_y_deg: f64,
        albedo: Option<[f64; 3]>,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShadowFile {
    lamp_radius_mm: Option<f64>,
    power: Option<f64>,
    rod_radius_mm: Option<f64>,
    rod_distance_mm: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LaserFile {
    source: Option<[f64; 3]>,
    sweep: Option<[f64; 2]>,
    frames: Option<usize>,
    wobble_deg: Option<f64>,
    jitter_mm: Option<f64>,
    sigma_mm: Option<f64>,
    power: Option<f64>,
    colour: Option<[f64; 3]>,
    speckle: Option<f64>,
    seed: Option<u64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorFile {
    gain: Option<f64>,
    read_noise: Option<f64>,
    shot_noise: Option<f64>,
    seed: Option<u64>,
}

fn set<T>(slot: &mut T, value: Option<T>) {
    if let Some(v) = value {
        *slot = v;
    }
}

const GREY: [f64; 3] = [0.6, 0.6, 0.6];
/// White paper, and the printer's black.
const PAPER: [f64; 3] = [0.85, 0.85, 0.83];
const INK: [f64; 3] = [0.06, 0.06, 0.06];

/// The turntable's frame where the file places it: centre, the print's `x` turned by `turn_deg`
/// from the camera's x about the vertical (−y), `y` across, the third axis down into the table.
fn turntable_pose(centre: [f64; 3], turn_deg: f64) -> Isometry3<f64> {
    let a = turn_deg.to_radians();
    let x = Vector3::new(a.cos(), 0.0, a.sin());
    let up = Vector3::new(0.0, -1.0, 0.0);
    let y = -up.cross(&x);
    let r = scanner_core::nalgebra::Rotation3::from_basis_unchecked(&[x, y, x.cross(&y)]);
    Isometry3::from_parts(
        Translation3::from(Vector3::from(centre)),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

impl Scene {
    /// Reads a scene from TOML text (see the module docs); mesh paths are relative to the
    /// current directory.
    ///
    /// # Errors
    /// [`RigError::Scene`] naming the line and field of a syntax error, an unknown field or a bad
    /// value.
    pub fn from_toml(text: &str) -> Result<Scene, RigError> {
        Self::from_toml_in(text, std::path::Path::new("."))
    }

    /// [`Scene::from_toml`] with mesh paths relative to `base` (the scene file's folder).
    ///
    /// # Errors
    /// As [`Scene::from_toml`]; also a mesh file that cannot be loaded.
    pub fn from_toml_in(text: &str, base: &std::path::Path) -> Result<Scene, RigError> {
        let f: File =
            toml::from_str(text).map_err(|e| RigError::Scene(e.to_string().trim().to_string()))?;
        let (width, height) = (f.width.unwrap_or(640), f.height.unwrap_or(480));
        Scene::check_size(width, height)?;
        let mut s = Scene::demo(width, height);
        set(&mut s.ambient, f.ambient);
        set(&mut s.blur_px, f.blur_px);
        set(&mut s.flicker, f.flicker);
        set(&mut s.mains_hz, f.mains_hz);
        set(&mut s.fps, f.fps);
        set(&mut s.exposure, f.exposure);
        if let Some(c) = f.camera {
            s.camera = c.over(&s.camera)?;
        }
        if let Some(b) = f.board {
            b.apply(&mut s.board, base)?;
        }
        if let Some(objects) = &f.objects {
            let discs: Vec<(usize, &ObjectEntry)> = objects
                .iter()
                .enumerate()
                .filter(|(_, o)| matches!(o.shape, ObjectFile::Turntable { .. }))
                .collect();
            if discs.len() > 1 {
                return Err(RigError::Scene(format!(
                    "objects: {} turntables, at most one",
                    discs.len()
                )));
            }
            s.turntable = discs
                .first()
                .map(|&(i, o)| {
                    let ObjectFile::Turntable {
                        paper,
                        centre,
                        turn_deg,
                        ..
                    } = &o.shape
                    else {
                        unreachable!("filtered")
                    };
                    Ok::<_, RigError>((i, paper_of(i, paper)?, *centre, *turn_deg))
                })
                .transpose()?
                .map(|(i, paper, centre, turn_deg)| {
                    let disc = scanner_calib::disc::Disc::new(paper);
                    super::TurntableSpec {
                        object: i,
                        disc,
                        sheet: std::sync::Arc::new(disc.sheet()),
                        pose: turntable_pose(centre, turn_deg),
                        ink: INK,
                        absent_in: Vec::new(),
                    }
                });
        }
        if let Some(objects) = f.objects {
            s.fixed = objects
                .iter()
                .enumerate()
                .filter(|(_, o)| o.fixed)
                .map(|(i, _)| i)
                .collect();
            if let Some(t) = &s.turntable
                && s.fixed.contains(&t.object)
            {
                return Err(RigError::Scene(format!(
                    "objects[{}]: the turntable disc turns with the views; it cannot be fixed",
                    t.object
                )));
            }
            s.objects = objects
                .into_iter()
                .enumerate()
                .map(|(i, o)| object(i, o, base))
                .collect::<Result<_, _>>()?;
        }
        if let Some(l) = f.laser {
            l.apply(&mut s.laser);
        }
        if let Some(sh) = f.shadow {
            let mut spec = crate::ShadowSpec::DESK;
            set(&mut spec.lamp_radius_mm, sh.lamp_radius_mm);
            set(&mut spec.power, sh.power);
            set(&mut spec.rod_radius_mm, sh.rod_radius_mm);
            set(&mut spec.rod_distance_mm, sh.rod_distance_mm);
            spec.check()?;
            s.shadow = Some(spec);
        }
        if let Some(views) = f.views {
            if views.len() > MAX_VIEWS {
                return Err(RigError::Scene(format!(
                    "{} views: at most {MAX_VIEWS}",
                    views.len()
                )));
            }
            let n = s.objects.len().max(1) as f64;
            let centre = Point3::from(
                s.objects
                    .iter()
                    .fold(Vector3::zeros(), |a, o| a + o.shape.centre().coords)
                    / n,
            );
            s.views = views
                .iter()
                .enumerate()
                .map(|(k, v)| v.pose(k, centre))
                .collect::<Result<_, _>>()?;
            let absent: Vec<usize> = (0..views.len())
                .filter(|&k| views[k].disc == Some(false))
                .collect();
            match &mut s.turntable {
                Some(t) => t.absent_in = absent,
                None if !absent.is_empty() => {
                    return Err(RigError::Scene(format!(
                        "views[{}]: disc = false, but the scene has no turntable",
                        absent[0]
                    )));
                }
                None => {}
            }
        }
        if let Some(deg) = f.tilt_deg {
            if !(deg.is_finite() && deg.abs() <= 80.0) {
                return Err(RigError::Scene(format!(
                    "tilt_deg {deg}: must be a number of degrees, −80 to 80"
                )));
            }
            let n = s.objects.len().max(1) as f64;
            let pivot = f.tilt_pivot.map_or_else(
                || {
                    s.objects
                        .iter()
                        .fold(Vector3::zeros(), |a, o| a + o.shape.centre().coords)
                        / n
                },
                Vector3::from,
            );
            let r = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), deg.to_radians());
            let tilt = Isometry3::from_parts(Translation3::from(pivot - r * pivot), r);
            for o in &mut s.objects {
                o.shape = o.shape.moved(&tilt);
            }
            if let Some(t) = &mut s.turntable {
                t.pose = tilt * t.pose;
            }
            for v in &mut s.views {
                *v = tilt * *v * tilt.inverse();
            }
        }
        if let Some(shots) = f.shots {
            if shots.len() > MAX_SHOT_POSES {
                return Err(RigError::Scene(format!(
                    "{} shots: at most {MAX_SHOT_POSES}",
                    shots.len()
                )));
            }
            for (k, p) in shots.iter().enumerate() {
                let turn = p.turn_deg.unwrap_or([0.0; 3]);
                if !p.centre.iter().chain(&turn).all(|v| v.is_finite())
                    || p.centre[2] <= 0.0
                    || turn.iter().any(|t| t.abs() >= 80.0)
                {
                    return Err(RigError::Scene(format!(
                        "shots[{k}]: the centre must lie in front of the camera (z > 0) and each turn within ±80°"
                    )));
                }
                s.shots.push(crate::TargetPose {
                    centre: Point3::from(p.centre),
                    turn_deg: turn,
                });
            }
        }
        if let Some(n) = f.sensor {
            set(&mut s.sensor.gain, n.gain);
            set(&mut s.sensor.read_noise, n.read_noise);
            set(&mut s.sensor.shot_noise, n.shot_noise);
            set(&mut s.sensor.seed, n.seed);
        }
        Ok(s)
    }
}

impl CameraFile {
    /// `old` with the values the file gives (`fy` defaults to the file's `fx`).
    fn over(self, old: &Camera<f64>) -> Result<Camera<f64>, RigError> {
        let d = *old.distortion();
        let pp = old.principal_point();
        Camera::new(
            self.fx.unwrap_or(old.fx()),
            self.fy.or(self.fx).unwrap_or(old.fy()),
            self.cx.unwrap_or(pp.x),
            self.cy.unwrap_or(pp.y),
            Distortion {
                k1: self.k1.unwrap_or(d.k1),
                k2: self.k2.unwrap_or(d.k2),
                p1: self.p1.unwrap_or(d.p1),
                p2: self.p2.unwrap_or(d.p2),
                k3: self.k3.unwrap_or(d.k3),
            },
        )
        .map_err(|e| RigError::Scene(format!("[camera]: {e}")))
    }
}

impl BoardFile {
    /// Sets what the file gives; the markers from `layout` (a board file relative to `base`),
    /// from `[board.markers]`, or the default board file's layout.
    fn apply(self, board: &mut BoardSpec, base: &std::path::Path) -> Result<(), RigError> {
        set(&mut board.distance, self.distance);
        set(&mut board.angle_deg, self.angle_deg);
        set(&mut board.yaw_deg, self.yaw_deg);
        set(&mut board.pitch_deg, self.pitch_deg);
        set(&mut board.albedo, self.albedo);
        board.markers = match (self.markers, self.layout) {
            (Some(_), Some(_)) => {
                return Err(RigError::Scene(
                    "[board]: give `layout` (a board file) or [board.markers], not both".into(),
                ));
            }
            (None, Some(path)) => Markers::from(
                &scanner_calib::board::BoardFile::load(&base.join(&path))
                    .map_err(|e| RigError::Scene(format!("[board] layout: {e}")))?,
            ),
            (Some(m), None) => {
                if !(m.diameter > 0.0) {
                    return Err(RigError::Scene(
                        "[board.markers]: diameter must be positive".into(),
                    ));
                }
                Markers {
                    left: m.left,
                    right: m.right,
                    diameter: m.diameter,
                    albedo: m.albedo.unwrap_or([0.06; 3]),
                    chess: [None, None],
                }
            }
            (None, None) => Markers::paper(110.0),
        };
        Ok(())
    }
}

impl LaserFile {
    fn apply(self, laser: &mut LaserSpec) {
        set(&mut laser.source, self.source.map(Point3::from));
        set(&mut laser.sweep, self.sweep.map(|[a, b]| (a, b)));
        set(&mut laser.frames, self.frames);
        set(&mut laser.wobble_deg, self.wobble_deg);
        set(&mut laser.jitter_mm, self.jitter_mm);
        set(&mut laser.sigma_mm, self.sigma_mm);
        set(&mut laser.power, self.power);
        set(&mut laser.colour, self.colour);
        set(&mut laser.speckle, self.speckle);
        set(&mut laser.seed, self.seed);
    }
}

/// `objects[i]`'s `paper`, named in the error when it is no paper a disc is printed on.
fn paper_of(i: usize, paper: &str) -> Result<scanner_calib::disc::Paper, RigError> {
    paper
        .parse()
        .map_err(|e| RigError::Scene(format!("objects[{i}]: paper: {e}")))
}

fn positive(i: usize, what: &str, v: f64) -> Result<f64, RigError> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(RigError::Scene(format!(
            "objects[{i}]: {what} must be positive, got {v}"
        )))
    }
}

/// `objects[i]`: its shape, albedo and checker texture.
fn object(i: usize, entry: ObjectEntry, base: &std::path::Path) -> Result<Object, RigError> {
    let texture = match (entry.texture_cell, entry.texture_albedo) {
        (Some(cell), Some(other)) => Some((positive(i, "texture_cell", cell)?, other)),
        (None, None) => None,
        _ => {
            return Err(RigError::Scene(format!(
                "objects[{i}]: texture_cell and texture_albedo go together"
            )));
        }
    };
    let o = entry.shape;
    let albedo = match &o {
        ObjectFile::Mesh { albedo, .. }
        | ObjectFile::Sphere { albedo, .. }
        | ObjectFile::Cylinder { albedo, .. }
        | ObjectFile::Box { albedo, .. }
        | ObjectFile::Plane { albedo, .. } => albedo.unwrap_or(GREY),
        ObjectFile::Turntable { albedo, .. } => albedo.unwrap_or(PAPER),
    };
    Ok(Object {
        shape: shape(i, o, base)?,
        albedo,
        texture,
    })
}

/// The shape of `objects[i]`, its sizes checked; a mesh is loaded relative to `base`.
fn shape(i: usize, o: ObjectFile, base: &std::path::Path) -> Result<Shape, RigError> {
    use scanner_core::nalgebra::Rotation3;
    Ok(match o {
        ObjectFile::Mesh {
            path,
            centre,
            height_mm,
            yaw_deg,
            ..
        } => {
            let at = Point3::from(centre);
            let mesh = super::mesh::SceneMesh::load(&base.join(&path), height_mm, yaw_deg, at)
                .map_err(|e| RigError::Mesh {
                    object: i,
                    source: e,
                })?;
            Shape::Mesh(std::sync::Arc::new(mesh))
        }
        ObjectFile::Sphere { centre, radius, .. } => Shape::Sphere {
            centre: Point3::from(centre),
            radius: positive(i, "radius", radius)?,
        },
        ObjectFile::Cylinder {
            base,
            axis,
            radius,
            height,
            ..
        } => {
            let axis = Vector3::from(axis);
            if !(axis.norm() > 0.0) {
                return Err(RigError::Scene(format!(
                    "objects[{i}]: axis must be non-zero"
                )));
            }
            Shape::Cylinder {
                base: Point3::from(base),
                axis: Unit::new_normalize(axis),
                radius: positive(i, "radius", radius)?,
                height: positive(i, "height", height)?,
            }
        }
        ObjectFile::Box {
            centre,
            size,
            yaw_deg,
            ..
        } => {
            let r = Rotation3::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians());
            let half = |k: usize| positive(i, "size", size[k]).map(|v| v / 2.0);
            Shape::Cuboid {
                centre: Point3::from(centre),
                half: Vector3::new(half(0)?, half(1)?, half(2)?),
                axes: [r * Vector3::x(), r * Vector3::y(), r * Vector3::z()],
            }
        }
        ObjectFile::Turntable {
            paper,
            centre,
            turn_deg,
            ..
        } => {
            let pose = turntable_pose(centre, turn_deg);
            Shape::Disc {
                centre: Point3::from(centre),
                axes: [pose.rotation * Vector3::x(), pose.rotation * Vector3::y()],
                radius: scanner_calib::disc::Disc::new(paper_of(i, &paper)?).radius,
            }
        }
        ObjectFile::Plane {
            centre,
            size,
            tilt_x_deg,
            tilt_y_deg,
            ..
        } => {
            let r =
                Rotation3::from_euler_angles(tilt_x_deg.to_radians(), tilt_y_deg.to_radians(), 0.0);
            let half = |k: usize| positive(i, "size", size[k]).map(|v| v / 2.0);
            Shape::Rectangle {
                centre: Point3::from(centre),
                axes: [r * Vector3::x(), r * Vector3::y()],
                half: [half(0)?, half(1)?],
            }
        }
    })
}
