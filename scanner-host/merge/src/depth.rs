//! Free space: what a view saw lies on the object's surface, so the space between its camera and
//! that surface is empty. A point of another view, placed by the registration in that space,
//! contradicts the first view — the mark of a view registered wrongly (turned the wrong way
//! round, slid along a flat face) that fits its neighbours' surface by chance. The loops of views
//! cannot tell where no loop closes, or where a wrong group of views closes its own loop; the
//! views' own measurements can.
//!
//! Each view's points give a map of the nearest depth it saw per bin of `BIN_PX` pixels of its
//! image (the ideal pinhole projection of its points, so that the lens's distortion, already
//! taken out of the points, plays no part). Another view's point, moved into this view's camera
//! frame, is tested where the bins around it all hold a depth (inside the seen surface, not at
//! its outline, where neighbouring rays may pass the object): it is in front when it lies more
//! than the tolerance nearer the camera than everything this view saw there.

use scanner_core::nalgebra::{Isometry3, Point3};
use scanner_wire::Header;

use crate::spatial::Cloud;

/// Side of a depth map's bins, pixels: about 1.9 mm at the 360° demo's 540 mm, two to three of
/// a view's points thinned to 0.75 mm across, so that a bin inside the seen surface holds a
/// depth.
const BIN_PX: f64 = 4.0;

/// The nearest depth a view saw in each bin of its image.
#[derive(Debug, Clone)]
pub struct DepthMap {
    /// Focal lengths and principal point, pixels.
    camera: [f64; 4],
    /// Bins across and down.
    cols: usize,
    rows: usize,
    /// Nearest depth per bin, mm (infinite: nothing seen).
    depth: Vec<f32>,
}

impl DepthMap {
    /// The map of `points` (camera frame, mm) seen by the camera of a scan's `header`: its bins
    /// cover the image, the header's width × height over 16 — at most 1024 × 1024 bins (4 MB),
    /// since the collector refuses a header beyond [`scanner_core::config::MAX_LINES`] pixels a
    /// side (300 KB at 1280×960); points behind the camera or outside the image are left out.
    pub fn new(points: &[Point3<f64>], header: &Header) -> DepthMap {
        let c = &header.camera;
        DepthMap::of(
            points,
            [c.fx, c.fy, c.cx, c.cy].map(f64::from),
            (header.width, header.height),
        )
    }

    /// [`DepthMap::new`] for a camera of focal lengths and principal point `camera` (pixels) and
    /// an image of `width × height` pixels (each side taken as at most
    /// [`scanner_core::config::MAX_LINES`], the largest image a head sends).
    pub fn of(points: &[Point3<f64>], camera: [f64; 4], (width, height): (u16, u16)) -> DepthMap {
        let side = |s: u16| {
            (usize::from(s).min(scanner_core::config::MAX_LINES) as f64 / BIN_PX).ceil() as usize
        };
        let (cols, rows) = (side(width), side(height));
        let mut map = DepthMap {
            camera,
            cols,
            rows,
            depth: vec![f32::INFINITY; cols * rows],
        };
        for p in points {
            if let Some(b) = map.bin(p) {
                map.depth[b] = map.depth[b].min(p.z as f32);
            }
        }
        map
    }

    /// The bin `p` (camera frame) projects into: `(col, row)`, `None` behind the camera or
    /// outside the image.
    fn cell(&self, p: &Point3<f64>) -> Option<(usize, usize)> {
        let [fx, fy, cx, cy] = self.camera;
        if !(p.z > 0.0) {
            return None;
        }
        let u = (fx * p.x / p.z + cx) / BIN_PX;
        let v = (fy * p.y / p.z + cy) / BIN_PX;
        let inside = |x: f64, n: usize| x >= 0.0 && x < n as f64;
        (inside(u, self.cols) && inside(v, self.rows)).then_some((u as usize, v as usize))
    }

    fn bin(&self, p: &Point3<f64>) -> Option<usize> {
        self.cell(p).map(|(c, r)| r * self.cols + c)
    }

    /// The nearest depth seen in the 3×3 bins around `p`'s, mm; `None` unless all nine hold
    /// one (`p` projects inside the seen surface, not onto its outline or past it).
    pub fn seen_around(&self, p: &Point3<f64>) -> Option<f64> {
        let (c, r) = self.cell(p)?;
        if c == 0 || r == 0 || c + 1 >= self.cols || r + 1 >= self.rows {
            return None;
        }
        let mut nearest = f32::INFINITY;
        for rr in r - 1..=r + 1 {
            for cc in c - 1..=c + 1 {
                let d = self.depth[rr * self.cols + cc];
                if d == f32::INFINITY {
                    return None;
                }
                nearest = nearest.min(d);
            }
        }
        Some(f64::from(nearest))
    }

    /// Whether `p` (this view's camera frame) lies more than `tol_mm` nearer the camera than
    /// everything the view saw around it; `None` where it does not project inside the seen
    /// surface ([`DepthMap::seen_around`]).
    pub fn in_front(&self, p: &Point3<f64>, tol_mm: f64) -> Option<bool> {
        self.seen_around(p).map(|seen| p.z < seen - tol_mm)
    }
}

/// One view's points against what another view saw.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Conflict {
    /// The view whose points were tested.
    pub view: usize,
    /// The view whose free space they were tested against.
    pub seen_by: usize,
    /// Points that project inside `seen_by`'s seen surface.
    pub tested: usize,
    /// Of those, the points more than the tolerance in front of it.
    pub in_front: usize,
}

impl Conflict {
    /// The share of the tested points in front (0 with none tested).
    pub fn share(&self) -> f64 {
        if self.tested == 0 {
            0.0
        } else {
            self.in_front as f64 / self.tested as f64
        }
    }
}

/// `cloud`'s points (its camera frame), moved by `pose` into the camera frame of `map`'s view,
/// against what that view saw: `(tested, in front)` — the points that project inside its seen
/// surface, and those of them more than `tol_mm` nearer than it.
pub(crate) fn in_front(
    cloud: &Cloud,
    pose: &Isometry3<f64>,
    map: &DepthMap,
    tol_mm: f64,
) -> (usize, usize) {
    let (mut tested, mut front) = (0, 0);
    for p in &cloud.points {
        if let Some(f) = map.in_front(&(pose * p), tol_mm) {
            tested += 1;
            front += usize::from(f);
        }
    }
    (tested, front)
}

/// Every view's points (`clouds`, each in its own camera frame, placed into a common frame by
/// `poses`) against every other view's free space (`map_of(k)`: view `k`'s [`DepthMap`], made
/// when its turn comes and dropped after, so that one map is held at a time): one [`Conflict`]
/// per ordered pair of views with at least one point tested (`in_front`).
pub fn conflicts(
    clouds: &[&Cloud],
    poses: &[Isometry3<f64>],
    tol_mm: f64,
    map_of: impl Fn(usize) -> DepthMap,
) -> Vec<Conflict> {
    let mut out = Vec::new();
    for a in 0..clouds.len() {
        let map = map_of(a);
        for (b, cloud) in clouds.iter().enumerate() {
            if a == b {
                continue;
            }
            // view b's camera frame into view a's
            let (tested, in_front) =
                in_front(cloud, &(poses[a].inverse() * poses[b]), &map, tol_mm);
            if tested > 0 {
                out.push(Conflict {
                    view: b,
                    seen_by: a,
                    tested,
                    in_front,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanner_core::nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn map(c: &Cloud) -> DepthMap {
        DepthMap::of(&c.points, [560.0, 560.0, 319.5, 239.5], (640, 480))
    }

    /// The front half of a sphere of radius 40 mm at 500 mm, as a camera there sees it.
    fn front_of_sphere(pose: &Isometry3<f64>) -> Cloud {
        let centre = Point3::new(0.0, 0.0, 500.0);
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for i in 0..200 {
            for j in 0..100 {
                let lon = std::f64::consts::TAU * f64::from(i) / 200.0;
                let lat = std::f64::consts::PI * (f64::from(j) + 0.5) / 100.0
                    - std::f64::consts::FRAC_PI_2;
                let n = Vector3::new(lat.cos() * lon.cos(), lat.sin(), lat.cos() * lon.sin());
                // the object turned by `pose`, seen from the camera at the origin
                let p = pose * (centre + 40.0 * n);
                let nn = pose.rotation * n;
                if nn.dot(&p.coords) < 0.0 {
                    points.push(p);
                    normals.push(nn);
                }
            }
        }
        Cloud { points, normals }
    }

    #[test]
    fn a_view_placed_right_keeps_out_of_the_others_free_space_and_one_placed_nearer_does_not() {
        let about = |deg: f64| {
            let c = Vector3::new(0.0, 0.0, 500.0);
            Isometry3::from_parts(
                Translation3::from(c),
                UnitQuaternion::from_scaled_axis(Vector3::y() * deg.to_radians()),
            ) * Isometry3::from_parts(Translation3::from(-c), UnitQuaternion::identity())
        };
        // view 1: the object turned by 60° before it was seen; its pose into view 0 turns it back
        let a = front_of_sphere(&Isometry3::identity());
        let b = front_of_sphere(&about(60.0));
        let clouds = [&a, &b];
        let right = [Isometry3::identity(), about(60.0).inverse()];
        let found = conflicts(&clouds, &right, 2.0, |k| map(clouds[k]));
        assert_eq!(found.len(), 2, "{found:?}");
        for c in &found {
            assert!(c.tested > 100 && c.in_front == 0, "{c:?}");
        }
        // placed 10 mm nearer view 1's camera: its points lie in the space view 0 saw empty
        let wrong = [
            Isometry3::identity(),
            about(60.0).inverse() * Isometry3::translation(0.0, 0.0, -10.0),
        ];
        let found = conflicts(&clouds, &wrong, 2.0, |k| map(clouds[k]));
        assert!(found.iter().any(|c| c.share() > 0.5), "{found:?}");
    }

    #[test]
    fn points_that_are_not_numbers_behind_the_camera_or_off_the_image_are_left_out() {
        let odd = Cloud {
            points: vec![
                Point3::new(f64::NAN, 0.0, 500.0),
                Point3::new(0.0, 0.0, f64::NAN),
                Point3::new(0.0, 0.0, -500.0),
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0e9, 0.0, 500.0),
                Point3::new(0.0, f64::INFINITY, 500.0),
            ],
            normals: vec![Vector3::z(); 6],
        };
        let m = map(&odd);
        assert!(m.depth.iter().all(|d| *d == f32::INFINITY));
        // nothing seen: nothing tested, whatever the pose
        let sphere = front_of_sphere(&Isometry3::identity());
        assert_eq!(in_front(&sphere, &Isometry3::identity(), &m, 1.0), (0, 0));
        let nan = Isometry3::translation(f64::NAN, 0.0, 0.0);
        assert_eq!(in_front(&sphere, &nan, &map(&sphere), 1.0), (0, 0));
        assert_eq!(
            in_front(&odd, &Isometry3::identity(), &map(&sphere), 1.0),
            (0, 0)
        );
        // an image size beyond what a head sends is taken at the largest
        let big = DepthMap::of(&[], [560.0, 560.0, 0.0, 0.0], (u16::MAX, u16::MAX));
        assert_eq!(
            big.depth.len(),
            (scanner_core::config::MAX_LINES / 4).pow(2)
        );
    }
}
