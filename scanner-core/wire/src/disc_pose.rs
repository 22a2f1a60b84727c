//! The turntable disc's pose in the sweep's laser-off reference frame ([`DiscPose`]).

use serde::{Deserialize, Serialize};

/// What the head found of the turntable disc in the sweep's laser-off reference frame (after
/// each header, when the head was asked to look for a disc).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct DiscPose {
    /// Scan id.
    pub scan_id: u32,
    /// What was found.
    pub found: DiscFound,
    /// Disc → camera rotation as a unit quaternion `i, j, k, w` (identity when not found).
    pub rotation: [f32; 4],
    /// The disc's centre in camera coordinates, mm.
    pub translation: [f32; 3],
    /// Dots used for the pose.
    pub markers: u16,
    /// Dots printed.
    pub of: u16,
    /// RMS reprojection error of the used dots, pixels.
    pub rms_px: f32,
}

/// What the head found of the turntable disc ([`DiscPose::found`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum DiscFound {
    /// Found: the pose is good.
    #[default]
    Found = 0,
    /// Too few of its dots were seen (not in view, or hidden).
    TooFewMarkers = 1,
    /// Two turns of the disc fit its visible dots nearly as well.
    Ambiguous = 2,
    /// Seen too nearly edge-on.
    Tilted = 3,
    /// Its dots fit no pose.
    PoorFit = 4,
}
wire_enum!(
    DiscFound,
    Found = 0,
    TooFewMarkers = 1,
    Ambiguous = 2,
    Tilted = 3,
    PoorFit = 4
);

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn disc_pose_golden_frame() {
        crate::golden::check(
            Message::Disc(DiscPose {
                scan_id: 3,
                found: DiscFound::Found,
                rotation: [1.0, 0.0, 0.0, 0.0],
                translation: [10.5, -20.25, 600.0],
                markers: 31,
                of: 36,
                rms_px: 0.35,
            }),
            &[
                0, 4, 2, 5, 3, 1, 1, 3, 128, 63, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 3, 40, 65,
                1, 3, 162, 193, 1, 13, 22, 68, 31, 36, 51, 51, 179, 62, 100, 71, 198, 107, 0,
            ],
        );
    }
}
