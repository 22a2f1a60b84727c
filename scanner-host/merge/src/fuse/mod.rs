//! The last stage, the fusion into one model. What it takes from the registered views — their points in view 0's frame, less
//! the isolated ones and the edge points that another view's clear surface or the winding
//! number of all contradicts, each weighed by how clear of its view's edges it lies — and the
//! fusion of them into one model (`crate::fuse::surface`), its unseen surface closed as asked.

pub(crate) mod hull;
mod surface;
mod winding;

pub use surface::{
    FLOATER_SHARE, Fill, HalfSpace, MeshCheck, Model, Piece, PieceKind, area, area_on, area_share,
    check, fuse, fuse_cut, fuse_filled, fuse_with, inliers, off_surface, pieces, trim,
    unseen_faces,
};
pub(crate) use surface::{OFF_SURFACE_MARGIN, colour_from};
pub use winding::Winding;

use scanner_core::nalgebra::{Isometry3, Point3, Vector3};

use crate::error::FuseError;
use crate::spatial::{Cloud, nearest_within};
use crate::view::View;

/// The fusion's weight of a point on its view's edge, against 1 for one clear of it: where a
/// clear point of another view saw the same surface it decides, elsewhere the edge point does.
const EDGE_WEIGHT: f64 = 0.05;

/// Distinct colours for views, in order.
const COLOURS: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
    [210, 245, 60],
];

/// Each point's view colour, views in order (as [`registered_points`] lists the points).
pub(crate) fn view_colours(views: &[View]) -> Vec<[u8; 3]> {
    views
        .iter()
        .enumerate()
        .flat_map(|(k, v)| std::iter::repeat_n(COLOURS[k % COLOURS.len()], v.cloud.points.len()))
        .collect()
}

/// All views' points and normals in view 0's frame.
pub(crate) fn registered_points(
    views: &[View],
    poses: &[Isometry3<f64>],
) -> (Vec<Point3<f64>>, Vec<Vector3<f64>>) {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for (v, pose) in views.iter().zip(poses) {
        points.extend(v.cloud.points.iter().map(|p| pose * p));
        normals.extend(v.cloud.normals.iter().map(|n| pose * n));
    }
    (points, normals)
}

/// What the fusion and the pictures take: the registered points without isolated ones
/// ([`crate::fuse::inliers`]), their normals and each point's view colour.
pub struct FusionInput {
    /// Points, view 0's frame.
    pub points: Vec<Point3<f64>>,
    /// Their normals.
    pub normals: Vec<Vector3<f64>>,
    /// Their views' colours.
    pub colours: Vec<[u8; 3]>,
    /// The surface's colour at each point (empty unless every view carried colour).
    pub surface: Vec<[u8; 3]>,
    /// The fusion's weight of each point: 1 clear of its view's edges, down to `EDGE_WEIGHT`
    /// on one.
    pub weights: Vec<f64>,
    /// Points on views' edges left out: off the surface another view saw clear
    /// (`contradicted_edges`).
    pub contradicted: usize,
    /// Points on views' edges left out: clearly off the surface all the points wind around
    /// ([`crate::fuse::off_surface`]).
    pub off_surface: usize,
    /// The median of the views' points' standard uncertainties, mm (0 when the views carried
    /// none).
    pub sigma_mm: f64,
}

/// A point on a view's edge ([`View::clearance`] under [`crate::view::MIN_CLEARANCE`]) is not fused when a point clear
/// of another view's edges lies within [`CONFIRM_MM`] of it and it lies more than this off that
/// point's tangent plane, mm: the stripe cut at an occluding edge placed it off the surface that
/// the other view saw clear (on the 360° demo 0.1–0.15 mm is the median error of edge points,
/// their p99 0.9–2.2 mm; clear points' p99 0.27–0.36 mm).
const EDGE_OFF_MM: f64 = 0.4;

/// How near a clear point of another view must lie to judge an edge point, mm ([`EDGE_OFF_MM`]).
const CONFIRM_MM: f64 = 2.0;

/// For every point of every view (views in order, as [`registered_points`] lists them), whether
/// it lies on its view's edge ([`View::clearance`] under [`crate::view::MIN_CLEARANCE`]) and, at the merged poses, more
/// than [`EDGE_OFF_MM`] off the tangent plane of the nearest point clear of another view's edges
/// within [`CONFIRM_MM`] ([`contradicted`]).
pub(crate) fn contradicted_edges(views: &[View], poses: &[Isometry3<f64>]) -> Vec<bool> {
    let clouds: Vec<&Cloud> = views.iter().map(|v| &v.cloud).collect();
    let clear: Vec<&[f64]> = views.iter().map(|v| &v.clearance[..]).collect();
    contradicted(&clouds, &clear, poses)
}

/// `contradicted_edges` of views' `clouds` (each in its own frame, placed by `poses`) with
/// their points' shares clear of the edges `clear` (a missing share counts as clear). An edge
/// point no other view saw clear stays.
pub fn contradicted(clouds: &[&Cloud], clear: &[&[f64]], poses: &[Isometry3<f64>]) -> Vec<bool> {
    let is_clear = |k: usize, i: usize| {
        clear[k]
            .get(i)
            .is_none_or(|&c| c >= crate::view::MIN_CLEARANCE)
    };
    // each view's clear points (indices into its cloud) and their tree, in its own frame
    let judges: Vec<(Vec<usize>, kiddo::KdTree<f64, 3>)> = clouds
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let keep: Vec<usize> = (0..c.points.len()).filter(|&i| is_clear(k, i)).collect();
            let points: Vec<Point3<f64>> = keep.iter().map(|&i| c.points[i]).collect();
            (keep, crate::spatial::tree(&points))
        })
        .collect();
    let inverses: Vec<Isometry3<f64>> = poses.iter().map(Isometry3::inverse).collect();
    let mut out = Vec::new();
    for (k, (c, pose)) in clouds.iter().zip(poses).enumerate() {
        for (i, p) in c.points.iter().enumerate() {
            if is_clear(k, i) {
                out.push(false);
                continue;
            }
            let q = pose * p;
            // the nearest clear point of another view: (squared distance, offset off its plane)
            let mut nearest: Option<(f64, f64)> = None;
            for (j, (keep, tree)) in judges.iter().enumerate() {
                if j == k {
                    continue;
                }
                let local = inverses[j] * q;
                let Some((m, d2)) = nearest_within(tree, &local, CONFIRM_MM) else {
                    continue;
                };
                let at = keep[m];
                let offset = (local - clouds[j].points[at]).dot(&clouds[j].normals[at]);
                if nearest.is_none_or(|(d, _)| d2 < d) {
                    nearest = Some((d2, offset));
                }
            }
            out.push(nearest.is_some_and(|(_, offset)| offset.abs() > EDGE_OFF_MM));
        }
    }
    out
}

/// The fusion's weight of a point clear of its view's edges by the share `clear` (`None`:
/// clear): 1 clear of them, down to `EDGE_WEIGHT` on one.
pub fn edge_weight(clear: Option<f64>) -> f64 {
    EDGE_WEIGHT + (1.0 - EDGE_WEIGHT) * clear.unwrap_or(1.0)
}

/// Which of the registered `points` (with `normals` and fusion `weights`) are fused: not
/// isolated ([`crate::fuse::inliers`]), not `contradicted` ([`contradicted`]), and of the edge
/// points left not off_surface ([`crate::fuse::off_surface`]). Returns their indices and how many were
/// off_surface.
pub fn fused_points(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    weights: &[f64],
    contradicted: &[bool],
) -> (Vec<usize>, usize) {
    let kept: Vec<usize> = crate::fuse::inliers(points)
        .into_iter()
        .filter(|&i| !contradicted[i])
        .collect();
    let pick = |i: &usize| (points[*i], normals[*i], weights[*i]);
    let (p, (n, w)): (Vec<_>, (Vec<_>, Vec<_>)) =
        kept.iter().map(pick).map(|(p, n, w)| (p, (n, w))).unzip();
    let off_surface = crate::fuse::off_surface(&p, &n, &w);
    let keep = kept
        .iter()
        .zip(&off_surface)
        .filter(|(_, a)| !**a)
        .map(|(&i, _)| i)
        .collect();
    (keep, off_surface.iter().filter(|&&a| a).count())
}

/// [`registered_points`] without isolated points and without the edge points that another view's
/// clear surface contradicts ([`contradicted_edges`]) or that float off the surface of all the
/// points ([`crate::fuse::off_surface`]), with their view colours.
pub(crate) fn fusion_input(views: &[View], poses: &[Isometry3<f64>]) -> FusionInput {
    let (points, normals) = registered_points(views, poses);
    let off = contradicted_edges(views, poses);
    let colours = view_colours(views);
    let surface: Vec<[u8; 3]> = if views
        .iter()
        .all(|v| v.colours.len() == v.cloud.points.len())
    {
        views
            .iter()
            .flat_map(|v| v.colours.iter().copied())
            .collect()
    } else {
        Vec::new()
    };
    let weights: Vec<f64> = views
        .iter()
        .flat_map(|v| (0..v.cloud.points.len()).map(|i| edge_weight(v.clearance.get(i).copied())))
        .collect();
    let (keep, off_surface) = fused_points(&points, &normals, &weights, &off);
    let mut sigma: Vec<f64> = views.iter().flat_map(|v| v.sigma.iter().copied()).collect();
    sigma.sort_by(f64::total_cmp);
    FusionInput {
        sigma_mm: sigma.get(sigma.len() / 2).copied().unwrap_or(0.0),
        contradicted: off.iter().filter(|&&o| o).count(),
        off_surface,
        weights: keep.iter().map(|&i| weights[i]).collect(),
        points: keep.iter().map(|&i| points[i]).collect(),
        normals: keep.iter().map(|&i| normals[i]).collect(),
        colours: keep.iter().map(|&i| colours[i]).collect(),
        surface: if surface.is_empty() {
            surface
        } else {
            keep.iter().map(|&i| surface[i]).collect()
        },
    }
}

/// How the fusion closes the surface no view saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Closing {
    /// Smoothly, by the points' winding number: the model is watertight.
    #[default]
    Smooth,
    /// Not at all: the unseen surface is removed and the model is open there.
    Trim,
    /// Cut level with the lowest point a view saw and closed flat there (a base to print on),
    /// smoothly elsewhere. Nothing a view saw lies below the cut; up is view 0's board's. Views
    /// on the turntable disc are cut at the disc's plane instead, up away from it.
    FlatBase,
}

/// The volume's bounds are widened by the seen area times this many of the points' median
/// standard uncertainty ([`FusionFigures::volume_bounds_mm3`]).
const BOUND_SIGMAS: f64 = 2.0;

/// How far from every point the model's surface counts as unseen, in fusion cells.
const UNSEEN_CELLS: f64 = 3.0;

/// What the report says of a fusion.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FusionFigures {
    /// Points on the views' edges left out: more than `EDGE_OFF_MM` off the surface another
    /// view saw clear of its edges.
    pub contradicted: usize,
    /// The distance off that surface that leaves an edge point out, mm.
    pub edge_off_mm: f64,
    /// Points on the views' edges left out: where the winding number of all the points is
    /// more than `off_surface_margin` from ½.
    pub off_surface: usize,
    /// That margin.
    pub off_surface_margin: f64,
    /// How the unseen surface was closed.
    pub closing: Closing,
    /// Surface farther than this from every point counts as unseen, mm.
    pub unseen_reach_mm: f64,
    /// The share of the model's area no view saw (before any trimming).
    pub unseen_share: f64,
    /// With [`Closing::Trim`]: faces removed.
    pub trimmed_faces: Option<usize>,
    /// With [`Closing::FlatBase`]: the base's area, mm².
    pub base_mm2: Option<f64>,
    /// Whether the surface no view saw was filled as solid where no view saw through it, down
    /// to the turntable disc's plane (views posed by the disc, not trimmed).
    pub filled: bool,
    /// With `filled`: the object's volume between two closings of what no view saw, mm³ — the
    /// points' winding number's (the least the seen surface encloses, its unseen part closed
    /// smoothly) and the filled model's (everything no view saw through) — each widened by the
    /// seen surface's area times twice the points' median standard uncertainty. The object's
    /// own volume lies between them unless a view placed a point wrongly.
    pub volume_bounds_mm3: Option<[f64; 2]>,
    /// Whether the model is coloured per vertex from the views (every view carried colour).
    pub coloured: bool,
    /// Vertices of the model.
    pub vertices: usize,
    /// Its faces.
    pub faces: usize,
    /// Its checks: watertight, components, volume.
    pub check: MeshCheck,
    /// Its pieces, largest first: one for a model of one object.
    pub pieces: Vec<Piece>,
}

/// The fused model and what the report says of it.
#[derive(Debug, Clone)]
pub struct Fused {
    /// The model, view 0's camera frame.
    pub model: Model,
    /// The figures of the fusion.
    pub figures: FusionFigures,
}

/// Fuses the views' points ([`fusion_input`]) with cells of `cell` mm, the unseen surface closed
/// as `closing` says (a flat base across `up`, unit, view 0's frame); coloured from the points
/// when they carry colour. With a `hull` (views that stood on the turntable disc), the surface
/// no view saw is filled as solid where no view saw through it, down to the disc's plane
/// ([`crate::fuse::hull`]); a flat base is then cut at the disc's plane. `progress` sees the grid's
/// slices done and in all.
///
/// # Errors
/// [`FuseError`] from the fusion.
pub(crate) fn fuse_views(
    input: &FusionInput,
    cell: f64,
    (closing, up): (Closing, Option<Vector3<f64>>),
    hull: Option<&crate::fuse::hull::Hull>,
    progress: impl FnMut(usize, usize),
) -> Result<Fused, FuseError> {
    use crate::fuse::{Fill, HalfSpace};
    let hull = hull.filter(|_| closing != Closing::Trim);
    let floor = hull.map(|h| {
        let (up, at) = h.floor();
        HalfSpace { up, at }
    });
    let base = match (closing, floor, up) {
        (Closing::FlatBase, Some(floor), _) => Some(floor),
        (Closing::FlatBase, None, Some(up)) => Some(HalfSpace {
            up,
            at: input
                .points
                .iter()
                .map(|p| up.dot(&p.coords))
                .fold(f64::INFINITY, f64::min),
        }),
        _ => None,
    };
    let solid = |q: &Point3<f64>| hull.is_some_and(|h| h.solid(q));
    let fill = floor.map(|floor| Fill {
        solid: &solid,
        floor,
    });
    let (mut model, smaller) = crate::fuse::fuse_filled(
        &input.points,
        &input.normals,
        &input.weights,
        cell,
        base,
        fill.as_ref(),
        progress,
    )?;
    let reach = UNSEEN_CELLS * cell;
    let unseen = crate::fuse::unseen_faces(&model, &input.points, reach);
    let unseen_share = crate::fuse::area_share(&model, &unseen);
    let trimmed_faces = (closing == Closing::Trim).then(|| crate::fuse::trim(&mut model, &unseen));
    let base_mm2 = base.map(|h| crate::fuse::area_on(&model, &h, 0.01));
    crate::fuse::colour_from(&mut model, &input.points, &input.surface);
    let check = crate::fuse::check(&model);
    // Each closing's volume, widened by the seen surface's own uncertainty: its area times
    // BOUND_SIGMAS of the points' median σ (the seen surface may lie that far in or out).
    let seen_mm2 = crate::fuse::area(&model) * (1.0 - unseen_share);
    let margin = seen_mm2 * BOUND_SIGMAS * input.sigma_mm;
    let volume_bounds_mm3 =
        smaller.map(|v| [v.min(check.volume_mm3) - margin, check.volume_mm3 + margin]);
    let figures = FusionFigures {
        contradicted: input.contradicted,
        edge_off_mm: EDGE_OFF_MM,
        off_surface: input.off_surface,
        off_surface_margin: crate::fuse::OFF_SURFACE_MARGIN,
        closing,
        unseen_reach_mm: reach,
        unseen_share,
        trimmed_faces,
        base_mm2,
        coloured: !model.colours.is_empty(),
        filled: fill.is_some(),
        volume_bounds_mm3,
        vertices: model.vertices.len(),
        faces: model.faces.len(),
        check,
        pieces: crate::fuse::pieces(&model),
    };
    Ok(Fused { model, figures })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A view of points with their clear shares, normals facing the camera (−z).
    fn view_of(points: &[(Point3<f64>, f64)]) -> View {
        let normals = vec![Vector3::new(0.0, 0.0, -1.0); points.len()];
        let cloud: Vec<Point3<f64>> = points.iter().map(|p| p.0).collect();
        View {
            clearance: points.iter().map(|p| p.1).collect(),
            ..View::for_tests(&cloud, &normals)
        }
    }

    #[test]
    fn edge_points_off_a_surface_another_view_saw_clear_are_left_out_of_the_fusion() {
        // View 0 saw a plate at 500 mm clear of its edges; view 1 (the same frame) has edge
        // points on it, 1 mm in front of it, 1 mm in front where view 0 saw nothing, and clear
        // points 1 mm in front (clear points are never judged).
        let mut plate = Vec::new();
        for i in -20..=20 {
            for j in -20..=20 {
                plate.push((Point3::new(i as f64 * 0.75, j as f64 * 0.75, 500.0), 1.0));
            }
        }
        let second = [
            (Point3::new(1.1, 2.3, 500.1), 0.0),
            (Point3::new(-3.2, 0.4, 499.0), 0.0),
            (Point3::new(4.0, -5.1, 500.5), 0.2),
            (Point3::new(40.0, 0.0, 499.0), 0.0),
            (Point3::new(0.3, 0.3, 499.0), 1.0),
        ];
        let views = [view_of(&plate), view_of(&second)];
        let results = [Isometry3::identity(); 2];
        let off = contradicted_edges(&views, &results);
        assert_eq!(off.len(), plate.len() + second.len());
        assert!(off[..plate.len()].iter().all(|&o| !o));
        assert_eq!(&off[plate.len()..], &[false, true, true, false, false]);
        // moved by the registration, the second view's points are judged where it put them
        let mut moved = results;
        moved[1] = Isometry3::translation(0.0, 0.0, 1.0);
        let off = contradicted_edges(&views, &moved);
        assert_eq!(&off[plate.len()..], &[true, false, true, false, false]);
        let input = fusion_input(&views, &results);
        assert_eq!(input.contradicted, 2);
        let fused = |p: &Point3<f64>| input.points.contains(p);
        assert!(fused(&second[0].0) && fused(&second[4].0));
        assert!(!fused(&second[1].0) && !fused(&second[2].0));
    }
}
