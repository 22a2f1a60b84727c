//! Subpixel estimators over one profile window around the rough peak.
//!
//! A window is the stripe signal of one line (column or row) from `start` to `start + n`, the
//! flags of samples whose raw pixel was clipped at 255, and the index of the rough centre found by
//! the 3×1 mask. Every estimator returns the centre in window coordinates (sample `i` at `i`).

use nalgebra::{Matrix3, Vector3};

/// Which subpixel estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The paper's (section 3B): the rough centre of the 3×1 mask, the stripe's edges at the
    /// strongest Sobel responses either side of it, and the weighted centroid between them
    /// (eq. 10), on the raw signal.
    Paper,
    /// Centroid of the signal above a local linear background plus 10 % of the peak height, over
    /// the contiguous run around the peak.
    Centroid,
    /// Weighted least-squares parabola through the log of the background-subtracted signal
    /// (a Gaussian fit), over the samples above 15 % of the peak height and not clipped, so that
    /// saturated stripes are located by their flanks. Falls back to [`Estimator::Centroid`] when
    /// fewer than three samples are usable.
    Gaussian,
}

/// One profile window.
#[derive(Debug, Clone, Copy)]
pub struct Window<'a> {
    /// Stripe signal.
    pub signal: &'a [u16],
    /// `true` where the raw pixel was clipped.
    pub clipped: &'a [bool],
    /// Index of the rough centre (3×1 mask maximum).
    pub rough: usize,
}

/// Peak, background and extent of the stripe in a window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shape {
    /// Index of the largest sample.
    pub peak_index: usize,
    /// Largest sample.
    pub peak: f32,
    /// Background at the window's first sample and its slope per sample.
    pub background: (f32, f32),
    /// Full width at half maximum above the background, samples.
    pub fwhm: f32,
    /// Longest run of clipped samples touching the peak's run.
    pub clipped_run: usize,
}

impl Window<'_> {
    fn bg(&self, shape: &Shape, i: usize) -> f32 {
        shape.background.0 + shape.background.1 * i as f32
    }

    /// Linear background through the means of the two samples at each end; the peak; the FWHM.
    pub fn shape(&self) -> Shape {
        let s = self.signal;
        let n = s.len();
        let k = n.min(2);
        let head = s[..k].iter().map(|&v| f32::from(v)).sum::<f32>() / k as f32;
        let tail = s[n - k..].iter().map(|&v| f32::from(v)).sum::<f32>() / k as f32;
        let slope = if n > k {
            (tail - head) / (n - k) as f32
        } else {
            0.0
        };
        let b0 = head - slope * (k as f32 - 1.0) / 2.0;
        // the peak nearest the rough centre: the largest sample within ±2 of it
        let lo = self.rough.saturating_sub(2);
        let hi = (self.rough + 3).min(n);
        let mut peak_index = lo;
        for i in lo..hi {
            if s[i] > s[peak_index] {
                peak_index = i;
            }
        }
        let mut shape = Shape {
            peak_index,
            peak: f32::from(s[peak_index]),
            background: (b0, slope),
            fwhm: 0.0,
            clipped_run: 0,
        };
        let height = shape.peak - self.bg(&shape, peak_index);
        let half = |i: usize| f32::from(s[i]) - self.bg(&shape, i) - height / 2.0;
        // walk out from the peak to the half-height crossings, interpolating linearly
        let mut left = 0.0;
        let mut i = peak_index;
        while i > 0 && half(i - 1) > 0.0 {
            i -= 1;
        }
        if i > 0 {
            let (a, b) = (half(i - 1), half(i));
            left = (i - 1) as f32 + a / (a - b);
        }
        let mut right = (n - 1) as f32;
        let mut j = peak_index;
        while j + 1 < n && half(j + 1) > 0.0 {
            j += 1;
        }
        if j + 1 < n {
            let (a, b) = (half(j), half(j + 1));
            right = j as f32 + a / (a - b);
        }
        shape.fwhm = right - left;
        // clipped run through the peak region
        let (mut a, mut b) = (peak_index, peak_index);
        if self.clipped[peak_index] {
            while a > 0 && self.clipped[a - 1] {
                a -= 1;
            }
            while b + 1 < n && self.clipped[b + 1] {
                b += 1;
            }
            shape.clipped_run = b - a + 1;
        }
        shape
    }

    /// The contiguous run around the peak where the background-subtracted signal exceeds
    /// `fraction` of the peak height, as `(first, last)` inclusive.
    fn run(&self, shape: &Shape, fraction: f32) -> (usize, usize) {
        let height = shape.peak - self.bg(shape, shape.peak_index);
        let level = |i: usize| f32::from(self.signal[i]) - self.bg(shape, i) > fraction * height;
        let (mut a, mut b) = (shape.peak_index, shape.peak_index);
        while a > 0 && level(a - 1) {
            a -= 1;
        }
        while b + 1 < self.signal.len() && level(b + 1) {
            b += 1;
        }
        (a, b)
    }

    /// The centre by `estimator`; `sobel` holds the Sobel response along the line for
    /// [`Estimator::Paper`] (ignored by the others). `None` when the profile has no usable shape.
    pub fn centre(&self, shape: &Shape, estimator: Estimator, sobel: &[i32]) -> Option<f32> {
        match estimator {
            Estimator::Paper => self.paper(sobel),
            Estimator::Centroid => self.centroid(shape),
            Estimator::Gaussian => self.gaussian(shape).or_else(|| self.centroid(shape)),
        }
    }

    fn paper(&self, sobel: &[i32]) -> Option<f32> {
        let n = self.signal.len();
        if sobel.len() != n || n < 3 {
            return None;
        }
        let c = self.rough.min(n - 1);
        // upper edge: strongest rising response at or before the centre; lower edge: strongest
        // falling response at or after it
        let mut ub = c;
        for i in 0..=c {
            if sobel[i] > sobel[ub] {
                ub = i;
            }
        }
        let mut lb = c;
        for i in c..n {
            if sobel[i] < sobel[lb] {
                lb = i;
            }
        }
        let (mut num, mut den) = (0.0f32, 0.0f32);
        for i in ub..=lb {
            let v = f32::from(self.signal[i]);
            num += i as f32 * v;
            den += v;
        }
        (den > 0.0).then(|| num / den)
    }

    fn centroid(&self, shape: &Shape) -> Option<f32> {
        let height = shape.peak - self.bg(shape, shape.peak_index);
        if !(height > 0.0) {
            return None;
        }
        let (a, b) = self.run(shape, 0.1);
        let (mut num, mut den) = (0.0f32, 0.0f32);
        for i in a..=b {
            let v = f32::from(self.signal[i]) - self.bg(shape, i) - 0.1 * height;
            if v > 0.0 {
                num += i as f32 * v;
                den += v;
            }
        }
        (den > 0.0).then(|| num / den)
    }

    fn gaussian(&self, shape: &Shape) -> Option<f32> {
        let height = shape.peak - self.bg(shape, shape.peak_index);
        if !(height > 0.0) {
            return None;
        }
        let (a, b) = self.run(shape, 0.15);
        let c = shape.peak_index as f32;
        // normal equations of ln v = p0 + p1 u + p2 u², u = i − c, weights v² (var(ln v) ∝ 1/v²)
        let mut m = Matrix3::<f32>::zeros();
        let mut r = Vector3::<f32>::zeros();
        let mut used = 0;
        for i in a..=b {
            let v = f32::from(self.signal[i]) - self.bg(shape, i);
            if v <= 0.0 || self.clipped[i] {
                continue;
            }
            let u = i as f32 - c;
            let w = v * v;
            let basis = Vector3::new(1.0, u, u * u);
            m += basis * basis.transpose() * w;
            r += basis * (w * libm::logf(v));
            used += 1;
        }
        if used < 3 {
            return None;
        }
        let p = m.try_inverse()? * r;
        if !(p.z < 0.0) {
            return None;
        }
        let offset = -p.y / (2.0 * p.z);
        // the vertex must lie within the samples used, else the fit is meaningless
        if !(offset.abs() <= (b - a) as f32 / 2.0 + 1.0) {
            return None;
        }
        Some(c + offset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window<'a>(s: &'a [u16], clipped: &'a [bool], rough: usize) -> Window<'a> {
        Window {
            signal: s,
            clipped,
            rough,
        }
    }

    #[test]
    fn symmetric_profile_centres_on_the_middle() {
        let s = [0, 0, 10, 50, 100, 50, 10, 0, 0];
        let c = [false; 9];
        let w = window(&s, &c, 4);
        let shape = w.shape();
        assert_eq!(shape.peak_index, 4);
        // half height 50 is reached exactly at 3 and 5
        assert!((shape.fwhm - 2.0).abs() < 1e-6, "{}", shape.fwhm);
        for e in [Estimator::Centroid, Estimator::Gaussian] {
            assert!(
                (w.centre(&shape, e, &[]).unwrap() - 4.0).abs() < 1e-5,
                "{e:?}"
            );
        }
        let sobel: [i32; 9] = core::array::from_fn(|i| {
            let g = |k: usize| i32::from(s[k.min(8)]);
            if i == 0 || i == 8 {
                0
            } else {
                g(i + 1) - g(i - 1)
            }
        });
        assert!((w.centre(&shape, Estimator::Paper, &sobel).unwrap() - 4.0).abs() < 1e-5);
    }

    #[test]
    fn gaussian_fit_is_exact_on_a_sampled_gaussian() {
        let centre = 7.3f32;
        let s: [u16; 16] = core::array::from_fn(|i| {
            let u = i as f32 - centre;
            (20.0 + 200.0 * libm::expf(-u * u / (2.0 * 1.5 * 1.5))) as u16
        });
        let c = [false; 16];
        let w = window(&s, &c, 7);
        let shape = w.shape();
        let got = w.centre(&shape, Estimator::Gaussian, &[]).unwrap();
        assert!((got - centre).abs() < 0.02, "{got}");
    }

    #[test]
    fn clipped_top_is_located_by_the_flanks() {
        let centre = 8.4f32;
        let mut clipped = [false; 18];
        let s: [u16; 18] = core::array::from_fn(|i| {
            let u = i as f32 - centre;
            let v = 600.0 * libm::expf(-u * u / (2.0 * 2.0 * 2.0));
            if v >= 255.0 {
                clipped[i] = true;
                255
            } else {
                v as u16
            }
        });
        let w = window(&s, &clipped, 8);
        let shape = w.shape();
        assert!(shape.clipped_run >= 3);
        let got = w.centre(&shape, Estimator::Gaussian, &[]).unwrap();
        assert!((got - centre).abs() < 0.05, "{got}");
    }

    #[test]
    fn flat_profile_has_no_centre() {
        let s = [7u16; 9];
        let c = [false; 9];
        let w = window(&s, &c, 4);
        let shape = w.shape();
        assert_eq!(w.centre(&shape, Estimator::Centroid, &[]), None);
        assert_eq!(w.centre(&shape, Estimator::Gaussian, &[]), None);
    }
}
