//! The camera's controls as the job keeps them (set by hand on the page, sent to the head again
//! when the studio opens the job), and the values scanning needs, suggested from the preview:
//! the picture not clipped, the laser line bright enough against the board.

use serde::Serialize;

use super::job::SetupCheck;

/// The controls set by hand on the page, as the job keeps them.
pub type CameraSettings = scanner_wire::ByHand;

/// Clipped pixels beyond which the exposure is too long, per mille (the set-up's own verdict).
pub const CLIPPED_PERMILLE: u16 = 20;
/// The light the laser adds below which its line is faint, DN: the stripe's sub-pixel centre
/// needs a few tens of DN above the board's noise.
pub const FAINT_LASER_DN: u16 = 25;

/// A control's suggested value and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Advice {
    /// The control (`exposure`).
    pub control: &'static str,
    /// Its number on the wire ([`scanner_wire::Adjustable`]).
    pub number: u8,
    /// The suggested value, when the current one is known (set on this page).
    pub value: Option<i32>,
    /// `clipped`, `laser_faint`.
    pub why: &'static str,
    /// What to do, in the page's terms.
    pub words: String,
}

/// The exposure a preview asks for: shorter when the picture clips, longer when the laser
/// line is faint; `None` when it needs neither.
pub fn advice(p: &SetupCheck, now: &CameraSettings) -> Option<Advice> {
    let (why, factor, words) = if p.clipped_permille > CLIPPED_PERMILLE {
        (
            "clipped",
            0.5,
            format!(
                "{:.1} % of the picture is clipped (white): halve the exposure",
                f64::from(p.clipped_permille) / 10.0
            ),
        )
    } else if p.laser_dn < FAINT_LASER_DN && p.laser_lines_pct > 0.0 {
        (
            "laser_faint",
            2.0,
            format!(
                "the laser adds only {} DN to the board (at least {FAINT_LASER_DN} wanted): double the exposure, or darken the room",
                p.laser_dn
            ),
        )
    } else {
        return None;
    };
    let value = now
        .exposure
        .map(|e| ((f64::from(e) * factor).round() as i32).max(1));
    Some(Advice {
        control: "exposure",
        number: scanner_wire::Adjustable::Exposure as u8,
        value,
        why,
        words: match value {
            Some(v) => format!("{words}: press Apply to set it to {v}."),
            None => format!("{words} (type the new value in Exposure and press Set)."),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(clipped: u16, laser_dn: u16) -> SetupCheck {
        SetupCheck {
            frame: 1,
            width: 160,
            height: 120,
            scale: 4,
            clipped_permille: clipped,
            markers: 12,
            laser_lines_pct: 90.0,
            laser_dn,
            state: "points".into(),
            verdict: String::new(),
        }
    }

    /// A clipped picture asks for half the exposure, a faint laser for double, a good one
    /// for nothing; the value only when the current one is known.
    #[test]
    fn the_exposure_asked_for_follows_the_picture() {
        let set = CameraSettings {
            exposure: Some(300),
            ..CameraSettings::default()
        };
        let a = advice(&check(150, 60), &set).unwrap();
        assert_eq!((a.why, a.value), ("clipped", Some(150)));
        let a = advice(&check(0, 10), &set).unwrap();
        assert_eq!((a.why, a.value), ("laser_faint", Some(600)));
        assert_eq!(advice(&check(3, 60), &set), None);
        let a = advice(&check(150, 60), &CameraSettings::default()).unwrap();
        assert_eq!(a.value, None);
    }
}
