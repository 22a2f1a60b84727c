//! The speed report (the paper's Table 2): `cargo run --release -p scanner-device --example
//! speed_report`. Frames per second of the light-intensity (LIM) and difference-image (DIM)
//! methods at the paper's four sizes — the extraction alone and the whole head pipeline
//! (extraction to the encoded packet handed to the link) — with points per second and bytes per
//! point on the wire, on pre-rendered virtual-rig frames (gray, one core).

use std::time::Instant;

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Extractor, Method, PixelFormat, StripeConfig};
use scanner_device::link::Link;
use scanner_device::session::truth_calibration;
use scanner_device::session::{ScanOptions, Session};
use scanner_device::source::{FrameSource, RigSource};
use scanner_rig::{Rig, Scene};
use scanner_wire::MAX_ENCODED;

/// The paper's frames/s (LIM, DIM) at each size.
const PAPER: [((u32, u32), (u32, u32)); 4] = [
    ((640, 480), (30, 30)),
    ((960, 720), (30, 24)),
    ((1280, 960), (24, 12)),
    ((1600, 1200), (16, 8)),
];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    println!(
        "| size | method | extraction alone | whole pipeline | points/frame | points/s | bytes/point | paper |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut ex = Box::new(Extractor::<4096>::new());
    for ((w, h), (paper_lim, paper_dim)) in PAPER {
        let rig = Rig::new(Scene::demo(w, h)).expect("rig");
        let cal = truth_calibration(&rig);
        let mut source = RigSource::new(rig, PixelFormat::Gray8);
        let reference = source.reference().expect("reference");
        let frames: Vec<_> = (0..60)
            .filter_map(|_| source.next_frame().expect("frame"))
            .step_by(4)
            .collect();
        for (method, paper) in [(Method::Lim, paper_lim), (Method::Dim, paper_dim)] {
            let cfg = StripeConfig::new(method, Axis::Columns);
            let r = reference.view().expect("view");
            let mut t_ex = Vec::new();
            for _ in 0..3 {
                for f in &frames {
                    let v = f.view().expect("view");
                    let t = Instant::now();
                    let _ =
                        std::hint::black_box(ex.extract(&v, Some(&r), &cfg).map(|e| e.threshold));
                    t_ex.push(t.elapsed().as_secs_f64());
                }
            }
            let opts = ScanOptions {
                head: HeadConfig::new(cfg),
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
            let mut link = Link::spawn(Box::new(std::io::sink()), 64, MAX_ENCODED);
            let (mut t_all, mut points) = (Vec::new(), 0usize);
            for _ in 0..3 {
                for f in &frames {
                    let t = Instant::now();
                    session
                        .frame(f, &mut link, |_, p| points += p.len())
                        .expect("frame");
                    t_all.push(t.elapsed().as_secs_f64());
                }
            }
            let s = session.status();
            link.finish().expect("link");
            let (fe, fa) = (1.0 / median(t_ex), 1.0 / median(t_all));
            let per_frame = points as f64 / (3 * frames.len()) as f64;
            println!(
                "| {w}×{h} | {method:?} | {fe:.0} frames/s | {fa:.0} frames/s | {per_frame:.0} | {:.0} | {:.2} | {paper} frames/s |",
                per_frame * fa,
                s.bytes as f64 / s.points.max(1) as f64
            );
        }
    }
    println!(
        "\nThe paper: LIM 30/30/24/16 and DIM 30/24/12/8 frames/s at these sizes, ≥ 4000 vertices/s. Points/frame are the demo sweep's object points (board points are not sent)."
    );
}
