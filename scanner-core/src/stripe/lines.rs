//! The frame read along lines: a sample, a window, a Sobel response and the print under a
//! stripe, in the extraction's signal ([`Io`]).

use super::config::{Axis, Roi};
use super::estimate::Profile;
use super::frame::Frame;
use super::signal;

/// Reference levels below this (DN) are taken as this for [`super::LineStatus::Print`]: in a dark
/// reference the ratio of two noise levels means nothing.
pub(super) const PRINT_FLOOR: u8 = 12;

/// The frame, the reference (the frame itself for LIM without one), the signal and the region.
pub(super) struct Io<'f, 'd> {
    pub(super) frame: &'f Frame<'d>,
    pub(super) reference: &'f Frame<'d>,
    pub(super) kind: signal::SignalKind,
    pub(super) axis: Axis,
    pub(super) roi: Roi,
}

impl Io<'_, '_> {
    /// Signal and clipping of sample `i` of `line`, with `line` shifted by `dl` lines (clamped to
    /// the region).
    pub(super) fn sample(&self, line: usize, i: usize, dl: isize) -> (u16, bool) {
        let (x, y) = self.sample_xy(line, i, dl);
        signal::pixel(self.kind, self.frame.row(y), self.reference.row(y), x)
    }

    pub(super) fn sample_xy(&self, line: usize, i: usize, dl: isize) -> (usize, usize) {
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
    pub(super) fn print_under(&self, line: usize, start: usize, shape: &Profile) -> f32 {
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
    pub(super) fn window(&self, line: usize, start: usize, sig: &mut [u16], clipped: &mut [bool]) {
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
    pub(super) fn sobel(&self, line: usize, start: usize, end: usize, out: &mut [i32]) {
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
