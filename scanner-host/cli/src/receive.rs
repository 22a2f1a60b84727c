//! `receive` and `replay`: arguments, then a checked plan (the options in range, the output
//! folder's journal free or appended to), then the run — the bytes into the collector, the
//! outputs written when the input ends.

use std::io::Read;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use scanner_host::collect::{CollectOptions, Collector, Journal};
use scanner_host::link::Input;
use scanner_host::mesh::MeshFrame;
use scanner_host::outputs::{OutputOptions, Summary, mesh_of, replay_corrected, write_outputs};
use scanner_host::{errln, outln};
use scanner_web::live::LiveView;
use scanner_wire::NoticeKind;

use crate::args::OutputArgs;
use crate::show::{interrupted, progress_bar, start_view};

/// What `receive` and `replay` write, checked.
#[derive(Debug, Clone)]
pub struct OutputPlan {
    /// The output folder.
    pub dir: PathBuf,
    /// How the samples are collected.
    pub collect: CollectOptions,
    /// How the outputs are made.
    pub outputs: OutputOptions,
    /// The laser sheet's thickness, mm (0: no correction).
    pub sheet_mm: f64,
    /// No progress display.
    pub quiet: bool,
    /// The other laser's output folder, the median distance within which the two agree (mm),
    /// and whether a disagreement is accepted.
    pub other_laser: Option<(PathBuf, f64, bool)>,
}

impl OutputPlan {
    /// The plan of `o`.
    ///
    /// # Errors
    /// A `--sheet` that is no sheet's thickness.
    pub fn new(o: &OutputArgs) -> Result<OutputPlan> {
        scanner_host::thickness::check_thickness(o.sheet)?;
        if !(o.agree_within.is_finite() && o.agree_within > 0.0 && o.agree_within <= 100.0) {
            return Err(scanner_host::lasers::LasersError::Within(o.agree_within).into());
        }
        Ok(OutputPlan {
            dir: o.out.clone(),
            collect: CollectOptions {
                cell: o.cell,
                ..CollectOptions::default()
            },
            outputs: OutputOptions {
                min_count: o.min_count,
                frame: o.frame.into(),
                bridge_gaps: !o.no_bridge,
            },
            sheet_mm: o.sheet,
            quiet: o.quiet,
            other_laser: o
                .other_laser
                .clone()
                .map(|d| (d, o.agree_within, o.accept_disagreement)),
        })
    }
}

/// A `receive`, checked.
#[derive(Debug)]
pub struct ReceivePlan {
    /// Where the bytes come from.
    pub input: Input,
    /// Stop at the head's first final status.
    pub until_done: bool,
    /// The journal's length before this session (where its frames start).
    pub held: u64,
    /// The live view's address.
    pub view: Option<SocketAddr>,
    /// The outputs.
    pub out: OutputPlan,
}

impl ReceivePlan {
    /// Checks a receive: the outputs' options, and that the output folder's journal is neither
    /// the input nor an earlier session's (unless `append`).
    ///
    /// # Errors
    /// As [`OutputPlan::new`]; the folder cannot be created; the journal is the input or holds
    /// an earlier session.
    pub fn new(
        input: &Input,
        (until_done, append): (bool, bool),
        view: Option<SocketAddr>,
        o: &OutputArgs,
    ) -> Result<ReceivePlan> {
        let out = OutputPlan::new(o)?;
        std::fs::create_dir_all(&out.dir)
            .with_context(|| format!("cannot create the output folder {}", out.dir.display()))?;
        let held = check_journal(input, &out.dir.join("journal.stream"), append)?;
        Ok(ReceivePlan {
            input: input.clone(),
            until_done,
            held,
            view,
            out,
        })
    }
}

/// Refuses a receive that would read its own journal, or mix into an earlier session's journal
/// unless told to append; returns the journal's length before this session (where this
/// session's frames will start).
fn check_journal(input: &Input, journal: &Path, append: bool) -> Result<u64> {
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

/// Hands the frames accepted since the last call to the live view.
fn publish(c: &mut Collector, v: &mut LiveView) {
    if !v.has_frame()
        && let Some(board) = c
            .header()
            .and_then(|h| scanner_core::geometry::Board::<f32>::try_from(h.board).ok())
    {
        v.set_frame(MeshFrame::board(&board));
    }
    for (pts, rgb) in c.take_watched() {
        v.points(&pts, &rgb);
    }
    if let Some(p) = c.take_preview() {
        v.preview(&p);
    }
}

/// Receives until the input ends, the head is done (`until_done`) or Ctrl-C, then writes the
/// outputs. `finish_view`: the page is given the scan's mesh at the end (with `--merge` it is
/// given the merged model instead). Returns the summary and the live view, still up.
///
/// # Errors
/// The journal or the input cannot be opened, the collector refuses a header, an output
/// cannot be written.
pub fn receive(plan: &ReceivePlan, finish_view: bool) -> Result<(Summary, Option<LiveView>)> {
    let o = &plan.out;
    let journal_path = o.dir.join("journal.stream");
    let mut c = Collector::new(o.collect, Some(Journal::open(&journal_path)?));
    let stop = interrupted();
    stop.store(false, Ordering::SeqCst);
    let mut view = plan.view.map(start_view).transpose()?;
    if view.is_some() {
        c.watch();
    }
    let mut input = plan.input.open()?;
    if let Some(name) = &input.device {
        scanner_host::export::write_atomic(&o.dir.join("device-port"), name.as_bytes())?;
        errln!("device end of the link: {name}");
    }
    let pb = progress_bar(o.quiet);
    let t0 = Instant::now();
    let mut buf = vec![0u8; 1 << 16];
    let mut last_draw = Instant::now();
    let mut no_laser = None;
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
                // The head's prompts, on this terminal too (the head's may be nobody's).
                for notice in c.take_notices() {
                    if !o.quiet {
                        pb.suspend(|| errln!("head: {}", scanner_io::words::notice_line(&notice)));
                    }
                    if notice.kind == NoticeKind::NoLaser {
                        no_laser = Some(notice);
                    }
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
        if plan.until_done && c.counts().status.values().any(|s| s.done) {
            break "the head's scan is done";
        }
        if plan.until_done && no_laser.is_some() {
            break "the head stopped: it saw no laser";
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
        errln!("{ended}; journal: {}", journal_path.display());
    }
    // --sheet: this session's frames read again from the journal, corrected.
    if o.sheet_mm > 0.0
        && let Some(correction) = scanner_host::outputs::sheet_correction(&c, o.sheet_mm)
    {
        let again = replay_corrected(o.collect, &journal_path, plan.held, correction)?;
        c.regrid(again);
    }
    let summary = match write_outputs(&c, &o.dir, &o.outputs) {
        Err(e) if c.header().is_none() && no_laser.is_some() => {
            let n = no_laser
                .map(|n| scanner_io::words::notice_line(&n))
                .unwrap_or_default();
            return Err(anyhow::anyhow!("{e}").context(format!("the head: {n}")));
        }
        r => r?,
    };
    let summary = compare_lasers(o, summary)?;
    if finish_view && let Some(v) = view.as_ref() {
        v.finish(
            Some(&c.counts()),
            mesh_of(&c, &o.outputs),
            &o.dir,
            &scanner_host::outputs::OUTPUT_FILES,
            ended,
        );
    }
    Ok((summary, view))
}

/// `replay`: every output rebuilt from a journal or a recording.
///
/// # Errors
/// The input cannot be read or an output cannot be written.
pub fn replay(input: &Path, plan: &OutputPlan) -> Result<Summary> {
    let c = scanner_host::outputs::replay(plan.collect, input, plan.sheet_mm)?;
    let summary = write_outputs(&c, &plan.dir, &plan.outputs)?;
    compare_lasers(plan, summary)
}

/// With `--other-laser`: this turntable model against the other laser's, in the summary; a
/// disagreement refused unless accepted (the outputs stay written).
fn compare_lasers(o: &OutputPlan, mut summary: Summary) -> Result<Summary> {
    use scanner_host::lasers::{LasersError, agreement};
    let Some((other, within, accept)) = &o.other_laser else {
        return Ok(summary);
    };
    if summary.fixed.is_none() {
        return Err(LasersError::NotTurntable.into());
    }
    let mut a = agreement(&o.dir, other, *within)?;
    a.accepted = !a.agree && *accept;
    summary.lasers = Some(a.clone());
    scanner_host::outputs::write_summary(&summary, &o.dir)?;
    if !a.agree && !*accept {
        return Err(LasersError::Disagree {
            median_mm: a.median_mm,
            volume_pct: 100.0 * (a.volume_ratio - 1.0),
            within_mm: *within,
            cause: a.likely_cause.unwrap_or("shape"),
        }
        .into());
    }
    Ok(summary)
}

/// `ports`: the serial ports, one a line.
///
/// # Errors
/// The ports cannot be listed.
pub fn ports() -> Result<()> {
    let ports = serialport::available_ports().context("listing serial ports")?;
    if ports.is_empty() {
        outln!("no serial ports found");
    }
    for p in ports {
        outln!("{}: {:?}", p.port_name, p.port_type);
    }
    Ok(())
}
