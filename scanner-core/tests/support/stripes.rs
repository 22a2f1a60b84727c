//! Synthetic stripe frames with known subpixel centres, and the accuracy bench over them.
//!
//! A frame is `WIDTH` columns by `HEIGHT` rows, 8-bit gray. The stripe runs roughly horizontally
//! (centre row `c(x) = 31.5 + slope·x + phase`, so every column has another subpixel phase); its
//! profile is a Gaussian of standard deviation `sigma` integrated over each pixel with peak
//! `amplitude` DN, on an ambient gradient of 25–70 DN; then sensor noise (Gaussian, `noise` DN),
//! rounding and clipping at 0 and 255. The reference frame has the same ambient light and its own
//! noise.

use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};
use scanner_core::stripe::{
    Axis, Estimator, Extractor, Frame, LineStatus, Method, PixelFormat, StripeConfig,
};

pub const WIDTH: usize = 200;
pub const HEIGHT: usize = 64;

/// One synthetic frame pair.
pub struct Synthetic {
    pub frame: Vec<u8>,
    pub reference: Vec<u8>,
    /// True centre row of each column.
    pub truth: Vec<f64>,
}

fn ambient(x: usize, y: usize) -> f64 {
    25.0 + 0.5 * y as f64 + 0.1 * x as f64
}

/// Pixel-integrated Gaussian of unit peak at `u` (pixel centre minus stripe centre).
fn profile(u: f64, sigma: f64) -> f64 {
    let s = sigma * std::f64::consts::SQRT_2;
    sigma
        * (std::f64::consts::PI / 2.0).sqrt()
        * (libm::erf((u + 0.5) / s) - libm::erf((u - 0.5) / s))
}

pub fn synthetic(sigma: f64, amplitude: f64, noise: f64, seed: u64) -> Synthetic {
    let mut rng = StdRng::seed_from_u64(seed);
    let n = Normal::new(0.0, noise.max(1e-9)).unwrap();
    let slope = 0.037;
    let phase = (seed % 97) as f64 / 97.0;
    let truth: Vec<f64> = (0..WIDTH)
        .map(|x| 31.5 - 3.0 + slope * x as f64 + phase)
        .collect();
    let mut frame = vec![0u8; WIDTH * HEIGHT];
    let mut reference = vec![0u8; WIDTH * HEIGHT];
    let q = |v: f64| v.round().clamp(0.0, 255.0) as u8;
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let a = ambient(x, y);
            let s = amplitude * profile(y as f64 - truth[x], sigma);
            frame[y * WIDTH + x] = q(a + s + n.sample(&mut rng));
            reference[y * WIDTH + x] = q(a + n.sample(&mut rng));
        }
    }
    Synthetic {
        frame,
        reference,
        truth,
    }
}

/// The bench grid.
pub const SIGMAS: [f64; 5] = [1.0, 1.5, 2.0, 3.0, 4.0];
pub const AMPLITUDES: [f64; 9] = [30.0, 45.0, 60.0, 90.0, 130.0, 180.0, 250.0, 350.0, 450.0];

/// Centre errors (px) of the valid columns and the number of columns judged, for one estimator
/// and method over the whole grid, split into (peak < 60 DN, peak ≥ 60 DN unclipped, clipped).
#[derive(Debug, Default, Clone)]
pub struct Errors {
    pub low: Vec<f64>,
    pub high: Vec<f64>,
    pub clipped: Vec<f64>,
    pub judged_high: usize,
    pub valid_high: usize,
}

pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

pub fn percentile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return f64::NAN;
    }
    s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1]
}

pub fn bench(estimator: Estimator, method: Method, noise: f64, repeats: u64) -> Errors {
    let mut ex = Box::new(Extractor::<256>::new());
    let mut cfg = StripeConfig::new(method, Axis::Columns);
    cfg.estimator = estimator;
    let mut out = Errors::default();
    let mut seed = 1;
    for &sigma in &SIGMAS {
        for &amp in &AMPLITUDES {
            for _ in 0..repeats {
                seed += 1;
                let s = synthetic(sigma, amp, noise, seed);
                let f = Frame::packed(&s.frame, WIDTH, HEIGHT, PixelFormat::Gray8).unwrap();
                let r = Frame::packed(&s.reference, WIDTH, HEIGHT, PixelFormat::Gray8).unwrap();
                let res = ex.extract(&f, Some(&r), &cfg).unwrap();
                // peak height above the ambient, as the stripe's top pixel gets it
                let top = amp * profile(0.0, sigma);
                let clipped = top + 60.0 > 255.0;
                for (x, p) in res.points.iter().enumerate() {
                    if amp >= 60.0 {
                        out.judged_high += 1;
                    }
                    if p.status != LineStatus::Valid {
                        continue;
                    }
                    let e = (f64::from(p.centre) - s.truth[x]).abs();
                    if amp < 60.0 {
                        out.low.push(e);
                    } else {
                        out.valid_high += 1;
                        if clipped {
                            out.clipped.push(e)
                        } else {
                            out.high.push(e)
                        }
                    }
                }
            }
        }
    }
    out
}

/// Centres against their stated uncertainty for one stripe width and peak (DIM, centroid, noise
/// 2 DN, six frames): the squared errors, the squared Cramér–Rao bounds (the stated σ without
/// the centroid's efficiency factor), the valid count and how many lie within 2 stated σ.
#[derive(Debug, Default, Clone, Copy)]
pub struct Stated {
    pub e2: f64,
    pub b2: f64,
    pub valid: usize,
    pub judged: usize,
    pub within_2: usize,
}

impl Stated {
    /// RMS error over RMS bound.
    pub fn ratio(&self) -> f64 {
        (self.e2 / self.b2).sqrt()
    }

    pub fn add(&mut self, o: &Stated) {
        self.e2 += o.e2;
        self.b2 += o.b2;
        self.valid += o.valid;
        self.judged += o.judged;
        self.within_2 += o.within_2;
    }
}

pub fn stated(sigma: f64, amplitude: f64, frames: u64) -> Stated {
    use scanner_core::stripe::CENTROID_EFFICIENCY;
    let mut ex = Box::new(Extractor::<256>::new());
    let mut cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    cfg.estimator = Estimator::Centroid;
    // the bench renders sensor noise only: no speckle
    cfg.speckle_px = 0.0;
    let mut out = Stated::default();
    for seed in 0..frames {
        let s = synthetic(sigma, amplitude, 2.0, 1000 + seed);
        let f = Frame::packed(&s.frame, WIDTH, HEIGHT, PixelFormat::Gray8).unwrap();
        let r = Frame::packed(&s.reference, WIDTH, HEIGHT, PixelFormat::Gray8).unwrap();
        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
        out.judged += res.points.len();
        for (x, p) in res.points.iter().enumerate() {
            if p.status != LineStatus::Valid {
                continue;
            }
            let e = f64::from(p.centre) - s.truth[x];
            let b = f64::from(p.sigma) / f64::from(CENTROID_EFFICIENCY);
            out.e2 += e * e;
            out.b2 += b * b;
            out.valid += 1;
            out.within_2 += usize::from(e.abs() <= 2.0 * f64::from(p.sigma));
        }
    }
    out
}
