//! Registration of two views of one object (issue 17's first stage): without an initial guess,
//! by matching local shape descriptors (FPFH, Rusu et al. 2009) with RANSAC, then refined by
//! point-to-plane ICP. Neighbour searches go through a k-d tree (`kiddo`). The views are then
//! refined together ([`crate::refine::clouds`]) and fused ([`crate::fuse::surface`]).
//!
//! Clouds are in millimetres, each in its own view's camera frame; a registration is the rigid
//! motion that takes the source view's points onto the target view's.

use kiddo::{KdTree, SquaredEuclidean};
use scanner_core::nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6,
};

use crate::error::RegisterError;
use crate::spatial::{Cloud, across, centre, thin, tree, tree_of};

/// Bins per angle feature of a descriptor (three features: 33 values).
const BINS: usize = 11;
/// Descriptor length.
const FPFH_LEN: usize = 3 * BINS;

/// Settings of a registration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisterOptions {
    /// Voxel size the clouds are thinned to for the descriptors and the coarse match, mm.
    pub voxel_mm: f64,
    /// RANSAC trials.
    pub trials: usize,
    /// Least share of the source's thinned points that must land on the target.
    pub min_overlap: f64,
    /// Seed of the random trials (the result is reproducible).
    pub seed: u64,
}

impl Default for RegisterOptions {
    fn default() -> Self {
        RegisterOptions {
            voxel_mm: 3.0,
            trials: 20_000,
            min_overlap: 0.4,
            seed: 2012,
        }
    }
}

/// A registration's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// Source → target.
    pub pose: Isometry3<f64>,
    /// Share of the source's points within the tolerance of the target after refinement.
    pub overlap: f64,
    /// RMS point-to-plane residual of the overlapping points after refinement, mm.
    pub rms_mm: f64,
}

/// The FPFH descriptor of every point within `radius` mm.
fn fpfh(c: &Cloud, radius: f64) -> Vec<[f32; FPFH_LEN]> {
    let t = tree(&c.points);
    let r2 = radius * radius;
    let neighbours: Vec<Vec<(usize, f64)>> = c
        .points
        .iter()
        .map(|p| {
            t.within_unsorted::<SquaredEuclidean>(&[p.x, p.y, p.z], r2)
                .into_iter()
                .map(|n| (n.item as usize, n.distance.sqrt()))
                .collect()
        })
        .collect();
    let bin =
        |v: f64, lo: f64, hi: f64| (((v - lo) / (hi - lo) * BINS as f64) as usize).min(BINS - 1);
    // Simplified point feature histograms.
    let spfh: Vec<[f64; FPFH_LEN]> = (0..c.points.len())
        .map(|i| {
            let mut h = [0.0; FPFH_LEN];
            let (p, n) = (c.points[i], c.normals[i]);
            let mut count = 0.0;
            for &(j, d) in &neighbours[i] {
                if j == i || d < 1e-9 {
                    continue;
                }
                let dv = (c.points[j] - p) / d;
                let u = n;
                let v = u.cross(&dv);
                if v.norm() < 1e-9 {
                    continue;
                }
                let v = v.normalize();
                let w = u.cross(&v);
                let nt = c.normals[j];
                let alpha = v.dot(&nt);
                let phi = u.dot(&dv);
                let theta = w.dot(&nt).atan2(u.dot(&nt));
                h[bin(alpha, -1.0, 1.0)] += 1.0;
                h[BINS + bin(phi, -1.0, 1.0)] += 1.0;
                h[2 * BINS + bin(theta, -std::f64::consts::PI, std::f64::consts::PI)] += 1.0;
                count += 1.0;
            }
            if count > 0.0 {
                h.iter_mut().for_each(|x| *x *= 100.0 / count);
            }
            h
        })
        .collect();
    (0..c.points.len())
        .map(|i| {
            let mut f = spfh[i];
            let mut k = 0.0;
            let mut acc = [0.0; FPFH_LEN];
            for &(j, d) in &neighbours[i] {
                if j != i && d > 1e-9 {
                    for (a, s) in acc.iter_mut().zip(&spfh[j]) {
                        *a += s / d;
                    }
                    k += 1.0;
                }
            }
            if k > 0.0 {
                for (x, a) in f.iter_mut().zip(acc) {
                    *x += a / k;
                }
            }
            f.map(|v| v as f32)
        })
        .collect()
}

/// The rigid motion that best takes `a[i]` onto `b[i]` (Kabsch).
fn kabsch(a: &[Point3<f64>], b: &[Point3<f64>]) -> Isometry3<f64> {
    let n = a.len() as f64;
    let ca = a.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let cb = b.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let h = a.iter().zip(b).fold(Matrix3::zeros(), |s, (p, q)| {
        s + (p.coords - ca) * (q.coords - cb).transpose()
    });
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.unwrap_or_default(), svd.v_t.unwrap_or_default());
    let mut r = vt.transpose() * u.transpose();
    if r.determinant() < 0.0 {
        let mut v = vt.transpose();
        v.column_mut(2).neg_mut();
        r = v * u.transpose();
    }
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Isometry3::from_parts(Translation3::from(cb - rot * ca), rot)
}

/// Share of `src` points within `tol` of `dst` after `pose`.
fn overlap(src: &[Point3<f64>], dst: &KdTree<f64, 3>, pose: &Isometry3<f64>, tol: f64) -> f64 {
    let t2 = tol * tol;
    let hits = src
        .iter()
        .filter(|p| {
            let q = pose * *p;
            dst.nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z])
                .distance
                <= t2
        })
        .count();
    hits as f64 / src.len().max(1) as f64
}

/// Coarse registration of `src` onto `dst` (both thinned): descriptor matches, then RANSAC over
/// triples whose edge lengths agree; the few distinct motions that bring the most points within
/// 1.5 voxels, each with that share over all points, best first.
fn coarse(src: &Cloud, dst: &Cloud, o: &RegisterOptions) -> Vec<(Isometry3<f64>, f64)> {
    let radius = 5.0 * o.voxel_mm;
    let (fs, fd) = (fpfh(src, radius), fpfh(dst, radius));
    let ftree: KdTree<f32, FPFH_LEN> = tree_of(fd.iter().copied());
    let matches: Vec<(usize, usize)> = fs
        .iter()
        .enumerate()
        .map(|(i, f)| (i, ftree.nearest_one::<SquaredEuclidean>(f).item as usize))
        .collect();
    let dst_tree = tree(&dst.points);
    let tol = 1.5 * o.voxel_mm;
    let mut rng = o.seed | 1;
    let mut next = move |n: usize| {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng % n as u64) as usize
    };
    let mut best: Vec<(Isometry3<f64>, f64)> = Vec::with_capacity(HYPOTHESES + 1);
    // Each trial scores a subsample; the best few are scored on all points.
    let sample: Vec<Point3<f64>> = src.points.iter().step_by(4).copied().collect();
    for _ in 0..o.trials {
        let m = [0, 1, 2].map(|_| matches[next(matches.len())]);
        let (a, b) = (m.map(|(i, _)| src.points[i]), m.map(|(_, j)| dst.points[j]));
        let consistent = (0..3).all(|k| {
            let (da, db) = (
                (a[k] - a[(k + 1) % 3]).norm(),
                (b[k] - b[(k + 1) % 3]).norm(),
            );
            da > 2.0 * o.voxel_mm && (da - db).abs() < 0.1 * da.max(db)
        });
        if !consistent {
            continue;
        }
        let pose = kabsch(&a, &b);
        let score = overlap(&sample, &dst_tree, &pose, tol);
        keep_best(&mut best, pose, score, o.voxel_mm);
    }
    best.into_iter()
        .map(|(pose, _)| (pose, overlap(&src.points, &dst_tree, &pose, tol)))
        .collect()
}

/// Source points paired in the fine fit.
const FINE_POINTS: usize = 10_000;

/// Coarse hypotheses kept for refinement: a wrong match can outscore the right one on the thinned
/// clouds (noisy normals blur the descriptors), and the refinement tells them apart.
const HYPOTHESES: usize = 6;

/// Keeps the [`HYPOTHESES`] best-scoring distinct motions in `best` (sorted, best first); a
/// motion within 2° and 2 voxels of a kept one replaces it only when it scores higher.
fn keep_best(best: &mut Vec<(Isometry3<f64>, f64)>, pose: Isometry3<f64>, score: f64, voxel: f64) {
    if best.len() == HYPOTHESES && score <= best[HYPOTHESES - 1].1 {
        return;
    }
    let near = best.iter().position(|(p, _)| same_motion(p, &pose, voxel));
    match near {
        Some(i) if best[i].1 >= score => return,
        Some(i) => {
            best.remove(i);
        }
        None => {}
    }
    let at = best.partition_point(|(_, s)| *s >= score);
    best.insert(at, (pose, score));
    best.truncate(HYPOTHESES);
}

/// Point-to-plane ICP from `init`, pairs within `max_dist` mm; returns the motion, the overlap
/// and the RMS residual of the pairs.
pub fn icp(
    src: &Cloud,
    dst: &Cloud,
    init: Isometry3<f64>,
    max_dist: f64,
    iterations: usize,
) -> Registration {
    icp_facing(src, dst, init, max_dist, iterations, -1.0)
}

/// [`icp`] pairing only points whose normals agree: the cosine between a source point's normal
/// (moved) and its partner's at least `min_cos`. A surface one cloud saw and the other did not
/// (the underside an object stood on) then pulls on nothing, instead of on the nearest other
/// surface facing elsewhere.
pub fn icp_facing(
    src: &Cloud,
    dst: &Cloud,
    init: Isometry3<f64>,
    max_dist: f64,
    iterations: usize,
    min_cos: f64,
) -> Registration {
    let t = tree(&dst.points);
    let mut pose = init;
    let mut result = Registration {
        pose,
        overlap: 0.0,
        rms_mm: f64::INFINITY,
    };
    for it in 0..iterations {
        // The pairing distance shrinks from `max_dist` to a third of it.
        let d = max_dist * (1.0 - 0.66 * it as f64 / iterations.max(1) as f64);
        let (mut ata, mut atb) = (Matrix6::zeros(), Vector6::zeros());
        let (mut sum2, mut pairs) = (0.0, 0usize);
        for (p, np) in src.points.iter().zip(&src.normals) {
            let q = pose * p;
            let nn = t.nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z]);
            if nn.distance > d * d {
                continue;
            }
            let j = nn.item as usize;
            let (pd, n) = (dst.points[j], dst.normals[j]);
            if (pose.rotation * np).dot(&n) < min_cos {
                continue;
            }
            let r = (q - pd).dot(&n);
            let c = q.coords.cross(&n);
            let row = Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
            ata += row * row.transpose();
            atb -= row * r;
            sum2 += r * r;
            pairs += 1;
        }
        if pairs < 6 {
            break;
        }
        result = Registration {
            pose,
            overlap: pairs as f64 / src.points.len() as f64,
            rms_mm: (sum2 / pairs as f64).sqrt(),
        };
        let Some(x) = ata.cholesky().map(|c| c.solve(&atb)) else {
            break;
        };
        let step = Isometry3::from_parts(
            Translation3::new(x[3], x[4], x[5]),
            UnitQuaternion::from_scaled_axis(Vector3::new(x[0], x[1], x[2])),
        );
        pose = step * pose;
        if x.norm() < 1e-9 {
            break;
        }
    }
    result.pose = pose;
    result
}

/// The motions of `src` onto `dst` if the object turned by `angle_deg` about the axis `up`
/// between them, either way round; the axis's place is not known, so each rotation is paired
/// with the translation that brings the clouds' centroids together (the refinement then finds
/// the rest).
pub fn turntable_motions(
    up: &Vector3<f64>,
    src: &Cloud,
    dst: &Cloud,
    angle_deg: f64,
) -> [Isometry3<f64>; 2] {
    let axis = scanner_core::nalgebra::Unit::new_normalize(*up);
    let (cs, cd) = (centre(&src.points).coords, centre(&dst.points).coords);
    let a = angle_deg.to_radians();
    [a, -a].map(|a| {
        let r = UnitQuaternion::from_axis_angle(&axis, a);
        Isometry3::from_parts(Translation3::from(cd - r * cs), r)
    })
}

/// Registers `src` onto `dst` without an initial guess: coarse by descriptors and RANSAC on the
/// clouds thinned to `voxel_mm`, then point-to-plane ICP on the full clouds.
///
/// # Errors
/// [`RegisterError::TooFewPoints`] for a view too small to describe,
/// [`RegisterError::NoOverlap`] when no motion brings `min_overlap` of it onto the other.
pub fn register(
    src: &Cloud,
    dst: &Cloud,
    o: &RegisterOptions,
) -> Result<Registration, RegisterError> {
    register_hinted(src, dst, o, &[])
}

/// [`register`] with `hints`: motions (e.g. from a turntable's known step) scored and refined
/// beside the descriptors' own hypotheses, never instead of them.
///
/// # Errors
/// As [`register`].
pub fn register_hinted(
    src: &Cloud,
    dst: &Cloud,
    o: &RegisterOptions,
    hints: &[Isometry3<f64>],
) -> Result<Registration, RegisterError> {
    let best = candidates(src, dst, o, hints)?[0];
    fine(src, dst, best.pose, o)
}

/// A motion of one view onto another that the coarse stage proposed and ICP refined on the
/// thinned clouds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Source → target.
    pub pose: Isometry3<f64>,
    /// Share of the source's thinned points within a third of a voxel of the target's.
    pub fit: f64,
    /// RMS point-to-plane residual of the refinement's pairs, mm.
    pub rms_mm: f64,
}

/// The distinct motions of `src` onto `dst` worth a fine fit, best fitting first: the coarse
/// stage's hypotheses (and `hints`) that bring `min_overlap` of the thinned points within 1.5
/// voxels, each refined by ICP on the thinned clouds.
///
/// # Errors
/// [`RegisterError::TooFewPoints`] for a view too small to describe,
/// [`RegisterError::NoOverlap`] when no hypothesis brings `min_overlap` of it onto the other.
pub fn candidates(
    src: &Cloud,
    dst: &Cloud,
    o: &RegisterOptions,
    hints: &[Isometry3<f64>],
) -> Result<Vec<Candidate>, RegisterError> {
    const MIN_POINTS: usize = 50;
    let (s, d) = (thin(src, o.voxel_mm), thin(dst, o.voxel_mm));
    for c in [&s, &d] {
        if c.points.len() < MIN_POINTS {
            return Err(RegisterError::TooFewPoints {
                points: c.points.len(),
                voxel_mm: o.voxel_mm,
                min: MIN_POINTS,
            });
        }
    }
    let dtree = tree(&d.points);
    let mut hypotheses = coarse(&s, &d, o);
    // A hint's rotation is taken as known, its translation as rough (a turntable's axis is not
    // known where it stands): the translation is searched across the plane the turn keeps, then
    // pulled in by a wide ICP on the thinned clouds before it is scored like the others.
    for h in hints {
        let placed = place_turn(&s, &dtree, h, o.voxel_mm);
        let pulled = icp(&s, &d, placed, 4.0 * o.voxel_mm, 30).pose;
        hypotheses.push((
            pulled,
            overlap(&s.points, &dtree, &pulled, 1.5 * o.voxel_mm),
        ));
    }
    let found = hypotheses.iter().map(|h| h.1).fold(0.0, f64::max);
    if found < o.min_overlap {
        return Err(RegisterError::NoOverlap {
            overlap_percent: 100.0 * found,
            tolerance_mm: 1.5 * o.voxel_mm,
            min_percent: 100.0 * o.min_overlap,
        });
    }
    // Each hypothesis refined on the thinned clouds and scored by the points it then fits
    // within a third of a voxel; hypotheses that met in one motion count once.
    let mut out: Vec<Candidate> = Vec::new();
    for h in hypotheses.iter().filter(|h| h.1 >= o.min_overlap) {
        let r = icp(&s, &d, h.0, 2.0 * o.voxel_mm, 30);
        let fit = overlap(&s.points, &dtree, &r.pose, o.voxel_mm / 3.0);
        let c = Candidate {
            pose: r.pose,
            fit,
            rms_mm: r.rms_mm,
        };
        match out
            .iter_mut()
            .find(|c| same_motion(&c.pose, &r.pose, o.voxel_mm))
        {
            Some(kept) if kept.fit >= fit => {}
            Some(kept) => *kept = c,
            None => out.push(c),
        }
    }
    out.sort_by(|a, b| b.fit.total_cmp(&a.fit));
    Ok(out)
}

/// `hint` moved across the plane its rotation keeps (perpendicular to the axis; a turn about an
/// axis of that direction, wherever it stands, moves nothing along it) to where it brings the most
/// of `src` within 1.5 voxels of `dst`: first a grid of 4 voxels over as far as `src` reaches
/// from its centre (points within 3 voxels counted, so that no peak falls between the grid's
/// points), then a grid of 1 voxel around the best. A rotation of under 1° has no axis to speak
/// of and is returned as it is.
fn place_turn(
    src: &Cloud,
    dst: &KdTree<f64, 3>,
    hint: &Isometry3<f64>,
    voxel: f64,
) -> Isometry3<f64> {
    let Some(axis) = hint
        .rotation
        .axis()
        .filter(|_| hint.rotation.angle() > 1f64.to_radians())
    else {
        return *hint;
    };
    let centre = centre(&src.points).coords;
    let reach = src
        .points
        .iter()
        .map(|p| (p.coords - centre).norm())
        .fold(0.0, f64::max);
    let (e1, e2) = across(&axis);
    let sample: Vec<Point3<f64>> = src.points.iter().step_by(4).copied().collect();
    // The best of a (2 half + 1)² grid of `step` around `from`, points within `tol` counted.
    let best_of = |from: Isometry3<f64>, step: f64, half: i32, tol: f64| {
        let mut best = (from, f64::NEG_INFINITY);
        for i in -half..=half {
            for j in -half..=half {
                let shift =
                    Translation3::from(e1 * (f64::from(i) * step) + e2 * (f64::from(j) * step));
                let pose = shift * from;
                let score = overlap(&sample, dst, &pose, tol);
                if score > best.1 {
                    best = (pose, score);
                }
            }
        }
        best.0
    };
    let coarse = 4.0 * voxel;
    let half = (reach / coarse).ceil().min(25.0) as i32;
    let near = best_of(*hint, coarse, half, 3.0 * voxel);
    best_of(near, voxel, 2, 1.5 * voxel)
}

/// Whether two motions differ by under 2° and 2 voxels.
pub(crate) fn same_motion(a: &Isometry3<f64>, b: &Isometry3<f64>, voxel: f64) -> bool {
    let d = a.inverse() * b;
    d.rotation.angle() < 2f64.to_radians() && d.translation.vector.norm() < 2.0 * voxel
}

/// The fine fit of `src` onto `dst` from `init`: point-to-plane ICP pairing at most
/// `FINE_POINTS` of the source (evenly spaced) with the whole target, within a voxel.
///
/// # Errors
/// [`RegisterError::NoOverlap`] when the refined fit covers less than `min_overlap`: a wrong match
/// that happened to score in the coarse stage (two views of opposite sides) is refused here.
pub fn fine(
    src: &Cloud,
    dst: &Cloud,
    init: Isometry3<f64>,
    o: &RegisterOptions,
) -> Result<Registration, RegisterError> {
    let step = src.points.len().div_ceil(FINE_POINTS).max(1);
    let sparse = Cloud {
        points: src.points.iter().step_by(step).copied().collect(),
        normals: src.normals.iter().step_by(step).copied().collect(),
    };
    let fine = icp(&sparse, dst, init, o.voxel_mm, 30);
    if fine.overlap < o.min_overlap {
        return Err(RegisterError::NoOverlap {
            overlap_percent: 100.0 * fine.overlap,
            tolerance_mm: o.voxel_mm / 3.0,
            min_percent: 100.0 * o.min_overlap,
        });
    }
    Ok(fine)
}
