//! Views posed by the turntable disc: a view whose head found the printed disc in its reference
//! frame carries the disc's pose (disc → camera); the object stands still on the disc, so two
//! such views are related by their disc poses alone, whatever the object's shape (a vase, a
//! cylinder). Views without a disc pose (the object laid on its side, the disc hidden) are
//! registered by geometry onto all the disc-posed views at once, as one cloud.

use kiddo::{KdTree, SquaredEuclidean};
use scanner_core::nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::error::MergeError;
use crate::pose::ViewResult;
use crate::pose::{RegisterOptions, Registration, icp, icp_facing};
use crate::spatial::{Cloud, thin};
use crate::view::View;

/// One view of a merge posed by the turntable disc.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DiscView {
    /// The view.
    pub view: usize,
    /// Whether the disc posed it (`false`: registered by its shape onto the disc-posed views).
    pub by_disc: bool,
    /// For a disc-posed view: the share of its points (clear of its edges) within the fits'
    /// tolerance of the other disc-posed views' (`None` for the others).
    pub agreement: Option<f64>,
}

/// How many views carry a disc pose.
pub(crate) fn carried(views: &[View]) -> usize {
    views.iter().filter(|v| v.disc.is_some()).count()
}

/// The views' poses in view 0's frame: the disc-posed views from their disc poses, the others
/// registered onto them by geometry. `progress` gets the pairs registered and the pairs in all.
///
/// # Errors
/// A view without a disc pose that matches none of the others, or fits it in two places;
/// [`MergeError::TooFewViews`] when fewer than two views carry a disc pose (the disc is not
/// chosen then, [`crate::pose::Source::choose`]).
pub(crate) fn disc_poses(
    views: &[View],
    o: &RegisterOptions,
    progress: impl FnMut(usize, usize),
) -> Result<Vec<ViewResult>, MergeError> {
    let posed: Vec<usize> = (0..views.len())
        .filter(|&k| views[k].disc.is_some())
        .collect();
    let (&[anchor, _, ..], Some(da)) = (&posed[..], posed.first().and_then(|&k| views[k].disc))
    else {
        return Err(MergeError::TooFewViews(posed.len()));
    };
    // Each view's pose in the anchor's camera frame.
    let mut in_anchor: Vec<Option<Isometry3<f64>>> = views
        .iter()
        .map(|v| v.disc.map(|d| da * d.inverse()))
        .collect();
    let rest: Vec<usize> = (0..views.len())
        .filter(|&k| in_anchor[k].is_none())
        .collect();
    let mut fits = vec![None; views.len()];
    if !rest.is_empty() {
        let mut group = Cloud::default();
        for &k in &posed {
            let Some(p) = in_anchor[k] else { continue };
            let c = views[k].clear_cloud();
            group.points.extend(c.points.iter().map(|q| p * q));
            group
                .normals
                .extend(c.normals.iter().map(|n| p.rotation * n));
        }
        let group = thin(&group, 0.75);
        let tree = crate::spatial::tree(&group.points);
        let mut progress = progress;
        // The disc-posed views and their poses, for the free-space test of each fit.
        let mut subset: Vec<View> = posed.iter().map(|&k| views[k].clone()).collect();
        let mut at: Vec<Isometry3<f64>> = posed.iter().filter_map(|&k| in_anchor[k]).collect();
        for (i, &k) in rest.iter().enumerate() {
            let cloud = views[k].clear_cloud();
            subset.push(views[k].clone());
            // The fits that overlap enough and keep out of what the disc-posed views saw empty,
            // best first.
            let tries = onto_group(&cloud, &group, &tree, o);
            let plausible: Vec<Registration> = tries
                .iter()
                .filter(|f| f.overlap >= o.min_overlap)
                .filter(|f| {
                    at.push(f.pose);
                    let worst = crate::free::free_space(&subset, &at, o.voxel_mm);
                    at.pop();
                    !worst.is_some_and(|c| crate::free::seen_through(&c))
                })
                .copied()
                .collect();
            subset.pop();
            let Some(best) = plausible.first() else {
                if let Some(t) = tries.first().filter(|t| t.overlap >= o.min_overlap) {
                    return Err(MergeError::ShapeNowhere {
                        view: k,
                        name: views[k].name.clone(),
                        overlap: t.overlap,
                    });
                }
                return Err(MergeError::NoMatch {
                    view: k,
                    name: views[k].name.clone(),
                    best: crate::error::RegisterError::NoOverlap {
                        overlap_percent: 100.0 * tries.first().map_or(0.0, |b| b.overlap),
                        tolerance_mm: o.voxel_mm / 3.0,
                        min_percent: 100.0 * o.min_overlap,
                    },
                });
            };
            // Another fit nearly as good that puts the view's surface elsewhere: its shape does
            // not tell where it goes (a fit that lays the surface where the best does, turned
            // about a symmetric object's axis, is the same model).
            if let Some(rival) = plausible[1..].iter().find(|r| {
                r.overlap >= RIVAL_SHARE * best.overlap
                    && !same_surface(&cloud, &best.pose, &r.pose, o.voxel_mm / 3.0)
            }) {
                return Err(MergeError::ShapeAmbiguous {
                    view: k,
                    name: views[k].name.clone(),
                    best: best.overlap,
                    rival: rival.overlap,
                });
            }
            in_anchor[k] = Some(best.pose);
            fits[k] = Some(*best);
            progress(i + 1, rest.len());
        }
    }
    let to0 = in_anchor[0].unwrap_or_else(Isometry3::identity).inverse();
    Ok((0..views.len())
        .map(|k| ViewResult {
            pose: to0 * in_anchor[k].unwrap_or_else(Isometry3::identity),
            onto: (k != anchor).then_some(anchor),
            fit: fits[k],
            agrees: Vec::new(),
            points: views[k].cloud.points.len(),
            on_turntable: false,
            turn_deg: None,
        })
        .collect())
}

/// The report's disc section: per view whether the disc posed it and, for those it posed, the
/// share of its points (clear of its edges) within the fits' tolerance of the other disc-posed
/// views' at `poses`.
pub(crate) fn report(views: &[View], poses: &[Isometry3<f64>], voxel_mm: f64) -> Vec<DiscView> {
    let clear: Vec<Cloud> = views
        .iter()
        .zip(poses)
        .map(|(v, p)| {
            let c = v.clear_cloud();
            Cloud {
                points: c.points.iter().map(|q| p * q).collect(),
                normals: c.normals.iter().map(|n| p.rotation * n).collect(),
            }
        })
        .collect();
    (0..views.len())
        .map(|k| {
            let others: Vec<Point3<f64>> = (0..views.len())
                .filter(|&j| j != k && views[j].disc.is_some())
                .flat_map(|j| clear[j].points.iter().copied())
                .collect();
            let agree = (views[k].disc.is_some() && !others.is_empty()).then(|| {
                overlap(
                    &clear[k],
                    &crate::spatial::tree(&others),
                    &Isometry3::identity(),
                    voxel_mm / 3.0,
                )
            });
            DiscView {
                view: k,
                by_disc: views[k].disc.is_some(),
                agreement: agree,
            }
        })
        .collect()
}

/// Axes and angles of the rotations a view is tried at against the disc-posed views: axes
/// spread evenly over the sphere, turns about each in even steps; every rotation lies within
/// about 20° of one of them, which the fit's wide first rounds close.
const SEARCH: (usize, usize) = (96, 18);

/// Points of a view the search fits (evenly spaced); the best few are then fitted with all.
const SEARCH_POINTS: usize = 300;

/// A second fit with at least this share of the best's overlap that lays the view's surface
/// elsewhere leaves the view's place undecided.
const RIVAL_SHARE: f64 = 0.85;

/// Least cosine between paired points' normals in the final fit: the surface the object stood
/// on, which only the view without the disc saw, pulls on nothing.
const FACING: f64 = 0.5;

/// Distinct fits of the search tried with all points.
const FINALISTS: usize = 8;

/// The view `cloud` fitted onto `group` (every disc-posed view in one frame, `tree` its k-d
/// tree) by trying it at rotations all round ([`SEARCH`]), its centre on the group's, each
/// refined by point-to-plane ICP from a wide pairing distance; the best few distinct fits by
/// overlap refined with all its points, best first. The group is the whole object seen from all
/// round, so the right pose overlaps it well whatever the object's symmetry; the free space
/// decides between fits that overlap alike.
fn onto_group(
    cloud: &Cloud,
    group: &Cloud,
    tree: &KdTree<f64, 3>,
    o: &RegisterOptions,
) -> Vec<Registration> {
    if cloud.points.len() < 6 || group.points.len() < 6 {
        return Vec::new();
    }
    let step = cloud.points.len().div_ceil(SEARCH_POINTS).max(1);
    let sparse = Cloud {
        points: cloud.points.iter().step_by(step).copied().collect(),
        normals: cloud.normals.iter().step_by(step).copied().collect(),
    };
    let (c, g) = (
        crate::spatial::centre(&sparse.points),
        crate::spatial::centre(&group.points),
    );
    let wide = 5.0 * o.voxel_mm;
    let mut tried: Vec<Registration> = rotations()
        .into_iter()
        .map(|r| {
            let start = Isometry3::from_parts(Translation3::from(g.coords - r * c.coords), r);
            let fit = icp(&sparse, group, start, wide, 20);
            Registration {
                overlap: overlap(&sparse, tree, &fit.pose, o.voxel_mm / 3.0),
                ..fit
            }
        })
        .collect();
    tried.sort_by(|a, b| b.overlap.total_cmp(&a.overlap));
    // Many starts end in the same fit: the finalists are distinct ones.
    let mut distinct: Vec<&Registration> = Vec::new();
    for t in &tried {
        if distinct.len() == FINALISTS {
            break;
        }
        if !distinct
            .iter()
            .any(|d| crate::pose::register::same_motion(&d.pose, &t.pose, o.voxel_mm))
        {
            distinct.push(t);
        }
    }
    let mut finalists: Vec<Registration> = distinct
        .iter()
        .map(|t| {
            let fit = icp_facing(cloud, group, t.pose, o.voxel_mm, 30, FACING);
            Registration {
                overlap: overlap(cloud, tree, &fit.pose, o.voxel_mm / 3.0),
                ..fit
            }
        })
        .collect();
    finalists.sort_by(|a, b| b.overlap.total_cmp(&a.overlap));
    finalists
}

/// Whether `cloud` at `a` and at `b` lies on the same surface: nine in ten of its points at `b`
/// within `tol` of its points at `a`.
fn same_surface(cloud: &Cloud, a: &Isometry3<f64>, b: &Isometry3<f64>, tol: f64) -> bool {
    let at_a: Vec<Point3<f64>> = cloud.points.iter().map(|p| a * p).collect();
    overlap(cloud, &crate::spatial::tree(&at_a), b, tol) >= 0.9
}

/// The share of `cloud`'s points that `pose` brings within `tol` of the tree's.
fn overlap(cloud: &Cloud, tree: &KdTree<f64, 3>, pose: &Isometry3<f64>, tol: f64) -> f64 {
    let near = cloud
        .points
        .iter()
        .filter(|p| {
            let q = pose * *p;
            tree.nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z])
                .distance
                <= tol * tol
        })
        .count();
    near as f64 / cloud.points.len().max(1) as f64
}

/// The search's rotations: the identity, then [`SEARCH`]'s axes (a Fibonacci sphere) and turns.
fn rotations() -> Vec<UnitQuaternion<f64>> {
    let (axes, turns) = SEARCH;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut out = vec![UnitQuaternion::identity()];
    for i in 0..axes {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / axes as f64;
        let r = (1.0 - z * z).sqrt();
        let a = golden * i as f64;
        let axis = Unit::new_normalize(Vector3::new(r * a.cos(), r * a.sin(), z));
        for t in 1..turns {
            let angle = std::f64::consts::TAU * t as f64 / turns as f64;
            // An axis and its opposite give the same turns the other way round: the lower
            // half of the sphere turns only up to half a turn.
            if z < 0.0 && angle > std::f64::consts::PI {
                continue;
            }
            out.push(UnitQuaternion::from_axis_angle(&axis, angle));
        }
    }
    out
}
