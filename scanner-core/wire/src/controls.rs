//! The camera controls the head fixed for the scan ([`Controls`], after each header).

use serde::{Deserialize, Serialize};

/// What the head did with one camera control the scan needs fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Control {
    /// The frames do not come from a camera (the virtual rig, image files).
    #[default]
    NoCamera,
    /// The camera does not offer the control (it may drift).
    NotOffered,
    /// Set to this value (the V4L2 value: for the power line 1 is 50 Hz, 2 is 60 Hz, 3 automatic;
    /// for the others the value that fixes the control).
    Set(i32),
    /// The camera refused the value.
    Refused,
}

/// The camera controls a difference image needs fixed between the reference and the laser
/// frames, as the head left them (sent after each [`Header`](crate::Header)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Controls {
    /// Scan id.
    pub scan_id: u32,
    /// Automatic exposure (set: manual).
    pub exposure: Control,
    /// Automatic white balance (set: off).
    pub white_balance: Control,
    /// Automatic gain (set: off).
    pub gain: Control,
    /// Automatic focus (set: off).
    pub focus: Control,
    /// Power-line frequency.
    pub power_line: Control,
}

impl Controls {
    /// The controls by name, in message order.
    pub fn named(&self) -> [(&'static str, Control); 5] {
        [
            ("exposure", self.exposure),
            ("white balance", self.white_balance),
            ("gain", self.gain),
            ("focus", self.focus),
            ("power line", self.power_line),
        ]
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn controls_golden_frame() {
        crate::golden::check(
            Message::Controls(Controls {
                scan_id: 3,
                exposure: Control::Set(156),
                white_balance: Control::NotOffered,
                gain: Control::Refused,
                focus: Control::NoCamera,
                power_line: Control::Set(-1),
            }),
            &[
                0, 9, 2, 3, 3, 2, 184, 2, 1, 3, 7, 2, 1, 16, 252, 194, 151, 0,
            ],
        );
    }
}
