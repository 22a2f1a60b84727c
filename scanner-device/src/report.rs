//! The head's reports as data: what `scan`, `capture` and `calibrate …` tell on the terminal,
//! written as JSON beside their outputs (the fields: docs/reports.md). Built from the results
//! here at the edge; the library crates stay free of the file formats.

use std::path::{Path, PathBuf};

use scanner_calib::selfcheck::SelfCheck;
use scanner_calib::{
    CalibError, Coverage, FoundGrid, ImageFit, ImageReport, IntrinsicsFit, SheetFit,
};
use scanner_wire::Skip;
use serde::Serialize;

use crate::session::{DiscOutcome, ScanReport};

/// A report that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write the report {path}")]
pub struct ReportError {
    /// The report's file.
    pub path: PathBuf,
    /// Why.
    #[source]
    pub source: std::io::Error,
}

/// Writes `report` as pretty JSON to `path`, whole or not at all.
///
/// # Errors
/// [`ReportError`]: the file cannot be written.
pub fn write_json(path: &Path, report: &impl Serialize) -> Result<(), ReportError> {
    let fail = |source| ReportError {
        path: path.to_path_buf(),
        source,
    };
    let bytes = serde_json::to_vec_pretty(report).map_err(|e| fail(std::io::Error::other(e)))?;
    scanner_calib::file::write_atomic(path, &bytes).map_err(fail)
}

/// `<stem>-report.json` beside a calibration file `out` (`camera.toml` → `camera-report.json`).
pub fn beside(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or("calibration".into(), |s| s.to_string_lossy());
    out.with_file_name(format!("{stem}-report.json"))
}

/// A scan's end, as `scan --report` writes it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanData {
    /// The scan's id.
    pub scan_id: u32,
    /// Frames taken after the reference.
    pub frames: u32,
    /// Point packets sent.
    pub packets: u32,
    /// Points sent.
    pub points: u64,
    /// Bytes sent, the final status included.
    pub bytes: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Point packets dropped because the link was busy.
    pub dropped: u64,
    /// Bytes per point on the link (framing and headers included); `None`: no point sent.
    pub bytes_per_point: Option<f64>,
    /// Why the scan ended early (the camera failed).
    pub ended_early: Option<String>,
    /// What stopped it (Ctrl-C, a signal, `--frames`, `--duration`).
    pub stopped: Option<String>,
    /// Frames the head skipped, per reason (reasons with none left out).
    pub skipped: Vec<Skipped>,
    /// The stripe's direction read: `columns` (a horizontal line) or `rows`.
    pub axis: &'static str,
    /// Whether it was found from the first laser frame rather than given.
    pub axis_found: bool,
    /// The direction the first laser frame's stripe runs, where it tells (`columns`, `rows`):
    /// other than `axis`, the summary names the flag to give.
    pub axis_seen: Option<&'static str>,
    /// The laser's colour the scan read with (`red`, `green`, `blue`, `white`: by brightness).
    pub laser_colour: &'static str,
    /// Whether it was found from the first laser frame rather than given.
    pub laser_colour_found: bool,
    /// What the first laser frame showed of the laser's colour, where it tells.
    pub laser_colour_seen: Option<ColourData>,
    /// Most frames saw the stripe on one sheet only: the summary says what to change.
    pub one_sheet_only: bool,
    /// The turntable disc, when the scan looked for one (`--disc`).
    pub disc: Option<DiscData>,
    /// What the platform's markers gave, when the scan measured its turns by them
    /// (`--markers`).
    pub markers: Option<MarkersData>,
    /// The pipeline's mean time per frame, ms.
    pub pipeline_ms: f64,
    /// From a camera that numbers its frames: the frames it made that the head never took
    /// (the pipeline was slower), and its frame period in ms (`None` until known).
    pub camera_dropped: Option<u64>,
    /// …and its frame period, ms.
    pub camera_period_ms: Option<f64>,
    /// A shadow sweep's bands (`--shadow`).
    pub shadow: Option<ShadowData>,
    /// Lines refused because their stripe was wider than the frame's limit.
    pub beyond_width_limit: u64,
    /// That limit, pixels (64 px or 4 % of the image width, whichever is more).
    pub width_limit_px: f32,
    /// …and the frames it sent that did not decode (corrupt MJPEG frames, skipped).
    pub camera_undecodable: Option<u64>,
    /// A shadow sweep read through time (`--shadow --temporal`): its planes, pixels, points,
    /// the object's coverage and the two edges' agreement.
    pub temporal: Option<crate::temporal::TemporalReport>,
}

/// What the head found of the turntable disc.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscData {
    /// Whether its pose was taken.
    pub found: bool,
    /// Dots used (found).
    pub markers: Option<usize>,
    /// Dots printed (found).
    pub of: Option<usize>,
    /// RMS reprojection error of the used dots, pixels (found).
    pub rms_px: Option<f64>,
    /// Its centre in camera coordinates, mm (found).
    pub centre_mm: Option<[f64; 3]>,
    /// Why not (not found): `too_few_markers`, `ambiguous`, `tilted` or `poor_fit`.
    pub missed: Option<&'static str>,
}

impl From<&DiscOutcome> for DiscData {
    fn from(d: &DiscOutcome) -> DiscData {
        use scanner_calib::disc::DiscMiss;
        match d {
            DiscOutcome::Found {
                pose,
                markers,
                of,
                rms_px,
            } => DiscData {
                found: true,
                markers: Some(*markers),
                of: Some(*of),
                rms_px: Some(*rms_px),
                centre_mm: Some(pose.translation.into()),
                missed: None,
            },
            DiscOutcome::Missed(m) => DiscData {
                found: false,
                markers: None,
                of: None,
                rms_px: None,
                centre_mm: None,
                missed: Some(match m {
                    DiscMiss::TooFewMarkers { .. } => "too_few_markers",
                    DiscMiss::Ambiguous { .. } => "ambiguous",
                    DiscMiss::Tilted { .. } => "tilted",
                    DiscMiss::PoorFit(_) => "poor_fit",
                }),
            },
        }
    }
}

fn axis_name(a: scanner_core::stripe::Axis) -> &'static str {
    match a {
        scanner_core::stripe::Axis::Columns => "columns",
        scanner_core::stripe::Axis::Rows => "rows",
    }
}

/// Frames skipped for one reason.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Skipped {
    /// The reason, as the head names it.
    pub reason: &'static str,
    /// Frames.
    pub frames: u32,
}

impl From<&ScanReport> for ScanData {
    fn from(r: &ScanReport) -> ScanData {
        let s = &r.status;
        ScanData {
            scan_id: s.scan_id,
            frames: s.frames,
            packets: s.packets,
            points: s.points,
            bytes: r.bytes,
            seconds: r.seconds,
            dropped: r.dropped,
            bytes_per_point: r.bytes_per_point(),
            ended_early: r.ended_early.clone(),
            stopped: r.stopped.clone(),
            skipped: Skip::ALL
                .iter()
                .filter(|&&k| s.skipped[k as usize] > 0)
                .map(|&k| Skipped {
                    reason: scanner_io::words::skip_reason(k),
                    frames: s.skipped[k as usize],
                })
                .collect(),
            axis: axis_name(r.axis),
            axis_found: r.axis_found,
            axis_seen: r.axis_seen.map(axis_name),
            laser_colour: r.colour.name(),
            laser_colour_found: r.colour_found,
            laser_colour_seen: r.colour_seen.map(|c| ColourData {
                colour: c.colour.name(),
                saturated: c.saturated,
                pixels: c.pixels,
            }),
            one_sheet_only: r.one_sheet_only(),
            disc: r.disc.as_ref().map(DiscData::from),
            markers: r.markers.as_ref().map(|m| MarkersData {
                frames: m.frames,
                missed: m.missed.clone(),
                ids: m.markers.clone(),
                step_deg: m.step_deg,
                unsteady: m
                    .unsteady
                    .iter()
                    .map(|&(frame, deg)| UnsteadyFrame { frame, deg })
                    .collect(),
            }),
            pipeline_ms: r.pipeline_ms,
            camera_dropped: r.pace.map(|p| p.dropped),
            camera_period_ms: r.pace.and_then(|p| p.period_ms()),
            camera_undecodable: r.pace.map(|p| p.undecodable),
            beyond_width_limit: r.beyond_limit.0,
            width_limit_px: r.beyond_limit.1,
            temporal: r.temporal.clone(),
            shadow: r.shadow.map(|b| ShadowData {
                band_lines: b.lines,
                edged_lines: b.edged,
                blurred: b.blurred(),
            }),
        }
    }
}

/// What a platform's markers gave ([`crate::marker_turn::MarkerSummary`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkersData {
    /// Frames whose turn the markers gave.
    pub frames: usize,
    /// Frames whose turn they did not give (left out of the model).
    pub missed: Vec<u32>,
    /// The markers' IDs seen.
    pub ids: Vec<usize>,
    /// The platform's steady turn per frame, degrees.
    pub step_deg: Option<f64>,
    /// Frames that turned otherwise than the steady turn since the frame before.
    pub unsteady: Vec<UnsteadyFrame>,
}

/// A frame that turned otherwise than the rest ([`MarkersData::unsteady`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct UnsteadyFrame {
    /// The frame.
    pub frame: u32,
    /// How much more it turned than the steady turn, degrees.
    pub deg: f64,
}

/// What the first laser frame showed of the laser's colour.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ColourData {
    /// The colour of the light added: `red`, `green`, `blue`, or `white` when no channel
    /// carries most of it.
    pub colour: &'static str,
    /// Whether the line's core is clipped white (read by its colour alone it shows nothing).
    pub saturated: bool,
    /// The stripe's pixels it was told from.
    pub pixels: u32,
}

/// What a shadow sweep's frames showed of the band.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShadowData {
    /// Lines, over all frames, where the band was found.
    pub band_lines: u64,
    /// Of them, lines where at least one of its edges was found.
    pub edged_lines: u64,
    /// The band was found but its edges almost never: the edges are a blur.
    pub blurred: bool,
}

/// One sheet of the board as fitted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SheetData {
    /// `left` or `right`.
    pub side: &'static str,
    /// Markers used in the fit.
    pub used: usize,
    /// Markers of the sheet's layout.
    pub markers: usize,
    /// RMS reprojection error of those used, pixels.
    pub rms_px: f64,
    /// Layout indices not found or dropped.
    pub missing: Vec<usize>,
}

impl SheetData {
    /// The sheet `s` on `side`.
    pub fn of(s: &SheetFit, side: &'static str) -> SheetData {
        SheetData {
            side,
            used: s.used(),
            markers: s.markers.len(),
            rms_px: s.rms_px,
            missing: s.missing(),
        }
    }
}

/// Why an image or a shot was not used.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageRefusal {
    /// A short name of the reason: `same_view`, `count_mismatch` (a grid larger than the target
    /// given), `reprojection` (the fit's error too high), `no_grid`, `no_markers`,
    /// `too_few_markers`, `size` (another image size), or `other`.
    pub reason: &'static str,
    /// The image it repeats (with `same_view`).
    pub same_as: Option<String>,
    /// What the refusal says.
    pub message: String,
}

impl ImageRefusal {
    /// The refusal `e`; `name(i)` names image `i`.
    pub fn of(e: &CalibError, name: impl Fn(usize) -> String) -> ImageRefusal {
        let (reason, same_as) = match e {
            CalibError::SameView { other } => ("same_view", Some(name(*other))),
            CalibError::CountMismatch { .. } | CalibError::CountTooLarge { .. } => {
                ("count_mismatch", None)
            }
            CalibError::ResidualTooHigh { .. } => ("reprojection", None),
            CalibError::NoGrid { .. } => ("no_grid", None),
            CalibError::NoMarkers { .. } => ("no_markers", None),
            CalibError::TooFewMarkers { .. } => ("too_few_markers", None),
            CalibError::ImageSize { .. } | CalibError::MixedSizes { .. } => ("size", None),
            _ => ("other", None),
        };
        ImageRefusal {
            reason,
            same_as,
            message: e.to_string(),
        }
    }
}

/// One image of `calibrate intrinsics`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IntrinsicsImage {
    /// Its path.
    pub path: String,
    /// Features used in the fit (`None`: refused).
    pub features: Option<usize>,
    /// RMS reprojection error of those, pixels.
    pub rms_px: Option<f64>,
    /// The largest, pixels.
    pub max_px: Option<f64>,
    /// Features identified but left out of the fit, far off it: (layout index, error px).
    pub dropped: Vec<(usize, f64)>,
    /// Why it was not used.
    pub refused: Option<ImageRefusal>,
    /// Its size where it was one pixel larger than the rest and was cropped to theirs.
    pub cropped_from: Option<(u32, u32)>,
}

impl IntrinsicsImage {
    /// Image `path` with its outcome; `name(i)` names image `i`.
    pub fn of(
        path: String,
        report: &ImageReport,
        name: impl Fn(usize) -> String,
    ) -> IntrinsicsImage {
        IntrinsicsImage {
            cropped_from: report.cropped_from,
            ..Self::of_status(path, &report.status, name)
        }
    }

    fn of_status(
        path: String,
        status: &Result<ImageFit, CalibError>,
        name: impl Fn(usize) -> String,
    ) -> IntrinsicsImage {
        match status {
            Ok(v) => IntrinsicsImage {
                path,
                features: Some(v.found.len()),
                rms_px: Some(v.rms_px),
                max_px: Some(v.max_px),
                dropped: v.dropped.iter().map(|&(k, _, e)| (k, e)).collect(),
                refused: None,
                cropped_from: None,
            },
            Err(e) => IntrinsicsImage {
                path,
                features: None,
                rms_px: None,
                max_px: None,
                dropped: Vec::new(),
                refused: Some(ImageRefusal::of(e, name)),
                cropped_from: None,
            },
        }
    }
}

/// The camera found, as numbers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CameraData {
    /// Focal lengths, pixels.
    pub fx: f64,
    /// …
    pub fy: f64,
    /// Principal point, pixels.
    pub cx: f64,
    /// …
    pub cy: f64,
    /// Radial and tangential distortion (Brown–Conrady).
    pub k1: f64,
    /// …
    pub k2: f64,
    /// …
    pub p1: f64,
    /// …
    pub p2: f64,
    /// …
    pub k3: f64,
}

impl CameraData {
    /// The numbers of `c`.
    pub fn of(c: &scanner_core::Camera<f64>) -> CameraData {
        let (d, p) = (c.distortion(), c.principal_point());
        CameraData {
            fx: c.fx(),
            fy: c.fy(),
            cx: p.x,
            cy: p.y,
            k1: d.k1,
            k2: d.k2,
            p1: d.p1,
            p2: d.p2,
            k3: d.k3,
        }
    }
}

/// Where the features used fell over the image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoverageData {
    /// Cells of the image's grid holding a feature used.
    pub cells: usize,
    /// Cells in all.
    pub of: usize,
    /// Of those on the image's border, the cells holding one.
    pub border: usize,
    /// Border cells in all.
    pub ring: usize,
    /// The image's corners with none (`top left`, …): the distortion is extrapolated there.
    pub empty_corners: Vec<&'static str>,
}

impl CoverageData {
    /// The coverage of a fit.
    pub fn of(fit: &IntrinsicsFit) -> CoverageData {
        let cover = Coverage::of(fit);
        let ((cells, of), (border, ring)) = (cover.cells(), cover.border());
        CoverageData {
            cells,
            of,
            border,
            ring,
            empty_corners: cover.empty_corners(),
        }
    }
}

/// `calibrate intrinsics`' report (`<out>-report.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IntrinsicsData {
    /// Each image, in the order given.
    pub images: Vec<IntrinsicsImage>,
    /// Images used.
    pub used: usize,
    /// The camera (`None`: none calibrated, see `error`).
    pub camera: Option<CameraData>,
    /// RMS reprojection error over the images used, pixels.
    pub rms_px: Option<f64>,
    /// Whether k3 was held at 0 (no feature on the image's border).
    pub k3_fixed: bool,
    /// Where the features used fell.
    pub coverage: Option<CoverageData>,
    /// The calibration's check of itself.
    pub self_check: Option<SelfCheckData>,
    /// Why no camera was calibrated.
    pub error: Option<String>,
}

/// The calibration's check of itself (`scanner_calib::selfcheck`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SelfCheckData {
    /// A feature's position noise per coordinate, from the residuals, pixels.
    pub noise_px: f64,
    /// Covariance of `fx, fy, cx, cy, k1, k2, p1, p2, k3`.
    pub covariance: [[f64; 9]; 9],
    /// The halves compared (`None`: see `halves_error`).
    pub halves: Option<HalvesData>,
    /// Why the halves were not compared.
    pub halves_error: Option<String>,
    /// The projection uncertainty's median over the cells the features covered, pixels.
    pub uncertainty_median_px: f64,
    /// Its largest value over the image, pixels.
    pub uncertainty_max_px: f64,
    /// The map: cells across and down, and per cell (row by row) the uncertainty in pixels
    /// (`null` where no ray leaves the pixel).
    pub map_cells: (usize, usize),
    /// Per cell, pixels.
    pub map_px: Vec<f64>,
    /// Where more shots would help, worst first: region and its uncertainty.
    pub more_shots: Vec<RegionData>,
}

/// One region of the image and its projection uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionData {
    /// "top left" … "bottom right".
    pub region: &'static str,
    /// Mean uncertainty, pixels.
    pub sigma_px: f64,
}

/// The halves' cross-validation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HalvesData {
    /// Images in each half.
    pub images: (usize, usize),
    /// RMS projection difference where the features were, pixels.
    pub features_rms_px: f64,
    /// What the halves' covariances predict there, pixels.
    pub expected_features_rms_px: f64,
    /// The ratio of the two.
    pub ratio: f64,
    /// Above the warning's ratio: the model or the data is wrong.
    pub warning: bool,
    /// RMS difference over the whole image, pixels.
    pub image_rms_px: f64,
    /// Largest difference over the whole image, pixels.
    pub image_max_px: f64,
    /// What the covariances predict over the whole image, pixels.
    pub expected_image_rms_px: f64,
}

impl SelfCheckData {
    /// The report of a self-check.
    pub fn of(c: &SelfCheck) -> SelfCheckData {
        SelfCheckData {
            noise_px: c.covariance.noise_px,
            covariance: c.covariance.matrix,
            halves: c.halves.as_ref().ok().map(|h| HalvesData {
                images: h.images,
                features_rms_px: h.features_rms_px,
                expected_features_rms_px: h.expected_features_rms_px,
                ratio: h.ratio(),
                warning: h.too_far(),
                image_rms_px: h.image_rms_px,
                image_max_px: h.image_max_px,
                expected_image_rms_px: h.expected_image_rms_px,
            }),
            halves_error: c.halves.as_ref().err().map(ToString::to_string),
            uncertainty_median_px: c.map.covered_median(),
            uncertainty_max_px: c.map.max(),
            map_cells: scanner_calib::selfcheck::MAP_CELLS,
            map_px: c.map.sigma_px.clone(),
            more_shots: c
                .map
                .more_shots()
                .into_iter()
                .map(|r| RegionData {
                    region: r.name,
                    sigma_px: r.sigma_px,
                })
                .collect(),
        }
    }
}

/// A shot `capture` looked at.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShotData {
    /// The frame's number, from 0.
    pub frame: u32,
    /// The file it was kept as (`None`: not usable).
    pub kept_as: Option<String>,
    /// With the intrinsics target: the grid found.
    pub grid: Option<GridData>,
    /// With the board: each sheet as fitted.
    pub sheets: Vec<SheetData>,
    /// With the board: the angle the sheets meet at, degrees.
    pub angle_deg: Option<f64>,
    /// Why it is not usable.
    pub refused: Option<ImageRefusal>,
}

/// A grid found in a shot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GridData {
    /// Points identified.
    pub points: usize,
    /// Columns and rows of the target seen.
    pub cols: usize,
    /// …
    pub rows: usize,
    /// Every grid point in that rectangle was found.
    pub complete: bool,
}

impl GridData {
    /// The grid of a view.
    pub fn of(v: &FoundGrid) -> GridData {
        GridData {
            points: v.found.len(),
            cols: v.extent.0,
            rows: v.extent.1,
            complete: v.complete,
        }
    }
}

/// `capture`'s report (`capture-report.json` in its folder).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaptureData {
    /// Each frame looked at.
    pub shots: Vec<ShotData>,
    /// Usable shots kept.
    pub kept: u32,
    /// Usable shots asked for.
    pub count: u32,
}

/// `calibrate board`'s report (`<out>-report.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoardData {
    /// Each sheet as fitted (none when the calibration failed).
    pub sheets: Vec<SheetData>,
    /// How the planes were found: `layout-pose` or `paper-lines`.
    pub method: Option<&'static str>,
    /// The angle between the planes, degrees.
    pub angle_deg: Option<f64>,
    /// A turntable disc found in the picture, whose dots were left out.
    pub turntable: Option<TurntableData>,
    /// Why no board was calibrated.
    pub error: Option<String>,
}

/// A turntable disc `calibrate board` found in its picture (of either paper: from one picture
/// the A3 disc and the A4 disc nearer the camera look the same).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TurntableData {
    /// Its dots found (each left out of the board's identification).
    pub dots: usize,
}

/// `calibrate distance`'s report (`<out>-report.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DistanceData {
    /// The image distance d_z, pixels.
    pub d_z_px: f64,
    /// The marks' common offset ε, mm (eq. 7).
    pub epsilon_mm: f64,
}
