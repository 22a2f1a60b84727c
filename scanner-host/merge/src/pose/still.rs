//! What stays still between views: without the turntable disc, a view keeps whatever it saw in
//! front of the board — the table or the stand the object stood on, a disc the head did not pose
//! — and those do not turn with the object. Registered, they pull every view back to where it
//! was (turns of 3–18° found for true 57–176°). A point of a view that lies, as it is in its
//! camera's frame, on the surface of most other views (within [`STILL_MM`], its normal alike)
//! stayed where it was while the object turned: it is left out of the registration. Still points
//! no higher than the object's lowest moving point (the table, the stand, the disc) are left out
//! of the model too; higher ones (a flat top centred on the turning axis turns onto itself) are
//! kept for it. About its own turning axis a round object stays still as a whole: it cannot be
//! registered by its shape, disc or not.

use crate::spatial::{nearest_within, tree};
use crate::view::View;

/// How near a point of another view, in the same camera frame, a point must lie to count as
/// still, mm: the views' noise and the thinning, well under a turn's move of the object.
pub(crate) const STILL_MM: f64 = 1.0;

/// How alike the normals of the two points must be (the cosine of their angle).
const NORMALS_ALIKE: f64 = 0.8;

/// Still points up to this far above the lowest moving point of their view are the support's
/// (the table, the stand, the disc), mm.
const SUPPORT_MM: f64 = 2.0;

/// The views without the still points ([`crate::pose::still`]): for the registration (none of them),
/// for the model (none of the support's), and how many each view left out of the registration.
/// A point is still when it lies on the surface of at least half the other views (and of one).
pub(crate) fn without_still(views: &[View]) -> (Vec<View>, Vec<View>, Vec<usize>) {
    let trees: Vec<_> = views.iter().map(|v| tree(&v.cloud.points)).collect();
    let need = (views.len() - 1).div_ceil(2).max(1);
    let (mut moving, mut model, mut lost) = (Vec::new(), Vec::new(), Vec::new());
    for (a, v) in views.iter().enumerate() {
        let still: Vec<bool> = (0..v.cloud.points.len())
            .map(|i| {
                let (p, n) = (&v.cloud.points[i], &v.cloud.normals[i]);
                let on = (0..views.len())
                    .filter(|&b| b != a)
                    .filter(|&b| {
                        nearest_within(&trees[b], p, STILL_MM)
                            .is_some_and(|(j, _)| views[b].cloud.normals[j].dot(n) >= NORMALS_ALIKE)
                    })
                    .count();
                on >= need
            })
            .collect();
        let keep: Vec<usize> = (0..still.len()).filter(|&i| !still[i]).collect();
        let height = |i: usize| v.up().map_or(0.0, |u| u.dot(&v.cloud.points[i].coords));
        let lowest = keep
            .iter()
            .map(|&i| height(i))
            .fold(f64::INFINITY, f64::min);
        let above: Vec<usize> = (0..still.len())
            .filter(|&i| !still[i] || height(i) > lowest + SUPPORT_MM)
            .collect();
        lost.push(still.len() - keep.len());
        moving.push(v.subset(&keep));
        model.push(v.subset(&above));
    }
    (moving, model, lost)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanner_core::nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

    /// A table top (`y = 60`, still) and a box standing on it, turned by `deg` about the
    /// vertical through (0, 60, 560): the points of both a camera would see, normals up or
    /// towards the camera.
    fn scene(deg: f64) -> View {
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for i in -60..=60 {
            for k in -40..=40 {
                let p = Point3::new(2.0 * f64::from(i), 60.0, 560.0 + 2.0 * f64::from(k));
                if p.x.abs() > 30.0 || (p.z - 560.0).abs() > 20.0 {
                    points.push(p);
                    normals.push(Vector3::new(0.0, -1.0, 0.0));
                }
            }
        }
        let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), deg.to_radians());
        let c = Vector3::new(0.0, 60.0, 560.0);
        let pose = Isometry3::from_parts(Translation3::from(c - turn * c), turn);
        // the box's front face (z = 540) and top (y = 20), before the turn
        for i in -15..=15 {
            for j in 0..20 {
                points
                    .push(pose * Point3::new(2.0 * f64::from(i), 20.0 + 2.0 * f64::from(j), 540.0));
                normals.push(turn * Vector3::new(0.0, 0.0, -1.0));
                points
                    .push(pose * Point3::new(2.0 * f64::from(i), 20.0, 540.0 + 2.0 * f64::from(j)));
                normals.push(turn * Vector3::new(0.0, -1.0, 0.0));
            }
        }
        View::for_tests(&points, &normals)
    }

    #[test]
    fn the_table_stays_still_and_the_object_does_not() {
        let views: Vec<View> = [0.0, 60.0, 130.0, 200.0].map(scene).into();
        let table = views[0].cloud.points.iter().filter(|p| p.y == 60.0).count();
        let (moving, model, lost) = without_still(&views);
        for k in 0..views.len() {
            let on_table = |v: &View| {
                v.cloud
                    .points
                    .iter()
                    .filter(|p| (p.y - 60.0).abs() < 1e-9)
                    .count()
            };
            assert_eq!(on_table(&moving[k]), 0, "view {k}: table points registered");
            assert_eq!(
                on_table(&model[k]),
                0,
                "view {k}: table points in the model"
            );
            assert!(lost[k] >= table, "view {k}: {} of {table}", lost[k]);
            // The box's front face moves; its top, centred near the axis, turns onto itself:
            // left out of the registration, kept for the model.
            let front = |v: &View| v.cloud.normals.iter().filter(|n| n.y.abs() < 0.5).count();
            assert!(front(&moving[k]) > 550, "view {k}: {}", front(&moving[k]));
            assert_eq!(
                model[k].cloud.points.len(),
                views[k].cloud.points.len() - table
            );
        }
    }
}
