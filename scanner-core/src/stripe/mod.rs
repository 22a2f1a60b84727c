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
//! Where each step lives: `config` (what is asked), `threshold` (1), `track` (2), `lines` (the
//! frame read along a line), `judge` (3, and the frame's lines judged together: widths, cuts,
//! edges, runs), `report` (what is given back); `signal`, `simd` and `estimate` are the kernels
//! they share.
//!
//! All state lives in an [`Extractor`] the caller owns, sized by the const generic `W` (largest
//! number of lines and largest profile length); a call allocates nothing.

mod config;
mod estimate;
mod frame;
mod judge;
mod lines;
mod report;
pub mod shadow;
mod signal;
mod simd;
mod threshold;
mod track;

pub use config::{
    Axis, BYTE_PASS_WIDTH, MAX_BAND, MAX_HALF_WINDOW, Roi, SAMPLE_STEP, SPECKLE_PX, StripeConfig,
    band_limit,
};
pub use estimate::{EdgeFit, Estimator, MAX_WINDOW, Profile, Window};
pub use frame::{Frame, FrameError, PixelFormat};
pub use report::{
    CENTRE_FLOOR, CENTROID_EFFICIENCY, Extraction, LineStatus, Locate, StripeError, StripePoint,
    centre_sigma, peak_dn,
};
pub use signal::{LaserColour, Method};

use judge::{
    CUT_BINS, MIN_RUN, drop_sharp_edges, drop_still_edges, joins_run, mark_cut, mark_too_wide,
    runs, width_bin,
};
use lines::Io;
use threshold::{dim_threshold, lim_background, lim_threshold, quantile};

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
}

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
