//! A turntable scanner on the rig: a fixed laser whose plane holds the platform's axis, objects
//! standing on a platform that turns a step between frames, with the truth — the objects' true
//! surfaces in the platform's frame, and the true calibration (camera, laser plane, platform).
//!
//! Each frame is rendered by a rig of its own (the objects are where the platform's turn puts
//! them; camera, laser and the board behind stay), so a frame costs a rig's set-up.

use scanner_core::nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::RigError;
use crate::render::{Rgb8, Rig};
use crate::scene::{Object, Scene};
use crate::surface::Shape;

/// A fixed-laser turntable scan: the scene (its laser fixed), the platform and its turn.
#[derive(Debug, Clone, PartialEq)]
pub struct TurningScan {
    /// The scene at turn 0: the objects standing on the platform (the platform's disc among
    /// them), the board far behind (a wall), the laser's `fixed` plane set.
    pub scene: Scene,
    /// Platform → camera: its origin on the axis at its top, `z` up the axis.
    pub platform: Isometry3<f64>,
    /// The platform's radius, mm.
    pub radius: f64,
    /// The turn between frames, radians.
    pub turn: f64,
    /// Frames rendered (one turn and the frame that closes it).
    pub frames: usize,
    /// Motor steps in one turn.
    pub steps_per_turn: u32,
}

impl TurningScan {
    /// A demo: at `width`×`height`, the demo scene's camera looking 12° down at a platform of
    /// 70 mm radius 260 mm away, a sphere of 30 mm radius and an upright cylinder of 18 mm
    /// radius and 60 mm height standing on it off the axis, the laser 120 mm to the right, its
    /// plane holding the axis; a dark box (ambient light 0.05); 100 frames a turn.
    pub fn demo(width: u32, height: u32) -> TurningScan {
        let mut scene = Scene::demo(width, height);
        let origin = Point3::new(0.0, 45.0, 250.0);
        // platform z up the axis: camera −y tilted 12° towards the camera (it looks down 12°);
        // x towards the camera's right
        let rotation = UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            std::f64::consts::FRAC_PI_2 + 12f64.to_radians(),
        );
        let platform = Isometry3::from_parts(Translation3::from(origin.coords), rotation);
        let at = |x: f64, y: f64, z: f64| platform * Point3::new(x, y, z);
        let up = platform * Vector3::z();
        let (px, py) = (platform * Vector3::x(), platform * Vector3::y());
        scene.board.distance = 900.0;
        scene.objects = vec![
            Object {
                shape: Shape::Disc {
                    centre: at(0.0, 0.0, 0.0),
                    axes: [px, py],
                    radius: 70.0,
                },
                albedo: [0.3, 0.3, 0.3],
                texture: None,
            },
            Object {
                shape: Shape::Sphere {
                    centre: at(14.0, 6.0, 30.0),
                    radius: 30.0,
                },
                albedo: [0.7, 0.6, 0.5],
                texture: None,
            },
            Object {
                shape: Shape::Cylinder {
                    base: at(-26.0, -22.0, 0.0),
                    axis: scanner_core::nalgebra::Unit::new_normalize(up),
                    radius: 18.0,
                    height: 60.0,
                },
                albedo: [0.5, 0.6, 0.7],
                texture: None,
            },
        ];
        scene.ambient = 0.05;
        let source = Point3::new(120.0, -40.0, 60.0);
        let axis_point = platform * Point3::origin();
        scene.laser.source = source;
        scene.laser.fixed = Some((source - axis_point).cross(&up));
        scene.laser.frames = 1;
        scene.laser.wobble_deg = 0.0;
        // a laser 150 mm from the objects, not 800: dimmer, so as not to saturate
        scene.laser.power = 0.15;
        scene.laser.jitter_mm = 0.0;
        let frames = 100;
        TurningScan {
            scene,
            platform,
            radius: 70.0,
            turn: std::f64::consts::TAU / frames as f64,
            frames: frames + 1,
            steps_per_turn: 6400,
        }
    }

    /// The scene of frame `k`: the objects turned `k · turn` about the platform's axis.
    pub fn frame_scene(&self, k: usize) -> Scene {
        let turn = Isometry3::rotation(Vector3::z() * (k as f64 * self.turn));
        let pose = self.platform * turn * self.platform.inverse();
        let mut s = self.scene.clone();
        for o in &mut s.objects {
            o.shape = o.shape.moved(&pose);
        }
        s.object_pose = pose;
        s
    }

    /// Frame `k` as the camera sees it.
    ///
    /// # Errors
    /// [`RigError`] for a scene the rig cannot build, or `k` past the frames.
    pub fn render(&self, k: usize) -> Result<Rgb8, RigError> {
        if k >= self.frames {
            return Err(RigError::NoSuchFrame {
                index: k,
                frames: self.frames,
            });
        }
        Rig::new(self.frame_scene(k))?.frame(0)
    }

    /// The distance of `p` (platform frame, turn 0) from the nearest true surface of the
    /// objects standing on the platform (the platform's disc left out), mm.
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let q = self.platform * p;
        self.scene
            .objects
            .iter()
            .skip(1)
            .filter_map(|o| o.shape.distance(&q))
            .fold(f64::INFINITY, f64::min)
    }

    /// The camera's distance from the platform's origin, mm (`D` of the accuracy figures).
    pub fn distance_to_platform(&self) -> f64 {
        self.platform.translation.vector.norm()
    }

    /// The true calibration: the camera, the laser's plane, the platform.
    pub fn truth_calibration(&self) -> scanner_calib::file::CalibrationFile {
        use scanner_calib::file::{CalibrationFile, PlaneEq, PlatformSection};
        let s = &self.scene;
        let mut f = CalibrationFile::from_camera(
            &s.camera,
            (s.width, s.height),
            "the virtual rig's true camera".into(),
            None,
        );
        let normal = s.laser.fixed.unwrap_or_else(Vector3::x);
        let plane = scanner_core::geometry::Plane::from_point_normal(&s.laser.source, &normal)
            .expect("the demo's laser plane is a plane")
            .facing_camera();
        f.lasers.push(PlaneEq {
            normal: (*plane.normal()).into(),
            offset: plane.offset(),
        });
        let r = self.platform.rotation.to_rotation_matrix();
        let m = r.matrix();
        f.platform = Some(PlatformSection {
            rotation: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
            origin: self.platform.translation.vector.into(),
            radius: self.radius,
            steps_per_turn: self.steps_per_turn,
            clockwise: false,
            height: 120.0,
        });
        f
    }
}
