//! `capture`: still images for calibration from the scan's own source (a camera opened and
//! locked as `scan` opens it, a folder, the virtual rig), each checked at once by the detector
//! that will use it; only usable shots are kept.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use scanner_calib::file::CalibrationFile;
use scanner_calib::{Target, board_planes, find_grid};
use scanner_core::stripe::PixelFormat;

use super::calibrate::TargetArgs;
use crate::calibrate::load_board;
use crate::report::{CaptureData, GridData, ImageRefusal, SheetData, ShotData, write_json};
use crate::source::OwnedFrame;

/// Fewer usable shots than asked for (the report and the kept shots are written).
#[derive(Debug, thiserror::Error)]
#[error(
    "{kept} of {of} usable shots kept (see the line of each frame): check the target is in view, lit and in focus"
)]
pub struct TooFewShots {
    /// Shots kept.
    pub kept: u32,
    /// Shots asked for.
    pub of: u32,
}

/// `capture`'s options.
#[derive(Debug, clap::Args)]
pub struct CaptureArgs {
    /// Frame source, as for `scan`: `/dev/videoN`, `dir:FOLDER`, `rig`, `rig:WIDTHxHEIGHT`.
    #[arg(long)]
    pub source: String,
    /// How the camera is opened: give what the scan will use.
    #[command(flatten)]
    pub camera: super::scan::CameraArgs,
    /// Capture the board (laser off) instead of the intrinsics target; each shot's planes are
    /// fitted with this camera file (from `calibrate intrinsics`).
    #[arg(long, value_name = "CAMERA_FILE")]
    pub board: Option<PathBuf>,
    /// Board file of the printed board (with `--board`); the default board without one.
    #[arg(long)]
    pub board_file: Option<PathBuf>,
    /// The intrinsics target (without `--board`).
    #[command(flatten)]
    pub target: TargetArgs,
    /// Usable shots to keep.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub count: u32,
    /// Seconds between shots from a camera (time to move the target); 0 from files and the rig.
    #[arg(long, default_value_t = 3.0)]
    pub interval: f64,
    /// Frames to try before giving up.
    #[arg(long, default_value_t = 200)]
    pub tries: u32,
    /// Folder for the kept shots (`board.png`, or `grid-00.png`, `grid-01.png`, …).
    #[arg(long, default_value = "captures")]
    pub out: PathBuf,
}

/// What a shot is checked for.
enum Check {
    Board {
        board: Box<scanner_calib::board::BoardFile>,
        camera: scanner_core::Camera<f64>,
    },
    Grid(Target),
}

impl Check {
    /// What the detector found in a shot (its `frame` number): usable when nothing refused it.
    fn run(&self, frame: u32, gray: &image::GrayImage) -> ShotData {
        let mut shot = ShotData {
            frame,
            kept_as: None,
            grid: None,
            sheets: Vec::new(),
            angle_deg: None,
            refused: None,
        };
        match self {
            Check::Board { board, camera } => match board_planes(gray, board, camera).result {
                Ok(fit) => {
                    shot.sheets = fit
                        .sheets
                        .iter()
                        .zip(["left", "right"])
                        .map(|(s, side)| SheetData::of(s, side))
                        .collect();
                    shot.angle_deg = Some(fit.board.angle().to_degrees());
                }
                Err(e) => shot.refused = Some(ImageRefusal::of(&e, |i| i.to_string())),
            },
            Check::Grid(target) => match find_grid(gray, target) {
                Ok(v) => shot.grid = Some(GridData::of(&v)),
                Err(e) => shot.refused = Some(ImageRefusal::of(&e, |i| i.to_string())),
            },
        }
        shot
    }
}

/// One line saying what the detector found in a shot.
fn shot_line(shot: &ShotData) -> String {
    if let Some(r) = &shot.refused {
        return format!("not usable: {}", r.message);
    }
    if let Some(g) = &shot.grid {
        return format!(
            "grid found: {} points identified over {}×{}{}",
            g.points,
            g.cols,
            g.rows,
            if g.complete { ", complete" } else { "" }
        );
    }
    let sheets: Vec<String> = shot
        .sheets
        .iter()
        .map(|s| {
            let mut line = format!(
                "{} sheet: {}/{} markers, rms {:.3} px",
                s.side, s.used, s.markers, s.rms_px
            );
            if !s.missing.is_empty() {
                line += &format!(", missing or dropped {:?}", s.missing);
            }
            line
        })
        .collect();
    format!(
        "{}; the sheets meet at {:.1}°",
        sheets.join("; "),
        shot.angle_deg.unwrap_or(f64::NAN)
    )
}

/// Runs `capture`: takes frames until `--count` usable shots are kept or `--tries` frames were
/// looked at; prints a line per frame.
///
/// # Errors
/// A source that cannot open, a bad camera or board file, fewer usable shots than asked.
pub fn capture(a: &CaptureArgs) -> Result<()> {
    let check = match &a.board {
        Some(camera_file) => Check::Board {
            board: Box::new(load_board(a.board_file.as_deref())?),
            camera: CalibrationFile::load(camera_file)?
                .camera()
                .with_context(|| format!("camera in {}", camera_file.display()))?,
        },
        None => Check::Grid(a.target.target()?),
    };
    if !(a.interval >= 0.0 && a.interval <= 600.0) {
        bail!("--interval must be 0 to 600 seconds, found {}", a.interval);
    }
    let opts = a.camera.options()?;
    let mut source = crate::source::open_with(&a.source, PixelFormat::Rgb24, &opts)
        .with_context(|| format!("source {}", a.source))?;
    let live = a.source.starts_with("/dev/") || a.source.starts_with("v4l:");
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create the output folder {}", a.out.display()))?;
    crate::outln!("capturing from {}", source.describe());
    let mut kept = 0u32;
    let mut shots = Vec::new();
    for shot in 0..a.tries {
        if kept == a.count {
            break;
        }
        if live && shot > 0 {
            std::thread::sleep(Duration::from_secs_f64(a.interval));
        }
        let Some(frame) = source.next_frame().context("the source")? else {
            break;
        };
        let rgb = to_image(&frame)?;
        let mut found = check.run(
            shot,
            &image::DynamicImage::ImageRgb8(rgb.clone()).to_luma8(),
        );
        let name = match (&check, found.refused.is_none()) {
            (_, false) => None,
            (Check::Board { .. }, true) if kept == 0 => Some("board.png".to_string()),
            (Check::Board { .. }, true) => Some(format!("board-{kept:02}.png")),
            (Check::Grid(_), true) => Some(format!("grid-{kept:02}.png")),
        };
        let what = shot_line(&found);
        match name {
            Some(name) => {
                let path = a.out.join(&name);
                let bytes = png_bytes(&rgb)?;
                scanner_calib::file::write_atomic(&path, &bytes)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                kept += 1;
                crate::outln!("frame {shot}: {what} → kept as {name}");
                found.kept_as = Some(name);
            }
            None => crate::outln!("frame {shot}: {what}"),
        }
        shots.push(found);
    }
    let data = CaptureData {
        shots,
        kept,
        count: a.count,
    };
    write_json(&a.out.join("capture-report.json"), &data)?;
    if kept < a.count {
        return Err(TooFewShots { kept, of: a.count }.into());
    }
    crate::outln!("{kept} shots in {}", a.out.display());
    Ok(())
}

/// An RGB frame as an image.
pub(super) fn to_image(f: &OwnedFrame) -> Result<image::RgbImage> {
    image::RgbImage::from_raw(f.width as u32, f.height as u32, f.data.clone())
        .context("a frame of the wrong size for its format")
}

pub(super) fn png_bytes(img: &image::RgbImage) -> Result<Vec<u8>> {
    let mut v = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png)
        .context("encoding a PNG")?;
    Ok(v)
}
