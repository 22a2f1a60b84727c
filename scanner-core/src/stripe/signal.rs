//! The stripe signal of a pixel: intensity (LIM) or change against the reference (DIM, eq. 11).
//!
//! Signals are `u16` so that a 3×1 sum never overflows:
//! - gray and YUYV: LIM the luma, DIM the positive difference `max(I_N − I_R, 0)` (laser light
//!   only adds; eq. 11 with n = 1, as a plain difference);
//! - RGB24: LIM the luma `(77 R + 150 G + 29 B) / 256`; DIM eq. 11, `Σ (V_R − V_N)²` over the
//!   three channels, divided by 9 so that its largest value (3·255²/9 = 21675) keeps a 3×1 sum
//!   within `u16`.

use super::frame::PixelFormat;

/// Light-intensity or difference-image method (paper section 3C).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Light-intensity method: the stripe is the brightest thing in the line, above an automatic
    /// threshold.
    Lim,
    /// Difference-image method: the stripe is what changed against the laser-off reference.
    Dim,
}

#[inline]
fn luma(p: &[u8]) -> u16 {
    ((77 * u32::from(p[0]) + 150 * u32::from(p[1]) + 29 * u32::from(p[2])) >> 8) as u16
}

#[inline]
fn rgb_change(a: &[u8], b: &[u8]) -> u16 {
    let d = |i: usize| {
        let v = i32::from(a[i]) - i32::from(b[i]);
        (v * v) as u32
    };
    ((d(0) + d(1) + d(2)) / 9) as u16
}

/// Writes the signal of the pixels `x0 .. x0 + out.len()` of one row into `out`. `reference`
/// must be given for DIM (the caller checks).
#[inline]
pub(crate) fn row(
    format: PixelFormat,
    method: Method,
    row: &[u8],
    reference: &[u8],
    x0: usize,
    out: &mut [u16],
) {
    let n = out.len();
    match (format, method) {
        (PixelFormat::Gray8, Method::Lim) => {
            for (o, &v) in out.iter_mut().zip(&row[x0..x0 + n]) {
                *o = u16::from(v);
            }
        }
        (PixelFormat::Gray8, Method::Dim) => {
            for ((o, &v), &r) in out
                .iter_mut()
                .zip(&row[x0..x0 + n])
                .zip(&reference[x0..x0 + n])
            {
                *o = u16::from(v.saturating_sub(r));
            }
        }
        (PixelFormat::Yuyv, Method::Lim) => {
            for (o, p) in out
                .iter_mut()
                .zip(row[2 * x0..2 * (x0 + n)].chunks_exact(2))
            {
                *o = u16::from(p[0]);
            }
        }
        (PixelFormat::Yuyv, Method::Dim) => {
            let cur = row[2 * x0..2 * (x0 + n)].chunks_exact(2);
            let refs = reference[2 * x0..2 * (x0 + n)].chunks_exact(2);
            for ((o, p), r) in out.iter_mut().zip(cur).zip(refs) {
                *o = u16::from(p[0].saturating_sub(r[0]));
            }
        }
        (PixelFormat::Rgb24, Method::Lim) => {
            for (o, p) in out
                .iter_mut()
                .zip(row[3 * x0..3 * (x0 + n)].chunks_exact(3))
            {
                *o = luma(p);
            }
        }
        (PixelFormat::Rgb24, Method::Dim) => {
            let cur = row[3 * x0..3 * (x0 + n)].chunks_exact(3);
            let refs = reference[3 * x0..3 * (x0 + n)].chunks_exact(3);
            for ((o, p), r) in out.iter_mut().zip(cur).zip(refs) {
                *o = rgb_change(r, p);
            }
        }
    }
}

/// [`row`] for gray and YUYV, whose signal fits a byte: the same values as `u8`. Kept parallel
/// to [`row`] rather than generic over the output type on purpose: the merged version compiled
/// to a YUYV loop 15 % slower in the bench.
///
/// # Panics
/// Never for RGB24 input, which the caller routes to [`row`]; it writes nothing then.
#[inline]
pub(crate) fn row_u8(
    format: PixelFormat,
    method: Method,
    row: &[u8],
    reference: &[u8],
    x0: usize,
    out: &mut [u8],
) {
    let n = out.len();
    match (format, method) {
        (PixelFormat::Gray8, Method::Lim) => out.copy_from_slice(&row[x0..x0 + n]),
        (PixelFormat::Gray8, Method::Dim) => {
            for ((o, &v), &r) in out
                .iter_mut()
                .zip(&row[x0..x0 + n])
                .zip(&reference[x0..x0 + n])
            {
                *o = v.saturating_sub(r);
            }
        }
        (PixelFormat::Yuyv, Method::Lim) => {
            let cur = &row[2 * x0..2 * (x0 + n)];
            let mut outs = out.chunks_exact_mut(16);
            for (o, p) in (&mut outs).zip(cur.chunks_exact(32)) {
                let p: &[u8; 32] = p.try_into().unwrap_or(&[0; 32]);
                for (i, o) in o.iter_mut().enumerate() {
                    *o = p[2 * i];
                }
            }
            let done = n - outs.into_remainder().len();
            for (i, o) in out.iter_mut().enumerate().skip(done) {
                *o = cur[2 * i];
            }
        }
        (PixelFormat::Yuyv, Method::Dim) => {
            // 16 pixels (32 bytes) at a time with fixed-size arrays, so that the even-byte
            // gather becomes a vector mask-and-pack instead of a scalar loop.
            let (cur, refs) = (&row[2 * x0..2 * (x0 + n)], &reference[2 * x0..2 * (x0 + n)]);
            let mut outs = out.chunks_exact_mut(16);
            let mut pairs = cur.chunks_exact(32).zip(refs.chunks_exact(32));
            for (o, (p, r)) in (&mut outs).zip(&mut pairs) {
                let (p, r): (&[u8; 32], &[u8; 32]) = (
                    p.try_into().unwrap_or(&[0; 32]),
                    r.try_into().unwrap_or(&[0; 32]),
                );
                for (i, o) in o.iter_mut().enumerate() {
                    *o = p[2 * i].saturating_sub(r[2 * i]);
                }
            }
            let done = n - outs.into_remainder().len();
            for (i, o) in out.iter_mut().enumerate().skip(done) {
                *o = cur[2 * i].saturating_sub(refs[2 * i]);
            }
        }
        (PixelFormat::Rgb24, _) => {}
    }
}

/// Signal of the single pixel `x` of a row, and whether its raw value is clipped (255 in any
/// channel).
#[inline]
pub(crate) fn pixel(
    format: PixelFormat,
    method: Method,
    row: &[u8],
    reference: &[u8],
    x: usize,
) -> (u16, bool) {
    let bpp = format.bytes_per_pixel();
    let p = &row[x * bpp..][..bpp];
    let clipped = match format {
        PixelFormat::Gray8 | PixelFormat::Yuyv => p[0] == 255,
        PixelFormat::Rgb24 => p.contains(&255),
    };
    let v = match (format, method) {
        (PixelFormat::Gray8 | PixelFormat::Yuyv, Method::Lim) => u16::from(p[0]),
        (PixelFormat::Gray8 | PixelFormat::Yuyv, Method::Dim) => {
            u16::from(p[0].saturating_sub(reference[x * bpp]))
        }
        (PixelFormat::Rgb24, Method::Lim) => luma(p),
        (PixelFormat::Rgb24, Method::Dim) => rgb_change(&reference[x * bpp..][..3], p),
    };
    (v, clipped)
}

/// Signed luma difference of one pixel (for the noise estimate of DIM).
#[inline]
pub(crate) fn signed_change(format: PixelFormat, row: &[u8], reference: &[u8], x: usize) -> i16 {
    let bpp = format.bytes_per_pixel();
    let (p, r) = (&row[x * bpp..][..bpp], &reference[x * bpp..][..bpp]);
    match format {
        PixelFormat::Gray8 | PixelFormat::Yuyv => i16::from(p[0]) - i16::from(r[0]),
        PixelFormat::Rgb24 => luma(p) as i16 - luma(r) as i16,
    }
}

/// Luma of one pixel (for the background histogram of LIM).
#[inline]
pub(crate) fn luma_of(format: PixelFormat, row: &[u8], x: usize) -> u8 {
    let bpp = format.bytes_per_pixel();
    let p = &row[x * bpp..][..bpp];
    match format {
        PixelFormat::Gray8 | PixelFormat::Yuyv => p[0],
        PixelFormat::Rgb24 => luma(p) as u8,
    }
}

/// Fills `sig` and `clipped` with the signal of the pixels at byte offsets `first`,
/// `first + step`, … of `frame` (and `reference`): one line of samples in any direction. The
/// format and method are matched once, outside the loop.
pub(crate) fn fill(
    format: PixelFormat,
    method: Method,
    frame: &[u8],
    reference: &[u8],
    first: usize,
    step: usize,
    sig: &mut [u16],
    clipped: &mut [bool],
) {
    #[inline(always)]
    fn run(
        sig: &mut [u16],
        clipped: &mut [bool],
        first: usize,
        step: usize,
        mut f: impl FnMut(usize) -> (u16, bool),
    ) {
        let mut i = first;
        for (s, c) in sig.iter_mut().zip(clipped.iter_mut()) {
            (*s, *c) = f(i);
            i += step;
        }
    }
    match (format, method) {
        (PixelFormat::Gray8 | PixelFormat::Yuyv, Method::Lim) => {
            run(sig, clipped, first, step, |i| {
                (u16::from(frame[i]), frame[i] == 255)
            });
        }
        (PixelFormat::Gray8 | PixelFormat::Yuyv, Method::Dim) => {
            run(sig, clipped, first, step, |i| {
                let v = frame[i];
                (u16::from(v.saturating_sub(reference[i])), v == 255)
            });
        }
        (PixelFormat::Rgb24, Method::Lim) => run(sig, clipped, first, step, |i| {
            let p = &frame[i..i + 3];
            (luma(p), p.contains(&255))
        }),
        (PixelFormat::Rgb24, Method::Dim) => run(sig, clipped, first, step, |i| {
            let p = &frame[i..i + 3];
            (rgb_change(&reference[i..i + 3], p), p.contains(&255))
        }),
    }
}
