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
    /// Where the platform slipped: from frame `k` on it stands this much further, radians (a
    /// motor that lost steps, a belt that jumped a tooth).
    pub slips: Vec<(usize, f64)>,
}

/// The ambient light of a scene with markers on its platform ([`TurningScan::with_markers`]):
/// a room lit enough to read them, the laser still the brightest.
pub const MARKER_AMBIENT: f64 = 0.6;

/// ArUco markers printed on a platform's top ([`TurningScan::with_markers`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PlatformMarkers {
    /// Their dictionary.
    pub dictionary: scanner_calib::aruco::Dictionary,
    /// Their IDs, one marker each, a quarter turn apart round the axis from the platform's
    /// `+x` (four at most).
    pub ids: Vec<usize>,
    /// Their side, mm.
    pub side: f64,
    /// Their centres' distance from the axis, mm.
    pub radius: f64,
}

impl PlatformMarkers {
    /// Each marker's ID and corners in the platform's frame on its top at turn 0, mm (top left,
    /// top right, bottom right, bottom left as printed, read from above the platform with its
    /// `+x` to the right), each marker's top towards the axis.
    pub fn corners(&self) -> Vec<(usize, [scanner_core::nalgebra::Point2<f64>; 4])> {
        use scanner_core::nalgebra::{Point2, Vector2};
        self.ids
            .iter()
            .take(4)
            .enumerate()
            .map(|(k, &id)| {
                let a = std::f64::consts::FRAC_PI_2 * k as f64;
                // the marker's up (towards the axis) and, from above, its right: a quarter
                // turn clockwise from its up
                let out = Vector2::new(a.cos(), a.sin());
                let right = Vector2::new(-out.y, out.x);
                let c = Point2::from(out * self.radius);
                let h = self.side / 2.0;
                (
                    id,
                    [
                        c - right * h - out * h,
                        c + right * h - out * h,
                        c + right * h + out * h,
                        c - right * h + out * h,
                    ],
                )
            })
            .collect()
    }
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
            slips: Vec::new(),
        }
    }

    /// This scan with `markers` printed black on the platform's top (a sheet of paper on it),
    /// the camera looking down `tilt_deg` at the platform instead (markers on the top need a
    /// steeper view than the demo's 12°).
    pub fn with_markers(mut self, markers: &PlatformMarkers, tilt_deg: f64) -> TurningScan {
        use scanner_calib::disc::{Disc, Paper};
        let rotation = UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            std::f64::consts::FRAC_PI_2 + tilt_deg.to_radians(),
        );
        // the platform's pose turned about its origin: the objects stand on it as before
        let to_new = Isometry3::from_parts(
            Translation3::from(self.platform.translation.vector),
            rotation,
        ) * self.platform.inverse();
        for o in &mut self.scene.objects {
            o.shape = o.shape.moved(&to_new);
        }
        self.platform = to_new * self.platform;
        // a room lit enough to read the markers by, a white sheet on the platform
        self.scene.ambient = MARKER_AMBIENT;
        self.scene.objects[0].albedo = [0.85, 0.85, 0.85];
        // the laser's plane holds the turned axis
        let up = self.platform * Vector3::z();
        let source = self.scene.laser.source;
        self.scene.laser.fixed = Some((source - self.platform * Point3::origin()).cross(&up));
        let disc = Disc::new(Paper::A4);
        let cell = markers.side / (markers.dictionary.n + 2) as f64;
        let mut squares = Vec::new();
        for (id, c) in markers.corners() {
            let Some(dark) = markers.dictionary.dark_cells(id) else {
                continue;
            };
            // the marker's cells along its top edge (c0 → c1) and down its left (c0 → c3)
            let (along, down) = ((c[1] - c[0]) / markers.side, (c[3] - c[0]) / markers.side);
            for (r, q) in dark {
                // the cell's centre; the markers stand a quarter turn apart, so their cells
                // are squares of the sheet
                let p = c[0] + along * ((q as f64 + 0.5) * cell) + down * ((r as f64 + 0.5) * cell);
                let (x, y) = disc.to_sheet(&p);
                squares.push((x - cell / 2.0, y - cell / 2.0, cell));
            }
        }
        let sheet = scanner_calib::print::Sheet {
            title: String::new(),
            width: 210.0,
            height: 297.0,
            dots: Vec::new(),
            squares,
            crease_x: None,
            bars: Vec::new(),
            circles: Vec::new(),
        };
        self.scene.turntable = Some(crate::scene::TurntableSpec {
            object: 0,
            disc,
            sheet: std::sync::Arc::new(sheet),
            pose: self.platform,
            ink: [0.03, 0.03, 0.03],
            absent_in: Vec::new(),
        });
        self
    }

    /// The platform's true turn at frame `k`, radians: `k · turn` and the slips before it.
    pub fn angle(&self, k: usize) -> f64 {
        k as f64 * self.turn
            + self
                .slips
                .iter()
                .filter(|(from, _)| *from <= k)
                .map(|(_, a)| a)
                .sum::<f64>()
    }

    /// The scene of frame `k`: the objects turned [`TurningScan::angle`] about the platform's
    /// axis.
    pub fn frame_scene(&self, k: usize) -> Scene {
        let turn = Isometry3::rotation(Vector3::z() * self.angle(k));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The demo with four markers of DICT_4X4_50 (IDs 0–3), 20 mm, 50 mm from the axis, seen
    /// from 30° above.
    fn marked() -> TurningScan {
        let markers = PlatformMarkers {
            dictionary: scanner_calib::aruco::Dictionary::named("DICT_4X4_50").unwrap(),
            ids: vec![0, 1, 2, 3],
            side: 20.0,
            radius: 50.0,
        };
        TurningScan::demo(640, 480).with_markers(&markers, 30.0)
    }

    #[test]
    fn the_markers_on_the_platform_read_as_their_ids_where_the_truth_puts_them() {
        let scan = marked();
        let frame = scan.render(0).unwrap();
        let gray = image::GrayImage::from_fn(frame.width as u32, frame.height as u32, |x, y| {
            let i = 3 * (y as usize * frame.width + x as usize);
            image::Luma([frame.data[i + 1]])
        });
        let dict = scanner_calib::aruco::Dictionary::named("DICT_4X4_50").unwrap();
        let quads = scanner_calib::aruco::quads(&gray, scanner_calib::aruco::MIN_QUAD_SIDE_PX);
        let found = scanner_calib::aruco::find_aruco(&gray, &quads, &dict);
        eprintln!(
            "{:?}",
            found.markers.iter().map(|m| m.id).collect::<Vec<_>>()
        );
        assert!(found.markers.len() >= 2, "{found:?}");
        // each found marker's corners where the truth projects them
        let truth = PlatformMarkers {
            dictionary: dict,
            ids: vec![0, 1, 2, 3],
            side: 20.0,
            radius: 50.0,
        }
        .corners();
        for m in &found.markers {
            let (_, c) = truth.iter().find(|(id, _)| *id == m.id).unwrap();
            for (seen, t) in m.corners.iter().zip(c) {
                let p = scan.platform * Point3::new(t.x, t.y, 0.0);
                let px = scan.scene.camera.project(&p).unwrap();
                assert!(
                    (px - seen).norm() < 1.0,
                    "marker {}: {seen} against {px}",
                    m.id
                );
            }
        }
    }
}
