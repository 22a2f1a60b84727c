//! The PC companion of the scanner head: reads point packets from a serial port, a recording or
//! stdin, collects them into the structured grid and writes meshes and pictures.
//!
//! Where it sits: `head ─► [scanner-host: link → decoder → journal → grid → exports] ─► files`.
//! - [`collect`]: the streaming decoder, the journal, the grid filling;
//! - [`grid`]: the 2-D structured grid with robust cells;
//! - [`mesh`]: triangles from neighbouring cells;
//! - [`export`]: OBJ, PLY, STL, depth and preview pictures, written atomically.
#![deny(missing_docs)]

pub mod collect;
pub mod export;
pub mod grid;
pub mod mesh;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use scanner_core::wire::Skip;

use collect::{CollectOptions, Collector, Journal};
use grid::Cell;
use mesh::MeshOptions;

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
        input: String,
        /// Stop at the first final status from the head.
        #[arg(long)]
        until_done: bool,
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
    /// List the serial ports.
    Ports,
}

/// What a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The counts.
    pub counts: collect::Counts,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh faces.
    pub faces: usize,
    /// Filled cells over all cells of the grid.
    pub coverage: f64,
    /// Points per second of capture time.
    pub point_rate: f64,
    /// Outlier samples rejected by the grid.
    pub outliers: u64,
}

impl Summary {
    /// The summary as text lines.
    pub fn text(&self) -> String {
        let c = &self.counts;
        let d = &c.decode;
        let mut s = format!(
            "frames {} ({} point packets, {} headers) from {} scan(s); points {} ({} in the grid, {} outliers); vertices {}, faces {}; coverage {:.1} % of the grid; {:.0} points/s\n",
            d.frames,
            c.packets,
            c.headers,
            c.scans.len(),
            c.points,
            c.gridded,
            self.outliers,
            self.vertices,
            self.faces,
            100.0 * self.coverage,
            self.point_rate
        );
        s += &format!(
            "link: {} bytes; rejected frames: {} bad CRC, {} bad COBS, {} unknown version, {} bad payload, {} oversize, {} truncated; {} packets with bad points, {} without a header, {} duplicates\n",
            d.bytes,
            d.bad_crc,
            d.bad_cobs,
            d.bad_version,
            d.bad_payload,
            d.oversize,
            d.truncated,
            c.bad_points,
            c.no_header,
            c.duplicates
        );
        let skipped = c.skipped();
        for r in Skip::ALL {
            if skipped[r as usize] > 0 {
                s += &format!(
                    "head skipped {} frames: {}\n",
                    skipped[r as usize],
                    r.name()
                );
            }
        }
        s
    }
}

/// Writes every output of a collection into `dir`.
///
/// # Errors
/// No header ever arrived (nothing to grid), or a file cannot be written.
pub fn write_outputs(c: &Collector, dir: &Path, min_count: u32) -> Result<Summary> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let counts = c.counts();
    let (Some(grid), Some(header)) = (c.grid(), c.header()) else {
        let s = format!(
            "no session header received ({} bytes, {} frames, {} rejected): nothing to build; is this a scanner stream?",
            counts.decode.bytes,
            counts.decode.frames,
            counts.decode.rejected()
        );
        export::write_atomic(&dir.join("summary.txt"), s.as_bytes())?;
        bail!(s);
    };
    let opts = MeshOptions {
        min_count,
        ..MeshOptions::default()
    };
    let m = mesh::build(grid, f64::from(header.camera.fx), &opts, c.colour());
    export::write_atomic(&dir.join("scan.obj"), export::obj(&m).as_bytes())?;
    export::write_atomic(&dir.join("scan.ply"), &export::ply(&m))?;
    export::write_atomic(&dir.join("scan.stl"), &export::stl(&m))?;
    export::write_atomic(
        &dir.join("depth.png"),
        &export::png_bytes(&export::depth_png(grid, &m))?,
    )?;
    export::write_atomic(
        &dir.join("preview.png"),
        &export::png_bytes(&export::shaded_png(grid, &m))?,
    )?;
    let span = counts.time_us.map_or(0.0, |(a, b)| (b - a) as f64 / 1e6);
    let summary = Summary {
        point_rate: if span > 0.0 {
            counts.points as f64 / span
        } else {
            0.0
        },
        counts,
        vertices: m.vertices.len(),
        faces: m.faces.len(),
        coverage: grid.filled() as f64 / (grid.cols * grid.rows) as f64,
        outliers: grid.rejected(),
    };
    export::write_atomic(&dir.join("summary.txt"), summary.text().as_bytes())?;
    Ok(summary)
}

/// Feeds a whole file (a journal or a recording) into a collector.
///
/// # Errors
/// The file cannot be read.
pub fn replay_into(c: &mut Collector, input: &Path) -> Result<()> {
    let mut f =
        std::fs::File::open(input).with_context(|| format!("cannot read {}", input.display()))?;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f
            .read(&mut buf)
            .with_context(|| format!("reading {}", input.display()))?;
        if n == 0 {
            return Ok(());
        }
        c.feed(&buf[..n])?;
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

fn receive(input: &str, until_done: bool, o: &OutputArgs) -> Result<Summary> {
    std::fs::create_dir_all(&o.out)
        .with_context(|| format!("cannot create {}", o.out.display()))?;
    let journal_path = o.out.join("journal.stream");
    let mut c = Collector::new(collect_options(o), Some(Journal::open(&journal_path)?));
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // A second handler cannot be installed in the same process (tests): ignore that.
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst));
    }
    // For `pty`: the far end stays open here so that the head may open and close it freely.
    let mut _keep_open = None;
    let mut reader: Box<dyn Read> = if input == "-" {
        Box::new(std::io::stdin())
    } else if input == "pty" {
        use serialport::SerialPort;
        let (mut ours, theirs) =
            serialport::TTYPort::pair().context("cannot create a pseudo-terminal pair")?;
        let name = theirs.name().context("the pseudo-terminal has no name")?;
        ours.set_timeout(Duration::from_millis(200))
            .context("pseudo-terminal timeout")?;
        export::write_atomic(&o.out.join("device-port"), name.as_bytes())?;
        eprintln!("device end of the link: {name}");
        _keep_open = Some(theirs);
        Box::new(ours)
    } else if let Some(spec) = input.strip_prefix("serial:") {
        let (path, baud) = match spec.split_once('@') {
            Some((p, b)) => (
                p,
                b.parse::<u32>()
                    .with_context(|| format!("{input:?}: {b:?} is not a baud rate"))?,
            ),
            None => (spec, 921_600),
        };
        Box::new(
            serialport::new(path, baud)
                .timeout(Duration::from_millis(200))
                .open_native()
                .with_context(|| format!("cannot open serial port {path} at {baud} baud"))?,
        )
    } else {
        Box::new(std::fs::File::open(input).with_context(|| format!("cannot read {input}"))?)
    };
    let pb = progress_bar(o.quiet);
    let t0 = Instant::now();
    let mut buf = vec![0u8; 1 << 16];
    let mut last_draw = Instant::now();
    let ended = loop {
        if stop.load(Ordering::SeqCst) {
            break "stopped (Ctrl-C)";
        }
        match reader.read(&mut buf) {
            Ok(0) => break "input ended",
            Ok(n) => c.feed(&buf[..n])?,
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
            last_draw = Instant::now();
        }
    };
    pb.finish_and_clear();
    c.sync()?;
    if !o.quiet {
        eprintln!("{ended}; journal: {}", journal_path.display());
    }
    write_outputs(&c, &o.out, o.min_count)
}

/// Runs the host tool with parsed arguments.
///
/// # Errors
/// Any failure of the run, with context naming what failed.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.info {
        println!(
            "scanner-host {}: units mm, camera +z forward, +y down",
            env!("CARGO_PKG_VERSION")
        );
        return Ok(());
    }
    let summary = match &args.command {
        None => {
            println!("scanner-host: nothing to do (try --help)");
            return Ok(());
        }
        Some(Command::Ports) => {
            let ports = serialport::available_ports().context("listing serial ports")?;
            if ports.is_empty() {
                println!("no serial ports found");
            }
            for p in ports {
                println!("{}: {:?}", p.port_name, p.port_type);
            }
            return Ok(());
        }
        Some(Command::Receive {
            input,
            until_done,
            out,
        }) => receive(input, *until_done, out)?,
        Some(Command::Replay { input, out }) => {
            let mut c = Collector::new(collect_options(out), None);
            replay_into(&mut c, input)?;
            write_outputs(&c, &out.out, out.min_count)?
        }
    };
    print!("{}", summary.text());
    Ok(())
}
