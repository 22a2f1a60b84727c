//! One sheet's plane fitted to its markers: each marker's pixel against its place in the layout,
//! the pose refined with the dot model, markers that pull the fit pruned ([`fit_sheet`]).

use scanner_core::Camera;
use scanner_core::calib::bundle::{initial_pose, refine, residuals};
use scanner_core::calib::{Free, TargetImage};
use scanner_core::geometry::{Board, Plane, Pose};
use scanner_core::nalgebra::{Point2, Vector2};

use crate::detect::Blob;
use crate::identify::Assignment;

use crate::error::{CalibError, geom};

/// The largest RMS of a sheet's markers against its layout that a board calibration accepts,
/// pixels (the rig's boards fit within 0.03 px; a dot-grid target mistaken for the board, 0.9 px).
pub const MAX_SHEET_RMS_PX: f64 = 0.5;

/// The opening angles of a two-plane board that a board calibration accepts, degrees.
pub const BOARD_ANGLE_DEG: (f64, f64) = (30.0, 150.0);

/// A marker of the chosen identification whose position the sheet's other markers predict worse
/// than this, pixels, and than [`PULL_SPREADS`] times their own RMS, is left out of the sheet's
/// fit (`fit_sheet`).
const PULL_PX: f64 = 0.1;
/// See [`PULL_PX`].
const PULL_SPREADS: f64 = 5.0;

/// A sheet's pose from a subset of its markers, the RMS and the residuals of those markers.
type SubsetFit = (Pose, f64, Vec<Vector2<f64>>);

/// How `fit_sheet` leaves out a marker that pulls the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Prune {
    /// Quickly, while candidate identifications are compared.
    Halving,
    /// Carefully, for the chosen one.
    Predicted,
}

/// Largest RMS reprojection error of a marker fit that is taken as the right layout.
pub const MAX_FIT_RMS_PX: f64 = 1.0;

/// One layout point's outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerFit {
    /// Position on the sheet, mm.
    pub sheet: Point2<f64>,
    /// Where it was found (`None`: missing).
    pub pixel: Option<Point2<f64>>,
    /// Predicted − found, pixels (`None`: missing or dropped).
    pub residual: Option<Vector2<f64>>,
    /// Found but dropped from the fit as an outlier (e.g. partly hidden).
    pub dropped: bool,
}

/// A sheet's pose from its markers.
#[derive(Debug, Clone, PartialEq)]
pub struct SheetFit {
    /// Sheet → camera.
    pub pose: Pose,
    /// Its plane, normal towards the camera.
    pub plane: Plane<f64>,
    /// Every layout point.
    pub markers: Vec<MarkerFit>,
    /// RMS reprojection error of the used markers, pixels.
    pub rms_px: f64,
}

impl SheetFit {
    /// Layout indices not found or dropped.
    pub fn missing(&self) -> Vec<usize> {
        self.markers
            .iter()
            .enumerate()
            .filter(|(_, m)| m.residual.is_none())
            .map(|(i, _)| i)
            .collect()
    }

    /// Markers used in the fit.
    pub fn used(&self) -> usize {
        self.markers.iter().filter(|m| m.residual.is_some()).count()
    }

    /// One line for people: `left sheet: 5/6 markers, rms 0.081 px, missing or dropped [3]`.
    pub fn summary(&self, side: &str) -> String {
        let missing = self.missing();
        let mut line = format!(
            "{side} sheet: {}/{} markers, rms {:.3} px",
            self.markers.len() - missing.len(),
            self.markers.len(),
            self.rms_px
        );
        if !missing.is_empty() {
            line += &format!(", missing or dropped {missing:?}");
        }
        line
    }
}

/// Pose of a planar layout from identified markers, with a camera known, from the markers an
/// earlier fit kept (`start`) or all found; markers that pull the fit are dropped by the rule of
/// `prune` (up to a quarter of them) and the pose refitted; refused above `max_rms` px RMS.
pub(crate) fn fit_sheet(
    what: &str,
    camera: &Camera<f64>,
    layout: &[Point2<f64>],
    features: &[Blob],
    a: &Assignment,
    radius: f64,
    prune: Prune,
    start: Option<&[usize]>,
    max_rms: f64,
) -> Result<SheetFit, CalibError> {
    let found: Vec<usize> = (0..layout.len())
        .filter(|&i| a.blob_of[i].is_some())
        .collect();
    let pixel = |i: usize| a.blob_of[i].map(|b| features[b].centre);
    let too_few = |used: &[usize]| CalibError::TooFewMarkers {
        what: what.to_string(),
        found: used.len(),
        expected: layout.len(),
        needed: 4,
        missing: (0..layout.len()).filter(|i| !used.contains(i)).collect(),
    };
    if found.len() < 4 {
        return Err(too_few(&found));
    }
    // Pose, RMS and residuals from a subset of the layout.
    let view_of = |used: &[usize]| -> (Vec<Point2<f64>>, Vec<Point2<f64>>) {
        (
            used.iter().map(|&i| layout[i]).collect(),
            used.iter().map(|&i| pixel(i).expect("found")).collect(),
        )
    };
    let solve = |used: &[usize]| -> Result<SubsetFit, CalibError> {
        let (l, p) = view_of(used);
        let view = TargetImage {
            layout: &l,
            pixels: &p,
        };
        let mut pose = [initial_pose(camera, &view).map_err(geom(what))?];
        let r = refine(camera, Free::NONE, &[view], &mut pose, radius).map_err(geom(what))?;
        let mut res = vec![Vector2::zeros(); l.len()];
        residuals(camera, &view, &pose[0], radius, &mut res).map_err(geom(what))?;
        Ok((pose[0], r.rms_px, res))
    };
    // All found markers, or those an earlier fit kept.
    let mut used: Vec<usize> = match start {
        Some(s) => found.iter().copied().filter(|i| s.contains(i)).collect(),
        None => found.clone(),
    };
    if used.len() < 4 {
        return Err(too_few(&used));
    }
    let (mut pose, mut rms, mut res) = solve(&used)?;
    // A marker partly hidden by the object, or a stray blob, pulls the fit: the one whose
    // removal leaves the best fit is left out while the rule of `prune` says so (at most a
    // quarter of the layout, keeping four).
    while used.len() > 4 && found.len() - used.len() < layout.len().div_ceil(4) {
        if prune == Prune::Halving && rms <= 0.15 {
            break;
        }
        let mut best: Option<(usize, SubsetFit)> = None;
        for k in 0..used.len() {
            let mut trial = used.clone();
            trial.remove(k);
            // Without a marker the rest fit at least as well, unless their pose went astray
            // (four markers nearly on a line).
            if let Ok(fit) = solve(&trial)
                && fit.1 <= rms
                && best.as_ref().is_none_or(|b| fit.1 < b.1.1)
            {
                best = Some((k, fit));
            }
        }
        let Some((k, fit)) = best else { break };
        let drop = match prune {
            // While candidate identifications are compared: when that more than halves a
            // poor fit's error.
            Prune::Halving => fit.1 < rms / 2.0,
            // The chosen identification: with few markers a sheet's pose absorbs most of one
            // marker's error (the 360° demo's board: a marker a pixel off left 0.23 px of
            // residual), so the marker is predicted from the others' fit, and left out when
            // that misses it by more than PULL_PX and PULL_SPREADS times their RMS.
            Prune::Predicted => {
                let (l, p) = view_of(&used);
                let view = TargetImage {
                    layout: &l,
                    pixels: &p,
                };
                let mut predicted = vec![Vector2::zeros(); used.len()];
                residuals(camera, &view, &fit.0, radius, &mut predicted).map_err(geom(what))?;
                let miss = predicted[k].norm();
                miss > PULL_PX && miss > PULL_SPREADS * fit.1
            }
        };
        if !drop {
            break;
        }
        used.remove(k);
        (pose, rms, res) = fit;
    }
    if rms > max_rms {
        return Err(CalibError::PoorFit {
            what: what.to_string(),
            rms_px: rms,
            limit_px: max_rms,
        });
    }
    let markers = (0..layout.len())
        .map(|i| MarkerFit {
            sheet: layout[i],
            pixel: pixel(i),
            residual: used.iter().position(|&u| u == i).map(|k| res[k]),
            dropped: found.contains(&i) && !used.contains(&i),
        })
        .collect();
    let plane = pose.plane().map_err(geom(what))?;
    Ok(SheetFit {
        pose,
        plane,
        markers,
        rms_px: rms,
    })
}

/// The features as an ideal pinhole camera would see them (distortion removed, back in pixels):
/// a sheet's markers then fit one homography exactly, however strong the lens distortion, and
/// identification can keep its tolerance tight. A feature that cannot be undistorted stays
/// where it is (it will not fit).
pub(crate) fn undistorted(features: &[Blob], camera: &Camera<f64>) -> Vec<Blob> {
    let pp = camera.principal_point();
    features
        .iter()
        .map(|b| {
            let mut u = *b;
            if let Ok(n) = camera.undistort(&b.centre) {
                u.centre = Point2::new(camera.fx() * n.x + pp.x, camera.fy() * n.y + pp.y);
            }
            u
        })
        .collect()
}

/// How the board planes were obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardMethod {
    /// Every marker of a sheet with its known layout (homography, refined with the dot model).
    LayoutPose,
    /// The paper's construction: two lines of three markers per sheet (eq. 1–6).
    PaperLines,
}

impl BoardMethod {
    /// Name used in the calibration file.
    pub fn name(self) -> &'static str {
        match self {
            BoardMethod::LayoutPose => "layout-pose",
            BoardMethod::PaperLines => "paper-lines",
        }
    }
}

/// Both board planes from one image of the board.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardFit {
    /// Image size.
    pub size: (u32, u32),
    /// The left and right sheets by the layout pose.
    pub sheets: [SheetFit; 2],
    /// The planes by the paper's three-point lines, where the layout is the paper's and all six
    /// markers of a sheet were found.
    pub paper: [Option<Plane<f64>>; 2],
    /// The board from the layout poses (crease `L_c`, angle).
    pub board: Board<f64>,
}
