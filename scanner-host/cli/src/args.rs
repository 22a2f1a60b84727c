//! The arguments: what the user typed, parsed by clap; each command checks them into its plan.

use std::net::SocketAddr;
use std::path::PathBuf;

use clap::{Parser, Subcommand};
use scanner_host::grid::Cell;
use scanner_host::link::Input;
use scanner_host::views::Thickness;
use scanner_merge::MergeOptions;

/// Command line of the host tool.
#[derive(Debug, Parser)]
#[command(
    name = "scanner-host",
    version,
    about = "Host: point packets → grid → OBJ and pictures"
)]
pub struct Args {
    /// Print the conventions of this build and exit.
    #[arg(long)]
    pub info: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Options shared by `receive` and `replay`.
#[derive(Debug, clap::Args)]
pub struct OutputArgs {
    /// Output folder (created): scan.obj, scan.ply, scan.stl, depth.png, preview.png,
    /// summary.txt.
    #[arg(long, default_value = "scan-out")]
    pub out: PathBuf,
    /// Grid cell: pixels (`2px`) or millimetres (`0.5mm`).
    #[arg(long, default_value = "2px")]
    pub cell: Cell,
    /// Cells with fewer samples are left out of the mesh.
    #[arg(long, default_value_t = 1)]
    pub min_count: u32,
    /// Leave the gaps between stripes open: by default an empty cell in a gap of up to two
    /// cells between two cells of one surface gets a vertex between them (interpolated, not
    /// measured; the summary counts them), where an uneven sweep skipped a row.
    #[arg(long)]
    pub no_bridge: bool,
    /// The meshes' frame: `board` (y up, for MeshLab/Blender/CloudCompare) or `camera` (+y
    /// down, +z forward). The pictures are the camera's view either way.
    #[arg(long, value_enum, default_value_t = FrameArg::Board)]
    pub frame: FrameArg,
    /// The laser sheet's thickness, mm (the Gaussian σ across it; a line laser's line width
    /// at half its brightness is 2.355 σ): each frame's points are moved to where the sheet's
    /// middle crosses the surface, which on a curved surface is not the lit band's centre (up
    /// to 0.1 mm on the rig's bunny at σ 0.6 mm). The scan is read twice for it. 0: the points
    /// as the head sent them.
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    pub sheet: f64,
    /// A turntable scan: the output folder of the same object scanned with the scanner's
    /// other laser. The two models are held against each other (summary.json → `lasers`), and
    /// when they disagree the model is refused (exit status 1, every output written) unless
    /// `--accept-disagreement`
    #[arg(long, value_name = "DIR")]
    pub other_laser: Option<PathBuf>,
    /// The median distance within which two lasers' models agree, mm (their volumes within
    /// 2 %)
    #[arg(long, value_name = "MM", default_value_t = 0.3)]
    pub agree_within: f64,
    /// Keep a model whose two lasers disagree: said, not refused
    #[arg(long)]
    pub accept_disagreement: bool,
    /// No progress display.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The host's commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Receive a scan from the head: `serial:PATH[@BAUD]`, a recorded stream file, `-` for
    /// stdin, or `pty`: a new pseudo-terminal pair whose device end (printed, and written to
    /// OUT/device-port) the head writes to, like a serial cable. Every accepted frame is journaled to OUT/journal.stream as it arrives; the outputs
    /// are written when the input ends, the head's final status arrives (`--until-done`), or on
    /// Ctrl-C.
    Receive {
        /// The input.
        input: Input,
        /// Stop at the first final status from the head.
        #[arg(long)]
        until_done: bool,
        /// Add this session to an existing OUT/journal.stream (by default a folder whose
        /// journal already holds a scan is refused, so that two sessions never mix by accident).
        #[arg(long)]
        append: bool,
        /// Each scan of this session is one view of an object turned between sweeps: at the
        /// end the journal is split into OUT/view-1, view-2, … (each with its own outputs) and
        /// the views are merged into OUT/model as `merge` does with its defaults. End the
        /// session with Ctrl-C or the input's end (--until-done would stop after the first).
        #[arg(long, conflicts_with = "until_done")]
        merge: bool,
        /// With --merge: the object was turned by DEG about the vertical between sweeps (a
        /// turntable's step), a hint to the merge as `merge --turntable` takes it.
        #[arg(
            long,
            value_name = "DEG",
            requires = "merge",
            allow_negative_numbers = true
        )]
        turntable: Option<f64>,
        /// With --merge: the share of a view's points that must fit another view for their
        /// registration to count, as `merge --min-overlap` takes it (views turned by 60° or
        /// more by hand often share only a third: give 0.3; views on the turntable disc need
        /// none).
        #[arg(long, requires = "merge", default_value_t = MergeOptions::default().min_overlap)]
        min_overlap: f64,
        /// Show the scan live in a web browser: serves a page on ADDR:PORT (default
        /// 127.0.0.1 and a free port, printed). Another address than loopback (e.g.
        /// `0.0.0.0:8080`, to watch from a phone) prints a warning and needs the random token in
        /// the printed address.
        #[arg(long, value_name = "ADDR:PORT", num_args = 0..=1, default_missing_value = "127.0.0.1:0")]
        view: Option<SocketAddr>,
        /// With --view: how long the page stays up after the scan, with the mesh and the files
        /// to download, seconds (default: until Ctrl-C).
        #[arg(long, value_name = "SECS", requires = "view")]
        view_for: Option<f64>,
        /// Outputs.
        #[command(flatten)]
        out: OutputArgs,
    },
    /// Rebuild all outputs from a journal or a raw recording.
    Replay {
        /// The journal or recording.
        input: PathBuf,
        /// Outputs.
        #[command(flatten)]
        out: OutputArgs,
    },
    /// Register several sweeps of one object, turned between them, into one frame and fuse them
    /// into one closed mesh (views: receive output folders or journals): writes
    /// model.obj/ply/stl/3mf (y up), views.ply (each view in its colour) and merge-report.txt.
    Merge {
        /// The views (each overlapping at least one other; view 0, the first, is the frame).
        #[arg(required = true)]
        views: Vec<PathBuf>,
        /// Output folder.
        #[arg(long, default_value = "model")]
        out: PathBuf,
        /// Grid cell of each view (as for receive). Default: 2 px for every 640 px of the view's
        /// image width (the same cell on the object whatever the camera: 4 px at 1280×960).
        #[arg(long)]
        cell: Option<Cell>,
        /// Voxel size the views are thinned to for the coarse match, mm.
        #[arg(long, default_value_t = MergeOptions::default().voxel_mm)]
        voxel: f64,
        /// Grid cell of the fusion into one mesh, mm.
        #[arg(long, default_value_t = MergeOptions::default().fuse_cell_mm)]
        fuse_cell: f64,
        /// Least share of a view's points that must land on another view for a candidate match
        /// (0.1–0.9); lower it for views turned far apart, which share less.
        #[arg(long, default_value_t = MergeOptions::default().min_overlap)]
        min_overlap: f64,
        /// A hint: the object was turned by DEG about the vertical (a turntable's step, either
        /// way round) between consecutive views. The turn is tried beside the registration's own
        /// guesses (where its axis stands is searched), and a match that agrees with it (within
        /// 5°) decides between matches that fit alike, as a nearly symmetric object's front and
        /// back do; a view that no step fits (laid over by hand) is placed by its own matches.
        /// Not needed for an object that looks different from every side: without it, views
        /// the merge finds to be turns about one axis (a turntable's, any steps) are refined as
        /// such all the same.
        #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
        turntable: Option<f64>,
        /// Register by the object's shape alone, even where the views carry the turntable
        /// disc's pose (by default views scanned on the disc, `scanner-device scan --disc`, are
        /// posed by it).
        #[arg(long)]
        no_disc: bool,
        /// The laser sheet's thickness, mm (the Gaussian σ across it; a line laser's line width
        /// at half its brightness is 2.355 σ): each view's points are moved to where the sheet's
        /// middle crosses the surface, which on a curved surface is not the lit band's centre
        /// (up to 0.1 mm on the rig's bunny at σ 0.6 mm). 0: points as the head sent them.
        /// `auto`: the thickness where the views agree best, from 0 to 1.2 mm (each tried
        /// thickness reads and refines the views again: the 360° demo's merge takes 18 s
        /// instead of 7 s; reported).
        #[arg(long, value_name = "MM|auto", default_value = "0")]
        sheet: Thickness,
        /// Remove the surface no view saw (farther than three fusion cells from every point):
        /// by default the fusion closes it smoothly (by the points' winding number) and the
        /// model is watertight; trimmed, it is open where the views left gaps.
        #[arg(long, conflicts_with = "flat_base")]
        trim_unseen: bool,
        /// Close the model flat at the bottom, for printing: cut it level with the lowest point
        /// any view saw (up: the board's crease) and cap it flat; the unseen surface below that
        /// goes, the rest is closed smoothly.
        #[arg(long)]
        flat_base: bool,
        /// Show the registered views and the fused model in a web browser (as for receive).
        #[arg(long, value_name = "ADDR:PORT", num_args = 0..=1, default_missing_value = "127.0.0.1:0")]
        view: Option<SocketAddr>,
        /// With --view: how long the page stays up after the merge, seconds (default: until
        /// Ctrl-C).
        #[arg(long, value_name = "SECS", requires = "view")]
        view_for: Option<f64>,
        /// No progress display.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Check the scanner on an artefact of known size (after VDI/VDE 2634-2): sphere size and
    /// form, two spheres' spacing, a plane's flatness, in mm and % of the distance, each passed
    /// or failed against its tolerance; writes OUT/check-report.txt and check-residuals.png and
    /// ends with an error when a figure fails.
    Check {
        /// The scan of the artefact: a receive output folder, a journal or a recording.
        scan: PathBuf,
        /// A sphere's nominal diameter, mm (give it twice for a bar of two spheres).
        #[arg(long = "sphere", value_name = "MM")]
        spheres: Vec<f64>,
        /// The nominal distance between the two spheres' centres, mm.
        #[arg(long, value_name = "MM")]
        spacing: Option<f64>,
        /// The flatness of the largest plane in the scan (the board itself, scanned with
        /// `scanner-device scan --keep-board`).
        #[arg(long)]
        plane: bool,
        /// Tolerance of the sphere size and spacing errors, ± % of the distance.
        #[arg(long, value_name = "PCT", default_value_t = 0.05)]
        size_tolerance: f64,
        /// Tolerance of the sphere form error, % of the distance.
        #[arg(long, value_name = "PCT", default_value_t = 0.15)]
        form_tolerance: f64,
        /// Tolerance of the flatness, % of the distance.
        #[arg(long, value_name = "PCT", default_value_t = 0.08)]
        flatness_tolerance: f64,
        /// Grid cell (as for receive).
        #[arg(long, default_value = "2px")]
        cell: Cell,
        /// The laser sheet's thickness, mm (as for receive): the points are moved to where the
        /// sheet's middle crosses the surface before the check (a sphere's size moves with it).
        #[arg(long, value_name = "MM", default_value_t = 0.0)]
        sheet: f64,
        /// Output folder.
        #[arg(long, default_value = "check")]
        out: PathBuf,
    },
    /// List the serial ports.
    Ports,
    /// The whole job from one browser page: set-up, calibration, sweeps, the merge and the
    /// model's files, the head driven by commands; the job is kept in a project folder (open
    /// the same folder again to go on). Prints the page's address.
    Studio(StudioArgs),
}

/// `--frame`: which frame the meshes are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameArg {
    /// The board's, y up: the right way up in MeshLab, Blender, CloudCompare (default).
    Board,
    /// The camera's: +y down, +z forward, as the head sends the points.
    Camera,
}

impl From<FrameArg> for scanner_host::FrameChoice {
    fn from(f: FrameArg) -> Self {
        match f {
            FrameArg::Board => scanner_host::FrameChoice::Board,
            FrameArg::Camera => scanner_host::FrameChoice::Camera,
        }
    }
}

/// `studio`'s options.
#[derive(Debug, Clone, clap::Args)]
pub struct StudioArgs {
    /// The head: `child` (this PC's camera or the virtual rig: the studio starts `scanner-device
    /// serve` beside it, with `--head-args`), or `serial:PATH[@BAUD]` (a Pi at the end of its
    /// cable, its service running).
    #[arg(long, default_value = "child")]
    pub head: String,
    /// With `--head child`: the head's frame source, as `scanner-device serve --source` takes
    /// it (`rig` for the virtual rig).
    #[arg(long, default_value = "/dev/video0")]
    pub source: String,
    /// With `--head child`: the camera's resolution, WIDTHxHEIGHT.
    #[arg(long)]
    pub size: Option<String>,
    /// With `--head child`: more of the head's settings, as `scanner-device serve` takes them
    /// (e.g. `--scene job.toml` with `--source rig`), in one argument.
    #[arg(long, default_value = "", allow_hyphen_values = true)]
    pub head_args: String,
    /// With `--head child`: talk to it over a pseudo-terminal (as over a Pi's cable) instead of
    /// pipes.
    #[arg(long)]
    pub pty: bool,
    /// The project folder: the job, each view's journal, the head's shots and calibration,
    /// the model.
    #[arg(long, default_value = "scan-project")]
    pub project: PathBuf,
    /// Where the page is served (a loopback address needs no token; any other gets one,
    /// printed with the address).
    #[arg(long, default_value = "127.0.0.1:8090")]
    pub listen: SocketAddr,
    /// A name of this machine the page may be opened by beside its addresses (e.g.
    /// `scanner.local`); repeat for more. Requests naming any other host are refused (421), so
    /// that no other site's page can reach the studio through a name it points here.
    #[arg(long, value_name = "NAME")]
    pub allow_host: Vec<String>,
    /// Stop after this many seconds (default: at Ctrl-C).
    #[arg(long, value_name = "SECS")]
    pub for_secs: Option<f64>,
}
