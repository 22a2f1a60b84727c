//! The scene file: TOML, every section optional. What a file leaves out is taken from
//! [`Scene::demo`] at the file's `width` × `height` (default 640×480); a listed `[[objects]]`
//! replaces the demo's objects. Lengths in mm, angles in degrees, camera coordinates (+z forward,
//! +y down). The README has a full example (`scanner-device/scenes/demo.toml`).

use scanner_core::nalgebra::{Point3, Unit, Vector3};
use scanner_core::{Camera, Distortion};
use serde::Deserialize;

use super::{Markers, Object, RigError, Scene, Shape};

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
    sensor: Option<SensorFile>,
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
        let mut s = Scene::demo(f.width.unwrap_or(640), f.height.unwrap_or(480));
        set(&mut s.ambient, f.ambient);
        set(&mut s.blur_px, f.blur_px);
        set(&mut s.flicker, f.flicker);
        set(&mut s.mains_hz, f.mains_hz);
        set(&mut s.fps, f.fps);
        set(&mut s.exposure, f.exposure);
        if let Some(c) = f.camera {
            let old = s.camera;
            let d = *old.distortion();
            let pp = old.principal_point();
            s.camera = Camera::new(
                c.fx.unwrap_or(old.fx()),
                c.fy.or(c.fx).unwrap_or(old.fy()),
                c.cx.unwrap_or(pp.x),
                c.cy.unwrap_or(pp.y),
                Distortion {
                    k1: c.k1.unwrap_or(d.k1),
                    k2: c.k2.unwrap_or(d.k2),
                    p1: c.p1.unwrap_or(d.p1),
                    p2: c.p2.unwrap_or(d.p2),
                    k3: c.k3.unwrap_or(d.k3),
                },
            )
            .map_err(|e| RigError::Scene(format!("[camera]: {e}")))?;
        }
        if let Some(b) = f.board {
            set(&mut s.board.distance, b.distance);
            set(&mut s.board.angle_deg, b.angle_deg);
            set(&mut s.board.yaw_deg, b.yaw_deg);
            set(&mut s.board.pitch_deg, b.pitch_deg);
            set(&mut s.board.albedo, b.albedo);
            s.board.markers = match (b.markers, b.layout) {
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
                // the default board file's layout
                (None, None) => Markers::paper(110.0),
            };
        }
        if let Some(objects) = f.objects {
            s.objects = objects
                .into_iter()
                .enumerate()
                .map(|(i, o)| {
                    let mut obj = object(i, o.shape, base)?;
                    obj.texture = match (o.texture_cell, o.texture_albedo) {
                        (Some(cell), Some(other)) => {
                            Some((positive(i, "texture_cell", cell)?, other))
                        }
                        (None, None) => None,
                        _ => {
                            return Err(RigError::Scene(format!(
                                "objects[{i}]: texture_cell and texture_albedo go together"
                            )));
                        }
                    };
                    Ok(obj)
                })
                .collect::<Result<_, _>>()?;
        }
        if let Some(l) = f.laser {
            set(&mut s.laser.source, l.source.map(Point3::from));
            set(&mut s.laser.sweep, l.sweep.map(|[a, b]| (a, b)));
            set(&mut s.laser.frames, l.frames);
            set(&mut s.laser.wobble_deg, l.wobble_deg);
            set(&mut s.laser.jitter_mm, l.jitter_mm);
            set(&mut s.laser.sigma_mm, l.sigma_mm);
            set(&mut s.laser.power, l.power);
            set(&mut s.laser.colour, l.colour);
            set(&mut s.laser.speckle, l.speckle);
            set(&mut s.laser.seed, l.seed);
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

fn positive(i: usize, what: &str, v: f64) -> Result<f64, RigError> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(RigError::Scene(format!(
            "objects[{i}]: {what} must be positive, got {v}"
        )))
    }
}

fn object(i: usize, o: ObjectFile, base: &std::path::Path) -> Result<Object, RigError> {
    Ok(match o {
        ObjectFile::Mesh {
            path,
            centre,
            height_mm,
            yaw_deg,
            albedo,
        } => {
            let mesh = super::mesh::Mesh::load(
                &base.join(&path),
                height_mm,
                yaw_deg,
                Point3::from(centre),
            )
            .map_err(|e| RigError::Mesh {
                object: i,
                source: e,
            })?;
            Object {
                shape: Shape::Mesh(std::sync::Arc::new(mesh)),
                albedo: albedo.unwrap_or(GREY),
                texture: None,
            }
        }
        ObjectFile::Sphere {
            centre,
            radius,
            albedo,
        } => Object {
            shape: Shape::Sphere {
                centre: Point3::from(centre),
                radius: positive(i, "radius", radius)?,
            },
            albedo: albedo.unwrap_or(GREY),
            texture: None,
        },
        ObjectFile::Cylinder {
            base,
            axis,
            radius,
            height,
            albedo,
        } => {
            let axis = Vector3::from(axis);
            if !(axis.norm() > 0.0) {
                return Err(RigError::Scene(format!(
                    "objects[{i}]: axis must be non-zero"
                )));
            }
            Object {
                shape: Shape::Cylinder {
                    base: Point3::from(base),
                    axis: Unit::new_normalize(axis),
                    radius: positive(i, "radius", radius)?,
                    height: positive(i, "height", height)?,
                },
                albedo: albedo.unwrap_or(GREY),
                texture: None,
            }
        }
        ObjectFile::Box {
            centre,
            size,
            yaw_deg,
            albedo,
        } => {
            let r = scanner_core::nalgebra::Rotation3::from_axis_angle(
                &Vector3::y_axis(),
                yaw_deg.to_radians(),
            );
            Object {
                shape: Shape::Cuboid {
                    centre: Point3::from(centre),
                    half: Vector3::new(
                        positive(i, "size", size[0])? / 2.0,
                        positive(i, "size", size[1])? / 2.0,
                        positive(i, "size", size[2])? / 2.0,
                    ),
                    axes: [r * Vector3::x(), r * Vector3::y(), r * Vector3::z()],
                },
                albedo: albedo.unwrap_or(GREY),
                texture: None,
            }
        }
        ObjectFile::Plane {
            centre,
            size,
            tilt_x_deg,
            tilt_y_deg,
            albedo,
        } => {
            let r = scanner_core::nalgebra::Rotation3::from_euler_angles(
                tilt_x_deg.to_radians(),
                tilt_y_deg.to_radians(),
                0.0,
            );
            Object {
                shape: Shape::Rectangle {
                    centre: Point3::from(centre),
                    axes: [r * Vector3::x(), r * Vector3::y()],
                    half: [
                        positive(i, "size", size[0])? / 2.0,
                        positive(i, "size", size[1])? / 2.0,
                    ],
                },
                albedo: albedo.unwrap_or(GREY),
                texture: None,
            }
        }
    })
}
