//! The laser speckle of a camera and laser, measured on a frame of the stripe across the bare
//! board: each sheet is flat, so the stripe's centres on it lie on a smooth curve (a straight line
//! bent by the lens), and their scatter about that curve, beyond what the sensor noise explains,
//! is the speckle's share of a centre's uncertainty ([`StripeConfig::speckle_px`]).

use scanner_core::geometry::{Board, Surface};
use scanner_core::nalgebra::{Matrix3, Point2, Vector3};
use scanner_core::stripe::{Axis, Extractor, Frame, StripeConfig};
use scanner_core::{Camera, config::MAX_LINES};

use super::CalibError;

/// A stripe centre: its line, its position along the line and its sensor-noise σ (pixels).
type Centre = (f64, f64, f64);

/// Fewest centres on a sheet for its scatter to count.
pub const MIN_SHEET_POINTS: usize = 50;
/// Centres farther than this from their sheet's curve are not the stripe on the sheet (an object,
/// the crease, the sheet's edge), pixels.
const OFF_CURVE_PX: f64 = 2.0;

/// One sheet's stripe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetScatter {
    /// Which sheet.
    pub side: Surface,
    /// Centres on its curve.
    pub points: usize,
    /// Their RMS distance from the curve, pixels.
    pub rms_px: f64,
    /// The RMS of their sensor-noise uncertainty, pixels.
    pub sensor_rms_px: f64,
    /// The RMS of their distance over their stated uncertainty (with the speckle given).
    pub z_rms: f64,
}

/// What [`stripe_scatter`] measured.
#[derive(Debug, Clone, PartialEq)]
pub struct StripeScatter {
    /// Each sheet the stripe crossed with enough centres.
    pub sheets: Vec<SheetScatter>,
    /// The speckle's share, pixels: the centres' mean square scatter less the sensor noise's,
    /// over every sheet (0 where the noise explains it all).
    pub speckle_px: f64,
    /// The RMS of every centre's distance from its curve over its stated uncertainty (with the
    /// speckle given): 1 where the stated uncertainty is the scatter.
    pub z_rms: f64,
}

/// The stripe's scatter on the board's sheets in `frame` (laser on) against `reference` (off),
/// extracted with `cfg` and judged with its `speckle_px` (`z_rms`).
///
/// # Errors
/// [`CalibError::Implausible`] when the frame does not match the reference, or no sheet holds
/// [`MIN_SHEET_POINTS`] centres of a stripe.
pub fn stripe_scatter(
    frame: &Frame<'_>,
    reference: &Frame<'_>,
    camera: &Camera<f64>,
    board: &Board<f64>,
    cfg: &StripeConfig,
) -> Result<StripeScatter, CalibError> {
    let mut ex = Box::new(Extractor::<MAX_LINES>::new());
    let sensor_only = StripeConfig {
        speckle_px: 0.0,
        ..*cfg
    };
    let found = ex
        .extract(frame, Some(reference), &sensor_only)
        .map_err(|e| CalibError::Implausible(format!("the laser frame: {e}")))?;
    let mut sheets: [Vec<Centre>; 2] = [Vec::new(), Vec::new()];
    for (line, p) in found.valid() {
        let px = match cfg.axis {
            Axis::Columns => Point2::new(line as f64, f64::from(p.centre)),
            Axis::Rows => Point2::new(f64::from(p.centre), line as f64),
        };
        let Ok(ray) = camera.pixel_to_ray(&px) else {
            continue;
        };
        let k = match board.intersect_ray(&ray, 0.05) {
            Ok((_, Surface::Left)) => 0,
            Ok((_, Surface::Right)) => 1,
            _ => continue,
        };
        sheets[k].push((line as f64, f64::from(p.centre), f64::from(p.sigma)));
    }
    let speckle = f64::from(cfg.speckle_px);
    let mut out = Vec::new();
    let (mut res2, mut sens2, mut zz, mut n) = (0.0, 0.0, 0.0, 0usize);
    for (side, pts) in [Surface::Left, Surface::Right].into_iter().zip(sheets) {
        let Some((kept, residuals)) = on_curve(pts) else {
            continue;
        };
        let m = kept.len() as f64;
        let r2: f64 = residuals.iter().map(|r| r * r).sum();
        let s2: f64 = kept.iter().map(|p| p.2 * p.2).sum();
        let z2: f64 = residuals
            .iter()
            .zip(&kept)
            .map(|(r, p)| r * r / (p.2 * p.2 + speckle * speckle).max(1e-12))
            .sum();
        res2 += r2;
        sens2 += s2;
        zz += z2;
        n += kept.len();
        out.push(SheetScatter {
            side,
            points: kept.len(),
            rms_px: (r2 / m).sqrt(),
            sensor_rms_px: (s2 / m).sqrt(),
            z_rms: (z2 / m).sqrt(),
        });
    }
    if out.is_empty() {
        return Err(CalibError::Implausible(format!(
            "no board sheet holds {MIN_SHEET_POINTS} centres of the stripe: the laser line must cross the bare board (nothing in front of it), the laser switched on after the reference"
        )));
    }
    Ok(StripeScatter {
        sheets: out,
        speckle_px: ((res2 - sens2) / n as f64).max(0.0).sqrt(),
        z_rms: (zz / n as f64).sqrt(),
    })
}

/// The centres that lie on one smooth curve `centre(line)` (a quadratic, refitted while those
/// far off it are left out) and their residuals; `None` for fewer than [`MIN_SHEET_POINTS`].
fn on_curve(mut pts: Vec<Centre>) -> Option<(Vec<Centre>, Vec<f64>)> {
    for tol in [20.0, 5.0, OFF_CURVE_PX] {
        if pts.len() < MIN_SHEET_POINTS {
            return None;
        }
        let res = quadratic_residuals(&pts)?;
        pts = pts
            .into_iter()
            .zip(&res)
            .filter(|(_, r)| r.abs() < tol)
            .map(|(p, _)| p)
            .collect();
    }
    if pts.len() < MIN_SHEET_POINTS {
        return None;
    }
    let res = quadratic_residuals(&pts)?;
    Some((pts, res))
}

/// Residuals of the least-squares quadratic `centre(line)`.
fn quadratic_residuals(pts: &[Centre]) -> Option<Vec<f64>> {
    let mid = pts.iter().map(|p| p.0).sum::<f64>() / pts.len().max(1) as f64;
    let row = |line: f64| {
        let u = (line - mid) / 100.0;
        Vector3::new(1.0, u, u * u)
    };
    let (mut a, mut b) = (Matrix3::zeros(), Vector3::zeros());
    for &(line, centre, _) in pts {
        let r = row(line);
        a += r * r.transpose();
        b += r * centre;
    }
    let c = a.cholesky()?.solve(&b);
    Some(
        pts.iter()
            .map(|&(line, centre, _)| centre - row(line).dot(&c))
            .collect(),
    )
}
