//! Which detected marker is which point of a known layout — without clicks.
//!
//! A seed of three neighbouring layout points is tried against every detected marker and pairs of
//! its nearest neighbours; each try fixes an affine map sheet → image, which must keep the sheet's
//! handedness (a sheet is seen from its printed side), may be required to run a given way along
//! the image's x axis (the left board sheet's `u` runs to the left), and must join markers of
//! similar size. The map predicts the other layout points; a try that finds a fourth is grown by
//! homographies (perspective, not affine) until its matches stop changing. The try matching the
//! most layout points, then with the smallest residual, wins. Layout points without a marker
//! (hidden by the object, out of view, rejected as clutter) are reported as missing.

use scanner_core::geometry::pose::homography;
use scanner_core::nalgebra::{Matrix2, Matrix3, Point2, Vector2, Vector3};

use super::detect::Blob;

/// Largest RMS distance of matched markers from the homography, as a fraction of the smallest
/// marker spacing in the image (a true match: about 0.001 without distortion, 0.01 with a
/// webcam's; markers of both sheets in one match: 0.1).
pub const MAX_RMS_OF_SPACING: f64 = 0.04;

/// Constraints a match must satisfy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Orientation {
    /// `true` if the layout appears mirrored in the image (`x` right, `y` down): the left board
    /// sheet, whose `u` runs from the crease to the left.
    pub mirrored: bool,
    /// If set, the sign with which the image `x` changes along the layout's `u`.
    pub u_along_x: Option<i8>,
}

/// A layout matched to detections.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// For each layout point, the index of its blob (or `None`: missing).
    pub blob_of: Vec<Option<usize>>,
    /// Sheet → pixel homography of the final match.
    pub homography: Matrix3<f64>,
    /// RMS distance between the homography's predictions and the matched blobs, pixels.
    pub rms_px: f64,
}

impl Assignment {
    /// Number of matched layout points.
    pub fn matched(&self) -> usize {
        self.blob_of.iter().filter(|b| b.is_some()).count()
    }
}

fn apply(h: &Matrix3<f64>, p: &Point2<f64>) -> Option<Point2<f64>> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    (q.z.abs() > 1e-12).then(|| Point2::new(q.x / q.z, q.y / q.z))
}

/// Index of the nearest blob to `p` within `tol`, if any and not in `used`.
fn nearest(blobs: &[Blob], used: &[bool], p: &Point2<f64>, tol: f64) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (i, b) in blobs.iter().enumerate() {
        if used[i] {
            continue;
        }
        let d = (b.centre - p).norm();
        if d <= tol && best.is_none_or(|(_, bd)| d < bd) {
            best = Some((i, d));
        }
    }
    best.map(|(i, _)| i)
}

/// Smallest distance between two layout points.
fn min_spacing(layout: &[Point2<f64>]) -> f64 {
    let mut m = f64::INFINITY;
    for (i, a) in layout.iter().enumerate() {
        for b in &layout[i + 1..] {
            m = m.min((a - b).norm());
        }
    }
    m
}

/// Seeds: parallelograms `(p, q, r, s = q + r − p)` of layout points, small ones near the middle
/// first, so that four matched markers fix a homography; several, so that a hidden marker does
/// not stop identification. A layout without parallelograms gets triangles (`s = None`).
fn seeds(layout: &[Point2<f64>]) -> Vec<([usize; 3], Option<usize>)> {
    let n = layout.len();
    let c = layout.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / n as f64;
    let scale = min_spacing(layout);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        (layout[a].coords - c)
            .norm()
            .total_cmp(&(layout[b].coords - c).norm())
    });
    let spans = |p: usize, q: usize, r: usize| {
        let (dq, dr) = (layout[q] - layout[p], layout[r] - layout[p]);
        let cross = dq.x * dr.y - dq.y * dr.x;
        (cross.abs() > 0.3 * dq.norm() * dr.norm()).then_some(cross.abs())
    };
    let mut quads: Vec<(f64, [usize; 3], usize)> = Vec::new();
    let mut tris: Vec<(f64, [usize; 3])> = Vec::new();
    for &p in order.iter().take(8) {
        let mut near: Vec<usize> = (0..n).filter(|&i| i != p).collect();
        near.sort_by(|&a, &b| {
            (layout[a] - layout[p])
                .norm()
                .total_cmp(&(layout[b] - layout[p]).norm())
        });
        near.truncate(8);
        for (x, &q) in near.iter().enumerate() {
            for &r in &near[x + 1..] {
                let Some(area) = spans(p, q, r) else { continue };
                let want = layout[q] + (layout[r] - layout[p]);
                match (0..n).find(|&s| (layout[s] - want).norm() < 1e-6 * scale) {
                    Some(s) => quads.push((area, [p, q, r], s)),
                    None => tris.push((area, [p, q, r])),
                }
            }
        }
    }
    quads.sort_by(|a, b| a.0.total_cmp(&b.0));
    tris.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<([usize; 3], Option<usize>)> = Vec::new();
    let mut seen: Vec<[usize; 4]> = Vec::new();
    for (_, t, s) in quads {
        let mut key = [t[0], t[1], t[2], s];
        key.sort_unstable();
        if !seen.contains(&key) {
            seen.push(key);
            out.push((t, Some(s)));
        }
        if out.len() >= 8 {
            break;
        }
    }
    if out.len() < 3 {
        out.extend(tris.into_iter().take(4).map(|(_, t)| (t, None)));
    }
    out
}

/// Whether some four of `pts` have no three on a line (a homography is then determined).
fn general_position(pts: &[Point2<f64>]) -> bool {
    let n = pts.len();
    let scale = pts.iter().map(|p| p.coords.norm()).fold(1e-9, f64::max);
    let off_line = |a: usize, b: usize, c: usize| {
        let (u, v) = (pts[b] - pts[a], pts[c] - pts[a]);
        (u.x * v.y - u.y * v.x).abs() > 1e-3 * scale * scale
    };
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                if !off_line(a, b, c) {
                    continue;
                }
                for d in c + 1..n {
                    if off_line(a, b, d) && off_line(a, c, d) && off_line(b, c, d) {
                        return true;
                    }
                }
            }
        }
    }
    false
}

/// The sheet → image map of matched points: a homography where they determine one, otherwise
/// the least-squares affine map.
fn sheet_to_image(src: &[Point2<f64>], dst: &[Vector2<f64>]) -> Option<Matrix3<f64>> {
    if src.len() >= 4 && general_position(src) {
        return homography(src, dst).ok();
    }
    if src.len() < 3 {
        return None;
    }
    let mut ata = Matrix3::<f64>::zeros();
    let (mut bx, mut by) = (Vector3::zeros(), Vector3::zeros());
    for (s, d) in src.iter().zip(dst) {
        let row = Vector3::new(s.x, s.y, 1.0);
        ata += row * row.transpose();
        bx += row * d.x;
        by += row * d.y;
    }
    let chol = ata.cholesky()?;
    let (ax, ay) = (chol.solve(&bx), chol.solve(&by));
    Some(Matrix3::new(
        ax[0], ax[1], ax[2], ay[0], ay[1], ay[2], 0.0, 0.0, 1.0,
    ))
}

/// Jacobian of the homography's image point with respect to the sheet point `p`.
fn jacobian(h: &Matrix3<f64>, p: &Point2<f64>) -> Option<Matrix2<f64>> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    let wp = q.z;
    if wp == 0.0 || !wp.is_finite() {
        return None;
    }
    let (x, y) = (q.x / wp, q.y / wp);
    Some(Matrix2::new(
        (h[(0, 0)] - x * h[(2, 0)]) / wp,
        (h[(0, 1)] - x * h[(2, 1)]) / wp,
        (h[(1, 0)] - y * h[(2, 0)]) / wp,
        (h[(1, 1)] - y * h[(2, 1)]) / wp,
    ))
}

/// For a chessboard corner: whether the blob's dark quadrants agree with the layout's colour
/// at `p` (`dark`: its (+u, +v) square is dark), seen through `h`. True where unknown.
fn colour_agrees(h: &Matrix3<f64>, p: &Point2<f64>, blob: &Blob, dark: Option<bool>) -> bool {
    let (Some(dark), Some(axis)) = (dark, blob.dark_axis) else {
        return true;
    };
    let Some(j) = jacobian(h, p) else {
        return false;
    };
    let (gu, gv) = (j.column(0).into_owned(), j.column(1).into_owned());
    if gu.norm() == 0.0 || gv.norm() == 0.0 {
        return false;
    }
    let diag = gu.normalize() + gv.normalize();
    super::lattice::turned(diag.y.atan2(diag.x), axis) != dark
}

/// Whether `h` maps the whole layout the way a sheet in front of the camera appears: no point
/// beyond the horizon (the homography's denominator keeps its sign), the handedness and the
/// direction of `u` as required at every layout point.
fn keeps_orientation(h: &Matrix3<f64>, layout: &[Point2<f64>], orient: Orientation) -> bool {
    let w = |p: &Point2<f64>| h[(2, 0)] * p.x + h[(2, 1)] * p.y + h[(2, 2)];
    let sign = w(&layout[0]).signum();
    layout.iter().all(|p| {
        let wp = w(p);
        if wp.signum() != sign || wp == 0.0 {
            return false;
        }
        let Some(j) = jacobian(h, p) else {
            return false;
        };
        let det = j.determinant();
        (det < 0.0) == orient.mirrored
            && det != 0.0
            && orient
                .u_along_x
                .is_none_or(|s| j[(0, 0)] * f64::from(s) > 0.0)
    })
}

/// The sheet → image map of a match, its strays left out: while the map misses the match's
/// points by more than [`STRAY_RMS_PX`] (RMS) and leaving one point out at least halves that,
/// the point is left out. A stray is another target's dot where an affine start, extrapolated
/// across a large layout (a disc's ring), put a far layout point: kept, it bends the map until
/// the true matches no longer fit it.
fn without_strays(
    blobs: &[Blob],
    layout: &[Point2<f64>],
    blob_of: &mut [Option<usize>],
) -> Option<Matrix3<f64>> {
    let fit = |blob_of: &[Option<usize>], skip: Option<usize>| -> Option<(Matrix3<f64>, f64)> {
        let (src, dst): (Vec<Point2<f64>>, Vec<Vector2<f64>>) = blob_of
            .iter()
            .enumerate()
            .filter(|&(i, _)| Some(i) != skip)
            .filter_map(|(i, b)| b.map(|b| (layout[i], blobs[b].centre.coords)))
            .unzip();
        let h = sheet_to_image(&src, &dst)?;
        let ss: f64 = src
            .iter()
            .zip(&dst)
            .map(|(s, t)| apply(&h, s).map_or(f64::INFINITY, |p| (p.coords - t).norm_squared()))
            .sum();
        Some((h, (ss / src.len().max(1) as f64).sqrt()))
    };
    loop {
        let (h, rms) = fit(blob_of, None)?;
        let matched: Vec<usize> = (0..blob_of.len())
            .filter(|&i| blob_of[i].is_some())
            .collect();
        if matched.len() <= 5 || rms <= STRAY_RMS_PX {
            return Some(h);
        }
        let best = matched
            .iter()
            .filter_map(|&k| fit(blob_of, Some(k)).map(|(_, r)| (k, r)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((k, r)) if r <= rms / 2.0 => blob_of[k] = None,
            _ => return Some(h),
        }
    }
}

/// See [`without_strays`]: true matches of features with the lens distortion removed fit a
/// homography within a few tenths of a pixel.
const STRAY_RMS_PX: f64 = 1.0;

/// Grows a match by homographies until it stops changing.
fn grow(
    blobs: &[Blob],
    layout: &[Point2<f64>],
    dark: Option<&[bool]>,
    exclude: &[bool],
    mut blob_of: Vec<Option<usize>>,
    spacing: f64,
    orient: Orientation,
) -> Option<Assignment> {
    let mut last = None;
    for _ in 0..24 {
        let h = without_strays(blobs, layout, &mut blob_of)?;
        let src: Vec<Point2<f64>> = (0..layout.len())
            .filter(|&i| blob_of[i].is_some())
            .map(|i| layout[i])
            .collect();
        // Checked where the match is (extrapolating a small seed across a large layout is not
        // reliable enough to judge points far from it).
        if !keeps_orientation(&h, &src, orient) {
            return None;
        }
        // Markers of one sheet have similar sizes: a sliver of a hidden one does not count.
        let mut areas: Vec<f64> = blob_of.iter().flatten().map(|&b| blobs[b].area).collect();
        areas.sort_by(f64::total_cmp);
        let median_area = areas[areas.len() / 2];
        let mut used = vec![false; blobs.len()];
        let mut next = vec![None; layout.len()];
        // Assign in order of closeness so that a blob goes to the layout point it fits best.
        let mut cands: Vec<(f64, usize, usize)> = Vec::new();
        let mut tols = Vec::new();
        for (i, p) in layout.iter().enumerate() {
            let (Some(c), Some(cx)) = (apply(&h, p), apply(&h, &(p + Vector2::new(spacing, 0.0))))
            else {
                continue;
            };
            let cy = apply(&h, &(p + Vector2::new(0.0, spacing)))?;
            let tol = 0.3 * (cx - c).norm().min((cy - c).norm());
            tols.push(tol);
            for (b, blob) in blobs.iter().enumerate() {
                if exclude.get(b).copied().unwrap_or(false)
                    || !(blob.area > median_area / 4.0 && blob.area < median_area * 4.0)
                {
                    continue;
                }
                let d = (blob.centre - c).norm();
                if d <= tol && colour_agrees(&h, p, blob, dark.map(|d| d[i])) {
                    cands.push((d, i, b));
                }
            }
        }
        cands.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut ss = 0.0;
        let spacing_px = tols.iter().fold(f64::INFINITY, |m, t| m.min(*t)) / 0.3;
        for (d, i, b) in cands {
            if next[i].is_none() && !used[b] {
                next[i] = Some(b);
                used[b] = true;
                ss += d * d;
            }
        }
        let n = next.iter().filter(|b| b.is_some()).count();
        if n < 4 {
            return None;
        }
        let done = next == blob_of;
        blob_of = next;
        let rms_px = (ss / n as f64).sqrt();
        // A sheet's markers fit one homography up to lens distortion; markers of two planes
        // (across the crease) or clutter do not.
        if rms_px > MAX_RMS_OF_SPACING * spacing_px {
            return None;
        }
        last = Some(Assignment {
            blob_of: blob_of.clone(),
            homography: h,
            rms_px,
        });
        if done {
            break;
        }
    }
    last
}

/// Matches `layout` (sheet mm) to `blobs`, skipping blobs marked in `exclude`. `None` if fewer
/// than four layout points can be matched consistently.
pub fn identify(
    blobs: &[Blob],
    exclude: &[bool],
    layout: &[Point2<f64>],
    orient: Orientation,
) -> Option<Assignment> {
    candidates(blobs, exclude, layout, None, orient)
        .into_iter()
        .next()
}

/// Every distinct consistent match of `layout` to `blobs`, best first (most layout points
/// matched, then the smallest residual). More than one survives where the layout leaves an
/// ambiguity (e.g. the paper's 2×3 layout with a marker hidden: a row can shift along itself
/// under a homography); a calibrated camera then decides ([`super::board_planes`]).
///
/// `dark`, for a chessboard's corners: per layout point, whether its (+u, +v) square is dark.
/// A corner is then matched only where its dark quadrants agree, so a match never runs along
/// the diagonals nor sits one square off.
pub fn candidates(
    blobs: &[Blob],
    exclude: &[bool],
    layout: &[Point2<f64>],
    dark: Option<&[bool]>,
    orient: Orientation,
) -> Vec<Assignment> {
    if layout.len() < 4 || blobs.len() < 4 {
        return Vec::new();
    }
    let spacing = min_spacing(layout);
    let avail: Vec<usize> = (0..blobs.len())
        .filter(|&i| !exclude.get(i).copied().unwrap_or(false))
        .collect();
    let mut all: Vec<Assignment> = Vec::new();
    for (corners, fourth) in seeds(layout) {
        let Some(seed) = Seed::new(layout, corners, fourth) else {
            continue;
        };
        for &i in &avail {
            let near = nearest_ten(blobs, &avail, i);
            for &j in &near {
                for &k in &near {
                    let three = [i, j, k];
                    if j == k || seed.grown(&all, three) {
                        continue;
                    }
                    let Some(start) = seed
                        .affine(blobs, three, orient)
                        .and_then(|a| seed.start(blobs, exclude, layout, three, &a, spacing))
                    else {
                        continue;
                    };
                    let Some(m) = grow(blobs, layout, dark, exclude, start, spacing, orient) else {
                        continue;
                    };
                    if m.matched() >= 4 && !all.iter().any(|a| a.blob_of == m.blob_of) {
                        all.push(m);
                    }
                }
            }
        }
    }
    all.sort_by(|a, b| {
        b.matched()
            .cmp(&a.matched())
            .then(a.rms_px.total_cmp(&b.rms_px))
    });
    all
}
/// The ten available features nearest to feature `i` (not `i` itself), nearest first.
fn nearest_ten(blobs: &[Blob], avail: &[usize], i: usize) -> Vec<usize> {
    let c = blobs[i].centre;
    let mut near: Vec<usize> = avail.iter().copied().filter(|&j| j != i).collect();
    near.sort_by(|&a, &b| {
        (blobs[a].centre - c)
            .norm()
            .total_cmp(&(blobs[b].centre - c).norm())
    });
    near.truncate(10);
    near
}

/// Three layout points `p`, `q`, `r` (an L) to place on three features, and the point
/// completing their parallelogram if the layout has one.
struct Seed {
    p: usize,
    q: usize,
    r: usize,
    fourth: Option<usize>,
    /// Inverse of the matrix with columns q − p and r − p (layout mm).
    inverse: Matrix2<f64>,
}

/// The affine map of a seed placed on three features (layout mm → pixels), and the matrix of
/// the features' offsets it came from.
struct Affine {
    map: Matrix2<f64>,
    offsets: Matrix2<f64>,
}

impl Seed {
    fn new(layout: &[Point2<f64>], [p, q, r]: [usize; 3], fourth: Option<usize>) -> Option<Seed> {
        let lm = Matrix2::from_columns(&[layout[q] - layout[p], layout[r] - layout[p]]);
        Some(Seed {
            p,
            q,
            r,
            fourth,
            inverse: lm.try_inverse()?,
        })
    }

    /// A seed inside a match already grown would grow it again. (Every seed is tried even
    /// after a full match: a symmetric layout also fits the other sheet's markers, mirrored, in
    /// full.)
    fn grown(&self, all: &[Assignment], [i, j, k]: [usize; 3]) -> bool {
        all.iter().any(|m| {
            m.blob_of[self.p] == Some(i)
                && m.blob_of[self.q] == Some(j)
                && m.blob_of[self.r] == Some(k)
        })
    }

    /// The seed on features `i`, `j`, `k`, if their sizes are alike and the map has the
    /// orientation asked for.
    fn affine(&self, blobs: &[Blob], [i, j, k]: [usize; 3], orient: Orientation) -> Option<Affine> {
        let (bi, bj, bk) = (&blobs[i], &blobs[j], &blobs[k]);
        let areas = [bi.area, bj.area, bk.area];
        let (amin, amax) = areas.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &a| {
            (lo.min(a), hi.max(a))
        });
        if amax > 3.0 * amin {
            return None;
        }
        let offsets = Matrix2::from_columns(&[bj.centre - bi.centre, bk.centre - bi.centre]);
        let map = offsets * self.inverse;
        let det = map.determinant();
        if (det < 0.0) != orient.mirrored || det == 0.0 {
            return None;
        }
        if let Some(s) = orient.u_along_x
            && (map[(0, 0)] * f64::from(s)) <= 0.0
        {
            return None;
        }
        Some(Affine { map, offsets })
    }

    /// The seed's three features and a fourth: the parallelogram's fourth corner if the layout
    /// has one (with it, a homography), else whatever the affine guess finds.
    fn start(
        &self,
        blobs: &[Blob],
        exclude: &[bool],
        layout: &[Point2<f64>],
        three: [usize; 3],
        a: &Affine,
        spacing: f64,
    ) -> Option<Vec<Option<usize>>> {
        let mut blob_of = vec![None; layout.len()];
        let mut used = vec![false; blobs.len()];
        for (e, ex) in exclude.iter().enumerate() {
            if *ex && e < used.len() {
                used[e] = true;
            }
        }
        for (l, b) in [self.p, self.q, self.r].into_iter().zip(three) {
            blob_of[l] = Some(b);
            used[b] = true;
        }
        let origin = blobs[three[0]].centre;
        let predict = |l: usize| origin + a.map * (layout[l] - layout[self.p]);
        if let Some(s) = self.fourth {
            // Allowing for strong perspective: a close, angled sheet foreshortens one side of
            // the parallelogram by a fraction of its length.
            let (c0, c1) = (a.offsets.column(0).norm(), a.offsets.column(1).norm());
            let tol = (0.35 * c0.min(c1)).max(0.25 * c0.max(c1));
            blob_of[s] = Some(nearest(blobs, &used, &predict(s), tol)?);
        } else {
            let tol = 0.35 * spacing * a.map.determinant().abs().sqrt();
            let mut found = 0;
            for (l, slot) in blob_of.iter_mut().enumerate() {
                if slot.is_none()
                    && let Some(b) = nearest(blobs, &used, &predict(l), tol)
                {
                    *slot = Some(b);
                    used[b] = true;
                    found += 1;
                }
            }
            if found == 0 {
                return None;
            }
        }
        Some(blob_of)
    }
}
