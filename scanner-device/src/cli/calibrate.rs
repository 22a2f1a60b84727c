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
use scanner_calib::{BoardMethod, DotGrid, Target, check_size, intrinsics_auto, print, short};

use super::values;
use crate::calibrate::{Said, load_board, load_gray, save_png};
use crate::report::{self, DistanceData, write_json};

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

/// A calibration's words on the terminal: findings to standard output, warnings to standard
/// error.
pub(crate) fn on_terminal(said: Said) {
    match said {
        Said::Line(l) => outln!("{l}"),
        Said::Warning(w) => crate::errln!("warning: {w}"),
    }
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
        } => {
            let plan = crate::calibrate::IntrinsicsPlan {
                target: target.target()?,
                images: images.clone(),
                out: out.clone(),
                overlays: overlays.clone(),
            };
            crate::calibrate::intrinsics(&plan, &mut on_terminal)?;
            Ok(())
        }
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
            let plan = crate::calibrate::BoardPlan {
                board: board.clone(),
                camera: camera.clone(),
                image: image.clone(),
                out: out.clone(),
                overlay: overlay.clone(),
                method: (*method).into(),
            };
            crate::calibrate::board(&plan, &mut on_terminal)?;
            Ok(())
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
    write_json(&report::beside(out), &data)?;
    Ok(())
}
