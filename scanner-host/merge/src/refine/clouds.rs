//! Joint refinement of all views together (issue 17): registering each view onto one neighbour
//! chains the views, and the small error of each link adds up around the object, so the last view
//! no longer meets the first (the loop does not close). Here all views but view 0 (which fixes
//! the frame) move together: each round pairs every view's points with every other view's
//! surface (point-to-plane) and solves one linear system for all their motions, so the loop's
//! error is spread over all links at once instead of piling up at the last (moving one view at
//! a time, Gauss–Seidel, takes about a round per link: on the seven-view demo eight such rounds
//! left a view 0.28° off, where eight joint rounds end at the poses thirty reach). Pairs far off
//! the others' surface count less (Cauchy's weights on the last round's robust spread of the
//! residuals). Each view's k-d tree is built once in its own frame; a point is paired in every
//! other view within the pairing distance. The merge passes the views' points clear of their
//! edges only ([`crate::view::View::clear_cloud`]).
//!
//! The loop-closure error says how well it worked: a view that also overlaps view 0 directly is
//! registered onto it by ICP from its pose, and the difference between that direct pose and its
//! pose through the chain is the error (before and after the refinement).

use kiddo::KdTree;
use scanner_core::nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Matrix6, Point3, Translation3, Unit, UnitQuaternion,
    Vector3, Vector6,
};

use crate::spatial::{Cloud, across, nearest_within, tree};

/// At most this many points of a view are paired (evenly spaced; the others' trees hold all
/// their points), so that a round costs the same for dense and sparse views.
const MAX_POINTS: usize = 4_000;

/// Cauchy's scale of the pairs' weights in robust spreads of their residuals: a pair that many
/// spreads off its partner's surface pulls half as hard as one on it.
const ROBUST: f64 = 1.0;

/// Least cosine between the normals of a pair (60°).
const MIN_NORMAL_COS: f64 = 0.5;

/// A view's points for the refinement, with its k-d tree in its own frame.
struct Part<'a> {
    cloud: &'a Cloud,
    tree: KdTree<f64, 3>,
    sample: Vec<usize>,
}

impl<'a> Part<'a> {
    fn new(cloud: &'a Cloud) -> Part<'a> {
        let tree = tree(&cloud.points);
        let step = cloud.points.len().div_ceil(MAX_POINTS).max(1);
        Part {
            cloud,
            tree,
            sample: (0..cloud.points.len()).step_by(step).collect(),
        }
    }
}

/// The row of one point-to-plane pair in the normal equations of the views' motions `δ`
/// (rotation vector, translation; `x ↦ x + ω × x + t`, view 0's frame): `q` a point of one view,
/// `pd` and `n` the surface of another it is paired with. The residual `r = (q − pd)·n` changes
/// by `row · δ` with the point's view's motion and by `−row · δ` with the surface's (to first
/// order, the normal's turn included). Returns `(row, r)`.
fn pair_row(q: &Point3<f64>, pd: &Point3<f64>, n: &Vector3<f64>) -> (Vector6<f64>, f64) {
    let c = q.coords.cross(n);
    (Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z), (q - pd).dot(n))
}

/// The nearest point of `part` (at `pose`, inverse `inverse`) to `q` within `max_dist` whose
/// normal is within 60° of `normal`: its position and normal in view 0's frame.
fn partner(
    part: &Part<'_>,
    (pose, inverse): (&Isometry3<f64>, &Isometry3<f64>),
    q: &Point3<f64>,
    normal: &Vector3<f64>,
    max_dist: f64,
) -> Option<(Point3<f64>, Vector3<f64>)> {
    // Searched within the distance only: most points of a view lie far from most other views.
    let (k, _) = nearest_within(&part.tree, &(inverse * q), max_dist)?;
    let n = pose * part.cloud.normals[k];
    // Normals face their cameras, so one surface seen from two views has normals on the same
    // side; a pair across a thin part (the two sides of an ear) has them opposed.
    (n.dot(normal) >= MIN_NORMAL_COS).then(|| (pose * part.cloud.points[k], n))
}

/// What one step of the refinement gives.
struct Step {
    /// The new poses.
    poses: Vec<Isometry3<f64>>,
    /// Robust spread of the pairs' residuals (1.4826 × their median absolute value), mm.
    spread: f64,
    /// The turns, moved with the poses.
    turns: Option<Turns>,
}

/// How near a view's pose must come to a turn about the axis the others share to count as one
/// of the turns ([`Turns::fit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnTolerance {
    /// Its rotation's axis off the shared axis, degrees.
    pub axis_deg: f64,
    /// Its pose's rotation off its turn, degrees.
    pub off_deg: f64,
    /// The axis's point moved by its pose and by its turn apart, mm.
    pub off_mm: f64,
}

/// With a turntable's step (`--turntable`): the registration's poses are within about 0.2°, and
/// by a step's coincidence a view turned over by hand can agree with the step.
pub const GIVEN_STEP: TurnTolerance = TurnTolerance {
    axis_deg: 2.0,
    off_deg: 1.0,
    off_mm: 3.0,
};

/// Views turned about one axis between them (a turntable), view 0 among them: the pose of each
/// is a turn by its own angle about the common axis, so that together they have one axis (its
/// direction and where it stands: 4 unknowns) and an angle each, not 6 unknowns each.
#[derive(Debug, Clone, PartialEq)]
pub struct Turns {
    /// The views turned, besides view 0 (whose angle is 0).
    pub views: Vec<usize>,
    /// The axis.
    pub axis: Unit<Vector3<f64>>,
    /// A point on it (view 0's frame), mm.
    pub point: Point3<f64>,
    /// Each view's angle about the axis, radians (as `views`).
    pub angles: Vec<f64>,
}

impl Turns {
    /// The turns that come nearest to `poses` of the views `on` the turntable (view 0 must be
    /// one). A view flagged on it that is not a turn about the axis the others share is left
    /// out: its rotation's axis or its pose farther from that axis or its turn than `tol`.
    /// `None` when view 0 is not on it or no other view is left.
    pub fn fit(poses: &[Isometry3<f64>], on: &[bool], tol: TurnTolerance) -> Option<Turns> {
        if !on.first().copied().unwrap_or(false) {
            return None;
        }
        let flagged: Vec<usize> = (1..poses.len())
            .filter(|&k| on.get(k) == Some(&true))
            .collect();
        // The axis the most views turned by over 10° share (their axes are well defined).
        let axis_of = |k: usize| {
            let r = poses[k].rotation;
            (r.angle() > 10f64.to_radians()).then(|| r.axis()).flatten()
        };
        let near = |a: &Unit<Vector3<f64>>, b: &Unit<Vector3<f64>>| {
            a.angle(b).min(a.angle(&-*b)) < tol.axis_deg.to_radians()
        };
        let shared = flagged.iter().filter_map(|&r| axis_of(r)).max_by_key(|a| {
            flagged
                .iter()
                .filter(|&&k| axis_of(k).is_some_and(|b| near(a, &b)))
                .count()
        })?;
        let sharing: Vec<usize> = flagged
            .iter()
            .copied()
            .filter(|&k| axis_of(k).is_none_or(|b| near(&shared, &b)))
            .collect();
        let first = Self::fit_views(poses, sharing)?;
        let close: Vec<usize> = first
            .views
            .iter()
            .enumerate()
            .filter(|&(i, &k)| first.within(i, &poses[k], tol))
            .map(|(_, &k)| k)
            .collect();
        Self::fit_views(poses, close)
    }

    /// [`Turns::fit`] of `views` (besides view 0), all of them: the axis the mean of their
    /// rotation axes (each turned to agree with the first), each angle its rotation about that
    /// axis, the point on the axis the least-squares fit of their translations.
    fn fit_views(poses: &[Isometry3<f64>], views: Vec<usize>) -> Option<Turns> {
        let reference = views.iter().find_map(|&k| poses[k].rotation.axis())?;
        let sum = views.iter().fold(Vector3::zeros(), |acc, &k| {
            let r = poses[k].rotation.scaled_axis();
            acc + if r.dot(&reference) < 0.0 { -r } else { r }
        });
        let axis = Unit::try_new(sum, 1e-9)?;
        let angles: Vec<f64> = views
            .iter()
            .map(|&k| {
                let r = poses[k].rotation;
                let (c, s) = (r.w, r.imag().dot(&axis));
                2.0 * s.atan2(c)
            })
            .collect();
        // t_k = (I − R_k) c for a turn about an axis through c: least squares for c, damped
        // along the axis (where no turn says anything).
        let mut m = Matrix3::identity() * 1e-9;
        let mut b = Vector3::zeros();
        for (&k, &a) in views.iter().zip(&angles) {
            let i_r = Matrix3::identity() - turn(&axis, a).to_rotation_matrix().into_inner();
            m += i_r.transpose() * i_r;
            b += i_r.transpose() * poses[k].translation.vector;
        }
        let point = Point3::from(m.try_inverse()? * b);
        Some(Turns {
            views,
            axis,
            point,
            angles,
        })
    }

    /// Whether `pose` is within `tol` of the `i`-th turn (the axis's direction aside).
    pub fn within(&self, i: usize, pose: &Isometry3<f64>, tol: TurnTolerance) -> bool {
        let t = self.pose(i);
        (t.inverse() * pose).rotation.angle() < tol.off_deg.to_radians()
            && (pose * self.point - t * self.point).norm() < tol.off_mm
    }

    /// The pose of the `i`-th of [`Turns::views`].
    pub fn pose(&self, i: usize) -> Isometry3<f64> {
        let r = turn(&self.axis, self.angles[i]);
        Isometry3::from_parts(
            Translation3::from(self.point.coords - r * self.point.coords),
            r,
        )
    }

    /// Two unit directions across the axis.
    fn across(&self) -> (Vector3<f64>, Vector3<f64>) {
        across(&self.axis)
    }
}

/// The turn by `angle` radians about `axis`.
fn turn(axis: &Unit<Vector3<f64>>, angle: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(axis, angle)
}

/// The unknowns of a step with `turns`: in place of each turned view's 6 (its motion, as in
/// [`step`]'s system), the axis's tilt (2), its shift (2) and each turned view's angle, then each
/// untouched view's 6. Returns the matrix `B` that maps them to the views' motions (`δ = B p`).
fn turn_unknowns(turns: &Turns, n: usize) -> DMatrix<f64> {
    let turned: Vec<Option<usize>> = (0..n)
        .map(|k| turns.views.iter().position(|&v| v == k))
        .collect();
    let own = 4 + turns.views.len();
    let mut place = vec![None; n];
    let mut next = own;
    for k in 1..n {
        if turned[k].is_none() {
            place[k] = Some(next);
            next += 6;
        }
    }
    let mut b = DMatrix::<f64>::zeros(6 * (n - 1), next);
    let (e1, e2) = turns.across();
    let (a, c) = (turns.axis.into_inner(), turns.point.coords);
    for k in 1..n {
        let row = 6 * (k - 1);
        if let Some(col) = place[k] {
            b.view_mut((row, col), (6, 6)).fill_with_identity();
            continue;
        }
        let Some(i) = turned[k] else { continue };
        let r = turn(&turns.axis, turns.angles[i])
            .to_rotation_matrix()
            .into_inner();
        let i_r = Matrix3::identity() - r;
        // A motion (ω, t) as x ↦ x + ω × x + t; the axis's point c.
        let mut set = |col: usize, omega: Vector3<f64>, t: Vector3<f64>| {
            b.fixed_view_mut::<3, 1>(row, col).copy_from(&omega);
            b.fixed_view_mut::<3, 1>(row + 3, col).copy_from(&t);
        };
        // The axis tilted by φ (across it): ω = (I − R) φ, t = c × ω.
        for (col, phi) in [(0, e1), (1, e2)] {
            let omega = i_r * phi;
            set(col, omega, c.cross(&omega));
        }
        // The axis shifted by u (across it): t = (I − R) u.
        for (col, u) in [(2, e1), (3, e2)] {
            set(col, Vector3::zeros(), i_r * u);
        }
        // The view turned further by δθ: ω = a, t = c × a.
        set(4 + i, a, c.cross(&a));
    }
    b
}

/// Bins of the residuals' histogram, from 0 to the pairing distance: the median to a 2 000th of
/// it without holding the residuals (a merge of 64 views pairs up to 16 million).
const SPREAD_BINS: usize = 2000;

/// One Gauss–Newton step of all views' poses together (view 0 fixed): every view's sampled
/// points paired with every other view's surface, both ways round, so that each pair of views
/// pulls symmetrically (nearest points on a curved surface lie off each other's tangent planes,
/// always on the same side: one-sided pairs would push the views apart), and one linear system
/// for all motions — the loop's error is spread over all its links at once instead of a link per
/// round. Pairs are weighed by Cauchy's function of their residual over `scale` (infinite: all
/// alike), so that a few points far off the others' surface (a stripe cut at an edge another
/// view saw clear) pull little. A view without pairs stays where it is. `None`: too few pairs.
fn step(
    parts: &[Part<'_>],
    poses: &[Isometry3<f64>],
    turns: Option<&Turns>,
    max_dist: f64,
    scale: f64,
) -> Option<Step> {
    let n = parts.len();
    let inverses: Vec<Isometry3<f64>> = poses.iter().map(Isometry3::inverse).collect();
    // Block of view k in the unknowns (view 0 has none).
    let block = |k: usize| k.checked_sub(1).map(|b| 6 * b);
    let free = 6 * (n - 1);
    let mut ata = DMatrix::<f64>::zeros(free, free);
    let mut atb = DVector::<f64>::zeros(free);
    let mut histogram = vec![0u32; SPREAD_BINS];
    let mut pairs = 0usize;
    for (i, from) in parts.iter().enumerate() {
        for (j, to) in parts.iter().enumerate() {
            if i == j {
                continue;
            }
            let (mut aii, mut bi) = (Matrix6::zeros(), Vector6::zeros());
            for &s in &from.sample {
                let q = poses[i] * from.cloud.points[s];
                let normal = poses[i] * from.cloud.normals[s];
                let Some((pd, nd)) = partner(to, (&poses[j], &inverses[j]), &q, &normal, max_dist)
                else {
                    continue;
                };
                let (row, r) = pair_row(&q, &pd, &nd);
                let w = 1.0 / (1.0 + (r / scale).powi(2));
                aii += row * row.transpose() * w;
                bi += row * (r * w);
                let bin = (r.abs() / max_dist * SPREAD_BINS as f64) as usize;
                histogram[bin.min(SPREAD_BINS - 1)] += 1;
                pairs += 1;
            }
            // The residual moves by row·δi − row·δj: the same block for both views, the
            // opposite off their diagonal.
            for (a, b) in [(block(i), block(i)), (block(j), block(j))] {
                if let (Some(a), Some(b)) = (a, b) {
                    let mut v = ata.fixed_view_mut::<6, 6>(a, b);
                    v += aii;
                }
            }
            if let (Some(a), Some(b)) = (block(i), block(j)) {
                let mut v = ata.fixed_view_mut::<6, 6>(a, b);
                v -= aii;
                let mut v = ata.fixed_view_mut::<6, 6>(b, a);
                v -= aii;
            }
            if let Some(a) = block(i) {
                let mut v = atb.fixed_rows_mut::<6>(a);
                v -= bi;
            }
            if let Some(b) = block(j) {
                let mut v = atb.fixed_rows_mut::<6>(b);
                v += bi;
            }
        }
    }
    if pairs < 6 * n {
        return None;
    }
    // With turns the unknowns are the turns' and the other views' (δ = B p).
    let (x, turns) = match turns {
        None => (solve(ata, &atb)?, None),
        Some(t) => {
            let b = turn_unknowns(t, n);
            let p = solve(b.transpose() * &ata * &b, &(b.transpose() * &atb))?;
            let (e1, e2) = t.across();
            let tilt = e1 * p[0] + e2 * p[1];
            let moved = Turns {
                views: t.views.clone(),
                axis: UnitQuaternion::from_scaled_axis(tilt) * t.axis,
                point: t.point + e1 * p[2] + e2 * p[3],
                angles: t
                    .angles
                    .iter()
                    .zip(p.iter().skip(4))
                    .map(|(a, d)| a + d)
                    .collect(),
            };
            (b * p, Some(moved))
        }
    };
    let mut seen = 0u32;
    let median = histogram
        .iter()
        .position(|&c| {
            seen += c;
            2 * seen as usize >= pairs
        })
        .unwrap_or(SPREAD_BINS - 1);
    let spread = 1.4826 * (median as f64 + 0.5) / SPREAD_BINS as f64 * max_dist;
    let moved = poses
        .iter()
        .enumerate()
        .map(|(k, p)| {
            // A turned view is where its turn puts it; any other moves by its own motion.
            let turned = turns.as_ref().and_then(|t| {
                let i = t.views.iter().position(|&v| v == k)?;
                Some(t.pose(i))
            });
            match (block(k), turned) {
                (None, _) => *p,
                (Some(_), Some(pose)) => pose,
                (Some(b), None) => {
                    let delta = Isometry3::from_parts(
                        Translation3::new(x[b + 3], x[b + 4], x[b + 5]),
                        UnitQuaternion::from_scaled_axis(Vector3::new(x[b], x[b + 1], x[b + 2])),
                    );
                    delta * p
                }
            }
        })
        .collect();
    Some(Step {
        poses: moved,
        spread,
        turns,
    })
}

/// Solves the normal equations `a x = b`. A view with no pair would leave them singular: a touch
/// of damping keeps it put (the others' diagonals are millions).
fn solve(mut a: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    for d in 0..a.nrows() {
        a[(d, d)] += 1e-6;
    }
    Some(a.cholesky()?.solve(b))
}

/// The pairing distance of round `round` of `rounds`: from `max_dist` down to a third of it by
/// the middle round, then kept (wide enough at first to catch the chain's errors, then narrow, so
/// that pairs are near and the tangent planes true).
fn distance(max_dist: f64, round: usize, rounds: usize) -> f64 {
    let half = (rounds / 2).max(1);
    max_dist * (1.0f64 / 3.0).powf(round.min(half) as f64 / half as f64)
}

/// Refines the poses of all views (view 0 stays) by `rounds` rounds of symmetric ICP of each view
/// against all others, pairs within `max_dist` mm at first, a third of it from the middle round
/// on; `progress` sees each finished round.
pub fn refine(
    clouds: &[&Cloud],
    poses: &[Isometry3<f64>],
    max_dist: f64,
    rounds: usize,
    progress: impl FnMut(usize),
) -> Vec<Isometry3<f64>> {
    refine_turns(clouds, poses, None, max_dist, rounds, progress).0
}

/// [`refine`] with the views of `turns` (a turntable's) kept turns about one axis: their axis
/// and angles are refined, not each view's pose. Returns the poses and the turns refined.
pub fn refine_turns(
    clouds: &[&Cloud],
    poses: &[Isometry3<f64>],
    turns: Option<Turns>,
    max_dist: f64,
    rounds: usize,
    progress: impl FnMut(usize),
) -> (Vec<Isometry3<f64>>, Option<Turns>) {
    let parts: Vec<Part<'_>> = clouds.iter().map(|c| Part::new(c)).collect();
    let pairing = |round| distance(max_dist, round, rounds);
    refine_paired(&parts, poses, turns, pairing, rounds, progress)
}

/// [`refine_turns`] with the pairing distance of each round from `pairing`.
fn refine_paired(
    parts: &[Part<'_>],
    poses: &[Isometry3<f64>],
    turns: Option<Turns>,
    pairing: impl Fn(usize) -> f64,
    rounds: usize,
    mut progress: impl FnMut(usize),
) -> (Vec<Isometry3<f64>>, Option<Turns>) {
    let mut poses = poses.to_vec();
    if poses.len() < 2 {
        return (poses, turns);
    }
    let mut turns = turns;
    if let Some(t) = &turns {
        for (i, &k) in t.views.iter().enumerate() {
            poses[k] = t.pose(i);
        }
    }
    // The first round weighs all pairs alike; each later one by the spread of the last.
    let mut scale = f64::INFINITY;
    for round in 0..rounds {
        if let Some(s) = step(parts, &poses, turns.as_ref(), pairing(round), scale) {
            poses = s.poses;
            scale = ROBUST * s.spread;
            turns = s.turns;
        }
        progress(round);
    }
    (poses, turns)
}

/// Without `--turntable`, views count as a turntable's when at least this many besides view 0
/// are turns about one axis within [`FOUND`] ([`found_turns`]).
const FOUND_MIN_VIEWS: usize = 2;

/// How near the jointly refined poses must come to turns about one axis for [`found_turns`] to
/// try them, and the turns refined to the free poses to keep them: on the 360° demo's views the
/// turned views' free poses are within 0.053° and 0.023 mm of their turns, on views turned by
/// uneven steps within 0.083° and 0.043 mm; an object turned by hand on a table slides by a
/// millimetre or more (views slid by 1 mm fit no turns; by 0.2 mm they fit, but refined as turns
/// move by up to 1.4° and agree 66 % worse: refused).
const FOUND: TurnTolerance = TurnTolerance {
    axis_deg: 0.5,
    off_deg: 0.2,
    off_mm: 0.5,
};

/// The views' surfaces may lie this much farther apart ([`surface_gap`]) kept as turns than
/// free for [`found_turns`] to keep the turns (the demo's lie 0.1 % farther, on uneven steps
/// 0.3 %).
const FOUND_SLACK: f64 = 0.01;

/// Rounds of [`found_turns`]'s refinement. It starts from converged poses and pairs as near as
/// the free refinement ends: on six noisy views the worst view was 0.048°, 0.050°, 0.052°,
/// 0.055°, 0.056° after 2, 3, 4, 6, 8 rounds, on the demo's views 0.031°, 0.032°, 0.033°,
/// 0.033°, 0.033° (with [`refine_turns`]'s wide first rounds, which move converged poses away
/// before they bring them back: 0.123° and 0.037° after 2 rounds, 0.058° and 0.032° after 8).
const FOUND_ROUNDS: usize = 3;

/// Turns found without a hint: where the freely refined poses `free` of at least
/// `FOUND_MIN_VIEWS` views besides view 0 are turns about one axis within `FOUND` (the object
/// on a turntable whose step the user did not give), they are refined again as such turns —
/// one axis and an angle each in place of six unknowns each, so that each view's noise is
/// averaged over all of them — pairs as near as [`refine_turns`]'s last rounds with `max_dist`
/// pair them. The turns are
/// kept only where every turned view stays within `FOUND` of its free pose and the views'
/// surfaces agree as well as free (within `FOUND_SLACK`); else `free` is returned as it is.
pub fn found_turns(
    clouds: &[&Cloud],
    free: Vec<Isometry3<f64>>,
    max_dist: f64,
) -> (Vec<Isometry3<f64>>, Option<Turns>) {
    let all = vec![true; free.len()];
    let Some(turns) = Turns::fit(&free, &all, FOUND).filter(|t| t.views.len() >= FOUND_MIN_VIEWS)
    else {
        return (free, None);
    };
    // From converged poses: pairs as near as the free refinement's last rounds from the first.
    let narrow = |_| distance(max_dist, usize::MAX, FOUND_ROUNDS);
    let parts: Vec<Part<'_>> = clouds.iter().map(|c| Part::new(c)).collect();
    let (turned, Some(t)) = refine_paired(&parts, &free, Some(turns), narrow, FOUND_ROUNDS, |_| {})
    else {
        return (free, None);
    };
    let stays = t
        .views
        .iter()
        .enumerate()
        .all(|(i, &k)| t.within(i, &free[k], FOUND));
    let agree = match (agreement(&parts, &free), agreement(&parts, &turned)) {
        (Some(a), Some(b)) => b <= a * (1.0 + FOUND_SLACK),
        _ => false,
    };
    if stays && agree {
        (turned, Some(t))
    } else {
        (free, None)
    }
}

/// Pairs of points of two views this near count in [`surface_gap`], mm.
pub(crate) const AGREE_MM: f64 = 1.0;

/// How far the views' surfaces lie apart where they overlap: the RMS distance of each view's
/// points (at most [`MAX_POINTS`], evenly spaced) from the tangent plane of the nearest point of
/// every other view within [`AGREE_MM`], the views placed by `poses`; `None` where no view
/// overlaps another.
pub(crate) fn surface_gap(clouds: &[&Cloud], poses: &[Isometry3<f64>]) -> Option<f64> {
    let parts: Vec<Part<'_>> = clouds.iter().map(|c| Part::new(c)).collect();
    agreement(&parts, poses)
}

/// [`surface_gap`] of the views' parts.
fn agreement(parts: &[Part<'_>], poses: &[Isometry3<f64>]) -> Option<f64> {
    let inverses: Vec<Isometry3<f64>> = poses.iter().map(Isometry3::inverse).collect();
    let (mut sum2, mut pairs) = (0.0, 0usize);
    for (j, dst) in parts.iter().enumerate() {
        for (k, src) in parts.iter().enumerate().filter(|(k, _)| *k != j) {
            for &s in &src.sample {
                let q = poses[k] * src.cloud.points[s];
                let local = inverses[j] * q;
                let Some((i, _)) = nearest_within(&dst.tree, &local, AGREE_MM) else {
                    continue;
                };
                sum2 += (local - dst.cloud.points[i])
                    .dot(&dst.cloud.normals[i])
                    .powi(2);
                pairs += 1;
            }
        }
    }
    (pairs > 0).then(|| (sum2 / pairs as f64).sqrt())
}

/// How far a loop of views is from closing.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LoopError {
    /// The view whose direct registration onto [`LoopError::onto`] was compared with its pose.
    pub view: usize,
    /// The view it was registered onto directly.
    pub onto: usize,
    /// Rotation between the two, degrees.
    pub rotation_deg: f64,
    /// Translation between the two, mm.
    pub translation_mm: f64,
}

/// The worst loop-closure error over `pairs` (view, onto) that the poses do not link directly
/// (each pair closes a loop of views): the view is registered onto the other alone by the same
/// symmetric ICP, from where their poses put it, and compared with that; a pair with fewer than
/// `min_overlap` of the view's points paired at the end closes no loop. `None` when no pair does.
pub fn loop_error(
    clouds: &[&Cloud],
    poses: &[Isometry3<f64>],
    pairs: &[(usize, usize)],
    max_dist: f64,
    min_overlap: f64,
) -> Option<LoopError> {
    const ROUNDS: usize = 16;
    let mut worst: Option<LoopError> = None;
    for &(k, j) in pairs {
        let (cloud, start) = (clouds[k], poses[j].inverse() * poses[k]);
        let pair = [Part::new(clouds[j]), Part::new(cloud)];
        let mut both = [Isometry3::identity(), start];
        let mut scale = f64::INFINITY;
        for round in 0..ROUNDS {
            match step(&pair, &both, None, distance(max_dist, round, ROUNDS), scale) {
                Some(s) => {
                    both = [s.poses[0], s.poses[1]];
                    scale = ROBUST * s.spread;
                }
                None => break,
            }
        }
        let d = distance(max_dist, ROUNDS, ROUNDS);
        let paired = pair[1]
            .sample
            .iter()
            .filter(|&&s| {
                let q = both[1] * cloud.points[s];
                let n = both[1] * cloud.normals[s];
                partner(&pair[0], (&both[0], &both[0]), &q, &n, d).is_some()
            })
            .count();
        if (paired as f64) < min_overlap * pair[1].sample.len() as f64 {
            continue;
        }
        let e = start.inverse() * (both[0].inverse() * both[1]);
        let e = LoopError {
            view: k,
            onto: j,
            rotation_deg: e.rotation.angle().to_degrees(),
            translation_mm: e.translation.vector.norm(),
        };
        if worst.is_none_or(|w| e.rotation_deg > w.rotation_deg) {
            worst = Some(e);
        }
    }
    worst
}
