//! Runs one extraction configuration in a loop over bench-like frames, for a profiler:
//! `perf record ./target/release/examples/profile_stripe`.
use scanner_core::stripe::{Axis, Extractor, Frame, Method, PixelFormat, StripeConfig};

fn main() {
    let (w, h) = (1600usize, 1200usize);
    let mut x = 7u64;
    let mut rnd = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut f = vec![0u8; w * h];
    let mut r = vec![0u8; w * h];
    for y in 0..h {
        for c in 0..w {
            let u = y as f64 - h as f64 * (0.3 + 0.4 * c as f64 / w as f64);
            f[y * w + c] =
                (30 + (rnd() % 5) as u8).saturating_add((160.0 * (-u * u / 4.5).exp()) as u8);
            r[y * w + c] = 30 + (rnd() % 5) as u8;
        }
    }
    let mut ex = Box::new(Extractor::<4096>::new());
    let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    let fr = Frame::packed(&f, w, h, PixelFormat::Gray8).unwrap();
    let rf = Frame::packed(&r, w, h, PixelFormat::Gray8).unwrap();
    let mut n = 0;
    let t = std::time::Instant::now();
    for _ in 0..1000 {
        n += ex.extract(&fr, Some(&rf), &cfg).unwrap().valid().count();
    }
    println!(
        "{n} valid, {:.3} ms per frame (in cache)",
        t.elapsed().as_secs_f64()
    );
}
