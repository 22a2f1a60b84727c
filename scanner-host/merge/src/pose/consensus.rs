//! Choosing one pose per view from every pair's candidate motions (issue 17): the set of motions
//! that agree with one another around the loops of views, not the best-fitting match of each
//! pair alone.
//!
//! On an object of flat faces, a wrong motion can fit a pair of views better than the true one
//! (a face laid on another face); it then disagrees with what the other pairs say about the same
//! two views. Each view's pose is placed from a candidate motion onto an already placed view, and
//! a set of placements scores the fit of every candidate — of every pair — that its poses agree
//! with. A beam search keeps the best partial sets while views are added.

use scanner_core::nalgebra::{Isometry3, Point3};

/// A candidate motion of view `from` onto view `to` and how well it fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// The view moved.
    pub from: usize,
    /// The view it is moved onto.
    pub to: usize,
    /// `from`'s camera frame → `to`'s.
    pub pose: Isometry3<f64>,
    /// Its fit (share of points that land on the other view).
    pub fit: f64,
}

/// Poses agree when they differ by under this angle, degrees...
pub(crate) const AGREE_DEG: f64 = 5.0;
/// ...and move the view's centre by under this many voxels.
const AGREE_VOXELS: f64 = 3.0;
/// Partial sets of placements kept at each step.
const BEAM: usize = 256;

/// The poses chosen: per view, its pose in view 0's frame and the edge that placed it (`None` for
/// view 0 and for views no candidate reaches).
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// Pose of each view in view 0's frame.
    pub poses: Vec<Option<Isometry3<f64>>>,
    /// Index into the edges of the candidate that placed each view.
    pub placed_by: Vec<Option<usize>>,
    /// Candidates the poses agree with.
    pub agreeing: Vec<usize>,
    /// Their summed fit.
    pub score: f64,
}

/// One way to place one more view from a partial set.
struct Step {
    /// The new set's score.
    score: f64,
    /// The partial set it grows (index in the beam).
    from: usize,
    /// The candidate that places the view.
    edge: usize,
    /// The view placed.
    view: usize,
    /// Its pose.
    pose: Isometry3<f64>,
    /// The candidates touching it that then agree.
    agreeing: Vec<usize>,
}

/// Whether `edge` agrees with the poses of its two views (`None` when either is unplaced).
fn agrees(
    edge: &Edge,
    pose: impl Fn(usize) -> Option<Isometry3<f64>>,
    centre: &Point3<f64>,
    voxel: f64,
) -> bool {
    let (Some(pf), Some(pt)) = (pose(edge.from), pose(edge.to)) else {
        return false;
    };
    let implied = pt.inverse() * pf;
    (implied.inverse() * edge.pose).rotation.angle() < AGREE_DEG.to_radians()
        && (edge.pose * centre - implied * centre).norm() < AGREE_VOXELS * voxel
}

/// Chooses the poses of `n` views from `edges`; `centres[k]` is a point central to view `k`
/// (in its own frame), where disagreement is measured; `voxel` the registration's voxel, mm.
/// Views no chain of candidates reaches from view 0 stay unplaced.
pub fn choose(n: usize, edges: &[Edge], centres: &[Point3<f64>], voxel: f64) -> Choice {
    let mut start = Choice {
        poses: vec![None; n],
        placed_by: vec![None; n],
        agreeing: Vec::new(),
        score: 0.0,
    };
    if n == 0 {
        return start;
    }
    start.poses[0] = Some(Isometry3::identity());
    let mut touching: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, e) in edges.iter().enumerate() {
        touching[e.from].push(i);
        touching[e.to].push(i);
    }
    // Fewer partial sets for many views: the work per step grows with views × candidates.
    let beam_width = (BEAM * 8 / n.max(8)).max(16);
    let mut beam = vec![start];
    loop {
        let mut next: Vec<Step> = Vec::new();
        for (b, s) in beam.iter().enumerate() {
            for (i, e) in edges.iter().enumerate() {
                let (view, pose) = match (s.poses[e.from], s.poses[e.to]) {
                    (None, Some(pt)) => (e.from, pt * e.pose),
                    (Some(pf), None) => (e.to, pf * e.pose.inverse()),
                    _ => continue,
                };
                let at = |v: usize| if v == view { Some(pose) } else { s.poses[v] };
                let agreeing: Vec<usize> = touching[view]
                    .iter()
                    .copied()
                    .filter(|&j| agrees(&edges[j], at, &centres[edges[j].from], voxel))
                    .collect();
                let gain: f64 = agreeing.iter().map(|&j| edges[j].fit).sum();
                next.push(Step {
                    score: s.score + gain,
                    from: b,
                    edge: i,
                    view,
                    pose,
                    agreeing,
                });
            }
        }
        if next.is_empty() {
            break;
        }
        next.sort_by(|a, b| b.score.total_cmp(&a.score));
        let mut kept: Vec<Choice> = Vec::with_capacity(beam_width);
        for st in next {
            if kept.len() == beam_width {
                break;
            }
            let mut c = beam[st.from].clone();
            c.poses[st.view] = Some(st.pose);
            c.placed_by[st.view] = Some(st.edge);
            c.agreeing.extend(st.agreeing);
            c.score = st.score;
            if !kept.iter().any(|k| same_placements(k, &c, voxel)) {
                kept.push(c);
            }
        }
        beam = kept;
    }
    beam.swap_remove(0)
}

/// Whether two partial sets place the same views at the same poses.
fn same_placements(a: &Choice, b: &Choice, voxel: f64) -> bool {
    a.poses.iter().zip(&b.poses).all(|(p, q)| match (p, q) {
        (None, None) => true,
        (Some(p), Some(q)) => crate::pose::register::same_motion(p, q, voxel),
        _ => false,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use scanner_core::nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// A turn of `deg` about the vertical through (0, 0, 500), as a turntable in front of the
    /// camera.
    pub(crate) fn turn(deg: f64) -> Isometry3<f64> {
        let c = Vector3::new(0.0, 0.0, 500.0);
        let r = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), deg.to_radians());
        Isometry3::from_parts(Translation3::from(c - r * c), r)
    }

    /// Six views 60° apart in a ring; each neighbour pair has its true motion, and one pair (1, 2)
    /// also a wrong motion that fits better. The ring's agreement must win over the better fit.
    #[test]
    fn the_motions_that_close_the_ring_win_over_a_better_fitting_wrong_one() {
        let n = 6;
        let truth: Vec<Isometry3<f64>> = (0..n).map(|k| turn(60.0 * k as f64)).collect();
        let centres = vec![Point3::new(0.0, 0.0, 500.0); n];
        let mut edges = Vec::new();
        for k in 0..n {
            let j = (k + 1) % n;
            // pose of view k in view 0's frame is truth[k]: motion k → j is truth[j]⁻¹ truth[k].
            edges.push(Edge {
                from: k,
                to: j,
                pose: truth[j].inverse() * truth[k],
                fit: 0.3,
            });
        }
        // The wrong motion of view 2 onto view 1: turned 180° the other way.
        edges.push(Edge {
            from: 2,
            to: 1,
            pose: turn(-120.0),
            fit: 0.5,
        });
        let choice = choose(n, &edges, &centres, 3.0);
        for (k, (p, t)) in choice.poses.iter().zip(&truth).enumerate() {
            let p = p.expect("every view placed");
            let err = (p.inverse() * t).rotation.angle().to_degrees();
            assert!(err < 0.01, "view {k} off by {err}°");
        }
        assert_eq!(choice.agreeing.len(), n, "{choice:?}");
        assert!(!choice.agreeing.contains(&n));
    }

    /// Many views (the merge allows 64): 48 turned 7.5° apart, each with true motions onto the
    /// three before it and, on every third view, a wrong one that fits better.
    #[test]
    fn many_views_are_chosen_right_too() {
        let n = 48;
        let truth: Vec<Isometry3<f64>> = (0..n).map(|k| turn(7.5 * k as f64)).collect();
        let centres = vec![Point3::new(0.0, 0.0, 500.0); n];
        let mut edges = Vec::new();
        for k in 1..n {
            for j in k.saturating_sub(3)..k {
                let pose = truth[j].inverse() * truth[k];
                edges.push(Edge {
                    from: k,
                    to: j,
                    pose,
                    fit: 0.3,
                });
            }
            if k % 3 == 0 {
                edges.push(Edge {
                    from: k,
                    to: k - 1,
                    pose: turn(150.0),
                    fit: 0.6,
                });
            }
        }
        let choice = choose(n, &edges, &centres, 3.0);
        for (k, (p, t)) in choice.poses.iter().zip(&truth).enumerate() {
            let p = p.expect("every view placed");
            let err = (p.inverse() * t).rotation.angle().to_degrees();
            assert!(err < 0.01, "view {k} off by {err}°");
        }
    }

    #[test]
    fn a_view_no_candidate_reaches_stays_unplaced() {
        let edges = [Edge {
            from: 1,
            to: 0,
            pose: turn(60.0),
            fit: 0.4,
        }];
        let choice = choose(3, &edges, &[Point3::origin(); 3], 3.0);
        assert!(choice.poses[1].is_some());
        assert_eq!(choice.poses[2], None);
        assert_eq!(choice.placed_by, vec![None, Some(0), None]);
    }
}
