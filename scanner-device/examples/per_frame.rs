//! The head's per-frame path, alone, for counting its instructions (`scripts/estimate-pi` runs it
//! under qemu's execution log for aarch64 and x86-64, and under callgrind on x86-64).
//!
//! ```text
//! per_frame prepare DIR WIDTHxHEIGHT   render the demo rig's reference and 8 laser frames into
//!                                      DIR as raw YUYV and as JPEG (4:2:2, quality 90, what a
//!                                      webcam's MJPEG looks like), with the rig's true calibration
//! per_frame run DIR yuyv|mjpeg N       read them, then run N frames through the head: MJPEG
//!                                      decoded to YUYV first (the reference too), by one kept
//!                                      decoder, as the camera source does; prints
//!                                      the median milliseconds per frame
//! ```
//!
//! Everything before the first frame is the same for every `N`, so the difference of two counts
//! over the difference of their `N` is the cost of one frame.

use std::path::Path;
use std::time::Instant;

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_device::link::Link;
use scanner_device::session::{Calibration, ScanOptions, Session};
use scanner_device::source::convert::{CameraFormat, Converter};
use scanner_device::source::{FrameSource, OwnedFrame, RigSource};
use scanner_wire::MAX_ENCODED;

/// Laser frames prepared.
const FRAMES: usize = 8;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let words: Vec<&str> = args.iter().skip(1).map(String::as_str).collect();
    let result = match words.as_slice() {
        ["prepare", dir, size] => prepare(Path::new(dir), size),
        ["run", dir, format, n] => match n.parse::<usize>() {
            Ok(n) => run(Path::new(dir), format, n),
            Err(_) => Err(anyhow::anyhow!("{n:?}: a number of frames")),
        },
        _ => Err(anyhow::anyhow!(
            "usage: per_frame prepare DIR WIDTHxHEIGHT | per_frame run DIR yuyv|mjpeg N"
        )),
    };
    if let Err(e) = result {
        eprintln!("per_frame: {e}");
        std::process::exit(2);
    }
}

fn prepare(dir: &Path, size: &str) -> anyhow::Result<()> {
    let (w, h) = scanner_device::source::parse_size(size)?;
    let scene = scanner_rig::Scene::demo(w, h);
    let rig = scanner_rig::Rig::new(scene)?;
    std::fs::create_dir_all(dir)?;
    rig.truth_calibration()
        .save(&dir.join("calibration.toml"))?;
    let mut yuyv = RigSource::new(rig.clone(), PixelFormat::Yuyv);
    let mut rgb = RigSource::new(rig.clone(), PixelFormat::Rgb24);
    let frames = rig.scene().laser.frames;
    // The reference, then frames from the middle of the sweep (where the line crosses objects).
    let mut picked: Vec<(String, OwnedFrame, OwnedFrame)> =
        vec![("reference".into(), yuyv.reference()?, rgb.reference()?)];
    for i in 0..frames {
        let (Some(y), Some(c)) = (yuyv.next_frame()?, rgb.next_frame()?) else {
            break;
        };
        if i >= frames / 3 && picked.len() <= FRAMES {
            picked.push((format!("frame-{}", picked.len() - 1), y, c));
        }
    }
    for (name, y, c) in &picked {
        std::fs::write(dir.join(format!("{name}.yuyv")), &y.data)?;
        let jpeg = scanner_rig::mjpeg(&c.data, w, h, 90)?;
        std::fs::write(dir.join(format!("{name}.jpg")), jpeg)?;
    }
    std::fs::write(dir.join("size"), format!("{w}x{h}"))?;
    println!(
        "prepared {} frames of {w}×{h} in {}",
        picked.len() - 1,
        dir.display()
    );
    Ok(())
}

fn run(dir: &Path, format: &str, n: usize) -> anyhow::Result<()> {
    let mjpeg = match format {
        "yuyv" => false,
        "mjpeg" => true,
        other => return Err(anyhow::anyhow!("{other:?}: yuyv or mjpeg")),
    };
    let size = std::fs::read_to_string(dir.join("size"))?;
    let (w, h) = scanner_device::source::parse_size(size.trim())?;
    let (w, h) = (w as usize, h as usize);
    let file = scanner_calib::file::CalibrationFile::load(&dir.join("calibration.toml"))?;
    let cal = Calibration {
        camera: file.camera()?,
        board: file
            .board()
            .ok_or_else(|| anyhow::anyhow!("no board in the calibration"))??,
        size: (w as u32, h as u32),
        spread: None,
        speckle_px: None,
    };
    let read = |name: &str| std::fs::read(dir.join(name));
    let frame = |data: Vec<u8>| OwnedFrame {
        data,
        width: w,
        height: h,
        format: PixelFormat::Yuyv,
        index: 0,
        time_us: Some(0),
    };
    let mut converter = Converter::new();
    let mut decode = |jpeg: &[u8], out: &mut OwnedFrame| {
        converter.convert(
            CameraFormat::Mjpeg,
            jpeg,
            w,
            h,
            2 * w,
            PixelFormat::Yuyv,
            &mut out.data,
        )
    };
    let mut reference = frame(read("reference.yuyv")?);
    if mjpeg {
        decode(&read("reference.jpg")?, &mut reference)?;
    }
    let raw: Vec<OwnedFrame> = (0..FRAMES)
        .map(|i| read(&format!("frame-{i}.yuyv")).map(frame))
        .collect::<Result<_, _>>()?;
    let jpegs: Vec<Vec<u8>> = (0..FRAMES)
        .map(|i| read(&format!("frame-{i}.jpg")))
        .collect::<Result<_, _>>()?;
    let opts = ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
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
    let mut session = Session::new(&cal, reference.clone(), opts)?;
    let mut link = Link::spawn(Box::new(std::io::sink()), 64, MAX_ENCODED);
    let mut decoded = reference.clone();
    let (mut times, mut points) = (Vec::with_capacity(n), 0usize);
    for i in 0..n {
        let t = Instant::now();
        let k = i % FRAMES;
        let f = if mjpeg {
            decode(&jpegs[k], &mut decoded)?;
            &decoded
        } else {
            &raw[k]
        };
        session.frame(f, &mut link, |_, p| points += p.len())?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    link.finish()?;
    times.sort_by(f64::total_cmp);
    let median = times.get(times.len() / 2).copied().unwrap_or(0.0);
    println!(
        "{{\"frames\": {n}, \"format\": \"{format}\", \"width\": {w}, \"height\": {h}, \"median_ms\": {median:.4}, \"points_per_frame\": {:.1}}}",
        points as f64 / n.max(1) as f64
    );
    Ok(())
}
