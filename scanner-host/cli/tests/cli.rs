//! The `scanner-host` binary runs, answers `--info`, and refuses a bad flag with a clear message.

#[test]
fn info_and_usage_errors() {
    scanner_tests::check_cli(env!("CARGO_BIN_EXE_scanner-host"), "scanner-host");
}

use std::io::Write;
use std::process::{Command, Stdio};

fn host() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_scanner-host"));
    c.env(scanner_io::ERRORS_ENV, "json");
    c
}

/// A recorded rig scan (320×240, 30 frames).
fn recording(dir: &std::path::Path) -> std::path::PathBuf {
    use scanner_core::pipeline::HeadConfig;
    use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
    let mut scene = scanner_rig::Scene::demo(320, 240);
    scene.laser.frames = 30;
    let rig = scanner_rig::Rig::new(scene).unwrap();
    let cal = scanner_device::session::truth_calibration(&rig);
    let mut src = scanner_device::source::RigSource::new(rig, PixelFormat::Gray8);
    let path = dir.join("rec.stream");
    // A recording, not a test of the link: its deepest queue (30 frames and a few headers and
    // statuses fit), so that a writer that falls behind on a busy machine drops nothing.
    let mut link = scanner_device::link::Link::spawn(
        Box::new(std::fs::File::create(&path).unwrap()),
        scanner_device::link::MAX_DEPTH,
        scanner_wire::MAX_ENCODED,
    );
    let opts = scanner_device::session::ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        header_every: 10,
        status_every: 10,
        scan_id: 3,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    };
    scanner_device::session::run_scan(&mut src, &cal, opts, &mut link, |_| {}, |_, _| {}).unwrap();
    let stats = link.finish().unwrap();
    assert_eq!(stats.dropped, 0, "the link dropped point packets");
    path
}

#[test]
fn receive_from_stdin_with_garbage_then_replay_the_journal() {
    let dir = tempfile::tempdir().unwrap();
    let rec = std::fs::read(recording(dir.path())).unwrap();
    // Garbage at the start and a corrupted byte in the middle.
    let mut bytes = b"\x01\x02garbage\x00".to_vec();
    bytes.extend(&rec);
    // A byte that does not become a delimiter (0x00 would cut the frame in two pieces).
    let mid = (bytes.len() / 2..)
        .find(|&i| bytes[i] != 0x5a && bytes[i] != 0)
        .unwrap();
    bytes[mid] ^= 0x5a;
    let out = dir.path().join("live");
    let mut child = host()
        .args(["receive", "-", "--quiet", "--out", out.to_str().unwrap()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&bytes).unwrap();
    let res = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&res.stdout);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    // The garbage and the corrupted frame: two rejections, as a bad CRC or bad COBS (which
    // one depends on whether the flipped byte was a COBS code).
    let count = |what: &str| -> u32 {
        let at = text.find(what).unwrap();
        let before = text[..at].trim_end();
        before[before.rfind(' ').map_or(0, |i| i + 1)..]
            .parse()
            .unwrap()
    };
    assert_eq!(count(" bad CRC") + count(" bad COBS"), 2, "{text}");
    for f in scanner_host::outputs::OUTPUT_FILES
        .into_iter()
        .chain(["journal.stream"])
    {
        assert!(out.join(f).exists(), "{f}");
    }
    // Replaying the journal rebuilds the same mesh.
    let again = dir.path().join("again");
    let res = host()
        .args([
            "replay",
            out.join("journal.stream").to_str().unwrap(),
            "--out",
            again.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(res.status.success());
    assert_eq!(
        std::fs::read(out.join("scan.obj")).unwrap(),
        std::fs::read(again.join("scan.obj")).unwrap()
    );
    let losses = scanner_tests::link_losses(&scanner_tests::summary(&again));
    assert!(
        losses.is_empty(),
        "the journal holds only good frames: {losses:?}"
    );
}

#[test]
fn ctrl_c_finishes_cleanly_and_writes_the_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let rec = std::fs::read(recording(dir.path())).unwrap();
    let out = dir.path().join("out");
    let mut child = host()
        .args(["receive", "-", "--quiet", "--out", out.to_str().unwrap()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&rec).unwrap();
    stdin.flush().unwrap();
    // The input stays open (a live link); wait until the journal has it all, then Ctrl-C.
    let journal = out.join("journal.stream");
    let t0 = std::time::Instant::now();
    while std::fs::metadata(&journal).map_or(0, |m| m.len()) < rec.len() as u64 - 64
        && t0.elapsed().as_secs() < 20
    {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    // The reader may be blocked on stdin: closing it lets the loop see the flag.
    drop(stdin);
    let res = child.wait_with_output().unwrap();
    assert!(res.status.success());
    assert!(out.join("scan.obj").exists() && out.join("summary.txt").exists());
}

#[test]
fn bad_inputs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let res = host()
        .args([
            "replay",
            "/nonexistent.stream",
            "--out",
            dir.path().to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!res.status.success());
    assert!(String::from_utf8_lossy(&res.stderr).contains("cannot read /nonexistent.stream"));
    // Not a scanner stream: nothing to build, said so.
    let junk = dir.path().join("junk.bin");
    std::fs::write(
        &junk,
        (0..5000u32)
            .map(|i| (i * 7 % 251) as u8)
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let res = host()
        .args([
            "replay",
            junk.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!res.status.success());
    assert!(
        String::from_utf8_lossy(&res.stderr).contains("no session header received"),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let res = host()
        .args([
            "receive",
            "serial:/dev/ttyNONE@115200",
            "--out",
            dir.path().join("p").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        String::from_utf8_lossy(&res.stderr)
            .contains("cannot open serial port /dev/ttyNONE at 115200 baud")
    );
    let res = host()
        .args(["replay", junk.to_str().unwrap(), "--cell", "2furlongs"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&res.stderr).contains("give a number with px or mm"));
    let res = host().arg("ports").output().unwrap();
    assert!(res.status.success());
}

#[test]
fn head_to_host_over_a_pseudo_terminal() {
    use scanner_core::pipeline::HeadConfig;
    use scanner_core::stripe::{Axis, Method, StripeConfig};
    use scanner_device::link::Link;
    use scanner_device::session::ScanOptions;
    use scanner_wire::MAX_ENCODED;
    use serialport::SerialPort;
    let (device_end, host_end) = serialport::TTYPort::pair().expect("a pseudo-terminal pair");
    let name = host_end.name().expect("the host end has a device name");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let host = std::process::Command::new(env!("CARGO_BIN_EXE_scanner-host"))
        .args([
            "receive",
            &format!("serial:{name}@921600"),
            "--until-done",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let mut scene = scanner_rig::Scene::demo(320, 240);
    scene.laser.frames = 40;
    let rig = scanner_rig::Rig::new(scene).unwrap();
    let cal = scanner_device::session::truth_calibration(&rig);
    let mut source =
        scanner_device::source::RigSource::new(rig, scanner_core::stripe::PixelFormat::Gray8);
    let mut link = Link::spawn(
        Box::new(device_end.try_clone_native().unwrap()),
        64,
        MAX_ENCODED,
    );
    let opts = ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        header_every: 10,
        status_every: 10,
        scan_id: 8,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    };
    let report =
        scanner_device::session::run_scan(&mut source, &cal, opts, &mut link, |_| {}, |_, _| {})
            .unwrap();
    link.finish().unwrap();
    let res = host.wait_with_output().unwrap();
    drop((device_end, host_end));
    let text = String::from_utf8_lossy(&res.stdout);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let summary = scanner_tests::summary(&out);
    assert_eq!(
        summary["point_packets"],
        u64::from(report.status.packets),
        "{text}"
    );
    let losses = scanner_tests::link_losses(&summary);
    assert!(losses.is_empty(), "{losses:?}");
    assert!(out.join("scan.ply").exists());
}

#[test]
fn an_output_that_cannot_be_written_is_named_and_the_journal_kept() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path());
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("scan.obj")).unwrap(); // a folder where the mesh should go
    let res = host()
        .args([
            "receive",
            rec.to_str().unwrap(),
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!res.status.success());
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(scanner_tests::has_kind(&err, "Write"), "{err}");
    // Everything received is in the journal, and replays elsewhere.
    let journal = out.join("journal.stream");
    assert_eq!(
        std::fs::metadata(&journal).unwrap().len(),
        std::fs::metadata(&rec).unwrap().len()
    );
    let again = dir.path().join("again");
    assert!(
        host()
            .args([
                "replay",
                journal.to_str().unwrap(),
                "--out",
                again.to_str().unwrap()
            ])
            .output()
            .unwrap()
            .status
            .success()
    );
    assert!(again.join("scan.obj").is_file());
}
