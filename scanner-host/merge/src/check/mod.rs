//! The third stage: the plausibility checks of the registered views, before anything is fused.
//! Each refuses the merge (no model is written) with the views and figures that failed it:
//! views posed by the disc that see through each other (`disc`: the object moved on it), loops
//! of views that do not close (`loops`), points where another view saw empty space
//! (`free_space`).

pub(crate) mod disc;
mod free_space;
mod loops;

use crate::depth::Conflict;
use crate::error::MergeError;
use crate::pose::Source;
use crate::refine::Closure;
use crate::view::View;

/// Every check of views registered with poses from `source`: `closure` is the joint
/// refinement's loop closure, `worst` the free-space measure's worst pair, `voxel_mm` the
/// registration's voxel.
///
/// # Errors
/// The first refusal: [`MergeError::DiscSize`], [`MergeError::DiscMoved`], [`MergeError::LoopOpen`],
/// [`MergeError::SeenThrough`].
pub(crate) fn registered(
    views: &[View],
    source: Source,
    closure: &Closure,
    worst: Option<Conflict>,
    voxel_mm: f64,
) -> Result<(), MergeError> {
    if source == Source::Disc {
        disc::check_size(views)?;
        disc::check(views, worst.as_ref())?;
    }
    loops::check_closure(closure, voxel_mm)?;
    free_space::check_free_space(worst, views, voxel_mm)
}
