//! Views posed by the disc must not contradict each other's free space.

use crate::depth::Conflict;
use crate::error::MergeError;
use crate::free::seen_through;
use crate::view::View;

/// The disc's plausibility check: two disc-posed views whose points contradict each other's
/// free space (`worst`, the free-space check's worst pair) mean that the object moved on the
/// disc between sweeps, or that a disc was misread.
///
/// # Errors
/// [`MergeError::DiscMoved`] naming the view.
pub(super) fn check(views: &[View], worst: Option<&Conflict>) -> Result<(), MergeError> {
    match worst {
        Some(c)
            if seen_through(c)
                && views[c.view].disc.is_some()
                && views[c.seen_by].disc.is_some() =>
        {
            Err(MergeError::DiscMoved {
                view: c.view,
                name: views[c.view].name.clone(),
                seen_by: c.seen_by,
                share: c.share(),
            })
        }
        _ => Ok(()),
    }
}
