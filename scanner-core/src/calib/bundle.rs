//! Intrinsics and target poses from views of planar targets (Zhang 2000), refined jointly.
//!
//! Each [`TargetImage`] is one image of a planar target: marker positions on the sheet (mm) and where a
//! detector found them (pixels). [`initial_camera`] is Zhang's closed form (zero skew) on the
//! views' homographies, [`initial_pose`] a view's pose from its homography, and [`refine`] the
//! Levenberg–Marquardt minimisation of the reprojection error over the free intrinsics
//! (`fx, fy, cx, cy, k1, k2, p1, p2, k3`) and all poses together. Markers are modelled as printed
//! discs of a given radius ([`model`](super::model)); radius 0 models corners.
//!
//! Memory is fixed: the normal equations have an arrow shape (each pose touches only its own
//! view), so every view's 6×6 block is folded into a 9×9 reduced system for the intrinsics by the
//! Schur complement, and the views' pose steps are recovered afterwards by recomputing their
//! blocks. Nothing is stored per view or per marker beyond the caller's slices.

use nalgebra::{
    Matrix3, Matrix6, Point2, Rotation3, SMatrix, SVector, SymmetricEigen, Vector2, Vector3,
    Vector6,
};

use super::model::dot_centre;
use crate::geometry::Pose;
use crate::geometry::pose::{homography, pose_from_homography};
use crate::{Camera, Distortion, GeomError};

/// Number of intrinsic parameters: `fx, fy, cx, cy, k1, k2, p1, p2, k3`.
pub const INTRINSICS: usize = 9;
/// Largest number of Levenberg–Marquardt iterations.
pub const MAX_ITERATIONS: usize = 200;
/// Fewest markers per view.
pub const MIN_MARKERS: usize = 4;

type Mat9 = SMatrix<f64, 9, 9>;
type Vec9 = SVector<f64, 9>;
type Mat69 = SMatrix<f64, 6, 9>;
/// A marker's residual and its Jacobians (intrinsics, pose).
type Observation = (Vector2<f64>, SMatrix<f64, 2, 9>, SMatrix<f64, 2, 6>);

/// Which intrinsics a refinement estimates (the others stay as given), in the order
/// `fx, fy, cx, cy, k1, k2, p1, p2, k3`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Free(pub [bool; INTRINSICS]);

impl Free {
    /// Poses only: the camera is fixed.
    pub const NONE: Free = Free([false; INTRINSICS]);
    /// Every intrinsic.
    pub const ALL: Free = Free([true; INTRINSICS]);
    /// Everything but `k3`, which few or fronto-parallel views do not determine.
    pub const NO_K3: Free = Free([true, true, true, true, true, true, true, true, false]);

    fn any(&self) -> bool {
        self.0.iter().any(|&f| f)
    }
}

/// One image of a planar target: `layout[i]` (mm on the sheet) was found at `pixels[i]`.
#[derive(Debug, Clone, Copy)]
pub struct TargetImage<'a> {
    /// Marker positions on the sheet, mm.
    pub layout: &'a [Point2<f64>],
    /// Where they were found, pixels.
    pub pixels: &'a [Point2<f64>],
}

impl TargetImage<'_> {
    fn check(&self) -> Result<(), GeomError> {
        if self.layout.len() != self.pixels.len() {
            return Err(GeomError::LengthMismatch);
        }
        if self.layout.len() < MIN_MARKERS {
            return Err(GeomError::TooFewPoints {
                needed: MIN_MARKERS,
                got: self.layout.len(),
            });
        }
        let finite = |p: &Point2<f64>| p.x.is_finite() && p.y.is_finite();
        if !self.layout.iter().all(finite) || !self.pixels.iter().all(finite) {
            return Err(GeomError::NotFinite);
        }
        Ok(())
    }
}

/// The result of [`refine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refinement {
    /// The refined camera.
    pub camera: Camera<f64>,
    /// Root-mean-square reprojection error over all markers, pixels (per marker, both axes).
    pub rms_px: f64,
    /// Largest reprojection error, pixels.
    pub max_px: f64,
    /// Levenberg–Marquardt iterations used.
    pub iterations: usize,
}

/// A camera's intrinsics in [`Covariance`]'s order: `fx, fy, cx, cy, k1, k2, p1, p2, k3`.
pub fn params(c: &Camera<f64>) -> [f64; INTRINSICS] {
    let d = c.distortion();
    let pp = c.principal_point();
    [c.fx(), c.fy(), pp.x, pp.y, d.k1, d.k2, d.p1, d.p2, d.k3]
}

/// The camera of intrinsics `p` in [`params`]' order.
///
/// # Errors
/// As [`Camera::new`].
pub fn camera_from(p: &[f64; INTRINSICS]) -> Result<Camera<f64>, GeomError> {
    Camera::new(
        p[0],
        p[1],
        p[2],
        p[3],
        Distortion {
            k1: p[4],
            k2: p[5],
            p1: p[6],
            p2: p[7],
            k3: p[8],
        },
    )
}

/// `pose` moved by `d`: a rotation by the vector `d[0..3]` applied in camera coordinates, then
/// the translation `d[3..6]` added (the step [`refine`] and [`pose_spread`] use).
pub fn step_pose(pose: &Pose, d: &Vector6<f64>) -> Pose {
    Pose {
        rotation: Rotation3::new(Vector3::new(d[0], d[1], d[2])) * pose.rotation,
        translation: pose.translation + Vector3::new(d[3], d[4], d[5]),
    }
}

/// One marker's residual (predicted − observed, pixels) and, if asked, its Jacobians with respect
/// to the intrinsics and to the pose (rotation vector applied on the left, translation).
fn observe(
    cam: &Camera<f64>,
    pose: &Pose,
    sheet: &Point2<f64>,
    radius: f64,
    pixel: &Point2<f64>,
    jacobians: bool,
) -> Result<Observation, GeomError> {
    let n = dot_centre(pose, sheet, radius)?;
    let (d, jd) = cam.distortion().apply_with_jacobian(n);
    let (fx, fy) = (cam.fx(), cam.fy());
    let pp = cam.principal_point();
    let r = Vector2::new(fx * d.x + pp.x - pixel.x, fy * d.y + pp.y - pixel.y);
    if !(r.x.is_finite() && r.y.is_finite()) {
        return Err(GeomError::NotFinite);
    }
    let mut jc = SMatrix::<f64, 2, 9>::zeros();
    let mut jp = SMatrix::<f64, 2, 6>::zeros();
    if jacobians {
        let (x, y) = (n.x, n.y);
        let r2 = x * x + y * y;
        let col = |a: f64, b: f64| Vector2::new(fx * a, fy * b);
        let cols = [
            Vector2::new(d.x, 0.0),
            Vector2::new(0.0, d.y),
            Vector2::new(1.0, 0.0),
            Vector2::new(0.0, 1.0),
            col(x * r2, y * r2),
            col(x * r2 * r2, y * r2 * r2),
            col(2.0 * x * y, r2 + 2.0 * y * y),
            col(r2 + 2.0 * x * x, 2.0 * x * y),
            col(x * r2 * r2 * r2, y * r2 * r2 * r2),
        ];
        for (k, c) in cols.iter().enumerate() {
            jc.set_column(k, c);
        }
        // d(pixel)/d(n) = diag(fx, fy) · J_distortion; d(n)/d(pose) by central differences.
        let scale = 1.0 + pose.translation.norm();
        for k in 0..6 {
            let h = if k < 3 { 1e-6 } else { 1e-6 * scale };
            let mut e = Vector6::zeros();
            e[k] = h;
            let plus = dot_centre(&step_pose(pose, &e), sheet, radius)?;
            let minus = dot_centre(&step_pose(pose, &-e), sheet, radius)?;
            let dn = jd * ((plus - minus) / (2.0 * h));
            jp.set_column(k, &Vector2::new(fx * dn.x, fy * dn.y));
        }
    }
    Ok((r, jc, jp))
}

/// A view's blocks of the normal equations.
struct Blocks {
    a: Matrix6<f64>,
    b: Mat69,
    gp: Vector6<f64>,
    c: Mat9,
    gc: Vec9,
    cost: f64,
    max: f64,
}

fn blocks(
    cam: &Camera<f64>,
    free: Free,
    view: &TargetImage,
    pose: &Pose,
    radius: f64,
) -> Result<Blocks, GeomError> {
    let mut bl = Blocks {
        a: Matrix6::zeros(),
        b: Mat69::zeros(),
        gp: Vector6::zeros(),
        c: Mat9::zeros(),
        gc: Vec9::zeros(),
        cost: 0.0,
        max: 0.0,
    };
    for (s, px) in view.layout.iter().zip(view.pixels) {
        let (r, mut jc, jp) = observe(cam, pose, s, radius, px, true)?;
        for (k, f) in free.0.iter().enumerate() {
            if !f {
                jc.column_mut(k).fill(0.0);
            }
        }
        bl.a += jp.transpose() * jp;
        bl.b += jp.transpose() * jc;
        bl.gp += jp.transpose() * r;
        bl.c += jc.transpose() * jc;
        bl.gc += jc.transpose() * r;
        bl.cost += r.norm_squared();
        bl.max = bl.max.max(r.norm());
    }
    Ok(bl)
}

fn damped6(a: &Matrix6<f64>, mu: f64) -> Result<Matrix6<f64>, GeomError> {
    let mut m = *a;
    for i in 0..6 {
        m[(i, i)] += mu * a[(i, i)].max(1e-9);
    }
    m.cholesky()
        .map(|c| c.inverse())
        .ok_or(GeomError::IllConditioned)
}

/// Sum of squared residuals and the largest residual of every view.
fn total_cost(
    cam: &Camera<f64>,
    views: &[TargetImage],
    poses: &[Pose],
    radius: f64,
) -> Result<(f64, f64, usize), GeomError> {
    let (mut cost, mut max, mut n) = (0.0, 0.0f64, 0);
    for (v, p) in views.iter().zip(poses) {
        for (s, px) in v.layout.iter().zip(v.pixels) {
            let (r, _, _) = observe(cam, p, s, radius, px, false)?;
            cost += r.norm_squared();
            max = max.max(r.norm());
            n += 1;
        }
    }
    Ok((cost, max, n))
}

/// Refines the free intrinsics of `camera` and every view's pose (in place) to minimise the
/// reprojection error of discs of radius `radius` (mm; 0 for corners).
///
/// `poses` start from [`initial_pose`] (or any nearby guess). With [`Free::NONE`] this is a
/// pose-only refinement for a calibrated camera.
///
/// # Errors
/// [`GeomError::LengthMismatch`] if `poses` and `views` differ in length, view errors
/// ([`GeomError::TooFewPoints`], [`GeomError::NotFinite`]), [`GeomError::TooFewPoints`] when the
/// free intrinsics outnumber the equations, [`GeomError::BehindCamera`] for a pose that puts a
/// marker behind the camera.
pub fn refine(
    camera: &Camera<f64>,
    free: Free,
    views: &[TargetImage],
    poses: &mut [Pose],
    radius: f64,
) -> Result<Refinement, GeomError> {
    check_problem(free, views, poses, radius)?;
    let mut cam = *camera;
    let (mut cost, _, count) = total_cost(&cam, views, poses, radius)?;
    let mut mu = 1e-3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS && mu <= 1e16 {
        iterations += 1;
        let lm = Damped {
            cam: &cam,
            free,
            views,
            radius,
            mu,
        };
        let Some((dc, candidate)) = lm.intrinsics_step(poses)? else {
            mu *= 10.0;
            continue;
        };
        match lm.cost_after(poses, &dc, &candidate) {
            Some(new_cost) if new_cost <= cost => {
                for (v, p) in views.iter().zip(poses.iter_mut()) {
                    *p = lm.pose_step(v, p, &dc)?;
                }
                let small_step = dc.norm() <= 1e-12 * (1.0 + params(&candidate)[0].abs());
                let converged = cost - new_cost <= 1e-13 * cost.max(1e-300);
                cam = candidate;
                cost = new_cost;
                mu = (mu / 10.0).max(1e-12);
                if converged && small_step || cost == 0.0 {
                    break;
                }
            }
            _ => mu *= 10.0,
        }
    }
    let (cost, max_px, _) = total_cost(&cam, views, poses, radius)?;
    Ok(Refinement {
        camera: cam,
        rms_px: libm::sqrt(cost / count as f64),
        max_px,
        iterations,
    })
}

/// The uncertainty of a calibration's intrinsics, from the fit's normal equations at its
/// solution and the scatter of its residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance {
    /// Covariance of `fx, fy, cx, cy, k1, k2, p1, p2, k3` (pixels², pixels and unitless; zero
    /// rows and columns for the parameters held fixed), the poses' share eliminated.
    pub matrix: [[f64; INTRINSICS]; INTRINSICS],
    /// Standard deviation of a feature's position per coordinate, pixels: the residuals' root
    /// sum of squares over the degrees of freedom (observations less unknowns).
    pub noise_px: f64,
}

/// The covariance of the free intrinsics of `camera` at a solution of [`refine`] (`views` at
/// `poses`): `σ² S⁻¹`, `S` the normal matrix of the intrinsics with every pose eliminated (the
/// Schur complement [`refine`] steps with, undamped) and `σ` the residuals' scatter. It assumes
/// independent, equal noise on every feature coordinate and a model that fits: the scatter of
/// two calibrations from disjoint images tells whether it does.
///
/// # Errors
/// As [`refine`]; [`GeomError::IllConditioned`] when the normal matrix is singular (a
/// parameter the views do not determine).
pub fn covariance(
    camera: &Camera<f64>,
    free: Free,
    views: &[TargetImage],
    poses: &[Pose],
    radius: f64,
) -> Result<Covariance, GeomError> {
    check_problem(free, views, poses, radius)?;
    let mut s = Mat9::zeros();
    let mut cost = 0.0;
    let mut count = 0usize;
    for (v, p) in views.iter().zip(poses) {
        let bl = blocks(camera, free, v, p, radius)?;
        let ainv = damped6(&bl.a, 0.0)?;
        s += bl.c - bl.b.transpose() * ainv * bl.b;
        cost += bl.cost;
        count += v.layout.len();
    }
    let n_free = free.0.iter().filter(|&&f| f).count();
    for (i, f) in free.0.iter().enumerate() {
        if !f {
            s.row_mut(i).fill(0.0);
            s.column_mut(i).fill(0.0);
            s[(i, i)] = 1.0;
        }
    }
    let dof = (2 * count).saturating_sub(6 * views.len() + n_free).max(1);
    let noise2 = cost / dof as f64;
    let inv = s.cholesky().ok_or(GeomError::IllConditioned)?.inverse();
    let mut matrix = [[0.0; INTRINSICS]; INTRINSICS];
    for (i, row) in matrix.iter_mut().enumerate() {
        for (j, m) in row.iter_mut().enumerate() {
            if free.0[i] && free.0[j] {
                *m = noise2 * inv[(i, j)];
            }
        }
    }
    Ok(Covariance {
        matrix,
        noise_px: libm::sqrt(noise2),
    })
}

/// How a view's pose, fitted with the camera held ([`refine`] with [`Free::NONE`]), answers to
/// the intrinsics and to its features' noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSpread {
    /// The pose's change ([`step_pose`]'s `d`) per unit change of each intrinsic, the pose
    /// refitted: `−A⁻¹B`, `A` the pose's normal matrix and `B` its cross terms.
    pub from_intrinsics: SMatrix<f64, 6, INTRINSICS>,
    /// `A⁻¹`: the pose's covariance per unit variance of a feature coordinate.
    pub per_noise: Matrix6<f64>,
    /// The residuals' sum of squares, pixels².
    pub cost: f64,
    /// Features.
    pub features: usize,
}

/// The [`PoseSpread`] of `view` at `pose` (a solution for `camera`).
///
/// # Errors
/// As [`refine`]; [`GeomError::IllConditioned`] when the features do not determine the pose.
pub fn pose_spread(
    camera: &Camera<f64>,
    view: &TargetImage,
    pose: &Pose,
    radius: f64,
) -> Result<PoseSpread, GeomError> {
    check_problem(
        Free::NONE,
        core::slice::from_ref(view),
        core::slice::from_ref(pose),
        radius,
    )?;
    let bl = blocks(camera, Free::ALL, view, pose, radius)?;
    let ainv = bl.a.cholesky().ok_or(GeomError::IllConditioned)?.inverse();
    Ok(PoseSpread {
        from_intrinsics: -(ainv * bl.b),
        per_noise: ainv,
        cost: bl.cost,
        features: view.layout.len(),
    })
}

/// The checks of [`refine`]'s errors section, before any work.
fn check_problem(
    free: Free,
    views: &[TargetImage],
    poses: &[Pose],
    radius: f64,
) -> Result<(), GeomError> {
    if views.len() != poses.len() {
        return Err(GeomError::LengthMismatch);
    }
    if views.is_empty() {
        return Err(GeomError::TooFewPoints { needed: 1, got: 0 });
    }
    for v in views {
        v.check()?;
    }
    if !(radius >= 0.0 && radius.is_finite()) {
        return Err(GeomError::BadParameter("marker radius must be ≥ 0"));
    }
    let equations: usize = views.iter().map(|v| 2 * v.layout.len()).sum();
    let unknowns = 6 * views.len() + free.0.iter().filter(|&&f| f).count();
    if equations < unknowns {
        return Err(GeomError::TooFewPoints {
            needed: unknowns.div_ceil(2),
            got: equations / 2,
        });
    }
    Ok(())
}

/// One Levenberg–Marquardt iteration at damping `mu`, with the poses eliminated (Schur
/// complement): the intrinsics' step first, then each view's pose step given it.
struct Damped<'a> {
    cam: &'a Camera<f64>,
    free: Free,
    views: &'a [TargetImage<'a>],
    radius: f64,
    mu: f64,
}

impl Damped<'_> {
    /// The reduced system S δc = rhs for the intrinsics, solved; with the camera it leads to.
    /// `None` when the damped system is singular or the step leaves the valid cameras (more
    /// damping is needed).
    fn intrinsics_step(&self, poses: &[Pose]) -> Result<Option<(Vec9, Camera<f64>)>, GeomError> {
        let mut s = Mat9::zeros();
        let mut rhs = Vec9::zeros();
        for (v, p) in self.views.iter().zip(poses) {
            let bl = blocks(self.cam, self.free, v, p, self.radius)?;
            let Ok(ainv) = damped6(&bl.a, self.mu) else {
                return Ok(None);
            };
            let bt_ainv = bl.b.transpose() * ainv;
            s += bl.c - bt_ainv * bl.b;
            rhs += -bl.gc + bt_ainv * bl.gp;
            // Damping of the intrinsics' diagonal uses the undamped C.
            for i in 0..INTRINSICS {
                s[(i, i)] += self.mu * bl.c[(i, i)];
            }
        }
        for (i, f) in self.free.0.iter().enumerate() {
            if !f {
                s.row_mut(i).fill(0.0);
                s.column_mut(i).fill(0.0);
                s[(i, i)] = 1.0;
                rhs[i] = 0.0;
            } else if !(s[(i, i)] > 0.0) {
                s[(i, i)] = 1e-12;
            }
        }
        let dc = if self.free.any() {
            match s.cholesky() {
                Some(ch) => ch.solve(&rhs),
                None => return Ok(None),
            }
        } else {
            Vec9::zeros()
        };
        let mut cp = params(self.cam);
        for (p, d) in cp.iter_mut().zip(dc.iter()) {
            *p += d;
        }
        Ok(camera_from(&cp).ok().map(|c| (dc, c)))
    }

    /// A view's pose after the step, given the intrinsics' step `dc`.
    fn pose_step(&self, v: &TargetImage, p: &Pose, dc: &Vec9) -> Result<Pose, GeomError> {
        let bl = blocks(self.cam, self.free, v, p, self.radius)?;
        let ainv = damped6(&bl.a, self.mu)?;
        Ok(step_pose(p, &(ainv * (-bl.gp - bl.b * dc))))
    }

    /// The cost with `candidate` and every pose stepped; `None` if a step fails or the cost is
    /// not finite.
    fn cost_after(&self, poses: &[Pose], dc: &Vec9, candidate: &Camera<f64>) -> Option<f64> {
        let mut cost = 0.0;
        for (v, p) in self.views.iter().zip(poses) {
            let np = self.pose_step(v, p, dc).ok()?;
            for (s, px) in v.layout.iter().zip(v.pixels) {
                let (r, _, _) = observe(candidate, &np, s, self.radius, px, false).ok()?;
                cost += r.norm_squared();
            }
        }
        cost.is_finite().then_some(cost)
    }
}

/// Reprojection errors (predicted − found, pixels) of one view, written to `out` (at least as
/// long as the view); returns the root-mean-square error.
///
/// # Errors
/// As [`refine`]; [`GeomError::LengthMismatch`] if `out` is too short.
pub fn residuals(
    camera: &Camera<f64>,
    view: &TargetImage,
    pose: &Pose,
    radius: f64,
    out: &mut [Vector2<f64>],
) -> Result<f64, GeomError> {
    view.check()?;
    if out.len() < view.layout.len() {
        return Err(GeomError::LengthMismatch);
    }
    let mut cost = 0.0;
    for ((s, px), o) in view.layout.iter().zip(view.pixels).zip(out.iter_mut()) {
        let (r, _, _) = observe(camera, pose, s, radius, px, false)?;
        *o = r;
        cost += r.norm_squared();
    }
    Ok(libm::sqrt(cost / view.layout.len() as f64))
}

/// A view's pose for a known camera, from the homography of its undistorted markers (to be
/// refined by [`refine`]).
///
/// # Errors
/// TargetImage errors, [`GeomError::Collinear`] for markers on one line, undistortion errors.
pub fn initial_pose(camera: &Camera<f64>, view: &TargetImage) -> Result<Pose, GeomError> {
    view.check()?;
    if view.layout.len() > crate::geometry::pose::MAX_MARKERS {
        return Err(GeomError::BadParameter(
            "more markers in one view than MAX_MARKERS",
        ));
    }
    let mut store = [Vector2::zeros(); crate::geometry::pose::MAX_MARKERS];
    let obs = &mut store[..view.layout.len()];
    for (o, px) in obs.iter_mut().zip(view.pixels) {
        *o = camera.undistort(px)?;
    }
    let h = homography(view.layout, obs)?;
    pose_from_homography(&h)
}

/// Zhang's constraints on `B = K⁻ᵀK⁻¹` from one homography, as rows over
/// `b = (B11, B12, B22, B13, B23, B33)`.
fn zhang_rows(h: &Matrix3<f64>) -> [SVector<f64, 6>; 2] {
    let v = |i: usize, j: usize| {
        let (hi, hj) = (h.column(i), h.column(j));
        SVector::<f64, 6>::from_column_slice(&[
            hi[0] * hj[0],
            hi[0] * hj[1] + hi[1] * hj[0],
            hi[1] * hj[1],
            hi[2] * hj[0] + hi[0] * hj[2],
            hi[2] * hj[1] + hi[1] * hj[2],
            hi[2] * hj[2],
        ])
    };
    [v(0, 1), v(0, 0) - v(1, 1)]
}

/// The smallest eigenvector of a symmetric matrix.
fn null_vector(m: SMatrix<f64, 6, 6>) -> Result<SVector<f64, 6>, GeomError> {
    let eig = SymmetricEigen::try_new(m, f64::EPSILON, 300).ok_or(GeomError::NoConvergence)?;
    let mut best = 0;
    for i in 1..6 {
        if eig.eigenvalues[i] < eig.eigenvalues[best] {
            best = i;
        }
    }
    Ok(eig.eigenvectors.column(best).into_owned())
}

/// Initial intrinsics from the views' homographies by Zhang's closed form with zero skew (three
/// or more views in general position), or — with fewer views, or when that fails — the focal
/// lengths alone with the principal point at the centre of a `width` × `height` image.
/// Distortion starts at zero.
///
/// # Errors
/// TargetImage errors; [`GeomError::IllConditioned`] if no positive focal lengths fit (e.g. every view
/// fronto-parallel).
pub fn initial_camera(
    views: &[TargetImage],
    width: u32,
    height: u32,
) -> Result<Camera<f64>, GeomError> {
    if views.is_empty() {
        return Err(GeomError::TooFewPoints { needed: 1, got: 0 });
    }
    if width == 0 || height == 0 {
        return Err(GeomError::BadParameter("image size must be positive"));
    }
    // Work in pixels scaled to about ±1 around the image centre for conditioning.
    let (cx0, cy0) = (
        (f64::from(width) - 1.0) / 2.0,
        (f64::from(height) - 1.0) / 2.0,
    );
    let sc = 2.0 / f64::from(width.max(height));
    let mut full = SMatrix::<f64, 6, 6>::zeros();
    let mut store = [Vector2::zeros(); crate::geometry::pose::MAX_MARKERS];
    for v in views {
        v.check()?;
        if v.layout.len() > store.len() {
            return Err(GeomError::BadParameter(
                "more markers in one view than MAX_MARKERS",
            ));
        }
        let obs = &mut store[..v.layout.len()];
        for (o, p) in obs.iter_mut().zip(v.pixels) {
            *o = Vector2::new((p.x - cx0) * sc, (p.y - cy0) * sc);
        }
        let mut h = homography(v.layout, obs)?;
        h /= h.norm();
        for row in zhang_rows(&h) {
            full += row * row.transpose();
        }
    }
    // Zero skew: B12 = 0, weighted like the data.
    let w = full.trace().max(1e-30);
    full[(1, 1)] += w;
    let scaled = |fx: f64, fy: f64, cx: f64, cy: f64| {
        Camera::new(
            fx / sc,
            fy / sc,
            cx / sc + cx0,
            cy / sc + cy0,
            Distortion::none(),
        )
    };
    if views.len() >= 3 {
        let b = null_vector(full)?;
        let b = if b[0] < 0.0 { -b } else { b };
        let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
        let den = b11 * b22 - b12 * b12;
        if b11 > 0.0 && den > 0.0 {
            let v0 = (b12 * b13 - b11 * b23) / den;
            let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
            let alpha = libm::sqrt(lambda / b11);
            let beta = libm::sqrt(lambda * b11 / den);
            let u0 = -b13 * alpha * alpha / lambda;
            if let Ok(c) = scaled(alpha, beta, u0, v0) {
                // Accept only a principal point inside the image.
                let pp = c.principal_point();
                if pp.x > 0.0 && pp.y > 0.0 && pp.x < f64::from(width) && pp.y < f64::from(height) {
                    return Ok(c);
                }
            }
        }
    }
    // Principal point at the centre as well: B13 = B23 = 0.
    full[(3, 3)] += w;
    full[(4, 4)] += w;
    let b = null_vector(full)?;
    let b = if b[0] < 0.0 { -b } else { b };
    let (b11, b22, b33) = (b[0], b[2], b[5]);
    // B = diag(1/fx², 1/fy², 1) up to scale.
    if !(b11 > 0.0 && b22 > 0.0 && b33 > 0.0) {
        return Err(GeomError::IllConditioned);
    }
    scaled(libm::sqrt(b33 / b11), libm::sqrt(b33 / b22), 0.0, 0.0)
        .map_err(|_| GeomError::IllConditioned)
}
