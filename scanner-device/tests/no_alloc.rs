//! The head's steady state allocates nothing: after the first frames, extraction, the laser
//! plane, triangulation, packet encoding and handing the packet to the link thread run without a
//! single heap allocation (a counting allocator watches this thread) — and so does decoding a
//! camera's MJPEG frame into the frame buffer kept from the one before.

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_device::link::Link;
use scanner_device::session::truth_calibration;
use scanner_device::session::{Calibration, ScanOptions, Session};
use scanner_device::source::convert::{CameraFormat, Converter};
use scanner_device::source::{FrameSource, OwnedFrame, RigSource};
use scanner_rig::{Rig, Scene};
use scanner_wire::MAX_ENCODED;

#[global_allocator]
static GLOBAL: scanner_alloc::Counting = scanner_alloc::Counting;

/// Runs `n` frames through a session on `reference` (a colour laser when `colour`), each made
/// by `fill` into one kept frame buffer; the first 4 warm up (the link's buffers reach their
/// size), then every allocation on this thread is counted. Asserts none, and enough points.
fn assert_steady_state_allocates_nothing(
    what: &str,
    cal: &Calibration,
    reference: OwnedFrame,
    colour: bool,
    n: usize,
    mut fill: impl FnMut(usize, &mut OwnedFrame),
) {
    let mut head = HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns));
    head.colour = colour;
    let opts = ScanOptions {
        head,
        header_every: 3,
        status_every: 2,
        scan_id: 1,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    };
    let mut frame = reference.clone();
    let mut session = Session::new(cal, reference, opts).unwrap();
    let mut link = Link::spawn(Box::new(std::io::sink()), 4, MAX_ENCODED);
    for i in 0..4 {
        fill(i, &mut frame);
        session.frame(&frame, &mut link, |_, _| {}).unwrap();
    }
    let before = scanner_alloc::allocations();
    let mut points = 0;
    for i in 4..n {
        fill(i, &mut frame);
        session
            .frame(&frame, &mut link, |_, p| points += p.len())
            .unwrap();
        // Let the writer catch up, as a camera's frame period would.
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let allocations = scanner_alloc::allocations() - before;
    assert!(points > 500, "{what}: only {points} points");
    assert_eq!(
        allocations,
        0,
        "{what}: {allocations} allocations in {} frames",
        n - 4
    );
    link.finish().unwrap();
}

#[test]
fn the_steady_state_allocates_nothing() {
    for (format, colour) in [
        (PixelFormat::Gray8, false),
        (PixelFormat::Yuyv, true),
        (PixelFormat::Rgb24, true),
    ] {
        let rig = Rig::new(Scene::demo(640, 480)).unwrap();
        let cal = truth_calibration(&rig);
        let mut source = RigSource::new(rig, format);
        let reference = source.reference().unwrap();
        let frames: Vec<_> = (0..40)
            .filter_map(|_| source.next_frame().unwrap())
            .skip(28)
            .collect();
        // A copy into the kept buffer (same size: no allocation), as a camera fills it.
        assert_steady_state_allocates_nothing(
            &format!("{format:?}"),
            &cal,
            reference,
            colour,
            frames.len(),
            |i, f| f.data.clone_from(&frames[i].data),
        );
    }
    // The counter works.
    let before = scanner_alloc::allocations();
    std::hint::black_box(vec![0u8; 3]);
    assert!(scanner_alloc::allocations() > before);
}

/// Motion JPEG as a webcam sends it (4:2:2), decoded by the head's decoder into one kept frame
/// buffer, then the pipeline: no allocation per frame.
#[test]
fn mjpeg_frames_decode_and_run_without_allocating() {
    let (w, h) = (640u32, 480u32);
    let rig = Rig::new(Scene::demo(w, h)).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Rgb24);
    let jpeg = |f: &OwnedFrame| scanner_rig::mjpeg(&f.data, w, h, 90).unwrap();
    let reference_jpeg = jpeg(&source.reference().unwrap());
    let jpegs: Vec<Vec<u8>> = (0..40)
        .filter_map(|_| source.next_frame().unwrap())
        .skip(28)
        .map(|f| jpeg(&f))
        .collect();
    let mut converter = Converter::new();
    let mut decode = |data: &[u8], frame: &mut OwnedFrame| {
        converter
            .convert(
                CameraFormat::Mjpeg,
                data,
                w as usize,
                h as usize,
                0,
                PixelFormat::Yuyv,
                &mut frame.data,
            )
            .unwrap();
    };
    let mut reference = source.reference().unwrap();
    reference.format = PixelFormat::Yuyv;
    decode(&reference_jpeg, &mut reference);
    assert_steady_state_allocates_nothing("MJPEG", &cal, reference, true, jpegs.len(), |i, f| {
        decode(&jpegs[i], f)
    });
}
