//! Intrinsics from several images of a planar grid target (dots or a chessboard), with a line of
//! outcome per image.
//!
//! 1. **Find** the grid in each image ([`find_grid`]): features, then a lattice grown through
//!    them ([`super::lattice`]) and placed on the target; a grid larger than the target given is
//!    an error that says what was seen.
//! 2. **Refuse** what cannot help: images without the grid, of another size, repeating another
//!    image's view.
//! 3. **Start** with Zhang's closed form; if it fails, the images that disagree are found by
//!    leaving each out, named and refused, and it is tried again.
//! 4. **Refine** intrinsics and poses jointly; features far off the fit (a false corner on the
//!    board's edge or on clutter) are dropped, images whose error stays far above the others'
//!    are refused, and the fit is repeated until nothing changes.

use image::GrayImage;
use scanner_core::Camera;
use scanner_core::calib::bundle::{initial_camera, initial_pose, refine, residuals};
use scanner_core::calib::{Free, TargetImage};
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Point2, Vector2};

use super::aruco::CharucoBoard;
use super::charuco::find_charuco;
use super::corners::{CornerConfig, find_corners};
use super::detect::{Blob, DetectConfig, find_markers};
use super::lattice::{MAX_FEATURES, Placement, lattices};
use super::{CalibError, Target};
use crate::error::geom;

/// A feature is dropped from the fit when its reprojection error exceeds this many times the
/// median error of all features…
pub const OUTLIER_OF_MEDIAN: f64 = 5.0;
/// …and this many pixels (the median of a good fit can be tiny).
pub const OUTLIER_MIN_PX: f64 = 0.5;
/// An image is refused when its RMS error exceeds this many times the median image's…
pub const VIEW_RMS_OF_MEDIAN: f64 = 3.0;
/// …and this many pixels.
pub const VIEW_RMS_MIN_PX: f64 = 0.5;
/// A calibration whose RMS error over all features exceeds this (pixels) is not one camera's:
/// a webcam's real photographs fit within 0.2–0.5 px.
pub const MAX_RMS_PX: f64 = 1.0;
/// Two images whose common features lie within this RMS distance (pixels) show the same view.
pub const SAME_VIEW_PX: f64 = 1.0;

/// Identified features of one image: `(layout index, pixel)`.
pub type Found = Vec<(usize, Point2<f64>)>;

/// The target as found in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundGrid {
    /// Every feature detected (dots or corners), identified or not.
    pub features: Vec<Blob>,
    /// The identified ones: `(layout index, pixel)`.
    pub found: Found,
    /// Columns × rows of the target seen.
    pub extent: (usize, usize),
    /// Every grid point in that rectangle was found.
    pub complete: bool,
}

/// The features of a target found in one image.
///
/// # Errors
/// [`CalibError::NoMarkers`] (nothing detected), [`CalibError::TooManyFeatures`],
/// [`CalibError::NoGrid`], [`CalibError::CountMismatch`] (a grid larger than the target
/// described), [`CalibError::TooFewMarkers`] (less than half the target).
pub fn find_grid(img: &GrayImage, target: &Target) -> Result<FoundGrid, CalibError> {
    if let Target::Charuco(b) = target {
        return find_charuco_grid(img, b);
    }
    let (features, rejected) = match target {
        Target::Dots(_) => {
            let det = find_markers(img, &DetectConfig::default());
            (det.blobs, det.rejected.len())
        }
        Target::Chessboard { .. } | Target::Charuco(_) => {
            (find_corners(img, &CornerConfig::default()), 0)
        }
    };
    if features.len() < 4 {
        return Err(CalibError::NoMarkers {
            found: rejected,
            hint: "is the calibration target in view and lit?",
        });
    }
    if features.len() > MAX_FEATURES {
        return Err(CalibError::TooManyFeatures {
            found: features.len(),
            limit: MAX_FEATURES,
        });
    }
    let (cols, rows) = target.grid();
    let layout_len = cols * rows;
    let found_lattices = lattices(&features, (cols, rows));
    let Some(largest) = found_lattices.first() else {
        return Err(CalibError::NoGrid {
            what: target.name().into(),
            features: features.len(),
        });
    };
    // Of the lattices that fit the target, the one placing the most features (a complete one
    // first): clutter beside the target can make a larger lattice that fits too (a checked
    // cloth askew, partly out of the picture), but not one with more of the target's corners.
    // Else the largest with a line of clutter beside it left out ([`Lattice::place_in`]).
    let dark_even = target.dark_even();
    let placed = found_lattices
        .iter()
        .filter_map(|l| l.place(&features, cols, rows, dark_even).ok())
        .fold(None, |best: Option<Placement>, p| match best {
            Some(b) if (b.complete, b.found.len()) >= (p.complete, p.found.len()) => Some(b),
            _ => Some(p),
        })
        .map_or_else(
            || largest.place_in(&features, (cols, rows), dark_even, true),
            Ok,
        )
        .map_err(|e| CalibError::CountMismatch {
            what: target.name().into(),
            seen: e.seen,
            given: (cols, rows),
            unit: target.unit(),
        })?;
    let found: Found = placed
        .found
        .iter()
        .map(|&(k, f)| (k, features[f].centre))
        .collect();
    let needed = (layout_len / 2).max(4);
    if found.len() < needed {
        return Err(too_few(target.name(), &found, layout_len, needed));
    }
    Ok(FoundGrid {
        features,
        found,
        extent: placed.extent,
        complete: placed.complete,
    })
}

/// Fewer of a target's `layout_len` features found than `needed`: the error, with the missing.
fn too_few(what: &str, found: &Found, layout_len: usize, needed: usize) -> CalibError {
    CalibError::TooFewMarkers {
        what: what.into(),
        found: found.len(),
        expected: layout_len,
        needed,
        missing: (0..layout_len)
            .filter(|i| !found.iter().any(|(k, _)| k == i))
            .collect(),
    }
}

/// The fewest corners of a ChArUco board that make a view for the intrinsics (a partial view
/// counts, but a corner or two cannot pose the board).
pub const MIN_CHARUCO_CORNERS: usize = 6;

/// [`find_grid`] for a ChArUco board: its corners named by their markers, however few of the
/// board are in view (at least a quarter, and [`MIN_CHARUCO_CORNERS`]).
fn find_charuco_grid(img: &GrayImage, board: &CharucoBoard) -> Result<FoundGrid, CalibError> {
    let quads = crate::aruco::quads(img, crate::aruco::MIN_QUAD_SIDE_PX);
    let seen = find_charuco(img, &quads, board);
    if !seen.markers.repeated.is_empty() {
        return Err(CalibError::RepeatedIds {
            what: "the target".into(),
            ids: seen.markers.repeated.iter().map(|&i| i as u32).collect(),
            dictionary: board.dictionary.name().to_string(),
        });
    }
    let layout_len = board.corner_count();
    let needed = (layout_len / 4).max(MIN_CHARUCO_CORNERS);
    let found: Found = seen.corners.clone();
    if found.len() < needed {
        if seen.markers.markers.is_empty() && seen.corners.is_empty() {
            return Err(CalibError::NoMarkers {
                found: seen.markers.unread,
                hint: "is the ChArUco board in view, lit, and of the dictionary given?",
            });
        }
        return Err(too_few("ChArUco board", &found, layout_len, needed));
    }
    let per = board.corners_per_row().max(1);
    let span = |f: fn(usize, usize) -> usize| {
        let v: Vec<usize> = found.iter().map(|&(k, _)| f(k, per)).collect();
        v.iter().max().unwrap_or(&0) - v.iter().min().unwrap_or(&0) + 1
    };
    let extent = (span(|k, per| k % per), span(|k, per| k / per));
    Ok(FoundGrid {
        features: found
            .iter()
            .map(|&(_, centre)| Blob::point(centre))
            .collect(),
        complete: found.len() == extent.0 * extent.1,
        found,
        extent,
    })
}

/// One image's part in the fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageFit {
    /// Layout index and pixel of every feature used.
    pub found: Found,
    /// Their reprojection errors (predicted − found), pixels.
    pub residuals: Vec<Vector2<f64>>,
    /// Identified but left out of the fit: layout index, pixel, reprojection error (px).
    pub dropped: Vec<(usize, Point2<f64>, f64)>,
    /// Target pose.
    pub pose: Pose,
    /// RMS reprojection error of the features used, pixels.
    pub rms_px: f64,
    /// Largest reprojection error of the features used, pixels.
    pub max_px: f64,
}

/// What became of one image.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageReport {
    /// The grid found in it (`None`: not found, see `status`).
    pub grid: Option<FoundGrid>,
    /// Used with its fit, or refused and why.
    pub status: Result<ImageFit, CalibError>,
    /// Its size where it was one pixel larger than the rest and cropped to theirs (its last
    /// column or row dropped).
    pub cropped_from: Option<(u32, u32)>,
}

/// The most common size among `images` (the first among equals; 0×0 for none).
fn common_size(images: &[GrayImage]) -> (u32, u32) {
    let sizes: Vec<(u32, u32)> = images.iter().map(GrayImage::dimensions).collect();
    let count = |s: &(u32, u32)| sizes.iter().filter(|t| *t == s).count();
    sizes
        .iter()
        .copied()
        .fold(None, |best: Option<(u32, u32)>, s| match best {
            Some(b) if count(&b) >= count(&s) => Some(b),
            _ => Some(s),
        })
        .unwrap_or((0, 0))
}

/// Intrinsics from several images: every image's outcome, and the result.
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicsOutcome {
    /// Image size (of the first image).
    pub size: (u32, u32),
    /// Per image, in the order given.
    pub images: Vec<ImageReport>,
    /// The camera and the RMS reprojection error over all features used (pixels).
    pub result: Result<(Camera<f64>, f64), CalibError>,
    /// The intrinsics estimated (the others held at their start).
    pub free: Free,
}

/// Full intrinsics from several images of a grid target.
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicsFit {
    /// Image size.
    pub size: (u32, u32),
    /// The camera.
    pub camera: Camera<f64>,
    /// RMS reprojection error over all features used, pixels.
    pub rms_px: f64,
    /// Per image (in the order given; `Err` for an image that was left out, and why).
    pub views: Vec<Result<ImageFit, CalibError>>,
    /// The intrinsics estimated (the others held at their start).
    pub free: Free,
}

impl IntrinsicsOutcome {
    /// The fit, or the error that stopped it.
    ///
    /// # Errors
    /// The calibration's error.
    pub fn into_fit(self) -> Result<IntrinsicsFit, CalibError> {
        let (camera, rms_px) = self.result?;
        Ok(IntrinsicsFit {
            size: self.size,
            camera,
            rms_px,
            views: self.images.into_iter().map(|r| r.status).collect(),
            free: self.free,
        })
    }
}

/// Intrinsics from images of a grid target; see [`intrinsics_outcome`] for every image's
/// outcome also when the calibration fails. `free` chooses the estimated parameters (normally
/// [`Free::ALL`]).
///
/// # Errors
/// [`CalibError::TooFewMarkers`] with fewer than three usable images,
/// [`CalibError::ClosedForm`] or [`CalibError::Geometry`] if the solution fails.
pub fn intrinsics(
    images: &[GrayImage],
    target: &Target,
    free: Free,
) -> Result<IntrinsicsFit, CalibError> {
    intrinsics_outcome(images, target, free).into_fit()
}

/// Columns and rows of the cells [`Coverage`] divides the image into.
pub const COVER_CELLS: (usize, usize) = (8, 6);

/// Where in the image the features of the images used fell: the image divided into
/// [`COVER_CELLS`], each cell covered when some used feature lies in it. The lens's distortion
/// is measured where features are and extrapolated elsewhere, and it grows fastest towards the
/// corners — where the board's markers and the laser's stripe on it lie: a target photographed
/// only in the middle of the view leaves the board measured through a guessed distortion.
#[derive(Debug, Clone, PartialEq)]
pub struct Coverage {
    /// Per cell, row by row: some used feature lies in it.
    pub covered: Vec<bool>,
}

impl Coverage {
    /// The coverage of the features `fit` used, over its image.
    pub fn of(fit: &IntrinsicsFit) -> Coverage {
        Coverage::of_views(fit.size, fit.views.iter().flatten())
    }

    /// The coverage of the features `views` used, over an image of `size`.
    pub fn of_views<'a>(size: (u32, u32), views: impl Iterator<Item = &'a ImageFit>) -> Coverage {
        let (cols, rows) = COVER_CELLS;
        let (w, h) = (f64::from(size.0.max(1)), f64::from(size.1.max(1)));
        let mut covered = vec![false; cols * rows];
        for v in views {
            for (_, p) in &v.found {
                let (c, r) = (p.x / w * cols as f64, p.y / h * rows as f64);
                if c >= 0.0 && r >= 0.0 && c < cols as f64 && r < rows as f64 {
                    covered[r as usize * cols + c as usize] = true;
                }
            }
        }
        Coverage { covered }
    }

    /// Covered cells and all cells.
    pub fn cells(&self) -> (usize, usize) {
        (
            self.covered.iter().filter(|&&c| c).count(),
            self.covered.len(),
        )
    }

    /// Covered cells on the image's border (its outer ring) and all border cells.
    pub fn border(&self) -> (usize, usize) {
        let (cols, rows) = COVER_CELLS;
        let ring = |k: usize| {
            let (c, r) = (k % cols, k / cols);
            c == 0 || r == 0 || c + 1 == cols || r + 1 == rows
        };
        let on: Vec<bool> = (0..self.covered.len())
            .filter(|&k| ring(k))
            .map(|k| self.covered[k])
            .collect();
        (on.iter().filter(|&&c| c).count(), on.len())
    }

    /// The image's corners (top left, top right, bottom left, bottom right) whose cell no used
    /// feature reached.
    pub fn empty_corners(&self) -> Vec<&'static str> {
        let (cols, rows) = COVER_CELLS;
        [
            (0, "top left"),
            (cols - 1, "top right"),
            ((rows - 1) * cols, "bottom left"),
            (rows * cols - 1, "bottom right"),
        ]
        .into_iter()
        .filter(|&(k, _)| !self.covered[k])
        .map(|(_, name)| name)
        .collect()
    }
}

/// Status of an image whose grid was found, until the fit says more.
fn pending() -> Result<ImageFit, CalibError> {
    Err(CalibError::NotSolved)
}

fn is_pending(r: &ImageReport) -> bool {
    matches!(r.status, Err(CalibError::NotSolved))
}

/// A usable image: its index and its correspondences (sheet mm, pixels, layout indices).
struct Active {
    image: usize,
    layout: Vec<Point2<f64>>,
    pixels: Vec<Point2<f64>>,
    index: Vec<usize>,
    dropped: Vec<(usize, Point2<f64>, f64)>,
}

impl Active {
    fn view(&self) -> TargetImage<'_> {
        TargetImage {
            layout: &self.layout,
            pixels: &self.pixels,
        }
    }
}

/// Every image's outcome and the intrinsics (see the module docs for the steps).
pub fn intrinsics_outcome(images: &[GrayImage], target: &Target, free: Free) -> IntrinsicsOutcome {
    let (size, reports) = find_grids(images, target);
    solve_outcome(size, reports, target, free)
}

/// The intrinsics from grids already found (another detector's corners, say: each image's
/// `FoundGrid` with its identified features), by the same solver as [`intrinsics_outcome`], so
/// that corner finders can be compared on one fit. `size` is the images' size.
pub fn intrinsics_from_grids(
    size: (u32, u32),
    grids: Vec<FoundGrid>,
    target: &Target,
    free: Free,
) -> IntrinsicsOutcome {
    let reports = grids
        .into_iter()
        .map(|g| ImageReport {
            grid: Some(g),
            status: pending(),
            cropped_from: None,
        })
        .collect();
    solve_outcome(size, reports, target, free)
}

/// As [`intrinsics_outcome`] with every parameter free, unless no feature used lies on the
/// image's border ([`Coverage::border`]): then `k3` is fixed at 0 and the fit repeated. `k3`
/// weighs the sixth power of the distance from the centre, so only features near the border
/// tell it from `k1` and `k2`; from the middle alone it takes any value that bends the rest
/// right there, and the extrapolated distortion goes wrong where the board and its stripes lie
/// (the rig's 24 shots of the 360° scene: `k3` −0.052 where the lens has none, 0.75 px off at
/// 0.6 of the focal length from the centre; fixed, `k1` and `k2` land within 0.0007 of the
/// lens's). Returns the outcome and whether `k3` was fixed.
pub fn intrinsics_auto(images: &[GrayImage], target: &Target) -> (IntrinsicsOutcome, bool) {
    let (size, reports) = find_grids(images, target);
    let all = solve_outcome(size, reports.clone(), target, Free::ALL);
    let used = all.images.iter().filter_map(|r| r.status.as_ref().ok());
    if all.result.is_ok() && Coverage::of_views(size, used).border().0 == 0 {
        (solve_outcome(size, reports, target, Free::NO_K3), true)
    } else {
        (all, false)
    }
}

/// The images' size (the most common; the first among equals) and each image's grid, or why
/// there is none. An image at most one pixel wider and taller than that is a known quirk of some
/// cameras' files (1281×721 among 1280×720): its last column and row are dropped, and its report
/// says so. Any other size is refused.
fn find_grids(images: &[GrayImage], target: &Target) -> ((u32, u32), Vec<ImageReport>) {
    let size = common_size(images);
    let mut reports: Vec<ImageReport> = images
        .iter()
        .map(|img| {
            let (w, h) = img.dimensions();
            let cropped_from = ((w, h) != size
                && (size.0..=size.0 + 1).contains(&w)
                && (size.1..=size.1 + 1).contains(&h))
            .then_some((w, h));
            if cropped_from.is_none() && (w, h) != size {
                return ImageReport {
                    grid: None,
                    status: Err(CalibError::MixedSizes {
                        found: (w, h),
                        most: size,
                    }),
                    cropped_from,
                };
            }
            let found = match cropped_from {
                Some(_) => find_grid(
                    &image::imageops::crop_imm(img, 0, 0, size.0, size.1).to_image(),
                    target,
                ),
                None => find_grid(img, target),
            };
            match found {
                Ok(g) => ImageReport {
                    grid: Some(g),
                    status: pending(),
                    cropped_from,
                },
                Err(e) => ImageReport {
                    grid: None,
                    status: Err(e),
                    cropped_from,
                },
            }
        })
        .collect();
    refuse_repeated_views(&mut reports);
    (size, reports)
}

/// The intrinsics (parameters `free`) from the images' grids.
fn solve_outcome(
    size: (u32, u32),
    mut reports: Vec<ImageReport>,
    target: &Target,
    free: Free,
) -> IntrinsicsOutcome {
    let result = match count_too_large(&reports, target) {
        Some(e) => Err(e),
        None => solve(&mut reports, &target.points(), target.radius(), size, free),
    };
    IntrinsicsOutcome {
        size,
        images: reports,
        result,
        free,
    }
}

/// Most images (three in four) show the same complete grid, smaller than the target given, and
/// none a larger complete one: the count is wrong (a chessboard's squares given as its corners,
/// say), not the images. (A stray feature may join a grid when the target given leaves room for
/// it: such an image is not complete and does not count against.) Not asked of a ChArUco
/// board, whose corners are named by their markers and may be seen in part.
fn count_too_large(reports: &[ImageReport], target: &Target) -> Option<CalibError> {
    if let Target::Charuco(_) = target {
        return None;
    }
    let grids: Vec<&FoundGrid> = reports.iter().filter_map(|r| r.grid.as_ref()).collect();
    let given = target.grid();
    let key = |e: (usize, usize)| (e.0.min(e.1), e.0.max(e.1));
    let complete: Vec<(usize, usize)> = grids
        .iter()
        .filter(|g| g.complete)
        .map(|g| key(g.extent))
        .collect();
    let (c, r) = *complete
        .iter()
        .max_by_key(|e| complete.iter().filter(|f| f == e).count())?;
    let same = complete.iter().filter(|e| **e == (c, r)).count();
    let larger = complete.iter().any(|e| e.0 * e.1 > c * r);
    if grids.len() < 2 || 4 * same < 3 * grids.len() || larger || c * r >= given.0 * given.1 {
        return None;
    }
    let seen = if given.0 <= given.1 { (c, r) } else { (r, c) };
    let hint = match target {
        Target::Chessboard { .. } => format!(
            " (a chessboard of {}×{} squares has {}×{} inner corners)",
            seen.0 + 1,
            seen.1 + 1,
            seen.0,
            seen.1
        ),
        Target::Dots(_) | Target::Charuco(_) => String::new(),
    };
    Some(CalibError::CountTooLarge {
        seen,
        given,
        unit: target.unit(),
        hint,
    })
}

/// Refuses an image whose features lie where another image's do: a repeated view adds no
/// constraint but counts as one, and three copies of one view leave the focal length free.
fn refuse_repeated_views(reports: &mut [ImageReport]) {
    for j in 1..reports.len() {
        let Some(gj) = &reports[j].grid else { continue };
        let same = (0..j).find(|&i| {
            is_pending(&reports[i])
                && reports[i].grid.as_ref().is_some_and(|gi| {
                    let d: Vec<f64> = gj
                        .found
                        .iter()
                        .filter_map(|(k, p)| {
                            gi.found
                                .iter()
                                .find(|(ki, _)| ki == k)
                                .map(|(_, q)| (p - q).norm_squared())
                        })
                        .collect();
                    d.len() >= 4 && (d.iter().sum::<f64>() / d.len() as f64).sqrt() < SAME_VIEW_PX
                })
        });
        if let Some(i) = same
            && is_pending(&reports[j])
        {
            reports[j].status = Err(CalibError::SameView { other: i });
        }
    }
}

fn too_few_images(reports: &[ImageReport], active: usize) -> CalibError {
    CalibError::TooFewImages {
        usable: active,
        given: reports.len(),
        needed: 3,
    }
}

/// Closed form, refinement and outlier rejection over the images still pending.
fn solve(
    reports: &mut [ImageReport],
    layout: &[Point2<f64>],
    radius: f64,
    size: (u32, u32),
    free: Free,
) -> Result<(Camera<f64>, f64), CalibError> {
    let mut active = pending_views(reports, layout);
    let mut camera = closed_form(reports, &mut active, size)?;
    let images = active.len();
    let needed = (layout.len() / 2).max(4);
    for _round in 0..30 {
        if active.len() < 3 {
            return Err(too_few_images(reports, active.len()));
        }
        let round = fit_round(&camera, free, &active, radius)?;
        camera = round.camera;
        let limit = (OUTLIER_OF_MEDIAN * median(round.errs.iter().flatten())).max(OUTLIER_MIN_PX);
        let view_limit =
            (VIEW_RMS_OF_MEDIAN * median(round.errs.iter().map(|e| rms(e)))).max(VIEW_RMS_MIN_PX);
        // Features far off the fit first; an image whose rest still fits badly goes after.
        let mut changed = false;
        for (a, e) in active.iter_mut().zip(&round.errs) {
            changed |= a.drop_beyond(e, limit);
        }
        let before = active.len();
        active = refuse_poor_views(
            active,
            &round.errs,
            reports,
            view_limit,
            needed,
            layout.len(),
        );
        if active.len() < before {
            // Features dropped while a refused image still pulled the fit get another chance.
            restore_dropped(&mut active, layout);
            continue;
        }
        if changed {
            continue;
        }
        if round.rms_px > MAX_RMS_PX {
            // No single image stands out, yet the whole does not fit one camera: leave out the
            // worst image while at most a third are gone; beyond that, refuse.
            let refused = images - active.len();
            if active.len() <= 3 || 3 * (refused + 1) > images {
                return Err(CalibError::PoorCalibration {
                    rms_px: round.rms_px,
                    limit_px: MAX_RMS_PX,
                });
            }
            let worst = round
                .errs
                .iter()
                .enumerate()
                .max_by(|a, b| rms(a.1).total_cmp(&rms(b.1)))
                .map_or(0, |(i, _)| i);
            let a = active.remove(worst);
            reports[a.image].status = Err(CalibError::ResidualTooHigh {
                rms_px: rms(&round.errs[worst]),
                limit_px: MAX_RMS_PX,
            });
            restore_dropped(&mut active, layout);
            continue;
        }
        record_fits(reports, &active, &round.poses, &camera, radius)?;
        return Ok((camera, round.rms_px));
    }
    Err(CalibError::Unstable)
}

/// The images still pending, with their correspondences.
fn pending_views(reports: &[ImageReport], layout: &[Point2<f64>]) -> Vec<Active> {
    reports
        .iter()
        .enumerate()
        .filter(|(_, r)| is_pending(r))
        .filter_map(|(i, r)| {
            let g = r.grid.as_ref()?;
            Some(Active {
                image: i,
                layout: g.found.iter().map(|(k, _)| layout[*k]).collect(),
                pixels: g.found.iter().map(|(_, p)| *p).collect(),
                index: g.found.iter().map(|(k, _)| *k).collect(),
                dropped: Vec::new(),
            })
        })
        .collect()
}

/// One refinement over the active images.
struct Round {
    camera: Camera<f64>,
    rms_px: f64,
    poses: Vec<Pose>,
    /// Per image, per feature: the reprojection error, pixels.
    errs: Vec<Vec<f64>>,
}

fn fit_round(
    camera: &Camera<f64>,
    free: Free,
    active: &[Active],
    radius: f64,
) -> Result<Round, CalibError> {
    let views: Vec<TargetImage> = active.iter().map(Active::view).collect();
    let mut poses: Vec<Pose> = views
        .iter()
        .map(|v| initial_pose(camera, v))
        .collect::<Result<_, _>>()
        .map_err(geom("intrinsics: initial poses"))?;
    let r =
        refine(camera, free, &views, &mut poses, radius).map_err(geom("intrinsics: refinement"))?;
    let mut errs: Vec<Vec<f64>> = Vec::with_capacity(views.len());
    for (v, p) in views.iter().zip(&poses) {
        let mut res = vec![Vector2::zeros(); v.layout.len()];
        residuals(&r.camera, v, p, radius, &mut res).map_err(geom("intrinsics: residuals"))?;
        errs.push(res.iter().map(|e| e.norm()).collect());
    }
    Ok(Round {
        camera: r.camera,
        rms_px: r.rms_px,
        poses,
        errs,
    })
}

fn rms(e: &[f64]) -> f64 {
    (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt()
}

/// The upper median (0 for none).
fn median(values: impl Iterator<Item = impl std::borrow::Borrow<f64>>) -> f64 {
    let mut v: Vec<f64> = values.map(|x| *x.borrow()).collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

impl Active {
    /// Moves the features whose error `errs` exceeds `limit` to `dropped`; true if any did.
    fn drop_beyond(&mut self, errs: &[f64], limit: f64) -> bool {
        if errs.iter().all(|&x| x <= limit) {
            return false;
        }
        let mut n = 0;
        for (i, &e) in errs.iter().enumerate() {
            if e <= limit {
                self.layout[n] = self.layout[i];
                self.pixels[n] = self.pixels[i];
                self.index[n] = self.index[i];
                n += 1;
            } else {
                self.dropped.push((self.index[i], self.pixels[i], e));
            }
        }
        self.layout.truncate(n);
        self.pixels.truncate(n);
        self.index.truncate(n);
        true
    }
}

/// Refuses the images fitting worse than `view_limit` (RMS of `errs`, measured before the
/// drops) or left with fewer than `needed` features; returns the rest.
fn refuse_poor_views(
    active: Vec<Active>,
    errs: &[Vec<f64>],
    reports: &mut [ImageReport],
    view_limit: f64,
    needed: usize,
    layout_len: usize,
) -> Vec<Active> {
    let mut kept = Vec::with_capacity(active.len());
    for (a, e) in active.into_iter().zip(errs) {
        let r = rms(e);
        let refused = if r > view_limit {
            Some(CalibError::ResidualTooHigh {
                rms_px: r,
                limit_px: view_limit,
            })
        } else if a.layout.len() < needed {
            Some(CalibError::TooFewMarkers {
                what: "after dropping features off the fit".into(),
                found: a.layout.len(),
                expected: layout_len,
                needed,
                missing: a.dropped.iter().map(|d| d.0).collect(),
            })
        } else {
            None
        };
        match refused {
            Some(e) => reports[a.image].status = Err(e),
            None => kept.push(a),
        }
    }
    kept
}

/// Each used image's report: its features, the ones dropped, its pose and residuals.
fn record_fits(
    reports: &mut [ImageReport],
    active: &[Active],
    poses: &[Pose],
    camera: &Camera<f64>,
    radius: f64,
) -> Result<(), CalibError> {
    for (a, p) in active.iter().zip(poses) {
        let mut res = vec![Vector2::zeros(); a.layout.len()];
        let rms_px = residuals(camera, &a.view(), p, radius, &mut res)
            .map_err(geom("intrinsics: residuals"))?;
        reports[a.image].status = Ok(ImageFit {
            found: a
                .index
                .iter()
                .copied()
                .zip(a.pixels.iter().copied())
                .collect(),
            dropped: a.dropped.clone(),
            pose: *p,
            rms_px,
            max_px: res.iter().map(|r| r.norm()).fold(0.0, f64::max),
            residuals: res,
        });
    }
    Ok(())
}

/// Puts every dropped feature back into its image's correspondences.
fn restore_dropped(active: &mut [Active], layout: &[Point2<f64>]) {
    for a in active {
        for (k, p, _) in a.dropped.drain(..) {
            a.index.push(k);
            a.pixels.push(p);
            a.layout.push(layout[k]);
        }
    }
}

/// Zhang's closed form over the active images; when it fails, each image is left out in turn,
/// and the ones whose absence lets it succeed are refused as disagreeing.
fn closed_form(
    reports: &mut [ImageReport],
    active: &mut Vec<Active>,
    size: (u32, u32),
) -> Result<Camera<f64>, CalibError> {
    let run = |set: &[&Active]| {
        let views: Vec<TargetImage> = set.iter().map(|a| a.view()).collect();
        initial_camera(&views, size.0, size.1)
    };
    loop {
        if active.len() < 3 {
            return Err(too_few_images(reports, active.len()));
        }
        let all: Vec<&Active> = active.iter().collect();
        let first = match run(&all) {
            Ok(c) => return Ok(c),
            Err(e) => e,
        };
        let culprit = (0..active.len()).find(|&k| {
            let rest: Vec<&Active> = active
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, a)| a)
                .collect();
            rest.len() >= 3 && run(&rest).is_ok()
        });
        match culprit {
            Some(k) => {
                let a = active.remove(k);
                reports[a.image].status = Err(CalibError::Disagrees);
            }
            None => {
                return Err(CalibError::ClosedForm {
                    images: active.iter().map(|a| a.image).collect(),
                    source: first,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanner_core::Distortion;
    use scanner_core::nalgebra::{Point3, Rotation3, Vector3};

    fn grid() -> Vec<Point2<f64>> {
        (0..54)
            .map(|k| Point2::new((k % 9) as f64 * 25.0, (k / 9) as f64 * 25.0))
            .collect()
    }

    fn view(cam: &Camera<f64>, turn: [f64; 3], at: [f64; 3]) -> Vec<Point2<f64>> {
        let r = Rotation3::from_euler_angles(
            turn[0].to_radians(),
            turn[1].to_radians(),
            turn[2].to_radians(),
        );
        grid()
            .iter()
            .map(|p| {
                cam.project(
                    &(Point3::from(
                        r * Vector3::new(p.x - 100.0, p.y - 62.5, 0.0) + Vector3::from(at),
                    )),
                )
                .unwrap()
            })
            .collect()
    }

    #[test]
    fn a_view_that_breaks_the_closed_form_is_named_and_the_rest_calibrate() {
        let cam = Camera::new(540.0, 540.0, 320.0, 240.0, Distortion::none()).unwrap();
        let turns = [
            [20.0, 10.0, 0.0],
            [-25.0, 5.0, 10.0],
            [5.0, -30.0, 0.0],
            [15.0, 25.0, -10.0],
        ];
        let mut views: Vec<Vec<Point2<f64>>> = turns
            .iter()
            .map(|t| view(&cam, *t, [0.0, 0.0, 500.0]))
            .collect();
        // A view no camera can make: stretched across and squeezed along its columns, more at
        // each column.
        let bad = views[0]
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let s = 1.0 + 0.08 * (k % 9) as f64;
                Point2::new(320.0 + (p.x - 320.0) * s * s, 240.0 + (p.y - 240.0) / s)
            })
            .collect();
        views.insert(2, bad);
        let layout = grid();
        let refs: Vec<TargetImage> = views
            .iter()
            .map(|p| TargetImage {
                layout: &layout,
                pixels: p,
            })
            .collect();
        assert!(
            initial_camera(&refs, 640, 480).is_err(),
            "the test needs a failing start"
        );
        let mut reports: Vec<ImageReport> = views
            .iter()
            .map(|p| ImageReport {
                grid: Some(FoundGrid {
                    features: Vec::new(),
                    found: p.iter().copied().enumerate().collect(),
                    extent: (9, 6),
                    complete: true,
                }),
                status: pending(),
                cropped_from: None,
            })
            .collect();
        let (got, rms) = solve(&mut reports, &layout, 0.0, (640, 480), Free::ALL).unwrap();
        assert_eq!(reports[2].status, Err(CalibError::Disagrees));
        assert!(
            reports
                .iter()
                .enumerate()
                .all(|(i, r)| i == 2 || r.status.is_ok())
        );
        assert!(
            (got.fx() - 540.0).abs() < 1e-3 && rms < 1e-6,
            "{} {rms}",
            got.fx()
        );
    }
}
