//! The camera's picture at up to its full resolution, as a JPEG ([`Picture`]), for aiming and
//! focus: the whole frame, or a part of it at full resolution (a zoom).

use serde::{Deserialize, Serialize};

/// Most bytes of a picture's JPEG.
pub const PICTURE_MAX_JPEG: usize = 64 * 1024;
/// Largest picture sent, pixels across (a larger region is averaged down to fit).
pub const PICTURE_MAX_WIDTH: u16 = 640;
/// Largest picture sent, pixels down.
pub const PICTURE_MAX_HEIGHT: u16 = 480;

/// A region of the camera's picture, as a gray JPEG, with how sharp its edges are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Picture<'a> {
    /// The preview session's id.
    pub scan_id: u32,
    /// The frame's number in the session.
    pub frame: u32,
    /// The region's left edge, camera pixels.
    pub x: u16,
    /// Its top edge.
    pub y: u16,
    /// Its width, camera pixels.
    pub width: u16,
    /// Its height.
    pub height: u16,
    /// Camera pixels per picture pixel (a block of `scale × scale` averaged).
    pub scale: u8,
    /// The width of the region's sharpest edges, hundredths of a camera pixel: the step's
    /// contrast over its steepest gradient, a median over the strongest edges (about 2.5 px
    /// for a sharp edge, 2.5 σ for one blurred by σ); `u16::MAX`: no edge to tell by.
    pub edge_cpx: u16,
    /// The picture, a baseline JPEG (gray), at most [`PICTURE_MAX_JPEG`] bytes.
    #[serde(borrow)]
    pub jpeg: &'a [u8],
}

impl Picture<'_> {
    /// Whether its sizes hold: a JPEG within its limit, a scale of at least 1, a region that
    /// averages down within the largest picture.
    pub fn is_consistent(&self) -> bool {
        let s = u32::from(self.scale);
        self.jpeg.len() <= PICTURE_MAX_JPEG
            && s >= 1
            && u32::from(self.width) / s <= u32::from(PICTURE_MAX_WIDTH)
            && u32::from(self.height) / s <= u32::from(PICTURE_MAX_HEIGHT)
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn picture_golden_frame() {
        crate::golden::check(
            Message::Picture(Picture {
                scan_id: 2,
                frame: 40,
                x: 16,
                y: 32,
                width: 64,
                height: 48,
                scale: 1,
                edge_cpx: 250,
                jpeg: &[0xFF, 0xD8, 0xFF, 0xD9],
            }),
            &[
                0, 21, 2, 12, 2, 40, 16, 32, 64, 48, 1, 250, 1, 4, 255, 216, 255, 217, 169, 219,
                62, 31, 0,
            ],
        );
    }
}
