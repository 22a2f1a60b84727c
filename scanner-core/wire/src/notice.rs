//! What the head tells its operator as it happens ([`Notice`]). The words are the ends': the
//! wire carries only what happened.

use serde::{Deserialize, Serialize};

/// What the head tells its operator, as it happens (the host shows it): the prompts of a scan
/// from a camera, which would otherwise reach only the head's own terminal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Notice {
    /// Scan id.
    pub scan_id: u32,
    /// What happened.
    pub kind: NoticeKind,
    /// For [`NoticeKind::SwitchLaserOn`] and [`NoticeKind::NoLaser`]: how long the head waits
    /// for the laser, seconds; 0 otherwise.
    pub seconds: u16,
}

/// What a [`Notice`] says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum NoticeKind {
    /// The head is taking its laser-off reference: keep the laser off.
    TakingReference = 0,
    /// The reference is taken: switch the laser on now.
    SwitchLaserOn = 1,
    /// The laser was seen: the scan counts frames from here.
    LaserSeen = 2,
    /// No laser was seen within the wait: the head stopped (exit status 3).
    NoLaser = 3,
    /// The head switched every laser it drives off: no word from the host (its heartbeat) for
    /// `seconds`. Sent when the host is heard again.
    LaserOffUnheard = 4,
}
wire_enum!(
    NoticeKind,
    TakingReference = 0,
    SwitchLaserOn = 1,
    LaserSeen = 2,
    NoLaser = 3,
    LaserOffUnheard = 4
);

impl NoticeKind {
    /// Its name in reports: `taking_reference`, `switch_laser_on`, `laser_seen`, `no_laser`.
    pub fn name(self) -> &'static str {
        match self {
            NoticeKind::TakingReference => "taking_reference",
            NoticeKind::SwitchLaserOn => "switch_laser_on",
            NoticeKind::LaserSeen => "laser_seen",
            NoticeKind::NoLaser => "no_laser",
            NoticeKind::LaserOffUnheard => "laser_off_unheard",
        }
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn notice_golden_frame() {
        crate::golden::check(
            Message::Notice(Notice {
                scan_id: 4,
                kind: NoticeKind::LaserOffUnheard,
                seconds: 2,
            }),
            &[0, 10, 2, 6, 4, 4, 2, 85, 247, 226, 20, 0],
        );
    }
}
