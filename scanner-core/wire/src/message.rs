//! Every message the head sends, as one type.

use serde::{Deserialize, Serialize};

use crate::{
    Calibrated, Controls, DiscPose, FixedLaser, Header, Notice, Picture, Planes, Points, Preview,
    Reply, ShotTaken, Status,
};

/// A message.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Message<'a> {
    /// The session header.
    Header(Header),
    /// A frame's points.
    #[serde(borrow)]
    Points(Points<'a>),
    /// Counters.
    Status(Status),
    /// The camera controls (after each header).
    Controls(Controls),
    /// The laser planes' fit since the last status (before each status).
    Planes(Planes),
    /// The turntable disc in the reference frame (after each header, when asked for).
    Disc(DiscPose),
    /// A prompt or an event for the operator.
    Notice(Notice),
    /// A thumbnail of the camera's picture with what the head found in it.
    #[serde(borrow)]
    Preview(Preview<'a>),
    /// The turning platform of a fixed-laser scan (after each header of one).
    FixedLaser(FixedLaser),
    /// The answer to a host's command.
    Reply(Reply),
    /// A calibration shot, as the detector judged it.
    Shot(ShotTaken),
    /// A calibration from the shots taken.
    Calibrated(Calibrated),
    /// The camera's picture (or a part of it) at up to full resolution, with its sharpness.
    #[serde(borrow)]
    Picture(Picture<'a>),
}

impl Message<'_> {
    /// The scan (or preview session) the message belongs to; `None` for the answers to
    /// commands, which belong to none.
    pub fn scan_id(&self) -> Option<u32> {
        Some(match self {
            Message::Header(h) => h.scan_id,
            Message::Points(p) => p.scan_id,
            Message::Status(s) => s.scan_id,
            Message::Controls(k) => k.scan_id,
            Message::Planes(p) => p.scan_id,
            Message::Disc(d) => d.scan_id,
            Message::Notice(n) => n.scan_id,
            Message::Preview(p) => p.scan_id,
            Message::FixedLaser(f) => f.scan_id,
            Message::Picture(p) => p.scan_id,
            Message::Reply(_) | Message::Shot(_) | Message::Calibrated(_) => return None,
        })
    }
}
