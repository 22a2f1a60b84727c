//! What the wire's numbers say to people, written once for both ends that show them: the head's
//! terminal and the host's (the wire itself carries only what happened).

use scanner_wire::{Control, Controls, Notice, NoticeKind, Skip};

/// Why a frame was skipped, in a few words (also the `reason` of the reports).
pub fn skip_reason(skip: Skip) -> &'static str {
    match skip {
        Skip::NoStripe => "no stripe on the board",
        Skip::OnePlaneOnly => "stripe on one plane only",
        Skip::PlaneThroughCamera => "laser plane through the camera",
        Skip::PoorPlane => "laser plane failed its check",
        Skip::BadFrame => "bad camera frame",
        Skip::LinkFull => "link too slow (frame dropped)",
    }
}

/// A notice as one line for the operator.
pub fn notice_line(n: &Notice) -> String {
    match n.kind {
        NoticeKind::TakingReference => {
            "keep the laser OFF: the head is taking its reference".to_string()
        }
        NoticeKind::SwitchLaserOn => format!(
            "reference taken: switch the laser ON now and sweep (the head waits {} s)",
            n.seconds
        ),
        NoticeKind::LaserSeen => "laser seen: scanning".to_string(),
        NoticeKind::NoLaser => format!(
            "no laser seen within {} s after the reference: the head stopped; start it again",
            n.seconds
        ),
        NoticeKind::LaserOffUnheard => format!(
            "the head switched the laser off: it heard nothing from the studio for {} s",
            n.seconds
        ),
    }
}

/// The camera controls as one line: `exposure fixed, white balance fixed, …, power line 50 Hz`.
pub fn controls_line(c: &Controls) -> String {
    if c.named().iter().all(|(_, c)| *c == Control::NoCamera) {
        return "no camera (nothing to fix)".to_string();
    }
    let words: Vec<String> = c
        .named()
        .into_iter()
        .map(|(name, c)| match (name, c) {
            (_, Control::NoCamera) => format!("{name} not a camera's"),
            (_, Control::NotOffered) => format!("{name} not offered"),
            (_, Control::Refused) => format!("{name} REFUSED by the camera"),
            ("power line", Control::Set(1)) => "power line 50 Hz".to_string(),
            ("power line", Control::Set(2)) => "power line 60 Hz".to_string(),
            ("power line", Control::Set(_)) => "power line automatic".to_string(),
            (_, Control::Set(_)) => format!("{name} fixed"),
        })
        .collect();
    words.join(", ")
}
