//! `scanner-device preview`: the camera's picture with what the head finds in it, about once a
//! second, on the same link as a scan (the host's page shows it): for aiming, focus and
//! exposure before a scan.

use anyhow::Result;
use clap::Args;

use super::scan::{ScanArgs, open};
use crate::preview::{PreviewOptions, PreviewReport, run_preview};

/// Options of `preview`: a scan's, and how often a picture is sent.
#[derive(Debug, Args)]
pub struct PreviewArgs {
    /// The source, calibration (optional here), laser and link, as for `scan`.
    #[command(flatten)]
    pub scan: ScanArgs,
    /// A picture every this many frames (30: about one a second from a 30 frames/s camera).
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub every: u32,
}

/// Runs `preview` until the source ends, `--frames`/`--duration`, or Ctrl-C.
///
/// # Errors
/// A bad option, a source, calibration or link that cannot open, the link failing.
pub fn preview(a: &PreviewArgs) -> Result<PreviewReport> {
    let mut o = open(&a.scan)?;
    let quiet = a.scan.quiet;
    if !quiet {
        crate::errln!("source: {}", o.source.describe());
        if o.calibration.is_none() {
            crate::errln!(
                "no --calibration: the preview shows the picture, the dots, the line and the exposure, not what a scan would skip"
            );
        }
    }
    let options = PreviewOptions {
        scan_id: o.scan_id,
        every: a.every,
        head: o.head,
        find_axis: o.find_axis,
        scale: 0,
        picture: None,
    };
    let report = run_preview(
        o.source.as_mut(),
        o.calibration.as_ref(),
        options,
        &mut o.link,
        &o.stop,
        |facts| {
            if !quiet {
                crate::errln!("{facts}");
            }
        },
    )?;
    o.link.finish()?;
    let line = format!(
        "preview {:08x}: {} frames, {} pictures sent{}{}",
        o.scan_id,
        report.frames,
        report.previews,
        if report.dropped > 0 {
            format!(", {} dropped (link busy)", report.dropped)
        } else {
            String::new()
        },
        report
            .stopped
            .as_deref()
            .map(|w| format!("; {w}"))
            .unwrap_or_default()
    );
    if a.scan.out.trim() == "-" {
        crate::errln!("{line}");
    } else {
        crate::outln!("{line}");
    }
    if let Some(e) = &report.ended_early {
        anyhow::bail!("{e}");
    }
    Ok(report)
}
