//! Why a calibration step failed ([`CalibError`]): each names what was expected and what was
//! found.

use scanner_core::GeomError;

/// Why a calibration step failed. Each names what was expected and what was found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibError {
    /// No marker-like dark discs at all.
    #[error("no markers found: {found} dark regions, none a disc of the expected kind ({hint})")]
    NoMarkers {
        /// Dark regions seen (rejected as clutter).
        found: usize,
        /// What to check.
        hint: &'static str,
    },
    /// A sheet or target did not show enough of its layout.
    #[error(
        "{what}: {found} of {expected} markers identified, at least {needed} needed{}",
        missing_list(missing)
    )]
    TooFewMarkers {
        /// Which sheet or target.
        what: String,
        /// Identified.
        found: usize,
        /// In the layout.
        expected: usize,
        /// Needed.
        needed: usize,
        /// Layout indices not found.
        missing: Vec<usize>,
    },
    /// Too few images are usable for the intrinsics.
    #[error(
        "{usable} of {given} images usable (grid found, not refused), at least {needed} needed: see the line of each image"
    )]
    TooFewImages {
        /// Usable images.
        usable: usize,
        /// Images given.
        given: usize,
        /// Needed.
        needed: usize,
    },
    /// A ChArUco board's marker IDs seen at two places or more: two boards that share IDs.
    #[error(
        "ChArUco board: {what}: marker IDs {ids:?} of {dictionary} are seen at two places or more: two boards that share IDs in view (print each sheet with its own dictionary or first_id)"
    )]
    RepeatedIds {
        /// The sheet or target.
        what: String,
        /// The IDs seen twice.
        ids: Vec<u32>,
        /// Their dictionary.
        dictionary: String,
    },
    /// Markers of another dictionary than the board file names, more than of the one named.
    #[error(
        "ChArUco board: {what}: {found} markers of {dictionary} found, but the picture shows {others}: does the board file name the dictionary printed?"
    )]
    OtherDictionary {
        /// The sheet.
        what: String,
        /// Markers of the named dictionary found.
        found: usize,
        /// The dictionary named.
        dictionary: String,
        /// What the picture shows instead (`12 markers of DICT_6X6`).
        others: String,
    },
    /// Markers too small in the picture to read.
    #[error(
        "ChArUco board: {what}: the board is too small in the picture: {count} dark squares of about {side_px:.0} px; a marker of {cells}×{cells} cells needs {needed_px:.0} px or more to be read (move the camera closer or print larger)"
    )]
    MarkersTooSmall {
        /// The sheet.
        what: String,
        /// Dark squares seen.
        count: usize,
        /// Their side, pixels.
        side_px: f64,
        /// The marker's cells a side.
        cells: usize,
        /// The side a marker needs, pixels.
        needed_px: f64,
    },
    /// A result that no real board or target gives (the text says why and what to check).
    #[error("implausible result: {0}")]
    Implausible(String),
    /// The image is not the size the camera was calibrated for.
    #[error(
        "image is {found_w}×{found_h} but the camera was calibrated at {expected_w}×{expected_h}"
    )]
    ImageSize {
        /// Calibrated width.
        expected_w: u32,
        /// Calibrated height.
        expected_h: u32,
        /// Image width.
        found_w: u32,
        /// Image height.
        found_h: u32,
    },
    /// An image of another size than most of the others (more than the one pixel that is
    /// cropped).
    #[error(
        "image is {}×{} while most are {}×{}: take every image at one resolution, or leave this one out",
        found.0, found.1, most.0, most.1
    )]
    MixedSizes {
        /// Its size.
        found: (u32, u32),
        /// The most common size.
        most: (u32, u32),
    },
    /// The geometry could not be solved.
    #[error("{what}: {reason}")]
    Geometry {
        /// Which step.
        what: String,
        /// Why (in the message itself, not chained: summaries print this error alone).
        reason: GeomError,
    },
    /// Too many features for a target: clutter, not a grid.
    #[error("{found} features detected, more than the {limit} a target search takes (clutter?)")]
    TooManyFeatures {
        /// Detected.
        found: usize,
        /// [`crate::lattice::MAX_FEATURES`].
        limit: usize,
    },
    /// Features were detected but none form a grid.
    #[error("{what} not found: {features} features detected, none of them in a grid")]
    NoGrid {
        /// Which target.
        what: String,
        /// Features detected.
        features: usize,
    },
    /// The grid seen is larger than the target described.
    #[error(
        "{what}: the image shows a grid of {}×{} {unit}, more than the {}×{} given: is the count right?",
        seen.0, seen.1, given.0, given.1
    )]
    CountMismatch {
        /// Which target.
        what: String,
        /// Columns × rows seen.
        seen: (usize, usize),
        /// Columns × rows given.
        given: (usize, usize),
        /// What is counted ("inner corners", "dots").
        unit: &'static str,
    },
    /// Most images show the same complete grid, smaller than the target described.
    #[error(
        "the images show a complete grid of {}×{} {unit}, but {}×{} were given{hint}",
        seen.0, seen.1, given.0, given.1
    )]
    CountTooLarge {
        /// Columns × rows seen.
        seen: (usize, usize),
        /// Columns × rows given.
        given: (usize, usize),
        /// What is counted.
        unit: &'static str,
        /// What to do.
        hint: String,
    },
    /// An image repeats another image's view.
    #[error("the same view as image {} (its features lie within 1 px): it adds nothing", other + 1)]
    SameView {
        /// Index of the earlier image.
        other: usize,
    },
    /// An image's features fit the common camera far worse than the others'.
    #[error(
        "reprojection error {rms_px:.2} px, above the limit of {limit_px:.2} px that the other images keep"
    )]
    ResidualTooHigh {
        /// The image's RMS error.
        rms_px: f64,
        /// The limit.
        limit_px: f64,
    },
    /// Zhang's closed form succeeds without this image but not with it.
    #[error(
        "disagrees with the other images (the closed-form start fails with it, succeeds without)"
    )]
    Disagrees,
    /// Zhang's closed form fails on the images, whichever one is left out.
    #[error(
        "intrinsics: the closed-form start fails on images {} whichever one is left out ({source}): are the views varied enough (tilt the target 20-45° in different directions)?",
        images.iter().map(|i| (i + 1).to_string()).collect::<Vec<_>>().join(", ")
    )]
    ClosedForm {
        /// The images (0-based).
        images: Vec<usize>,
        /// Why.
        source: GeomError,
    },
    /// The images do not fit one camera.
    #[error(
        "intrinsics: the images do not fit one camera (RMS {rms_px:.2} px, a good calibration fits within {limit_px} px): are they all from this camera at one resolution and zoom, of one flat target of the size given?"
    )]
    PoorCalibration {
        /// RMS reprojection error of the best fit.
        rms_px: f64,
        /// [`crate::intrinsics::MAX_RMS_PX`].
        limit_px: f64,
    },
    /// The fit kept changing its set of features and images.
    #[error("intrinsics: the fit did not settle on a set of features in 30 rounds")]
    Unstable,
    /// The image's grid was found but the calibration as a whole failed.
    #[error("grid found; the calibration as a whole failed (below)")]
    NotSolved,
    /// The markers fit the layout badly (wrong board file, or a mis-identification).
    #[error(
        "{what}: markers fit the layout with {rms_px:.2} px RMS (expected < {limit_px} px): does the board file match the printed board?"
    )]
    PoorFit {
        /// Which sheet or target.
        what: String,
        /// RMS reprojection error.
        rms_px: f64,
        /// Limit.
        limit_px: f64,
    },
}

pub(crate) fn missing_list(m: &[usize]) -> String {
    if m.is_empty() {
        String::new()
    } else {
        format!(
            " (missing: {})",
            m.iter()
                .map(|i| i.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

pub(crate) fn geom(what: &str) -> impl Fn(GeomError) -> CalibError + '_ {
    move |reason| CalibError::Geometry {
        what: what.to_string(),
        reason,
    }
}
