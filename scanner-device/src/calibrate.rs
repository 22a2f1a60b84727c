//! The head's camera and board calibrations as procedures: a plan in (the target, the images,
//! where the files go), the calibration file, its overlays and its JSON report out, and what was
//! found said line by line to the caller (the terminal, or the studio's log). No flag reaches
//! here: the command line and the head's service (`serve`) each build a plan.

use std::path::{Path, PathBuf};

use image::GrayImage;
use scanner_calib::board::{BoardError, BoardFile};
use scanner_calib::file::{CalibrationFile, FileError, write_atomic};
use scanner_calib::selfcheck::{Halves, SelfCheck, self_check};
use scanner_calib::{
    BoardMethod, CalibError, Coverage, ImageFit, Target, board_planes, check_size, intrinsics_auto,
    overlay,
};
use scanner_io::image_file::ImageFileError;

use crate::report::{
    self, BoardData, CameraData, CoverageData, IntrinsicsData, IntrinsicsImage, ReportError,
    SelfCheckData, SheetData, TurntableData, write_json,
};

/// What a calibration says as it goes: a line of its findings, or a warning.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Said {
    /// A finding (the terminal's standard output).
    Line(String),
    /// Something the user should look at (standard error).
    Warning(String),
}

/// Why a calibration gave no file. Each names the file or the step.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// An image that cannot be read.
    #[error(transparent)]
    Image(#[from] ImageFileError),
    /// A board file that cannot be read.
    #[error(transparent)]
    BoardFile(#[from] BoardError),
    /// A calibration file that cannot be read or written.
    #[error(transparent)]
    File(#[from] FileError),
    /// The camera of a calibration file is unusable.
    #[error("the camera in {path}")]
    Camera {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: scanner_core::GeomError,
    },
    /// An image of another size than the camera's.
    #[error("{image} with the camera of {camera}")]
    Size {
        /// The image.
        image: PathBuf,
        /// The camera's file.
        camera: PathBuf,
        /// The sizes.
        #[source]
        source: Box<CalibError>,
    },
    /// A picture or a folder that cannot be written.
    #[error("cannot write {path}")]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A report that cannot be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The board's planes were not found (its report and overlay are written).
    #[error("board calibration from {image} (see {overlay})")]
    Board {
        /// The board's image.
        image: PathBuf,
        /// Its overlay.
        overlay: PathBuf,
        /// Why.
        #[source]
        source: Box<CalibError>,
    },
    /// No camera was calibrated (its report and overlays are written).
    #[error("no camera calibrated (pictures: {overlays})")]
    Intrinsics {
        /// The overlays' folder.
        overlays: PathBuf,
        /// Why.
        #[source]
        source: Box<CalibError>,
    },
}

/// Reads an image file as gray.
///
/// # Errors
/// [`ImageFileError`] naming the file and the problem.
pub fn load_gray(path: &Path) -> Result<GrayImage, ImageFileError> {
    Ok(scanner_io::image_file::open(path)?.to_luma8())
}

/// The board file at `path`, or the default board.
///
/// # Errors
/// [`BoardError`] naming the file.
pub fn load_board(path: Option<&Path>) -> Result<BoardFile, BoardError> {
    match path {
        Some(p) => BoardFile::load(p),
        None => Ok(BoardFile::default()),
    }
}

/// Writes `img` as a PNG, whole or not at all.
///
/// # Errors
/// [`CalibrateError::Write`].
pub fn save_png(img: &image::RgbImage, path: &Path) -> Result<(), CalibrateError> {
    let fail = |source| CalibrateError::Write {
        path: path.to_path_buf(),
        source,
    };
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| fail(std::io::Error::other(e)))?;
    write_atomic(path, &bytes).map_err(fail)
}

/// A camera calibration: the intrinsics from pictures of a target.
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicsPlan {
    /// The target the pictures show.
    pub target: Target,
    /// The pictures.
    pub images: Vec<PathBuf>,
    /// The camera file to write.
    pub out: PathBuf,
    /// Where the overlays go; `<out stem>-overlays/` beside the camera file without one.
    pub overlays: Option<PathBuf>,
}

/// The camera from pictures of a target: a line and an overlay per image (also when the
/// calibration fails), then the camera file, the self-check and the report.
///
/// # Errors
/// [`CalibrateError`]: a file that cannot be read or written, or no camera calibrated.
pub fn intrinsics(
    plan: &IntrinsicsPlan,
    say: &mut dyn FnMut(Said),
) -> Result<IntrinsicsData, CalibrateError> {
    let (target, images, out) = (&plan.target, &plan.images, plan.out.as_path());
    let imgs: Vec<GrayImage> = images
        .iter()
        .map(|p| load_gray(p))
        .collect::<Result<_, _>>()?;
    let (outcome, k3_fixed) = intrinsics_auto(&imgs, target);
    let name = |i: usize| images[i].display().to_string();
    for (i, r) in outcome.images.iter().enumerate() {
        let cropped = r.cropped_from.map_or(String::new(), |(w, h)| {
            format!(
                " ({w}×{h}, one pixel more than the rest: its last {} dropped)",
                match (w > outcome.size.0, h > outcome.size.1) {
                    (true, true) => "column and row",
                    (true, false) => "column",
                    _ => "row",
                }
            )
        });
        say(Said::Line(format!(
            "  {}: {}{cropped}",
            name(i),
            image_line(&r.status, name)
        )));
    }
    let mut data = IntrinsicsData {
        images: outcome
            .images
            .iter()
            .enumerate()
            .map(|(i, r)| IntrinsicsImage::of(name(i), r, name))
            .collect(),
        used: 0,
        camera: None,
        rms_px: None,
        k3_fixed,
        coverage: None,
        self_check: None,
        error: None,
    };
    let dir = plan
        .overlays
        .clone()
        .unwrap_or_else(|| default_overlays(out));
    std::fs::create_dir_all(&dir).map_err(|source| CalibrateError::Write {
        path: dir.clone(),
        source,
    })?;
    for ((p, img), r) in images.iter().zip(&imgs).zip(&outcome.images) {
        let stem = p
            .file_stem()
            .map_or("image".into(), |s| s.to_string_lossy());
        save_png(
            &overlay::grid_overlay(img, r),
            &dir.join(format!("{stem}-overlay.png")),
        )?;
    }
    let overlays_note = format!("(pictures: {})", dir.display());
    let fit = match outcome.into_fit() {
        Ok(fit) => fit,
        Err(e) => {
            data.error = Some(e.to_string());
            write_json(&report::beside(out), &data)?;
            return Err(CalibrateError::Intrinsics {
                overlays: dir,
                source: Box::new(e),
            });
        }
    };
    let used = fit.views.iter().filter(|v| v.is_ok()).count();
    let check = self_check(&fit, target);
    let mut file = CalibrationFile::from_camera(
        &fit.camera,
        fit.size,
        source_note(target, used),
        Some(fit.rms_px),
    );
    if let Ok(c) = &check {
        let halves = c.halves.as_ref().ok();
        file.set_covariance(
            &c.covariance,
            halves.map(Halves::ratio),
            halves.map_or(1.0, Halves::covariance_scale),
        );
    }
    file.save(out)?;
    let c = &fit.camera;
    let d = c.distortion();
    say(Said::Line(format!(
        "fx {:.3} fy {:.3} cx {:.3} cy {:.3} k1 {:.5} k2 {:.5} p1 {:.6} p2 {:.6} k3 {:.5}; rms {:.4} px over {used} images -> {} {overlays_note}",
        c.fx(),
        c.fy(),
        c.principal_point().x,
        c.principal_point().y,
        d.k1,
        d.k2,
        d.p1,
        d.p2,
        d.k3,
        fit.rms_px,
        out.display()
    )));
    let cover = Coverage::of(&fit);
    let ((cells, all), (border, ring)) = (cover.cells(), cover.border());
    let (cols, rows) = scanner_calib::intrinsics::COVER_CELLS;
    let empty = cover.empty_corners();
    let corners = if empty.is_empty() {
        String::new()
    } else {
        format!(
            "; none in the {} corner{}, where the distortion is extrapolated",
            empty.join(", "),
            if empty.len() == 1 { "" } else { "s" }
        )
    };
    say(Said::Line(format!(
        "coverage: the features used fall in {cells} of the image's {all} cells ({cols}×{rows}), {border} of the {ring} on its border{corners}"
    )));
    if k3_fixed {
        say(Said::Line(
            "k3 fixed at 0: no feature used lies on the image's border, and only there does k3 show apart from k1 and k2 (shots with the target in the corners let it be fitted)".into(),
        ));
    }
    match &check {
        Ok(c) => {
            let picture = dir.join("uncertainty.png");
            let first = fit.views.iter().position(Result::is_ok).unwrap_or(0);
            let features = fit
                .views
                .iter()
                .flatten()
                .flat_map(|v| v.found.iter().map(|f| f.1));
            save_png(
                &overlay::uncertainty_overlay(&imgs[first], c, features),
                &picture,
            )?;
            self_check_lines(c, &picture, say);
            data.self_check = Some(SelfCheckData::of(c));
        }
        Err(e) => say(Said::Line(format!("self-check: not possible ({e})"))),
    }
    data.used = used;
    data.camera = Some(CameraData::of(&fit.camera));
    data.rms_px = Some(fit.rms_px);
    data.coverage = Some(CoverageData::of(&fit));
    write_json(&report::beside(out), &data)?;
    Ok(data)
}

/// The self-check's lines: the halves' difference, the uncertainty and where to add shots.
fn self_check_lines(c: &SelfCheck, picture: &Path, say: &mut dyn FnMut(Said)) {
    match &c.halves {
        Ok(h) => {
            say(Said::Line(format!(
                "cross-validation: halves of {} and {} images differ by {:.3} px rms where the features were ({:.3} px expected from the corner noise of {:.3} px), {:.3} px rms and {:.3} px at most over the whole image",
                h.images.0,
                h.images.1,
                h.features_rms_px,
                h.expected_features_rms_px,
                c.covariance.noise_px,
                h.image_rms_px,
                h.image_max_px
            )));
            if h.too_far() {
                say(Said::Line(format!(
                    "warning: the halves differ {:.1}× more than the corner noise explains: the lens model does not fit, the target is not flat, or some shots moved or blurred — check the overlays, retake the worst images",
                    h.ratio()
                )));
            }
        }
        Err(e) => say(Said::Line(format!(
            "cross-validation: not possible ({e}): with {} or more usable images each half is calibrated apart and the two compared",
            2 * scanner_calib::selfcheck::MIN_HALF_IMAGES
        ))),
    }
    let more = c.map.more_shots();
    let advice = if more.is_empty() {
        String::new()
    } else {
        format!(
            "; more shots with the target in the {} would help",
            more.iter()
                .map(|r| format!("{} ({:.2} px)", r.name, r.sigma_px))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    say(Said::Line(format!(
        "projection uncertainty: {:.3} px median where the features were, {:.3} px at most{advice} (map: {})",
        c.map.covered_median(),
        c.map.max(),
        picture.display()
    )));
}

/// A board calibration: the board's planes from one picture of it, with a calibrated camera.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardPlan {
    /// The board file (its sheets' layout); the default board without one.
    pub board: Option<PathBuf>,
    /// The camera's calibration file.
    pub camera: PathBuf,
    /// The board's picture, laser off.
    pub image: PathBuf,
    /// The calibration file to write (the camera and the board).
    pub out: PathBuf,
    /// The overlay picture to write.
    pub overlay: PathBuf,
    /// How the planes are found.
    pub method: BoardMethod,
}

/// Both planes of the board from one image; the overlay and the report are written also when
/// it fails.
///
/// # Errors
/// [`CalibrateError`]: a file that cannot be read or written, an image of another size than
/// the camera's, a board whose planes were not found.
pub fn board(p: &BoardPlan, say: &mut dyn FnMut(Said)) -> Result<BoardData, CalibrateError> {
    let method = p.method;
    let b = load_board(p.board.as_deref())?;
    let cam_file = CalibrationFile::load(&p.camera)?;
    let cam = cam_file.camera().map_err(|source| CalibrateError::Camera {
        path: p.camera.clone(),
        source,
    })?;
    let img = load_gray(&p.image)?;
    check_size((cam_file.image.width, cam_file.image.height), &img).map_err(|source| {
        CalibrateError::Size {
            image: p.image.clone(),
            camera: p.camera.clone(),
            source: Box::new(source),
        }
    })?;
    let outcome = board_planes(&img, &b, &cam);
    save_png(
        &overlay::board_overlay(&img, &outcome, &b, &cam),
        &p.overlay,
    )?;
    let turntable = outcome
        .turntable
        .as_ref()
        .map(|t| TurntableData { dots: t.fit.used });
    if let Some(t) = &turntable {
        say(Said::Line(format!(
            "turntable disc in the picture: its {} dots are no board markers, left out",
            t.dots
        )));
    }
    let fit = match outcome.result {
        Ok(fit) => fit,
        Err(e) => {
            if turntable.is_some() {
                say(Said::Warning(
                    "the turntable disc lies in the picture: if it hides the board's lower markers, take the board's picture without it".into(),
                ));
            }
            let data = BoardData {
                sheets: Vec::new(),
                method: None,
                angle_deg: None,
                turntable,
                error: Some(e.to_string()),
            };
            write_json(&report::beside(&p.out), &data)?;
            return Err(CalibrateError::Board {
                image: p.image.clone(),
                overlay: p.overlay.clone(),
                source: Box::new(e),
            });
        }
    };
    let mut file = cam_file;
    let used = file.set_board(&fit, &b, &cam, method);
    if used != method {
        say(Said::Warning(
            "the paper's construction needs all six markers of the paper's layout on each sheet; used the layout pose".into(),
        ));
    }
    let angle = file.board.as_ref().map_or(f64::NAN, |s| s.angle_deg);
    file.save(&p.out)?;
    for (k, s) in fit.sheets.iter().enumerate() {
        say(Said::Line(s.summary(["left", "right"][k])));
        if s.rms_px > scanner_calib::MAX_SHEET_RMS_PX {
            say(Said::Warning(format!(
                "the {} sheet fits its layout with {:.2} px RMS, a flat print within {} px: is it flat? A bent sheet tilts its plane, by a tenth of a degree or so where the object hides part of it",
                ["left", "right"][k],
                s.rms_px,
                scanner_calib::MAX_SHEET_RMS_PX
            )));
        }
    }
    say(Said::Line(format!(
        "planes by {}; angle between them {angle:.3}°; -> {} (picture: {})",
        used.name(),
        p.out.display(),
        p.overlay.display()
    )));
    let data = BoardData {
        sheets: fit
            .sheets
            .iter()
            .zip(["left", "right"])
            .map(|(s, side)| SheetData::of(s, side))
            .collect(),
        method: Some(used.name()),
        angle_deg: Some(angle),
        turntable,
        error: None,
    };
    write_json(&report::beside(&p.out), &data)?;
    Ok(data)
}

/// What `calibrate intrinsics` says about one image.
fn image_line(status: &Result<ImageFit, CalibError>, name: impl Fn(usize) -> String) -> String {
    match status {
        Ok(v) if v.dropped.is_empty() => format!(
            "used: {} features, rms {:.3} px, max {:.3} px",
            v.found.len(),
            v.rms_px,
            v.max_px
        ),
        Ok(v) => format!(
            "used: {} features, rms {:.3} px, max {:.3} px; dropped {} far off the fit ({})",
            v.found.len(),
            v.rms_px,
            v.max_px,
            v.dropped.len(),
            v.dropped
                .iter()
                .map(|(k, _, e)| format!("#{k} {e:.1} px"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Err(CalibError::SameView { other }) => {
            format!(
                "refused: the same view as {} (it adds nothing)",
                name(*other)
            )
        }
        Err(e) => format!("refused: {e}"),
    }
}

/// `<out stem>-overlays/` beside the camera file.
fn default_overlays(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or("camera".into(), |s| s.to_string_lossy());
    out.with_file_name(format!("{stem}-overlays"))
}

/// The calibration file's note on where the intrinsics came from.
pub(crate) fn source_note(target: &Target, used: usize) -> String {
    match *target {
        Target::Dots(g) => format!(
            "intrinsics from {used} dot-grid images ({}x{}, {} mm pitch)",
            g.cols, g.rows, g.pitch
        ),
        Target::Chessboard { cols, rows, square } => format!(
            "intrinsics from {used} chessboard images ({cols}x{rows} squares of {square} mm, {}x{} inner corners)",
            cols - 1,
            rows - 1
        ),
        Target::Charuco(b) => format!(
            "intrinsics from {used} ChArUco images ({}x{} squares of {} mm, markers {} mm, {} from ID {})",
            b.cols,
            b.rows,
            b.square,
            b.marker,
            b.dictionary.name(),
            b.first_id
        ),
    }
}
