//! Views posed by the turntable disc: a view whose head found the printed disc in its reference
//! frame carries the disc's pose (disc → camera); the object stands still on the disc, so two
//! such views are related by their disc poses alone, whatever the object's shape (a vase, a
//! cylinder). Views without a disc pose (the object laid on its side, the disc hidden) are
//! registered by geometry onto all the disc-posed views at once, as one cloud.

use scanner_core::nalgebra::Isometry3;

use crate::error::MergeError;
use crate::poses::{Unplaced, ViewResult, register_clouds};
use crate::register::RegisterOptions;
use crate::spatial::{Cloud, thin};
use crate::view::View;

/// Most a disc-posed view may move in the joint refinement, degrees and mm: beyond, the object
/// moved on the disc between sweeps (or the disc was misread) and the disc's pose is not its.
pub(crate) const MAX_MOVE: (f64, f64) = (0.5, 2.0);

/// The views' poses in view 0's frame when at least two carry a disc pose (`None` otherwise):
/// the disc-posed views from their disc poses, the others registered onto them by geometry.
/// `progress` gets the pairs registered and the pairs in all.
///
/// # Errors
/// A view without a disc pose that matches none of the others.
pub(crate) fn disc_poses(
    views: &[View],
    o: &RegisterOptions,
    progress: impl FnMut(usize, usize),
) -> Option<Result<Vec<ViewResult>, MergeError>> {
    let posed: Vec<usize> = (0..views.len())
        .filter(|&k| views[k].disc.is_some())
        .collect();
    let &anchor = posed.first()?;
    if posed.len() < 2 {
        return None;
    }
    let da = views[anchor].disc?;
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
            let p = in_anchor[k]?;
            let c = &views[k].cloud;
            group.points.extend(c.points.iter().map(|q| p * q));
            group
                .normals
                .extend(c.normals.iter().map(|n| p.rotation * n));
        }
        let group = thin(&group, 0.75);
        let mut clouds: Vec<&Cloud> = vec![&group];
        clouds.extend(rest.iter().map(|&k| &views[k].cloud));
        let placed = register_clouds(&clouds, o, |_, _| Vec::new(), |_| None, progress);
        let placed = match placed {
            Ok(p) => p,
            Err(e) => return Some(Err(unplaced(views, &rest, &posed, e))),
        };
        for (i, &k) in rest.iter().enumerate() {
            in_anchor[k] = Some(placed[i + 1].pose);
            fits[k] = placed[i + 1].fit;
        }
    }
    let to0 = in_anchor[0]?.inverse();
    Some(Ok((0..views.len())
        .map(|k| ViewResult {
            pose: to0 * in_anchor[k].unwrap_or_else(Isometry3::identity),
            onto: (k != anchor).then_some(anchor),
            fit: fits[k],
            agrees: Vec::new(),
            points: views[k].cloud.points.len(),
            on_turntable: false,
            turn_deg: None,
        })
        .collect()))
}

/// The registration's failure for the views without a disc pose, in the views' numbers.
fn unplaced(views: &[View], rest: &[usize], posed: &[usize], e: Unplaced) -> MergeError {
    let view = |i: usize| if i == 0 { posed[0] } else { rest[i - 1] };
    match e {
        Unplaced::NoMatch { view: i, best } => MergeError::NoMatch {
            view: view(i),
            name: views[view(i)].name.clone(),
            best,
        },
        Unplaced::Apart { apart, .. } => MergeError::Apart {
            placed: posed.to_vec(),
            apart: apart.into_iter().map(view).collect(),
        },
    }
}

/// How far the joint refinement moved each disc-posed view from its disc pose: degrees and mm
/// (`None` for views without a disc pose).
pub(crate) fn moved(
    views: &[View],
    before: &[ViewResult],
    after: &[ViewResult],
) -> Vec<Option<(f64, f64)>> {
    views
        .iter()
        .zip(before.iter().zip(after))
        .map(|(v, (b, a))| {
            v.disc.map(|_| {
                let d = b.pose.inverse() * a.pose;
                let c = v.centre();
                (d.rotation.angle().to_degrees(), (d * c - c).norm())
            })
        })
        .collect()
}
