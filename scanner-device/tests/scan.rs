//! The scanner head end to end on the virtual rig: the stream in a file decodes to exactly the
//! points the head computed; a whole scan crosses a pseudo-terminal pair intact; a slow link
//! drops whole frames and never corrupts the stream; the pipeline allocates nothing per frame.

use std::collections::BTreeMap;
use std::io::Read;

use serialport::SerialPort;

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_device::link::Link;
use scanner_device::session::truth_calibration;
use scanner_device::session::{ScanOptions, run_scan};
use scanner_device::source::RigSource;
use scanner_rig::{Rig, Scene};
use scanner_wire::{Decoder, MAX_ENCODED, Message, points};

fn options(scan_id: u32) -> ScanOptions {
    ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        header_every: 10,
        status_every: 10,
        scan_id,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    }
}

type Decoded = (
    BTreeMap<u32, Vec<[i32; 3]>>,
    usize,
    Option<scanner_wire::Status>,
    scanner_wire::DecodeStats,
);

/// Decodes a byte stream: (frame → points) of every point packet, headers seen, the last
/// status, the decoder's counts.
fn decode(bytes: &[u8]) -> Decoded {
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    let (mut frames, mut headers, mut last) = (BTreeMap::new(), 0, None);
    for chunk in bytes.chunks(777) {
        d.feed(chunk, |m| match m.expect("a valid frame") {
            Message::Header(_) => headers += 1,
            Message::Points(p) => {
                let mut v = Vec::new();
                points::decode(p.xyz, p.count as usize, |q| v.push(q)).unwrap();
                frames.insert(p.frame, v);
            }
            Message::Status(s) => last = Some(s),
            Message::Controls(_)
            | Message::Planes(_)
            | Message::Disc(_)
            | Message::Notice(_)
            | Message::Preview(_)
            | Message::Picture(_)
            | Message::FixedLaser(_)
            | Message::Turn(_) => {}
            m @ (Message::Reply(_) | Message::Shot(_) | Message::Calibrated(_)) => {
                panic!("a scan answers no command: {m:?}")
            }
        });
    }
    (frames, headers, last, d.stats())
}

#[test]
fn the_stream_in_a_file_decodes_to_exactly_the_heads_points() {
    let rig = Rig::new(Scene::demo(640, 480)).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scan.stream");
    // The deepest link (`--link-depth` 64): headers, like point packets, are dropped when every
    // buffer waits (they repeat), and the count below assumes a writer that keeps up.
    let mut link = Link::spawn(
        Box::new(std::fs::File::create(&path).unwrap()),
        scanner_device::link::MAX_DEPTH,
        MAX_ENCODED,
    );
    let mut mine: BTreeMap<u32, Vec<[i32; 3]>> = BTreeMap::new();
    let report = run_scan(
        &mut source,
        &cal,
        options(11),
        &mut link,
        |_| {},
        |f, p| {
            mine.insert(f, p.to_vec());
        },
    )
    .unwrap();
    link.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let (theirs, headers, last, stats) = decode(&bytes);
    assert_eq!(stats.rejected(), 0);
    // On a busy machine the link may drop point packets rather than hold the camera up (counted,
    // by design): every packet that arrived is exactly what the head made of its frame, and
    // those missing are the ones the link counted as dropped.
    for (f, points) in &theirs {
        assert_eq!(
            Some(points),
            mine.get(f),
            "frame {f}: decoded points differ"
        );
    }
    assert_eq!(
        (mine.len() - theirs.len()) as u64,
        report.dropped,
        "packets missing without being counted as dropped"
    );
    let status = last.expect("a final status");
    assert!(status.done && status.ended == scanner_wire::EndReason::Completed);
    assert_eq!(u64::from(status.packets), theirs.len() as u64);
    assert_eq!(
        status.points,
        theirs.values().map(|v| v.len() as u64).sum::<u64>()
    );
    assert_eq!(bytes.len() as u64, report.bytes);
    assert!(headers >= 6, "{headers} headers for 60 frames");
    assert!(report.status.points > 3000);
    println!(
        "{} points, {:.2} bytes per point",
        report.status.points,
        report.bytes_per_point().expect("points were sent")
    );
    // about 3.5 bytes for the coordinates (framing and headers included), one for the
    // point's uncertainty
    assert!(
        report.bytes_per_point().expect("points were sent") <= 5.0,
        "{}",
        report.bytes_per_point().expect("points were sent")
    );
}

#[test]
fn a_whole_scan_crosses_a_pseudo_terminal_pair() {
    use serialport::TTYPort;
    let (device_end, mut host_end) = TTYPort::pair().expect("a pseudo-terminal pair");
    let reader = std::thread::spawn(move || {
        let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
        let mut buf = [0u8; 4096];
        let (mut packets, mut done) = (0u32, None);
        host_end
            .set_timeout(std::time::Duration::from_secs(10))
            .unwrap();
        while done.is_none() {
            let n = match host_end.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => break,
                Err(e) => panic!("reading the host end: {e}"),
            };
            d.feed(&buf[..n], |m| match m {
                Ok(Message::Points(_)) => packets += 1,
                Ok(Message::Status(s)) if s.done => done = Some(s),
                _ => {}
            });
        }
        (packets, done, d.stats())
    });
    let rig = Rig::new(Scene::demo(320, 240)).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    // The link writes through a clone; this end stays open until the reader is done (a pty
    // master reads EIO once its slave is closed, even with data pending).
    let mut link = Link::spawn(
        Box::new(device_end.try_clone_native().unwrap()),
        64,
        MAX_ENCODED,
    );
    let report = run_scan(&mut source, &cal, options(12), &mut link, |_| {}, |_, _| {}).unwrap();
    link.finish().unwrap();
    let (packets, done, stats) = reader.join().unwrap();
    drop(device_end);
    let done = done.expect("the final status arrived");
    assert_eq!(stats.rejected(), 0, "{stats:?}");
    assert_eq!(packets, report.status.packets, "every packet decoded");
    assert_eq!(done.packets, report.status.packets);
    assert!(packets > 40, "{packets} packets");
}

/// A writer slower than the camera: 20 ms per write.
struct Slow(Vec<u8>, std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl std::io::Write for Slow {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        std::thread::sleep(std::time::Duration::from_millis(20));
        self.1.lock().unwrap().extend(self.0.drain(..));
        Ok(())
    }
}

#[test]
fn a_slow_link_drops_whole_frames_and_the_stream_stays_valid() {
    let rig = Rig::new(Scene::demo(320, 240)).unwrap();
    let cal = truth_calibration(&rig);
    // Pre-render so that the camera is faster than the link.
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    let out = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let mut link = Link::spawn(Box::new(Slow(Vec::new(), out.clone())), 2, MAX_ENCODED);
    let mut mine: BTreeMap<u32, Vec<[i32; 3]>> = BTreeMap::new();
    let report = run_scan(
        &mut source,
        &cal,
        options(13),
        &mut link,
        |_| {},
        |f, p| {
            mine.insert(f, p.to_vec());
        },
    )
    .unwrap();
    link.finish().unwrap();
    let bytes = out.lock().unwrap().clone();
    let (theirs, _, last, stats) = decode(&bytes);
    assert_eq!(stats.rejected(), 0);
    let dropped = report.status.skipped[scanner_wire::Skip::LinkFull as usize];
    println!(
        "{dropped} of {} packets dropped by the slow link",
        mine.len()
    );
    assert!(dropped > 0, "the link kept up: make it slower");
    assert_eq!(dropped as u64, report.dropped);
    // What arrived is exactly what the head computed for those frames.
    assert_eq!(theirs.len() + dropped as usize, mine.len());
    for (f, p) in &theirs {
        assert_eq!(Some(p), mine.get(f));
    }
    assert!(last.is_some_and(|s| s.done));
}

#[test]
fn a_camera_that_fails_mid_scan_ends_with_a_final_status() {
    struct Failing(RigSource, u32);
    impl scanner_device::source::FrameSource for Failing {
        fn describe(&self) -> String {
            "failing".into()
        }
        fn format(&self) -> PixelFormat {
            self.0.format()
        }
        fn size(&self) -> (usize, usize) {
            self.0.size()
        }
        fn reference(
            &mut self,
        ) -> Result<scanner_device::source::OwnedFrame, scanner_device::source::SourceError>
        {
            self.0.reference()
        }
        fn next_frame(
            &mut self,
        ) -> Result<Option<scanner_device::source::OwnedFrame>, scanner_device::source::SourceError>
        {
            self.1 += 1;
            if self.1 > 5 {
                return Err(scanner_device::source::SourceError::Camera {
                    device: "/dev/video0".into(),
                    what: "the camera stopped".into(),
                    source: Some(std::io::Error::from_raw_os_error(19)),
                });
            }
            self.0.next_frame()
        }
    }
    let rig = Rig::new(Scene::demo(320, 240)).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = Failing(RigSource::new(rig, PixelFormat::Gray8), 0);
    let out = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let mut link = Link::spawn(Box::new(Slow(Vec::new(), out.clone())), 64, MAX_ENCODED);
    let report = run_scan(&mut source, &cal, options(14), &mut link, |_| {}, |_, _| {}).unwrap();
    link.finish().unwrap();
    assert!(
        report
            .ended_early
            .as_ref()
            .is_some_and(|e| e.contains("No such device")),
        "{:?}",
        report.ended_early
    );
    let (_, _, last, stats) = decode(&out.lock().unwrap());
    assert_eq!(stats.rejected(), 0);
    let last = last.expect("a final status");
    assert!(last.done && last.ended == scanner_wire::EndReason::CameraLost && last.frames == 5);
}

#[test]
fn the_papers_construction_and_least_squares_agree_on_the_rig() {
    let mut counts = Vec::new();
    for method in [
        scanner_wire::PlaneMethod::LeastSquares,
        scanner_wire::PlaneMethod::Paper,
    ] {
        let rig = Rig::new(Scene::demo(320, 240)).unwrap();
        let cal = truth_calibration(&rig);
        let mut source = RigSource::new(rig, PixelFormat::Gray8);
        let mut link = Link::spawn(Box::new(std::io::sink()), 8, MAX_ENCODED);
        let mut opts = options(15);
        opts.head.method = method;
        let report = run_scan(&mut source, &cal, opts, &mut link, |_| {}, |_, _| {}).unwrap();
        link.finish().unwrap();
        println!(
            "{method:?}: {} packets, {} points, skipped {:?}",
            report.status.packets, report.status.points, report.status.skipped
        );
        counts.push(report.status.points as f64);
    }
    assert!(counts[1] > 0.9 * counts[0], "{counts:?}");
}

/// The skip reasons of the middle frames of a scene, with a head configured by `tweak`.
fn skips(scene: Scene, tweak: impl Fn(&mut HeadConfig)) -> Vec<Option<scanner_wire::Skip>> {
    let rig = Rig::new(scene).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    use scanner_device::source::FrameSource;
    let reference = source.reference().unwrap();
    let frames: Vec<_> = (0..40)
        .filter_map(|_| source.next_frame().unwrap())
        .skip(25)
        .take(6)
        .collect();
    let mut opts = options(16);
    tweak(&mut opts.head);
    let mut session = scanner_device::session::Session::new(&cal, reference, opts).unwrap();
    let mut link = Link::spawn(Box::new(std::io::sink()), 8, MAX_ENCODED);
    let out = frames
        .iter()
        .map(|f| session.frame(f, &mut link, |_, _| {}).unwrap())
        .collect();
    let s = session.status();
    link.finish().unwrap();
    // Every frame is counted: packets plus skips.
    assert_eq!(
        u64::from(s.packets) + s.skipped.iter().map(|&v| u64::from(v)).sum::<u64>(),
        6
    );
    out
}

#[test]
fn degenerate_frames_are_skipped_and_counted_by_reason() {
    use scanner_wire::Skip;
    let base = || Scene::demo(320, 240);
    // The normal case sends packets.
    assert!(skips(base(), |_| {}).iter().all(Option::is_none));
    // No laser at all.
    let mut s = base();
    s.laser.power = 0.0;
    assert!(skips(s, |_| {}).iter().all(|k| *k == Some(Skip::NoStripe)));
    // The stripe on one board plane only (the left third of the image).
    let one = skips(base(), |h| {
        h.stripe.roi = Some(scanner_core::stripe::Roi {
            x: 0,
            y: 0,
            width: 100,
            height: 240,
        });
    });
    assert!(
        one.iter().all(|k| *k == Some(Skip::OnePlaneOnly)),
        "{one:?}"
    );
    // A laser held at the camera: its plane passes through the camera centre.
    let mut s = base();
    s.laser.source = scanner_core::nalgebra::Point3::new(0.0, 0.0, 0.0);
    let through = skips(s, |_| {});
    assert!(
        through.iter().all(|k| matches!(
            k,
            Some(Skip::PlaneThroughCamera | Skip::NoStripe | Skip::PoorPlane)
        )),
        "{through:?}"
    );
    assert!(
        through.contains(&Some(Skip::PlaneThroughCamera)),
        "{through:?}"
    );
    // The whole frame saturated by ambient light.
    let mut s = base();
    s.ambient = 40.0;
    assert!(skips(s, |_| {}).iter().all(|k| *k == Some(Skip::NoStripe)));
}

#[test]
fn a_frame_of_the_wrong_size_or_format_is_skipped_not_sent() {
    use scanner_wire::Skip;
    let rig = Rig::new(Scene::demo(320, 240)).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    use scanner_device::source::FrameSource;
    let reference = source.reference().unwrap();
    let mut session =
        scanner_device::session::Session::new(&cal, reference.clone(), options(17)).unwrap();
    let mut link = Link::spawn(Box::new(std::io::sink()), 8, MAX_ENCODED);
    let mut bad = reference.clone();
    bad.width = 160; // the buffer no longer matches
    assert_eq!(
        session
            .frame(&bad, &mut link, |_, _| panic!("no points"))
            .unwrap(),
        Some(Skip::BadFrame)
    );
    let mut other = reference.clone();
    other.format = PixelFormat::Rgb24;
    other.data = vec![0; 320 * 240 * 3];
    assert_eq!(
        session
            .frame(&other, &mut link, |_, _| panic!("no points"))
            .unwrap(),
        Some(Skip::BadFrame)
    );
    assert_eq!(session.status().skipped[Skip::BadFrame as usize], 2);
    link.finish().unwrap();
}

/// A serial port that vanishes after `left` writes.
struct Vanishing(usize);

impl std::io::Write for Vanishing {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if self.0 == 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::BrokenPipe,
                "/dev/ttyACM0 was unplugged",
            ));
        }
        self.0 -= 1;
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_serial_port_that_vanishes_stops_the_scan_with_a_clear_error() {
    let rig = Rig::new(Scene::demo(320, 240)).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    let mut link = Link::spawn(Box::new(Vanishing(5)), 2, MAX_ENCODED);
    let e = run_scan(&mut source, &cal, options(18), &mut link, |_| {}, |_, _| {}).unwrap_err();
    assert!(
        scanner_device::error_chain(&e).contains("the link failed: /dev/ttyACM0 was unplugged"),
        "{e}"
    );
}
