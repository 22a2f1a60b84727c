//! Views posed by the disc must not contradict each other's free space, and the disc must be
//! the size its poses were computed for.

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

/// Farthest the disc's measured size may lie from the size chosen, as a share (the disc's pose
/// and the laser agree within about 0.5 % on the rig; a disc of the other paper is 31 % off).
pub const DISC_SIZE_TOLERANCE: f64 = 0.03;

/// The disc-posed views' median measure of the disc's size ([`View::disc_scale`]), with the
/// views that measured it; `None` when none did.
pub(crate) fn scale(views: &[View]) -> Option<(f64, Vec<usize>)> {
    let measured: Vec<(usize, f64)> = views
        .iter()
        .enumerate()
        .filter(|(_, v)| v.disc.is_some())
        .filter_map(|(k, v)| Some((k, v.disc_scale?)))
        .collect();
    if measured.is_empty() {
        return None;
    }
    let mut s: Vec<f64> = measured.iter().map(|m| m.1).collect();
    s.sort_by(f64::total_cmp);
    Some((s[s.len() / 2], measured.iter().map(|m| m.0).collect()))
}

/// The disc's size check.
///
/// # Errors
/// [`MergeError::DiscSize`] when the laser measures the disc more than
/// [`DISC_SIZE_TOLERANCE`] off the size chosen.
pub(super) fn check_size(views: &[View]) -> Result<(), MergeError> {
    match scale(views) {
        Some((measured, views)) if (measured - 1.0).abs() > DISC_SIZE_TOLERANCE => {
            Err(MergeError::DiscSize { measured, views })
        }
        _ => Ok(()),
    }
}
