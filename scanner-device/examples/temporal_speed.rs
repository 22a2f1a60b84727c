//! The speed of a shadow sweep read through time, one core, on a recorded sweep (default: the
//! shared real one, `../shared/data/real-shadow`, 200 frames at 1024×768): the frames decoded
//! once (JPEG to luma, timed apart), then the sweep read frame by frame and finished, timed.
//!
//! ```sh
//! cargo run --release -p scanner-device --example temporal_speed [-- FOLDER]
//! ```
//!
//! `FOLDER` holds `calibration.toml` and `frames/`. Prints the decoding and the sweep's
//! milliseconds a frame and the sweep's frames a second (its report's coverage beside them).

use std::path::PathBuf;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let dir = std::env::args().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real-shadow"),
        PathBuf::from,
    );
    let cal = scanner_calib::file::CalibrationFile::load(&dir.join("calibration.toml"))?;
    let camera = cal.camera()?;
    let board = cal
        .board()
        .ok_or_else(|| anyhow::anyhow!("{} has no board", dir.display()))??;
    let mut names: Vec<PathBuf> = std::fs::read_dir(dir.join("frames"))?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    names.sort();
    let t = Instant::now();
    let mut frames = Vec::new();
    let mut size = (0, 0);
    for name in &names {
        let img = image::open(name)?.to_luma8();
        size = (img.width() as usize, img.height() as usize);
        frames.push(img.into_raw());
    }
    let decode = t.elapsed().as_secs_f64();
    anyhow::ensure!(!frames.is_empty(), "no frames in {}", dir.display());
    // each pixel's lit and shadowed values (the scan takes the mean of its top and bottom
    // eighth; the extremes are as fast to read and enough for the timing)
    let n = frames[0].len();
    let (mut lit, mut dark) = (vec![0u8; n], vec![255u8; n]);
    for f in &frames {
        for ((l, d), &v) in lit.iter_mut().zip(&mut dark).zip(f) {
            *l = (*l).max(v);
            *d = (*d).min(v);
        }
    }
    let t = Instant::now();
    let mut sweep = scanner_device::temporal::TemporalSweep::new(camera, board, size, &lit, &dark)?;
    for f in &frames {
        sweep.frame(f)?;
    }
    let (_, report) = sweep.finish();
    let read = t.elapsed().as_secs_f64();
    let k = frames.len() as f64;
    println!(
        "{} frames {}x{}: decoding {:.1} ms/frame; the sweep through time {:.1} ms/frame ({:.0} frames/s, one core); object coverage {:.1} %",
        frames.len(),
        size.0,
        size.1,
        1000.0 * decode / k,
        1000.0 * read / k,
        k / read,
        100.0 * report.coverage
    );
    Ok(())
}
