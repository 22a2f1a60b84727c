//! The head's whole per-frame pipeline — extraction, board points, laser plane, triangulation,
//! packet encoding, hand-over to the link thread — on pre-rendered virtual-rig frames (rendering
//! excluded). `cargo bench -p scanner-device --bench pipeline` (one core for the pipeline; the
//! link thread writes to a sink). Target (issue 6): ≥ 300 frames/s at 1600×1200. The MJPEG row
//! decodes each frame from its JPEG (4:2:2, quality 90, what most USB webcams send at
//! 1600×1200) to YUYV first, inside the timed part, by the head's own decoder kept across
//! frames: the head's real cost for such a camera.

use std::time::Instant;

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_device::link::Link;
use scanner_device::session::truth_calibration;
use scanner_device::session::{ScanOptions, Session};
use scanner_device::source::convert::{CameraFormat, Converter};
use scanner_device::source::{FrameSource, OwnedFrame, RigSource};
use scanner_rig::{Rig, Scene};
use scanner_wire::MAX_ENCODED;
use scanner_wire::PlaneMethod;

fn main() {
    println!(
        "| frames | format | method | laser plane | points/frame | median ms/frame | frames/s | bytes/point |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let (w, h) = (1600u32, 1200u32);
    let rig = Rig::new(Scene::demo(w, h)).expect("demo scene");
    let cal = truth_calibration(&rig);
    // (format, from MJPEG, method, plane)
    let cases = [
        (
            PixelFormat::Gray8,
            false,
            Method::Dim,
            PlaneMethod::LeastSquares,
        ),
        (
            PixelFormat::Yuyv,
            false,
            Method::Dim,
            PlaneMethod::LeastSquares,
        ),
        (
            PixelFormat::Yuyv,
            true,
            Method::Dim,
            PlaneMethod::LeastSquares,
        ),
        (
            PixelFormat::Gray8,
            false,
            Method::Lim,
            PlaneMethod::LeastSquares,
        ),
        (PixelFormat::Gray8, false, Method::Dim, PlaneMethod::Paper),
    ];
    let mut rendered: Vec<(PixelFormat, _, Vec<_>)> = Vec::new();
    for (format, ..) in cases {
        if rendered.iter().any(|(f, ..)| *f == format) {
            continue;
        }
        let mut source = RigSource::new(rig.clone(), format);
        let reference = source.reference().expect("reference");
        // Frames across the sweep (every third), rendered once.
        let frames: Vec<_> = (0..60)
            .filter_map(|_| source.next_frame().expect("frame"))
            .step_by(3)
            .collect();
        rendered.push((format, reference, frames));
    }
    // The RGB renders as a webcam's MJPEG, for the MJPEG row.
    let jpegs: Vec<Vec<u8>> = {
        let mut source = RigSource::new(rig.clone(), PixelFormat::Rgb24);
        std::iter::once(source.reference().expect("reference"))
            .chain(
                (0..60)
                    .filter_map(|_| source.next_frame().expect("frame"))
                    .step_by(3),
            )
            .map(|f| scanner_rig::mjpeg(&f.data, w, h, 90).expect("jpeg"))
            .collect()
    };
    let mut converter = Converter::new();
    let mut decode = |jpeg: &[u8], out: &mut OwnedFrame| {
        converter
            .convert(
                CameraFormat::Mjpeg,
                jpeg,
                w as usize,
                h as usize,
                2 * w as usize,
                PixelFormat::Yuyv,
                &mut out.data,
            )
            .expect("decode");
    };
    for (format, mjpeg, method, plane) in cases {
        let (_, reference, frames) = rendered
            .iter()
            .find(|(f, ..)| *f == format)
            .expect("rendered");
        let mut reference = reference.clone();
        if mjpeg {
            decode(&jpegs[0], &mut reference);
        }
        let mut head = HeadConfig::new(StripeConfig::new(method, Axis::Columns));
        head.method = plane;
        let opts = ScanOptions {
            head,
            header_every: 30,
            status_every: 30,
            scan_id: 1,
            find_axis: false,
            find_colour: false,
            disc: None,
            fixed: None,
            markers: None,
            shadow: false,
            temporal: false,
        };
        let mut session = Session::new(&cal, reference.clone(), opts).expect("session");
        let mut decoded = reference.clone();
        let mut link = Link::spawn(Box::new(std::io::sink()), 64, MAX_ENCODED);
        let mut times = Vec::new();
        let mut points = 0usize;
        for round in 0..5 {
            for (i, f) in frames.iter().enumerate() {
                let t = Instant::now();
                let f = if mjpeg {
                    decode(&jpegs[i + 1], &mut decoded);
                    &decoded
                } else {
                    f
                };
                session
                    .frame(f, &mut link, |_, p| points += p.len())
                    .expect("frame");
                if round > 0 {
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let s = session.status();
        link.finish().expect("link");
        println!(
            "| {w}×{h} | {}{format:?} | {method:?} | {plane:?} | {:.0} | {median:.3} | {:.0} | {:.2} |",
            if mjpeg { "MJPEG → " } else { "" },
            points as f64 / (5 * frames.len()) as f64,
            1e3 / median,
            s.bytes as f64 / s.points.max(1) as f64
        );
    }
}
