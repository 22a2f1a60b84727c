//! Prints how far the f32 per-frame path (pixel → ray → laser plane) lands from exact data,
//! against the angle under which the camera sees the laser plane (README, "Precision").
//!
//! `cargo run --release -p scanner-core --example f32_precision`

#[path = "../tests/support/mod.rs"]
mod support;

use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::TestRunner;
use scanner_core::geometry::{Board, Limits, Plane, triangulate};
use support::{Scene, params, rel32};

fn main() {
    let mut runner = TestRunner::deterministic();
    let strategy = params(true);
    let mut rows = Vec::new();
    for _ in 0..5000 {
        let s = Scene::new(&strategy.new_tree(&mut runner).unwrap().current());
        if !s.well_viewed() {
            continue;
        }
        let board = Board::new(s.left.plane().unwrap(), s.right.plane().unwrap()).unwrap();
        let laser = Plane::new(s.laser_normal, s.laser_d).unwrap();
        let (cam, b, l) = (
            s.camera.cast::<f32>(),
            board.cast::<f32>(),
            laser.cast::<f32>(),
        );
        for q in s.object_points(&[0.1, 0.3, 0.45]) {
            let px = s.camera.project(&q).unwrap().cast::<f32>();
            if let Ok((got, _)) = triangulate::triangulate(&cam, &b, &l, &px, &Limits::default()) {
                rows.push((s.laser_d / q.coords.norm(), rel32(&got, &q)));
            }
        }
    }
    println!(
        "f32 triangulation vs exact data, random cameras with distortion, boards 0.2-4 m at 60-150°"
    );
    println!("| sin(view angle) ≥ | points | worst relative error | worst error × sin |");
    println!("|---|---|---|---|");
    for lo in [0.1, 0.2, 0.5] {
        let sel: Vec<_> = rows.iter().filter(|r| r.0 >= lo).collect();
        let worst = sel.iter().map(|r| r.1).fold(0.0, f64::max);
        let scaled = sel.iter().map(|r| r.1 * r.0).fold(0.0, f64::max);
        println!("| {lo} | {} | {worst:.2e} | {scaled:.2e} |", sel.len());
    }
}
