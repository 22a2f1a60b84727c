//! Joint refinement of all views together (issue 17): registering each view onto one neighbour
//! chains the views, and the small error of each link adds up around the object, so the last view
//! no longer meets the first (the loop does not close). Here every view except view 0 (which fixes
//! the frame) is moved in turn by point-to-plane ICP against *all* other views at their current
//! poses, round after round (Gauss–Seidel), so the loop's error is spread over all links instead
//! of piling up at the last. Each view's k-d tree is built once in its own frame; a point is
//! paired in every other view within the pairing distance.
//!
//! The loop-closure error says how well it worked: a view that also overlaps view 0 directly is
//! registered onto it by ICP from its pose, and the difference between that direct pose and its
//! pose through the chain is the error (before and after the refinement).

use kiddo::{KdTree, SquaredEuclidean};
use scanner_core::nalgebra::{
    Isometry3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6,
};

use crate::register::Cloud;

/// At most this many points of a view are paired (evenly spaced; the others' trees hold all
/// their points), so that a round costs the same for dense and sparse views.
pub const MAX_POINTS: usize = 4_000;

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
        let tree = crate::register::tree(&cloud.points);
        let step = cloud.points.len().div_ceil(MAX_POINTS).max(1);
        Part {
            cloud,
            tree,
            sample: (0..cloud.points.len()).step_by(step).collect(),
        }
    }
}

/// Adds one point-to-plane pair to the normal equations of a view's motion `δ` (rotation vector,
/// translation; `x ↦ x + ω × x + t`, view 0's frame): `q` a point that moves with the view, `pd`
/// and `n` the fixed surface it is paired with; or (`moves_surface`) `q` fixed and the surface
/// moving with the view. Returns the squared residual `((q − pd)·n)²`.
///
/// Taking both kinds for each view makes every pair of views pull symmetrically: nearest points
/// on a curved surface lie off each other's tangent planes, always on the same side, and
/// one-sided pairs would push each view outward against the others, round after round.
fn add_pair(
    q: &Point3<f64>,
    pd: &Point3<f64>,
    n: &Vector3<f64>,
    moves_surface: bool,
    (ata, atb): (&mut Matrix6<f64>, &mut Vector6<f64>),
) -> f64 {
    let r = (q - pd).dot(n);
    // d r / d(ω, t): [q × n, n] when q moves; −[q × n, n] when the surface moves (to first
    // order, the normal's turn included).
    let c = q.coords.cross(n);
    let mut row = Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
    if moves_surface {
        row = -row;
    }
    *ata += row * row.transpose();
    *atb -= row * r;
    r * r
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
    let local = inverse * q;
    // Searched within the distance only: most points of a view lie far from most other views,
    // and an unbounded nearest-point search from far away visits much of the tree.
    let nn = part.tree.nearest_n_within::<SquaredEuclidean>(
        &[local.x, local.y, local.z],
        max_dist * max_dist,
        std::num::NonZero::<usize>::MIN,
        false,
    );
    let k = nn.first()?.item as usize;
    let n = pose * part.cloud.normals[k];
    // Normals face their cameras, so one surface seen from two views has normals on the same
    // side; a pair across a thin part (the two sides of an ear) has them opposed.
    (n.dot(normal) >= MIN_NORMAL_COS).then(|| (pose * part.cloud.points[k], n))
}

/// One ICP step of view `i` against every other view at `poses`: view `i`'s points paired with
/// the others' surfaces and theirs with view `i`'s. Returns the new pose and the RMS residual of
/// its pairs (`None`: too few pairs).
fn step(
    parts: &[Part<'_>],
    poses: &[Isometry3<f64>],
    i: usize,
    max_dist: f64,
) -> Option<(Isometry3<f64>, f64)> {
    let (mut ata, mut atb) = (Matrix6::zeros(), Vector6::zeros());
    let (mut sum2, mut pairs) = (0.0, 0usize);
    let inverses: Vec<Isometry3<f64>> = poses.iter().map(Isometry3::inverse).collect();
    for (j, part) in parts.iter().enumerate().filter(|(j, _)| *j != i) {
        let sides = [
            (
                &parts[i],
                part,
                (&poses[i], (&poses[j], &inverses[j])),
                false,
            ),
            (
                part,
                &parts[i],
                (&poses[j], (&poses[i], &inverses[i])),
                true,
            ),
        ];
        for (from, to, (from_pose, to_pose), moves_surface) in sides {
            for &s in &from.sample {
                let q = from_pose * from.cloud.points[s];
                let normal = from_pose * from.cloud.normals[s];
                if let Some((pd, n)) = partner(to, to_pose, &q, &normal, max_dist) {
                    sum2 += add_pair(&q, &pd, &n, moves_surface, (&mut ata, &mut atb));
                    pairs += 1;
                }
            }
        }
    }
    if pairs < 6 {
        return None;
    }
    let x = ata.cholesky()?.solve(&atb);
    let delta = Isometry3::from_parts(
        Translation3::new(x[3], x[4], x[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(x[0], x[1], x[2])),
    );
    Some((delta * poses[i], (sum2 / pairs as f64).sqrt()))
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
    mut progress: impl FnMut(usize),
) -> Vec<Isometry3<f64>> {
    let parts: Vec<Part<'_>> = clouds.iter().map(|c| Part::new(c)).collect();
    let mut poses = poses.to_vec();
    for round in 0..rounds {
        let d = distance(max_dist, round, rounds);
        for i in 1..poses.len() {
            if let Some((pose, _)) = step(&parts, &poses, i, d) {
                poses[i] = pose;
            }
        }
        progress(round);
    }
    poses
}

/// How far a loop of views is from closing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopError {
    /// The view whose direct registration onto view 0 was compared with its pose.
    pub view: usize,
    /// Rotation between the two, degrees.
    pub rotation_deg: f64,
    /// Translation between the two, mm.
    pub translation_mm: f64,
}

/// The worst loop-closure error over the views (other than `skip`, those registered onto view 0
/// already) that overlap view 0 directly: each is registered onto view 0 alone by the same
/// symmetric ICP, from its pose, and compared with that pose; a view with fewer than
/// `min_overlap` of its points paired with view 0 at the end closes no loop. `None` when no view
/// does.
pub fn loop_error(
    clouds: &[&Cloud],
    poses: &[Isometry3<f64>],
    skip: &[usize],
    max_dist: f64,
    min_overlap: f64,
) -> Option<LoopError> {
    const ROUNDS: usize = 16;
    let mut worst: Option<LoopError> = None;
    for (k, (cloud, pose)) in clouds.iter().zip(poses).enumerate().skip(1) {
        if skip.contains(&k) {
            continue;
        }
        let pair = [Part::new(clouds[0]), Part::new(cloud)];
        let mut both = [Isometry3::identity(), *pose];
        for round in 0..ROUNDS {
            match step(&pair, &both, 1, distance(max_dist, round, ROUNDS)) {
                Some((p, _)) => both[1] = p,
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
        let e = pose.inverse() * both[1];
        let e = LoopError {
            view: k,
            rotation_deg: e.rotation.angle().to_degrees(),
            translation_mm: e.translation.vector.norm(),
        };
        if worst.is_none_or(|w| e.rotation_deg > w.rotation_deg) {
            worst = Some(e);
        }
    }
    worst
}
