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
    /// Light less than this above the background is taken for noise by [`Profile::spread`] (0:
    /// only its 15 %-of-the-height level applies). On a faint stripe 15 % of the height is about
    /// one noise σ, and the noise samples above it made a halo of nothing.
    pub noise: f32,
}

/// An edge of a profile ([`Window::edges`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeFit {
    /// Where the flank crosses half the height, samples.
    pub at: f32,
    /// The flank's slope there, signal per sample.
    pub slope: f32,
    /// Samples the flank's line was fitted to.
    pub samples: usize,
    /// The band's height it was measured against (the level over the middle half of its
    /// half-maximum run, above the background).
    pub height: f32,
}

/// Largest window an estimator handles.
pub const MAX_WINDOW: usize = 2 * super::MAX_HALF_WINDOW + 1;

/// Peak, background and extent of the stripe in a window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// Index of the largest sample near the rough centre.
    pub peak_index: usize,
    /// Largest sample near the rough centre.
    pub peak: f32,
    /// Height of the peak above the background.
    pub height: f32,
    /// Background at the window's first sample and its slope per sample.
    pub background: (f32, f32),
    /// Half-maximum crossings, samples.
    pub half_max: (f32, f32),
    /// Full width at half maximum (`half_max.1 − half_max.0`), samples. Where the raw profile is
    /// a single hot or clipped pixel on top of a wider stripe (seen on real webcam frames), the
    /// width of the 3-sample median of the profile instead, which is the stripe's.
    pub fwhm: f32,
    /// Longest run of clipped samples touching the peak's run.
    pub clipped_run: usize,
    /// `2.3548 ×` the standard deviation of the light above 15 % of the height over the whole
    /// window, samples: equal to the FWHM for a Gaussian, a little below it for a flat top, and
    /// far above it when the stripe sits on a halo of scattered light (a glint nearby).
    pub spread: f32,
    /// Samples above half the height that lie outside the peak's half-maximum run: a second
    /// hump in the window (a glint beside the stripe, the stripe split by an edge).
    pub stray: usize,
    /// The highest of those, as a fraction of the peak's raw value (0 without any): above 1, a
    /// higher hump than the one the stripe was taken at.
    pub stray_peak: f32,
}

/// Linear background through the means of the two samples at each end of `v(0..n)`:
/// `(b0, slope)`.
#[inline]
fn linear_background(n: usize, v: impl Fn(usize) -> f32) -> (f32, f32) {
    let k = n.min(2);
    let head = (0..k).map(&v).sum::<f32>() / k as f32;
    let tail = (n - k..n).map(&v).sum::<f32>() / k as f32;
    let slope = if n > k {
        (tail - head) / (n - k) as f32
    } else {
        0.0
    };
    (head - slope * (k as f32 - 1.0) / 2.0, slope)
}

/// Half-maximum crossings of `v(0..n)` around `top` above the background `bg`.
#[inline]
fn crossings(n: usize, v: impl Fn(usize) -> f32, bg: (f32, f32), top: usize) -> (f32, f32) {
    let b = |i: usize| bg.0 + bg.1 * i as f32;
    let height = v(top) - b(top);
    if !(height > 0.0) {
        // no peak above the background: no width
        return (top as f32, top as f32);
    }
    let half = |i: usize| v(i) - b(i) - height / 2.0;
    // a crossing between samples i and i + 1, where `a` and `c` have opposite signs
    let cross = |i: usize, a: f32, c: f32| {
        let t = a / (a - c);
        i as f32 + if t.is_finite() { t } else { 0.5 }
    };
    let mut i = top;
    while i > 0 && half(i - 1) > 0.0 {
        i -= 1;
    }
    let left = if i > 0 {
        cross(i - 1, half(i - 1), half(i))
    } else {
        0.0
    };
    let mut j = top;
    while j + 1 < n && half(j + 1) > 0.0 {
        j += 1;
    }
    let right = if j + 1 < n {
        cross(j, half(j), half(j + 1))
    } else {
        (n - 1) as f32
    };
    (left, right)
}

impl Window<'_> {
    fn bg(&self, shape: &Profile, i: usize) -> f32 {
        shape.background.0 + shape.background.1 * i as f32
    }

    /// Background, peak, height and FWHM of the window (see [`Profile`]).
    #[inline]
    pub fn shape(&self) -> Profile {
        let n = self.signal.len().min(MAX_WINDOW);
        let s = &self.signal[..n];
        let raw = |i: usize| f32::from(s[i]);
        let background = linear_background(n, raw);
        let bg = |i: usize| background.0 + background.1 * i as f32;
        // the peak nearest the rough centre: the largest sample within ±2 of it
        let lo = self.rough.min(n - 1).saturating_sub(2);
        let hi = (self.rough + 3).min(n);
        let peak_index = (lo..hi).fold(lo, |p, i| if s[i] > s[p] { i } else { p });
        let mut half_max = crossings(n, raw, background, peak_index);
        if half_max.1 - half_max.0 < 1.5 {
            // a one-pixel spike? measure the stripe under it on the 3-sample median
            let med = |i: usize| {
                let (a, b, c) = (s[i.saturating_sub(1)], s[i], s[(i + 1).min(n - 1)]);
                f32::from(a.max(b).min(a.min(b).max(c)))
            };
            let mbg = linear_background(n, med);
            let top = (lo..hi).fold(lo, |p, i| if med(i) > med(p) { i } else { p });
            if med(top) - (mbg.0 + mbg.1 * top as f32) > 0.0 {
                let m = crossings(n, med, mbg, top);
                if m.1 - m.0 > half_max.1 - half_max.0 {
                    half_max = m;
                }
            }
        }
        // clipped run through the peak region
        let mut clipped_run = 0;
        if self.clipped[peak_index] {
            let (mut a, mut b) = (peak_index, peak_index);
            while a > 0 && self.clipped[a - 1] {
                a -= 1;
            }
            while b + 1 < n && self.clipped[b + 1] {
                b += 1;
            }
            clipped_run = b - a + 1;
        }
        let height = raw(peak_index) - bg(peak_index);
        let (mut m0, mut m1, mut m2) = (0f32, 0f32, 0f32);
        let level = (0.15 * height).max(self.noise);
        // Samples above half the height outside the half-maximum run: a second hump.
        let (lo_run, hi_run) = (half_max.0 - 0.5, half_max.1 + 0.5);
        let (mut stray, mut stray_top) = (0usize, 0u16);
        for (i, &v) in s.iter().enumerate() {
            // branch-free: samples below the level weigh nothing
            let above = f32::from(v) - bg(i);
            let w = (above - level).max(0.0);
            let u = i as f32 - peak_index as f32;
            m0 += w;
            m1 += w * u;
            m2 += w * u * u;
            let fi = i as f32;
            let out = above > 0.5 * height && (fi < lo_run || fi > hi_run);
            stray += usize::from(out);
            stray_top = stray_top.max(if out { v } else { 0 });
        }
        let spread = if m0 > 0.0 {
            let mean = m1 / m0;
            2.3548 * libm::sqrtf((m2 / m0 - mean * mean).max(0.0))
        } else {
            0.0
        };
        let stray_peak = if stray > 0 {
            f32::from(stray_top) / raw(peak_index).max(1.0)
        } else {
            0.0
        };
        Profile {
            peak_index,
            peak: raw(peak_index),
            height,
            background,
            half_max,
            fwhm: half_max.1 - half_max.0,
            clipped_run,
            spread,
            stray,
            stray_peak,
        }
    }

    /// The contiguous run around the peak where the background-subtracted signal exceeds
    /// `fraction` of the peak height, as `(first, last)` inclusive.
    #[inline]
    fn run(&self, shape: &Profile, fraction: f32) -> (usize, usize) {
        let height = shape.height;
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

    /// The profile's two edges, rising then falling: where its flank crosses half the band's
    /// height above the background (its level over the middle half of the half-maximum run),
    /// from a least-squares line through the flank's unclipped samples
    /// between 15 % and 85 % of the height (at least the two about the crossing), so that the
    /// noise of a wide, shallow flank (a shadow's penumbra) averages out. Each with the line's
    /// slope (signal per sample) and the number of samples it was fitted to; `None` for a flank
    /// that does not come down inside the window.
    ///
    /// `level`, when positive, is the signal the edges cross instead of half the band's height
    /// (a shadow's contrast scaled to the lamp's full share: half of it is where half the lamp
    /// is hidden, however deep the band); a band that does not reach it has no edges.
    pub fn edges(&self, shape: &Profile, level: f32) -> [Option<EdgeFit>; 2] {
        let n = self.signal.len();
        if !(shape.height > 0.0) || n < 3 {
            return [None, None];
        }
        let v = |i: usize| f32::from(self.signal[i]) - self.bg(shape, i);
        // The band's height: the mean over the middle half of its half-maximum run (a flat
        // top's level; the largest sample alone stands a noise σ or more above it, and would
        // pull both edges in).
        let (lo, hi) = shape.half_max;
        let quarter = (hi - lo) / 4.0;
        let (from, to) = (
            libm::ceilf(lo + quarter).max(0.0) as usize,
            (libm::floorf(hi - quarter).max(0.0) as usize).min(n - 1),
        );
        let top = if from <= to {
            (from..=to).map(v).sum::<f32>() / (to - from + 1) as f32
        } else {
            shape.height
        };
        // `h`: twice the level the edges cross, above the background
        let peak_bg = self.bg(shape, shape.peak_index.min(n - 1));
        let h = if level > 0.0 {
            2.0 * (level - peak_bg)
        } else {
            top
        };
        if !(h > 0.0 && top > 0.5 * h) {
            return [None, None];
        }
        let peak = shape.peak_index.min(n - 1);
        let edge = |rising: bool| -> Option<EdgeFit> {
            // the first sample beyond the crossing of half the height, walking out of the peak
            let mut i = peak;
            let crossed = loop {
                if v(i) < 0.5 * h {
                    break Some(i);
                }
                match (rising, i) {
                    (true, 0) => break None,
                    (true, _) => i -= 1,
                    (false, _) if i + 1 >= n => break None,
                    (false, _) => i += 1,
                }
            }?;
            // the two samples about the crossing, widened along the flank while it stays
            // between 15 % and 85 % of the height and keeps its direction
            let (mut a, mut b) = if rising {
                (crossed, crossed + 1)
            } else {
                (crossed - 1, crossed)
            };
            let inside = |i: usize| {
                let x = v(i);
                x > 0.15 * h && x < 0.85 * h.min(top) && !self.clipped[i]
            };
            let up = |i: usize, j: usize| (v(j) > v(i)) == rising;
            while a > 0 && inside(a - 1) && up(a - 1, a) {
                a -= 1;
            }
            while b + 1 < n && inside(b + 1) && up(b, b + 1) {
                b += 1;
            }
            let m = (b - a + 1) as f32;
            let (mut sx, mut sy, mut sxx, mut sxy) = (0f32, 0f32, 0f32, 0f32);
            for i in a..=b {
                let (x, y) = ((i - a) as f32, v(i));
                sx += x;
                sy += y;
                sxx += x * x;
                sxy += x * y;
            }
            let det = m * sxx - sx * sx;
            if !(det > 0.0) {
                return None;
            }
            let slope = (m * sxy - sx * sy) / det;
            let at = (sy - slope * sx) / m;
            if !((slope > 0.0) == rising && slope != 0.0) {
                return None;
            }
            let x = a as f32 + (0.5 * h - at) / slope;
            (x > a as f32 - 1.0 && x < b as f32 + 1.0).then_some(EdgeFit {
                at: x,
                slope: slope.abs(),
                samples: b - a + 1,
                height: h,
            })
        };
        [edge(true), edge(false)]
    }

    /// The centre by `estimator`; `sobel` holds the Sobel response along the line for
    /// [`Estimator::Paper`] (ignored by the others). `None` when the profile has no usable shape.
    #[inline]
    pub fn centre(&self, shape: &Profile, estimator: Estimator, sobel: &[i32]) -> Option<f32> {
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

    #[inline]
    fn centroid(&self, shape: &Profile) -> Option<f32> {
        let height = shape.height;
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

    fn gaussian(&self, shape: &Profile) -> Option<f32> {
        let height = shape.height;
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
        // A Gaussian fit is trusted only where the profile looks Gaussian: the vertex between the
        // half-maximum crossings and the fitted width within 2× of the measured one. Flat-topped
        // or spiky real profiles fail this and fall back to the centroid.
        let vertex = c + offset;
        let fitted_fwhm = 2.3548 * libm::sqrtf(-1.0 / (2.0 * p.z));
        let consistent = vertex >= shape.half_max.0
            && vertex <= shape.half_max.1
            && fitted_fwhm <= 2.0 * shape.fwhm
            && 2.0 * fitted_fwhm >= shape.fwhm;
        if !consistent {
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
            noise: 0.0,
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
