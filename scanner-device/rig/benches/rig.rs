//! Virtual rig speed: one-off set-up and per-frame rendering of the demo scene.
//!
//! `cargo bench -p scanner-rig --bench rig` (one core; prints a Markdown table). Targets
//! (issue 4): a 640×480 frame in ≤ 20 ms, a 1600×1200 frame in ≤ 150 ms.

use std::hint::black_box;
use std::time::Instant;

use scanner_core::stripe::PixelFormat;
use scanner_rig::{Rig, Scene};

fn main() {
    println!("| size | set-up (once) | laser frame, median | reference | target |");
    println!("|---|---|---|---|---|");
    for (w, h, target) in [(640u32, 480u32, 20.0), (1600, 1200, 150.0)] {
        let t = Instant::now();
        let rig = Rig::new(Scene::demo(w, h)).expect("demo scene");
        let setup = t.elapsed().as_secs_f64() * 1e3;
        let frames = rig.scene().laser.frames;
        let mut times: Vec<f64> = (0..frames.min(15))
            .map(|i| {
                let t = Instant::now();
                let f = rig.frame(i * frames / 15).expect("frame");
                black_box(f.to_format(PixelFormat::Yuyv));
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(f64::total_cmp);
        let t = Instant::now();
        black_box(rig.reference());
        let reference = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "| {w}×{h} | {setup:.0} ms | {:.1} ms | {reference:.1} ms | ≤ {target} ms |",
            times[times.len() / 2]
        );
    }
}
