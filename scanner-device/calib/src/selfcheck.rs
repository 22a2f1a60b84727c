//! A calibration that checks itself (after mrcal): how far the projection can be trusted, where
//! in the image, and whether the lens model fits at all.
//!
//! - **Uncertainty map.** The fit's covariance ([`covariance`]: the normal equations at the
//!   solution and the corners' scatter) carried to the projection of a fixed direction at every
//!   point of the image: the worst-direction standard deviation in pixels. A rotation of the whole
//!   camera is taken out first (fitted over the features used), since the board planes are
//!   measured through the same intrinsics and absorb it: what is left moves a point.
//! - **Cross-validation.** The used images split into two disjoint halves (alternate images),
//!   each calibrated on its own; the two projections are compared — rotation taken out as above
//!   — where the features were and over the whole image. With a model that fits and independent
//!   corner noise, the difference is what the halves' covariances predict; much more than that
//!   (more than [`WARN_RATIO`]) says the model or the data is wrong (a lens the model cannot
//!   bend to, a board that is not flat, shots that moved, corners pulled by clutter), however
//!   small the reprojection error.

use scanner_core::Camera;
use scanner_core::calib::TargetImage;
use scanner_core::calib::bundle::{
    Covariance, INTRINSICS, camera_from, covariance, params, refine,
};
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Matrix2, Matrix3, Point2, Point3, Rotation3, SMatrix, Vector3};

use super::intrinsics::IntrinsicsFit;
use super::{CalibError, Target};

/// Columns and rows of the uncertainty map's cells.
pub const MAP_CELLS: (usize, usize) = (32, 24);
/// Fewest used images per half for the cross-validation (each half is a calibration of its own).
pub const MIN_HALF_IMAGES: usize = 3;
/// The halves' difference over what their covariances predict beyond which the check warns.
pub const WARN_RATIO: f64 = 2.0;
/// Most feature points the rotation is fitted over (evenly thinned beyond).
const MAX_ALIGN_POINTS: usize = 2000;
/// A region of the image where more shots would help: its uncertainty above this many times
/// the median over the cells the features covered, and above [`ADVICE_MIN_PX`].
const ADVICE_OF_MEDIAN: f64 = 3.0;
/// Uncertainty below which no region needs more shots, pixels.
const ADVICE_MIN_PX: f64 = 0.05;

type Jac = SMatrix<f64, 2, INTRINSICS>;
type Rot = SMatrix<f64, 2, 3>;

/// What [`self_check`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct SelfCheck {
    /// The fit's covariance and the corners' noise.
    pub covariance: Covariance,
    /// The projection's uncertainty over the image.
    pub map: UncertaintyMap,
    /// The cross-validation, or why it could not run.
    pub halves: Result<Halves, CalibError>,
}

/// The two halves' calibrations compared.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Halves {
    /// Images in each half.
    pub images: (usize, usize),
    /// RMS projection difference at the features used, pixels.
    pub features_rms_px: f64,
    /// RMS and largest projection difference over the whole image (the map's cell centres),
    /// pixels.
    pub image_rms_px: f64,
    /// Largest over the whole image, pixels.
    pub image_max_px: f64,
    /// RMS difference at the features that the halves' covariances predict, pixels.
    pub expected_features_rms_px: f64,
    /// The same over the whole image, pixels.
    pub expected_image_rms_px: f64,
}

impl Halves {
    /// The difference at the features over the expected one.
    pub fn ratio(&self) -> f64 {
        self.features_rms_px / self.expected_features_rms_px.max(1e-12)
    }

    /// More difference than the corner noise explains ([`WARN_RATIO`]).
    pub fn too_far(&self) -> bool {
        self.ratio() > WARN_RATIO
    }

    /// What the fit's covariance is scaled by to explain the halves' difference: the ratio
    /// squared when it is [`too_far`](Self::too_far), else 1 (a smaller ratio is what chance
    /// gives a model that fits: 0.44–1.40 on synthetic corners).
    pub fn covariance_scale(&self) -> f64 {
        if self.too_far() {
            self.ratio().powi(2)
        } else {
            1.0
        }
    }
}

/// The projection's standard deviation in its worst direction, pixels, at the centre of each of
/// [`MAP_CELLS`] (row by row; NaN where no ray leaves the pixel).
#[derive(Debug, Clone, PartialEq)]
pub struct UncertaintyMap {
    /// Image size.
    pub size: (u32, u32),
    /// Per cell, row by row, pixels.
    pub sigma_px: Vec<f64>,
    /// Per cell: some feature used lies in it.
    pub covered: Vec<bool>,
}

/// One of nine parts of the image (thirds across and down) and its uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    /// "top left" … "bottom right".
    pub name: &'static str,
    /// Largest uncertainty over its cells, pixels.
    pub sigma_px: f64,
}

impl UncertaintyMap {
    /// The uncertainty at pixel `(x, y)`: the nearest cell's.
    pub fn at(&self, x: f64, y: f64) -> f64 {
        let (cols, rows) = MAP_CELLS;
        let c = (x / f64::from(self.size.0.max(1)) * cols as f64).clamp(0.0, cols as f64 - 1.0);
        let r = (y / f64::from(self.size.1.max(1)) * rows as f64).clamp(0.0, rows as f64 - 1.0);
        self.sigma_px[r as usize * cols + c as usize]
    }

    /// Median over the cells the features covered, pixels.
    pub fn covered_median(&self) -> f64 {
        median(
            self.sigma_px
                .iter()
                .zip(&self.covered)
                .filter(|(s, c)| **c && s.is_finite())
                .map(|(s, _)| *s),
        )
    }

    /// Largest over the image, pixels.
    pub fn max(&self) -> f64 {
        self.sigma_px
            .iter()
            .copied()
            .filter(|s| s.is_finite())
            .fold(0.0, f64::max)
    }

    /// The nine regions, each with its largest uncertainty.
    pub fn regions(&self) -> Vec<Region> {
        const NAMES: [&str; 9] = [
            "top left",
            "top",
            "top right",
            "left",
            "middle",
            "right",
            "bottom left",
            "bottom",
            "bottom right",
        ];
        let (cols, rows) = MAP_CELLS;
        let mut worst = [0.0f64; 9];
        for (k, s) in self.sigma_px.iter().enumerate() {
            let part = (k / cols) * 3 / rows * 3 + (k % cols) * 3 / cols;
            // a cell no ray leaves counts as unknown: as bad as can be
            worst[part] = worst[part].max(if s.is_finite() { *s } else { f64::INFINITY });
        }
        (0..9)
            .map(|i| Region {
                name: NAMES[i],
                sigma_px: worst[i],
            })
            .collect()
    }

    /// Where more shots (with the target there) would help most, worst first: the regions
    /// whose uncertainty is well above that where the features were.
    pub fn more_shots(&self) -> Vec<Region> {
        let limit = (ADVICE_OF_MEDIAN * self.covered_median()).max(ADVICE_MIN_PX);
        let mut out: Vec<Region> = self
            .regions()
            .into_iter()
            .filter(|r| r.sigma_px > limit)
            .collect();
        out.sort_by(|a, b| b.sigma_px.total_cmp(&a.sigma_px));
        out
    }
}

/// The upper median (NaN for none).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The used images' correspondences and poses.
struct Used {
    layout: Vec<Vec<Point2<f64>>>,
    pixels: Vec<Vec<Point2<f64>>>,
    poses: Vec<Pose>,
}

impl Used {
    fn of(fit: &IntrinsicsFit, target: &Target) -> Used {
        let points = target.points();
        let mut u = Used {
            layout: Vec::new(),
            pixels: Vec::new(),
            poses: Vec::new(),
        };
        for v in fit.views.iter().flatten() {
            u.layout
                .push(v.found.iter().map(|(k, _)| points[*k]).collect());
            u.pixels.push(v.found.iter().map(|(_, p)| *p).collect());
            u.poses.push(v.pose);
        }
        u
    }

    fn views(&self, pick: impl Fn(usize) -> bool) -> (Vec<TargetImage<'_>>, Vec<Pose>) {
        let mut views = Vec::new();
        let mut poses = Vec::new();
        for (i, (l, p)) in self.layout.iter().zip(&self.pixels).enumerate() {
            if pick(i) {
                views.push(TargetImage {
                    layout: l,
                    pixels: p,
                });
                poses.push(self.poses[i]);
            }
        }
        (views, poses)
    }

    /// Every feature pixel, thinned evenly to at most `n`.
    fn features(&self, n: usize) -> Vec<Point2<f64>> {
        let all: Vec<Point2<f64>> = self.pixels.iter().flatten().copied().collect();
        let step = all.len().div_ceil(n.max(1)).max(1);
        all.into_iter().step_by(step).collect()
    }
}

fn geom(what: &'static str) -> impl Fn(scanner_core::GeomError) -> CalibError {
    move |reason| CalibError::Geometry {
        what: what.into(),
        reason,
    }
}

/// The map's cell centres, row by row.
fn cell_centres(size: (u32, u32)) -> Vec<Point2<f64>> {
    let (cols, rows) = MAP_CELLS;
    let (w, h) = (f64::from(size.0), f64::from(size.1));
    (0..rows)
        .flat_map(|r| {
            (0..cols).map(move |c| {
                Point2::new(
                    (c as f64 + 0.5) * w / cols as f64,
                    (r as f64 + 0.5) * h / rows as f64,
                )
            })
        })
        .collect()
}

/// Checks a calibration: its covariance, the uncertainty map and the two halves compared.
///
/// # Errors
/// [`CalibError::Geometry`] when the fit's covariance cannot be had (a parameter the images do
/// not determine). The halves' own failure is reported in [`SelfCheck::halves`].
pub fn self_check(fit: &IntrinsicsFit, target: &Target) -> Result<SelfCheck, CalibError> {
    let used = Used::of(fit, target);
    let radius = target.radius();
    let (views, poses) = used.views(|_| true);
    let cov = covariance(&fit.camera, fit.free, &views, &poses, radius)
        .map_err(geom("self-check: the fit's covariance"))?;
    let features = used.features(MAX_ALIGN_POINTS);
    let lin = Linear::new(&fit.camera, &features);
    let centres = cell_centres(fit.size);
    let cover = super::intrinsics::Coverage::of_views(fit.size, fit.views.iter().flatten());
    let map = UncertaintyMap {
        size: fit.size,
        sigma_px: centres
            .iter()
            .map(|q| lin.covariance_at(&fit.camera, q, &cov.matrix))
            .map(|c| c.map_or(f64::NAN, worst_sigma))
            .collect(),
        covered: centres
            .iter()
            .map(|q| {
                let (cc, cr) = super::intrinsics::COVER_CELLS;
                let c = (q.x / f64::from(fit.size.0) * cc as f64) as usize;
                let r = (q.y / f64::from(fit.size.1) * cr as f64) as usize;
                cover.covered[r.min(cr - 1) * cc + c.min(cc - 1)]
            })
            .collect(),
    };
    let halves = cross_validate(fit, &used, radius, &lin, &features, &centres);
    Ok(SelfCheck {
        covariance: cov,
        map,
        halves,
    })
}

/// Calibrates the alternate images apart and compares the two.
fn cross_validate(
    fit: &IntrinsicsFit,
    used: &Used,
    radius: f64,
    lin: &Linear,
    features: &[Point2<f64>],
    centres: &[Point2<f64>],
) -> Result<Halves, CalibError> {
    let n = used.poses.len();
    if n < 2 * MIN_HALF_IMAGES {
        return Err(CalibError::TooFewImages {
            usable: n,
            given: n,
            needed: 2 * MIN_HALF_IMAGES,
        });
    }
    let half = |parity: usize| -> Result<(Camera<f64>, Covariance), CalibError> {
        let (views, mut poses) = used.views(|i| i % 2 == parity);
        let r = refine(&fit.camera, fit.free, &views, &mut poses, radius)
            .map_err(geom("self-check: a half's calibration"))?;
        let c = covariance(&r.camera, fit.free, &views, &poses, radius)
            .map_err(geom("self-check: a half's covariance"))?;
        Ok((r.camera, c))
    };
    let (a, ca) = half(0)?;
    let (b, cb) = half(1)?;
    let sum: [[f64; INTRINSICS]; INTRINSICS] =
        core::array::from_fn(|i| core::array::from_fn(|j| ca.matrix[i][j] + cb.matrix[i][j]));
    let rotation = align(&a, &b, features).map_err(geom("self-check: aligning the halves"))?;
    let diff = |q: &Point2<f64>| -> Option<f64> {
        let r = a.pixel_to_ray(q).ok()?;
        let p = b.project(&Point3::from(rotation * r)).ok()?;
        Some((p - q).norm())
    };
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let at_features: Vec<f64> = features.iter().filter_map(diff).collect();
    let over_image: Vec<f64> = centres.iter().filter_map(diff).collect();
    let expected = |pts: &[Point2<f64>]| -> f64 {
        let traces: Vec<f64> = pts
            .iter()
            .filter_map(|q| lin.covariance_at(&fit.camera, q, &sum))
            .map(|c| c.trace())
            .collect();
        (traces.iter().sum::<f64>() / traces.len().max(1) as f64).sqrt()
    };
    Ok(Halves {
        images: (n.div_ceil(2), n / 2),
        features_rms_px: rms(&at_features),
        image_rms_px: rms(&over_image),
        image_max_px: over_image.iter().copied().fold(0.0, f64::max),
        expected_features_rms_px: expected(features),
        expected_image_rms_px: expected(centres),
    })
}

/// The rotation `R` that brings `b`'s projection of `R · ray_a(q)` closest to `q` over `pts`
/// (Gauss–Newton from none).
fn align(
    a: &Camera<f64>,
    b: &Camera<f64>,
    pts: &[Point2<f64>],
) -> Result<Rotation3<f64>, scanner_core::GeomError> {
    let rays: Vec<(Vector3<f64>, Point2<f64>)> = pts
        .iter()
        .filter_map(|q| Some((a.pixel_to_ray(q).ok()?, *q)))
        .collect();
    let mut rot = Rotation3::identity();
    for _ in 0..10 {
        let mut h = Matrix3::zeros();
        let mut g = Vector3::zeros();
        for (r, q) in &rays {
            let r = rot * r;
            let Some(k) = rotation_jacobian(b, &r) else {
                continue;
            };
            let e = b.project(&Point3::from(r))? - q;
            h += k.transpose() * k;
            g += k.transpose() * e;
        }
        let Some(step) = h.cholesky().map(|c| c.solve(&(-g))) else {
            break;
        };
        rot = Rotation3::new(step) * rot;
        if step.norm() < 1e-12 {
            break;
        }
    }
    Ok(rot)
}

/// How the projection of a ray moves with a small rotation of it (2×3), by central
/// differences.
fn rotation_jacobian(cam: &Camera<f64>, r: &Vector3<f64>) -> Option<Rot> {
    const H: f64 = 1e-6;
    let mut k = Rot::zeros();
    for i in 0..3 {
        let mut w = Vector3::zeros();
        w[i] = H;
        let p = cam.project(&Point3::from(Rotation3::new(w) * r)).ok()?;
        let m = cam.project(&Point3::from(Rotation3::new(-w) * r)).ok()?;
        k.set_column(i, &((p - m) / (2.0 * H)));
    }
    Some(k)
}

/// How the projection of a fixed ray moves with the intrinsics (2×9), by central differences.
fn intrinsics_jacobian(cam: &Camera<f64>, r: &Vector3<f64>) -> Option<Jac> {
    const H: [f64; INTRINSICS] = [1e-3, 1e-3, 1e-3, 1e-3, 1e-6, 1e-6, 1e-7, 1e-7, 1e-6];
    let p0 = params(cam);
    let mut j = Jac::zeros();
    for i in 0..INTRINSICS {
        let mut plus = p0;
        let mut minus = p0;
        plus[i] += H[i];
        minus[i] -= H[i];
        let pp = camera_from(&plus).ok()?.project(&Point3::from(*r)).ok()?;
        let pm = camera_from(&minus).ok()?.project(&Point3::from(*r)).ok()?;
        j.set_column(i, &((pp - pm) / (2.0 * H[i])));
    }
    Some(j)
}

/// The projection's linear response to the intrinsics with the best-fitting rotation taken out:
/// a change `δp` moves the projection at `q` by `(J_q − K_q M) δp`, `M` the rotation that
/// best undoes `J δp` over the features (`(Σ KᵀK)⁻¹ Σ KᵀJ`).
struct Linear {
    m: SMatrix<f64, 3, INTRINSICS>,
}

impl Linear {
    fn new(cam: &Camera<f64>, features: &[Point2<f64>]) -> Linear {
        let mut ktk = Matrix3::zeros();
        let mut ktj = SMatrix::<f64, 3, INTRINSICS>::zeros();
        for q in features {
            let Some((j, k)) = jacobians(cam, q) else {
                continue;
            };
            ktk += k.transpose() * k;
            ktj += k.transpose() * j;
        }
        let m = ktk
            .cholesky()
            .map_or_else(SMatrix::zeros, |c| c.solve(&ktj));
        Linear { m }
    }

    /// The 2×2 covariance of the projection at `q` for intrinsics of covariance `cov`.
    fn covariance_at(
        &self,
        cam: &Camera<f64>,
        q: &Point2<f64>,
        cov: &[[f64; INTRINSICS]; INTRINSICS],
    ) -> Option<Matrix2<f64>> {
        let (j, k) = jacobians(cam, q)?;
        let g = j - k * self.m;
        let s = SMatrix::<f64, INTRINSICS, INTRINSICS>::from_fn(|i, j| cov[i][j]);
        Some(g * s * g.transpose())
    }
}

fn jacobians(cam: &Camera<f64>, q: &Point2<f64>) -> Option<(Jac, Rot)> {
    let r = cam.pixel_to_ray(q).ok()?;
    Some((intrinsics_jacobian(cam, &r)?, rotation_jacobian(cam, &r)?))
}

/// The standard deviation along the covariance's worst direction.
fn worst_sigma(c: Matrix2<f64>) -> f64 {
    let (a, b, d) = (c[(0, 0)], 0.5 * (c[(0, 1)] + c[(1, 0)]), c[(1, 1)]);
    let mean = 0.5 * (a + d);
    let l = mean + (0.25 * (a - d) * (a - d) + b * b).sqrt();
    l.max(0.0).sqrt()
}
