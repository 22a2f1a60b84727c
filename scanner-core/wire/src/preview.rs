//! A thumbnail of the camera's picture with what the head found in it ([`Preview`]).

use serde::{Deserialize, Serialize};

use crate::SKIP_REASONS;

/// Largest thumbnail a [`Preview`] carries, pixels (160 × 120).
pub const PREVIEW_MAX_PIXELS: usize = 160 * 120;
/// Largest thumbnail side, pixels.
pub const PREVIEW_MAX_SIDE: u16 = 255;
/// Most markers a [`Preview`] carries.
pub const PREVIEW_MAX_MARKERS: usize = 256;

/// What the head would make of a preview's frame ([`Preview::state`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum PreviewState {
    /// The frame gives points ([`Preview::points`] of them).
    Points = 0,
    /// The frame would be skipped, for [`Preview::skip`].
    Skipped = 1,
    /// The head has no calibration: it cannot tell.
    NoCalibration = 2,
    /// The reference shows the laser: switch it off (the head takes the reference again).
    LaserInReference = 3,
}
wire_enum!(
    PreviewState,
    Points = 0,
    Skipped = 1,
    NoCalibration = 2,
    LaserInReference = 3
);

/// A small picture of what the camera sees, with what the head found in it (`scanner-device
/// preview`, about once a second): for aiming, focus and exposure before a scan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Preview<'a> {
    /// Scan (preview session) id.
    pub scan_id: u32,
    /// The frame's number in the session.
    pub frame: u32,
    /// Thumbnail width, pixels (at most [`PREVIEW_MAX_SIDE`]).
    pub width: u16,
    /// Thumbnail height, pixels.
    pub height: u16,
    /// Camera pixels per thumbnail pixel.
    pub scale: u16,
    /// The thumbnail's luma, row by row: `width · height` bytes, at most [`PREVIEW_MAX_PIXELS`].
    #[serde(borrow)]
    pub pixels: &'a [u8],
    /// The dark dots found (board markers, the turntable disc's dots): `x, y` pairs of bytes in
    /// thumbnail pixels, at most [`PREVIEW_MAX_MARKERS`].
    #[serde(borrow)]
    pub markers: &'a [u8],
    /// Which way [`Preview::stripe`] runs: 0 one entry per thumbnail column (a horizontal
    /// line), 1 per row.
    pub axis: u8,
    /// The laser line as found against the reference: its position along each thumbnail column
    /// (or row), thumbnail pixels, 255 where none; empty without a reference.
    #[serde(borrow)]
    pub stripe: &'a [u8],
    /// Pixels at 250 or brighter (clipped), per mille of the frame.
    pub clipped_permille: u16,
    /// The light the laser adds over the reference where its line was found, DN (the median
    /// over its lines; 0: no line found).
    pub laser_dn: u16,
    /// What the head would make of the frame.
    pub state: PreviewState,
    /// With [`PreviewState::Skipped`]: the [`Skip`](crate::Skip) reason's number.
    pub skip: u8,
    /// With [`PreviewState::Points`]: the points the frame gives.
    pub points: u16,
}

impl Preview<'_> {
    /// Whether the message keeps its own limits (a reader checks before using it).
    pub fn is_consistent(&self) -> bool {
        let pixels = usize::from(self.width) * usize::from(self.height);
        let lines = if self.axis == 0 {
            self.width
        } else {
            self.height
        };
        pixels <= PREVIEW_MAX_PIXELS
            && self.width <= PREVIEW_MAX_SIDE
            && self.height <= PREVIEW_MAX_SIDE
            && self.pixels.len() == pixels
            && self.markers.len().is_multiple_of(2)
            && self.markers.len() <= 2 * PREVIEW_MAX_MARKERS
            && self.axis <= 1
            && (self.stripe.is_empty() || self.stripe.len() == usize::from(lines))
            && usize::from(self.skip) < SKIP_REASONS
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn preview_golden_frame() {
        crate::golden::check(
            Message::Preview(Preview {
                scan_id: 1,
                frame: 6,
                width: 4,
                height: 2,
                scale: 160,
                pixels: &[0, 64, 128, 255, 10, 20, 30, 40],
                markers: &[1, 1, 3, 0],
                axis: 0,
                stripe: &[0, 1, 255, 2],
                clipped_permille: 3,
                laser_dn: 180,
                state: PreviewState::Points,
                skip: 0,
                points: 3,
            }),
            &[
                0, 10, 2, 7, 1, 6, 4, 2, 160, 1, 8, 12, 64, 128, 255, 10, 20, 30, 40, 4, 1, 1, 3,
                1, 2, 4, 7, 1, 255, 2, 3, 180, 1, 1, 6, 3, 104, 165, 140, 4, 0,
            ],
        );
    }
}
