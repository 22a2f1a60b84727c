//! The head's counters ([`Status`]), with why frames were skipped and why the scan ended.

use serde::{Deserialize, Serialize};

/// Number of reasons a frame can be skipped.
pub const SKIP_REASONS: usize = 6;

/// Why a frame produced no points, in [`Status::skipped`] order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[repr(u8)]
pub enum Skip {
    /// Too few stripe pixels on the board (laser off, out of view, too faint).
    NoStripe = 0,
    /// The stripe was on one board plane only.
    OnePlaneOnly = 1,
    /// The laser plane (nearly) contains the camera centre.
    PlaneThroughCamera = 2,
    /// The laser plane failed its quality check (e.g. the stripe's board parts disagree).
    PoorPlane = 3,
    /// The camera delivered a bad frame (size, format).
    BadFrame = 4,
    /// The link was too slow: the frame was dropped whole.
    LinkFull = 5,
}

impl Skip {
    /// Every reason, in order.
    pub const ALL: [Skip; SKIP_REASONS] = [
        Skip::NoStripe,
        Skip::OnePlaneOnly,
        Skip::PlaneThroughCamera,
        Skip::PoorPlane,
        Skip::BadFrame,
        Skip::LinkFull,
    ];
}

/// Why a scan ended (the last status says it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum EndReason {
    /// It has not ended, or it ran to its end.
    #[default]
    Completed = 0,
    /// The camera failed or vanished mid-scan.
    CameraLost = 1,
    /// The operator stopped it (Ctrl-C, a signal, a frame or time limit).
    Stopped = 2,
}

wire_enum!(EndReason, Completed = 0, CameraLost = 1, Stopped = 2);

/// Counters of the head.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Status {
    /// Scan id.
    pub scan_id: u32,
    /// Frames captured.
    pub frames: u32,
    /// Point packets sent.
    pub packets: u32,
    /// Points sent.
    pub points: u64,
    /// Bytes sent (framing included).
    pub bytes: u64,
    /// Frames skipped, by [`Skip`] reason.
    pub skipped: [u32; SKIP_REASONS],
    /// Frames per second processed, × 1000.
    pub fps_milli: u32,
    /// `true` in the last status of a scan.
    pub done: bool,
    /// Why the scan ended (in the last status; [`EndReason::Completed`] before).
    pub ended: EndReason,
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn status_golden_frame() {
        crate::golden::check(
            Message::Status(Status {
                scan_id: 4,
                frames: 300,
                packets: 290,
                points: 185_000,
                bytes: 1_200_000,
                skipped: [4, 3, 0, 2, 1, 0],
                fps_milli: 29_970,
                done: true,
                ended: EndReason::Stopped,
            }),
            &[
                0, 16, 2, 2, 4, 172, 2, 162, 2, 168, 165, 11, 128, 159, 73, 4, 3, 3, 2, 1, 10, 146,
                234, 1, 1, 2, 98, 2, 29, 133, 0,
            ],
        );
    }
}
