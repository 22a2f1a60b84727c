//! The stripe signal of a pixel: what the laser adds (DIM) or how much of the laser's colour a
//! pixel shows (LIM), made for the laser's [`LaserColour`].
//!
//! Signals:
//! - gray: the gray level (a gray camera sees no colour; the laser's colour does not matter);
//! - YUYV and RGB24, white laser: the luma (RGB DIM: its squared positive change, as below);
//! - YUYV and RGB24, red, green or blue laser: DIM the square of the *positive* change of that
//!   channel against the reference, `Δ² / 9` (laser light only adds; a drop in any channel — a
//!   shadow, a change of exposure — never makes a stripe; squared like eq. 11 so that the
//!   stripe's core outweighs the halo of scattered light around it), LIM the channel minus the
//!   mean of the other two (how
//!   much more of the laser's colour than of the others, so a white surface shows nothing and
//!   a dark red one little). YUYV channels come from BT.601 full-range YCbCr, the chroma shared
//!   by each pair of pixels.
//!
//! The paper's eq. 11 (`Σ (V_R − V_N)²` over R, G, B) itself is not used: it squares every
//! change, a drop as well, so a drop of 15 DN in blue between the two exposures passes the
//! threshold as a stripe does (found on the real photographs of `tests/data/real-stripes`).

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

/// The colour of the laser: the signal is made for it (red by default, the common line laser).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LaserColour {
    /// A red laser (635–660 nm).
    #[default]
    Red,
    /// A green laser (520–532 nm).
    Green,
    /// A blue or violet laser (405–450 nm).
    Blue,
    /// Any colour, by brightness (luma) alone.
    White,
}

impl LaserColour {
    /// Every colour, in a fixed order.
    pub const ALL: [LaserColour; 4] = [Self::Red, Self::Green, Self::Blue, Self::White];

    /// Its name, lower case.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Red => "red",
            Self::Green => "green",
            Self::Blue => "blue",
            Self::White => "white",
        }
    }
}

/// What the signal is made of: the frame's format, the method and the laser's colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Kind {
    pub format: PixelFormat,
    pub method: Method,
    pub colour: LaserColour,
}

#[inline]
fn luma(p: &[u8]) -> u8 {
    ((77 * u32::from(p[0]) + 150 * u32::from(p[1]) + 29 * u32::from(p[2])) >> 8) as u8
}

/// The laser colour's channel of an RGB pixel (white: the luma).
#[inline]
fn rgb_value(c: LaserColour, p: &[u8]) -> u8 {
    match c {
        LaserColour::Red => p[0],
        LaserColour::Green => p[1],
        LaserColour::Blue => p[2],
        LaserColour::White => luma(p),
    }
}

/// How much more of the laser's colour than of the other two an RGB pixel shows (white: luma).
#[inline]
fn rgb_lim(c: LaserColour, p: &[u8]) -> u8 {
    let excess = |k: usize, a: usize, b: usize| {
        p[k].saturating_sub(((u16::from(p[a]) + u16::from(p[b])) / 2) as u8)
    };
    match c {
        LaserColour::Red => excess(0, 1, 2),
        LaserColour::Green => excess(1, 0, 2),
        LaserColour::Blue => excess(2, 0, 1),
        LaserColour::White => luma(p),
    }
}

/// The laser colour's channel from BT.601 full-range YCbCr, in 1/256 steps (white: Y).
#[inline]
fn yuv_value(c: LaserColour, y: u8, u: u8, v: u8) -> u8 {
    let (y, cb, cr) = (i32::from(y), i32::from(u) - 128, i32::from(v) - 128);
    let x = match c {
        LaserColour::Red => y + ((359 * cr) >> 8),
        LaserColour::Green => y - ((88 * cb + 183 * cr) >> 8),
        LaserColour::Blue => y + ((454 * cb) >> 8),
        LaserColour::White => y,
    };
    x.clamp(0, 255) as u8
}

/// [`rgb_lim`] from YCbCr: the channel minus the mean of the others depends on chroma alone.
#[inline]
fn yuv_lim(c: LaserColour, y: u8, u: u8, v: u8) -> u8 {
    let (cb, cr) = (i32::from(u) - 128, i32::from(v) - 128);
    let x = match c {
        LaserColour::Red => (450 * cr - 183 * cb) >> 8,
        LaserColour::Green => -((315 * cb + 362 * cr) >> 8),
        LaserColour::Blue => (498 * cb - 88 * cr) >> 8,
        LaserColour::White => i32::from(y),
    };
    x.clamp(0, 255) as u8
}

/// Y, U, V of pixel `x` of a YUYV row (the chroma of its pair).
#[inline]
fn yuyv_at(row: &[u8], x: usize) -> (u8, u8, u8) {
    let pair = &row[4 * (x / 2)..][..4];
    (row[2 * x], pair[1], pair[3])
}

/// Square of the light added to one channel, `Δ⁺² / 9`.
#[inline]
fn added(now: u8, before: u8) -> u16 {
    let d = u16::from(now.saturating_sub(before));
    d * d / 9
}

/// A channel of the frame at least this bright may be saturated by the laser.
const BRIGHT: u8 = 128;

/// DIM of a coloured laser from the RGB of the frame and of the reference: the squared light
/// added to the laser's channel, plus that added to the other two where the laser's channel is
/// bright (a saturated red pixel spills into green and blue, and the camera's colour processing
/// may even lower its red: seen on the real photographs' glint). At most `3 · 255² / 9`.
/// Squared like eq. 11, which weights the stripe's core against the low halo of scattered light
/// around it — but of added light only. A white laser counts every channel.
#[inline]
fn dim_rgb(c: LaserColour, now: [u8; 3], before: [u8; 3]) -> u16 {
    let k = match c {
        LaserColour::Red => 0,
        LaserColour::Green => 1,
        LaserColour::Blue => 2,
        LaserColour::White => {
            return (0..3).map(|i| added(now[i], before[i])).sum();
        }
    };
    let own = added(now[k], before[k]);
    if now[k] < BRIGHT {
        return own;
    }
    own + added(now[(k + 1) % 3], before[(k + 1) % 3])
        + added(now[(k + 2) % 3], before[(k + 2) % 3])
}

/// R, G, B from BT.601 full-range YCbCr, in 1/256 steps.
#[inline]
fn yuv_rgb(y: u8, u: u8, v: u8) -> [u8; 3] {
    let (y, cb, cr) = (i32::from(y), i32::from(u) - 128, i32::from(v) - 128);
    [
        y + ((359 * cr) >> 8),
        y - ((88 * cb + 183 * cr) >> 8),
        y + ((454 * cb) >> 8),
    ]
    .map(|x| x.clamp(0, 255) as u8)
}

/// The signal of pixel `x` of a row whose colour matters (YUYV or RGB24 with a coloured laser,
/// RGB24 with a white one): LIM or DIM by `k`.
#[inline(always)]
fn colour_pixel(k: Kind, row: &[u8], reference: &[u8], x: usize) -> u16 {
    let rgb = |row: &[u8]| -> [u8; 3] {
        match k.format {
            PixelFormat::Rgb24 => [row[3 * x], row[3 * x + 1], row[3 * x + 2]],
            _ => {
                let (y, u, v) = yuyv_at(row, x);
                yuv_rgb(y, u, v)
            }
        }
    };
    match (k.format, k.method) {
        (PixelFormat::Rgb24, Method::Lim) => u16::from(rgb_lim(k.colour, &row[3 * x..][..3])),
        (_, Method::Lim) => {
            let (y, u, v) = yuyv_at(row, x);
            u16::from(yuv_lim(k.colour, y, u, v))
        }
        (_, Method::Dim) => dim_rgb(k.colour, rgb(row), rgb(reference)),
    }
}

/// Whether the luma kernels serve `k`: gray, or a white laser in YUYV.
#[inline]
fn luma_only(k: Kind) -> bool {
    k.format == PixelFormat::Gray8
        || (k.format == PixelFormat::Yuyv && k.colour == LaserColour::White)
}

/// Whether the signal fits a byte (the byte-wide pass can take it): everything but the squared
/// DIM of a colour channel.
#[inline]
pub(crate) fn fits_byte(k: Kind) -> bool {
    luma_only(k) || k.method == Method::Lim
}

/// [`colour_pixel`] over pixels `x0 ..` of a row.
#[inline(always)]
fn colour_row(k: Kind, row: &[u8], reference: &[u8], x0: usize, out: &mut [u16]) {
    for (i, o) in out.iter_mut().enumerate() {
        *o = colour_pixel(k, row, reference, x0 + i);
    }
}

/// Writes the signal of the pixels `x0 .. x0 + out.len()` of one row into `out`. `reference`
/// must be given for DIM (the caller checks).
#[inline]
pub(crate) fn row(k: Kind, row: &[u8], reference: &[u8], x0: usize, out: &mut [u16]) {
    if !luma_only(k) {
        return colour_row(k, row, reference, x0, out);
    }
    let n = out.len();
    match (k.format, k.method) {
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
        (_, Method::Lim) => {
            for (o, p) in out
                .iter_mut()
                .zip(row[2 * x0..2 * (x0 + n)].chunks_exact(2))
            {
                *o = u16::from(p[0]);
            }
        }
        (_, Method::Dim) => {
            let cur = row[2 * x0..2 * (x0 + n)].chunks_exact(2);
            let refs = reference[2 * x0..2 * (x0 + n)].chunks_exact(2);
            for ((o, p), r) in out.iter_mut().zip(cur).zip(refs) {
                *o = u16::from(p[0].saturating_sub(r[0]));
            }
        }
    }
}

/// [`row`] as bytes (the same values). The luma kernels are kept parallel to [`row`] rather
/// than generic over the output type on purpose: the merged version compiled to a YUYV loop
/// 15 % slower in the bench.
///
/// For a signal that [`fits_byte`] only; others are written as 0 (the caller routes them to
/// [`row`]).
#[inline]
pub(crate) fn row_u8(k: Kind, row: &[u8], reference: &[u8], x0: usize, out: &mut [u8]) {
    if !luma_only(k) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = colour_pixel(k, row, reference, x0 + i).min(255) as u8;
        }
        return;
    }
    let n = out.len();
    match (k.format, k.method) {
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
        (_, Method::Lim) => {
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
        (_, Method::Dim) => {
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
    }
}

/// Signal of the single pixel `x` of a row, and whether its raw value is clipped (255 in any
/// channel of RGB, in Y of YUYV).
#[inline]
pub(crate) fn pixel(k: Kind, row: &[u8], reference: &[u8], x: usize) -> (u16, bool) {
    let bpp = k.format.bytes_per_pixel();
    let p = &row[x * bpp..][..bpp];
    let clipped = match k.format {
        PixelFormat::Gray8 | PixelFormat::Yuyv => p[0] == 255,
        PixelFormat::Rgb24 => p.contains(&255),
    };
    let v = if luma_only(k) {
        u16::from(match k.method {
            Method::Lim => p[0],
            Method::Dim => p[0].saturating_sub(reference[x * bpp]),
        })
    } else {
        colour_pixel(k, row, reference, x)
    };
    (v, clipped)
}

/// Signed change of one pixel's colour value (for the noise estimate of DIM); `None` where the
/// value is clipped to black or white in both frames (such a pixel shows no noise, and a frame
/// that is mostly black would otherwise seem noise-free).
#[inline]
pub(crate) fn signed_change(k: Kind, row: &[u8], reference: &[u8], x: usize) -> Option<i16> {
    let value = |row: &[u8]| match k.format {
        PixelFormat::Gray8 => row[x],
        PixelFormat::Yuyv => {
            let (y, u, v) = yuyv_at(row, x);
            yuv_value(k.colour, y, u, v)
        }
        PixelFormat::Rgb24 => rgb_value(k.colour, &row[3 * x..][..3]),
    };
    let (a, b) = (value(row), value(reference));
    let clipped = |v: u8| v == 0 || v == 255;
    (!(clipped(a) && a == b)).then(|| i16::from(a) - i16::from(b))
}

/// The LIM signal of one pixel (for the background histogram of LIM).
#[inline]
pub(crate) fn lim_of(k: Kind, row: &[u8], x: usize) -> u8 {
    let lim = Kind {
        method: Method::Lim,
        ..k
    };
    pixel(lim, row, row, x).0 as u8
}

/// Fills `sig` and `clipped` with the signal of the pixels at byte offsets `first`,
/// `first + step`, … of `frame` (and `reference`): one line of samples in any direction. Rows
/// are `stride` bytes apart (a YUYV pixel's chroma is found from its place in its row).
pub(crate) fn fill(
    k: Kind,
    frame: &[u8],
    reference: &[u8],
    stride: usize,
    first: usize,
    step: usize,
    sig: &mut [u16],
    clipped: &mut [bool],
) {
    let bpp = k.format.bytes_per_pixel();
    let mut i = first;
    for (s, c) in sig.iter_mut().zip(clipped.iter_mut()) {
        let (row_start, x) = (i - i % stride, (i % stride) / bpp);
        let end = (row_start + stride).min(frame.len());
        (*s, *c) = pixel(k, &frame[row_start..end], &reference[row_start..end], x);
        i += step;
    }
}
