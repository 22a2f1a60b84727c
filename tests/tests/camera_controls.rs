//! The camera's controls travel with the scan: a camera-like source (rig frames, controls chosen
//! from a recorded `v4l2-ctl` list, one refused) sends them after each header, a recording keeps
//! them so that reprocessing gives the same bytes, and the host's summary names them — a refused
//! control with a warning. A source that is no camera sends none (the stream is as before).

use std::path::Path;

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_device::session::{ScanOptions, truth_calibration};
use scanner_device::source::controls::{on_wire, parse_v4l2_ctl, plan};
use scanner_device::source::record::{Recorder, RecordingSource};
use scanner_device::source::{FrameSource, OwnedFrame, RigSource, SourceError};
use scanner_host::collect::{CollectOptions, Collector};
use scanner_host::{OutputOptions, replay_into, write_outputs};
use scanner_rig::{Rig, Scene};
use scanner_wire::{Control, Controls, Decoder, MAX_ENCODED, Message};

/// The rig's frames, with the controls a camera would report.
struct FakeCamera {
    rig: RigSource,
    controls: Controls,
}

impl FrameSource for FakeCamera {
    fn describe(&self) -> String {
        "a camera-like rig".into()
    }
    fn format(&self) -> PixelFormat {
        self.rig.format()
    }
    fn size(&self) -> (usize, usize) {
        self.rig.size()
    }
    fn controls(&self) -> Controls {
        self.controls
    }
    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        self.rig.reference()
    }
    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        self.rig.next_frame()
    }
}

fn scene() -> Scene {
    let mut s = Scene::demo(320, 240);
    s.laser.frames = 24;
    s
}

fn scan(source: &mut dyn FrameSource, out: &Path) {
    let rig = Rig::new(scene()).unwrap();
    let opts = ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        header_every: 10,
        status_every: 10,
        scan_id: 0x00c0_ffee,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    };
    // A buffer for every message of the scan (24 frames, a header, its controls and a status
    // every 10, the last status: under 40): on a busy machine a shallower link drops point
    // packets (as it must, so as not to hold the camera up), and the reprocessed stream
    // would differ by what was dropped.
    scanner_tests::record_scan(
        source,
        &truth_calibration(&rig),
        opts,
        Box::new(std::fs::File::create(out).unwrap()),
    );
}

fn controls_in(bytes: &[u8]) -> Vec<Controls> {
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    let mut out = Vec::new();
    d.feed(bytes, |m| {
        if let Ok(Message::Controls(k)) = m {
            out.push(k);
        }
    });
    assert_eq!(d.stats().rejected(), 0);
    out
}

#[test]
fn controls_are_sent_recorded_reprocessed_and_reported() {
    let list = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scanner-device/tests/data/controls/uvc-webcam.txt"
    ))
    .unwrap();
    let p = plan(&parse_v4l2_ctl(&list), Some(50));
    let refused = [(
        "focus_auto".to_string(),
        "Input/output error (os error 5)".to_string(),
    )];
    let controls = on_wire(&p, &refused);
    assert_eq!(controls.exposure, Control::Set(1), "manual exposure");
    assert_eq!(
        controls.white_balance,
        Control::Set(0),
        "automatic white balance off"
    );
    assert_eq!(
        controls.gain,
        Control::NotOffered,
        "this webcam has no automatic gain"
    );
    assert_eq!(controls.focus, Control::Refused);
    assert_eq!(controls.power_line, Control::Set(1), "50 Hz");

    let dir = tempfile::tempdir().unwrap();
    let (first, again) = (
        dir.path().join("first.stream"),
        dir.path().join("again.stream"),
    );
    let camera = FakeCamera {
        rig: RigSource::new(Rig::new(scene()).unwrap(), PixelFormat::Yuyv),
        controls,
    };
    let mut recorder = Recorder::new(Box::new(camera), &dir.path().join("rec")).unwrap();
    scan(&mut recorder, &first);
    drop(recorder);
    let bytes = std::fs::read(&first).unwrap();
    let sent = controls_in(&bytes);
    assert!(sent.len() >= 3, "after each of the headers: {}", sent.len());
    assert!(sent.iter().all(|k| *k
        == Controls {
            scan_id: 0x00c0_ffee,
            ..controls
        }));

    // The recording keeps them: reprocessed, the stream is the same, byte for byte.
    let mut replayed = RecordingSource::open(&dir.path().join("rec")).unwrap();
    assert_eq!(replayed.controls(), controls);
    scan(&mut replayed, &again);
    assert!(
        bytes == std::fs::read(&again).unwrap(),
        "reprocessing changed the stream"
    );

    // The host names them, and warns of the refused one.
    let mut c = Collector::new(CollectOptions::default(), None);
    replay_into(&mut c, &first).unwrap();
    let summary = write_outputs(&c, &dir.path().join("out"), &OutputOptions::default())
        .unwrap()
        .data();
    let states: Vec<(u32, &str, &str)> = summary
        .controls
        .iter()
        .map(|c| (c.scan, c.control, c.state))
        .collect();
    assert_eq!(
        states,
        [
            (0xc0ffee, "exposure", "set"),
            (0xc0ffee, "white balance", "set"),
            (0xc0ffee, "gain", "not_offered"),
            (0xc0ffee, "focus", "refused"),
            (0xc0ffee, "power line", "set"),
        ],
        "{summary:?}"
    );
    // the power line's value is V4L2's for 50 Hz
    assert_eq!(summary.controls[4].value, Some(1), "{summary:?}");
    // and the file says the same
    let file = scanner_tests::summary(&dir.path().join("out"));
    assert_eq!(file["controls"][3]["state"], "refused", "{file}");

    // A source that is no camera sends no controls.
    let plain = dir.path().join("plain.stream");
    scan(
        &mut RigSource::new(Rig::new(scene()).unwrap(), PixelFormat::Yuyv),
        &plain,
    );
    let plain = std::fs::read(&plain).unwrap();
    assert!(controls_in(&plain).is_empty());
    assert!(plain.len() < bytes.len());
}
