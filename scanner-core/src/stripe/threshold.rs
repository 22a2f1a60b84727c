//! The automatic thresholds: DIM's from the noise of the signed change, LIM's from the
//! reference's bright tail and the lit lines' peaks.

use super::config::{Roi, SAMPLE_STEP};
use super::lines::Io;
use super::signal;

/// DIM threshold: the background change sits at the mode of the signed change over about
/// [`NOISE_SAMPLES`] pixels of every [`SAMPLE_STEP`]-th row (pixels clipped to black or white in
/// both frames left out: they show no noise); its noise is measured on the side below the mode
/// only (laser light only adds, so that side is stripe-free however much of the frame the stripe
/// covers). The threshold is six of those standard deviations above the mode — or, where the
/// noise has heavier tails than a Gaussian's (a compressed frame's blocks in dark areas, seen on
/// the real photographs), the 99th percentile of the drops, mirrored. A Gaussian's is 2.6 σ, so
/// on clean frames the six σ decide; the price is that a shadow over more than 1 % of the frame
/// raises the threshold towards its depth (lock the exposure, keep the ambient light steady).
/// Returns the threshold (signal units) and the noise σ of the change (DN: a sixth of the
/// margin above the mode, so the heavier tail counts when it decides).
pub(super) fn dim_threshold(io: &Io<'_, '_>) -> (u16, f32) {
    let mut hist = [0u32; 511];
    let Roi {
        x,
        y,
        width,
        height,
    } = io.roi;
    // about NOISE_SAMPLES pixels: every SAMPLE_STEP-th row, columns spaced to fit
    let rows = height.div_ceil(SAMPLE_STEP);
    let step = (rows * width / NOISE_SAMPLES).clamp(1, 16);
    for r in (y..y + height).step_by(SAMPLE_STEP) {
        let (row, reference) = (io.frame.row(r), io.reference.row(r));
        signal::signed_changes(io.kind, row, reference, x..x + width, step, |d| {
            hist[(d + 255) as usize] += 1;
        });
    }
    let mode = (0..hist.len()).fold(0, |m, i| if hist[i] > hist[m] { i } else { m });
    // half-normal below the mode: its median is 0.6745 σ; the mode bin is split evenly
    let mut below = [0u32; 511];
    for (i, &h) in hist[..mode].iter().enumerate() {
        below[mode - i] += 2 * h;
    }
    below[0] = hist[mode];
    let n: u32 = below.iter().sum();
    let sigma = (1.4826 * quantile(&below, n, 0.5) as f32).max(0.5);
    let q99 = quantile(&below, n, 0.99) as f32;
    let noise = (6.0 * sigma).max(q99);
    let centre = (mode as i32 - 255).max(0) as f32;
    let level = if !io.kind.squared() {
        centre + noise
    } else {
        // the squared change of the laser's channel, `Δ² / 9`
        noise * noise / 9.0
    };
    // The noise the centres' uncertainty is stated with: the median interpolated within its
    // 1-DN bin (the threshold's whole-bin median overstates a σ of 2 DN by up to 40 %), or the
    // heavier tail's sixth where that decides the threshold.
    let stated = (1.4826 * median_within_bins(&below, n))
        .max(q99 / 6.0)
        .max(0.3);
    (libm::ceilf(level).clamp(3.0, 7225.0) as u16, stated)
}

/// The median of absolute changes binned by their rounded value (bin 0 holds `[0, 0.5)`, bin
/// `k` holds `[k − 0.5, k + 0.5)`), interpolated linearly within its bin.
pub(super) fn median_within_bins(hist: &[u32], n: u32) -> f32 {
    let half = n as f32 / 2.0;
    let mut acc = 0.0;
    for (k, &h) in hist.iter().enumerate() {
        let h = h as f32;
        if h > 0.0 && acc + h >= half {
            let f = (half - acc) / h;
            return if k == 0 { 0.5 * f } else { k as f32 - 0.5 + f };
        }
        acc += h;
    }
    hist.len() as f32
}

/// Columns sampled by the LIM threshold: every this many.
pub(super) const SAMPLE_COLUMNS: usize = 4;
/// Pixels the DIM noise estimate aims to sample.
pub(super) const NOISE_SAMPLES: usize = 8192;

/// The bright tail of the LIM background: the 99.9th percentile of the reference's LIM signal
/// (or the frame's, without a reference) over every [`SAMPLE_STEP`]-th row and [`SAMPLE_COLUMNS`]-th
/// column.
pub(super) fn lim_background(io: &Io<'_, '_>) -> u8 {
    let mut hist = [0u32; 256];
    let mut n = 0u32;
    let Roi {
        x,
        y,
        width,
        height,
    } = io.roi;
    for r in (y..y + height).step_by(SAMPLE_STEP) {
        let row = io.reference.row(r);
        for c in (x..x + width).step_by(SAMPLE_COLUMNS) {
            hist[usize::from(signal::lim_of(io.kind, row, c))] += 1;
            n += 1;
        }
    }
    quantile(&hist, n, 0.999) as u8
}

/// LIM threshold (paper section 4): halfway between the background's bright `tail` and the
/// median peak of the lines that rise above it (a line's peak: the mean of the three samples
/// under the 3×1 mask).
pub(super) fn lim_threshold(tail: u16, best: &[u16]) -> u16 {
    let mut peaks = [0u32; 256];
    let mut m = 0u32;
    for &b in best {
        let p = b / 3;
        if p > tail {
            peaks[usize::from(p.min(255))] += 1;
            m += 1;
        }
    }
    if m == 0 {
        return tail + 1;
    }
    let median_peak = quantile(&peaks, m, 0.5) as u16;
    tail + (median_peak - tail).div_ceil(2)
}

/// The smallest bin index whose cumulative count reaches `q` of `n`.
pub(super) fn quantile(hist: &[u32], n: u32, q: f32) -> usize {
    let target = libm::ceilf(q * n as f32).max(1.0) as u64;
    let mut acc = 0u64;
    for (i, &h) in hist.iter().enumerate() {
        acc += u64::from(h);
        if acc >= target {
            return i;
        }
    }
    hist.len() - 1
}
