//! The head's prompts reach the host: a scan whose laser never comes on tells the host why it
//! stopped (a notice on the link, in the host's summary and its error), and ends with its own
//! exit status (3) so that a service manager need not restart it in a loop.

use std::process::Command;

use scanner_tests::workspace_bin;

#[test]
fn a_scan_that_sees_no_laser_tells_the_host_why_and_exits_with_status_3() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    // The rig with its laser off for thousands of frames: the head waits, then gives up.
    let text = "width = 160\nheight = 120\n\n[laser]\nframes = 5000\npower = 0.0\n";
    std::fs::write(d.join("dark.toml"), text).unwrap();
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::from_toml_in(text, d).unwrap()).unwrap();
    rig.truth_calibration()
        .save(&d.join("calibration.toml"))
        .unwrap();
    let head = Command::new(workspace_bin("scanner-device"))
        .args(["scan", "--source", "rig", "--scene"])
        .arg(d.join("dark.toml"))
        .arg("--calibration")
        .arg(d.join("calibration.toml"))
        .args(["--wait-for-laser", "0.3", "--out"])
        .arg(d.join("dark.stream"))
        .output()
        .unwrap();
    assert_eq!(
        head.status.code(),
        Some(i32::from(scanner_device::session::EXIT_NO_LASER)),
        "{}",
        String::from_utf8_lossy(&head.stderr)
    );
    let host = Command::new(workspace_bin("scanner-host"))
        .args(["receive", "--until-done", "--quiet", "--out"])
        .arg(d.join("out"))
        .arg(d.join("dark.stream"))
        .output()
        .unwrap();
    assert!(!host.status.success(), "no scan arrived: the host fails");
    let s = scanner_tests::json(&d.join("out/summary.json"));
    let kinds: Vec<&str> = s["notices"]
        .as_array()
        .expect("the notices")
        .iter()
        .map(|n| n["kind"].as_str().unwrap())
        .collect();
    assert_eq!(
        kinds,
        ["taking_reference", "switch_laser_on", "no_laser"],
        "{s}"
    );
    let err = String::from_utf8_lossy(&host.stderr);
    assert!(
        err.contains(&s["notices"][2]["text"].as_str().unwrap()[..20]),
        "{err}"
    );
}
