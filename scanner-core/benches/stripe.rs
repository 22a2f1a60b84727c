//! Stripe extraction speed against the memory floor, measured in the same run.
//!
//! `cargo bench -p scanner-core --bench stripe` (one core; prints a Markdown table).
//!
//! For each size, method and format: the median time of a full extraction (rough pass +
//! threshold + subpixel centre of every column, centroid estimator) beside the median time of one
//! plain pass that sums every byte the extraction must read: the frame, the reference for DIM,
//! and the reference rows the LIM threshold samples. Frames rotate through a set larger than the
//! caches so both read from memory.
//!
//! The floor is noisy: over the very same bytes, the pass beside one row has taken twice the
//! time of the pass beside another. So the ratio is taken against a robust floor: the least
//! time per byte any floor pass of that frame size reached, times the bytes this row reads
//! (the row's own floor is printed beside it). Colour frames (YUYV, RGB) show a red stripe on a gray
//! ambient, read as a red laser (the default) and by brightness (`white`). The last row of each
//! size is a gray frame with a wide line: a saturated, flat-topped band about 40 px wide.

use std::hint::black_box;
use std::time::{Duration, Instant};

use scanner_core::stripe::{
    Axis, Extractor, Frame, LaserColour, Method, PixelFormat, SAMPLE_STEP, StripeConfig,
};

const SIZES: [(usize, usize); 4] = [(640, 480), (960, 720), (1280, 960), (1600, 1200)];
/// Frames in rotation: 12 × 3.8 MB (1600×1200 YUYV) ≈ 46 MB per set, frame and reference.
const ROTATION: usize = 12;

/// Full width at half maximum of the wide line's profile before it clips, pixels: with its
/// height, a flat-topped band about 40 px wide.
const WIDE_FWHM: f64 = 24.0;

/// `wide`: the stripe is a saturated, flat-topped band about 40 px wide instead of a line of
/// σ 1.5 px.
fn frames(
    w: usize,
    h: usize,
    format: PixelFormat,
    seed: u64,
    wide: bool,
) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let bpp = format.bytes_per_pixel();
    let mut x = seed | 1;
    let mut rnd = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut fs = Vec::new();
    let mut rs = Vec::new();
    for k in 0..ROTATION {
        let mut f = vec![0u8; w * h * bpp];
        let mut r = vec![0u8; w * h * bpp];
        for y in 0..h {
            for c in 0..w {
                let ambient = 30 + (rnd() % 5) as u8;
                let before = 30 + (rnd() % 5) as u8;
                let centre = h as f64 * (0.3 + 0.4 * c as f64 / w as f64) + k as f64;
                let u = y as f64 - centre;
                let stripe = if wide {
                    let s = WIDE_FWHM / 2.3548;
                    (900.0 * (-u * u / (2.0 * s * s)).exp()).min(255.0) as u8
                } else {
                    (160.0 * (-u * u / 4.5).exp()) as u8
                };
                let i = (y * w + c) * bpp;
                match format {
                    PixelFormat::Gray8 => {
                        f[i] = ambient.saturating_add(stripe);
                        r[i] = before;
                    }
                    PixelFormat::Rgb24 => {
                        f[i..i + 3].copy_from_slice(&[
                            ambient.saturating_add(stripe),
                            ambient,
                            ambient,
                        ]);
                        r[i..i + 3].copy_from_slice(&[before; 3]);
                    }
                    PixelFormat::Yuyv => {
                        // The red stripe in BT.601: Y + 0.299 R, V + 0.5 R (U − 0.169 R).
                        let s = f64::from(stripe);
                        f[i] = ambient.saturating_add((0.299 * s) as u8);
                        f[i + 1] = if c % 2 == 0 {
                            (128.0 - 0.169 * s) as u8
                        } else {
                            (128.0 + 0.5 * s) as u8
                        };
                        r[i] = before;
                        r[i + 1] = 128;
                    }
                }
            }
        }
        fs.push(f);
        rs.push(r);
    }
    (fs, rs)
}

/// One plain pass summing the bytes of `bufs` (the memory floor).
fn sum_pass(bufs: &[&[u8]]) -> u64 {
    bufs.iter()
        .map(|b| {
            b.chunks(1 << 12)
                .map(|c| c.iter().map(|&v| u32::from(v)).sum::<u32>() as u64)
                .sum::<u64>()
        })
        .sum()
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Median times of `a` and `b`, measured alternately (a, b, a, b, …) so that both see the same
/// state of a shared, noisy machine.
fn time_pair(
    iterations: usize,
    mut a: impl FnMut(usize),
    mut b: impl FnMut(usize),
) -> (Duration, Duration) {
    for i in 0..ROTATION {
        a(i); // warm-up
        b(i);
    }
    let (mut ta, mut tb) = (Vec::new(), Vec::new());
    for i in 0..iterations {
        let t = Instant::now();
        a(i % ROTATION);
        ta.push(t.elapsed());
        let t = Instant::now();
        b(i % ROTATION);
        tb.push(t.elapsed());
    }
    (median(ta), median(tb))
}

/// One measured row.
struct Row {
    method: Method,
    format: PixelFormat,
    laser: String,
    extraction: Duration,
    floor: Duration,
    bytes: usize,
}

/// The median width of the valid lines of a gray frame, pixels.
fn mean_width(
    ex: &mut Extractor<4096>,
    f: &[u8],
    r: &[u8],
    (w, h): (usize, usize),
    cfg: &StripeConfig,
) -> f32 {
    let f = Frame::packed(f, w, h, PixelFormat::Gray8).unwrap();
    let r = Frame::packed(r, w, h, PixelFormat::Gray8).unwrap();
    let res = ex.extract(&f, Some(&r), cfg).unwrap();
    let mut widths: Vec<f32> = res.valid().map(|(_, p)| p.width).collect();
    widths.sort_by(f32::total_cmp);
    widths.get(widths.len() / 2).copied().unwrap_or(0.0)
}

fn main() {
    let mut ex = Box::new(Extractor::<4096>::new());
    println!(
        "| size | method | format | laser | extraction | its floor pass | robust floor | ratio | frames/s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for &(w, h) in &SIZES {
        let iterations = (2_000_000_000 / (w * h * 40)).clamp(40, 400);
        let kinds = [
            (PixelFormat::Gray8, LaserColour::Red, false),
            (PixelFormat::Yuyv, LaserColour::Red, false),
            (PixelFormat::Yuyv, LaserColour::White, false),
            (PixelFormat::Rgb24, LaserColour::Red, false),
            (PixelFormat::Rgb24, LaserColour::White, false),
            (PixelFormat::Gray8, LaserColour::Red, true),
        ];
        let mut rows = Vec::new();
        for (format, colour, wide) in kinds {
            let (fs, rs) = frames(w, h, format, 7, wide);
            let row = w * format.bytes_per_pixel();
            for method in [Method::Lim, Method::Dim] {
                let cfg = StripeConfig {
                    colour,
                    ..StripeConfig::new(method, Axis::Columns)
                };
                let read = |i: usize| -> Vec<&[u8]> {
                    let mut bufs: Vec<&[u8]> = vec![&fs[i]];
                    match method {
                        Method::Dim => bufs.push(&rs[i]),
                        Method::Lim => bufs.extend(rs[i].chunks(row).step_by(SAMPLE_STEP)),
                    }
                    bufs
                };
                let bytes = read(0).iter().map(|b| b.len()).sum();
                let (t_ex, t_floor) = time_pair(
                    iterations,
                    |i| {
                        let f = Frame::packed(&fs[i], w, h, format).unwrap();
                        let r = Frame::packed(&rs[i], w, h, format).unwrap();
                        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
                        black_box(res.points.len());
                    },
                    |i| {
                        black_box(sum_pass(&read(i)));
                    },
                );
                let valid = {
                    let f = Frame::packed(&fs[0], w, h, format).unwrap();
                    let r = Frame::packed(&rs[0], w, h, format).unwrap();
                    ex.extract(&f, Some(&r), &cfg).unwrap().valid().count()
                };
                assert!(
                    valid * 10 >= w * 9,
                    "the bench frames must have a stripe in most columns ({valid}/{w})"
                );
                let laser = if wide {
                    format!(
                        "— (a band {:.0} px wide)",
                        mean_width(&mut ex, &fs[0], &rs[0], (w, h), &cfg)
                    )
                } else if format == PixelFormat::Gray8 {
                    "—".to_string()
                } else {
                    colour.name().to_string()
                };
                rows.push(Row {
                    method,
                    format,
                    laser,
                    extraction: t_ex,
                    floor: t_floor,
                    bytes,
                });
            }
        }
        // The least time per byte any floor pass of this size reached.
        let per_byte = rows
            .iter()
            .map(|r| r.floor.as_secs_f64() / r.bytes as f64)
            .fold(f64::INFINITY, f64::min);
        for r in rows {
            let robust = per_byte * r.bytes as f64;
            println!(
                "| {w}×{h} | {:?} | {:?} | {} | {:.3} ms | {:.3} ms | {:.3} ms | {:.2} | {:.0} |",
                r.method,
                r.format,
                r.laser,
                r.extraction.as_secs_f64() * 1e3,
                r.floor.as_secs_f64() * 1e3,
                robust * 1e3,
                r.extraction.as_secs_f64() / robust,
                1.0 / r.extraction.as_secs_f64()
            );
        }
    }
}
