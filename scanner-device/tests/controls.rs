//! The camera controls a scan sets, chosen from control lists in `v4l2-ctl --list-ctrls-menus`
//! form (tests/data/controls, see its README); what is set, refused and missing is reported.

use scanner_device::source::controls::{ControlKind, id, parse_v4l2_ctl, plan, report};

fn list(name: &str) -> Vec<scanner_device::source::controls::CameraControl> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/controls")
        .join(name);
    parse_v4l2_ctl(&std::fs::read_to_string(path).unwrap())
}

fn value(p: &scanner_device::source::controls::Plan, id: u32) -> Option<i64> {
    p.settings.iter().find(|s| s.id == id).map(|s| s.value)
}

#[test]
fn a_uvc_webcam_gets_manual_exposure_fixed_white_balance_and_focus_and_mains() {
    let c = list("uvc-webcam.txt");
    assert_eq!(c.len(), 10);
    let exposure = c.iter().find(|c| c.id == id::EXPOSURE_AUTO).unwrap();
    assert_eq!(exposure.kind, ControlKind::Menu);
    assert_eq!(exposure.menu.len(), 2);
    let p = plan(&c, Some(50));
    assert_eq!(value(&p, id::EXPOSURE_AUTO), Some(1));
    assert_eq!(value(&p, id::EXPOSURE_AUTO_PRIORITY), Some(0));
    assert_eq!(value(&p, id::AUTO_WHITE_BALANCE), Some(0));
    assert_eq!(value(&p, id::FOCUS_AUTO), Some(0));
    assert_eq!(value(&p, id::POWER_LINE_FREQUENCY), Some(1));
    assert!(p.missing.is_empty(), "{:?}", p.missing);
    assert_eq!(
        value(&plan(&c, Some(60)), id::POWER_LINE_FREQUENCY),
        Some(2)
    );
    // Without --mains this camera has no automatic choice: it is named as missing.
    let p = plan(&c, None);
    assert_eq!(value(&p, id::POWER_LINE_FREQUENCY), None);
    assert!(
        report(&p, &[]).contains("not offered: power-line frequency (give --mains 50 or 60)"),
        "{}",
        report(&p, &[])
    );
    // A control the camera refuses is named with the camera's error.
    let r = report(
        &plan(&c, Some(50)),
        &[(
            "focus_auto".into(),
            "Input/output error (os error 5)".into(),
        )],
    );
    assert!(r.starts_with("camera controls: exposure manual (fixed), constant frame rate, white balance fixed, power line 50 Hz"), "{r}");
    assert!(
        r.contains("the camera refused focus_auto (Input/output error (os error 5))"),
        "{r}"
    );
}

#[test]
fn automatic_gain_and_mains_are_used_where_offered() {
    let p = plan(&list("fixed-focus-auto-mains.txt"), None);
    assert_eq!(value(&p, id::AUTOGAIN), Some(0));
    assert_eq!(value(&p, id::POWER_LINE_FREQUENCY), Some(3));
    assert_eq!(value(&p, id::FOCUS_AUTO), None, "no focus control to set");
    assert!(p.missing.is_empty(), "{:?}", p.missing);
}

#[test]
fn a_camera_without_manual_controls_is_reported_not_refused() {
    let p = plan(&list("auto-only.txt"), Some(50));
    assert!(p.settings.is_empty(), "{:?}", p.settings);
    let r = report(&p, &[]);
    assert!(
        r.contains("none set")
            && r.contains("manual exposure")
            && r.contains("fixed white balance"),
        "{r}"
    );
}

/// A control set by hand (the studio's camera controls) is found by its V4L2 id and checked
/// against the camera's own range: a webcam's exposure 3–2047 and white balance 2000–6500 K;
/// a focus it has not got is named.
#[test]
fn controls_set_by_hand_are_checked_against_the_cameras_range() {
    use scanner_device::source::controls::{AdjustError, by_hand};
    use scanner_wire::Adjustable;
    let c = list("uvc-webcam.txt");
    let s = by_hand(&c, Adjustable::Exposure, 100).unwrap();
    assert_eq!((s.id, s.value), (id::EXPOSURE_ABSOLUTE, 100));
    assert_eq!(
        by_hand(&c, Adjustable::Exposure, 5000),
        Err(AdjustError::OutOfRange {
            control: "exposure",
            value: 5000,
            min: 3,
            max: 2047
        })
    );
    assert_eq!(
        by_hand(&c, Adjustable::WhiteBalance, 5000).map(|s| s.id),
        Ok(id::WHITE_BALANCE_TEMPERATURE)
    );
    assert_eq!(
        by_hand(&c, Adjustable::Gain, 40).map(|s| s.id),
        Ok(id::GAIN)
    );
    let fixed = list("fixed-focus-auto-mains.txt");
    assert_eq!(
        by_hand(&fixed, Adjustable::Focus, 10),
        Err(AdjustError::NotOffered("focus"))
    );
}
