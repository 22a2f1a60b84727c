//! The plausibility check by free space: no view's points may lie in the space another view
//! saw empty ([`crate::depth`]), or one of the two is registered wrongly.

use scanner_core::nalgebra::Isometry3;

use crate::depth::Conflict;
use crate::spatial::Cloud;
use crate::view::View;

/// The largest share of one view's points (those clear of its edges) that may lie in front of
/// what another view saw (by more than [`SEEN_TOL_VOXELS`], among the points that fall on its
/// seen surface): views placed right leave none (the 360° demo's views of the bunny, and pairs of
/// the part's views, merged right), the part's views placed wrongly 2.3–26 % where the check
/// tells at all (docs/reports.md). A merge beyond it is refused.
pub(crate) const SEEN_THROUGH_MAX: f64 = 0.01;

/// How far in front of what another view saw a point must lie to count ([`SEEN_THROUGH_MAX`]),
/// in voxels of the registration: a third of one (1 mm at the default 3 mm), the tolerance of
/// the fits' overlap — ten times the 360° demo's registered points' median error, and a wrong
/// placement that slides a face along another puts tenths of its points beyond it.
const SEEN_TOL_VOXELS: f64 = 1.0 / 3.0;

/// Fewest points of a view that must fall on another's seen surface for their share in front
/// of it to count ([`SEEN_THROUGH_MAX`]).
pub(crate) const SEEN_MIN_TESTED: usize = 50;

/// How far in front of what a view saw another's point must lie to count, mm, for the
/// registration's voxel `voxel_mm`.
pub fn tolerance(voxel_mm: f64) -> f64 {
    SEEN_TOL_VOXELS * voxel_mm
}

/// Whether `c`'s share of points in front is more than a merge accepts.
pub fn seen_through(c: &Conflict) -> bool {
    c.tested >= SEEN_MIN_TESTED && c.in_front as f64 > SEEN_THROUGH_MAX * c.tested as f64
}

/// Every view's points clear of its edges ([`View::clear_cloud`]: those on them lie off the
/// surface, as a stripe cut at an occluding edge does) at `poses` against every other view's
/// free space ([`crate::depth::conflicts`], points more than [`tolerance`] in front): the pair
/// with the largest share in front among those with at least `SEEN_MIN_TESTED` points tested
/// (`None`: no pair has so many).
pub fn free_space(views: &[View], poses: &[Isometry3<f64>], voxel_mm: f64) -> Option<Conflict> {
    let clear: Vec<Cloud> = views.iter().map(View::clear_cloud).collect();
    let clouds: Vec<&Cloud> = clear.iter().collect();
    crate::depth::conflicts(&clouds, poses, tolerance(voxel_mm), |k| {
        views[k].depth_map()
    })
    .into_iter()
    .filter(|c| c.tested >= SEEN_MIN_TESTED)
    .max_by(|a, b| a.share().total_cmp(&b.share()))
}
