//! A turning platform's measured turn at one frame ([`MeasuredTurn`]).

use serde::{Deserialize, Serialize};

/// The platform's turn at one frame of a fixed-laser scan as the head measured it (from
/// markers printed on the platform), sent before that frame's points. When a scan sends any,
/// the host takes each frame's turn from them instead of `frame · turn`, and leaves out the
/// points of frames without one.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MeasuredTurn {
    /// Scan id.
    pub scan_id: u32,
    /// The frame (as its points are numbered).
    pub frame: u32,
    /// The turn from the scan's first frame, radians, counter-clockwise seen from above (past a
    /// whole turn it goes on past 2π).
    pub angle: f64,
    /// Markers it was measured with.
    pub markers: u8,
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn turn_golden_frame() {
        crate::golden::check(
            Message::Turn(MeasuredTurn {
                scan_id: 7,
                frame: 40,
                angle: 2.5,
                markers: 3,
            }),
            &[
                0, 5, 2, 13, 7, 40, 1, 1, 1, 1, 1, 8, 4, 64, 3, 227, 18, 79, 234, 0,
            ],
        );
    }
}
