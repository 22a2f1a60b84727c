//! What an extraction is asked to do: the stripe's axis, the region, the method and the limits
//! of a stripe ([`StripeConfig`]).

use super::estimate::Estimator;
use super::signal::{LaserColour, Method};

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
    /// wider than the stripe around it ([`Self::width_spread`]), is [`LineStatus::Saturated`](super::LineStatus::Saturated)
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
    /// around it (an eighth of the lines) is [`LineStatus::TooWide`](super::LineStatus::TooWide): the limit of width that
    /// remains, measured on the stripe itself (0 keeps every line).
    pub width_spread: f32,
    /// A valid line narrower than this fraction of the median width of the frame's valid lines,
    /// and weaker than [`Self::cut_peak`] of their median peak, is [`LineStatus::Cut`](super::LineStatus::Cut) (0 keeps
    /// every line).
    pub cut_width: f32,
    /// Find the edges ([`StripePoint::edges`](super::StripePoint::edges)) of every line (a shadow's); otherwise only of
    /// lines at least 12 px wide, for the check of a wide line cut by a border.
    pub edges: bool,
    /// The signal the edges ([`StripePoint::edges`](super::StripePoint::edges)) cross: positive for a band whose full
    /// depth is known (a shadow's contrast scaled by the lamp's full share: 127.5 is half the
    /// lamp hidden); 0 for half of each band's own height.
    pub edge_level: f32,
    /// An edge that rises through the band's height in less than this fraction of the frame's
    /// median for that edge ([`StripePoint::ramps`](super::StripePoint::ramps)), where that median is softer than the lens
    /// makes an outline, is dropped (NaN): a border, an object's outline or dark ink cutting a
    /// wide stripe or a shadow's band, sharper than the band's own flanks (0 keeps every edge).
    pub edge_ramp: f32,
    /// A line with an edge dropped by [`Self::edge_ramp`] is [`LineStatus::Cut`](super::LineStatus::Cut) (true: a
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
    /// quadrature to the sensor noise's ([`centre_sigma`](super::centre_sigma)): [`SPECKLE_PX`] unless measured for
    /// the camera and laser at hand.
    pub speckle_px: f32,
    /// With the difference method, a valid line is [`LineStatus::Print`](super::LineStatus::Print) where the laser-off
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
