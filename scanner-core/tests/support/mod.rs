//! Exact synthetic scenes for the geometry tests: a camera, a concave two-plane board with marker
//! layouts, a laser plane from a hand-held source, in f64 with known truth.
#![allow(dead_code)]

use proptest::prelude::*;
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Point2, Point3, Rotation3, Vector3};
use scanner_core::{Camera, Distortion};

pub const WIDTH: u32 = 1600;
pub const HEIGHT: u32 = 1200;

/// The random choices a scene is built from.
#[derive(Debug, Clone)]
pub struct SceneParams {
    pub distance: f64,
    pub angle_deg: f64,
    pub yaw: f64,
    pub pitch: f64,
    pub roll: f64,
    pub offset: (f64, f64),
    pub fx: f64,
    pub aspect: f64,
    pub pp: (f64, f64),
    pub dist: [f64; 5],
    /// Laser source position as fractions of the distance (x, y, z).
    pub laser: (f64, f64, f64),
    /// Laser target heights on the left and right half, in marker spacings.
    pub laser_v: (f64, f64),
}

pub fn params(distortion: bool) -> impl Strategy<Value = SceneParams> {
    let k = if distortion { 1.0 } else { 0.0 };
    (
        (200.0..4000.0f64, 60.0..150.0f64),
        (-0.2..0.2f64, -0.15..0.15f64, -0.15..0.15f64),
        (-0.05..0.05f64, -0.05..0.05f64),
        (
            900.0..2000.0f64,
            0.98..1.02f64,
            -40.0..40.0f64,
            -30.0..30.0f64,
        ),
        (
            -0.2..0.2f64,
            -0.05..0.05f64,
            -0.001..0.001f64,
            -0.001..0.001f64,
            -0.02..0.02f64,
        ),
        (
            -0.3..0.3f64,
            0.15..0.5f64,
            -0.1..0.1f64,
            -1.0..1.0f64,
            -1.0..1.0f64,
        ),
        any::<bool>(),
    )
        .prop_map(
            move |(
                (distance, angle_deg),
                (yaw, pitch, roll),
                (ox, oy),
                (fx, aspect, px, py),
                d,
                (lx, ly, lz, v1, v2),
                side,
            )| {
                SceneParams {
                    distance,
                    angle_deg,
                    yaw,
                    pitch,
                    roll,
                    offset: (ox * distance, oy * distance),
                    fx,
                    aspect,
                    pp: (px, py),
                    dist: [d.0 * k, d.1 * k, d.2 * k, d.3 * k, d.4 * k],
                    // held above or below the camera: the stripe is roughly horizontal
                    laser: (lx, if side { ly } else { -ly }, lz),
                    laser_v: (v1, v2),
                }
            },
        )
}

/// Exact scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub camera: Camera<f64>,
    pub left: Pose,
    pub right: Pose,
    /// Marker spacing (mm): distance / 7, as in the paper's Table 3.
    pub spacing: f64,
    pub distance: f64,
    pub angle: f64,
    pub crease_point: Point3<f64>,
    pub crease_dir: Vector3<f64>,
    pub laser_source: Point3<f64>,
    /// Laser plane as (unit normal facing the camera, d).
    pub laser_normal: Vector3<f64>,
    pub laser_d: f64,
}

impl Scene {
    pub fn new(p: &SceneParams) -> Scene {
        let camera = Camera::new(
            p.fx,
            p.fx * p.aspect,
            (f64::from(WIDTH) - 1.0) / 2.0 + p.pp.0,
            (f64::from(HEIGHT) - 1.0) / 2.0 + p.pp.1,
            Distortion {
                k1: p.dist[0],
                k2: p.dist[1],
                p1: p.dist[2],
                p2: p.dist[3],
                k3: p.dist[4],
            },
        )
        .unwrap();
        let half = p.angle_deg.to_radians() / 2.0;
        let g = Rotation3::from_euler_angles(p.pitch, p.yaw, p.roll);
        let origin = Point3::new(p.offset.0, p.offset.1, p.distance);
        let c = g * Vector3::y();
        let hl = g * Vector3::new(-half.sin(), 0.0, -half.cos());
        let hr = g * Vector3::new(half.sin(), 0.0, -half.cos());
        let pose = |h: Vector3<f64>| Pose {
            rotation: Rotation3::from_matrix_unchecked(
                scanner_core::nalgebra::Matrix3::from_columns(&[h, c, h.cross(&c)]),
            ),
            translation: origin.coords,
        };
        let spacing = p.distance / 7.0;
        // Laser: through the source and a point on each half.
        let source = Point3::new(
            p.laser.0 * p.distance,
            p.laser.1 * p.distance,
            p.laser.2 * p.distance,
        );
        let left = pose(hl);
        let right = pose(hr);
        let tl = left.transform(&Point2::new(1.5 * spacing, p.laser_v.0 * spacing));
        let tr = right.transform(&Point2::new(1.5 * spacing, p.laser_v.1 * spacing));
        let mut n = (tl - source).cross(&(tr - source)).normalize();
        let mut d = -n.dot(&source.coords);
        if d < 0.0 {
            n = -n;
            d = -d;
        }
        Scene {
            camera,
            left,
            right,
            spacing,
            distance: p.distance,
            angle: p.angle_deg.to_radians(),
            crease_point: origin,
            crease_dir: c,
            laser_source: source,
            laser_normal: n,
            laser_d: d,
        }
    }

    /// `true` if the camera sees the laser plane under at least ~6° (sin 0.1) at the crease,
    /// i.e. the frame is not one of the degenerate ones that the estimators refuse.
    pub fn well_viewed(&self) -> bool {
        self.laser_d > 0.1 * self.laser_crease_point().coords.norm()
    }

    /// The paper's layout: two lines of three markers, spacing m, 2m apart.
    pub fn paper_layout(&self) -> [[Point2<f64>; 3]; 2] {
        let m = self.spacing;
        [-1.0, 1.0].map(|v| [0.6, 1.6, 2.6].map(|u| Point2::new(u * m, v * m)))
    }

    /// A denser grid layout with `cols` × `rows` markers.
    pub fn grid_layout(&self, cols: usize, rows: usize) -> Vec<Point2<f64>> {
        let m = self.spacing;
        let mut out = Vec::new();
        for j in 0..rows {
            for i in 0..cols {
                let u = 0.4 * m + 2.4 * m * i as f64 / (cols - 1).max(1) as f64;
                let v = -1.2 * m + 2.4 * m * j as f64 / (rows - 1).max(1) as f64;
                out.push(Point2::new(u, v));
            }
        }
        out
    }

    pub fn in_image(&self, px: &Point2<f64>) -> bool {
        px.x >= 0.0 && px.y >= 0.0 && px.x <= f64::from(WIDTH - 1) && px.y <= f64::from(HEIGHT - 1)
    }

    /// Pixel of a 3-D point, if it is in front of the camera and inside the image.
    pub fn pixel(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        let px = self.camera.project(p).ok()?;
        self.in_image(&px).then_some(px)
    }

    /// Exact stripe points on the board: `n` per side, from the crease crossing outward up to
    /// 3 spacings, only those visible in the image.
    pub fn stripe_points(&self, n: usize) -> (Vec<Point3<f64>>, Vec<Point3<f64>>) {
        let side = |pose: &Pose| -> Vec<Point3<f64>> {
            let normal = pose.rotation * Vector3::z();
            let mut dir = self.laser_normal.cross(&normal).normalize();
            let outward = pose.rotation * Vector3::x();
            if dir.dot(&outward) < 0.0 {
                dir = -dir;
            }
            let s = self.laser_crease_point();
            (1..=n)
                .map(|k| s + dir * (3.0 * self.spacing * k as f64 / n as f64))
                .filter(|p| self.pixel(p).is_some())
                .collect()
        };
        (side(&self.left), side(&self.right))
    }

    /// Where the laser plane meets the crease.
    pub fn laser_crease_point(&self) -> Point3<f64> {
        let t = -(self.laser_normal.dot(&self.crease_point.coords) + self.laser_d)
            / self.laser_normal.dot(&self.crease_dir);
        self.crease_point + self.crease_dir * t
    }

    /// Points on the laser plane in front of the board: board stripe points moved towards the
    /// laser source by the fraction `lambda`.
    pub fn object_points(&self, lambda: &[f64]) -> Vec<Point3<f64>> {
        let (l, r) = self.stripe_points(12);
        l.iter()
            .chain(&r)
            .zip(lambda.iter().cycle())
            .map(|(b, &f)| b + (self.laser_source - b) * f)
            .filter(|p| self.pixel(p).is_some())
            .collect()
    }

    /// Signed distance of a point from a board half's plane (positive towards the camera).
    pub fn board_distance(&self, pose: &Pose, p: &Point3<f64>) -> f64 {
        let mut n = pose.rotation * Vector3::z();
        let mut d = -n.dot(&pose.translation);
        if d < 0.0 {
            n = -n;
            d = -d;
        }
        n.dot(&p.coords) + d
    }

    /// `true` if every marker of both planes is visible.
    pub fn markers_visible(&self, layout: &[Point2<f64>]) -> bool {
        [&self.left, &self.right].iter().all(|pose| {
            layout
                .iter()
                .all(|uv| self.pixel(&pose.transform(uv)).is_some())
        })
    }
}

pub fn rel(a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    (a - b).norm() / b.coords.norm()
}

pub fn rel32(a: &Point3<f32>, b: &Point3<f64>) -> f64 {
    (a.cast::<f64>() - b).norm() / b.coords.norm()
}

pub mod monte_carlo;
pub mod real;
pub mod stripes;
