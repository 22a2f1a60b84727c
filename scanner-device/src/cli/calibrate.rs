//! The calibration commands: print the board, calibrate intrinsics / image distance / board.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Subcommand, ValueEnum};
use image::GrayImage;
use scanner_core::Camera;
use scanner_io::outln;

use scanner_calib::board::BoardFile;
use scanner_calib::disc::{Disc, Paper};
use scanner_calib::file::{CalibrationFile, write_atomic};
use scanner_calib::selfcheck::{Halves, SelfCheck, self_check};
use scanner_calib::{
    BoardMethod, CalibError, Coverage, DotGrid, ImageFit, Target, board_planes, check_size,
    intrinsics_auto, overlay, print, short,
};

use super::report::{
    self, BoardData, CameraData, CoverageData, DistanceData, IntrinsicsData, IntrinsicsImage,
    SelfCheckData, SheetData, TurntableData, write_json,
};
use super::values;

/// The intrinsics target: a dot grid (default) or a chessboard, with its sizes.
#[derive(Debug, Clone, clap::Args)]
pub struct TargetArgs {
    /// A chessboard with COLSxROWS inner corners (OpenCV's count: 9x6 for a board of 10x7
    /// squares) instead of the dot grid.
    #[arg(long, value_parser = values::parse_grid, conflicts_with_all = ["dots", "pitch", "dot", "chessboard_squares"])]
    pub chessboard_corners: Option<(usize, usize)>,
    /// A chessboard of COLSxROWS squares (10x7 has 9x6 inner corners) instead of the dot grid.
    #[arg(long, value_parser = values::parse_grid, conflicts_with_all = ["dots", "pitch", "dot"])]
    pub chessboard_squares: Option<(usize, usize)>,
    /// Refused: it did not say whether it counts squares or inner corners.
    #[arg(long, hide = true)]
    pub chessboard: Option<String>,
    /// A ChArUco board of COLSxROWS squares (OpenCV's layout and count: 7x5 for 6x4 inner
    /// corners) instead of the dot grid; give --square, --marker and --dictionary.
    #[arg(long, value_parser = values::parse_grid, conflicts_with_all = ["dots", "pitch", "dot", "chessboard_squares", "chessboard_corners"])]
    pub charuco: Option<(usize, usize)>,
    /// The ChArUco board's marker side, mm.
    #[arg(long, requires = "charuco")]
    pub marker: Option<f64>,
    /// The ChArUco board's dictionary, as OpenCV names it (DICT_4X4_50 … DICT_7X7_1000).
    #[arg(long, requires = "charuco", default_value = "DICT_4X4_50")]
    pub dictionary: String,
    /// The ChArUco board's first marker ID.
    #[arg(long, requires = "charuco", default_value_t = 0)]
    pub first_id: usize,
    /// Chessboard or ChArUco square side, mm.
    #[arg(long, default_value_t = 25.0)]
    pub square: f64,
    /// The grid: dots per row × rows.
    #[arg(long, default_value = "9x7", value_parser = values::parse_grid)]
    pub dots: (usize, usize),
    /// Centre-to-centre distance, mm.
    #[arg(long, default_value_t = 30.0)]
    pub pitch: f64,
    /// Dot diameter, mm.
    #[arg(long, default_value_t = 12.0)]
    pub dot: f64,
}

impl TargetArgs {
    /// The target the options describe, checked.
    ///
    /// # Errors
    /// An ambiguous `--chessboard`, a chessboard under 3×3 squares, sizes out of range.
    pub fn target(&self) -> Result<Target> {
        if let Some(v) = &self.chessboard {
            bail!(
                "--chessboard {v} is ambiguous: say what it counts, --chessboard-squares {v} (squares along each side) or --chessboard-corners {v} (inner corners, OpenCV's convention; a board of 10x7 squares has 9x6)"
            );
        }
        if let Some(squares) = self.charuco {
            return charuco_target(
                squares,
                self.square,
                self.marker,
                &self.dictionary,
                self.first_id,
            );
        }
        let squares = self
            .chessboard_squares
            .or(self.chessboard_corners.map(|(c, r)| (c + 1, r + 1)));
        match squares {
            Some(squares) => chessboard_target(squares, self.square),
            None => dot_target(self.dots, self.pitch, self.dot),
        }
    }
}

/// What to calibrate.
#[derive(Debug, Subcommand)]
pub enum Calibrate {
    /// Full intrinsics (fx, fy, cx, cy, k1, k2, p1, p2, k3) from several images of a dot grid
    /// (default) or a chessboard.
    Intrinsics {
        /// The target in the images.
        #[command(flatten)]
        target: TargetArgs,
        /// Output camera file (TOML; a calibration file without a board).
        #[arg(long, default_value = "camera.toml")]
        out: PathBuf,
        /// Folder for an annotated copy of every image (used or not, and why); default: beside
        /// the output, `<out>-overlays/`.
        #[arg(long)]
        overlays: Option<PathBuf>,
        /// The images (PNG/JPEG), at least three.
        #[arg(required = true)]
        images: Vec<PathBuf>,
    },
    /// The paper's image distance d_z from two images of the cross pattern (eq. 7-9); the
    /// principal point is taken at the image centre, no distortion.
    Distance {
        /// Board file (for the cross's size); the default board without one.
        #[arg(long)]
        board: Option<PathBuf>,
        /// Image of the cross at the nearer position.
        #[arg(long)]
        near: PathBuf,
        /// Tape-measured distance of the near shot, mm.
        #[arg(long)]
        near_mm: f64,
        /// Image of the cross at the farther position.
        #[arg(long)]
        far: PathBuf,
        /// Tape-measured distance of the far shot, mm.
        #[arg(long)]
        far_mm: f64,
        /// Output camera file.
        #[arg(long, default_value = "camera.toml")]
        out: PathBuf,
    },
    /// A turntable scanner's fixed lasers and platform (FabScanPi's and Horus's way): a
    /// chessboard standing on the platform, photographed lit at several turns, and after some of
    /// those lit shots, without moving, one dark frame per laser with only that laser on. Gives
    /// the intrinsics, each laser's plane and the platform's axis and top in one calibration
    /// file for `scan --fixed-laser`.
    Fixed {
        /// The chessboard (`--chessboard-corners` or `--chessboard-squares`, `--square`).
        #[command(flatten)]
        target: TargetArgs,
        /// The pattern's lowest row of inner corners stands this far above the platform's top,
        /// mm (FabScanPi's `origin_distance`).
        #[arg(long)]
        origin_distance: f64,
        /// Motor steps in one turn of the platform.
        #[arg(long)]
        steps_per_turn: u32,
        /// The platform's radius, mm (0: not known).
        #[arg(long, default_value_t = 0.0)]
        radius: f64,
        /// The platform turns clockwise seen from above when the motor steps forward, as in a
        /// scan (FabScanPi's do; its calibration turns them the other way).
        #[arg(long)]
        clockwise: bool,
        /// Output calibration file.
        #[arg(long, default_value = "calibration.toml")]
        out: PathBuf,
        /// The images in the order they were taken (name order for a folder's): a lit shot of
        /// the pattern, then its dark laser frames (laser 0 first), the next lit shot, …
        #[arg(required = true)]
        images: Vec<PathBuf>,
    },
    /// Both board planes from an image of the board without laser.
    Board {
        /// Board file; the default board without one.
        #[arg(long)]
        board: Option<PathBuf>,
        /// Camera file from `calibrate intrinsics` or `calibrate distance`.
        #[arg(long)]
        camera: PathBuf,
        /// Planes by the layout pose (default) or the paper's three-point lines.
        #[arg(long, value_enum, default_value_t = MethodArg::LayoutPose)]
        method: MethodArg,
        /// Output calibration file.
        #[arg(long, default_value = "calibration.toml")]
        out: PathBuf,
        /// Annotated picture of what was found (written even when calibration fails).
        #[arg(long, default_value = "calibration-overlay.png")]
        overlay: PathBuf,
        /// The board image.
        image: PathBuf,
    },
}

/// `--method` of `calibrate board`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Every marker of a sheet with its known layout.
    LayoutPose,
    /// The paper's construction: two lines of three markers per sheet (eq. 1-6).
    PaperLines,
}

impl From<MethodArg> for BoardMethod {
    fn from(m: MethodArg) -> BoardMethod {
        match m {
            MethodArg::LayoutPose => BoardMethod::LayoutPose,
            MethodArg::PaperLines => BoardMethod::PaperLines,
        }
    }
}

/// Reads an image file as gray.
///
/// # Errors
/// Names the file and the problem.
pub fn load_gray(path: &Path) -> Result<GrayImage> {
    Ok(scanner_io::image_file::open(path)?.to_luma8())
}

pub(crate) fn load_board(path: Option<&Path>) -> Result<BoardFile> {
    match path {
        Some(p) => Ok(BoardFile::load(p)?),
        None => Ok(BoardFile::default()),
    }
}

fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )?;
    write_atomic(path, &bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// `scanner-device board`: writes the board file and its printable sheets.
///
/// # Errors
/// Unreadable board file, unwritable output.
pub fn board_command(
    b: &BoardFile,
    out: &Path,
    dpi: f64,
    a4: bool,
    turntable: Option<Paper>,
) -> Result<()> {
    let mut sheets = print::sheets(b).to_vec();
    let disc_stem = turntable.map(|p| format!("turntable-{}", p.name()));
    if let (Some(p), Some(stem)) = (turntable, &disc_stem) {
        sheets.push((stem.as_str(), Disc::new(p).sheet()));
    }
    // Every picture's size is checked before anything is written.
    for (_, sheet) in &sheets {
        sheet.check_png(dpi / 25.4)?;
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let bf = out.join("board.toml");
    write_atomic(&bf, b.to_toml()?.as_bytes())
        .with_context(|| format!("cannot write {}", bf.display()))?;
    for (stem, sheet) in sheets {
        let svg = out.join(format!("{stem}.svg"));
        write_atomic(&svg, sheet.svg().as_bytes())
            .with_context(|| format!("cannot write {}", svg.display()))?;
        save_png(&sheet.png(dpi / 25.4)?, &out.join(format!("{stem}.png")))?;
        if a4 && (sheet.width > print::A4.0 - 20.0 || sheet.height > print::A4.1 - 20.0) {
            for t in print::a4_tiles(&sheet) {
                let path = out.join(format!("{stem}-a4-{}-{}.svg", t.at.0 + 1, t.at.1 + 1));
                write_atomic(&path, t.svg.as_bytes())
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
        }
    }
    outln!(
        "wrote board.toml, left-sheet, right-sheet, cross{} and target (the intrinsics dot grid) (.svg, .png at {dpi} dpi){} to {}; print the SVGs at 100 % and check the 100 mm ruler",
        disc_stem.map_or(String::new(), |s| format!(", {s} (the turntable disc)")),
        if a4 {
            ", and each as A4 tiles (*-a4-ROW-COL.svg: overlap them so that the crosses meet)"
        } else {
            ""
        },
        out.display()
    );
    Ok(())
}

/// Runs a calibration command.
///
/// # Errors
/// With context naming the file or step that failed.
pub fn calibrate(cmd: &Calibrate) -> Result<()> {
    match cmd {
        Calibrate::Intrinsics {
            target,
            out,
            overlays,
            images,
        } => intrinsics_command(&target.target()?, images, out, overlays.as_deref()),
        Calibrate::Distance {
            board,
            near,
            near_mm,
            far,
            far_mm,
            out,
        } => distance_command(board.as_deref(), (near, *near_mm), (far, *far_mm), out),
        Calibrate::Fixed {
            target,
            origin_distance,
            steps_per_turn,
            radius,
            clockwise,
            out,
            images,
        } => fixed_command(
            &target.target()?,
            images,
            (*origin_distance, *steps_per_turn, *radius, *clockwise),
            out,
        ),
        Calibrate::Board {
            board,
            camera,
            method,
            out,
            overlay,
            image,
        } => {
            let paths = BoardPaths {
                board: board.as_deref(),
                camera,
                image,
                out,
                overlay,
            };
            board_planes_command(&paths, (*method).into())
        }
    }
}

/// A frame whose mean luma is under this is dark: a laser frame, not a lit shot.
const DARK_MEAN: f64 = 20.0;

/// Most lasers a turntable scanner has.
const MAX_FIXED_LASERS: usize = 8;

/// `calibrate fixed`: the intrinsics from the lit shots, each laser's plane from the dark frames
/// after them, the platform from the lit shots' poses.
fn fixed_command(
    target: &Target,
    images: &[PathBuf],
    (origin_distance, steps_per_turn, radius, clockwise): (f64, u32, f64, bool),
    out: &Path,
) -> Result<()> {
    let Target::Chessboard { cols, rows, square } = *target else {
        bail!(
            "calibrate fixed takes a chessboard: give --chessboard-corners or --chessboard-squares"
        );
    };
    if !(origin_distance.is_finite() && origin_distance.abs() <= 1000.0) {
        bail!(
            "--origin-distance {} mm: give the pattern's lowest corners' height above the platform",
            short(origin_distance)
        );
    }
    if steps_per_turn == 0 || steps_per_turn > scanner_calib::file::MAX_STEPS_PER_TURN {
        bail!(
            "--steps-per-turn {steps_per_turn}: a turntable's is 1 to {}",
            scanner_calib::file::MAX_STEPS_PER_TURN
        );
    }
    let mut gray = Vec::with_capacity(images.len());
    for p in images {
        gray.push(load_gray(p)?);
    }
    let dark: Vec<bool> = gray
        .iter()
        .map(|g| {
            let n = g.as_raw().len().max(1) as f64;
            g.as_raw().iter().map(|&v| f64::from(v)).sum::<f64>() / n < DARK_MEAN
        })
        .collect();
    let lit: Vec<usize> = (0..gray.len()).filter(|&i| !dark[i]).collect();
    let lit_images: Vec<GrayImage> = lit.iter().map(|&i| gray[i].clone()).collect();
    let (outcome, k3_fixed) = intrinsics_auto(&lit_images, target);
    let fit = outcome
        .into_fit()
        .context("the intrinsics from the lit shots of the pattern")?;
    let camera = fit.camera;
    // each lit shot's pose, and the dark frames after it (laser 0 first)
    let mut poses = Vec::new();
    let mut lasers: Vec<Vec<scanner_core::nalgebra::Point3<f64>>> = Vec::new();
    let mut shots = [0usize; MAX_FIXED_LASERS];
    for (k, view) in fit.views.iter().enumerate() {
        let Ok(v) = view else { continue };
        poses.push(v.pose);
        let at = lit[k];
        for (laser, j) in (at + 1..images.len()).take_while(|&j| dark[j]).enumerate() {
            if laser >= MAX_FIXED_LASERS {
                bail!(
                    "{}: more than {MAX_FIXED_LASERS} dark frames after a lit shot",
                    images[j].display()
                );
            }
            let rgb = scanner_io::image_file::open(&images[j])?.to_rgb8();
            let points =
                scanner_calib::fixed::laser_points(&camera, (cols, rows, square), &v.pose, &rgb)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", images[j].display()))?;
            if lasers.len() <= laser {
                lasers.resize_with(laser + 1, Vec::new);
            }
            if !points.is_empty() {
                shots[laser] += 1;
            }
            lasers[laser].extend(points);
        }
    }
    if lasers.is_empty() {
        bail!(
            "no dark laser frame follows a lit shot whose pattern was found: take one with each laser alone after a lit shot, without moving the pattern"
        );
    }
    let platform =
        scanner_calib::fixed::fit_platform((cols, rows, square), &poses, origin_distance)
            .map_err(|e| anyhow::anyhow!("the platform: {e}"))?;
    let mut file = CalibrationFile::from_camera(
        &camera,
        fit.size,
        format!(
            "intrinsics, fixed lasers and platform from {} lit shots of a {}x{} chessboard ({} mm squares){}",
            poses.len(),
            cols - 1,
            rows - 1,
            short(square),
            if k3_fixed { ", k3 fixed at 0" } else { "" }
        ),
        Some(fit.rms_px),
    );
    let mut laser_data = Vec::new();
    for (n, points) in lasers.iter().enumerate() {
        let l = scanner_calib::fixed::fit_laser(points).map_err(|e| {
            anyhow::anyhow!(
                "laser {n} (from {} frames with its stripe on the pattern): {e}",
                shots[n]
            )
        })?;
        file.lasers.push(scanner_calib::file::PlaneEq {
            normal: (*l.plane.normal()).into(),
            offset: l.plane.offset(),
        });
        outln!(
            "laser {n}: {} points from {} frames, {} dropped, rms {:.3} mm; plane normal [{:.5}, {:.5}, {:.5}], offset {:.3} mm",
            l.points,
            shots[n],
            l.dropped,
            l.rms_mm,
            l.plane.normal().x,
            l.plane.normal().y,
            l.plane.normal().z,
            l.plane.offset()
        );
        laser_data.push(serde_json::json!({
            "laser": n, "frames": shots[n], "points": l.points, "dropped": l.dropped,
            "rms_mm": l.rms_mm, "normal": [l.plane.normal().x, l.plane.normal().y, l.plane.normal().z],
            "offset_mm": l.plane.offset(),
        }));
    }
    let pl = platform.platform;
    let r = pl.rotation();
    file.platform = Some(scanner_calib::file::PlatformSection {
        rotation: [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]),
        origin: pl.origin().coords.into(),
        radius,
        steps_per_turn,
        clockwise,
        height: 0.0,
    });
    // the checks any calibration file gets
    let text = toml::to_string(&file).context("the calibration as TOML")?;
    let file = CalibrationFile::parse(&text, &out.display().to_string())?;
    file.save(out)?;
    let a = pl.axis();
    outln!(
        "camera: fx {:.3} fy {:.3} cx {:.3} cy {:.3}, rms {:.3} px over {} shots",
        camera.fx(),
        camera.fy(),
        camera.principal_point().x,
        camera.principal_point().y,
        fit.rms_px,
        poses.len()
    );
    outln!(
        "platform: axis [{:.5}, {:.5}, {:.5}], origin [{:.2}, {:.2}, {:.2}] mm, from {} turns spanning {:.1}°, corners {:.3} mm rms off their circles",
        a.x,
        a.y,
        a.z,
        pl.origin().x,
        pl.origin().y,
        pl.origin().z,
        platform.poses,
        platform.span_deg,
        platform.circle_rms_mm
    );
    let report = serde_json::json!({
        "camera": {"fx": camera.fx(), "fy": camera.fy(), "cx": camera.principal_point().x,
                   "cy": camera.principal_point().y, "rms_px": fit.rms_px, "shots": poses.len(),
                   "k3_fixed": k3_fixed},
        "lasers": laser_data,
        "platform": {"axis": [a.x, a.y, a.z], "origin": [pl.origin().x, pl.origin().y, pl.origin().z],
                     "poses": platform.poses, "span_deg": platform.span_deg,
                     "clockwise": clockwise,
                     "turns_clockwise": platform.turns.0, "turns_counter_clockwise": platform.turns.1,
                     "circle_rms_mm": platform.circle_rms_mm},
        "images": images.len(), "dark": dark.iter().filter(|&&d| d).count(),
    });
    let path = report::beside(out);
    write_json(&path, &report)?;
    outln!("wrote {} and {}", out.display(), path.display());
    Ok(())
}

fn chessboard_target((cols, rows): (usize, usize), square: f64) -> Result<Target> {
    if !(square > 0.0 && square <= 1000.0) {
        bail!(
            "--square must be between 0 and 1000 mm, found {}",
            short(square)
        );
    }
    if cols < 3 || rows < 3 {
        bail!(
            "a chessboard needs at least 3x3 squares (2x2 inner corners), found {cols}x{rows} squares"
        );
    }
    Ok(Target::Chessboard { cols, rows, square })
}

fn charuco_target(
    (cols, rows): (usize, usize),
    square: f64,
    marker: Option<f64>,
    dictionary: &str,
    first_id: usize,
) -> Result<Target> {
    // The squares are checked as a chessboard's.
    chessboard_target((cols, rows), square)?;
    let Some(marker) = marker else {
        bail!("--charuco needs --marker: the markers' side, mm (OpenCV's markerLength)");
    };
    if !(marker > 0.0 && marker < square) {
        bail!(
            "--marker {} mm: a ChArUco marker is smaller than its square ({} mm)",
            short(marker),
            short(square)
        );
    }
    let Some(dict) = scanner_calib::aruco::Dictionary::named(dictionary) else {
        bail!(
            "--dictionary {dictionary}: not one of OpenCV's predefined dictionaries ({})",
            scanner_calib::aruco::DICTIONARIES.join(", ")
        );
    };
    let board = scanner_calib::aruco::CharucoBoard {
        cols,
        rows,
        square,
        marker,
        dictionary: dict,
        first_id,
    };
    if board.ids().end > dict.count {
        bail!(
            "a ChArUco board of {cols}x{rows} squares has {} markers: from ID {first_id} they run past the {} codes of {dictionary}",
            board.marker_count(),
            dict.count
        );
    }
    Ok(Target::Charuco(board))
}

fn dot_target((cols, rows): (usize, usize), pitch: f64, dot: f64) -> Result<Target> {
    if !(pitch > dot && dot > 0.0 && pitch <= 1000.0) {
        bail!(
            "--pitch ({} mm) must exceed --dot ({} mm), both positive and at most 1000 mm",
            short(pitch),
            short(dot)
        );
    }
    Ok(Target::Dots(DotGrid {
        cols,
        rows,
        pitch,
        dot,
    }))
}

/// `calibrate distance`: the paper's d_z from the cross at two tape-measured distances.
fn distance_command(
    board: Option<&Path>,
    (near, near_mm): (&Path, f64),
    (far, far_mm): (&Path, f64),
    out: &Path,
) -> Result<()> {
    let b = load_board(board)?;
    let (n, f) = (load_gray(near)?, load_gray(far)?);
    check_size(n.dimensions(), &f)
        .with_context(|| format!("{} against {}", far.display(), near.display()))?;
    let d = scanner_calib::image_distance(&b.cross, (&n, near_mm), (&f, far_mm))?;
    let (w, h) = n.dimensions();
    let cam = Camera::paper(d.d_z, w, h).context("image distance")?;
    let file = CalibrationFile::from_camera(
        &cam,
        (w, h),
        format!(
            "image distance by the paper's two-position procedure (eq. 7-9); mark offset {:.2} mm",
            d.epsilon_mm
        ),
        None,
    );
    file.save(out)?;
    outln!(
        "d_z {:.3} px, mark offset ε {:.2} mm -> {}",
        d.d_z,
        d.epsilon_mm,
        out.display()
    );
    let data = DistanceData {
        d_z_px: d.d_z,
        epsilon_mm: d.epsilon_mm,
    };
    write_json(&report::beside(out), &data)
}

/// The files of `calibrate board`.
struct BoardPaths<'a> {
    board: Option<&'a Path>,
    camera: &'a Path,
    image: &'a Path,
    out: &'a Path,
    overlay: &'a Path,
}

/// `calibrate board`: both planes from one image, the overlay written also when it fails.
fn board_planes_command(p: &BoardPaths, method: BoardMethod) -> Result<()> {
    let b = load_board(p.board)?;
    let cam_file = CalibrationFile::load(p.camera)?;
    let cam = cam_file
        .camera()
        .with_context(|| format!("camera in {}", p.camera.display()))?;
    let img = load_gray(p.image)?;
    check_size((cam_file.image.width, cam_file.image.height), &img).with_context(|| {
        format!(
            "{} with the camera of {}",
            p.image.display(),
            p.camera.display()
        )
    })?;
    let outcome = board_planes(&img, &b, &cam);
    save_png(&overlay::board_overlay(&img, &outcome, &b, &cam), p.overlay)?;
    let turntable = outcome
        .turntable
        .as_ref()
        .map(|t| TurntableData { dots: t.fit.used });
    if let Some(t) = &turntable {
        outln!(
            "turntable disc in the picture: its {} dots are no board markers, left out",
            t.dots
        );
    }
    let fit = match outcome.result {
        Ok(fit) => fit,
        Err(e) => {
            if turntable.is_some() {
                crate::errln!(
                    "the turntable disc lies in the picture: if it hides the board's lower markers, take the board's picture without it"
                );
            }
            let data = BoardData {
                sheets: Vec::new(),
                method: None,
                angle_deg: None,
                turntable,
                error: Some(e.to_string()),
            };
            write_json(&report::beside(p.out), &data)?;
            return Err(e).with_context(|| {
                format!(
                    "board calibration from {} (see {})",
                    p.image.display(),
                    p.overlay.display()
                )
            });
        }
    };
    let mut file = cam_file;
    let used = file.set_board(&fit, &b, &cam, method);
    if used != method {
        crate::errln!(
            "warning: the paper's construction needs all six markers of the paper's layout on each sheet; used the layout pose"
        );
    }
    let angle = file.board.as_ref().map_or(f64::NAN, |s| s.angle_deg);
    file.save(p.out)?;
    for (k, s) in fit.sheets.iter().enumerate() {
        outln!("{}", s.summary(["left", "right"][k]));
        if s.rms_px > scanner_calib::MAX_SHEET_RMS_PX {
            crate::errln!(
                "warning: the {} sheet fits its layout with {:.2} px RMS, a flat print within {} px: is it flat? A bent sheet tilts its plane, by a tenth of a degree or so where the object hides part of it",
                ["left", "right"][k],
                s.rms_px,
                scanner_calib::MAX_SHEET_RMS_PX
            );
        }
    }
    outln!(
        "planes by {}; angle between them {angle:.3}°; -> {} (picture: {})",
        used.name(),
        p.out.display(),
        p.overlay.display()
    );
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
    write_json(&report::beside(p.out), &data)
}

/// `calibrate intrinsics`: a line and an overlay per image (also when the calibration fails),
/// then the camera file.
fn intrinsics_command(
    target: &Target,
    images: &[PathBuf],
    out: &Path,
    overlays: Option<&Path>,
) -> Result<()> {
    let imgs: Vec<GrayImage> = images.iter().map(|p| load_gray(p)).collect::<Result<_>>()?;
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
        outln!("  {}: {}{cropped}", name(i), image_line(&r.status, name));
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
    let dir = overlays.map_or_else(|| default_overlays(out), Path::to_path_buf);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
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
            return Err(e).with_context(|| format!("no camera calibrated {overlays_note}"));
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
    outln!(
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
    );
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
    outln!(
        "coverage: the features used fall in {cells} of the image's {all} cells ({cols}×{rows}), {border} of the {ring} on its border{corners}"
    );
    if k3_fixed {
        outln!(
            "k3 fixed at 0: no feature used lies on the image's border, and only there does k3 show apart from k1 and k2 (shots with the target in the corners let it be fitted)"
        );
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
            print_self_check(c, &picture);
            data.self_check = Some(SelfCheckData::of(c));
        }
        Err(e) => outln!("self-check: not possible ({e})"),
    }
    data.used = used;
    data.camera = Some(CameraData::of(&fit.camera));
    data.rms_px = Some(fit.rms_px);
    data.coverage = Some(CoverageData::of(&fit));
    write_json(&report::beside(out), &data)
}

/// The self-check's lines: the halves' difference, the uncertainty and where to add shots.
fn print_self_check(c: &SelfCheck, picture: &Path) {
    match &c.halves {
        Ok(h) => {
            outln!(
                "cross-validation: halves of {} and {} images differ by {:.3} px rms where the features were ({:.3} px expected from the corner noise of {:.3} px), {:.3} px rms and {:.3} px at most over the whole image",
                h.images.0,
                h.images.1,
                h.features_rms_px,
                h.expected_features_rms_px,
                c.covariance.noise_px,
                h.image_rms_px,
                h.image_max_px
            );
            if h.too_far() {
                outln!(
                    "warning: the halves differ {:.1}× more than the corner noise explains: the lens model does not fit, the target is not flat, or some shots moved or blurred — check the overlays, retake the worst images",
                    h.ratio()
                );
            }
        }
        Err(e) => outln!(
            "cross-validation: not possible ({e}): with {} or more usable images each half is calibrated apart and the two compared",
            2 * scanner_calib::selfcheck::MIN_HALF_IMAGES
        ),
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
    outln!(
        "projection uncertainty: {:.3} px median where the features were, {:.3} px at most{advice} (map: {})",
        c.map.covered_median(),
        c.map.max(),
        picture.display()
    );
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
fn source_note(target: &Target, used: usize) -> String {
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
