//! What became of a calibration shot ([`ShotTaken`]) and of a calibration ([`Calibrated`]),
//! answering the host's shot and calibrate commands.

use serde::{Deserialize, Serialize};

/// Cells of the coverage map across the picture.
pub const COVER_COLS: u32 = 8;
/// Cells of the coverage map down the picture.
pub const COVER_ROWS: u32 = 8;

/// A calibration shot, as the head's detector judged it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ShotTaken {
    /// The command that asked for it.
    pub seq: u32,
    /// The board (laser off) rather than the intrinsics target.
    pub board: bool,
    /// Whether it is kept: 0 kept, 1 the target was not found, 2 found but not usable (too
    /// few points, a sheet that does not fit).
    pub found: u8,
    /// Shots of this kind kept so far, this one included.
    pub kept: u16,
    /// Points the detector placed.
    pub points: u16,
    /// Where on the picture the points lie: bit `row · 8 + col` of an 8 × 8 grid of cells.
    pub cover: u64,
    /// The target's tilt about the picture's horizontal and vertical axes, degrees (from the
    /// shot's homography with a focal length of the picture's larger side when none is known
    /// yet): shots at several tilts fix the focal length.
    pub tilt_deg: [i8; 2],
}

/// A calibration from the shots taken.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Calibrated {
    /// The command that asked for it.
    pub seq: u32,
    /// 0 calibrated (the head scans with it from now on); 1 the intrinsics failed their
    /// checks; 2 the board failed.
    pub result: u8,
    /// Target shots used.
    pub shots: u16,
    /// The intrinsics' RMS reprojection error, pixels.
    pub rms_px: f32,
    /// The intrinsics' self-check: the shots split in two halves, each calibrated alone, their
    /// projections' RMS difference over the picture, pixels (NaN: too few shots to split).
    pub halves_px: f32,
    /// The board's fit, RMS pixels.
    pub board_rms_px: f32,
    /// The angle between the board's two sheets, degrees.
    pub board_angle_deg: f32,
}

impl ShotTaken {
    /// The cell `(col, row)` of the coverage map that pixel `(x, y)` of a `width × height`
    /// picture falls in.
    pub fn cell(x: f64, y: f64, width: u32, height: u32) -> (u32, u32) {
        let c = (x / f64::from(width.max(1)) * f64::from(COVER_COLS)).clamp(0.0, 7.0);
        let r = (y / f64::from(height.max(1)) * f64::from(COVER_ROWS)).clamp(0.0, 7.0);
        (c as u32, r as u32)
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn shot_taken_golden_frame() {
        crate::golden::check(
            Message::Shot(ShotTaken {
                seq: 7,
                board: true,
                found: 42,
                kept: 40,
                points: 1234,
                cover: 0x0000_00F0_F0F0_0000,
                tilt_deg: [-12, 30],
            }),
            &[
                0, 21, 2, 10, 7, 1, 42, 40, 210, 9, 128, 128, 192, 135, 143, 30, 244, 30, 146, 248,
                15, 109, 0,
            ],
        );
    }

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn calibrated_golden_frame() {
        crate::golden::check(
            Message::Calibrated(Calibrated {
                seq: 8,
                result: 0,
                shots: 12,
                rms_px: 0.21,
                halves_px: 0.05,
                board_rms_px: 0.4,
                board_angle_deg: 91.5,
            }),
            &[
                0, 4, 2, 11, 8, 14, 12, 61, 10, 87, 62, 205, 204, 76, 61, 205, 204, 204, 62, 1, 7,
                183, 66, 36, 16, 60, 180, 0,
            ],
        );
    }
}
