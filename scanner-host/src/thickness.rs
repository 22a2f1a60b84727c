//! The light sheet's thickness on a curved surface: where the lit band's centre lies.
//!
//! A line laser's sheet has a thickness: across it the light falls off as a Gaussian of width σ
//! (mm). Where the sheet cuts a flat surface the lit band is symmetric and its centre is where the
//! sheet's middle plane meets the surface. Where the surface curves, the distance from the middle
//! plane grows faster on one side of the band than on the other, the band is skewed, and its
//! brightest middle and its centroid move off the true crossing — to first order by `−3 b σ²/a³`
//! pixels, `a` and `b` the first and second derivative of that distance along the image column
//! (over 2 for `b`). The light's angle of incidence also changes across a curved band, and its
//! cosine over the distance² weighs one side more. The offset is largest where the sheet grazes
//! the surface (small `a`). On the
//! rig's bunny (σ 0.6 mm) it moves points by up to 0.1 mm, and as each view sees the object from
//! its own side, it turns views against each other by up to 0.07° (docs/reports.md).
//!
//! [`centre_offset`] computes the offset for one point from a local fit of the surface
//! ([`Quadric`], from the scan's own points around it), the frame's laser plane and the camera,
//! by sampling the band along the image column; [`shifted`] moves the point to where the true
//! crossing is. The head finds centres along image columns (the stripe runs across the image),
//! so the band is sampled along the column through the point.

use kiddo::{KdTree, SquaredEuclidean};
use scanner_core::nalgebra::{Matrix3, Matrix6, Point3, Vector3, Vector6};

/// The thickest laser sheet the correction takes, mm (σ; a line 12 mm wide at half its
/// brightness, far thicker than any line laser meant for scanning).
pub const MAX_SIGMA_MM: f64 = 5.0;

/// A laser sheet's thickness out of range.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("--sheet must be 0 (off) to {MAX_SIGMA_MM} mm, found {0}")]
pub struct ThicknessError(pub f64);

/// Refuses a thickness that is no sheet's: 0 (no correction) to [`MAX_SIGMA_MM`].
///
/// # Errors
/// [`ThicknessError`] naming the value.
pub fn check_thickness(mm: f64) -> Result<(), ThicknessError> {
    if (0.0..=MAX_SIGMA_MM).contains(&mm) {
        Ok(())
    } else {
        Err(ThicknessError(mm))
    }
}

/// Least neighbours a local fit needs (six unknowns).
pub const MIN_NEIGHBOURS: usize = 10;

/// The band is sampled out to this many of its half-widths on either side.
const REACH: f64 = 4.0;

/// Samples across the band.
const SAMPLES: usize = 161;

/// The surface around a point is fitted to the scan's points within this distance, mm, or to its
/// [`FIT_POINTS`] nearest where fewer lie that near (coarse grids: 2-pixel cells are 0.8 mm apart
/// on the bunny at 1280×960, 1.6 mm at 640×480), out to [`FIT_MAX_MM`].
pub const FIT_MM: f64 = 3.0;

/// Points of a fit where fewer than these lie within [`FIT_MM`].
pub const FIT_POINTS: usize = 24;

/// The farthest point of a fit, mm.
pub const FIT_MAX_MM: f64 = 6.0;

/// A sample is corrected by the fit of the nearest surface point within this distance, mm.
pub const NEAR_MM: f64 = 1.5;

/// Larger offsets are left alone, rows: where the sheet grazes the surface or the fit is poor
/// the first-order picture no longer holds.
pub const MAX_ROWS: f64 = 3.0;

/// A surface near a point as a height over its tangent plane: `h(x, y) = c0 + c1 x + c2 y + c3 x²
/// + c4 x y + c5 y²`, `x` and `y` along `e1` and `e2`, the height along `n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quadric {
    origin: Point3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
    n: Vector3<f64>,
    c: Vector6<f64>,
}

impl Quadric {
    /// Least-squares fit to `neighbours` around `origin` with the normal `normal`; `None` with
    /// fewer than [`MIN_NEIGHBOURS`] points or when they do not fix the six coefficients.
    pub fn fit(
        origin: Point3<f64>,
        normal: Vector3<f64>,
        neighbours: impl IntoIterator<Item = Point3<f64>>,
    ) -> Option<Quadric> {
        let n = normal.try_normalize(1e-12)?;
        let helper = if n.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = n.cross(&helper).normalize();
        let e2 = n.cross(&e1);
        let (mut ata, mut atb, mut count) = (Matrix6::zeros(), Vector6::zeros(), 0usize);
        for q in neighbours {
            let d = q - origin;
            let (x, y) = (d.dot(&e1), d.dot(&e2));
            let row = Vector6::new(1.0, x, y, x * x, x * y, y * y);
            ata += row * row.transpose();
            atb += row * d.dot(&n);
            count += 1;
        }
        if count < MIN_NEIGHBOURS {
            return None;
        }
        let c = ata.cholesky()?.solve(&atb);
        c.iter().all(|v| v.is_finite()).then_some(Quadric {
            origin,
            e1,
            e2,
            n,
            c,
        })
    }

    /// The surface's unit normal at `p` (on it), on the side of `n`.
    fn normal_at(&self, p: &Point3<f64>) -> Vector3<f64> {
        let d = p - self.origin;
        let (x, y) = (d.dot(&self.e1), d.dot(&self.e2));
        let c = &self.c;
        let (hx, hy) = (
            c[1] + 2.0 * c[3] * x + c[4] * y,
            c[2] + c[4] * x + 2.0 * c[5] * y,
        );
        (self.n - self.e1 * hx - self.e2 * hy).normalize()
    }

    /// Where the ray from the camera's centre along `dir` meets the surface: on the ray
    /// `t · dir` the height off the surface is a quadratic in `t`; of its roots the one nearest
    /// the depth `t0`. `None` where the ray misses the surface.
    fn hit(&self, dir: &Vector3<f64>, t0: f64) -> Option<Point3<f64>> {
        let q = -self.origin.coords;
        let (r1, r2, r3) = (dir.dot(&self.e1), dir.dot(&self.e2), dir.dot(&self.n));
        let (q1, q2, q3) = (q.dot(&self.e1), q.dot(&self.e2), q.dot(&self.n));
        let c = &self.c;
        let a = -(c[3] * r1 * r1 + c[4] * r1 * r2 + c[5] * r2 * r2);
        let b = r3
            - c[1] * r1
            - c[2] * r2
            - (2.0 * c[3] * r1 * q1 + c[4] * (r1 * q2 + r2 * q1) + 2.0 * c[5] * r2 * q2);
        let k =
            q3 - c[0] - c[1] * q1 - c[2] * q2 - (c[3] * q1 * q1 + c[4] * q1 * q2 + c[5] * q2 * q2);
        let t = if a.abs() <= 1e-12 * b.abs() {
            -k / b
        } else {
            let disc = b * b - 4.0 * a * k;
            if disc < 0.0 {
                return None;
            }
            // the two roots without cancellation
            let s = -0.5 * (b + b.signum() * disc.sqrt());
            let (x, y) = (s / a, k / s);
            if (x - t0).abs() < (y - t0).abs() {
                x
            } else {
                y
            }
        };
        (t.is_finite() && t > 0.0).then(|| Point3::from(dir * t))
    }
}

/// The direction of the ray through the pixel `rows` image rows below the point `p` (camera
/// coordinates, pinhole with the focal length `fy` in pixels along the column).
fn ray(p: &Point3<f64>, rows: f64, fy: f64) -> Vector3<f64> {
    Vector3::new(p.x / p.z, p.y / p.z + rows / fy, 1.0)
}

/// How far (image rows, + down) the lit band's centroid along the image column through `p` lies
/// from where the sheet's middle plane (through `p`, unit normal `m`) crosses the surface
/// `surface`, for a sheet of Gaussian thickness `sigma_mm`; `fy` is the camera's focal length in
/// pixels along the column. `None` where the band cannot be followed (the column grazes the
/// surface, or the sheet meets it at under 1 mm per 20 rows).
pub fn centre_offset(
    surface: &Quadric,
    p: &Point3<f64>,
    m: &Vector3<f64>,
    fy: f64,
    sigma_mm: f64,
    source: Option<&Point3<f64>>,
) -> Option<f64> {
    if !(sigma_mm > 0.0 && p.z > 0.0 && fy > 0.0) {
        return None;
    }
    // The sheet's distance at the point seen `u` rows away.
    let at = |u: f64| surface.hit(&ray(p, u, fy), p.z);
    let d = |u: f64| at(u).map(|s| m.dot(&(s - p)));
    // Rows per σ where the band crosses: the band's half-width.
    let slope = (d(0.5)? - d(-0.5)?).abs();
    if slope < 0.05 {
        return None;
    }
    let half = sigma_mm / slope;
    let reach = REACH * half;
    let (mut sum, mut weight) = (0.0, 0.0);
    let (mut crossing, mut last): (Option<f64>, Option<(f64, f64)>) = (None, None);
    for i in 0..SAMPLES {
        let u = -reach + 2.0 * reach * i as f64 / (SAMPLES - 1) as f64;
        let s = at(u)?;
        let du = m.dot(&(s - p));
        let mut g = (-du * du / (2.0 * sigma_mm * sigma_mm)).exp();
        if let Some(l) = source {
            let to = l - s;
            g *= surface.normal_at(&s).dot(&to).abs() / to.norm().powi(3);
        }
        sum += u * g;
        weight += g;
        if let Some((u0, d0)) = last
            && (d0 <= 0.0) != (du <= 0.0)
            && crossing.is_none_or(|c| c.abs() > u.abs())
        {
            crossing = Some(u0 + (u - u0) * d0 / (d0 - du));
        }
        last = Some((u, du));
    }
    let centroid = sum / weight;
    Some(centroid - crossing?)
}

/// The point on the laser plane (through `p`, unit normal `m`) seen `rows` image rows from `p`
/// along its column: with `rows = −offset`, where the sheet's middle truly crosses the surface.
pub fn shifted(p: &Point3<f64>, m: &Vector3<f64>, rows: f64, fy: f64) -> Option<Point3<f64>> {
    let r = ray(p, rows, fy);
    let along = m.dot(&r);
    (along.abs() > 1e-9).then(|| Point3::from(r * (m.dot(&p.coords) / along)))
}

/// The point all frames' laser planes pass nearest: where the laser's light comes from. A hand
/// sweep turns the sheet about one line (the source's), so along that line the planes say little;
/// there the point nearest the camera is taken. Sums of the planes only: fixed memory.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LaserOrigin {
    a: Matrix3<f64>,
    b: Vector3<f64>,
    planes: usize,
}

impl LaserOrigin {
    /// Adds a frame's plane `n·x + d = 0` (`[nx, ny, nz, d]`, `n` a unit vector); others are
    /// ignored.
    pub fn add(&mut self, plane: [f32; 4]) {
        let n = Vector3::new(plane[0], plane[1], plane[2]).cast::<f64>();
        let d = f64::from(plane[3]);
        if !((n.norm() - 1.0).abs() < 1e-3 && d.is_finite()) {
            return;
        }
        self.a += n * n.transpose();
        self.b -= n * d;
        self.planes += 1;
    }

    /// The source: least squares over the planes, directions they leave open (eigenvalues under
    /// a thousandth of the largest) taken from the camera's centre; `None` before three planes.
    pub fn source(&self) -> Option<Point3<f64>> {
        if self.planes < 3 {
            return None;
        }
        let e = self.a.symmetric_eigen();
        let top = e.eigenvalues.max();
        if !(top > 0.0) {
            return None;
        }
        let mut x = Vector3::zeros();
        for (i, &l) in e.eigenvalues.iter().enumerate() {
            if l > 1e-3 * top {
                let v = e.eigenvectors.column(i);
                x += v * (v.dot(&self.b) / l);
            }
        }
        x.iter().all(|v| v.is_finite()).then_some(Point3::from(x))
    }
}

/// Moves a scan's samples to where the sheet's middle truly crosses the surface: the surface
/// fitted around each of the scan's points once, each sample corrected with its frame's plane
/// and the fit of the point nearest it.
pub struct Correction {
    tree: KdTree<f64, 3>,
    fits: Vec<Option<Quadric>>,
    fy: f64,
    sigma_mm: f64,
    source: Option<Point3<f64>>,
}

impl Correction {
    /// From the scan's surface (`points` with their `normals`, e.g. its mesh's vertices), the
    /// camera's focal length along the column `fy` (pixels), the sheet's Gaussian thickness
    /// `sigma_mm` and where its light comes from (`None`: its fall-off across the band is not
    /// weighed).
    pub fn new(
        points: &[Point3<f64>],
        normals: &[Vector3<f64>],
        fy: f64,
        sigma_mm: f64,
        source: Option<Point3<f64>>,
    ) -> Correction {
        let tree = scanner_merge::spatial::tree(points);
        let fits = points
            .iter()
            .zip(normals)
            .map(|(p, n)| {
                let at = [p.x, p.y, p.z];
                let mut near: Vec<u64> = tree
                    .within_unsorted::<SquaredEuclidean>(&at, FIT_MM * FIT_MM)
                    .iter()
                    .map(|q| q.item)
                    .collect();
                if near.len() < FIT_POINTS {
                    near = tree
                        .nearest_n::<SquaredEuclidean>(&at, FIT_POINTS)
                        .iter()
                        .filter(|q| q.distance <= FIT_MAX_MM * FIT_MAX_MM)
                        .map(|q| q.item)
                        .collect();
                }
                Quadric::fit(*p, *n, near.iter().map(|&i| points[i as usize]))
            })
            .collect();
        Correction {
            tree,
            fits,
            fy,
            sigma_mm,
            source,
        }
    }

    /// Corrects one frame's samples (camera frame, mm) taken with the laser plane `plane`
    /// (`[nx, ny, nz, d]`); returns how many moved. Samples with no surface point within
    /// [`NEAR_MM`], or whose offset cannot be followed or exceeds [`MAX_ROWS`], stay.
    pub fn apply(&self, plane: [f32; 4], samples: &mut [Point3<f32>]) -> usize {
        let m = Vector3::new(plane[0], plane[1], plane[2]).cast::<f64>();
        let Some(m) = m.try_normalize(1e-9) else {
            return 0;
        };
        if self.fits.is_empty() || !m.iter().all(|v| v.is_finite()) {
            return 0;
        }
        let mut moved = 0;
        for s in samples.iter_mut() {
            let p: Point3<f64> = s.cast();
            let nn = self.tree.nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z]);
            if nn.distance > NEAR_MM * NEAR_MM {
                continue;
            }
            let Some(fit) = &self.fits[nn.item as usize] else {
                continue;
            };
            let Some(off) =
                centre_offset(fit, &p, &m, self.fy, self.sigma_mm, self.source.as_ref())
            else {
                continue;
            };
            if off.abs() > MAX_ROWS {
                continue;
            }
            if let Some(c) = shifted(&p, &m, -off, self.fy) {
                *s = c.cast();
                moved += 1;
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere's points around `p` (on it), as a scan would give them.
    fn sphere_patch(
        centre: Point3<f64>,
        radius: f64,
        p: &Point3<f64>,
        reach: f64,
    ) -> Vec<Point3<f64>> {
        let mut out = Vec::new();
        for i in -10..=10 {
            for j in -10..=10 {
                for k in -10..=10 {
                    let q = p + Vector3::new(i as f64, j as f64, k as f64) * (reach / 10.0);
                    let on = centre + (q - centre).normalize() * radius;
                    if (on - p).norm() <= reach && (i + j + k) % 3 == 0 {
                        out.push(on);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn a_plane_leaves_the_centre_where_it_is() {
        let p = Point3::new(10.0, -5.0, 500.0);
        let n = Vector3::new(0.2, -0.3, -1.0).normalize();
        let e = n.cross(&Vector3::x()).normalize();
        let pts: Vec<_> = (-5..=5)
            .flat_map(|i| (-5..=5).map(move |j| (i, j)))
            .map(|(i, j)| p + e * i as f64 * 0.5 + n.cross(&e) * j as f64 * 0.5)
            .collect();
        let q = Quadric::fit(p, n, pts).expect("fits");
        let m = Vector3::new(0.0, 0.8, 0.6).normalize();
        let off = centre_offset(&q, &p, &m, 1000.0, 0.6, None).expect("offset");
        // Only the perspective bends the distance along the column: a few thousandths of a row.
        assert!(off.abs() < 0.01, "{off}");
    }

    #[test]
    fn a_sphere_moves_the_centre_as_the_first_order_formula_says() {
        // A ball of 20 mm radius 500 mm away, the sheet cutting it off its middle at a slant.
        let centre = Point3::new(0.0, 0.0, 520.0);
        let p = centre + Vector3::new(0.0, -0.6, -0.8) * 20.0;
        let n = (p - centre).normalize();
        let q = Quadric::fit(p, n, sphere_patch(centre, 20.0, &p, 3.0)).expect("fits");
        let m = Vector3::new(0.0, 0.95, 0.3).normalize();
        let (fy, sigma) = (1000.0, 0.6);
        let off = centre_offset(&q, &p, &m, fy, sigma, None).expect("offset");
        // First order: −3 b σ²/a³ with d(u) ≈ a u + b u² sampled from the exact sphere.
        let d = |u: f64| {
            let r = ray(&p, u, fy).normalize();
            // ray–sphere: |t r − c|² = R², nearer root
            let b = r.dot(&centre.coords);
            let t = b - (b * b - centre.coords.norm_squared() + 400.0).sqrt();
            m.dot(&(r * t - p.coords))
        };
        let h = 0.5;
        let a = (d(h) - d(-h)) / (2.0 * h);
        let b = (d(h) - 2.0 * d(0.0) + d(-h)) / (2.0 * h * h);
        let first = -3.0 * b * sigma * sigma / (a * a * a);
        assert!(first.abs() > 0.01, "the case has a visible offset: {first}");
        assert!(
            (off - first).abs() < 0.15 * first.abs(),
            "offset {off} rows, first order {first}"
        );
    }

    #[test]
    fn the_offset_on_a_lit_sphere_is_the_exact_bands_and_the_shift_undoes_it() {
        // The band rendered exactly (ray–sphere, the sheet's Gaussian times the light's cosine
        // over distance², sampled finely along the column), its centroid and crossing found
        // here independently of the module; then the module from a local fit of scan-like
        // points must give the same offset, and shifting the measured point by it must land on
        // the sphere.
        let (c, radius, fy, sigma) = (Point3::new(5.0, 10.0, 540.0), 25.0, 1100.0, 0.6);
        let light = Point3::new(20.0, -150.0, 30.0);
        let ray_hit = |r: Vector3<f64>| {
            let r = r.normalize();
            let b = r.dot(&c.coords);
            let disc = b * b - c.coords.norm_squared() + radius * radius;
            (disc > 0.0).then(|| Point3::from(r * (b - disc.sqrt())))
        };
        let (mut cases, mut largest) = (0, 0.0f64);
        for dir in [
            Vector3::new(0.0, -0.9, -0.3),
            Vector3::new(0.0, -0.3, -0.9),
            Vector3::new(0.0, 0.6, -0.8),
            Vector3::new(0.0, 0.9, -0.3),
            Vector3::new(0.5, 0.2, -0.84),
            Vector3::new(-0.7, -0.2, -0.7),
        ] {
            let p = c + dir.normalize() * radius;
            let m = Vector3::x().cross(&(p - light)).normalize();
            // exact: the band along the column through p, out to 6 of its half-widths
            let exact = || -> Option<f64> {
                let at = |u: f64| ray_hit(ray(&p, u, fy));
                let reach = 6.0 * sigma / m.dot(&(at(0.5)? - at(-0.5)?)).abs();
                let (mut sum, mut weight, mut crossing, mut last) = (0.0, 0.0, None, None);
                for i in -4000..=4000 {
                    let u = i as f64 / 4000.0 * reach;
                    let s = at(u)?;
                    let d = m.dot(&(s - p));
                    let to = light - s;
                    let g = (-d * d / (2.0 * sigma * sigma)).exp()
                        * (s - c).normalize().dot(&to).max(0.0)
                        / to.norm().powi(3);
                    sum += u * g;
                    weight += g;
                    if let Some((u0, d0)) = last
                        && (d0 <= 0.0) != (d <= 0.0)
                    {
                        crossing = Some(u0 + (u - u0) * d0 / (d0 - d));
                    }
                    last = Some((u, d));
                }
                Some(sum / weight - crossing?)
            };
            // (the camera's rays graze the sphere's top and bottom: no whole band there)
            let Some(exact) = exact() else { continue };
            largest = largest.max(exact.abs());
            cases += 1;
            let fit = Quadric::fit(p, dir, sphere_patch(c, radius, &p, FIT_MM)).expect("fits");
            let off = centre_offset(&fit, &p, &m, fy, sigma, Some(&light)).expect("offset");
            eprintln!("dir {dir:?} exact {exact} off {off}");
            if exact.abs() < 0.02 {
                continue;
            }
            assert!(
                (off - exact).abs() < 0.05 * exact.abs() + 0.001,
                "offset {off} rows, exact {exact}"
            );
            // The point the head would report (on the plane, at the band's centroid) shifted
            // back by the offset lies on the sphere.
            let measured = shifted(&p, &m, exact, fy).expect("on the plane");
            let back = shifted(&measured, &m, -off, fy).expect("on the plane");
            let miss = |q: &Point3<f64>| ((q - c).norm() - radius).abs();
            assert!(
                miss(&back) < 0.1 * miss(&measured) + 1e-4,
                "corrected {} mm off, measured {} mm",
                miss(&back),
                miss(&measured)
            );
        }
        assert!(cases >= 4, "{cases} bands followed");
        assert!(
            largest > 0.05,
            "the largest offset, {largest} rows, is visible"
        );
    }

    #[test]
    fn the_planes_of_a_hand_sweep_meet_at_the_source() {
        // The rig's sweep: planes through the source holding a (rolled) horizontal direction and
        // a point on the crease; with no roll, or the rig's ±1.5° (the planes' normals then vary
        // by under a thousandth of their spread along x), they leave the source's x open and the
        // camera's centre's, 0, is taken; turned by ±10° they fix it.
        let source = Point3::new(20.0, -150.0, 30.0);
        for roll_deg in [0.0f64, 1.5, 10.0] {
            let mut pencil = LaserOrigin::default();
            for i in 0..60 {
                let aim = Point3::new(0.0, -150.0 + 380.0 * i as f64 / 59.0, 800.0);
                let roll = (roll_deg * if i % 2 == 0 { 1.0 } else { -1.0 }).to_radians();
                let along = Vector3::new(roll.cos(), roll.sin(), 0.0);
                let n = along.cross(&(aim - source)).normalize();
                let d = -n.dot(&source.coords);
                pencil.add([n.x as f32, n.y as f32, n.z as f32, d as f32]);
            }
            let found = pencil.source().expect("a source");
            let expected_x = if roll_deg < 5.0 { 0.0 } else { source.x };
            assert!(
                (found - Point3::new(expected_x, source.y, source.z)).norm() < 1.0,
                "roll {roll_deg}°: {found}"
            );
        }
        assert_eq!(LaserOrigin::default().source(), None);
    }

    #[test]
    fn no_surface_or_no_plane_moves_nothing() {
        let mut samples = [Point3::new(1.0f32, 2.0, 500.0)];
        let none = Correction::new(&[], &[], 1000.0, 0.6, None);
        assert_eq!(none.apply([0.0, 1.0, 0.0, -2.0], &mut samples), 0);
        let p = Point3::new(1.0, 2.0, 500.0);
        let grid: Vec<Point3<f64>> = (-5..=5)
            .flat_map(|i| (-5..=5).map(move |j| p + Vector3::new(i as f64, j as f64, 0.0) * 0.5))
            .collect();
        let normals = vec![-Vector3::z(); grid.len()];
        let flat = Correction::new(&grid, &normals, 1000.0, 0.6, None);
        for plane in [[0.0, 0.0, 0.0, 1.0], [f32::NAN, 0.0, 1.0, 0.0]] {
            assert_eq!(flat.apply(plane, &mut samples), 0, "{plane:?}");
        }
        assert_eq!(samples[0], Point3::new(1.0f32, 2.0, 500.0));
    }
}
