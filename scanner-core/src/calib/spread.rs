//! The calibration's share of a point's uncertainty.
//!
//! A scan's points are rays through the calibrated camera met with a laser plane that is itself
//! fitted to rays met with the calibrated board planes: an error of the intrinsics or of a board
//! plane moves every point of a frame together. The calibration's covariance is carried here as
//! a few independent *modes* — each one standard deviation of the calibration along one
//! direction of its covariance — and each frame's points are moved by each mode to first order:
//! the rays by the mode's change of the lens (looked up on a coarse grid of the image), the board
//! points by that and by the mode's change of the board planes, the laser plane refitted
//! (linearised: one 3×3 system shared by all modes), and every object point moved along. A
//! point's calibration share is the root sum of squares of its moves.
//!
//! The modes: the intrinsics' covariance (`fx, fy, cx, cy, k1, k2, p1, p2, k3`) split into its
//! eigen-directions, each moving the lens and — through the board's fit, which was made with the
//! same intrinsics — both board planes; and each sheet's plane's own scatter (its markers'
//! noise), split likewise.

use nalgebra::{
    Matrix3, Matrix4, Point2, Point3, SMatrix, SVector, SymmetricEigen, Vector2, Vector3,
};

use super::bundle::{INTRINSICS, camera_from, params};
use crate::{Camera, GeomError};

/// Nodes of the grid over the image on which a lens mode's change of the rays is kept.
pub const GRID: (usize, usize) = (13, 10);
/// The most modes: one per intrinsic, three per sheet.
pub const MAX_MODES: usize = INTRINSICS + 6;
const NODES: usize = GRID.0 * GRID.1;

/// A board sheet's plane `n·x + d = 0` as the calibration knows it: the covariance of
/// `(n_x, n_y, n_z, d)` from its markers' noise (mm for `d`), and how it moves with the
/// intrinsics (`∂(n, d)/∂p`, the board refitted with the changed camera).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetSpread {
    /// Covariance of the plane from the markers' noise.
    pub noise: [[f64; 4]; 4],
    /// The plane's change per unit change of each intrinsic.
    pub from_intrinsics: [[f64; INTRINSICS]; 4],
}

/// One mode: the rays' change over the image (normalised coordinates, at the grid's nodes) and
/// each sheet's plane change `(δn, δd)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Mode {
    rays: Option<[[f32; 2]; NODES]>,
    planes: [[f32; 4]; 2],
}

/// The calibration's modes for one image size: what [`CalibrationSpread::point_moves`] applies
/// to each frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationSpread {
    modes: [Mode; MAX_MODES],
    count: usize,
    size: (f32, f32),
}

/// Eigen-directions of a covariance as one-σ steps, those below `1e-12` of the largest left
/// out.
macro_rules! steps {
    ($cov:expr, $n:literal) => {{
        let cov = $cov;
        let e = SymmetricEigen::new((cov + cov.transpose()) * 0.5);
        let top = e.eigenvalues.iter().copied().fold(0.0, f64::max);
        let mut out = [SVector::<f64, $n>::zeros(); $n];
        let mut count = 0;
        for k in 0..$n {
            let l = e.eigenvalues[k];
            if l > 0.0 && l > 1e-12 * top {
                out[count] = e.eigenvectors.column(k) * libm::sqrt(l);
                count += 1;
            }
        }
        (out, count)
    }};
}

impl CalibrationSpread {
    /// The modes of a calibration: `camera` at image `size` with the intrinsics' covariance
    /// `intrinsics`, and each sheet's plane spread (left, right).
    ///
    /// # Errors
    /// [`GeomError::NotFinite`] for a covariance or plane spread with non-finite values, and as
    /// [`Camera::new`] for a mode that moves the camera out of what is a camera.
    pub fn new(
        camera: &Camera<f64>,
        size: (u32, u32),
        intrinsics: &[[f64; INTRINSICS]; INTRINSICS],
        sheets: &[SheetSpread; 2],
    ) -> Result<Self, GeomError> {
        let finite = intrinsics.iter().flatten().all(|v| v.is_finite())
            && sheets.iter().all(|s| {
                s.noise.iter().flatten().all(|v| v.is_finite())
                    && s.from_intrinsics.iter().flatten().all(|v| v.is_finite())
            });
        if !finite || size.0 == 0 || size.1 == 0 {
            return Err(GeomError::NotFinite);
        }
        let mut out = CalibrationSpread {
            modes: [Mode {
                rays: None,
                planes: [[0.0; 4]; 2],
            }; MAX_MODES],
            count: 0,
            size: (size.0 as f32, size.1 as f32),
        };
        let cov = SMatrix::<f64, INTRINSICS, INTRINSICS>::from_fn(|i, j| intrinsics[i][j]);
        let p0 = params(camera);
        let (intrinsic_steps, n) = steps!(cov, 9);
        for step in &intrinsic_steps[..n] {
            // The rays' change, linear in the step: central differences over a thousandth of it
            // (a whole σ of a loosely held distortion term can bend the lens past inverting).
            const EPS: f64 = 1e-3;
            let shifted = |sign: f64| {
                let p: [f64; INTRINSICS] = core::array::from_fn(|i| p0[i] + sign * EPS * step[i]);
                camera_from(&p)
            };
            let (plus, minus) = (shifted(1.0)?, shifted(-1.0)?);
            let mut rays = [[0.0f32; 2]; NODES];
            for (k, node) in rays.iter_mut().enumerate() {
                let q = node_pixel(k, size);
                // a node where the lens does not invert (beyond its valid field) moves nothing
                if let (Ok(a), Ok(b)) = (plus.undistort(&q), minus.undistort(&q)) {
                    let d: Vector2<f64> = (a - b) / (2.0 * EPS);
                    *node = [d.x as f32, d.y as f32];
                }
            }
            let planes = sheets.map(|s| {
                let j = SMatrix::<f64, 4, INTRINSICS>::from_fn(|r, c| s.from_intrinsics[r][c]);
                let d = j * step;
                [d[0] as f32, d[1] as f32, d[2] as f32, d[3] as f32]
            });
            out.push(Mode {
                rays: Some(rays),
                planes,
            });
        }
        for (side, s) in sheets.iter().enumerate() {
            let noise = Matrix4::from_fn(|i, j| s.noise[i][j]);
            let (noise_steps, n) = steps!(noise, 4);
            let mut order: [usize; 4] = [0, 1, 2, 3];
            order[..n]
                .sort_unstable_by(|&a, &b| noise_steps[b].norm().total_cmp(&noise_steps[a].norm()));
            for &k in order[..n].iter().take(3) {
                let step = noise_steps[k];
                let mut planes = [[0.0f32; 4]; 2];
                planes[side] = [
                    step[0] as f32,
                    step[1] as f32,
                    step[2] as f32,
                    step[3] as f32,
                ];
                out.push(Mode { rays: None, planes });
            }
        }
        Ok(out)
    }

    fn push(&mut self, m: Mode) {
        if self.count < MAX_MODES {
            self.modes[self.count] = m;
            self.count += 1;
        }
    }

    /// Modes kept.
    pub fn modes(&self) -> usize {
        self.count
    }

    /// The change of the ray `(x, y, 1)` through pixel `px` under mode `k` (bilinear between the
    /// grid's nodes; none for a mode that leaves the lens alone).
    fn ray_change(&self, k: usize, px: &Point2<f32>) -> Vector3<f32> {
        let Some(rays) = &self.modes[k].rays else {
            return Vector3::zeros();
        };
        let (cols, rows) = GRID;
        let gx = (px.x / self.size.0 * (cols - 1) as f32).clamp(0.0, (cols - 1) as f32);
        let gy = (px.y / self.size.1 * (rows - 1) as f32).clamp(0.0, (rows - 1) as f32);
        let (x0, y0) = ((gx as usize).min(cols - 2), (gy as usize).min(rows - 2));
        let (fx, fy) = (gx - x0 as f32, gy - y0 as f32);
        let at = |x: usize, y: usize| rays[y * cols + x];
        let mut d = [0.0f32; 2];
        for (i, v) in d.iter_mut().enumerate() {
            *v = (1.0 - fy) * ((1.0 - fx) * at(x0, y0)[i] + fx * at(x0 + 1, y0)[i])
                + fy * ((1.0 - fx) * at(x0, y0 + 1)[i] + fx * at(x0 + 1, y0 + 1)[i]);
        }
        Vector3::new(d[0], d[1], 0.0)
    }

    /// Each object point's calibration share, mm, written to `out` (same order as `objects`).
    ///
    /// `board` holds the frame's board points the laser plane was fitted to — pixel, ray
    /// (`z = 1`), point and sheet (0 left, 1 right) — `sheets` the board planes `(n, d)`, `laser`
    /// the fitted laser plane `(n, d)`, and `objects` each object point's pixel, ray and point.
    /// Points whose geometry makes no move (a ray along a plane) get infinity.
    pub fn point_moves(
        &self,
        board: impl Iterator<Item = (Point2<f32>, Vector3<f32>, Point3<f32>, usize)> + Clone,
        sheets: &[(Vector3<f32>, f32); 2],
        laser: (Vector3<f32>, f32),
        objects: impl Iterator<Item = (Point2<f32>, Vector3<f32>, Point3<f32>)> + Clone,
        out: &mut [f32],
    ) {
        out.iter_mut().for_each(|v| *v = 0.0);
        let (n, _) = laser;
        // Two directions across the laser plane's normal, and the board points' centroid: the
        // linearised refit solves for (δn along e1, δn along e2, δ offset at the centroid).
        let e1 = if libm::fabsf(n.x) < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = (e1 - n * n.dot(&e1)).normalize();
        let e2 = n.cross(&e1);
        let mut centroid = Vector3::zeros();
        let mut count = 0.0f32;
        for (_, _, b, _) in board.clone() {
            centroid += b.coords;
            count += 1.0;
        }
        if count < 3.0 {
            out.iter_mut().for_each(|v| *v = f32::INFINITY);
            return;
        }
        centroid /= count;
        let design = |b: &Point3<f32>| {
            let c = b.coords - centroid;
            Vector3::new(e1.dot(&c), e2.dot(&c), 1.0)
        };
        let mut ata = Matrix3::zeros();
        for (_, _, b, _) in board.clone() {
            let a = design(&b);
            ata += a * a.transpose();
        }
        let Some(chol) = ata.cholesky() else {
            out.iter_mut().for_each(|v| *v = f32::INFINITY);
            return;
        };
        for k in 0..self.count {
            let planes = self.modes[k].planes;
            let mut rhs = Vector3::zeros();
            for (px, ray, b, side) in board.clone() {
                let (ns, _) = sheets[side.min(1)];
                let p = planes[side.min(1)];
                let (dns, dds) = (Vector3::new(p[0], p[1], p[2]), p[3]);
                let dr = self.ray_change(k, &px);
                let t = b.z / ray.z;
                let along = ns.dot(&ray);
                if libm::fabsf(along) < 1e-9 {
                    continue;
                }
                let dt = -(dns.dot(&b.coords) + t * ns.dot(&dr) + dds) / along;
                let db = ray * dt + dr * t;
                rhs -= design(&b) * n.dot(&db);
            }
            let x = chol.solve(&rhs);
            let dn = e1 * x[0] + e2 * x[1];
            let dd = x[2] - dn.dot(&centroid);
            for ((px, ray, p), v) in objects.clone().zip(out.iter_mut()) {
                let dr = self.ray_change(k, &px);
                let t = p.z / ray.z;
                let along = n.dot(&ray);
                if libm::fabsf(along) < 1e-9 {
                    *v = f32::INFINITY;
                    continue;
                }
                let dt = -(dn.dot(&p.coords) + t * n.dot(&dr) + dd) / along;
                *v += (ray * dt + dr * t).norm_squared();
            }
        }
        out.iter_mut().for_each(|v| *v = libm::sqrtf(*v));
    }
}

/// The pixel of grid node `k` (row by row; the nodes span the image from edge to edge).
fn node_pixel(k: usize, size: (u32, u32)) -> Point2<f64> {
    let (cols, rows) = GRID;
    Point2::new(
        (k % cols) as f64 / (cols - 1) as f64 * f64::from(size.0),
        (k / cols) as f64 / (rows - 1) as f64 * f64::from(size.1),
    )
}
