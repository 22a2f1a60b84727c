//! The camera controls a scan needs, chosen from what a camera offers: the difference image
//! compares every frame with the laser-off reference, so nothing may change between them —
//! exposure, gain, white balance and focus are fixed, and the power-line frequency is set so that
//! lamps do not beat with the exposure. Pure: the V4L2 source applies the plan to a device, and
//! tests check it on control lists in `v4l2-ctl --list-ctrls-menus` form.

/// A control's kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlKind {
    /// An integer range.
    Integer,
    /// On or off.
    Boolean,
    /// Numbered choices.
    Menu,
    /// Anything else (buttons, strings): never set here.
    Other,
}

/// One control a camera offers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraControl {
    /// V4L2 control id.
    pub id: u32,
    /// Its name as the driver gives it.
    pub name: String,
    /// Its kind.
    pub kind: ControlKind,
    /// Smallest value.
    pub min: i64,
    /// Largest value.
    pub max: i64,
    /// For menus: the offered indices and their names.
    pub menu: Vec<(i64, String)>,
    /// Read-only controls cannot be set.
    pub read_only: bool,
}

impl CameraControl {
    fn offers(&self, value: i64) -> bool {
        !self.read_only
            && value >= self.min
            && value <= self.max
            && (self.kind != ControlKind::Menu || self.menu.iter().any(|(i, _)| *i == value))
    }
}

/// V4L2 control ids (linux/v4l2-controls.h).
pub mod id {
    /// `V4L2_CID_EXPOSURE_AUTO` (menu: 0 auto, 1 manual, 2 shutter priority, 3 aperture priority).
    pub const EXPOSURE_AUTO: u32 = 0x009a_0901;
    /// `V4L2_CID_EXPOSURE_AUTO_PRIORITY` (may the camera lower the frame rate to expose longer).
    pub const EXPOSURE_AUTO_PRIORITY: u32 = 0x009a_0903;
    /// `V4L2_CID_AUTO_WHITE_BALANCE`.
    pub const AUTO_WHITE_BALANCE: u32 = 0x0098_090c;
    /// `V4L2_CID_AUTOGAIN`.
    pub const AUTOGAIN: u32 = 0x0098_0912;
    /// `V4L2_CID_FOCUS_AUTO`.
    pub const FOCUS_AUTO: u32 = 0x009a_090c;
    /// `V4L2_CID_POWER_LINE_FREQUENCY` (menu: 0 off, 1 50 Hz, 2 60 Hz, 3 auto).
    pub const POWER_LINE_FREQUENCY: u32 = 0x0098_0918;
    /// `V4L2_CID_EXPOSURE_ABSOLUTE` (units of 100 µs).
    pub const EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
    /// `V4L2_CID_GAIN`.
    pub const GAIN: u32 = 0x0098_0913;
    /// `V4L2_CID_FOCUS_ABSOLUTE`.
    pub const FOCUS_ABSOLUTE: u32 = 0x009a_090a;
    /// `V4L2_CID_WHITE_BALANCE_TEMPERATURE` (kelvin).
    pub const WHITE_BALANCE_TEMPERATURE: u32 = 0x0098_091a;
}

/// Why a control set by hand (the studio's camera controls) cannot be set.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AdjustError {
    /// The camera (or the source) has no such control.
    #[error("the camera has no {0} control")]
    NotOffered(&'static str),
    /// The value lies outside what the camera offers.
    #[error("{control} {value} is outside the camera's {min}–{max}")]
    OutOfRange {
        /// The control.
        control: &'static str,
        /// The value asked for.
        value: i64,
        /// The camera's smallest.
        min: i64,
        /// The camera's largest.
        max: i64,
    },
}

/// The setting that gives `control` the value `value` on a camera offering `controls`
/// (V4L2's own units: exposure in 100 µs, white balance in kelvin). Setting it by hand needs
/// the control's automatic mode off, which [`plan`] does for every scan.
///
/// # Errors
/// [`AdjustError`]: the camera has no such control, or not this value.
pub fn by_hand(
    controls: &[CameraControl],
    control: scanner_wire::Adjustable,
    value: i32,
) -> Result<Setting, AdjustError> {
    use scanner_wire::Adjustable as A;
    let name = control.name();
    let wanted = match control {
        A::Exposure => id::EXPOSURE_ABSOLUTE,
        A::Gain => id::GAIN,
        A::Focus => id::FOCUS_ABSOLUTE,
        A::WhiteBalance => id::WHITE_BALANCE_TEMPERATURE,
    };
    let c = controls
        .iter()
        .find(|c| c.id == wanted && !c.read_only && c.kind == ControlKind::Integer)
        .ok_or(AdjustError::NotOffered(name))?;
    let value = i64::from(value);
    if !c.offers(value) {
        return Err(AdjustError::OutOfRange {
            control: name,
            value,
            min: c.min,
            max: c.max,
        });
    }
    Ok(Setting {
        id: c.id,
        control: c.name.clone(),
        kind: c.kind,
        value,
        meaning: "set by hand",
    })
}

/// One control to set, and what the value means.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Setting {
    /// CameraControl id.
    pub id: u32,
    /// The control's name (the driver's).
    pub control: String,
    /// Its kind (how the value is sent).
    pub kind: ControlKind,
    /// The value.
    pub value: i64,
    /// What it does, for people.
    pub meaning: &'static str,
}

/// The settings for a camera, and what it does not offer.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Plan {
    /// Controls to set, in order.
    pub settings: Vec<Setting>,
    /// What the scan would want but the camera does not offer (it may drift there).
    pub missing: Vec<&'static str>,
}

/// Chooses the settings from the controls a camera offers; `mains_hz` is the local mains
/// frequency (50 or 60) when known, else the camera's automatic choice is taken if it has one.
pub fn plan(controls: &[CameraControl], mains_hz: Option<u32>) -> Plan {
    let find = |id: u32| controls.iter().find(|c| c.id == id);
    let mut p = Plan::default();
    let mut want =
        |id: u32, values: &[i64], meaning: &'static str, missing: &'static str| match find(id)
            .and_then(|c| values.iter().find(|v| c.offers(**v)).map(|v| (c, *v)))
        {
            Some((c, value)) => p.settings.push(Setting {
                id,
                control: c.name.clone(),
                kind: c.kind,
                value,
                meaning,
            }),
            None => p.missing.push(missing),
        };
    want(
        id::EXPOSURE_AUTO,
        &[1],
        "exposure manual (fixed)",
        "manual exposure",
    );
    if find(id::EXPOSURE_AUTO_PRIORITY).is_some() {
        want(
            id::EXPOSURE_AUTO_PRIORITY,
            &[0],
            "constant frame rate",
            "constant frame rate",
        );
    }
    want(
        id::AUTO_WHITE_BALANCE,
        &[0],
        "white balance fixed",
        "fixed white balance",
    );
    if find(id::AUTOGAIN).is_some() {
        want(id::AUTOGAIN, &[0], "gain fixed", "fixed gain");
    }
    if find(id::FOCUS_AUTO).is_some() {
        want(id::FOCUS_AUTO, &[0], "focus fixed", "fixed focus");
    }
    let mains: &[i64] = match mains_hz {
        Some(50) => &[1],
        Some(60) => &[2],
        _ => &[3],
    };
    want(
        id::POWER_LINE_FREQUENCY,
        mains,
        match mains_hz {
            Some(50) => "power line 50 Hz",
            Some(60) => "power line 60 Hz",
            _ => "power line automatic",
        },
        "power-line frequency (give --mains 50 or 60)",
    );
    p
}

/// One line for people: what was set, what the camera refused (named with its error), what it
/// does not offer.
pub fn report(plan: &Plan, refused: &[(String, String)]) -> String {
    let set: Vec<&str> = plan
        .settings
        .iter()
        .filter(|s| !refused.iter().any(|(c, _)| *c == s.control))
        .map(|s| s.meaning)
        .collect();
    let mut line = format!(
        "camera controls: {}",
        if set.is_empty() {
            "none set".to_string()
        } else {
            set.join(", ")
        }
    );
    for (control, why) in refused {
        line += &format!("; the camera refused {control} ({why})");
    }
    if !plan.missing.is_empty() {
        line += &format!(
            "; not offered: {} (the picture may drift between the reference and the laser frames)",
            plan.missing.join(", ")
        );
    }
    line
}

/// What the plan did, for the stream ([`scanner_wire::Controls`], sent after each header):
/// per control the value set, refused (named in `refused` by the driver's name), or not offered.
pub fn on_wire(plan: &Plan, refused: &[(String, String)]) -> scanner_wire::Controls {
    use scanner_wire::Control as C;
    let state = |id: u32| match plan.settings.iter().find(|s| s.id == id) {
        None => C::NotOffered,
        Some(s) if refused.iter().any(|(c, _)| *c == s.control) => C::Refused,
        Some(s) => C::Set(i32::try_from(s.value).unwrap_or(i32::MAX)),
    };
    scanner_wire::Controls {
        scan_id: 0,
        exposure: state(id::EXPOSURE_AUTO),
        white_balance: state(id::AUTO_WHITE_BALANCE),
        gain: state(id::AUTOGAIN),
        focus: state(id::FOCUS_AUTO),
        power_line: state(id::POWER_LINE_FREQUENCY),
    }
}

/// Reads `v4l2-ctl --list-ctrls-menus` output (what a camera offers, recorded once with that
/// tool): `name 0xID (kind) : min=… max=… … flags=…`, menus followed by `N: Name` lines.
/// Lines that are neither are skipped.
pub fn parse_v4l2_ctl(text: &str) -> Vec<CameraControl> {
    let mut out: Vec<CameraControl> = Vec::new();
    for line in text.lines() {
        let t = line.trim();
        if let Some((index, name)) = t.split_once(": ")
            && let Ok(i) = index.trim().parse::<i64>()
        {
            if let Some(c) = out.last_mut()
                && c.kind == ControlKind::Menu
            {
                c.menu.push((i, name.trim().to_string()));
            }
            continue;
        }
        let Some((head, fields)) = t.split_once(':') else {
            continue;
        };
        let mut words = head.split_whitespace();
        let (Some(name), Some(hex), Some(kind)) = (words.next(), words.next(), words.next()) else {
            continue;
        };
        let Some(id) = hex
            .strip_prefix("0x")
            .and_then(|h| u32::from_str_radix(h, 16).ok())
        else {
            continue;
        };
        let field = |key: &str| {
            fields.split_whitespace().find_map(|w| {
                w.strip_prefix(key)
                    .and_then(|v| v.strip_prefix('='))
                    .and_then(|v| v.parse::<i64>().ok())
            })
        };
        let kind = match kind {
            "(int)" => ControlKind::Integer,
            "(bool)" => ControlKind::Boolean,
            "(menu)" | "(intmenu)" => ControlKind::Menu,
            _ => ControlKind::Other,
        };
        out.push(CameraControl {
            id,
            name: name.to_string(),
            kind,
            min: field("min").unwrap_or(0),
            max: field("max").unwrap_or(if kind == ControlKind::Boolean { 1 } else { 0 }),
            menu: Vec::new(),
            read_only: fields.contains("read-only"),
        });
    }
    out
}
