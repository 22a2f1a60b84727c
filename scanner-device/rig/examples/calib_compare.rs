//! Intrinsics side by side with OpenCV: renders dot-grid shots on the virtual rig (1280×960,
//! sensor noise σ = 2 DN, the demo camera's barrel distortion), calibrates them with ours, and
//! writes everything `scripts/opencv-compare.py` needs to run OpenCV's `calibrateCamera` on the
//! same images (with OpenCV's own circle-grid detector, and on our detected dots).
//!
//! `cargo run --release -p scanner-rig --example calib_compare -- OUT_DIR [VIEWS]`

use std::fmt::Write as _;

use scanner_calib::{DotGrid, Target, intrinsics};
use scanner_core::calib::Free;
use scanner_rig::target::{Pattern, TargetPose};
use scanner_rig::{Rig, Scene};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = std::path::PathBuf::from(args.next().unwrap_or_else(|| "calib-compare".into()));
    let n: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(12);
    std::fs::create_dir_all(&out)?;
    let mut scene = Scene::demo(1280, 960);
    scene.sensor.read_noise = 2.0;
    scene.sensor.shot_noise = 0.0;
    let rig = Rig::new(scene)?;
    let grid = DotGrid::RIG;
    let pattern = Pattern::from(&grid);
    let chess = Pattern::Chessboard {
        cols: 10,
        rows: 8,
        square: 25.0,
    };
    let mut images = Vec::new();
    let mut chess_images = Vec::new();
    for i in 0..n {
        let pose = TargetPose::sweep(i, n);
        let img = rig.shot(&pattern, &pose, i as u64).image.to_gray_image();
        img.save(out.join(format!("grid-{i:02}.png")))?;
        images.push(img);
        let img = rig
            .shot(&chess, &pose, 100 + i as u64)
            .image
            .to_gray_image();
        img.save(out.join(format!("chess-{i:02}.png")))?;
        chess_images.push(img);
    }
    let t0 = std::time::Instant::now();
    let fit = intrinsics(&images, &Target::Dots(grid), Free::ALL)?;
    let secs = t0.elapsed().as_secs_f64();
    let cam = |c: &scanner_core::Camera<f64>| {
        let d = c.distortion();
        let p = c.principal_point();
        format!(
            "{} {} {} {} {} {} {} {} {}",
            c.fx(),
            c.fy(),
            p.x,
            p.y,
            d.k1,
            d.k2,
            d.p1,
            d.p2,
            d.k3
        )
    };
    std::fs::write(out.join("truth.txt"), cam(&rig.scene().camera) + "\n")?;
    std::fs::write(
        out.join("ours.txt"),
        format!("{} {} {secs}\n", cam(&fit.camera), fit.rms_px),
    )?;
    let mut csv = String::from("image,index,x,y\n");
    for (i, v) in fit.views.iter().enumerate() {
        if let Ok(v) = v {
            for (k, p) in &v.found {
                writeln!(csv, "{i},{k},{},{}", p.x, p.y)?;
            }
        }
    }
    std::fs::write(out.join("points.csv"), csv)?;
    let t0 = std::time::Instant::now();
    let cfit = intrinsics(
        &chess_images,
        &Target::Chessboard {
            cols: 10,
            rows: 8,
            square: 25.0,
        },
        Free::ALL,
    )?;
    let csecs = t0.elapsed().as_secs_f64();
    std::fs::write(
        out.join("ours-chess.txt"),
        format!("{} {} {csecs}\n", cam(&cfit.camera), cfit.rms_px),
    )?;
    println!(
        "chessboards: ours rms {:.4} px in {csecs:.2} s",
        cfit.rms_px
    );
    println!(
        "{n} views: ours rms {:.4} px in {secs:.2} s; wrote {}",
        fit.rms_px,
        out.display()
    );
    Ok(())
}
