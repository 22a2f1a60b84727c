//! A scan, planned and run: the source open, the calibration read and checked against it, the
//! link open ([`ScanPlan`]); [`run`] takes frames to the link until the plan's stop, and
//! [`report_lines`] says how it ended. The command line and the head's service build plans.

use scanner_core::stripe::LaserColour;
use scanner_wire::Skip;

use crate::link::Link;
use crate::session::{Calibration, DiscOutcome, ScanOptions, ScanReport, StopWhen, run_scan_until};
use crate::source::FrameSource;

/// A scan, validated and with its resources open: what [`run`] runs.
pub struct ScanPlan {
    /// The frames.
    pub source: Box<dyn FrameSource>,
    /// The camera and the planes (or the fixed laser's).
    pub calibration: Calibration,
    /// The pipeline's settings and the scan's.
    pub options: ScanOptions,
    /// Where the packets go.
    pub link: Link,
    /// When to stop.
    pub stop: StopWhen,
}

/// Link speeds for the README's table, bytes per second.
pub const LINKS: [(&str, f64); 3] = [
    ("115200 baud UART", 11_520.0),
    ("921600 baud UART", 92_160.0),
    ("USB CDC", 1_000_000.0),
];

/// Counts a noun: `1 frame`, `2 frames`.
fn count(n: impl Into<u64>, noun: &str) -> String {
    let n = n.into();
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}

/// The end-of-scan summary, one line per item.
pub fn report_lines(r: &ScanReport) -> Vec<String> {
    let s = &r.status;
    let mut lines = vec![format!(
        "scan {:08x}: {}, {}, {}, {} bytes in {:.2} s ({:.1} frames/s){}",
        s.scan_id,
        count(s.frames, "frame"),
        count(s.packets, "point packet"),
        count(s.points, "point"),
        r.bytes,
        r.seconds,
        f64::from(s.frames) / r.seconds.max(1e-9),
        match (&r.ended_early, &r.stopped) {
            (Some(e), _) => format!("; ended early: {e}"),
            (None, Some(why)) => format!("; {why}"),
            (None, None) => String::new(),
        }
    )];
    match r.bytes_per_point() {
        Some(bpp) => {
            lines.push(format!(
                "{bpp:.2} bytes per point on the link (framing and headers included)"
            ));
            for (name, bps) in LINKS {
                lines.push(format!("  {name}: {:.0} points/s", bps / bpp));
            }
        }
        None => lines.push(
            "no points were sent: check the laser, the reference frame and the calibration (the skip reasons below)".into(),
        ),
    }
    for reason in Skip::ALL {
        let n = s.skipped[reason as usize];
        if n > 0 {
            lines.push(format!(
                "  skipped {}: {}",
                count(n, "frame"),
                scanner_io::words::skip_reason(reason)
            ));
        }
    }
    if let Some(line) = colour_line(r) {
        lines.push(line);
    }
    match &r.disc {
        Some(DiscOutcome::Found {
            pose,
            markers,
            of,
            rms_px,
        }) => lines.push(format!(
            "turntable disc: found, {markers} of {of} dots, rms {rms_px:.3} px, centre {:.1} mm from the camera",
            pose.translation.norm()
        )),
        Some(DiscOutcome::Missed(why)) => lines.push(format!(
            "turntable disc: not found: {why} (the merge registers this view by its shape)"
        )),
        None => {}
    }
    if let Some(m) = &r.markers {
        lines.push(markers_line(m, r.status.frames));
    }
    if let Some(t) = &r.temporal {
        lines.extend(temporal_lines(t));
    }
    if let Some(pace) = &r.pace {
        lines.push(format!(
            "camera: {}",
            crate::session::pace_line(pace, r.pipeline_ms)
        ));
    }
    if r.one_sheet_only() {
        lines.push(one_plane_hint(r));
    }
    lines
}

/// What a shadow sweep read through time gave: the planes, the object's pixels with a point,
/// the two edges' agreement, and the pixels left without a point and why.
fn temporal_lines(t: &crate::temporal::TemporalReport) -> Vec<String> {
    let pct = |n: u64| 100.0 * n as f64 / t.pixels.max(1) as f64;
    vec![
        format!(
            "shadow through time: the band moved along {}; edge planes in {} and {} of {} frames ({} and {} more blended across gaps), their board points {:.2}/{:.2} and {:.2}/{:.2} mm RMS (left/right sheet)",
            t.along.unwrap_or("no line (no band seen moving)"),
            t.planes[0],
            t.planes[1],
            t.frames,
            t.planes_blended[0],
            t.planes_blended[1],
            t.plane_rms_mm[0][0],
            t.plane_rms_mm[0][1],
            t.plane_rms_mm[1][0],
            t.plane_rms_mm[1][1],
        ),
        format!(
            "  the object: {:.1} % of its {} pixels with a point; its two edges {:.2} mm apart (median; 90 % within {:.2}), on the board {:.2} mm; the board's points {:.2} mm from its planes (median; 90 % within {:.2})",
            100.0 * t.coverage,
            t.object_pixels,
            t.edges_apart_mm[0],
            t.edges_apart_mm[1],
            t.edges_apart_board_mm[0],
            t.board_off_mm[0],
            t.board_off_mm[1],
        ),
        format!(
            "  pixels without a point: {:.1} % too little contrast, {:.1} % crossed more than once, {:.1} % with no plane to place them, {:.1} % whose edges disagree by more than {:.1} mm",
            pct(t.low_contrast),
            pct(t.crossed_again[0].max(t.crossed_again[1])),
            pct(t.no_plane[0].max(t.no_plane[1])),
            pct(t.edges_disagree),
            t.edges_agree_within_mm,
        ),
    ]
}

/// What the first laser frame showed of the laser's colour, when it matters: a colour found
/// (what was read), one that differs from what was read, or a clipped line read by a colour.
fn colour_line(r: &ScanReport) -> Option<String> {
    let seen = r.colour_seen?;
    let core = if seen.saturated {
        ", its core clipped white"
    } else {
        ""
    };
    if r.colour_found {
        Some(format!(
            "laser: the first laser frame shows a {} line{core}: read {}",
            seen.colour.name(),
            if r.colour == LaserColour::White {
                "by brightness".to_string()
            } else {
                format!("as {}", r.colour.name())
            }
        ))
    } else if seen.saturated && r.colour != LaserColour::White {
        Some(format!(
            "laser: the line's core is clipped white, which --laser {} does not read as its colour: leave --laser out (a clipped line is read by brightness) or lower the exposure",
            r.colour.name()
        ))
    } else {
        None
    }
}

/// What the platform's markers gave: the frames they turned, the steady turn, the frames that
/// turned otherwise and those they did not turn.
fn markers_line(m: &crate::marker_turn::MarkerSummary, frames: u32) -> String {
    let mut line = format!(
        "markers: the turn of {} of {} frames from markers {:?}",
        m.frames, frames, m.markers
    );
    if let Some(step) = m.step_deg {
        line += &format!(", {step:.3}° a frame");
    }
    if !m.unsteady.is_empty() {
        let list: Vec<String> = m
            .unsteady
            .iter()
            .take(8)
            .map(|(f, d)| format!("{f} ({d:+.2}°)"))
            .collect();
        line += &format!(
            "; {} turned otherwise than the rest (the motor slipped?): {}{}",
            count(m.unsteady.len() as u64, "frame"),
            list.join(", "),
            if m.unsteady.len() > 8 { ", …" } else { "" }
        );
    }
    if !m.missed.is_empty() {
        line += &format!(
            "; {} showed no marker seen before and are left out",
            count(m.missed.len() as u64, "frame")
        );
    }
    line
}

/// What to do when most frames saw the stripe on one board sheet only.
fn one_plane_hint(r: &ScanReport) -> String {
    let (flag, line) = crate::axis::words(r.axis);
    format!(
        "most frames showed the stripe on one sheet only: the laser line must cross the crease onto both sheets (the scan read a {line} line, {flag}, {})",
        if r.axis_found {
            "found from the first laser frame"
        } else {
            "as given"
        }
    )
}

/// Prints the end-of-scan summary: on standard output, or on standard error when standard
/// output carries the scan itself (`--out -`). A closed stream is not an error.
pub fn print_report(r: &ScanReport, to_stderr: bool) {
    use std::io::Write as _;
    for line in report_lines(r) {
        let _ = if to_stderr {
            writeln!(std::io::stderr().lock(), "{line}")
        } else {
            writeln!(std::io::stdout().lock(), "{line}")
        };
    }
}

/// Runs a planned scan to its end; `progress` sees the counters after every frame.
///
/// # Errors
/// [`RunError`]: the source failing before the first frame, the link failing.
pub fn run(
    plan: ScanPlan,
    mut progress: impl FnMut(&scanner_wire::Status),
) -> Result<ScanReport, RunError> {
    let ScanPlan {
        mut source,
        calibration,
        options,
        mut link,
        stop,
    } = plan;
    let report = run_scan_until(
        source.as_mut(),
        &calibration,
        options,
        &mut link,
        &stop,
        |s| progress(s),
        |_, _| {},
    );
    // Whatever the session came to, what it queued reaches the host before this returns (a
    // scan that saw no laser has told the host so; the process may exit right after).
    let finished = link.finish();
    let report = report?;
    finished?;
    Ok(report)
}

/// Why a scan stopped short of its report.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The session failed (the source before the first frame, the link).
    #[error(transparent)]
    Session(#[from] crate::session::SessionError),
    /// The link could not be finished (its last packets flushed).
    #[error(transparent)]
    Link(#[from] crate::link::LinkError),
}
