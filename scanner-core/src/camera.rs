//! The camera model: pinhole with Brown–Conrady lens distortion.
//!
//! Conventions: the camera centre is the origin, +z looks forward, +x is right, +y is down (image
//! rows grow downward). Pixel `(0, 0)` is the centre of the top-left pixel. A pixel maps to the ray
//! `(x_n, y_n, 1)` where `(x_n, y_n)` are the undistorted normalised coordinates; the paper's image
//! point `A' = (x, y, d_z)` is the same ray scaled by `d_z`.
//!
//! Distortion follows OpenCV's 5-parameter model, applied to normalised coordinates:
//! ```text
//! r² = x² + y²,  radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
//! x_d = x·radial + 2 p1 x y + p2 (r² + 2x²)
//! y_d = y·radial + p1 (r² + 2y²) + 2 p2 x y
//! ```

use nalgebra::{Matrix2, Point2, Point3, Vector2, Vector3};

use scanner_wire::CameraBlock;

use crate::{GeomError, Real};

/// Largest number of Newton steps [`Camera::undistort`] takes.
pub const UNDISTORT_MAX_STEPS: usize = 20;

/// Brown–Conrady distortion coefficients (OpenCV order k1, k2, p1, p2, k3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion<T> {
    /// Radial r² coefficient.
    pub k1: T,
    /// Radial r⁴ coefficient.
    pub k2: T,
    /// Tangential coefficient p1.
    pub p1: T,
    /// Tangential coefficient p2.
    pub p2: T,
    /// Radial r⁶ coefficient.
    pub k3: T,
}

impl<T: Real> Distortion<T> {
    /// No distortion.
    pub fn none() -> Self {
        Self {
            k1: T::zero(),
            k2: T::zero(),
            p1: T::zero(),
            p2: T::zero(),
            k3: T::zero(),
        }
    }

    /// `true` if every coefficient is zero.
    pub fn is_none(&self) -> bool {
        *self == Self::none()
    }

    fn all_finite(&self) -> bool {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
            .iter()
            .all(|x| x.finite())
    }

    /// Distorts undistorted normalised coordinates.
    pub fn apply(&self, p: Vector2<T>) -> Vector2<T> {
        self.apply_with_jacobian(p).0
    }

    /// Distorts `p` and returns the 2×2 Jacobian ∂distorted/∂p.
    pub fn apply_with_jacobian(&self, p: Vector2<T>) -> (Vector2<T>, Matrix2<T>) {
        let (x, y) = (p.x, p.y);
        let two = T::lit(2.0);
        let r2 = x * x + y * y;
        let radial = T::one() + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d(radial)/dx = g·x, d(radial)/dy = g·y
        let g = two * self.k1 + r2 * (T::lit(4.0) * self.k2 + r2 * T::lit(6.0) * self.k3);
        let xd = x * radial + two * self.p1 * x * y + self.p2 * (r2 + two * x * x);
        let yd = y * radial + self.p1 * (r2 + two * y * y) + two * self.p2 * x * y;
        let cross = g * x * y + two * (self.p1 * x + self.p2 * y);
        let j = Matrix2::new(
            radial + g * x * x + two * self.p1 * y + T::lit(6.0) * self.p2 * x,
            cross,
            cross,
            radial + g * y * y + T::lit(6.0) * self.p1 * y + two * self.p2 * x,
        );
        (Vector2::new(xd, yd), j)
    }

    /// Converts every coefficient to another float type.
    pub fn cast<U: Real>(&self) -> Distortion<U> {
        Distortion {
            k1: U::lit(self.k1.to_f64()),
            k2: U::lit(self.k2.to_f64()),
            p1: U::lit(self.p1.to_f64()),
            p2: U::lit(self.p2.to_f64()),
            k3: U::lit(self.k3.to_f64()),
        }
    }
}

/// Pinhole camera with focal lengths and principal point in pixels, and lens distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera<T> {
    fx: T,
    fy: T,
    cx: T,
    cy: T,
    distortion: Distortion<T>,
}

/// The camera as the wire carries it.
impl<T: Real> From<&Camera<T>> for CameraBlock {
    fn from(c: &Camera<T>) -> Self {
        let c: Camera<f32> = c.cast();
        let (d, pp) = (c.distortion(), c.principal_point());
        CameraBlock {
            fx: c.fx(),
            fy: c.fy(),
            cx: pp.x,
            cy: pp.y,
            k1: d.k1,
            k2: d.k2,
            p1: d.p1,
            p2: d.p2,
            k3: d.k3,
        }
    }
}

impl TryFrom<CameraBlock> for Camera<f32> {
    type Error = GeomError;
    /// The camera a header carries, checked as [`Camera::new`] checks it (a head sending
    /// garbage gets a [`GeomError`]).
    fn try_from(b: CameraBlock) -> Result<Self, GeomError> {
        Camera::new(
            b.fx,
            b.fy,
            b.cx,
            b.cy,
            Distortion {
                k1: b.k1,
                k2: b.k2,
                p1: b.p1,
                p2: b.p2,
                k3: b.k3,
            },
        )
    }
}

impl<T: Real> Camera<T> {
    /// A camera from its intrinsics.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`] for a NaN or infinite value, [`GeomError::BadParameter`] for a
    /// focal length that is not positive.
    pub fn new(fx: T, fy: T, cx: T, cy: T, distortion: Distortion<T>) -> Result<Self, GeomError> {
        if ![fx, fy, cx, cy].iter().all(|v| v.finite()) || !distortion.all_finite() {
            return Err(GeomError::NotFinite);
        }
        if fx <= T::zero() || fy <= T::zero() {
            return Err(GeomError::BadParameter("focal length must be positive"));
        }
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            distortion,
        })
    }

    /// Whether the camera is plausible for a `width` × `height` image (see [`crate::config`] for
    /// the limits): each side 1 to [`MAX_LINES`](crate::config::MAX_LINES); focal lengths from
    /// [`MIN_FOCAL_PER_SIDE`](crate::config::MIN_FOCAL_PER_SIDE) to
    /// [`MAX_FOCAL_PER_SIDE`](crate::config::MAX_FOCAL_PER_SIDE) times the longer side and
    /// within a factor 2 of each other; the principal point within half an image of the image;
    /// radial coefficients within ±[`MAX_RADIAL`](crate::config::MAX_RADIAL), tangential within
    /// ±[`MAX_TANGENTIAL`](crate::config::MAX_TANGENTIAL). A camera outside these is a corrupt
    /// file or header, not a lens: every frame would fail later, so it is refused at the start.
    ///
    /// # Errors
    /// [`GeomError::BadParameter`] saying which value is out of range.
    pub fn check_plausible(&self, width: u32, height: u32) -> Result<(), GeomError> {
        use crate::config::{
            MAX_FOCAL_PER_SIDE, MAX_LINES, MAX_RADIAL, MAX_TANGENTIAL, MIN_FOCAL_PER_SIDE,
        };
        let bad = |why| Err(GeomError::BadParameter(why));
        if width == 0 || height == 0 || width as usize > MAX_LINES || height as usize > MAX_LINES {
            return bad("the image size must be 1 to 4096 pixels on each side");
        }
        let side = f64::from(width.max(height));
        let (fx, fy) = (self.fx.to_f64(), self.fy.to_f64());
        if !(fx >= MIN_FOCAL_PER_SIDE * side
            && fx <= MAX_FOCAL_PER_SIDE * side
            && fy >= MIN_FOCAL_PER_SIDE * side
            && fy <= MAX_FOCAL_PER_SIDE * side)
        {
            return bad("the focal length must be 0.1 to 50 times the image's longer side");
        }
        if !(fx <= 2.0 * fy && fy <= 2.0 * fx) {
            return bad("fx and fy must be within a factor 2 of each other");
        }
        let (cx, cy) = (self.cx.to_f64(), self.cy.to_f64());
        let (w, h) = (f64::from(width), f64::from(height));
        if !(cx >= -0.5 * w && cx <= 1.5 * w && cy >= -0.5 * h && cy <= 1.5 * h) {
            return bad("the principal point must lie within half an image of the image");
        }
        let d = self.distortion;
        if ![d.k1, d.k2, d.k3]
            .iter()
            .all(|k| k.to_f64().abs() <= MAX_RADIAL)
        {
            return bad("radial distortion k1, k2, k3 must be within ±100");
        }
        if ![d.p1, d.p2]
            .iter()
            .all(|p| p.to_f64().abs() <= MAX_TANGENTIAL)
        {
            return bad("tangential distortion p1, p2 must be within ±1");
        }
        Ok(())
    }

    /// The paper's camera: one image distance `d_z` in pixels for both axes, the principal point
    /// at the centre of a `width` × `height` image, no distortion.
    ///
    /// # Errors
    /// As [`Camera::new`]; also [`GeomError::BadParameter`] for an empty image.
    pub fn paper(d_z: T, width: u32, height: u32) -> Result<Self, GeomError> {
        if width == 0 || height == 0 {
            return Err(GeomError::BadParameter("image size must be positive"));
        }
        let half = |n: u32| T::lit((f64::from(n) - 1.0) / 2.0);
        Self::new(d_z, d_z, half(width), half(height), Distortion::none())
    }

    /// Focal length along x, pixels.
    pub fn fx(&self) -> T {
        self.fx
    }
    /// Focal length along y, pixels.
    pub fn fy(&self) -> T {
        self.fy
    }
    /// Principal point, pixels.
    pub fn principal_point(&self) -> Point2<T> {
        Point2::new(self.cx, self.cy)
    }
    /// Lens distortion.
    pub fn distortion(&self) -> &Distortion<T> {
        &self.distortion
    }

    /// Converts to another float type (e.g. the `f64` calibration result to the `f32` head).
    pub fn cast<U: Real>(&self) -> Camera<U> {
        let c = |v: T| U::lit(v.to_f64());
        Camera {
            fx: c(self.fx),
            fy: c(self.fy),
            cx: c(self.cx),
            cy: c(self.cy),
            distortion: self.distortion.cast(),
        }
    }

    /// Undistorted normalised coordinates → pixel.
    pub fn normalized_to_pixel(&self, n: Vector2<T>) -> Point2<T> {
        let d = self.distortion.apply(n);
        Point2::new(self.fx * d.x + self.cx, self.fy * d.y + self.cy)
    }

    /// Projects a 3-D point in camera coordinates to a pixel.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`], or [`GeomError::BehindCamera`] when `z` is not positive.
    pub fn project(&self, p: &Point3<T>) -> Result<Point2<T>, GeomError> {
        if !crate::real::all_finite(&p.coords) {
            return Err(GeomError::NotFinite);
        }
        if p.z <= T::zero() {
            return Err(GeomError::BehindCamera);
        }
        let px = self.normalized_to_pixel(Vector2::new(p.x / p.z, p.y / p.z));
        if px.x.finite() && px.y.finite() {
            Ok(px)
        } else {
            Err(GeomError::NotFinite)
        }
    }

    /// Pixel → undistorted normalised coordinates `(x_n, y_n)`.
    ///
    /// Newton's method on the distortion model, at most [`UNDISTORT_MAX_STEPS`] steps, started at
    /// the distorted coordinates. The answer is accepted only where the model is locally
    /// invertible (positive Jacobian determinant), so a pixel outside the region where the
    /// polynomial is monotonic gives an error rather than a folded-back ray.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`] or [`GeomError::NoConvergence`].
    pub fn undistort(&self, pixel: &Point2<T>) -> Result<Vector2<T>, GeomError> {
        if !(pixel.x.finite() && pixel.y.finite()) {
            return Err(GeomError::NotFinite);
        }
        let target = Vector2::new((pixel.x - self.cx) / self.fx, (pixel.y - self.cy) / self.fy);
        if !crate::real::all_finite(&target) {
            return Err(GeomError::NotFinite);
        }
        if self.distortion.is_none() {
            return Ok(target);
        }
        // Newton converges quadratically: iterate until the step is at rounding level, so the
        // answer is as good as the float type allows (a residual test alone stops early).
        let scale = T::one() + target.norm();
        let mut x = target;
        for _ in 0..UNDISTORT_MAX_STEPS {
            let (d, j) = self.distortion.apply_with_jacobian(x);
            let residual = d - target;
            let det = j.determinant();
            if !crate::real::all_finite(&residual) || !(det > T::zero()) {
                return Err(GeomError::NoConvergence);
            }
            // 2×2 inverse written out: det > 0 was checked.
            let step = Vector2::new(
                j.m22 * residual.x - j.m12 * residual.y,
                j.m11 * residual.y - j.m21 * residual.x,
            ) / det;
            x -= step;
            if step.norm() <= T::lit(2.0) * T::EPSILON * scale {
                break;
            }
        }
        // Accept only a true solution in the invertible region, whatever the steps did.
        let (d, j) = self.distortion.apply_with_jacobian(x);
        if (d - target).norm() <= T::lit(64.0) * T::EPSILON * scale
            && j.determinant() > T::zero()
            && crate::real::all_finite(&x)
        {
            Ok(x)
        } else {
            Err(GeomError::NoConvergence)
        }
    }

    /// Pixel → the ray `(x_n, y_n, 1)` through it (not unit length).
    ///
    /// # Errors
    /// As [`Camera::undistort`].
    pub fn pixel_to_ray(&self, pixel: &Point2<T>) -> Result<Vector3<T>, GeomError> {
        let n = self.undistort(pixel)?;
        Ok(Vector3::new(n.x, n.y, T::one()))
    }
}
