//! The laser plane of one frame, from the stripe's 3-D points on the two board planes (paper
//! section 2B, Fig. 4).
//!
//! The stripe crosses the left plane along `MN` and the right plane along `QR`; both lines meet
//! the crease `L_c`, in theory at one point (`S = T`). Two estimators:
//! - [`paper`]: fit `MN` and `QR`, intersect each with `L_c` (`S`, `T`), move both lines through
//!   the midpoint of `S` and `T`, and take the plane of the two corrected lines.
//! - [`least_squares`]: a plane over all board-stripe points, seeded by a small deterministic
//!   MSAC and refined by iterated least squares with 3σ trimming, so glints and object pixels
//!   mistaken for board pixels are rejected rather than averaged in.
//!
//! Both report a [`LaserQuality`] (residuals in mm, and `|S − T|` for the paper's construction)
//! so that the caller can reject a bad frame, and both refuse the degenerate frames of `NOTES.md`:
//! a stripe on one plane only, and a laser plane (nearly) through the camera centre.

use nalgebra::{Point3, Vector3};

use super::board::Board;
use super::fit::{LineFit, fit_line, fit_plane};
use super::plane::{Line, Plane};
use crate::{GeomError, Real};

/// Tuning of the laser-plane estimators. Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserFitConfig<T> {
    /// Fewest stripe points each board plane must contribute (after outlier rejection).
    pub min_points_per_side: usize,
    /// Smallest accepted sine of the angle under which the camera sees the laser plane: the
    /// plane's distance from the camera centre over the distance of the stripe points. Below it
    /// every ray grazes the plane and triangulation is meaningless.
    pub min_view_sin: T,
    /// Outlier threshold floor (mm): points closer to the plane are never rejected.
    pub inlier_tol: T,
    /// Outlier threshold of the seed relative to the points' distance from the camera (the
    /// refinement then adapts it to the residuals).
    pub inlier_tol_rel: T,
    /// Residuals beyond this many RMS (and beyond `inlier_tol`) are outliers.
    pub outlier_sigmas: T,
    /// Largest number of refit rounds.
    pub max_rounds: usize,
}

impl<T: Real> Default for LaserFitConfig<T> {
    fn default() -> Self {
        Self {
            min_points_per_side: 5,
            min_view_sin: T::lit(0.05),
            inlier_tol: T::lit(0.1),
            inlier_tol_rel: T::lit(0.0005),
            outlier_sigmas: T::lit(3.0),
            max_rounds: 10,
        }
    }
}

/// How well the stripe's board points agree with the laser plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserQuality<T: Real> {
    /// RMS distance of the used points from the plane, mm.
    pub rms: T,
    /// Largest distance of a used point from the plane, mm.
    pub max: T,
    /// Points used in the final fit.
    pub used: usize,
    /// Points rejected as outliers.
    pub rejected: usize,
    /// `|S − T|`, mm: the gap between the crease crossings of the two stripe lines (paper's
    /// construction only).
    pub st_gap: Option<T>,
    /// Standard uncertainty of the plane's normal, radians: the residual σ (never below
    /// `inlier_tol`) over the used points' spread in the plane's narrower direction
    /// ([`PlaneFit::spread`](super::PlaneFit::spread)). Large when one side's stripe is short
    /// or its points bunch together, however well they fit.
    pub tilt: T,
    /// The residual σ behind `tilt`, mm: the standard uncertainty of a board point about the
    /// plane (never below `inlier_tol`).
    pub sigma: T,
    /// Centroid of the used points, mm: the plane's tilt turns it about here, so a point's
    /// uncertainty from the plane grows with its distance from it ([`LaserQuality::at`]).
    pub centroid: Point3<T>,
}

impl<T: Real> LaserQuality<T> {
    /// The standard uncertainty the plane gives a point `p` on it, along the plane's normal, mm:
    /// its offset's (`sigma / √used`) and its tilt's (`tilt` times the distance from the
    /// centroid) in quadrature.
    pub fn at(&self, p: &Point3<T>) -> T {
        let offset = self.sigma / T::lit(self.used.max(1) as f64).sqrt();
        let turn = self.tilt * (p - self.centroid).norm();
        (offset * offset + turn * turn).sqrt()
    }
}

/// A laser plane with its quality.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserPlane<T: Real> {
    /// The plane, normal towards the camera.
    pub plane: Plane<T>,
    /// Its quality figures.
    pub quality: LaserQuality<T>,
}

fn check_sides<T: Real>(
    left: &[Point3<T>],
    right: &[Point3<T>],
    cfg: &LaserFitConfig<T>,
) -> Result<(), GeomError> {
    let need = cfg.min_points_per_side.max(2);
    match (left.len() >= need, right.len() >= need) {
        (true, true) => Ok(()),
        (false, false) => Err(GeomError::TooFewPoints {
            needed: need,
            got: left.len().max(right.len()),
        }),
        _ => Err(GeomError::OnePlaneOnly),
    }
}

fn check_view<T: Real>(
    plane: &Plane<T>,
    centroid: &Point3<T>,
    cfg: &LaserFitConfig<T>,
) -> Result<(), GeomError> {
    let dist = centroid.coords.norm();
    if !(plane.offset().abs() > cfg.min_view_sin * dist) {
        return Err(GeomError::PlaneThroughCamera);
    }
    Ok(())
}

/// The uncertainty of a plane over `pts` (see [`LaserQuality::tilt`]), with the points'
/// residual RMS `rms` about it: `(tilt, sigma, centroid)`.
fn tilt<'a, T: Real>(
    pts: impl Iterator<Item = &'a Point3<T>> + Clone,
    rms: T,
    used: usize,
    cfg: &LaserFitConfig<T>,
) -> Result<(T, T, Point3<T>), GeomError> {
    let fit = fit_plane(pts.copied())?;
    // the unbiased σ: three parameters came from the same points
    let dof = T::lit(used as f64 / (used.max(4) - 3) as f64);
    let sigma = (rms * dof.sqrt()).max(cfg.inlier_tol);
    let tilt = if fit.spread > T::zero() {
        sigma / fit.spread
    } else {
        T::lit(f64::INFINITY)
    };
    Ok((tilt, sigma, fit.centroid))
}

/// `1.4826 ×` the median absolute residual about `plane` of the points within `within` of it
/// (the σ of Gaussian residuals), found without a buffer by bisecting on the count of residuals
/// below a level.
fn mad_sigma<T: Real>(plane: &Plane<T>, sides: &[&[Point3<T>]], within: T) -> T {
    let all = || {
        sides
            .iter()
            .flat_map(|s| s.iter())
            .map(|p| plane.signed_distance(p).abs())
            .filter(move |&r| r <= within)
    };
    let n = all().count();
    let (mut lo, mut hi) = (T::zero(), all().fold(T::zero(), |a, r| a.max(r)));
    for _ in 0..40 {
        let mid = (lo + hi) / T::lit(2.0);
        if 2 * all().filter(|&r| r <= mid).count() >= n {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    T::lit(1.4826) * hi
}

/// Residuals of the points in `pts` that pass `keep`.
fn residuals<'a, T: Real>(
    plane: &Plane<T>,
    pts: impl Iterator<Item = &'a Point3<T>>,
) -> (T, T, usize) {
    let (mut s2, mut max, mut n) = (T::zero(), T::zero(), 0usize);
    for p in pts {
        let r = plane.signed_distance(p).abs();
        s2 += r * r;
        max = max.max(r);
        n += 1;
    }
    let rms = if n > 0 {
        (s2 / T::lit(n as f64)).sqrt()
    } else {
        T::zero()
    };
    (rms, max, n)
}

/// The paper's construction (Fig. 4) from the stripe's points on the left and right planes.
///
/// # Errors
/// [`GeomError::OnePlaneOnly`] / [`GeomError::TooFewPoints`], [`GeomError::Collinear`] (a side's
/// points coincide), [`GeomError::Parallel`] (a stripe line parallel to the crease, so `S` or `T`
/// does not exist), [`GeomError::PlaneThroughCamera`], [`GeomError::NotFinite`].
pub fn paper<T: Real>(
    board: &Board<T>,
    left: &[Point3<T>],
    right: &[Point3<T>],
    cfg: &LaserFitConfig<T>,
) -> Result<LaserPlane<T>, GeomError> {
    check_sides(left, right, cfg)?;
    let (mn, mn_tol) = robust_line(left, cfg)?;
    let (qr, qr_tol) = robust_line(right, cfg)?;
    let min_sin = T::lit(0.02);
    let (s, _) = mn.line.closest_points(board.crease(), min_sin)?;
    let (t, _) = qr.line.closest_points(board.crease(), min_sin)?;
    let mid = Point3::from((s.coords + t.coords) / T::lit(2.0));
    // Corrected lines: from the midpoint of S and T through each side's centroid.
    let d1 = mn.line.point() - mid;
    let d2 = qr.line.point() - mid;
    let normal: Vector3<T> = d1.cross(&d2);
    if !(normal.norm() > T::lit(1e-3) * d1.norm() * d2.norm()) {
        return Err(GeomError::Collinear);
    }
    let plane = Plane::from_point_normal(&mid, &normal)?.facing_camera();
    check_view(&plane, &mid, cfg)?;
    // Quality over each side's line inliers (the object's pixels behind which the board lies
    // are not board points).
    let inliers = left
        .iter()
        .filter(within(&mn.line, mn_tol))
        .chain(right.iter().filter(within(&qr.line, qr_tol)));
    let (rms, max, used) = residuals(&plane, inliers.clone());
    let (tilt, sigma, centroid) = tilt(inliers, rms, used, cfg)?;
    Ok(LaserPlane {
        plane,
        quality: LaserQuality {
            rms,
            max,
            used,
            rejected: left.len() + right.len() - used,
            st_gap: Some((s - t).norm()),
            tilt,
            sigma,
            centroid,
        },
    })
}

/// Points within `tol` of `line`.
fn within<T: Real>(line: &Line<T>, tol: T) -> impl Fn(&&Point3<T>) -> bool + Clone + '_ {
    move |p| line.distance(p) <= tol
}

/// A side's stripe line, robust to the object's pixels among the board points (the paper limits
/// MN and QR to hand-drawn board regions; this finds them): a small deterministic MSAC over point
/// pairs, then least squares on the inliers, refitted once with a tolerance of three times their
/// RMS (never below `inlier_tol`). Returns the line and the final inlier tolerance.
fn robust_line<T: Real>(
    pts: &[Point3<T>],
    cfg: &LaserFitConfig<T>,
) -> Result<(LineFit<T>, T), GeomError> {
    let mut next = picker(0x85EB_CA6B ^ (pts.len() as u32).wrapping_mul(0x9E37));
    let mut best: Option<(Line<T>, T, T)> = None;
    for _ in 0..SEED_HYPOTHESES {
        let (a, b) = (pts[next(pts.len())], pts[next(pts.len())]);
        let Ok(line) = Line::new(a, b - a) else {
            continue;
        };
        let mid = Point3::from((a.coords + b.coords) / T::lit(2.0));
        let tol = cfg.inlier_tol.max(cfg.inlier_tol_rel * mid.coords.norm());
        let tol2 = tol * tol;
        let mut score = T::zero();
        for p in pts {
            let d = line.distance(p);
            score += (d * d).min(tol2) / tol2;
        }
        if best.as_ref().is_none_or(|b| score < b.2) {
            best = Some((line, tol, score));
        }
    }
    let (line, tol, _) = best.ok_or(GeomError::Collinear)?;
    let fit = fit_line(pts.iter().filter(within(&line, tol)).copied())?;
    let tol = (T::lit(3.0) * fit.rms)
        .max(cfg.inlier_tol)
        .min(tol * T::lit(3.0));
    let refit = fit_line(pts.iter().filter(within(&fit.line, tol)).copied())?;
    if refit.count < cfg.min_points_per_side {
        return Err(GeomError::TooFewPoints {
            needed: cfg.min_points_per_side,
            got: refit.count,
        });
    }
    Ok((refit, tol))
}

/// A deterministic index picker (xorshift32 from `state`): `next(n)` is in `0..n`.
fn picker(mut state: u32) -> impl FnMut(usize) -> usize {
    move |n| {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as usize % n
    }
}

/// Candidate planes the seed tries at least: enough when most board-stripe points are the
/// board's.
const SEED_HYPOTHESES: u32 = 64;
/// Candidate planes the seed tries at most, when the board's points are few among the rest (a
/// stand or a table in front of the board, a large object): enough for a 0.999 chance of one
/// candidate through board points alone when a tenth of each side's points are the board's.
const SEED_HYPOTHESES_MAX: u32 = 1024;

/// A small deterministic MSAC seed: planes through one point of one side and two near each other
/// (at most a quarter of the side's points, and 48, apart in line order) of the other, chosen by a
/// fixed pseudo-random sequence. A candidate is judged by its weaker side: each side's support is
/// the sum over its points within the seed tolerance of `1 − (r / tol)²`, and the candidate whose
/// lesser support is largest wins. The laser crosses both sheets in a line each, so the true
/// plane is well supported on both; graded support rather than inlier counts, so that a plane
/// that gathers many points loosely loses to one that gathers them closely.
///
/// What this keeps out: the stripe on a surface in front of the board (a stand, a table, the
/// turntable disc, a large object) is a line whose points, carried along their rays onto both
/// sheets, all lie in the plane of that line and the camera centre. Where they outnumber the
/// board's own points, that plane (through the camera: never taken, see below) or one through
/// one side's share of them and a few points of the other side near the crease would win on the
/// total; on its weaker side it gathers only those few.
/// - A plane (nearly) through the camera is never taken ([`check_view`]).
/// - When no candidate off the camera has `min_points_per_side` inliers on both sides, the
///   refinement would only polish a plane that is not the laser's: the laser plane is through
///   the camera ([`GeomError::PlaneThroughCamera`]) when a candidate through it fitted both
///   sides, and otherwise the stripe is on one sheet only as far as a plane can tell
///   ([`GeomError::OnePlaneOnly`], as the final fit would find).
/// - The number of candidates grows from [`SEED_HYPOTHESES`] towards [`SEED_HYPOTHESES_MAX`] as
///   the best plane's share of each side's points says it must (the usual RANSAC count for a
///   0.999 chance of one all-inlier draw).
fn seed<T: Real>(
    sides: &[&[Point3<T>]],
    cfg: &LaserFitConfig<T>,
) -> Result<(Plane<T>, T), GeomError> {
    let (left, right) = (sides[0], sides.get(1).copied().unwrap_or(&[]));
    let mut next = picker(0x9E37_79B9 ^ (left.len() as u32).wrapping_mul(31) ^ right.len() as u32);
    let need = cfg.min_points_per_side.max(2);
    // The ordered pairs of sides a candidate draws its single point and its pair from, every
    // side with a point in turn.
    let mut pairs: heapless::Vec<(usize, usize), { (MAX_SIDES - 1) * MAX_SIDES }> =
        heapless::Vec::new();
    for (x, y) in SIDE_PAIRS {
        if x < sides.len() && y < sides.len() && !sides[x].is_empty() && !sides[y].is_empty() {
            let _ = pairs.push((x, y));
        }
    }
    if pairs.is_empty() {
        return Err(GeomError::OnePlaneOnly);
    }
    // (plane, tolerance, the second-best side's support, two sides have enough inliers)
    let mut best: Option<(Plane<T>, T, T, bool)> = None;
    // a plane through the camera fitted two sides
    let mut through_fits = false;
    let mut trials = SEED_HYPOTHESES;
    let mut h = 0;
    while h < trials {
        let (x, y) = pairs[h as usize % pairs.len()];
        let (one, two) = (sides[x], sides[y]);
        h += 1;
        let a = one[next(one.len())];
        // Two points a few lines apart on the other side: points in line order, so both lie on
        // the same surface far more often than two drawn anywhere (the board's stripe is one run
        // of lines at a side's edge, however short).
        let i = next(two.len());
        let reach = (two.len() / 4).clamp(4, 48);
        let j = i.saturating_sub(reach) + next(2 * reach + 1);
        let (b, c) = (two[i], two[j.min(two.len() - 1)]);
        let Ok(plane) = Plane::from_point_normal(&a, &(b - a).cross(&(c - a))) else {
            continue;
        };
        let centroid = Point3::from((a.coords + b.coords + c.coords) / T::lit(3.0));
        let tol = cfg
            .inlier_tol
            .max(cfg.inlier_tol_rel * centroid.coords.norm());
        let tol2 = tol * tol;
        // per side: inliers, and support (each point's 1 − r²/tol², 0 beyond tol)
        let mut inliers = [0usize; MAX_SIDES];
        let mut support = [T::zero(); MAX_SIDES];
        for (side, pts) in sides.iter().enumerate() {
            for p in pts.iter() {
                let r = plane.signed_distance(p);
                let r2 = r * r;
                if r2 <= tol2 {
                    inliers[side] += 1;
                    support[side] += T::one() - r2 / tol2;
                }
            }
        }
        let (first, second) = two_best(&support[..sides.len()]);
        let both = inliers[first] >= need && inliers[second] >= need;
        if check_view(&plane, &centroid, cfg).is_err() {
            through_fits |= both;
            continue;
        }
        let weaker = support[second];
        if best.as_ref().is_none_or(|b| (both, weaker) > (b.3, b.2)) {
            best = Some((plane, tol, weaker, both));
            if both {
                let share = |k: usize| inliers[k] as f64 / sides[k].len() as f64;
                trials = trials.max(trials_for(share(first), share(second)));
            }
        }
    }
    match best {
        Some((p, tol, _, true)) => Ok((p, tol)),
        _ if through_fits => Err(GeomError::PlaneThroughCamera),
        Some(_) => Err(GeomError::OnePlaneOnly),
        None => Err(GeomError::Collinear),
    }
}

/// The most known surfaces a laser plane is fitted on: the board's two sheets and the turntable
/// disc.
pub const MAX_SIDES: usize = 3;

/// The ordered pairs of sides a seed candidate draws from, in turn: for two sides, one point of
/// the left and two of the right, then the other way round.
const SIDE_PAIRS: [(usize, usize); 6] = [(0, 1), (1, 0), (0, 2), (2, 0), (1, 2), (2, 1)];

/// The indices of the largest and the second largest of `v` (two or more values).
fn two_best<T: Real>(v: &[T]) -> (usize, usize) {
    let (mut first, mut second) = (0, 1);
    if v[1] > v[0] {
        (first, second) = (1, 0);
    }
    for k in 2..v.len() {
        if v[k] > v[first] {
            (first, second) = (k, first);
        } else if v[k] > v[second] {
            second = k;
        }
    }
    (first, second)
}

/// Candidates for a 0.999 chance that one draw (one point of one side, a pair of the other, the
/// sides alternating) is all inliers, when shares `wl` and `wr` of the sides' points are (a pair
/// counted as one draw: its points are near each other); within
/// [`SEED_HYPOTHESES`]..=[`SEED_HYPOTHESES_MAX`].
fn trials_for(wl: f64, wr: f64) -> u32 {
    let all = wl * wr;
    if !(all > 0.0) {
        return SEED_HYPOTHESES_MAX;
    }
    if all >= 1.0 {
        return SEED_HYPOTHESES;
    }
    let n = libm::ceil(libm::log(0.001) / libm::log(1.0 - all));
    if n >= f64::from(SEED_HYPOTHESES_MAX) {
        SEED_HYPOTHESES_MAX
    } else {
        (n as u32).max(SEED_HYPOTHESES)
    }
}

/// Least-squares laser plane over all board-stripe points, with outlier rejection.
///
/// # Errors
/// [`GeomError::OnePlaneOnly`] / [`GeomError::TooFewPoints`] (also when outliers leave a side
/// with too few points), [`GeomError::Collinear`], [`GeomError::PlaneThroughCamera`],
/// [`GeomError::NotFinite`], [`GeomError::NoConvergence`].
pub fn least_squares<T: Real>(
    left: &[Point3<T>],
    right: &[Point3<T>],
    cfg: &LaserFitConfig<T>,
) -> Result<LaserPlane<T>, GeomError> {
    check_sides(left, right, cfg)?;
    least_squares_on(&[left, right], cfg)
}

/// [`least_squares`] over the stripe's points on two or three known surfaces (the board's sheets,
/// and the turntable disc where its plane is known): the laser crosses each in a line, and two
/// lines fix the plane, so at least two surfaces must each give `min_points_per_side` inliers.
///
/// # Errors
/// As [`least_squares`]; [`GeomError::TooFewPoints`] for fewer than two or more than
/// [`MAX_SIDES`] surfaces.
pub fn least_squares_on<T: Real>(
    sides: &[&[Point3<T>]],
    cfg: &LaserFitConfig<T>,
) -> Result<LaserPlane<T>, GeomError> {
    let need = cfg.min_points_per_side.max(2);
    if !(2..=MAX_SIDES).contains(&sides.len()) {
        return Err(GeomError::TooFewPoints {
            needed: 2,
            got: sides.len(),
        });
    }
    let enough = sides.iter().filter(|s| s.len() >= need).count();
    if enough < 2 {
        let most = sides.iter().map(|s| s.len()).max().unwrap_or(0);
        return Err(if enough == 1 {
            GeomError::OnePlaneOnly
        } else {
            GeomError::TooFewPoints {
                needed: need,
                got: most,
            }
        });
    }
    let all = || sides.iter().flat_map(|s| s.iter());
    if !all().all(|p| crate::real::all_finite(&p.coords)) {
        return Err(GeomError::NotFinite);
    }
    let (mut plane, mut tol) = seed(sides, cfg)?;
    let mut used = usize::MAX;
    let mut fit = None;
    for _ in 0..cfg.max_rounds.max(1) {
        let current = plane;
        let inliers = all()
            .copied()
            .filter(move |p| current.signed_distance(p).abs() <= tol);
        let f = fit_plane(inliers)?;
        plane = f.plane;
        let stable = f.count == used;
        used = f.count;
        tol = cfg.inlier_tol.max(cfg.outlier_sigmas * f.rms);
        fit = Some(f);
        if stable {
            break;
        }
    }
    let fit = fit.ok_or(GeomError::NoConvergence)?;
    // The final inlier set is judged with the final plane and threshold.
    let keep = |p: &&Point3<T>| plane.signed_distance(p).abs() <= tol;
    let crossed = sides
        .iter()
        .filter(|s| s.iter().filter(keep).count() >= need)
        .count();
    if crossed < 2 {
        return Err(GeomError::OnePlaneOnly);
    }
    check_view(&plane, &fit.centroid, cfg)?;
    let used_points = all().filter(keep);
    let (rms, max, used) = residuals(&plane, used_points.clone());
    // The noise for the uncertainty: the trimming can settle on a tight subset whose RMS is
    // well below the points' real scatter (measured: 0.10 mm from 0.3 mm noise), so a robust σ
    // of the points within three times the final tolerance counts too (the object's pixels
    // among the board points, often more than half of them late in a sweep, lie further off).
    let robust = mad_sigma(&plane, sides, T::lit(3.0) * tol);
    let (tilt, sigma, centroid) = tilt(used_points, rms.max(robust), used, cfg)?;
    Ok(LaserPlane {
        plane,
        quality: LaserQuality {
            rms,
            max,
            used,
            rejected: all().count() - used,
            st_gap: None,
            tilt,
            sigma,
            centroid,
        },
    })
}
