//! Judging a line's profile and the frame's lines together: the window read around each peak
//! ([`Extractor::judge`]), then the widths, cuts, edges and runs that mark lines as no stripe.

use super::Extractor;
use super::config::{Axis, MAX_BAND, StripeConfig};
use super::estimate::{Estimator, MAX_WINDOW, Window};
use super::lines::Io;
use super::report::{CENTRE_FLOOR, LineStatus, StripePoint, centre_sigma};
use super::signal::Method;
use super::threshold::quantile;

/// Half size of the first, narrow window read around a peak.
pub(super) const NARROW_HALF_WINDOW: usize = 6;

/// Smallest half size of the second window, read when the first has not come down to the
/// background: room enough to see a halo or a hump beside a narrow stripe (the 3σ tails of a
/// 14 px one).
pub(super) const HALO_HALF_WINDOW: usize = 24;

/// `true` if both ends of a window (two samples each) are within 5 % of the height of the
/// sample at `rough` above the lowest end sample: the stripe has come down to the background
/// inside the window. Five samples, whatever the window's length.
pub(super) fn settled(sig: &[u16], rough: usize) -> bool {
    let n = sig.len();
    if n < 4 {
        return false;
    }
    let ends = [sig[0], sig[1], sig[n - 2], sig[n - 1]];
    let lo = ends.iter().copied().min().unwrap_or(0);
    let hi = ends.iter().copied().max().unwrap_or(0);
    let peak = sig[rough.min(n - 1)].max(lo);
    u32::from(hi) <= u32::from(lo) + u32::from(peak - lo) / 20
}
/// The contiguous run around `rough` of samples above halfway from the lowest end sample to
/// the sample at `rough`, as `(first, last)` inclusive.
pub(super) fn half_run(sig: &[u16], rough: usize) -> (usize, usize) {
    let n = sig.len();
    let lo = [sig[0], sig[n - 1]].into_iter().min().unwrap_or(0);
    let top = sig[rough.min(n - 1)].max(lo);
    let level = lo + (top - lo) / 2;
    let (mut a, mut b) = (rough.min(n - 1), rough.min(n - 1));
    while a > 0 && sig[a - 1] > level {
        a -= 1;
    }
    while b + 1 < n && sig[b + 1] > level {
        b += 1;
    }
    (a, b)
}

/// Bins of [`mark_cut`]'s and [`mark_too_wide`]'s medians: widths in half pixels up to
/// [`MAX_BAND`] (wider ones count in the last bin); peaks in eighths of an octave over the whole
/// `u16` range (the first 128 bins).
pub(super) const CUT_BINS: usize = 2 * MAX_BAND as usize + 1;

/// Regions of a frame's lines over which [`mark_too_wide`] takes the stripe's median width.
pub(super) const WIDTH_REGIONS: usize = 8;

/// Fewest valid lines of a region for its own median width (fewer: the frame's).
pub(super) const MIN_REGION_LINES: u32 = 8;

/// The half-pixel bin of a width.
pub(super) fn width_bin(w: f32) -> usize {
    ((w * 2.0) as usize).min(CUT_BINS - 1)
}

/// Marks valid lines wider than `spread` times the median width of the valid lines of their
/// region (an eighth of the lines; the whole frame's when the region has fewer than
/// [`MIN_REGION_LINES`]) [`LineStatus::TooWide`], or [`LineStatus::Saturated`] when their
/// clipped plateau is longer than `max_plateau`: a halo, a glint or a blur beside the stripe,
/// measured against the stripe itself rather than a fixed limit (a stripe saturated and wide
/// everywhere is the stripe). `spread` 0 keeps every line.
pub(super) fn mark_too_wide(points: &mut [StripePoint], spread: f32, max_plateau: usize) {
    if !(spread > 0.0) || points.is_empty() {
        return;
    }
    // no line can be too wide when the widest is within `spread` of the narrowest
    let (lo, hi) = points
        .iter()
        .filter(|p| p.status == LineStatus::Valid)
        .fold((f32::INFINITY, 0f32), |(lo, hi), p| {
            (lo.min(p.width), hi.max(p.width))
        });
    if hi <= spread * lo {
        return;
    }
    let median = |points: &[StripePoint]| {
        let mut widths = [0u32; CUT_BINS];
        let mut n = 0u32;
        for p in points.iter().filter(|p| p.status == LineStatus::Valid) {
            widths[width_bin(p.width)] += 1;
            n += 1;
        }
        (n, (quantile(&widths, n, 0.5) as f32 + 0.5) / 2.0)
    };
    let (all, frame_median) = median(points);
    if all == 0 {
        return;
    }
    let size = points.len().div_ceil(WIDTH_REGIONS);
    for region in points.chunks_mut(size) {
        let (n, m) = median(region);
        let limit = spread
            * if n >= MIN_REGION_LINES {
                m
            } else {
                frame_median
            };
        for p in region
            .iter_mut()
            .filter(|p| p.status == LineStatus::Valid && p.width > limit)
        {
            let status = if usize::from(p.plateau) > max_plateau {
                LineStatus::Saturated
            } else {
                LineStatus::TooWide
            };
            *p = StripePoint {
                status,
                ..StripePoint::invalid(*p)
            };
        }
    }
}

/// Fewest neighbouring narrow, weak lines that [`mark_cut`] takes for a cut: the light sheet
/// passing a border runs along it, while a dark speck on a surface weakens a line or three.
pub(super) const CUT_RUN: usize = 4;

/// The eighth-octave bin of a peak (0 and 1 in bin 0; within 9 % of its value).
pub(super) fn octave_bin(v: u16) -> usize {
    if v == 0 {
        return 0;
    }
    let octave = 15 - v.leading_zeros() as usize;
    let eighth = if octave >= 3 {
        usize::from(v >> (octave - 3)) & 7
    } else {
        usize::from(v << (3 - octave)) & 7
    };
    8 * octave + eighth
}

/// The smallest value of an eighth-octave bin.
pub(super) fn octave_value(bin: usize) -> f32 {
    let (octave, eighth) = (bin / 8, bin % 8);
    (8 + eighth) as f32 * libm::exp2f(octave as f32) / 8.0
}

/// Marks valid lines that are both narrower than `fraction` of the median width of the frame's
/// valid lines and weaker than `peak_fraction` of their median peak [`LineStatus::Cut`]: the tail of the light
/// sheet on a surface whose border it has passed. Narrow alone is not enough (a real stripe's
/// width varies with speckle), nor weak alone (a dark surface).
pub(super) fn mark_cut(points: &mut [StripePoint], fraction: f32, peak_fraction: f32) {
    if !(fraction > 0.0) {
        return;
    }
    let peak_bin = |p: &StripePoint| octave_bin(p.peak);
    let mut widths = [0u32; CUT_BINS];
    let mut peaks = [0u32; CUT_BINS];
    let mut n = 0u32;
    for p in points.iter().filter(|p| p.status == LineStatus::Valid) {
        widths[width_bin(p.width)] += 1;
        peaks[peak_bin(p)] += 1;
        n += 1;
    }
    if n == 0 {
        return;
    }
    let width = fraction * (quantile(&widths, n, 0.5) as f32 + 0.5) / 2.0;
    let peak = peak_fraction * octave_value(quantile(&peaks, n, 0.5));
    let suspect = |p: &StripePoint| {
        p.status == LineStatus::Valid && p.width < width && f32::from(p.peak) < peak
    };
    cut_runs(points, suspect);
}

/// Marks [`LineStatus::Cut`] the `suspect` lines that make runs of at least [`CUT_RUN`] (the
/// gaps of invalid lines inside a run bridged): the light sheet passing a border runs along it,
/// while a dark speck on a surface touches a line or three.
pub(super) fn cut_runs(points: &mut [StripePoint], suspect: impl Fn(&StripePoint) -> bool) {
    let mut i = 0;
    while i < points.len() {
        if !suspect(&points[i]) {
            i += 1;
            continue;
        }
        let (start, mut end, mut count) = (i, i, 0);
        while i < points.len() && (suspect(&points[i]) || points[i].status != LineStatus::Valid) {
            if suspect(&points[i]) {
                end = i;
                count += 1;
            }
            i += 1;
        }
        if count >= CUT_RUN {
            for p in points[start..=end].iter_mut().filter(|p| suspect(p)) {
                *p = StripePoint {
                    status: LineStatus::Cut,
                    ..StripePoint::invalid(*p)
                };
            }
        }
        i = end + 1;
    }
}

/// Drops (NaN) each edge that moved less than `fraction` of its line's other edge since the
/// last frame (`last`, then set to this frame's edges as found), where that one moved more
/// than a pixel: an outline or ink cutting a moving band stays put. 0 keeps every edge.
pub(super) fn drop_still_edges(points: &mut [StripePoint], last: &mut [[f32; 2]], fraction: f32) {
    for (p, before) in points.iter_mut().zip(last.iter_mut()) {
        let now = p.edges;
        let moved = [0, 1].map(|k| libm::fabsf(now[k] - before[k]));
        if fraction > 0.0 && moved.iter().all(|m| m.is_finite()) {
            for k in 0..2 {
                let other = moved[1 - k];
                if other > 1.0 && moved[k] < fraction * other {
                    p.edges[k] = f32::NAN;
                    p.edge_sigma[k] = 0.0;
                }
            }
        }
        *before = now;
    }
}

/// Softest median ramp ([`StripePoint::ramps`]) of a frame's edges below which
/// [`drop_sharp_edges`] marks no laser line cut, pixels: a stripe narrower than about 12 px
/// keeps the narrow-and-weak check alone (its flanks hardly softer than the lens makes an
/// outline; on the rig's plate at 280 mm the sharp check as well cost 2.4 % of the points).
pub(super) const MIN_SOFT_RAMP: f32 = 10.0;

/// Narrowest line whose edges [`Extractor::extract`] finds unless asked for every line's
/// ([`StripeConfig::edges`]), pixels: a Gaussian profile's ramp is 0.72 of its width, so
/// narrower lines never reach [`MIN_SOFT_RAMP`] (and their edges cost a quarter of the
/// extraction's time).
pub(super) const MIN_EDGE_WIDTH: f32 = 12.0;

/// Drops (NaN) each edge of the valid lines that rises in less than `fraction` of the median
/// ramp of that edge over the frame's valid lines ([`StripePoint::ramps`]): the band cut by an
/// outline, a border or dark ink, sharper than its own flanks. With `cut` (a laser's stripe,
/// whose centre such a cut pulls), the lines are [`LineStatus::Cut`] instead, where that median
/// is at least [`MIN_SOFT_RAMP`] and the sharp lines make runs ([`cut_runs`]). `fraction` 0
/// keeps every edge.
pub(super) fn drop_sharp_edges(points: &mut [StripePoint], fraction: f32, cut: bool) {
    if !(fraction > 0.0) {
        return;
    }
    for k in 0..2 {
        let mut ramps = [0u32; CUT_BINS];
        let mut n = 0;
        for p in points
            .iter()
            .filter(|p| p.status == LineStatus::Valid && p.edges[k].is_finite())
        {
            ramps[width_bin(p.ramps[k])] += 1;
            n += 1;
        }
        if n == 0 {
            continue;
        }
        let median = (quantile(&ramps, n, 0.5) as f32 + 0.5) / 2.0;
        let sharp = |p: &StripePoint| {
            p.status == LineStatus::Valid
                && p.edges[k].is_finite()
                && p.ramps[k] < fraction * median
        };
        if !cut {
            for p in points.iter_mut().filter(|p| sharp(p)) {
                p.edges[k] = f32::NAN;
                p.edge_sigma[k] = 0.0;
            }
        } else if median >= MIN_SOFT_RAMP {
            cut_runs(points, sharp);
        }
    }
}

/// Lines a stripe may skip between two of its centres (invalid lines in between).
pub(super) const CONTINUITY_GAP: usize = 2;

/// How far a stripe's centre may move from one line to the next, pixels (a stripe crossing the
/// lines at up to 63°, beyond which the other axis is the one to scan).
pub(super) const CONTINUITY_SLOPE: f32 = 2.0;

/// Fewest lines of a run of continuous centres: the light sheet meets a surface in a curve
/// over many lines, while a colour fringe at a printed edge, a glint or a speck shows in one to
/// three (the real two-plane frames' fringes run along a square's side for two or three rows).
pub(super) const MIN_RUN: u16 = 4;

/// Whether centres `a` on line `i` and `b` on line `j` can be one stripe.
pub(super) fn continuous((i, a): (usize, f32), (j, b): (usize, f32)) -> bool {
    (a - b).abs() <= CONTINUITY_SLOPE * i.abs_diff(j) as f32 + 1.0
}

/// The root of `i` in a union-find forest `parent`.
pub(super) fn root(parent: &mut [u16], mut i: usize) -> usize {
    while usize::from(parent[i]) != i {
        let up = usize::from(parent[usize::from(parent[i])]);
        parent[i] = up as u16;
        i = up;
    }
    i
}

/// Groups the valid centres of `points` into runs (each centre joined to every valid centre up
/// to [`CONTINUITY_GAP`] lines before it that it continues) and leaves in `size[i]` the length of
/// the run of line `i` (0 for an invalid line); `parent` is scratch.
pub(super) fn runs(points: &[StripePoint], parent: &mut [u16], size: &mut [u16]) {
    let n = points.len();
    for i in 0..n {
        parent[i] = i as u16;
        size[i] = 0;
    }
    let valid = |i: usize| points[i].status == LineStatus::Valid;
    for i in (0..n).filter(|&i| valid(i)) {
        for j in i.saturating_sub(CONTINUITY_GAP + 1)..i {
            if valid(j) && continuous((i, points[i].centre), (j, points[j].centre)) {
                let (a, b) = (root(parent, i), root(parent, j));
                parent[a] = b as u16;
            }
        }
    }
    for i in (0..n).filter(|&i| valid(i)) {
        let r = root(parent, i);
        size[r] += 1;
    }
    for i in (0..n).filter(|&i| valid(i)) {
        let r = root(parent, i);
        size[i] = size[r];
    }
}

/// Whether a centre at `centre` on `line` continues a run of at least [`MIN_RUN`] lines beside
/// it (`size` from [`runs`]).
pub(super) fn joins_run(points: &[StripePoint], size: &[u16], line: usize, centre: f32) -> bool {
    let hi = (line + CONTINUITY_GAP + 1).min(points.len().saturating_sub(1));
    (line.saturating_sub(CONTINUITY_GAP + 1)..=hi)
        .filter(|&j| j != line && size[j] >= MIN_RUN)
        .any(|j| continuous((line, centre), (j, points[j].centre)))
}

impl<const W: usize> Extractor<W> {
    /// Reads the window around the peak at `rough` of `line` and decides its status and centre.
    pub(super) fn judge(
        &self,
        io: &Io<'_, '_>,
        cfg: &StripeConfig,
        (line, rough): (usize, usize),
        (length, width_limit): (usize, f32),
        (threshold, noise): (u16, f32),
        scratch: (&mut [u16; MAX_WINDOW], &mut [bool; MAX_WINDOW]),
    ) -> StripePoint {
        let mut point = StripePoint::NONE;
        if self.best[line] == 0 {
            return point;
        }
        let (sig, clipped) = scratch;
        // A narrow window first; a wider one, centred on the profile's half-maximum run, only
        // while the profile has not come down to the background at its ends (a wide stripe, a
        // shadow's band). A halo that never comes down stops the growth once the window holds
        // the run with room either side.
        let (mut centre, mut half) = (rough, cfg.half_window.min(NARROW_HALF_WINDOW));
        let (start, n) = loop {
            let start = centre.saturating_sub(half).min(rough);
            let end = (centre + half + 1).min(length).max(rough + 1);
            let n = end - start;
            io.window(line, start, &mut sig[..n], &mut clipped[..n]);
            if half >= cfg.half_window || settled(&sig[..n], rough - start) {
                break (start, n);
            }
            let (a, b) = half_run(&sig[..n], rough - start);
            let run = b - a + 1;
            let touches = a == 0 || b + 1 == n;
            let next = if touches {
                2 * half.max(12)
            } else {
                (run + run / 3 + NARROW_HALF_WINDOW).max(HALO_HALF_WINDOW)
            };
            if next <= half {
                break (start, n);
            }
            centre = start + (a + b) / 2;
            half = next.min(cfg.half_window);
        };
        let end = start + n;
        let window = Window {
            signal: &sig[..n],
            clipped: &clipped[..n],
            rough: rough - start,
            // the DIM threshold is six noise σ (at least): half of it is three
            noise: match cfg.method {
                Method::Dim => f32::from(threshold) / 2.0,
                Method::Lim => 0.0,
            },
        };
        let shape = window.shape();
        point.peak = sig[shape.peak_index];
        point.width = shape.fwhm;
        point.plateau = shape.clipped_run.min(usize::from(u16::MAX)) as u16;
        let t3 = 3 * u32::from(threshold);
        // a second peak inside the same band (the signal between the two never below half of
        // the second's) is the band's own top, not a rival
        let second_at = usize::from(self.second_at[line]);
        let same_band = || {
            second_at >= start && second_at < end && {
                let (a, b) = (rough.min(second_at) - start, rough.max(second_at) - start);
                let valley = sig[a..=b].iter().copied().min().unwrap_or(0);
                3 * u32::from(valley) >= u32::from(self.second[line]) / 2
            }
        };
        let strong_second = u32::from(self.second[line]) > t3
            && f32::from(self.second[line]) > cfg.ambiguity * f32::from(self.best[line])
            && !same_band();
        point.status = if point.peak < threshold {
            LineStatus::NoStripe
        } else if strong_second {
            LineStatus::Ambiguous
        } else if shape.fwhm > width_limit
            || shape.spread > 2.0 * shape.fwhm + 1.0
            || shape.stray as f32 > shape.fwhm
            || shape.stray_peak > 1.0
        {
            LineStatus::TooWide
        } else if shape.fwhm < cfg.min_width {
            LineStatus::TooNarrow
        } else {
            LineStatus::Valid
        };
        if point.status == LineStatus::Valid
            && cfg.method == Method::Dim
            && cfg.print_ratio > 0.0
            && io.print_under(line, start, &shape) > cfg.print_ratio
        {
            point.status = LineStatus::Print;
        }
        if point.status != LineStatus::Valid {
            return point;
        }
        let centre = if cfg.estimator == Estimator::Paper {
            let mut sobel = [0i32; MAX_WINDOW];
            io.sobel(line, start, end, &mut sobel[..n]);
            window.centre(&shape, cfg.estimator, &sobel[..n])
        } else {
            window.centre(&shape, cfg.estimator, &[])
        };
        match centre {
            Some(c) if c.is_finite() => {
                let origin = match cfg.axis {
                    Axis::Columns => io.roi.y,
                    Axis::Rows => io.roi.x,
                };
                point.centre = (origin + start) as f32 + c;
                // the noise in signal units at the peak: a squared signal `Δ²/9` moves by
                // `2Δ/9 = ⅔√signal` per DN of change
                let noise = if io.kind.squared() {
                    2.0 / 3.0 * libm::sqrtf(shape.height.max(1.0)) * noise
                } else {
                    noise
                };
                point.sigma = libm::hypotf(
                    centre_sigma(shape.height, shape.fwhm, noise),
                    cfg.speckle_px,
                );
                // the edges, each with the noise over its flank's slope (averaged over the
                // samples its line was fitted to)
                // the edges, where wanted: every line's for a shadow, a wide line's for the
                // border check (a narrow line's flanks tell nothing: see MIN_SOFT_RAMP)
                let edges = if cfg.edges || shape.fwhm >= MIN_EDGE_WIDTH {
                    window.edges(&shape, cfg.edge_level)
                } else {
                    [None, None]
                };
                for (k, e) in edges.into_iter().enumerate() {
                    if let Some(e) = e {
                        point.edges[k] = (origin + start) as f32 + e.at;
                        point.ramps[k] = e.height / e.slope;
                        let sigma = noise / (e.slope * libm::sqrtf(e.samples as f32));
                        point.edge_sigma[k] = libm::hypotf(sigma.max(CENTRE_FLOOR), cfg.speckle_px);
                    }
                }
            }
            _ => point.status = LineStatus::BadProfile,
        }
        point
    }
}
