//! The host's peak memory for the worst stream a head can send with default options: a valid
//! header of the largest image (4096 × 4096 pixels, the head's `MAX_LINES`), default 2-pixel
//! cells (the largest grid the host accepts, `MAX_CELLS`), and points filling every cell, so
//! that the mesh and the pictures are as large as they get; then every output is written.
//! Prints the peak of live heap bytes, counted by a global allocator:
//! `cargo run --release -p scanner-host --example peak_memory`.

use scanner_alloc::peak_bytes;
use scanner_core::geometry::{Board, Plane};
use scanner_core::nalgebra::{Point2, Vector3};
use scanner_core::{Camera, Distortion};
use scanner_host::collect::{CollectOptions, Collector};
use scanner_wire::{Header, MAX_ENCODED, Message, PlaneMethod, Points, points};

#[global_allocator]
static A: scanner_alloc::Peak = scanner_alloc::Peak;

const MB: f64 = 1024.0 * 1024.0;

fn main() {
    let side = scanner_core::config::MAX_LINES as u16;
    let f = 0.9 * f64::from(side);
    let c = (f64::from(side) - 1.0) / 2.0;
    let camera = Camera::new(f, f, c, c, Distortion::none()).expect("camera");
    let plane = |x: f64| Plane::new(Vector3::new(x, 0.0, -1.0).normalize(), 800.0).expect("plane");
    let board = Board::new(plane(0.7), plane(-0.7)).expect("board");
    let header = Header::new(
        1,
        (side, side),
        (&camera).into(),
        (&board).into(),
        true,
        PlaneMethod::LeastSquares,
    );
    let (mut scratch, mut out) = (vec![0u8; scanner_wire::MAX_MESSAGE], vec![0u8; MAX_ENCODED]);
    let mut xyz = vec![0u8; scanner_wire::MAX_MESSAGE];
    let mut c_ = Collector::new(CollectOptions::default(), None);
    let mut feed = |msg: &Message, c_: &mut Collector| {
        let n = scanner_wire::encode(msg, &mut scratch, &mut out).expect("encode");
        c_.feed(&out[..n]).expect("feed");
    };
    feed(&Message::Header(header), &mut c_);
    let before = peak_bytes();
    // One point at the centre of every 2×2-pixel cell, on a surface 700–900 mm away, in packets
    // of one image column pair each.
    let unit = f64::from(header.unit_um) / 1000.0;
    for (frame, col) in (0u32..).zip((0..side).step_by(2)) {
        let q: Vec<[i32; 3]> = (0..side)
            .step_by(2)
            .map(|row| {
                let px = Point2::new(f64::from(col) + 1.0, f64::from(row) + 1.0);
                let ray = camera.pixel_to_ray(&px).expect("ray");
                let z = 800.0 + 100.0 * (f64::from(col) / f64::from(side) - 0.5);
                let p = ray * (z / ray.z);
                [p.x, p.y, p.z].map(|v| (v / unit).round() as i32)
            })
            .collect();
        let n = points::encode(&q, &mut xyz).expect("points");
        let rgb = vec![200u8; 3 * q.len()];
        let sigma = vec![points::uncertainty_code(0.05); q.len()];
        let msg = Message::Points(Points {
            scan_id: 1,
            frame,
            time_us: u64::from(frame) * 1000,
            plane: [1.0, 0.0, 0.0, 0.0],
            count: q.len() as u32,
            xyz: &xyz[..n],
            rgb: &rgb,
            uncertainty: &sigma,
        });
        feed(&msg, &mut c_);
    }
    let grid = c_.grid().expect("grid");
    println!(
        "worst stream: a {side}×{side} header, default 2 px cells: a grid of {}×{} cells, {} filled",
        grid.cols,
        grid.rows,
        grid.filled()
    );
    let dir = tempfile::tempdir().expect("temporary folder");
    let summary =
        scanner_host::write_outputs(&c_, dir.path(), &scanner_host::OutputOptions::default())
            .expect("outputs");
    println!(
        "mesh: {} vertices, {} faces; peak heap {:.0} MB (after the header and the decoder: {:.0} MB; limit 1024 MB)",
        summary.vertices,
        summary.faces,
        peak_bytes() as f64 / MB,
        before as f64 / MB
    );
}
