//! Host speed: decoding a recorded stream (bytes/s through the decoder and point decoding) and
//! inserting points into the grid (points/s). `cargo bench -p scanner-host --bench host`
//! (one core). Targets (issue 7): decode ≥ 50 MB/s, grid insertion ≥ 5 million points/s.

use std::hint::black_box;
use std::time::Instant;

use scanner_core::nalgebra::Point3;
use scanner_core::{Camera, Distortion};
use scanner_host::collect::{CollectOptions, Collector};
use scanner_host::grid::{Cell, Grid};
use scanner_wire::{Decoder, MAX_ENCODED, Message, Points, points};

/// A synthetic stream: `frames` packets of 1600 stripe points over a sphere-like bump.
fn stream(frames: u32) -> Vec<u8> {
    let camera = scanner_core::Camera::new(
        1400.0,
        1400.0,
        799.5,
        599.5,
        scanner_core::Distortion {
            k1: -0.06,
            k2: 0.02,
            ..scanner_core::Distortion::none()
        },
    )
    .unwrap();
    let plane = |x: f64| {
        scanner_core::geometry::Plane::new(
            scanner_core::nalgebra::Vector3::new(x, 0.0, -0.707),
            565.7,
        )
        .unwrap()
    };
    let board = scanner_core::geometry::Board::new(plane(0.707), plane(-0.707)).unwrap();
    let header = scanner_wire::Header::new(
        1,
        (1600, 1200),
        (&camera).into(),
        (&board).into(),
        false,
        scanner_wire::PlaneMethod::LeastSquares,
    );
    let mut scratch = vec![0u8; scanner_wire::MAX_MESSAGE];
    let mut out = vec![0u8; MAX_ENCODED];
    let mut s = Vec::new();
    let n = scanner_wire::encode(&Message::Header(header), &mut scratch, &mut out).unwrap();
    s.extend_from_slice(&out[..n]);
    let mut xyz = vec![0u8; 15 * 1600];
    for f in 0..frames {
        let y = -300.0 + 600.0 * f as f32 / frames as f32;
        let pts: Vec<[i32; 3]> = (0..1600)
            .map(|c| {
                let x = (c as f32 - 800.0) * 0.55;
                let z = 700.0 - 100.0 * (-(x * x + y * y) / 20000.0).exp();
                [x, y, z].map(|v| points::quantise(v).unwrap())
            })
            .collect();
        let len = points::encode(&pts, &mut xyz).unwrap();
        let sigma = [points::uncertainty_code(0.05); 1600];
        let msg = Message::Points(Points {
            scan_id: 1,
            frame: f,
            time_us: u64::from(f) * 33_000,
            plane: [0.0, 1.0, 0.0, -y],
            count: 1600,
            xyz: &xyz[..len],
            rgb: &[],
            uncertainty: &sigma,
        });
        let n = scanner_wire::encode(&msg, &mut scratch, &mut out).unwrap();
        s.extend_from_slice(&out[..n]);
    }
    s
}

fn main() {
    let bytes = stream(600);
    // Decoding alone: frames and their points.
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
        let mut sum = 0i64;
        d.feed(&bytes, |m| {
            if let Ok(Message::Points(p)) = m {
                points::decode(p.xyz, p.count as usize, |q| sum += i64::from(q[2])).unwrap();
            }
        });
        black_box(sum);
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!("| stage | throughput | target |");
    println!("|---|---|---|");
    println!(
        "| decode (COBS, CRC, postcard, points) | {:.0} MB/s ({:.1} M points/s) | ≥ 50 MB/s |",
        bytes.len() as f64 / best / 1e6,
        600.0 * 1600.0 / best / 1e6
    );
    // Grid insertion alone (2-px cells, the projection included).
    let cam = Camera::new(
        1400.0,
        1400.0,
        799.5,
        599.5,
        Distortion {
            k1: -0.06,
            k2: 0.02,
            ..Distortion::none()
        },
    )
    .unwrap();
    let pts: Vec<Point3<f32>> = (0..2_000_000)
        .map(|i| {
            let (c, r) = ((i % 1600) as f32, (i / 1600 % 1200) as f32);
            let z = 700.0;
            Point3::new((c - 799.5) * z / 1400.0, (r - 599.5) * z / 1400.0, z)
        })
        .collect();
    for cell in [Cell::Pixels(2.0), Cell::Mm(0.5)] {
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let mut g = Grid::new(cam, 1600, 1200, cell, 1200.0, 2.0).unwrap();
            let t = Instant::now();
            for p in &pts {
                g.insert(p, None, Some(0.05));
            }
            best = best.min(t.elapsed().as_secs_f64());
            black_box(g.filled());
        }
        println!(
            "| grid insertion, {cell:?} cells | {:.1} M points/s | ≥ 5 M points/s |",
            pts.len() as f64 / best / 1e6
        );
    }
    // Everything the host does per byte: decode + grid.
    let t = Instant::now();
    let mut c = Collector::new(CollectOptions::default(), None);
    for chunk in bytes.chunks(4096) {
        c.feed(chunk).unwrap();
    }
    let s = t.elapsed().as_secs_f64();
    println!(
        "| decode + grid (collector) | {:.0} MB/s ({:.1} M points/s) | |",
        bytes.len() as f64 / s / 1e6,
        c.counts().points as f64 / s / 1e6
    );
}
