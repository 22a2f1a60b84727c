//! The second stage: all views refined together from the poses the first found (`clouds`: the
//! joint refinement of point clouds),
//! and the loop-closure check of the result; the laser sheet's thickness where the views agree
//! best.

mod clouds;

pub(crate) use clouds::{AGREE_MM, surface_gap};
pub use clouds::{
    GIVEN_STEP, LoopError, TurnTolerance, Turns, found_turns, loop_error, refine, refine_turns,
};

use scanner_core::nalgebra::Isometry3;

use crate::pose::RegisterOptions;
use crate::pose::ViewResult;
use crate::spatial::Cloud;
use crate::view::View;

/// The loop closure before and after `refine_views`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Closure {
    /// Pairs of views checked: those that close loops ([`ViewResult::agrees`]).
    pub pairs: usize,
    /// The worst of them before the joint refinement (`None`: no pair overlaps enough to tell).
    pub before: Option<LoopError>,
    /// After it.
    pub after: Option<LoopError>,
}

/// Rounds of the joint refinement.
pub(crate) const ROUNDS: usize = 8;

/// Refines all views' poses together ([`crate::refine::clouds`]) from those [`crate::pose::register_views`] found,
/// pairs within `voxel_mm`; returns the loop closure before and after, over the pairs of views
/// that agree without one registered onto the other ([`ViewResult::agrees`]).
pub(crate) fn refine_views(
    views: &[View],
    results: &mut [ViewResult],
    o: &RegisterOptions,
    progress: impl FnMut(usize),
) -> Closure {
    use crate::refine::{loop_error, refine_turns};
    // Points on a view's edges lie off the surface, all the same way: they would pull the views
    // apart.
    let clear: Vec<Cloud> = views.iter().map(View::clear_cloud).collect();
    let clouds: Vec<&Cloud> = clear.iter().collect();
    let poses: Vec<Isometry3<f64>> = results.iter().map(|r| r.pose).collect();
    // Pairs of views that agree but were not registered one onto the other close loops.
    let loops: Vec<(usize, usize)> = results
        .iter()
        .enumerate()
        .flat_map(|(k, r)| {
            r.agrees
                .iter()
                .filter(move |&&j| j < k)
                .map(move |&j| (k, j))
        })
        .collect();
    let closure = |p: &[Isometry3<f64>]| loop_error(&clouds, p, &loops, o.voxel_mm, o.min_overlap);
    let before = closure(&poses);
    // Views on a turntable (view 0 among them) stay turns about one axis.
    let on: Vec<bool> = results.iter().map(|r| r.on_turntable).collect();
    let hinted = crate::refine::Turns::fit(&poses, &on, crate::refine::GIVEN_STEP);
    let (joint, turns) = if hinted.is_some() {
        refine_turns(&clouds, &poses, hinted, o.voxel_mm, ROUNDS, progress)
    } else {
        let free = refine_turns(&clouds, &poses, None, o.voxel_mm, ROUNDS, progress).0;
        crate::refine::found_turns(&clouds, free, o.voxel_mm)
    };
    for (r, p) in results.iter_mut().zip(&joint) {
        r.pose = *p;
    }
    if let Some(t) = turns {
        // As a turntable counts: the first view turned forwards, every angle in [0°, 360°).
        let sign = t.angles.first().map_or(1.0, |a| a.signum());
        results[0].turn_deg = Some(0.0);
        for (&k, a) in t.views.iter().zip(&t.angles) {
            results[k].turn_deg = Some((sign * a.to_degrees()).rem_euclid(360.0));
        }
    }
    Closure {
        pairs: loops.len(),
        before,
        after: closure(&joint),
    }
}

/// The laser sheet's thicknesses (σ, mm) `merge --sheet auto` tries: from none to twice the
/// thickest a scanning line laser's line usually is (a line 5.7 mm wide at half its brightness).
pub(crate) const THICKNESS_TRIES: [f64; 7] = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2];

/// How far the views' surfaces lie apart where they overlap ([`crate::refine::surface_gap`] of
/// their points clear of their edges, placed by `results`); `None` where no view overlaps
/// another.
///
/// Each view's stripe centres are off the surface by an amount that depends on how its own
/// sweep met the surface, so views that see the same surface from different sides disagree by
/// it; moved by the right sheet thickness (`--sheet`), they agree best.
pub(crate) fn disagreement(views: &[View], results: &[ViewResult]) -> Option<f64> {
    let clear: Vec<Cloud> = views.iter().map(View::clear_cloud).collect();
    let clouds: Vec<&Cloud> = clear.iter().collect();
    let poses: Vec<Isometry3<f64>> = results.iter().map(|r| r.pose).collect();
    crate::refine::surface_gap(&clouds, &poses)
}

/// The sheet thickness where the views agree best, from `tried` (σ ascending, with the views'
/// [`disagreement`] at each): the least one refined by the parabola through it and its two
/// neighbours in σ² and the disagreement squared (the correction moves points by σ² to first
/// order, so the squared disagreement is a parabola in σ² where the bias dominates), its vertex
/// kept between the neighbours; at either end of the list, that end. `None` when no thickness
/// was measured.
pub(crate) fn best_thickness(tried: &[(f64, f64)]) -> Option<f64> {
    let (i, _) = tried
        .iter()
        .enumerate()
        .filter(|(_, t)| t.1.is_finite())
        .min_by(|a, b| a.1.1.total_cmp(&b.1.1))?;
    if i == 0 || i + 1 == tried.len() {
        return Some(tried[i].0);
    }
    let [(a, ya), (b, yb), (c, yc)] =
        [tried[i - 1], tried[i], tried[i + 1]].map(|(s, d)| (s * s, d * d));
    let num = (b - a).powi(2) * (yb - yc) - (b - c).powi(2) * (yb - ya);
    let den = (b - a) * (yb - yc) - (b - c) * (yb - ya);
    let vertex = b - 0.5 * num / den;
    if !vertex.is_finite() || den >= 0.0 {
        return Some(tried[i].0);
    }
    Some(vertex.clamp(a, c).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_sheet_is_the_parabola_vertex_inside_the_grid_and_the_end_outside() {
        // the squared disagreement a parabola in σ², least at σ 0.57 mm
        let d = |s: f64| (0.01 + (s * s - 0.57f64.powi(2)).powi(2)).sqrt();
        let tried: Vec<(f64, f64)> = THICKNESS_TRIES.iter().map(|&s| (s, d(s))).collect();
        let best = best_thickness(&tried).unwrap();
        assert!((best - 0.57).abs() < 1e-9, "{best}");
        // falling all the way: the thickest tried
        let falling: Vec<(f64, f64)> = THICKNESS_TRIES.iter().map(|&s| (s, 1.0 - s)).collect();
        assert_eq!(best_thickness(&falling), Some(1.2));
        // a measurement missing where it would be least is passed over
        let mut gap = tried.clone();
        gap[3].1 = f64::NAN;
        assert!(best_thickness(&gap).is_some_and(|b| (0.4..=0.8).contains(&b)));
        assert_eq!(best_thickness(&[]), None);
    }
}
