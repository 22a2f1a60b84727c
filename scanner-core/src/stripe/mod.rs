//! Laser stripe extraction: for every image column (stripe roughly horizontal) or row (stripe
//! roughly vertical) the subpixel centre of the stripe, its peak, its width and a status that says
//! why a line has no valid centre (paper sections 3B, 3C and 4).
//!
//! # How a frame is read
//! 1. **Threshold**, automatic, from sampled rows before the pass: DIM from a robust noise
//!    estimate of the signed change over every 32nd row (its mode, and its spread below the
//!    mode); LIM from the bright tail of the laser-off reference (or the frame), then, after the
//!    pass, halfway to the median peak of the lit lines (section 4).
//! 2. **One pass in memory order.** Each row becomes a row of signal values (LIM intensity, or
//!    DIM change, eq. 11) and the 3×1 mask sums of the last three rows update per-line state: the
//!    strongest peak and the strongest peak at least `separation` lines away from it (a
//!    competing reflection or glint). Sums below a floor derived from the threshold cannot make a
//!    stripe, so for gray and YUYV each row marks, in bytes, the 64-column blocks that hold a
//!    sample able to reach it, and only those blocks are summed and tracked. Row mode reads each
//!    row once, contiguously.
//! 3. **Per line**, a window around the peak is read again (±6 samples, widened to
//!    `half_window` when the profile has not come down to the background) and judged: no stripe,
//!    competing peaks, saturated plateau, too wide (or on a halo), too narrow — or a centre from
//!    the chosen [`Estimator`].
//!
//! All state lives in an [`Extractor`] the caller owns, sized by the const generic `W` (largest
//! number of lines and largest profile length); a call allocates nothing.

mod estimate;
mod frame;
pub mod shadow;
mod signal;
mod simd;

pub use estimate::{EdgeFit, Estimator, MAX_WINDOW, Profile, Window};
pub use frame::{Frame, FrameError, PixelFormat};
pub use signal::{LaserColour, Method};

use core::fmt;

/// Largest `half_window` an extractor accepts: a window of 225 samples holds a band of
/// [`MAX_BAND`] pixels with its flanks.
pub const MAX_HALF_WINDOW: usize = 112;
/// Widest band any frame may have, pixels: what a window of `2 × MAX_HALF_WINDOW + 1` samples
/// holds with 32 samples of background either side ([`band_limit`] of a 4000-pixel image).
pub const MAX_BAND: f32 = 160.0;
/// The widest stripe or shadow band accepted in an image `width` pixels wide, pixels: 64 px or
/// 4 % of the width, whichever is more (a laser out of focus, close to the object or seen by a
/// 4K camera; a shadow's band), at most [`MAX_BAND`]. Within it, a line is refused as too wide
/// only against the frame's own lines ([`StripeConfig::width_spread`]).
pub fn band_limit(width: usize) -> f32 {
    (0.04 * width as f32).clamp(64.0, MAX_BAND)
}
/// Widest region the byte-wide column pass takes (64 blocks of 64 columns, one bit each).
pub const BYTE_PASS_WIDTH: usize = 64 * 64;
/// Half size of the first, narrow window read around a peak.
const NARROW_HALF_WINDOW: usize = 6;

/// Reference levels below this (DN) are taken as this for [`LineStatus::Print`]: in a dark
/// reference the ratio of two noise levels means nothing.
const PRINT_FLOOR: u8 = 12;
/// Smallest half size of the second window, read when the first has not come down to the
/// background: room enough to see a halo or a hump beside a narrow stripe (the 3σ tails of a
/// 14 px one).
const HALO_HALF_WINDOW: usize = 24;

/// `true` if both ends of a window (two samples each) are within 5 % of the height of the
/// sample at `rough` above the lowest end sample: the stripe has come down to the background
/// inside the window. Five samples, whatever the window's length.
fn settled(sig: &[u16], rough: usize) -> bool {
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
fn half_run(sig: &[u16], rough: usize) -> (usize, usize) {
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
const CUT_BINS: usize = 2 * MAX_BAND as usize + 1;

/// Regions of a frame's lines over which [`mark_too_wide`] takes the stripe's median width.
const WIDTH_REGIONS: usize = 8;

/// Fewest valid lines of a region for its own median width (fewer: the frame's).
const MIN_REGION_LINES: u32 = 8;

/// The half-pixel bin of a width.
fn width_bin(w: f32) -> usize {
    ((w * 2.0) as usize).min(CUT_BINS - 1)
}

/// Marks valid lines wider than `spread` times the median width of the valid lines of their
/// region (an eighth of the lines; the whole frame's when the region has fewer than
/// [`MIN_REGION_LINES`]) [`LineStatus::TooWide`], or [`LineStatus::Saturated`] when their
/// clipped plateau is longer than `max_plateau`: a halo, a glint or a blur beside the stripe,
/// measured against the stripe itself rather than a fixed limit (a stripe saturated and wide
/// everywhere is the stripe). `spread` 0 keeps every line.
fn mark_too_wide(points: &mut [StripePoint], spread: f32, max_plateau: usize) {
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
const CUT_RUN: usize = 4;

/// The eighth-octave bin of a peak (0 and 1 in bin 0; within 9 % of its value).
fn octave_bin(v: u16) -> usize {
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
fn octave_value(bin: usize) -> f32 {
    let (octave, eighth) = (bin / 8, bin % 8);
    (8 + eighth) as f32 * libm::exp2f(octave as f32) / 8.0
}

/// Marks valid lines that are both narrower than `fraction` of the median width of the frame's
/// valid lines and weaker than `peak_fraction` of their median peak [`LineStatus::Cut`]: the tail of the light
/// sheet on a surface whose border it has passed. Narrow alone is not enough (a real stripe's
/// width varies with speckle), nor weak alone (a dark surface).
fn mark_cut(points: &mut [StripePoint], fraction: f32, peak_fraction: f32) {
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
fn cut_runs(points: &mut [StripePoint], suspect: impl Fn(&StripePoint) -> bool) {
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
fn drop_still_edges(points: &mut [StripePoint], last: &mut [[f32; 2]], fraction: f32) {
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
const MIN_SOFT_RAMP: f32 = 10.0;

/// Narrowest line whose edges [`Extractor::extract`] finds unless asked for every line's
/// ([`StripeConfig::edges`]), pixels: a Gaussian profile's ramp is 0.72 of its width, so
/// narrower lines never reach [`MIN_SOFT_RAMP`] (and their edges cost a quarter of the
/// extraction's time).
const MIN_EDGE_WIDTH: f32 = 12.0;

/// Drops (NaN) each edge of the valid lines that rises in less than `fraction` of the median
/// ramp of that edge over the frame's valid lines ([`StripePoint::ramps`]): the band cut by an
/// outline, a border or dark ink, sharper than its own flanks. With `cut` (a laser's stripe,
/// whose centre such a cut pulls), the lines are [`LineStatus::Cut`] instead, where that median
/// is at least [`MIN_SOFT_RAMP`] and the sharp lines make runs ([`cut_runs`]). `fraction` 0
/// keeps every edge.
fn drop_sharp_edges(points: &mut [StripePoint], fraction: f32, cut: bool) {
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
const CONTINUITY_GAP: usize = 2;

/// How far a stripe's centre may move from one line to the next, pixels (a stripe crossing the
/// lines at up to 63°, beyond which the other axis is the one to scan).
const CONTINUITY_SLOPE: f32 = 2.0;

/// Fewest lines of a run of continuous centres: the light sheet meets a surface in a curve
/// over many lines, while a colour fringe at a printed edge, a glint or a speck shows in one to
/// three (the real two-plane frames' fringes run along a square's side for two or three rows).
const MIN_RUN: u16 = 4;

/// Whether centres `a` on line `i` and `b` on line `j` can be one stripe.
fn continuous((i, a): (usize, f32), (j, b): (usize, f32)) -> bool {
    (a - b).abs() <= CONTINUITY_SLOPE * i.abs_diff(j) as f32 + 1.0
}

/// The root of `i` in a union-find forest `parent`.
fn root(parent: &mut [u16], mut i: usize) -> usize {
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
fn runs(points: &[StripePoint], parent: &mut [u16], size: &mut [u16]) {
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
fn joins_run(points: &[StripePoint], size: &[u16], line: usize, centre: f32) -> bool {
    let hi = (line + CONTINUITY_GAP + 1).min(points.len().saturating_sub(1));
    (line.saturating_sub(CONTINUITY_GAP + 1)..=hi)
        .filter(|&j| j != line && size[j] >= MIN_RUN)
        .any(|j| continuous((line, centre), (j, points[j].centre)))
}

/// The automatic thresholds sample every this many rows.
pub const SAMPLE_STEP: usize = 32;

/// Which way the stripe runs, and so which lines are scanned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// One result per image column: the stripe is roughly horizontal; centres are rows.
    Columns,
    /// One result per image row: the stripe is roughly vertical; centres are columns.
    Rows,
}

/// A rectangle of the frame, pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Roi {
    /// Left column.
    pub x: usize,
    /// Top row.
    pub y: usize,
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
}

/// Settings of the extraction. The threshold is not among them: it is automatic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripeConfig {
    /// Lines to scan.
    pub axis: Axis,
    /// Region of interest; `None` for the whole frame.
    pub roi: Option<Roi>,
    /// Light-intensity or difference-image method.
    pub method: Method,
    /// The laser's colour: the signal is made for it (ignored for gray frames).
    pub colour: LaserColour,
    /// Subpixel estimator.
    pub estimator: Estimator,
    /// Largest accepted full width at half maximum, pixels; infinite by default, so that the
    /// frame's [`band_limit`] and [`Self::width_spread`] decide (a value here only lowers them).
    pub max_width: f32,
    /// Smallest accepted full width at half maximum, pixels.
    pub min_width: f32,
    /// A line whose run of clipped (255) pixels at the peak is longer than this, and which is
    /// wider than the stripe around it ([`Self::width_spread`]), is [`LineStatus::Saturated`]
    /// (a glint) rather than too wide.
    pub max_plateau: usize,
    /// A second peak at least `separation` pixels away and stronger than this fraction of the
    /// first makes the line ambiguous.
    pub ambiguity: f32,
    /// Smallest distance between two peaks that count as different, pixels.
    pub separation: u16,
    /// Largest half size of the window read around each peak, pixels (≤ [`MAX_HALF_WINDOW`]).
    /// The window starts at ±6 and grows, centred on the profile's half-maximum run, only until
    /// the profile comes down to the background at its ends.
    pub half_window: usize,
    /// A valid line wider than this many times the median width of the frame's valid lines
    /// around it (an eighth of the lines) is [`LineStatus::TooWide`]: the limit of width that
    /// remains, measured on the stripe itself (0 keeps every line).
    pub width_spread: f32,
    /// A valid line narrower than this fraction of the median width of the frame's valid lines,
    /// and weaker than [`Self::cut_peak`] of their median peak, is [`LineStatus::Cut`] (0 keeps
    /// every line).
    pub cut_width: f32,
    /// Find the edges ([`StripePoint::edges`]) of every line (a shadow's); otherwise only of
    /// lines at least 12 px wide, for the check of a wide line cut by a border.
    pub edges: bool,
    /// The signal the edges ([`StripePoint::edges`]) cross: positive for a band whose full
    /// depth is known (a shadow's contrast scaled by the lamp's full share: 127.5 is half the
    /// lamp hidden); 0 for half of each band's own height.
    pub edge_level: f32,
    /// An edge that rises through the band's height in less than this fraction of the frame's
    /// median for that edge ([`StripePoint::ramps`]), where that median is softer than the lens
    /// makes an outline, is dropped (NaN): a border, an object's outline or dark ink cutting a
    /// wide stripe or a shadow's band, sharper than the band's own flanks (0 keeps every edge).
    pub edge_ramp: f32,
    /// A line with an edge dropped by [`Self::edge_ramp`] is [`LineStatus::Cut`] (true: a
    /// laser's wide stripe cut by a border, its centre pulled), or keeps its other edge (false:
    /// a shadow's).
    pub cut_sharp: bool,
    /// An edge that moved less than this fraction of its line's other edge since the last
    /// frame, where that one moved more than a pixel, is dropped (NaN): an outline or ink
    /// cutting a shadow's band stays put while the band moves on (0 keeps every edge).
    pub edge_motion: f32,
    /// The peak, as a fraction of the frame's median, below which a narrow line counts as cut:
    /// 0.5 for a laser (the sheet's tail beyond a border is weak); infinite for a shadow, whose
    /// band keeps its depth where an outline cuts it.
    pub cut_peak: f32,
    /// The laser speckle's share of a centre's standard uncertainty, pixels, added in
    /// quadrature to the sensor noise's ([`centre_sigma`]): [`SPECKLE_PX`] unless measured for
    /// the camera and laser at hand.
    pub speckle_px: f32,
    /// With the difference method, a valid line is [`LineStatus::Print`] where the laser-off
    /// reference's level (in the laser's channel) changes by more than this factor within two
    /// samples somewhere across its profile: the edge of dark print under the stripe. 0 keeps
    /// every line (the default: on a textured object it takes whole stretches of the stripe);
    /// 1.5 for an accuracy check on a printed board — the rig's dots (ink 0.06 on paper 0.8, a
    /// ratio of 13) and a real printed board's edges far exceed it, shading within two pixels
    /// does not come near it.
    pub print_ratio: f32,
}

/// A real webcam's speckle share of a stripe centre's uncertainty, pixels: the scatter of the
/// centres of real stripes on a flat board about a smooth curve, beyond the sensor noise's share
/// — 0.34 px on the four stripes of the Ciclop photographs (`scanner-core/tests/real_stripes.rs`),
/// checked on another camera and laser (`scanner-device/tests/real_two_plane.rs`). Coherent light
/// on a rough surface makes a grain the size of the lens's blur spot, and the stripe's centre
/// follows the grain, whatever the sensor noise.
pub const SPECKLE_PX: f32 = 0.34;

impl StripeConfig {
    /// Defaults for a method and axis: whole frame, a red laser, centroid estimator (the most
    /// robust on real webcam profiles, see the README), widths from 1.5 px (narrower is
    /// undersampled: no subpixel centre in it) up to the frame's [`band_limit`] and 3× the
    /// median width around the line, plateaus up to 12 px, ambiguity 0.5, separation 10 px
    /// (more once the scan's stripe is known to be wider), windows up to ±[`MAX_HALF_WINDOW`].
    pub const fn new(method: Method, axis: Axis) -> Self {
        Self {
            axis,
            roi: None,
            method,
            colour: LaserColour::Red,
            estimator: Estimator::Centroid,
            max_width: f32::INFINITY,
            min_width: 1.5,
            max_plateau: 12,
            ambiguity: 0.5,
            separation: 10,
            half_window: MAX_HALF_WINDOW,
            width_spread: 3.0,
            cut_width: 0.5,
            cut_peak: 0.5,
            print_ratio: 0.0,
            edges: false,
            edge_level: 0.0,
            edge_ramp: 0.5,
            cut_sharp: true,
            edge_motion: 0.2,
            speckle_px: SPECKLE_PX,
        }
    }
}

/// Why a line has no valid centre, or that it has one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LineStatus {
    /// A valid centre.
    Valid,
    /// Nothing above the threshold.
    NoStripe,
    /// A second, separate peak nearly as strong (reflection, glint, second laser).
    Ambiguous,
    /// A clipped plateau, wider than the stripe around it (glint or specular highlight).
    Saturated,
    /// Wider than allowed, sitting on a halo of scattered light much wider than the stripe, or
    /// with a second hump beside it in its window (a glint or reflection next to it) that would
    /// pull its centre.
    TooWide,
    /// Narrower than allowed (a hot pixel, not a stripe).
    TooNarrow,
    /// The profile passed every check but the estimator found no centre in it.
    BadProfile,
    /// Much narrower than the frame's other stripe lines: the stripe cut by an edge (the light
    /// sheet falling off a surface's border, so that only part of its profile lies on the
    /// surface, with its centre pulled inwards).
    Cut,
    /// Its centre belongs to no run of continuous centres over at least four lines: the light
    /// sheet meets a surface in a curve over many lines, so a lone peak or two is something
    /// else (a colour fringe at a printed edge, a glint, a speck); nor did the line's second
    /// peak continue the stripe.
    Isolated,
    /// The surface's brightness changes under the stripe by more than
    /// [`StripeConfig::print_ratio`] in the
    /// laser-off reference (the edge of dark print, of a marker, of a painted line): the
    /// profile is the light times the print, its centre pulled towards the brighter side (a
    /// couple of millimetres on the board's markers).
    Print,
}

impl LineStatus {
    /// Every status, in a fixed order (for tables and counters).
    pub const ALL: [LineStatus; 10] = [
        LineStatus::Valid,
        LineStatus::NoStripe,
        LineStatus::Ambiguous,
        LineStatus::Saturated,
        LineStatus::TooWide,
        LineStatus::TooNarrow,
        LineStatus::BadProfile,
        LineStatus::Cut,
        LineStatus::Isolated,
        LineStatus::Print,
    ];
}

impl fmt::Display for LineStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Valid => "valid",
            Self::NoStripe => "no stripe",
            Self::Ambiguous => "competing peaks",
            Self::Saturated => "saturated plateau",
            Self::TooWide => "too wide",
            Self::TooNarrow => "too narrow",
            Self::BadProfile => "no fit",
            Self::Cut => "cut by an edge",
            Self::Isolated => "isolated",
            Self::Print => "on a print's edge",
        })
    }
}

/// The stripe in one line. Two points are equal when every field is, a missing edge (NaN)
/// equal to a missing edge.
#[derive(Debug, Clone, Copy)]
pub struct StripePoint {
    /// Subpixel centre along the line in image coordinates (a row in column mode, a column in row
    /// mode); 0 unless `status` is [`LineStatus::Valid`].
    pub centre: f32,
    /// Largest signal sample near the peak.
    pub peak: u16,
    /// Full width at half maximum, pixels.
    pub width: f32,
    /// Standard uncertainty of `centre`, pixels: the sensor noise's ([`centre_sigma`]) and the
    /// speckle's ([`StripeConfig::speckle_px`]) in quadrature; 0 unless valid.
    pub sigma: f32,
    /// Valid, or why not.
    pub status: LineStatus,
    /// Longest run of clipped pixels at the peak.
    pub plateau: u16,
    /// The profile's half-maximum crossings, image coordinates along the line: where the signal
    /// rises through half its height and where it falls through it again (the two edges of a
    /// shadow's band, [`Self::located`]); NaN where the crossing is not inside the window read,
    /// where they were not looked for ([`StripeConfig::edges`]), and unless `status` is valid.
    pub edges: [f32; 2],
    /// Standard uncertainty of each edge, pixels: the noise over the profile's slope at the
    /// crossing, and the speckle's share, in quadrature; 0 where the edge is NaN.
    pub edge_sigma: [f32; 2],
    /// How many pixels each edge takes to rise through the band's height (the height over the
    /// flank's slope): a shadow's penumbra, the same all along its edge, or an outline's or an
    /// ink's edge, as sharp as the lens makes it.
    pub ramps: [f32; 2],
}

impl PartialEq for StripePoint {
    fn eq(&self, o: &Self) -> bool {
        let same = |a: [f32; 2], b: [f32; 2]| {
            a.iter()
                .zip(&b)
                .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
        };
        self.centre == o.centre
            && self.peak == o.peak
            && self.width == o.width
            && self.sigma == o.sigma
            && self.status == o.status
            && self.plateau == o.plateau
            && same(self.edges, o.edges)
            && same(self.edge_sigma, o.edge_sigma)
            && same(self.ramps, o.ramps)
    }
}

impl StripePoint {
    const NONE: Self = Self {
        centre: 0.0,
        peak: 0,
        width: 0.0,
        sigma: 0.0,
        status: LineStatus::NoStripe,
        plateau: 0,
        edges: [f32::NAN; 2],
        edge_sigma: [0.0; 2],
        ramps: [0.0; 2],
    };

    /// `p` without its centre and edges (its status to be set).
    const fn invalid(p: Self) -> Self {
        Self {
            centre: 0.0,
            sigma: 0.0,
            edges: [f32::NAN; 2],
            edge_sigma: [0.0; 2],
            ramps: [0.0; 2],
            ..p
        }
    }

    /// How wide what [`Locate`] picks is, samples: the stripe's FWHM for its centre, the ramp of
    /// an edge (NaN where that edge is missing).
    pub fn extent(&self, locate: Locate) -> f32 {
        match locate {
            Locate::Centre => self.width,
            Locate::RisingEdge => self.ramps[0],
            Locate::FallingEdge => self.ramps[1],
        }
    }

    /// What [`Locate`] picks of a valid line: its centre, or one of its edges, with its
    /// standard uncertainty; `None` where that is missing.
    pub fn located(&self, locate: Locate) -> Option<(f32, f32)> {
        if self.status != LineStatus::Valid {
            return None;
        }
        let (at, sigma) = match locate {
            Locate::Centre => (self.centre, self.sigma),
            Locate::RisingEdge => (self.edges[0], self.edge_sigma[0]),
            Locate::FallingEdge => (self.edges[1], self.edge_sigma[1]),
        };
        at.is_finite().then_some((at, sigma))
    }
}

/// What of a line's profile becomes its point: the stripe's centre (a laser), or one edge of the
/// band (a shadow: each edge is the border of its own plane of light).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Locate {
    /// The centre of the stripe ([`StripeConfig::estimator`]).
    #[default]
    Centre,
    /// Where the signal rises through half the band's height, the lower coordinate.
    RisingEdge,
    /// Where it falls through it again, the higher coordinate.
    FallingEdge,
}

/// How far the centroid's error exceeds the Cramér–Rao bound of a Gaussian profile
/// ([`centre_sigma`]): the RMS error of the valid centres over the RMS of their bounds on the
/// synthetic bench is 1.15–1.6, 1.37 overall (DIM, σ 1–4 px, peaks 20–130 DN; `--example
/// centre_uncertainty`, asserted in `scanner-core/tests/stripe.rs`); checked on the rig's scans
/// (`scanner-device/tests/uncertainty.rs`).
pub const CENTROID_EFFICIENCY: f32 = 1.2;

/// Smallest centre uncertainty given, pixels: what an 8-bit profile's quantisation and its
/// departure from the model leave on a strong stripe (the bench's p95 for peaks ≥ 130 DN).
pub const CENTRE_FLOOR: f32 = 0.02;

/// The standard uncertainty of a stripe centre, pixels: the Cramér–Rao bound of the position of
/// a Gaussian profile of full width `fwhm` and height `height` (signal units) in white noise of
/// standard deviation `noise` (signal units), `σ_c = noise / height · √(2 s / √π)` with
/// `s = fwhm / 2.3548` — times [`CENTROID_EFFICIENCY`], never below [`CENTRE_FLOOR`].
///
/// The bound comes from the Fisher information of the position,
/// `Σ (h · g'(x))² / noise² ≈ h² √π / (2 s noise²)` for `g` the unit Gaussian of σ `s`.
pub fn centre_sigma(height: f32, fwhm: f32, noise: f32) -> f32 {
    if !(height > 0.0 && fwhm > 0.0 && noise >= 0.0) {
        return f32::INFINITY;
    }
    let s = fwhm / 2.3548;
    let bound = noise / height * libm::sqrtf(2.0 * s / libm::sqrtf(core::f32::consts::PI));
    (CENTROID_EFFICIENCY * bound).max(CENTRE_FLOOR)
}

/// The light a stripe's [`StripePoint::peak`] stands for, DN: the magnitude whose signal it is
/// (for the difference image of a coloured laser the signal is the magnitude squared over 9;
/// otherwise the magnitude itself), for frames of `format` read with `cfg`.
pub fn peak_dn(format: PixelFormat, cfg: &StripeConfig, peak: u16) -> u16 {
    let kind = signal::SignalKind {
        format,
        method: cfg.method,
        colour: cfg.colour,
    };
    kind.magnitude_for(peak).min(255)
}

/// What [`Extractor::extract`] found.
#[derive(Debug, Clone, Copy)]
pub struct Extraction<'a> {
    /// One point per line of the region of interest.
    pub points: &'a [StripePoint],
    /// Image coordinate of the first line (column in column mode, row in row mode).
    pub first_line: usize,
    /// The automatic threshold, in signal units.
    pub threshold: u16,
    /// The frame's noise σ, DN of the change (DIM: measured below the mode of the signed change,
    /// at least a sixth of the threshold's margin; LIM: a sixth of the threshold above the
    /// background's bright tail, a rough figure).
    pub noise: f32,
    /// The widest band this frame accepts, pixels: [`band_limit`] of its width, or
    /// [`StripeConfig::max_width`] when that is less.
    pub width_limit: f32,
    /// The median width of the valid lines of the scan's last frame that had any, pixels (0
    /// before): the stripe's width measured on the data, which sets how far apart two peaks must
    /// be to compete (at least 1.5 of it).
    pub typical_width: f32,
}

impl Extraction<'_> {
    /// `(line, point)` for the valid lines, with `line` in image coordinates.
    pub fn valid(&self) -> impl Iterator<Item = (usize, &StripePoint)> + '_ {
        self.points
            .iter()
            .enumerate()
            .filter(|(_, p)| p.status == LineStatus::Valid)
            .map(|(i, p)| (self.first_line + i, p))
    }
}

/// Why an extraction could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum StripeError {
    /// The frame, reference or region of interest is unusable.
    Frame(FrameError),
    /// The difference-image method needs a reference frame.
    NoReference,
    /// A setting is out of range (the text names it).
    BadConfig(&'static str),
}

impl From<FrameError> for StripeError {
    fn from(e: FrameError) -> Self {
        Self::Frame(e)
    }
}

impl fmt::Display for StripeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Frame(e) => e.fmt(f),
            Self::NoReference => f.write_str("the difference-image method needs a reference frame"),
            Self::BadConfig(what) => write!(f, "bad stripe setting: {what}"),
        }
    }
}

impl core::error::Error for StripeError {}

/// Fixed-memory state of the extraction for at most `W` lines of at most `W` samples.
///
/// About `W × 35` bytes: own it once (a `static`, a `Box`, or the device's frame loop) and reuse
/// it for every frame.
pub struct Extractor<const W: usize> {
    rows: Aligned<[[u16; W]; 3]>,
    bytes: Aligned<[[u8; W]; 3]>,
    best: [u16; W],
    best_at: [u16; W],
    second: [u16; W],
    second_at: [u16; W],
    out: [StripePoint; W],
    /// Runs of continuous centres: union-find parents, then each line's run length.
    parent: [u16; W],
    run: [u16; W],
    /// The median width of the valid lines of the last frame that had any (0 before).
    typical_width: f32,
    /// Each line's edges in the last frame, as found (NaN where none).
    last_edges: [[f32; 2]; W],
    /// Whether the last frame had any edge (else `last_edges` is all NaN).
    edges_last: bool,
    /// The last extraction's lines, first line, threshold, noise and width limit.
    last: (usize, usize, u16, f32, f32),
}

/// Row buffers on a cache line's boundary: the pass copies or computes every row of a frame
/// into them, and aligned they made a 1600×1200 gray frame's LIM extraction about 5 % faster
/// (the row copy is most of it).
#[repr(align(64))]
struct Aligned<T>(T);

impl<const W: usize> Default for Extractor<W> {
    fn default() -> Self {
        Self::new()
    }
}

/// Per-line peak tracking over a stream of 3×1 sums: updates the strongest peak and the strongest
/// one at least `sep` lines away from it. Branch-free on purpose: it is the inner loop.
#[inline(always)]
fn track(
    t: u16,
    at: u16,
    sep: u16,
    best: &mut u16,
    best_at: &mut u16,
    second: &mut u16,
    second_at: &mut u16,
) {
    let far_b = at.wrapping_sub(*best_at) > sep;
    let far_s = at.wrapping_sub(*second_at) > sep;
    // Ties move the peak forward: on a clipped plateau it then ends at the plateau's far end and
    // the plateau's own shoulders stay within `sep` instead of looking like a rival.
    let gt = t >= *best;
    let cand_b = if far_b { *best } else { 0 };
    let cand_s = if far_s { *second } else { 0 };
    let (demote, demote_at) = if cand_b >= cand_s {
        (cand_b, *best_at)
    } else {
        (cand_s, *second_at)
    };
    let rival = far_b & (t > *second);
    let new_second = if gt {
        demote
    } else if rival {
        t
    } else {
        *second
    };
    let new_second_at = if gt {
        demote_at
    } else if rival {
        at
    } else {
        *second_at
    };
    *second = new_second;
    *second_at = new_second_at;
    *best_at = if gt { at } else { *best_at };
    *best = if gt { t } else { *best };
}

/// The three rows of a rolling buffer for row `r`: the one to write (slot `r % 3`) and the two
/// before it, newest first.
fn ring<T, const W: usize>(rows: &mut [[T; W]; 3], r: usize) -> (&mut [T; W], &[T; W], &[T; W]) {
    let [s0, s1, s2] = rows;
    match r % 3 {
        0 => (s0, &*s2, &*s1),
        1 => (s1, &*s0, &*s2),
        _ => (s2, &*s1, &*s0),
    }
}

/// Per-line state from some line on: best, its position, second, its position.
type Span<'a> = (&'a mut [u16], &'a mut [u16], &'a mut [u16], &'a mut [u16]);

/// [`track`] for the lines of `state` whose sums `t` reach `floor`.
#[inline(never)]
fn track_span(state: Span<'_>, t: &[u16], at: u16, sep: u16, floor: u16) {
    let (best, best_at, second, second_at) = state;
    for (i, &v) in t.iter().enumerate() {
        if v >= floor {
            track(
                v,
                at,
                sep,
                &mut best[i],
                &mut best_at[i],
                &mut second[i],
                &mut second_at[i],
            );
        }
    }
}

impl<const W: usize> Extractor<W> {
    /// A fresh extractor.
    pub const fn new() -> Self {
        Self {
            rows: Aligned([[0; W]; 3]),
            bytes: Aligned([[0; W]; 3]),
            best: [0; W],
            best_at: [0; W],
            second: [0; W],
            second_at: [0; W],
            out: [StripePoint::NONE; W],
            parent: [0; W],
            run: [0; W],
            typical_width: 0.0,
            last_edges: [[f32::NAN; 2]; W],
            edges_last: false,
            last: (0, 0, 0, 0.0, 0.0),
        }
    }

    /// The last frame's extraction again (nothing before the first).
    pub fn last(&self) -> Extraction<'_> {
        let (lines, first_line, threshold, noise, width_limit) = self.last;
        Extraction {
            points: &self.out[..lines],
            first_line,
            threshold,
            noise,
            width_limit,
            typical_width: self.typical_width,
        }
    }

    /// Extracts the stripe of `frame`. `reference` is the laser-off frame: required for
    /// [`Method::Dim`], used for the threshold of [`Method::Lim`] when given.
    ///
    /// # Errors
    /// [`StripeError`] for a reference of another shape, a missing reference, a region of
    /// interest outside the frame, more lines than `W`, or a setting out of range.
    pub fn extract(
        &mut self,
        frame: &Frame<'_>,
        reference: Option<&Frame<'_>>,
        cfg: &StripeConfig,
    ) -> Result<Extraction<'_>, StripeError> {
        let (roi, lines, length) = checked::<W>(frame, reference, cfg)?;
        let reference_or_frame = reference.unwrap_or(frame);
        let io = Io {
            frame,
            reference: reference_or_frame,
            kind: signal::SignalKind {
                format: frame.format(),
                method: cfg.method,
                colour: cfg.colour,
            },
            axis: cfg.axis,
            roi,
        };
        // Thresholds come from sampled rows before the pass, so that the pass can ignore the
        // background: 3×1 sums below `floor` cannot make a stripe or a rival (see `track`).
        let (threshold, floor, dim_noise) = match cfg.method {
            Method::Dim => {
                let (t, noise) = dim_threshold(&io);
                (t, t.saturating_mul(2), noise)
            }
            Method::Lim => {
                // a line counts as lit when the mean of its 3×1 mask exceeds the tail
                let tail = u16::from(lim_background(&io));
                (tail, 3 * (tail + 1), 0.0)
            }
        };
        // Two peaks compete only when further apart than the stripe is wide.
        let separation = cfg
            .separation
            .max(libm::ceilf(1.5 * self.typical_width).min(f32::from(u16::MAX)) as u16);
        match cfg.axis {
            Axis::Columns if roi.width <= BYTE_PASS_WIDTH => {
                self.track_columns_u8(&io, separation, floor)
            }
            Axis::Columns => self.track_columns(&io, separation, floor),
            Axis::Rows => self.track_rows(&io, separation, floor),
        }
        let width_limit = band_limit(frame.width()).min(cfg.max_width);
        let (threshold, noise) = match cfg.method {
            Method::Dim => (threshold, dim_noise),
            Method::Lim => {
                let t = lim_threshold(threshold, &self.best[..lines]);
                (t, (f32::from(t) - f32::from(threshold)).max(1.0) / 6.0)
            }
        };
        // window scratch, reused for every line (overwritten before it is read)
        let mut sig = [0u16; MAX_WINDOW];
        let mut clipped = [false; MAX_WINDOW];
        for line in 0..lines {
            let rough = usize::from(self.best_at[line]);
            self.out[line] = self.judge(
                &io,
                cfg,
                (line, rough),
                (length, width_limit),
                (threshold, noise),
                (&mut sig, &mut clipped),
            );
        }
        // A centre in a run of fewer than MIN_RUN lines is no stripe: its line's second peak
        // takes its place where that continues a run, else the line has none.
        runs(
            &self.out[..lines],
            &mut self.parent[..lines],
            &mut self.run[..lines],
        );
        let origin = match cfg.axis {
            Axis::Columns => roi.y,
            Axis::Rows => roi.x,
        };
        for line in 0..lines {
            let p = self.out[line];
            if p.status != LineStatus::Valid || self.run[line] >= MIN_RUN {
                continue;
            }
            let second = usize::from(self.second_at[line]);
            let continues = |c: f32| joins_run(&self.out[..lines], &self.run[..lines], line, c);
            let candidate = (self.second[line] > 0 && continues((origin + second) as f32))
                .then(|| {
                    self.judge(
                        &io,
                        cfg,
                        (line, second),
                        (length, width_limit),
                        (threshold, noise),
                        (&mut sig, &mut clipped),
                    )
                })
                .filter(|q| q.status == LineStatus::Valid && continues(q.centre));
            self.out[line] = candidate.unwrap_or(StripePoint {
                status: LineStatus::Isolated,
                ..StripePoint::invalid(p)
            });
        }
        mark_too_wide(&mut self.out[..lines], cfg.width_spread, cfg.max_plateau);
        mark_cut(&mut self.out[..lines], cfg.cut_width, cfg.cut_peak);
        // the edge checks, where any line has edges (a narrow laser's have none)
        let out = &mut self.out[..lines];
        if out.iter().any(|p| p.edges.iter().any(|e| e.is_finite())) {
            drop_still_edges(out, &mut self.last_edges[..lines], cfg.edge_motion);
            drop_sharp_edges(out, cfg.edge_ramp, cfg.cut_sharp);
            self.edges_last = true;
        } else if self.edges_last {
            self.last_edges[..lines].fill([f32::NAN; 2]);
            self.edges_last = false;
        }
        let mut widths = [0u32; CUT_BINS];
        let mut n = 0;
        for p in self.out[..lines]
            .iter()
            .filter(|p| p.status == LineStatus::Valid)
        {
            widths[width_bin(p.width)] += 1;
            n += 1;
        }
        if n > 0 {
            self.typical_width = (quantile(&widths, n, 0.5) as f32 + 0.5) / 2.0;
        }
        let first_line = match cfg.axis {
            Axis::Columns => roi.x,
            Axis::Rows => roi.y,
        };
        self.last = (lines, first_line, threshold, noise, width_limit);
        Ok(self.last())
    }

    fn reset(&mut self, lines: usize) {
        self.best[..lines].fill(0);
        self.best_at[..lines].fill(0);
        self.second[..lines].fill(0);
        self.second_at[..lines].fill(0);
    }

    /// Column mode: rows in memory order, per-column state.
    ///
    /// The 3×1 sums of each row are formed 64 columns at a time and the block is skipped unless
    /// one of them reaches `floor`: on a frame the stripe covers a few rows of each column, so the
    /// bookkeeping of [`track`] runs for a few per cent of the chunks and the pass runs at about
    /// the speed of reading the frame.
    fn track_columns(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16) {
        const BLOCK: usize = 64;
        let Roi {
            x,
            y,
            width,
            height,
        } = io.roi;
        self.reset(width);
        for r in 0..height {
            let (newest, older, oldest) = ring(&mut self.rows.0, r);
            signal::row(
                io.kind,
                io.frame.row(y + r),
                io.reference.row(y + r),
                x,
                &mut newest[..width],
            );
            if r < 2 {
                continue;
            }
            let at = (r - 1) as u16;
            let newest = &*newest;
            // Blocks of 64 columns: sums, and an OR of `sum − (floor − 1)` (saturating) that is
            // non-zero iff a sum reaches the floor; one horizontal reduction per block.
            let below = floor.saturating_sub(1);
            let mut b = 0;
            while b < width {
                let n = (width - b).min(BLOCK);
                let mut t = [0u16; BLOCK];
                let mut hit = 0u16;
                let rows = newest[b..b + n]
                    .iter()
                    .zip(&older[b..b + n])
                    .zip(&oldest[b..b + n]);
                for (t, ((&p, &q), &o)) in t.iter_mut().zip(rows) {
                    *t = p + q + o;
                    hit |= t.saturating_sub(below);
                }
                if hit != 0 {
                    let state = (
                        &mut self.best[b..],
                        &mut self.best_at[b..],
                        &mut self.second[b..],
                        &mut self.second_at[b..],
                    );
                    track_span(state, &t[..n], at, sep, floor);
                }
                b += n;
            }
        }
    }

    /// [`Self::track_columns`] on the pixels' one-byte magnitudes, for at most
    /// [`BYTE_PASS_WIDTH`] columns.
    ///
    /// A 3×1 sum reaches `floor` only if one of its three samples reaches `⌈floor / 3⌉`, so each
    /// row, as it is made, marks in a 64-bit mask the blocks of 64 columns holding a magnitude
    /// whose signal reaches that (one compare per pixel, in bytes). A centre row then forms exact
    /// sums only in the blocks its three rows mark (through a table from magnitude to signal); on
    /// a frame that is nearly all background that is a few blocks per row.
    fn track_columns_u8(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16) {
        if io.kind.squared() {
            let mut table = [0u16; 256];
            for (m, v) in table.iter_mut().enumerate() {
                *v = io.kind.value(m as u8);
            }
            self.track_bytes(io, sep, floor, |m| table[usize::from(m)]);
        } else {
            self.track_bytes(io, sep, floor, u16::from);
        }
    }

    /// [`Self::track_columns_u8`] with the signal of a magnitude given by `value` (monomorphic:
    /// the linear signals keep plain sums).
    #[inline(always)]
    fn track_bytes(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16, value: impl Fn(u8) -> u16) {
        const BLOCK: usize = 64;
        let Roi {
            x,
            y,
            width,
            height,
        } = io.roi;
        self.reset(width);
        let mark = io.kind.magnitude_for(floor.div_ceil(3));
        if mark > 255 {
            return;
        }
        let below = (mark as u8).saturating_sub(1);
        let mut lit = [0u64; 3];
        for r in 0..height {
            let (newest, older, oldest) = ring(&mut self.bytes.0, r);
            signal::magnitudes(
                io.kind,
                io.frame.row(y + r),
                io.reference.row(y + r),
                x,
                &mut newest[..width],
            );
            let mut marks = 0u64;
            for (b, chunk) in newest[..width].chunks(BLOCK).enumerate() {
                let mut hit = 0u8;
                for &v in chunk {
                    hit |= v.saturating_sub(below);
                }
                marks |= u64::from(hit != 0) << b;
            }
            lit[r % 3] = marks;
            if r < 2 {
                continue;
            }
            let at = (r - 1) as u16;
            let newest = &*newest;
            let mut blocks = lit[0] | lit[1] | lit[2];
            while blocks != 0 {
                let b = blocks.trailing_zeros() as usize * BLOCK;
                blocks &= blocks - 1;
                for c in b..(b + BLOCK).min(width) {
                    let sum = value(newest[c]) + value(older[c]) + value(oldest[c]);
                    if sum >= floor {
                        track(
                            sum,
                            at,
                            sep,
                            &mut self.best[c],
                            &mut self.best_at[c],
                            &mut self.second[c],
                            &mut self.second_at[c],
                        );
                    }
                }
            }
        }
    }

    /// Row mode: each row is one line, read contiguously.
    fn track_rows(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16) {
        let Roi {
            x,
            y,
            width,
            height,
        } = io.roi;
        self.reset(height);
        for r in 0..height {
            let buf = &mut self.rows.0[0][..width];
            signal::row(
                io.kind,
                io.frame.row(y + r),
                io.reference.row(y + r),
                x,
                buf,
            );
            let (mut b, mut ba, mut s, mut sa) = (0, 0, 0, 0);
            for (i, w) in buf.windows(3).enumerate() {
                let t = w[0] + w[1] + w[2];
                if t >= floor {
                    track(t, (i + 1) as u16, sep, &mut b, &mut ba, &mut s, &mut sa);
                }
            }
            self.best[r] = b;
            self.best_at[r] = ba;
            self.second[r] = s;
            self.second_at[r] = sa;
        }
    }

    /// Reads the window around the peak at `rough` of `line` and decides its status and centre.
    fn judge(
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

/// The frame, the reference (the frame itself for LIM without one), the signal and the region.
struct Io<'f, 'd> {
    frame: &'f Frame<'d>,
    reference: &'f Frame<'d>,
    kind: signal::SignalKind,
    axis: Axis,
    roi: Roi,
}

impl Io<'_, '_> {
    /// Signal and clipping of sample `i` of `line`, with `line` shifted by `dl` lines (clamped to
    /// the region).
    fn sample(&self, line: usize, i: usize, dl: isize) -> (u16, bool) {
        let (x, y) = self.sample_xy(line, i, dl);
        signal::pixel(self.kind, self.frame.row(y), self.reference.row(y), x)
    }

    fn sample_xy(&self, line: usize, i: usize, dl: isize) -> (usize, usize) {
        let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
        match self.axis {
            Axis::Columns => (
                self.roi.x + clamp(line as isize + dl, self.roi.width),
                self.roi.y + i,
            ),
            Axis::Rows => (
                self.roi.x + i,
                self.roi.y + clamp(line as isize + dl, self.roi.height),
            ),
        }
    }

    /// How sharply the surface's brightness changes under the stripe: the largest ratio of two
    /// reference levels (in the laser's channel) two samples apart, across the profile's
    /// half-maximum run and half its width beyond either side, levels taken no lower than
    /// [`PRINT_FLOOR`]. An edge of print (blurred over a pixel or two by the lens) changes the
    /// level by its whole contrast within two samples; shading, a smooth gradient, does not.
    fn print_under(&self, line: usize, start: usize, shape: &Profile) -> f32 {
        let pad = 0.5 * shape.fwhm + 1.0;
        let len = match self.axis {
            Axis::Columns => self.roi.height,
            Axis::Rows => self.roi.width,
        };
        let a = (start as f32 + shape.half_max.0 - pad).max(0.0) as usize;
        let b = ((start as f32 + shape.half_max.1 + pad) as usize).min(len - 1);
        let level = |i: usize| {
            let (x, y) = self.sample_xy(line, i, 0);
            signal::level(self.kind, self.reference.row(y), x).max(PRINT_FLOOR)
        };
        let (mut worst, mut before) = (1.0f32, [level(a), level(a)]);
        for i in a + 1..=b {
            let now = level(i);
            let (lo, hi) = (now.min(before[0]), now.max(before[0]));
            worst = worst.max(f32::from(hi) / f32::from(lo));
            before = [before[1], now];
        }
        worst
    }

    /// Signal and clipping of samples `start .. start + sig.len()` of `line`.
    fn window(&self, line: usize, start: usize, sig: &mut [u16], clipped: &mut [bool]) {
        let bpp = self.frame.format().bytes_per_pixel();
        let stride = self.frame.stride();
        let (first, step) = match self.axis {
            Axis::Columns => (
                (self.roi.y + start) * stride + (self.roi.x + line) * bpp,
                stride,
            ),
            Axis::Rows => (
                (self.roi.y + line) * stride + (self.roi.x + start) * bpp,
                bpp,
            ),
        };
        signal::fill(
            self.kind,
            self.frame.data(),
            self.reference.data(),
            stride,
            first,
            step,
            sig,
            clipped,
        );
    }

    /// Sobel response along the line (derivative along the line, smoothed [1 2 1] across lines)
    /// for samples `start..end`.
    fn sobel(&self, line: usize, start: usize, end: usize, out: &mut [i32]) {
        let len = match self.axis {
            Axis::Columns => self.roi.height,
            Axis::Rows => self.roi.width,
        };
        for (k, i) in (start..end).enumerate() {
            if i == 0 || i + 1 >= len {
                out[k] = 0;
                continue;
            }
            let mut g = 0i32;
            for (dl, w) in [(-1isize, 1i32), (0, 2), (1, 1)] {
                g += w
                    * (i32::from(self.sample(line, i + 1, dl).0)
                        - i32::from(self.sample(line, i - 1, dl).0));
            }
            out[k] = g;
        }
    }
}

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
fn dim_threshold(io: &Io<'_, '_>) -> (u16, f32) {
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
fn median_within_bins(hist: &[u32], n: u32) -> f32 {
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
const SAMPLE_COLUMNS: usize = 4;
/// Pixels the DIM noise estimate aims to sample.
const NOISE_SAMPLES: usize = 8192;

/// The bright tail of the LIM background: the 99.9th percentile of the reference's LIM signal
/// (or the frame's, without a reference) over every [`SAMPLE_STEP`]-th row and [`SAMPLE_COLUMNS`]-th
/// column.
fn lim_background(io: &Io<'_, '_>) -> u8 {
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
fn lim_threshold(tail: u16, best: &[u16]) -> u16 {
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
fn quantile(hist: &[u32], n: u32, q: f32) -> usize {
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
/// The checks of `extract`'s errors section, for `W` lines: the region of interest (the whole
/// frame by default), the number of lines across it and their length.
fn checked<const W: usize>(
    frame: &Frame<'_>,
    reference: Option<&Frame<'_>>,
    cfg: &StripeConfig,
) -> Result<(Roi, usize, usize), StripeError> {
    if let Some(r) = reference
        && !frame.same_shape(r)
    {
        return Err(FrameError::ReferenceMismatch.into());
    }
    if cfg.method == Method::Dim && reference.is_none() {
        return Err(StripeError::NoReference);
    }
    if cfg.half_window == 0 || cfg.half_window > MAX_HALF_WINDOW {
        return Err(StripeError::BadConfig("half_window must be 1..=112"));
    }
    if !(cfg.min_width >= 0.0 && cfg.max_width >= cfg.min_width) || cfg.width_spread.is_nan() {
        return Err(StripeError::BadConfig("need 0 ≤ min_width ≤ max_width"));
    }
    if !(cfg.cut_width >= 0.0 && cfg.cut_width < 1.0) {
        return Err(StripeError::BadConfig("need 0 ≤ cut_width < 1"));
    }
    if !(cfg.ambiguity > 0.0) {
        return Err(StripeError::BadConfig("ambiguity must be positive"));
    }
    let roi = cfg.roi.unwrap_or(Roi {
        x: 0,
        y: 0,
        width: frame.width(),
        height: frame.height(),
    });
    let inside = roi.width > 0
        && roi.height > 0
        && roi
            .x
            .checked_add(roi.width)
            .is_some_and(|e| e <= frame.width())
        && roi
            .y
            .checked_add(roi.height)
            .is_some_and(|e| e <= frame.height());
    if !inside {
        return Err(FrameError::BadRoi.into());
    }
    let (lines, length) = match cfg.axis {
        Axis::Columns => (roi.width, roi.height),
        Axis::Rows => (roi.height, roi.width),
    };
    for n in [lines, length, roi.width] {
        if n > W || n > usize::from(u16::MAX) {
            return Err(FrameError::TooLarge {
                asked: n,
                capacity: W.min(usize::from(u16::MAX)),
            }
            .into());
        }
    }
    Ok((roi, lines, length))
}
