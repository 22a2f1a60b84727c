//! What an extraction gives: each line's status and centre ([`StripePoint`], [`LineStatus`]), the
//! frame's lines ([`Extraction`]) and why a frame was not read ([`StripeError`]).

use core::fmt;

use super::config::StripeConfig;
use super::frame::{FrameError, PixelFormat};
use super::signal;

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
    pub(super) const NONE: Self = Self {
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
    pub(super) const fn invalid(p: Self) -> Self {
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

/// What [`Extractor::extract`](super::Extractor::extract) found.
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
    /// The widest band this frame accepts, pixels: [`band_limit`](super::band_limit) of its width, or
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
