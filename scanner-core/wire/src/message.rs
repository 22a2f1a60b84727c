//! Every message the head sends, as one type.

use serde::{Deserialize, Serialize};

use crate::{
    Calibrated, Controls, DiscPose, FixedLaser, Header, MeasuredTurn, Notice, Picture, Planes,
    Points, Preview, Reply, ShotTaken, Status,
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
    /// A turning platform's measured turn at one frame (before that frame's points).
    Turn(MeasuredTurn),
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
            Message::Turn(t) => t.scan_id,
            Message::Reply(_) | Message::Shot(_) | Message::Calibrated(_) => return None,
        })
    }
}

#[cfg(test)]
mod largest {
    extern crate std;

    use super::*;
    use crate::{
        MAX_ENCODED, MAX_MESSAGE, MAX_POINTS, MAX_XYZ_BYTES_PER_POINT, PICTURE_MAX_JPEG,
        PREVIEW_MAX_MARKERS, PREVIEW_MAX_PIXELS, PreviewState,
    };

    /// The largest message of each growing kind (a frame's points at their most, the largest
    /// preview, the largest picture), every number at its widest, encodes within
    /// [`MAX_MESSAGE`] and [`MAX_ENCODED`]: the buffers both ends allocate.
    #[test]
    fn the_largest_messages_fit_the_buffers() {
        let xyz = std::vec![0xFFu8; MAX_POINTS * MAX_XYZ_BYTES_PER_POINT];
        let rgb = std::vec![0xFFu8; 3 * MAX_POINTS];
        let unc = std::vec![0xFFu8; MAX_POINTS];
        let pixels = std::vec![0xFFu8; PREVIEW_MAX_PIXELS];
        let markers = std::vec![0xFFu8; 2 * PREVIEW_MAX_MARKERS];
        let stripe = std::vec![0xFFu8; 160];
        let jpeg = std::vec![0xFFu8; PICTURE_MAX_JPEG];
        let messages = [
            Message::Points(Points {
                scan_id: u32::MAX,
                frame: u32::MAX,
                time_us: u64::MAX,
                plane: [f32::MAX; 4],
                count: MAX_POINTS as u32,
                xyz: &xyz,
                rgb: &rgb,
                uncertainty: &unc,
            }),
            Message::Preview(Preview {
                scan_id: u32::MAX,
                frame: u32::MAX,
                width: 160,
                height: 120,
                scale: u16::MAX,
                pixels: &pixels,
                markers: &markers,
                axis: 0,
                stripe: &stripe,
                clipped_permille: u16::MAX,
                laser_dn: u16::MAX,
                state: PreviewState::LaserInReference,
                skip: 5,
                points: u16::MAX,
            }),
            Message::Picture(Picture {
                scan_id: u32::MAX,
                frame: u32::MAX,
                x: u16::MAX,
                y: u16::MAX,
                width: 640,
                height: 480,
                scale: 1,
                edge_cpx: u16::MAX,
                jpeg: &jpeg,
            }),
        ];
        // the head's and the journal's scratch: MAX_MESSAGE bytes for version, body and CRC
        let mut scratch = std::vec![0u8; MAX_MESSAGE];
        let mut out = std::vec![0u8; MAX_ENCODED];
        for m in messages {
            let e = crate::framing::encode(&m, &mut scratch, &mut out)
                .unwrap_or_else(|e| panic!("{e:?}: {m:?}"));
            assert!(e <= MAX_ENCODED);
        }
    }
}
