//! The command line: `receive`, `replay`, `ports`.

use std::io::Read;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

use crate::collect::{CollectOptions, Collector, Journal};
use crate::grid::Cell;
use crate::link::Input;
use crate::live::LiveView;
use crate::mesh::MeshFrame;
use crate::outputs::{
    FrameChoice, OutputOptions, Summary, mesh_of, replay_corrected, write_outputs,
};

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
    /// The meshes' frame: `board` (y up, for MeshLab/Blender/CloudCompare) or `camera` (+y
    /// down, +z forward). The pictures are the camera's view either way.
    #[arg(long, value_enum, default_value_t = FrameChoice::Board)]
    pub frame: FrameChoice,
    /// The laser sheet's thickness, mm (the Gaussian σ across it; a line laser's line width
    /// at half its brightness is 2.355 σ): each frame's points are moved to where the sheet's
    /// middle crosses the surface, which on a curved surface is not the lit band's centre (up
    /// to 0.1 mm on the rig's bunny at σ 0.6 mm). The scan is read twice for it. 0: the points
    /// as the head sent them.
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    pub sheet: f64,
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
        /// Grid cell of each view (as for receive).
        #[arg(long, default_value = "2px")]
        cell: Cell,
        /// Voxel size the views are thinned to for the coarse match, mm.
        #[arg(long, default_value_t = crate::merge::VOXEL_MM)]
        voxel: f64,
        /// Grid cell of the fusion into one mesh, mm.
        #[arg(long, default_value_t = crate::merge::FUSE_CELL_MM)]
        fuse_cell: f64,
        /// Least share of a view's points that must land on another view for a candidate match
        /// (0.1–0.9); lower it for views turned far apart, which share less.
        #[arg(long, default_value_t = crate::merge::MIN_OVERLAP)]
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
        /// The laser sheet's thickness, mm (the Gaussian σ across it; a line laser's line width
        /// at half its brightness is 2.355 σ): each view's points are moved to where the sheet's
        /// middle crosses the surface, which on a curved surface is not the lit band's centre
        /// (up to 0.1 mm on the rig's bunny at σ 0.6 mm). 0: points as the head sent them.
        /// `auto`: the thickness where the views agree best, from 0 to 1.2 mm (each tried
        /// thickness reads and refines the views again: the 360° demo's merge takes 18 s
        /// instead of 7 s; reported).
        #[arg(long, value_name = "MM|auto", default_value = "0")]
        sheet: SheetArg,
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
}

impl OutputArgs {
    fn output_options(&self) -> OutputOptions {
        OutputOptions {
            min_count: self.min_count,
            frame: self.frame,
        }
    }
}

fn collect_options(o: &OutputArgs) -> CollectOptions {
    CollectOptions {
        cell: o.cell,
        ..CollectOptions::default()
    }
}

fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new_spinner();
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    pb
}

/// Refuses a receive that would read its own journal, or mix into an earlier session's journal
/// unless told to append; returns the journal's length before this session (where this
/// session's frames will start).
fn check_journal(input: &Input, journal: &std::path::Path, append: bool) -> Result<u64> {
    if let Input::File(path) = input
        && let (Ok(a), Ok(b)) = (path.canonicalize(), journal.canonicalize())
        && a == b
    {
        anyhow::bail!(
            "{} is this output folder's own journal: receiving from it would append to what it reads; use `scanner-host replay {}` or another --out",
            path.display(),
            path.display()
        );
    }
    let held = std::fs::metadata(journal).map_or(0, |m| m.len());
    if held > 0 && !append {
        anyhow::bail!(
            "{} already holds {held} bytes from an earlier session: give another --out, move it away, or add --append to add this session to it",
            journal.display()
        );
    }
    Ok(held)
}

/// Refuses a `--view-for` that is no duration.
fn check_view_for(secs: Option<f64>) -> Result<()> {
    match secs {
        Some(s) if !(s.is_finite() && (0.0..=31_536_000.0).contains(&s)) => {
            anyhow::bail!("--view-for must be 0 to 31536000 seconds (a year), found {s}")
        }
        _ => Ok(()),
    }
}

/// Keeps the live view up after the work: `for_secs`, or until Ctrl-C.
fn linger(v: &LiveView, for_secs: Option<f64>) {
    match for_secs {
        Some(s) => crate::errln!("the live view shows the result at {} for {s} s", v.url()),
        None => crate::errln!(
            "the live view shows the result at {}; Ctrl-C to quit",
            v.url()
        ),
    }
    // A Ctrl-C that ended the work does not end the page: the next one does.
    let stop = interrupted();
    stop.store(false, Ordering::SeqCst);
    v.linger(stop, for_secs);
}

/// Keeps the live view up after a merge ([`linger`]); a merge that stopped is shown on the page
/// as stopped, with what it left in `dir`, and its error said before the page lingers (the exit
/// status still fails).
fn linger_after_merge(
    v: &LiveView,
    merged: Result<()>,
    dir: &std::path::Path,
    for_secs: Option<f64>,
) -> Result<()> {
    if let Err(e) = &merged {
        crate::errln!("scanner-host: error: {e:#}");
        v.stopped(dir, MERGE_REFUSED_FILES, &format!("{e:#}"));
    }
    linger(v, for_secs);
    merged.map_err(|_| anyhow::anyhow!("the merge stopped (the reason above)"))
}

/// Set by Ctrl-C (and SIGTERM); the handler is installed once per process.
fn interrupted() -> &'static AtomicBool {
    static STOP: AtomicBool = AtomicBool::new(false);
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        // Another handler already installed in this process (tests) leaves the flag unset.
        let _ = ctrlc::set_handler(|| STOP.store(true, Ordering::SeqCst));
    });
    &STOP
}

/// Starts the live view and says where it is.
fn start_view(addr: SocketAddr) -> Result<LiveView> {
    let v = LiveView::start(addr)?;
    if v.is_public() {
        crate::errln!(
            "warning: the live view is served on {addr}, reachable from other machines on the network; the token in its address is the only key"
        );
    }
    crate::errln!("live view: {}", v.url());
    Ok(v)
}

/// Hands the frames accepted since the last call to the live view.
fn publish(c: &mut Collector, v: &mut LiveView) {
    if !v.has_frame()
        && let Some(board) = c.header().and_then(|h| h.board().ok())
    {
        v.set_frame(MeshFrame::board(&board));
    }
    for (pts, rgb) in c.take_watched() {
        v.points(&pts, &rgb);
    }
}

fn receive(
    input: &Input,
    (until_done, append, merge): (bool, bool, bool),
    view: Option<SocketAddr>,
    o: &OutputArgs,
) -> Result<(Summary, Option<LiveView>)> {
    std::fs::create_dir_all(&o.out)
        .with_context(|| format!("cannot create the output folder {}", o.out.display()))?;
    let journal_path = o.out.join("journal.stream");
    let held = check_journal(input, &journal_path, append)?;
    let mut c = Collector::new(collect_options(o), Some(Journal::open(&journal_path)?));
    let stop = interrupted();
    stop.store(false, Ordering::SeqCst);
    let mut view = view.map(start_view).transpose()?;
    if view.is_some() {
        c.watch();
    }
    let mut input = input.open()?;
    if let Some(name) = &input.device {
        crate::export::write_atomic(&o.out.join("device-port"), name.as_bytes())?;
        crate::errln!("device end of the link: {name}");
    }
    let pb = progress_bar(o.quiet);
    let t0 = Instant::now();
    let mut buf = vec![0u8; 1 << 16];
    let mut last_draw = Instant::now();
    let ended = loop {
        if stop.load(Ordering::SeqCst) {
            break "stopped (Ctrl-C)";
        }
        match input.reader.read(&mut buf) {
            Ok(0) => break "input ended",
            Ok(n) => {
                c.feed(&buf[..n])?;
                if let Some(v) = &mut view {
                    publish(&mut c, v);
                }
            }
            Err(e)
                if e.kind() == std::io::ErrorKind::TimedOut
                    || e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => {
                pb.println(format!("input failed: {e}; writing what was received"));
                break "input failed";
            }
        }
        if until_done && c.counts().status.values().any(|s| s.done) {
            break "the head's scan is done";
        }
        if last_draw.elapsed() > Duration::from_millis(100) {
            let k = c.counts();
            pb.set_message(format!(
                "frames {}, points {}, {:.0} points/s, link errors {}",
                k.decode.frames,
                k.points,
                k.points as f64 / t0.elapsed().as_secs_f64().max(1e-3),
                k.decode.rejected()
            ));
            pb.tick();
            if let Some(v) = &view {
                v.status(&k);
            }
            last_draw = Instant::now();
        }
    };
    pb.finish_and_clear();
    c.finish();
    c.sync()?;
    if !o.quiet {
        crate::errln!("{ended}; journal: {}", journal_path.display());
    }
    // --sheet: this session's frames read again from the journal, corrected.
    if o.sheet > 0.0
        && let Some(correction) = crate::outputs::sheet_correction(&c, o.sheet)
    {
        let again = replay_corrected(collect_options(o), &journal_path, held, correction)?;
        c.regrid(again);
    }
    let summary = write_outputs(&c, &o.out, &o.output_options())?;
    // (With --merge the page is given the merged model instead.)
    if let Some(v) = view.as_ref().filter(|_| !merge) {
        v.finish(
            Some(&c.counts()),
            mesh_of(&c, &o.output_options()),
            &o.out,
            &crate::outputs::OUTPUT_FILES,
            ended,
        );
    }
    Ok((summary, view))
}

/// Runs the host tool with parsed arguments.
///
/// # Errors
/// Any failure of the run, with context naming what failed.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.info {
        crate::outln!(
            "scanner-host {}: units mm, camera +z forward, +y down",
            env!("CARGO_PKG_VERSION")
        );
        return Ok(());
    }
    let summary = match &args.command {
        None => {
            crate::outln!("scanner-host: nothing to do (try --help)");
            return Ok(());
        }
        Some(Command::Ports) => {
            let ports = serialport::available_ports().context("listing serial ports")?;
            if ports.is_empty() {
                crate::outln!("no serial ports found");
            }
            for p in ports {
                crate::outln!("{}: {:?}", p.port_name, p.port_type);
            }
            return Ok(());
        }
        Some(Command::Receive {
            input,
            until_done,
            append,
            merge,
            turntable,
            view,
            view_for,
            out,
        }) => {
            check_view_for(*view_for)?;
            check_sheet(out.sheet)?;
            check_turntable(*turntable)?;
            let (summary, view) = receive(input, (*until_done, *append, *merge), *view, out)?;
            crate::outln!("{}", summary.text().trim_end());
            let merged = if *merge {
                merge_sweeps(out, *turntable, view.as_ref())
            } else {
                Ok(())
            };
            return match view {
                Some(v) => linger_after_merge(&v, merged, &out.out.join("model"), *view_for),
                None => merged,
            };
        }
        Some(Command::Merge {
            views,
            out,
            cell,
            voxel,
            fuse_cell,
            min_overlap,
            turntable,
            sheet,
            trim_unseen,
            flat_base,
            view,
            view_for,
            quiet,
        }) => {
            check_view_for(*view_for)?;
            check_turntable(*turntable)?;
            let view = view.map(start_view).transpose()?;
            let merged = merge_command(
                views,
                out,
                *cell,
                (*voxel, *fuse_cell, *min_overlap, *turntable, *sheet),
                (*trim_unseen, *flat_base, *quiet),
                view.as_ref(),
            );
            return match view {
                Some(v) => linger_after_merge(&v, merged, out, *view_for),
                None => merged,
            };
        }
        Some(Command::Check {
            scan,
            spheres,
            spacing,
            plane,
            size_tolerance,
            form_tolerance,
            flatness_tolerance,
            cell,
            sheet,
            out,
        }) => {
            check_sheet(*sheet)?;
            let tolerances = crate::check::Tolerances {
                size_pct: *size_tolerance,
                form_pct: *form_tolerance,
                flatness_pct: *flatness_tolerance,
            };
            return check_command(
                scan,
                (spheres, *spacing, *plane),
                tolerances,
                (*cell, *sheet),
                out,
            );
        }
        Some(Command::Replay { input, out }) => {
            check_sheet(out.sheet)?;
            let c = crate::outputs::replay(collect_options(out), input, out.sheet)?;
            write_outputs(&c, &out.out, &out.output_options())?
        }
    };
    crate::outln!("{}", summary.text().trim_end());
    Ok(())
}

/// The thickest laser sheet `--sheet` takes, mm (σ; a line 12 mm wide at half its brightness,
/// far thicker than any line laser meant for scanning).
const MAX_SHEET_MM: f64 = 5.0;

/// `merge --sheet`: the laser sheet's thickness given (mm, 0: off), or `auto`: found from where
/// the views agree best ([`crate::merge::disagreement`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SheetArg {
    /// Given, mm.
    Mm(f64),
    /// Found by the merge.
    Auto,
}

impl std::str::FromStr for SheetArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "auto" {
            return Ok(SheetArg::Auto);
        }
        s.parse::<f64>().map(SheetArg::Mm).map_err(|_| {
            format!("expected the sheet's thickness in mm (0 to {MAX_SHEET_MM}) or \"auto\"")
        })
    }
}

/// Refuses a `--sheet` that is no sheet's thickness.
fn check_sheet(sheet: f64) -> Result<()> {
    if !(0.0..=MAX_SHEET_MM).contains(&sheet) {
        anyhow::bail!("--sheet must be 0 (off) to {MAX_SHEET_MM} mm, found {sheet}");
    }
    Ok(())
}

/// What a refused merge leaves to look at (those written before it stopped).
const MERGE_REFUSED_FILES: &[&str] = &["views.png", "views.ply", "merge-report.txt"];

/// `--turntable`'s step must turn the object (more than 0°) and at most half a turn either way.
fn check_turntable(step: Option<f64>) -> Result<()> {
    match step {
        Some(t) if !(t.abs() > 0.0 && t.abs() <= 180.0) => anyhow::bail!(
            "--turntable must be a step of more than 0 and at most 180 degrees, found {t}"
        ),
        _ => Ok(()),
    }
}

/// `receive --merge`: the session's journal split into one view per scan, each view's
/// outputs, and the merge of the views into OUT/model (with a turntable's step, if given).
fn merge_sweeps(o: &OutputArgs, turntable: Option<f64>, view: Option<&LiveView>) -> Result<()> {
    let folders = crate::merge::split_scans(&o.out.join("journal.stream"), &o.out)?;
    for f in &folders {
        let c = crate::outputs::replay(collect_options(o), &f.join("journal.stream"), o.sheet)?;
        let s = write_outputs(&c, f, &o.output_options())?;
        crate::outln!(
            "{}: {}",
            f.display(),
            s.text().lines().next().unwrap_or_default()
        );
    }
    merge_command(
        &folders,
        &o.out.join("model"),
        o.cell,
        (
            crate::merge::VOXEL_MM,
            crate::merge::FUSE_CELL_MM,
            crate::merge::MIN_OVERLAP,
            turntable,
            SheetArg::Mm(o.sheet),
        ),
        (false, false, o.quiet),
        view,
    )
}

fn merge_command(
    views: &[PathBuf],
    out: &std::path::Path,
    cell: Cell,
    (voxel, fuse_cell, min_overlap, turntable, sheet): (f64, f64, f64, Option<f64>, SheetArg),
    (trim_unseen, flat_base, quiet): (bool, bool, bool),
    view: Option<&LiveView>,
) -> Result<()> {
    use crate::merge;
    let stage = |text: &str| {
        if let Some(v) = view {
            v.stage(text);
        }
    };
    if !(voxel > 0.0 && voxel <= 50.0) {
        anyhow::bail!("--voxel must be more than 0 and at most 50 mm, found {voxel}");
    }
    if !(0.1..=20.0).contains(&fuse_cell) {
        anyhow::bail!("--fuse-cell must be 0.1 to 20 mm, found {fuse_cell}");
    }
    if !(0.1..=0.9).contains(&min_overlap) {
        anyhow::bail!("--min-overlap must be 0.1 to 0.9, found {min_overlap}");
    }
    if let SheetArg::Mm(mm) = sheet {
        check_sheet(mm)?;
    }
    if views.len() < 2 {
        return Err(merge::MergeError::TooFewViews(views.len()).into());
    }
    let opts = crate::register::RegisterOptions {
        voxel_mm: voxel,
        min_overlap,
        ..Default::default()
    };
    let pb = progress_bar(quiet);
    let load = |sheet: f64, what: &str| -> Result<Vec<merge::View>> {
        let mut loaded = Vec::new();
        for (k, p) in views.iter().enumerate() {
            pb.set_message(format!("reading view {k} ({}){what}", p.display()));
            pb.tick();
            stage(&format!("reading view {k} of {}{what}", views.len()));
            loaded.push(merge::load_view(k, p, cell, sheet)?);
        }
        Ok(loaded)
    };
    let (sheet, sheet_line) = match sheet {
        SheetArg::Mm(mm) => (mm, String::new()),
        SheetArg::Auto => auto_sheet(&load, &opts, turntable, &pb, &stage)?,
    };
    let loaded = load(sheet, "")?;
    let frame = loaded[0]
        .header
        .board()
        .map(|b| crate::mesh::MeshFrame::board(&b))
        .unwrap_or_default();
    let closing = match (trim_unseen, flat_base) {
        (true, _) => merge::Closing::Trim,
        (false, false) => merge::Closing::Smooth,
        (false, true) => merge::Closing::FlatBase {
            up: frame.up().ok_or_else(|| {
                anyhow::anyhow!(
                    "--flat-base needs to know which way is up: view 0's scan carries no board calibration"
                )
            })?,
        },
    };
    let mut results = merge::register_views(&loaded, &opts, turntable, |done, all| {
        pb.set_message(format!("registering pairs of views: {done} of {all}"));
        pb.tick();
        stage(&format!("registering pairs of views: {done} of {all}"));
    })?;
    let closure = merge::refine_views(&loaded, &mut results, &opts, |round| {
        pb.set_message(format!("refining all views together: round {}", round + 1));
        pb.tick();
        stage(&format!("refining all views together: round {}", round + 1));
    });
    pb.finish_and_clear();
    if closure.after.is_none() {
        crate::errln!(
            "warning: no loop of views to check the registration by (each view rests on one pairwise match): look at views.png before trusting the model; a view that overlaps two others closes a loop"
        );
    }
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the output folder {}", out.display()))?;
    crate::export::write_atomic(
        &out.join("views.ply"),
        &merge::views_ply(&loaded, &results, &frame),
    )?;
    let seen = merge::free_space(&loaded, &results, voxel);
    let mut report = sheet_line;
    report += &merge::report(&loaded, &results);
    report += &merge::closure_line(&closure);
    report += &merge::free_space_line(seen, voxel);
    let input = merge::fusion_input(&loaded, &results);
    let colours = &input.colours;
    // The registered views in their colours (front and side), the board's frame like the model:
    // written before the plausibility check, which they help to read.
    let mut views_cloud = crate::mesh::Mesh {
        vertices: input.points.iter().map(|p| p.cast()).collect(),
        ..crate::mesh::Mesh::default()
    };
    views_cloud.into_frame(frame);
    crate::export::write_atomic_with(&out.join("views.png"), |w| {
        crate::export::write_png(
            &crate::export::points_png(&views_cloud.vertices, colours),
            w,
        )
    })?;
    if let Some(v) = view {
        // The registered views in their colours (the board's frame, like the model): while the
        // fusion runs, or to see which view went wrong when the check below refuses them.
        for (pts, rgb) in views_cloud.vertices.chunks(8192).zip(colours.chunks(8192)) {
            v.points(pts, rgb);
        }
    }
    if let Err(e) = merge::check_closure(&closure, voxel)
        .and_then(|()| merge::check_free_space(seen, &loaded, voxel))
    {
        crate::export::write_atomic(&out.join("merge-report.txt"), report.as_bytes())?;
        crate::outln!("{}", report.trim_end());
        return Err(e.into());
    }
    let pb = progress_bar(quiet);
    pb.set_message("fusing the views into one mesh");
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    if let Some(v) = view {
        v.stage("fusing the views into one mesh");
    }
    let fused = merge::fuse_views(&input, fuse_cell, closing, |done, all| {
        pb.set_message(format!(
            "fusing the views into one mesh: {} %",
            100 * done / all.max(1)
        ));
    })
    .context("fusing the views")?;
    pb.finish_and_clear();
    report += &fused.report;
    let mut model = fused.model;
    model.into_frame(frame);
    crate::export::write_atomic_with(&out.join("model.png"), |w| {
        crate::export::write_png(&crate::export::orbit_png(&model), w)
    })?;
    crate::export::write_atomic_with(&out.join("model.obj"), |w| {
        crate::export::write_obj(&model, w)
    })?;
    crate::export::write_atomic_with(&out.join("model.ply"), |w| {
        crate::export::write_ply(&model, w)
    })?;
    crate::export::write_atomic_with(&out.join("model.stl"), |w| {
        crate::export::write_stl(&model, w)
    })?;
    crate::export::write_atomic_with(&out.join("model.3mf"), |w| {
        crate::export::write_3mf(&model, w)
    })?;
    crate::export::write_atomic(&out.join("merge-report.txt"), report.as_bytes())?;
    crate::outln!("{}", report.trim_end());
    crate::outln!(
        "wrote model.obj, model.ply, model.stl, model.3mf (one mesh, y up), model.png (from four sides), views.ply and views.png (each view in its colour) to {}",
        out.display()
    );
    if let Some(v) = view {
        v.finish(
            None,
            Some(model),
            out,
            &[
                "model.obj",
                "model.ply",
                "model.stl",
                "model.3mf",
                "model.png",
                "views.png",
                "views.ply",
                "merge-report.txt",
            ],
            "merged",
        );
    }
    Ok(())
}

/// `merge --sheet auto`: the views registered once without a sheet's correction, then, for each
/// of [`crate::merge::SHEET_TRIES`], read with it and refined from those poses, and their
/// [`crate::merge::disagreement`] measured; the thickness where they agree best
/// ([`crate::merge::best_sheet`]) and the report's line naming it.
///
/// # Errors
/// A view that cannot be read or registered; views that nowhere overlap, which tell no
/// thickness.
fn auto_sheet(
    load: &dyn Fn(f64, &str) -> Result<Vec<crate::merge::View>>,
    opts: &crate::register::RegisterOptions,
    turntable: Option<f64>,
    pb: &indicatif::ProgressBar,
    stage: &dyn Fn(&str),
) -> Result<(f64, String)> {
    use crate::merge;
    let first = load(0.0, ", for --sheet auto")?;
    let registered = merge::register_views(&first, opts, turntable, |done, all| {
        let message = format!("--sheet auto: registering pairs of views: {done} of {all}");
        pb.set_message(message.clone());
        pb.tick();
        stage(&message);
    })?;
    let mut tried = Vec::with_capacity(merge::SHEET_TRIES.len());
    for (i, &sigma) in merge::SHEET_TRIES.iter().enumerate() {
        let what = format!(
            ", --sheet auto: σ {sigma} mm ({} of {})",
            i + 1,
            merge::SHEET_TRIES.len()
        );
        let read;
        let views = if i == 0 {
            &first
        } else {
            read = load(sigma, &what)?;
            &read
        };
        let mut results = registered.clone();
        merge::refine_views(views, &mut results, opts, |_| {
            pb.set_message(format!("refining all views together{what}"));
            pb.tick();
        });
        tried.push((
            sigma,
            merge::disagreement(views, &results).unwrap_or(f64::NAN),
        ));
    }
    let best = merge::best_sheet(&tried).ok_or_else(|| {
        anyhow::anyhow!(
            "--sheet auto: the views nowhere overlap within {} mm of each other, so they tell no sheet thickness; give it with --sheet MM",
            crate::refine::AGREE_MM
        )
    })?;
    let list: Vec<String> = tried
        .iter()
        .map(|(s, d)| format!("{s} mm: {:.4} mm", d))
        .collect();
    let mut line = format!(
        "laser sheet (--sheet auto): σ {best:.2} mm, where the views agree best (RMS between overlapping views, σ {})",
        list.join(", ")
    );
    if best >= merge::SHEET_TRIES[merge::SHEET_TRIES.len() - 1] {
        line += "; the thickest tried: the sheet may be thicker, or the views disagree for another reason (look at views.png)";
    }
    line.push('\n');
    Ok((best, line))
}

fn check_command(
    scan: &std::path::Path,
    (spheres, spacing, plane): (&[f64], Option<f64>, bool),
    tolerances: crate::check::Tolerances,
    (cell, sheet): (Cell, f64),
    out: &std::path::Path,
) -> Result<()> {
    if spheres.len() > 2 {
        anyhow::bail!(
            "--sphere is given once or twice (a bar of two spheres), found {} times",
            spheres.len()
        );
    }
    for d in spheres {
        if !(1.0..=500.0).contains(d) {
            anyhow::bail!("--sphere must be a diameter of 1 to 500 mm, found {d}");
        }
    }
    if let Some(s) = spacing
        && !(1.0..=5000.0).contains(&s)
    {
        anyhow::bail!("--spacing must be 1 to 5000 mm, found {s}");
    }
    for (name, t) in [
        ("--size-tolerance", tolerances.size_pct),
        ("--form-tolerance", tolerances.form_pct),
        ("--flatness-tolerance", tolerances.flatness_pct),
    ] {
        if !(t > 0.0 && t <= 10.0) {
            anyhow::bail!("{name} must be more than 0 and at most 10 %, found {t}");
        }
    }
    let view = crate::merge::load_view(0, scan, cell, sheet).context("reading the scan")?;
    let (points, normals) = (&view.cloud.points, &view.cloud.normals);
    let report = crate::check::check(points, normals, spheres, spacing, plane, tolerances)?;
    let (mut text, pass) = report.text();
    if let Some((moved, all)) = view.sheet_moved {
        text += &format!(
            "laser sheet (--sheet {sheet} mm): {moved} of {all} points moved to where its middle crosses the surface\n"
        );
    }
    // The residual picture: the checked points in the board's frame, coloured by residual.
    let scale = report
        .spheres
        .iter()
        .map(|s| s.form.rms)
        .chain(report.plane.iter().map(|p| p.flatness.rms))
        .fold(0.0, f64::max)
        * 3.0;
    let scale = scale.max(0.02);
    let frame = view
        .header
        .board()
        .map(|b| MeshFrame::board(&b))
        .unwrap_or_default();
    // One band per checked feature (each sphere, the plane), each from the front and the side.
    let panels: Vec<image::RgbImage> = report
        .features(points)
        .map(|feature| {
            let (pts, colours): (Vec<_>, Vec<_>) = feature
                .map(|(p, r)| {
                    (
                        frame.point(&p.cast::<f32>()),
                        crate::check::residual_colour(r, scale),
                    )
                })
                .unzip();
            crate::export::points_png(&pts, &colours)
        })
        .collect();
    let width = panels.iter().map(image::RgbImage::width).max().unwrap_or(1);
    let height: u32 = panels.iter().map(image::RgbImage::height).sum();
    let mut picture = image::RgbImage::new(width, height.max(1));
    let mut y = 0;
    for p in &panels {
        image::imageops::replace(&mut picture, p, 0, i64::from(y));
        y += p.height();
    }
    text += &format!(
        "check-residuals.png: each checked feature (top to bottom as above) from the front and the side, blue {:.3} mm inside … white 0 … red {:.3} mm outside\n",
        -scale, scale
    );
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the output folder {}", out.display()))?;
    crate::export::write_atomic_with(&out.join("check-residuals.png"), |w| {
        crate::export::write_png(&picture, w)
    })?;
    crate::export::write_atomic(&out.join("check-report.txt"), text.as_bytes())?;
    crate::outln!("{}", text.trim_end());
    if !pass {
        anyhow::bail!(
            "the check failed: see {} (a figure beyond its tolerance)",
            out.join("check-report.txt").display()
        );
    }
    Ok(())
}
