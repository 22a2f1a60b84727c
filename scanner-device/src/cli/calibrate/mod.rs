//! The calibration commands: print the board, calibrate intrinsics / image distance / board.

mod fixed;
mod targets;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Subcommand, ValueEnum};
use scanner_core::Camera;
use scanner_io::outln;

use scanner_calib::board::BoardFile;
use scanner_calib::disc::{Disc, Paper};
use scanner_calib::file::{CalibrationFile, write_atomic};
use scanner_calib::{BoardMethod, Target, check_size, print};

use super::values;
use crate::calibrate::{Said, load_board, load_gray, save_png};
use crate::report::{self, DistanceData, write_json};
use fixed::fixed_command;
use targets::{charuco_target, chessboard_target, dot_target};

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
