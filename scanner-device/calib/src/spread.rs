//! How far the board planes can be trusted: each sheet's plane's covariance from its markers'
//! noise, and how it moves with the intrinsics (the sheet's pose refitted with a changed
//! camera). With the intrinsics' covariance this gives the head the calibration's share of each
//! point's uncertainty ([`scanner_core::calib::spread`]).

use scanner_core::calib::TargetImage;
use scanner_core::calib::bundle::{INTRINSICS, pose_spread, step_pose};
use scanner_core::calib::spread::SheetSpread;
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Point2, SMatrix, Vector6};
use scanner_core::{Camera, GeomError};

use super::board::BoardFile;
use super::{BoardFit, CalibError};

/// The plane `(n_x, n_y, n_z, d)` of a pose's sheet.
fn plane_of(pose: &Pose) -> Result<[f64; 4], GeomError> {
    let p = pose.plane()?;
    let n = p.normal();
    Ok([n.x, n.y, n.z, p.offset()])
}

/// `∂(n, d)/∂pose` at `pose` (the pose moved as [`step_pose`] moves it), by central differences.
fn plane_jacobian(pose: &Pose) -> Result<SMatrix<f64, 4, 6>, GeomError> {
    const H: f64 = 1e-6;
    let mut j = SMatrix::<f64, 4, 6>::zeros();
    for k in 0..6 {
        let mut d = Vector6::zeros();
        d[k] = H;
        let (a, b) = (
            plane_of(&step_pose(pose, &d))?,
            plane_of(&step_pose(pose, &-d))?,
        );
        for r in 0..4 {
            j[(r, k)] = (a[r] - b[r]) / (2.0 * H);
        }
    }
    Ok(j)
}

/// Both sheets' [`SheetSpread`] of a board fit made with `camera` from the board `board`. The
/// markers' noise is the pooled scatter of both sheets' residuals (over their degrees of freedom).
///
/// # Errors
/// [`CalibError::Geometry`] when a sheet's markers do not determine its pose.
pub fn board_spread(
    fit: &BoardFit,
    board: &BoardFile,
    camera: &Camera<f64>,
) -> Result<[SheetSpread; 2], CalibError> {
    let geom = |reason| CalibError::Geometry {
        what: "the board planes' spread".into(),
        reason,
    };
    let sheets = [&board.left, &board.right];
    let mut parts = Vec::new();
    for (k, s) in fit.sheets.iter().enumerate() {
        let (layout, pixels): (Vec<Point2<f64>>, Vec<Point2<f64>>) = s
            .markers
            .iter()
            .filter(|m| m.residual.is_some())
            .filter_map(|m| Some((m.sheet, m.pixel?)))
            .unzip();
        let view = TargetImage {
            layout: &layout,
            pixels: &pixels,
        };
        let radius = sheets[k].marker_radius(board.marker_diameter);
        let spread = pose_spread(camera, &view, &s.pose, radius).map_err(geom)?;
        parts.push((spread, plane_jacobian(&s.pose).map_err(geom)?));
    }
    let cost: f64 = parts.iter().map(|p| p.0.cost).sum();
    let equations: usize = parts.iter().map(|p| 2 * p.0.features).sum();
    let noise2 = cost / (equations.saturating_sub(12).max(1)) as f64;
    let spread = |(p, j): &(scanner_core::calib::bundle::PoseSpread, SMatrix<f64, 4, 6>)| {
        let noise = j * (p.per_noise * noise2) * j.transpose();
        let from = j * p.from_intrinsics;
        SheetSpread {
            noise: core::array::from_fn(|r| core::array::from_fn(|c| noise[(r, c)])),
            from_intrinsics: core::array::from_fn(|r| {
                core::array::from_fn::<f64, INTRINSICS, _>(|c| from[(r, c)])
            }),
        }
    };
    Ok([spread(&parts[0]), spread(&parts[1])])
}
