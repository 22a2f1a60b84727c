//! The first stage: the views' poses. By the turntable disc where two or more views carry its
//! pose (`disc`), otherwise by the views' shapes: every pair of views registered into
//! candidate motions (`register`), the candidates
//! that agree around the loops of views chosen together (`crate::pose::select`), then each view
//! fitted finely onto the view it was placed from. A choice whose views contradict each other's
//! free space ([`crate::free`]) is made again without its weakest link.

mod consensus;
pub(crate) mod disc;
mod register;
pub(crate) mod still;

pub use register::{
    Candidate, RegisterOptions, Registration, candidates, fine, icp, icp_facing, register,
    register_hinted, turntable_motions,
};

use scanner_core::nalgebra::{Isometry3, Point3};

use crate::error::{MergeError, RegisterError};
use crate::pose::consensus::Edge;
use crate::spatial::Cloud;
use crate::view::View;

/// Where the views' poses come from, chosen once at the start of a merge ([`Source::choose`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Source {
    /// The turntable disc's pose, which two or more views carry; the others are fitted onto
    /// them by shape ([`disc`]).
    Disc,
    /// The views' shapes, registered pair by pair, with `--turntable`'s step between
    /// consecutive views as a hint (degrees).
    Turntable(f64),
    /// The views' shapes alone.
    Shape,
}

impl Source {
    /// The disc when `use_disc` and two or more views carry its pose, else the turntable's
    /// step when one was given, else the shapes alone.
    pub(crate) fn choose(views: &[View], use_disc: bool, turntable_deg: Option<f64>) -> Source {
        match turntable_deg {
            _ if use_disc && disc::carried(views) >= 2 => Source::Disc,
            Some(step) => Source::Turntable(step),
            None => Source::Shape,
        }
    }

    /// The turntable step the registration is hinted with.
    pub(crate) fn turntable_deg(self) -> Option<f64> {
        match self {
            Source::Turntable(step) => Some(step),
            Source::Disc | Source::Shape => None,
        }
    }
}

/// What the merge found for one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewResult {
    /// Its pose in view 0's frame.
    pub pose: Isometry3<f64>,
    /// The view it was registered onto (`None` for view 0).
    pub onto: Option<usize>,
    /// The registration (`None` for view 0).
    pub fit: Option<Registration>,
    /// The other views (besides `onto`) a candidate motion of which agrees with the poses: pairs
    /// that close loops of views.
    pub agrees: Vec<usize>,
    /// Points.
    pub points: usize,
    /// On the turntable: a candidate of it agrees with `--turntable`'s step.
    pub on_turntable: bool,
    /// Its angle about the turntable's axis, degrees (0–360, the first view turned forwards),
    /// when the joint refinement kept the views on the turntable turns about one axis
    /// (`refine_views`).
    pub turn_deg: Option<f64>,
}

/// A candidate that agrees with a turntable's step counts as one only if it fits at least this
/// share as well as the best of its pair's candidates (fit times [`tightness`]): on the part of
/// flat faces (1280×960) every right step was its pair's best, and a step-agreeing wrong match of
/// its side view onto a turned view fitted a hundredth as well as that pair's best.
const STEP_FIT_SHARE: f64 = 0.5;

/// Choices of poses made again at most, each time one view's points lie in front of what
/// another saw ([`register_views`]).
const MAX_RETRIES: usize = 16;

/// Views each view is paired with, besides view 0: the ones before it up to this many back.
const PAIR_REACH: usize = 7;

/// Registers every view into view 0's frame: every pair of views (each view onto view 0 and the
/// [`PAIR_REACH`] before it) registered into candidate motions, the candidates that
/// agree around the loops of views chosen together ([`crate::pose::select`]), then each view fitted
/// finely onto the view it was placed from.
///
/// `progress` gets the pairs done and the pairs in all.
///
/// # Errors
/// Fewer than two views, views of another camera, a view that overlaps none of the others, views
/// that match one another but not view 0's group.
pub(crate) fn register_views(
    views: &[View],
    o: &RegisterOptions,
    turntable_deg: Option<f64>,
    progress: impl FnMut(usize, usize),
) -> Result<Vec<ViewResult>, MergeError> {
    let n = views.len();
    if n < 2 {
        return Err(MergeError::TooFewViews(n));
    }
    let first = &views[0].header;
    for (k, v) in views.iter().enumerate().skip(1) {
        let h = &v.header;
        if (h.width, h.height) != (first.width, first.height) || h.camera != first.camera {
            return Err(MergeError::OtherCamera {
                view: k,
                name: v.name.clone(),
            });
        }
    }
    let clouds: Vec<&Cloud> = views.iter().map(|v| &v.cloud).collect();
    let hints = |a: usize, b: usize| {
        turntable_deg.map_or_else(Vec::new, |step| turntable_hints(views, a, b, step))
    };
    // A choice that the free-space check would refuse (after the joint refinement) is made
    // again without the weakest placement between the two views.
    let implausible = |results: &[ViewResult]| {
        let poses: Vec<Isometry3<f64>> = results.iter().map(|r| r.pose).collect();
        crate::free::free_space(views, &poses, o.voxel_mm)
            .filter(crate::free::seen_through)
            .map(|c| (c.view, c.seen_by))
    };
    register_clouds(&clouds, o, hints, implausible, progress).map_err(|e| match e {
        Unplaced::NoMatch { view, best } => MergeError::NoMatch {
            view,
            name: views[view].name.clone(),
            best,
        },
        Unplaced::Apart { placed, apart } => MergeError::Apart { placed, apart },
    })
}

/// Why [`register_clouds`] could not place every view.
#[derive(Debug, Clone, PartialEq)]
pub enum Unplaced {
    /// A view matches none of the others.
    NoMatch {
        /// Which view.
        view: usize,
        /// Its best failed registration.
        best: RegisterError,
    },
    /// Some views match one another but none of view 0's group.
    Apart {
        /// Views placed in view 0's frame.
        placed: Vec<usize>,
        /// Views not.
        apart: Vec<usize>,
    },
}

/// `register_views` on the views' clouds: `hints(a, b)` gives motions of view `a` onto view `b`
/// to try beside the descriptors' (a turntable's step), `implausible(results)` two views whose
/// placements contradict each other (one's points where the other saw empty space), `progress`
/// the pairs done and in all.
///
/// # Errors
/// [`Unplaced`]: a view that overlaps none of the others, views that match one another but not
/// view 0's group.
pub fn register_clouds(
    clouds: &[&Cloud],
    o: &RegisterOptions,
    hints: impl Fn(usize, usize) -> Vec<Isometry3<f64>>,
    implausible: impl Fn(&[ViewResult]) -> Option<(usize, usize)>,
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<ViewResult>, Unplaced> {
    let n = clouds.len();
    let pairs: Vec<(usize, usize)> = (1..n)
        .flat_map(|k| {
            (0..k)
                .filter(move |&j| j == 0 || k - j <= PAIR_REACH)
                .map(move |j| (k, j))
        })
        .collect();
    let mut edges = Vec::new();
    // Per view, the best failed registration: the reason given if it stays unplaced.
    let mut failed: Vec<Option<RegisterError>> = vec![None; n];
    // Per candidate, whether it agrees with its pair's hint.
    let mut stepped = Vec::new();
    for (done, &(a, b)) in pairs.iter().enumerate() {
        let hinted = hints(a, b);
        match crate::pose::candidates(clouds[a], clouds[b], o, &hinted) {
            Ok(found) => {
                let pair: Vec<Edge> = found
                    .iter()
                    .map(|c| Edge {
                        from: a,
                        to: b,
                        pose: c.pose,
                        fit: c.fit * tightness(c.rms_mm, o.voxel_mm),
                    })
                    .collect();
                // The step decides between matches that fit alike: one that agrees with it but
                // fits less than half as well as the pair's best (a view turned over by hand,
                // laid on a symmetric face by chance) does not count as a step.
                let best = pair.iter().map(|e| e.fit).fold(0.0, f64::max);
                stepped.extend(
                    pair.iter().map(|e| {
                        agrees_with_hint(&e.pose, &hinted) && e.fit >= STEP_FIT_SHARE * best
                    }),
                );
                edges.extend(pair);
            }
            Err(e) => {
                for v in [a, b] {
                    if better_failure(&e, failed[v].as_ref()) {
                        failed[v] = Some(e.clone());
                    }
                }
            }
        }
        progress(done + 1, pairs.len());
    }
    let on_turntable = keep_stepped(&mut edges, &stepped, n);
    let centres: Vec<Point3<f64>> = clouds
        .iter()
        .map(|c| crate::spatial::centre(&c.points))
        .collect();
    // A candidate whose fine fit fails is dropped and the choice made again without it.
    let mut dropped = vec![false; edges.len()];
    let mut fits = std::collections::HashMap::new();
    let (mut first_implausible, mut retries) = (None, 0);
    loop {
        let live: Vec<usize> = (0..edges.len()).filter(|&i| !dropped[i]).collect();
        let live_edges: Vec<Edge> = live.iter().map(|&i| edges[i]).collect();
        let choice = crate::pose::consensus::choose(n, &live_edges, &centres, o.voxel_mm);
        if let Some(k) = choice.poses.iter().position(Option::is_none) {
            if let Some(first) = first_implausible.take() {
                return Ok(first);
            }
            let reached = live_edges.iter().any(|e| e.from == k || e.to == k);
            return Err(match failed[k].take() {
                Some(best) if !reached => Unplaced::NoMatch { view: k, best },
                _ => Unplaced::Apart {
                    placed: (0..n).filter(|&v| choice.poses[v].is_some()).collect(),
                    apart: (0..n).filter(|&v| choice.poses[v].is_none()).collect(),
                },
            });
        }
        let agreeing: Vec<usize> = choice.agreeing.iter().map(|&i| live[i]).collect();
        match fine_tree(clouds, &edges, &agreeing, o, &mut fits) {
            Ok((mut out, by)) => {
                for &i in &agreeing {
                    let (a, b) = (edges[i].from, edges[i].to);
                    let linked = out[a].onto == Some(b) || out[b].onto == Some(a);
                    if !linked && !out[a].agrees.contains(&b) {
                        out[a].agrees.push(b);
                        out[b].agrees.push(a);
                    }
                }
                for (r, &on) in out.iter_mut().zip(&on_turntable) {
                    r.agrees.sort_unstable();
                    r.on_turntable = on;
                }
                let Some((a, b)) = implausible(&out) else {
                    return Ok(out);
                };
                // One view's points in front of what another saw: one of the candidates that
                // link the two (through the views that placed them) is wrong. The weakest gives
                // way and the choice is made again. If no other choice holds, the first is
                // given (the final check names the pair).
                let weaker = link(&out, &by, a, b)
                    .into_iter()
                    .min_by(|&i, &j| edges[i].fit.total_cmp(&edges[j].fit));
                let first = first_implausible.get_or_insert(out);
                match weaker {
                    Some(i) if retries < MAX_RETRIES => {
                        retries += 1;
                        dropped[i] = true;
                    }
                    _ => return Ok(std::mem::take(first)),
                }
            }
            Err(bad) => {
                // Every view is reached by an agreeing candidate: a view left out means a fine
                // fit failed, so each round drops one candidate at least.
                debug_assert!(!bad.is_empty());
                if bad.is_empty() {
                    return Err(Unplaced::Apart {
                        placed: vec![0],
                        apart: (1..n).collect(),
                    });
                }
                for i in bad {
                    dropped[i] = true;
                    for v in [edges[i].from, edges[i].to] {
                        if let Some(Err(e)) = fits.get(&(i, v))
                            && better_failure(e, failed[v].as_ref())
                        {
                            failed[v] = Some(e.clone());
                        }
                    }
                }
            }
        }
    }
}

/// The candidates (`by`, per view the one that placed it onto `results[k].onto`) on the path
/// between views `a` and `b` through the tree of placements: those their relative pose rests on.
fn link(results: &[ViewResult], by: &[Option<usize>], a: usize, b: usize) -> Vec<usize> {
    let to_root = |mut k: usize| {
        let mut path = Vec::new();
        // A tree of n views has paths of under n steps; the bound guards against a cycle.
        for _ in 0..results.len() {
            match (results[k].onto, by[k]) {
                (Some(onto), Some(i)) => {
                    path.push(i);
                    k = onto;
                }
                _ => break,
            }
        }
        path
    };
    let (pa, pb) = (to_root(a), to_root(b));
    // The shared part of the two paths (from view 0 down to where they part) moves both alike.
    let shared = pa
        .iter()
        .rev()
        .zip(pb.iter().rev())
        .take_while(|(x, y)| x == y)
        .count();
    let mut out = pa[..pa.len() - shared].to_vec();
    out.extend_from_slice(&pb[..pb.len() - shared]);
    out
}

/// The fine fits along the best-fitting `agreeing` candidates that reach every view from view 0
/// (Prim's tree), composed outwards; a candidate whose fine fit fails gives way to the next.
/// `fits` keeps each candidate's fine fit (by candidate and the view moved) for the next call.
///
/// Returns the results and, per view, the candidate that placed it.
///
/// # Errors
/// The candidates whose fine fits failed, when some view is left unreached.
#[allow(clippy::type_complexity)]
fn fine_tree(
    clouds: &[&Cloud],
    edges: &[Edge],
    agreeing: &[usize],
    o: &RegisterOptions,
    fits: &mut std::collections::HashMap<(usize, usize), Result<Registration, RegisterError>>,
) -> Result<(Vec<ViewResult>, Vec<Option<usize>>), Vec<usize>> {
    let n = clouds.len();
    let mut agreeing = agreeing.to_vec();
    agreeing.sort_by(|&a, &b| edges[b].fit.total_cmp(&edges[a].fit).then(a.cmp(&b)));
    let mut out: Vec<Option<ViewResult>> = vec![None; n];
    out[0] = Some(ViewResult {
        pose: Isometry3::identity(),
        onto: None,
        fit: None,
        agrees: Vec::new(),
        points: clouds[0].points.len(),
        on_turntable: false,
        turn_deg: None,
    });
    let mut bad = Vec::new();
    let mut by = vec![None; n];
    loop {
        let next = agreeing.iter().copied().find_map(|i| {
            let e = edges[i];
            match (&out[e.from], &out[e.to]) {
                (None, Some(_)) if !bad.contains(&i) => Some((i, e.from, e.to, e.pose)),
                (Some(_), None) if !bad.contains(&i) => Some((i, e.to, e.from, e.pose.inverse())),
                _ => None,
            }
        });
        let Some((i, k, onto, init)) = next else {
            break;
        };
        let fit = fits
            .entry((i, k))
            .or_insert_with(|| crate::pose::fine(clouds[k], clouds[onto], init, o));
        match fit {
            Ok(fit) => {
                by[k] = Some(i);
                let base = out[onto].as_ref().map_or(Isometry3::identity(), |r| r.pose);
                out[k] = Some(ViewResult {
                    pose: base * fit.pose,
                    onto: Some(onto),
                    fit: Some(*fit),
                    agrees: Vec::new(),
                    points: clouds[k].points.len(),
                    on_turntable: false,
                    turn_deg: None,
                });
            }
            Err(_) => bad.push(i),
        }
    }
    if out.iter().any(Option::is_none) {
        return Err(bad);
    }
    Ok((out.into_iter().flatten().collect(), by))
}

/// Whether `pose`'s rotation agrees with one of `hints`' (within [`crate::pose::consensus::AGREE_DEG`]).
fn agrees_with_hint(pose: &Isometry3<f64>, hints: &[Isometry3<f64>]) -> bool {
    hints.iter().any(|h| {
        (h.rotation.inverse() * pose.rotation).angle()
            < crate::pose::consensus::AGREE_DEG.to_radians()
    })
}

/// With a turntable's step the user's word decides between motions that fit alike (a symmetric
/// object's front and back): a view with a candidate that agrees with the step (`stepped`) is
/// on the turntable, and between two views on it only such candidates are kept. A view with none
/// (turned over by hand between sweeps) keeps all of its own.
/// The candidates that agree with the step then count before any others in the choice: each
/// weighs more than all the others' fits together. Returns which views are on the turntable.
fn keep_stepped(edges: &mut Vec<Edge>, stepped: &[bool], n: usize) -> Vec<bool> {
    let mut on = vec![false; n];
    for (e, _) in edges.iter().zip(stepped).filter(|(_, s)| **s) {
        on[e.from] = true;
        on[e.to] = true;
    }
    let outweigh = 1.0 + edges.iter().map(|e| e.fit).sum::<f64>();
    let mut kept = Vec::with_capacity(edges.len());
    for (mut e, &s) in edges.drain(..).zip(stepped) {
        if s {
            e.fit += outweigh;
            kept.push(e);
        } else if !(on[e.from] && on[e.to]) {
            kept.push(e);
        }
    }
    *edges = kept;
    on
}

/// How much of a candidate's fit counts in the choice, by its residual: right motions leave
/// residuals of the points' noise (0.20–0.36 mm on the thinned 360° demo views), wrong ones that
/// lay a curved surface on another larger (0.69–1.16 mm); 1 at none, ½ at a sixth of a voxel.
fn tightness(rms_mm: f64, voxel_mm: f64) -> f64 {
    1.0 / (1.0 + (rms_mm / (voxel_mm / 6.0)).powi(4))
}

/// Whether failure `e` says more than `than` (fewer points beats none; a larger overlap found
/// beats a smaller).
fn better_failure(e: &RegisterError, than: Option<&RegisterError>) -> bool {
    let found = |e: &RegisterError| match e {
        RegisterError::NoOverlap {
            overlap_percent, ..
        } => *overlap_percent,
        RegisterError::TooFewPoints { .. } => -1.0,
    };
    than.is_none_or(|t| found(e) > found(t))
}

/// The motions a turntable suggests from view `k` onto view `j`, `step_deg` per view about the
/// board's vertical (its crease): see [`crate::pose::turntable_motions`].
fn turntable_hints(views: &[View], k: usize, j: usize, step_deg: f64) -> Vec<Isometry3<f64>> {
    let Some(up) = views[0].up() else {
        return Vec::new();
    };
    let angle = step_deg * (k - j) as f64;
    crate::pose::turntable_motions(&up, &views[k].cloud, &views[j].cloud, angle).to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turntables_step_decides_between_its_views_and_leaves_a_view_turned_by_hand_alone() {
        use crate::pose::consensus::{Edge, tests::turn};
        let edge = |from, to, deg, fit| Edge {
            from,
            to,
            pose: turn(deg),
            fit,
        };
        // A step of 60°: rotations within 5° of it (either way) agree.
        let hints = [turn(60.0), turn(-60.0)];
        assert!(agrees_with_hint(&turn(62.0), &hints) && agrees_with_hint(&turn(-58.5), &hints));
        assert!(!agrees_with_hint(&turn(66.0), &hints) && !agrees_with_hint(&turn(180.0), &hints));
        assert!(!agrees_with_hint(&turn(60.0), &[]));
        // Views 0, 1, 2 on the turntable, view 3 turned over by hand (no candidate of it agrees).
        let mut edges = vec![
            edge(1, 0, 60.0, 0.3),  // the step: kept, and counts before all the others
            edge(1, 0, 180.0, 0.5), // a symmetric object's other side, between turntable views: gone
            edge(2, 1, 60.0, 0.2),  // the step
            edge(2, 0, 10.0, 0.4), // no candidate of this pair agrees, but both views are on it: gone
            edge(3, 0, 90.0, 0.4), // view 3's own candidates stay, all of them
            edge(3, 2, 150.0, 0.1),
        ];
        let stepped = [true, false, true, false, false, false];
        let total: f64 = edges.iter().map(|e| e.fit).sum();
        let on = keep_stepped(&mut edges, &stepped, 4);
        assert_eq!(on, [true, true, true, false]);
        let want = [
            (1, 0, 0.3 + 1.0 + total),
            (2, 1, 0.2 + 1.0 + total),
            (3, 0, 0.4),
            (3, 2, 0.1),
        ];
        assert_eq!(edges.len(), want.len(), "{edges:?}");
        for (e, w) in edges.iter().zip(want) {
            assert!(
                (e.from, e.to) == (w.0, w.1) && (e.fit - w.2).abs() < 1e-12,
                "{edges:?}"
            );
        }
        // Without a hint nothing changes.
        let mut plain = vec![edge(1, 0, 60.0, 0.3), edge(1, 0, 180.0, 0.5)];
        let before = plain.clone();
        assert_eq!(keep_stepped(&mut plain, &[false, false], 2), [false, false]);
        assert_eq!(plain, before);
    }

    /// The candidates between two views through the tree of placements: 1 and 2 onto 0, 3 onto
    /// 1, 4 onto 3 (candidates 10, 20, 30, 40).
    #[test]
    fn the_link_between_two_views_is_the_path_through_the_views_that_placed_them() {
        let onto = [None, Some(0), Some(0), Some(1), Some(3)];
        let results: Vec<ViewResult> = onto
            .iter()
            .map(|&onto| ViewResult {
                pose: Isometry3::identity(),
                onto,
                fit: None,
                agrees: Vec::new(),
                points: 0,
                on_turntable: false,
                turn_deg: None,
            })
            .collect();
        let by = [None, Some(10), Some(20), Some(30), Some(40)];
        let sorted = |mut v: Vec<usize>| {
            v.sort_unstable();
            v
        };
        assert_eq!(sorted(link(&results, &by, 4, 2)), [10, 20, 30, 40]);
        // The shared way down from view 0 (candidate 10) moves 3 and 4 alike.
        assert_eq!(sorted(link(&results, &by, 4, 1)), [30, 40]);
        assert_eq!(sorted(link(&results, &by, 3, 4)), [40]);
        assert_eq!(sorted(link(&results, &by, 0, 3)), [10, 30]);
        assert!(link(&results, &by, 2, 2).is_empty());
    }
}
