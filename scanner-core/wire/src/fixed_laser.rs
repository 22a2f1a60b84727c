//! A fixed laser over a turning platform ([`FixedLaser`]): the scan's points are the laser's
//! crossings with an object that turns between frames, and the host carries each frame's points
//! into the platform's frame with the platform's pose and the frame's turn.

use serde::{Deserialize, Serialize};

/// The turning platform of a fixed-laser scan (after each header of such a scan). The points
/// stay in camera coordinates, as in any scan; each `Points` message's `plane` is the fixed
/// laser's plane.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FixedLaser {
    /// Scan id.
    pub scan_id: u32,
    /// Which of the rig's lasers drew the stripe (0 first).
    pub laser: u8,
    /// The platform's axes as the columns of a rotation (platform → camera), row-major: `x`,
    /// `y` on its top at turn 0, `z` up the turning axis.
    pub rotation: [f32; 9],
    /// The platform's origin (the axis at its top), camera coordinates, mm.
    pub origin: [f32; 3],
    /// The platform's turn between consecutive frames, radians (frame `k` is at `k · turn`;
    /// the sign is the direction it turns, positive counter-clockwise seen from above).
    pub turn: f32,
    /// The platform's radius, mm: what lies farther from the axis is not the object (0: not
    /// known).
    pub radius: f32,
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn fixed_laser_golden_frame() {
        crate::golden::check(
            Message::FixedLaser(FixedLaser {
                scan_id: 9,
                laser: 1,
                rotation: [1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0],
                origin: [0.0, 80.0, 300.0],
                turn: 0.8,
                radius: 70.0,
            }),
            &[
                0, 5, 2, 8, 9, 1, 1, 3, 128, 63, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
                3, 128, 191, 1, 1, 1, 1, 1, 3, 128, 63, 1, 1, 1, 1, 1, 1, 1, 1, 1, 3, 160, 66, 1,
                7, 150, 67, 205, 204, 76, 63, 1, 7, 140, 66, 37, 206, 75, 56, 0,
            ],
        );
    }
}
