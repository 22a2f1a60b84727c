//! How well the laser planes fitted the board since the last status ([`Planes`]).

use serde::{Deserialize, Serialize};

/// How well the laser planes of the frames since the last status fitted the board's stripe
/// (sent before each [`Status`](crate::Status)): the operator's check that the sweep is clean.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Planes {
    /// Scan id.
    pub scan_id: u32,
    /// Laser planes fitted (frames whose plane passed its check).
    pub planes: u32,
    /// Their mean RMS of the board's stripe points about the plane, µm.
    pub rms_mean_um: u32,
    /// The largest of those RMS, µm.
    pub rms_max_um: u32,
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn planes_golden_frame() {
        crate::golden::check(
            Message::Planes(Planes {
                scan_id: 3,
                planes: 120,
                rms_mean_um: 180,
                rms_max_um: 950,
            }),
            &[0, 13, 2, 4, 3, 120, 180, 1, 182, 7, 192, 10, 87, 35, 0],
        );
    }
}
