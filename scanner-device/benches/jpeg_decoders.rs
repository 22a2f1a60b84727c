//! The head's JPEG decoder against the alternatives, on what a webcam sends: 1600×1200 rig
//! frames as 4:2:2 MJPEG (quality 90). Per frame, one core, median of 20 frames × 5 rounds,
//! decode only, and the heap allocations a frame makes after the first (a counting allocator):
//! - `scanner_jpeg` into YUYV (the head's path: into the frame buffer it keeps);
//! - `zune-jpeg` (what the `image` crate uses; AVX2 and NEON kernels) asked for YCbCr, its
//!   cheapest output, then packed to YUYV;
//! - the `image` crate to RGB, then to YUYV (the head's path before its own decoder).
//!
//! `cargo bench -p scanner-device --bench jpeg_decoders` (pin it: `taskset -c 1`). Prints a
//! table and, last, one JSON line.

use std::time::Instant;

use scanner_core::stripe::PixelFormat;
use scanner_device::source::convert::{CameraFormat, Converter, convert};
use scanner_device::source::{FrameSource, RigSource};
use scanner_rig::{Rig, Scene};
use zune_core::bytestream::ZCursor;
use zune_core::colorspace::ColorSpace;
use zune_core::options::DecoderOptions;

#[global_allocator]
static GLOBAL: scanner_alloc::Counting = scanner_alloc::Counting;

fn main() {
    let (w, h) = (1600usize, 1200usize);
    let rig = Rig::new(Scene::demo(w as u32, h as u32)).expect("demo scene");
    let mut source = RigSource::new(rig, PixelFormat::Rgb24);
    let jpegs: Vec<Vec<u8>> = (0..60)
        .filter_map(|_| source.next_frame().expect("frame"))
        .step_by(3)
        .map(|f| scanner_rig::mjpeg(&f.data, w as u32, h as u32, 90).expect("jpeg"))
        .collect();
    let mut converter = Converter::new();
    let (mut ours, mut zune, mut via_rgb) = (Vec::new(), Vec::new(), Vec::new());
    let mut ycbcr = vec![0u8; 3 * w * h];
    type Decode<'a> = Box<dyn FnMut(&[u8]) + 'a>;
    let cases: Vec<(&str, Decode)> = vec![
        (
            "scanner_jpeg → YUYV",
            Box::new(|j: &[u8]| {
                converter
                    .convert(
                        CameraFormat::Mjpeg,
                        j,
                        w,
                        h,
                        0,
                        PixelFormat::Yuyv,
                        &mut ours,
                    )
                    .expect("decode");
            }),
        ),
        (
            "zune-jpeg → YCbCr → YUYV",
            Box::new(|j: &[u8]| {
                let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::YCbCr);
                let mut d = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(j), options);
                d.decode_into(&mut ycbcr).expect("zune");
                zune.clear();
                for p in ycbcr.chunks_exact(6) {
                    zune.extend([p[0], p[1], p[3], p[2]]);
                }
            }),
        ),
        (
            "image → RGB → YUYV",
            Box::new(|j: &[u8]| {
                let rgb = image::load_from_memory(j).expect("image").to_rgb8();
                convert(
                    CameraFormat::Rgb3,
                    rgb.as_raw(),
                    w,
                    h,
                    3 * w,
                    PixelFormat::Yuyv,
                    &mut via_rgb,
                )
                .expect("convert");
            }),
        ),
    ];
    println!("| decoder (1600×1200 4:2:2 MJPEG) | median ms/frame | allocations/frame |");
    println!("|---|---|---|");
    let mut json = Vec::new();
    for (name, mut decode) in cases {
        decode(&jpegs[0]);
        let mut times = Vec::with_capacity(5 * jpegs.len());
        let before = scanner_alloc::allocations();
        for _ in 0..5 {
            for j in &jpegs {
                let t = Instant::now();
                decode(j);
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        let allocs = (scanner_alloc::allocations() - before) as f64 / times.len() as f64;
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        println!("| {name} | {median:.3} | {allocs:.1} |");
        json.push(format!(
            "{{\"decoder\": \"{name}\", \"median_ms\": {median:.4}, \"allocations_per_frame\": {allocs:.2}}}"
        ));
    }
    println!("[{}]", json.join(", "));
}
