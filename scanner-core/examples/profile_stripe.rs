//! Runs one extraction configuration in a loop over a bench-like 1600×1200 frame (a red stripe
//! on a gray ambient), for a profiler or an instruction count:
//! `profile_stripe [gray|yuyv|rgb] [ITERATIONS]` (gray, 1000), e.g.
//! `valgrind --tool=callgrind ./target/release/examples/profile_stripe rgb 20`; the difference
//! of two counts (20 and 40 iterations) over 20 is the cost of one extraction.
use scanner_core::stripe::{Axis, Extractor, Frame, Method, PixelFormat, StripeConfig};

fn main() {
    let mut args = std::env::args().skip(1);
    let format = match args.next().as_deref() {
        None | Some("gray") => PixelFormat::Gray8,
        Some("yuyv") => PixelFormat::Yuyv,
        Some("rgb") => PixelFormat::Rgb24,
        Some(other) => {
            eprintln!("profile_stripe: unknown format {other:?} (gray, yuyv, rgb)");
            std::process::exit(2);
        }
    };
    let iterations: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(1000);
    let (w, h) = (1600usize, 1200usize);
    let bpp = format.bytes_per_pixel();
    let mut x = 7u64;
    let mut rnd = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut f = vec![0u8; w * h * bpp];
    let mut r = vec![0u8; w * h * bpp];
    for y in 0..h {
        for c in 0..w {
            let u = y as f64 - h as f64 * (0.3 + 0.4 * c as f64 / w as f64);
            let stripe = (160.0 * (-u * u / 4.5).exp()) as u8;
            let (a, b) = (30 + (rnd() % 5) as u8, 30 + (rnd() % 5) as u8);
            let i = (y * w + c) * bpp;
            match format {
                PixelFormat::Gray8 => {
                    f[i] = a.saturating_add(stripe);
                    r[i] = b;
                }
                PixelFormat::Yuyv => {
                    let s = f64::from(stripe);
                    f[i] = a.saturating_add((0.299 * s) as u8);
                    f[i + 1] = if c % 2 == 0 {
                        (128.0 - 0.169 * s) as u8
                    } else {
                        (128.0 + 0.5 * s) as u8
                    };
                    (r[i], r[i + 1]) = (b, 128);
                }
                PixelFormat::Rgb24 => {
                    f[i..i + 3].copy_from_slice(&[a.saturating_add(stripe), a, a]);
                    r[i..i + 3].copy_from_slice(&[b; 3]);
                }
            }
        }
    }
    let mut ex = Box::new(Extractor::<4096>::new());
    let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    let fr = Frame::packed(&f, w, h, format).expect("frame");
    let rf = Frame::packed(&r, w, h, format).expect("reference");
    let mut n = 0;
    let t = std::time::Instant::now();
    for _ in 0..iterations {
        n += ex
            .extract(&fr, Some(&rf), &cfg)
            .expect("extract")
            .valid()
            .count();
    }
    println!(
        "{format:?}: {n} valid over {iterations} extractions, {:.3} ms each (frame in cache)",
        t.elapsed().as_secs_f64() * 1e3 / iterations.max(1) as f64
    );
}
