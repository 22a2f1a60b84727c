//! The command line of the scanner head: arguments, then a validated plan, then the run.

pub mod calibrate;
pub mod capture;
pub mod import;
pub mod preview;
#[cfg(feature = "rig")]
pub mod render;
pub mod scan;
pub mod serve;
pub mod values;

use std::path::PathBuf;

use clap::{Parser, Subcommand};

/// Command line of the scanner head.
#[derive(Debug, Parser)]
#[command(
    name = "scanner-device",
    version,
    about = "Scanner head: camera → points → serial link"
)]
pub struct Args {
    /// Print the fixed capacities and conventions of this build and exit.
    #[arg(long)]
    pub info: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// The head's commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    #[cfg(feature = "rig")]
    /// Render a scene of the virtual rig to PNG files with ground truth (truth.csv, lasers.csv).
    Render {
        /// Scene file (TOML); the demo scene at 640×480 without one.
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Output folder.
        #[arg(long, default_value = "rig-frames")]
        out: PathBuf,
        /// Write gray PNGs instead of RGB.
        #[arg(long)]
        gray: bool,
        /// Render at most this many frames of the sweep.
        #[arg(long)]
        frames: Option<usize>,
        /// This view of a scene with `[[views]]` (a 360° scan), numbered from 0; its true pose
        /// is written to `view-pose.txt`.
        #[arg(long)]
        view: Option<usize>,
        /// No progress lines.
        #[arg(long, short)]
        quiet: bool,
    },
    #[cfg(feature = "rig")]
    /// Render calibration images of a rig scene: the board without laser, dot-grid shots and the
    /// image-distance cross at two distances.
    RenderCalibration {
        /// Scene file (TOML); the demo scene at 640×480 without one.
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Output folder.
        #[arg(long, default_value = "rig-calibration")]
        out: PathBuf,
        /// Dot-grid shots for the intrinsics (3 to 64): more shots, a steadier focal length
        /// (the rig's 12 leave it about 0.01–0.03 % off, which moves every depth by as much).
        #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u8).range(3..=64))]
        shots: u8,
    },
    /// Write a board file (the paper's layout unless given one) and its printable 1:1 sheets:
    /// left and right sheet and the image-distance cross, as SVG and PNG, with a scale ruler.
    Board {
        /// Board file to print; the default board without one.
        #[arg(long)]
        board: Option<PathBuf>,
        /// Print a board of ChArUco sheets instead of the default board (OpenCV's layout, A3:
        /// 10×7 squares of 30 mm, markers of 22 mm, DICT_5X5_100, IDs 0–34 left and 35–69
        /// right): its corners are named by the markers, so a partly hidden sheet still counts.
        #[arg(long, conflicts_with = "board")]
        charuco: bool,
        /// Output folder.
        #[arg(long, default_value = "board")]
        out: PathBuf,
        /// Resolution of the PNGs, dots per inch.
        #[arg(long, default_value_t = 150.0)]
        dpi: f64,
        /// Also cut every sheet into A4 landscape tiles (`*-a4-ROW-COL.svg`) for a printer
        /// without A3: 10 mm overlaps with alignment crosses, a 100 mm bar on each.
        #[arg(long)]
        a4: bool,
        /// Also print the turntable disc the object stands on for a 360° scan, on this paper
        /// (`a4`: a disc of 190 mm, `a3`: 277 mm): `turntable-a4.svg` and `.png`.
        #[arg(long, value_name = "PAPER")]
        turntable: Option<scanner_calib::disc::Paper>,
    },
    /// Calibrate from images: intrinsics, the paper's image distance, or the board planes.
    #[command(subcommand)]
    Calibrate(calibrate::Calibrate),
    /// Capture still images for calibration from the scan's source (a camera locked as `scan`
    /// locks it, a folder, the rig): each is checked by the detector at once and only usable
    /// shots are kept.
    Capture(capture::CaptureArgs),
    /// Scan: frames from the source through the pipeline to point packets on the link.
    Scan(scan::ScanArgs),
    /// Preview: the camera's picture about once a second with what the head finds in it (the
    /// board's dots, the laser line, clipped pixels, the laser's margin, and with a calibration
    /// what a scan would skip and why), on the link for the host's page: aim, focus and set the
    /// exposure before a scan.
    Preview(preview::PreviewArgs),
    /// The head as a service on a two-way link (`--out serial:PATH[@BAUD]` or `-`): it waits
    /// for the host's commands (preview, calibration shots, calibrate, sweep, stop, laser,
    /// turntable) and answers each; the studio (`scanner-host studio`) drives it. A Pi's unit
    /// starts it once.
    Serve(Box<serve::ServeArgs>),
    /// List the V4L2 cameras with their formats and sizes.
    Devices,
    /// Import another program's calibration: a FabScanPi config or a Horus calibration.json
    /// (camera, laser planes and platform, for `scan --fixed-laser`, turned back to the frames
    /// as the camera stores them), or a camera from OpenCV (FileStorage .yml, .yaml, .xml) or
    /// NumPy (.npz)
    Import(import::ImportArgs),
    /// Import a FabScanPi config (`*.config.json`): its camera, laser planes and platform into
    /// a calibration file for `scan --fixed-laser`, turned back to the frames as the camera
    /// stores them.
    ImportFabscan {
        /// FabScanPi's config.
        config: PathBuf,
        /// The calibration file to write.
        #[arg(long, default_value = "calibration.toml")]
        out: PathBuf,
    },
}

/// Runs the scanner head with parsed arguments.
///
/// # Errors
/// Any failure of the run, with context naming what failed.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.info {
        crate::outln!(
            "scanner-device {}: units mm, camera +z forward, +y down; markers per plane ≤ {}",
            env!("CARGO_PKG_VERSION"),
            scanner_core::geometry::pose::MAX_MARKERS
        );
        return Ok(());
    }
    match &args.command {
        #[cfg(feature = "rig")]
        Some(Command::Render {
            scene,
            out,
            gray,
            frames,
            view,
            quiet,
        }) => {
            let job = render::RenderJob {
                scene: scene.clone(),
                out: out.clone(),
                gray: *gray,
                frames: *frames,
                view: *view,
            };
            let n = render::render(&job, |done, total| {
                if !quiet && (done % 10 == 0 || done == total) {
                    crate::errln!("rendered {done}/{total} frames");
                }
            })?;
            crate::outln!(
                "wrote the reference, {n} frames, truth.csv and lasers.csv to {}",
                out.display()
            );
        }
        #[cfg(feature = "rig")]
        Some(Command::RenderCalibration { scene, out, shots }) => {
            let scene = render::load_scene(scene.as_deref())?;
            let rig = scanner_rig::Rig::new(scene)
                .map_err(|e| anyhow::anyhow!("building the virtual rig: {e}"))?;
            render::render_calibration(&rig, out, usize::from(*shots))?;
            crate::outln!(
                "wrote board.png, grid-00..{:02}.png, cross-near.png, cross-far.png, shots.txt and truth-calibration.toml to {}",
                shots - 1,
                out.display()
            );
        }
        Some(Command::Board {
            board,
            charuco,
            out,
            dpi,
            a4,
            turntable,
        }) => {
            if !(*dpi >= 25.0 && *dpi <= 1200.0) {
                anyhow::bail!("--dpi must be between 25 and 1200, found {dpi}");
            }
            let b = if *charuco {
                scanner_calib::board::BoardFile::charuco_default()
            } else {
                crate::calibrate::load_board(board.as_deref())?
            };
            calibrate::board_command(&b, out, *dpi, *a4, *turntable)?;
        }
        Some(Command::Calibrate(c)) => calibrate::calibrate(c)?,
        Some(Command::Scan(a)) => {
            let done = scan::scan(a)?;
            crate::scan::print_report(&done, a.out.trim() == "-");
            if let Some(path) = &a.report {
                crate::report::write_json(path, &crate::report::ScanData::from(&done))?;
            }
            if let Some(e) = done.ended_early {
                anyhow::bail!("{e}");
            }
            let (lines, limit) = done.beyond_limit;
            if done.status.points == 0 && lines > 0 {
                return Err(scan::ScanFailed::TooWide { lines, limit }.into());
            }
            if let Some(t) = &done.temporal
                && let Some(polarity) = t.contradicted()
            {
                return Err(scan::ScanFailed::PlanesContradicted {
                    polarity,
                    planes: t.planes[polarity],
                    tried: t.planes_tried[polarity],
                }
                .into());
            }
            if let Some(b) = done.shadow.filter(crate::session::ShadowBands::blurred) {
                return Err(scan::ScanFailed::BlurredShadow {
                    lines: b.lines,
                    edged: b.edged,
                }
                .into());
            }
        }
        Some(Command::Preview(a)) => {
            preview::preview(a)?;
        }
        Some(Command::Capture(a)) => capture::capture(a)?,
        Some(Command::Serve(a)) => serve::serve(a)?,
        Some(Command::Devices) => scan::devices(),
        Some(Command::Import(a)) => import::import(a)?,
        Some(Command::ImportFabscan { config, out }) => import::import_fabscan(config, out)?,
        None => crate::outln!("scanner-device: nothing to do yet (try --help)"),
    }
    Ok(())
}
