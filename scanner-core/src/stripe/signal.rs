//! The stripe signal of a pixel: what the laser adds (DIM) or how much of the laser's colour a
//! pixel shows (LIM), made for the laser's [`LaserColour`].
//!
//! Each pixel first gives a byte, its *magnitude* (one pass over a row, the kernels below); the
//! signal is the magnitude itself, or for the difference method with a coloured laser its
//! square `m² / 9` (at most 7225, so a 3×1 sum fits a `u16`):
//! - gray: the gray level, DIM its positive change (a gray camera sees no colour; the laser's
//!   colour does not matter);
//! - YUYV and RGB24, white laser: the luma, DIM its positive change;
//! - red, green or blue laser: DIM the light *added* to that channel, squared (laser light only
//!   adds: a drop in any channel — a shadow, a change of exposure — never makes a stripe;
//!   squared like the paper's eq. 11 so that the stripe's core outweighs the low halo of
//!   scattered light around it). In RGB, white light added with it counts too (the least added
//!   to the other two channels): a camera's colour processing turns a saturated laser white,
//!   even lowering its red (seen on the real photographs' glint), while a rise in one other
//!   channel alone is not the laser's. LIM: the channel minus the mean of the other two (a
//!   white surface shows nothing, a red stripe on it does).
//! - YUYV channels are BT.601 full range, `R = Y + 1.40 Cr`, `G = Y − 0.34 Cb − 0.72 Cr`,
//!   `B = Y + 1.77 Cb`, with the chroma of each pair of pixels; the difference method adds the
//!   change of Y and of the chroma (full resolution from Y), the light-intensity method uses the
//!   chroma alone (half resolution along rows).
//!
//! The paper's eq. 11 (`Σ (V_R − V_N)²` over R, G, B) itself is not used: it squares every
//! change, a drop as well, so a drop of 15 DN in blue between the two exposures passes the
//! threshold as a stripe does (found on the real photographs of `tests/data/real-stripes`).

use super::frame::PixelFormat;
use super::simd;

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
pub(crate) struct SignalKind {
    pub format: PixelFormat,
    pub method: Method,
    pub colour: LaserColour,
}

#[inline]
fn luma(p: &[u8]) -> u8 {
    crate::colour::luma([p[0], p[1], p[2]])
}

/// Index of the laser's channel and of the other two (white: none).
#[inline]
const fn channels(c: LaserColour) -> Option<(usize, usize, usize)> {
    match c {
        LaserColour::Red => Some((0, 1, 2)),
        LaserColour::Green => Some((1, 0, 2)),
        LaserColour::Blue => Some((2, 0, 1)),
        LaserColour::White => None,
    }
}

/// Chroma weights (×64) of the laser's channel: `(Cb, Cr)`.
#[inline]
const fn chroma_weights(c: LaserColour) -> (i16, i16) {
    match c {
        LaserColour::Red => (0, 90),
        LaserColour::Green => (-22, -46),
        LaserColour::Blue => (113, 0),
        LaserColour::White => (0, 0),
    }
}

/// Chroma weights (×16) of the laser channel's excess over the other two's mean.
#[inline]
const fn excess_weights(c: LaserColour) -> (i16, i16) {
    match c {
        LaserColour::Red => (-11, 28),
        LaserColour::Green => (-20, -23),
        LaserColour::Blue => (31, -6),
        LaserColour::White => (0, 0),
    }
}

/// The laser colour's channel of a YUYV pixel, `Y + chroma`, clamped.
#[inline]
fn yuv_value(c: LaserColour, y: u8, u: u8, v: u8) -> u8 {
    let (wb, wr) = chroma_weights(c);
    let (cb, cr) = (i16::from(u) - 128, i16::from(v) - 128);
    (i16::from(y) + ((wb * cb + wr * cr) >> 6)).clamp(0, 255) as u8
}

/// Y, U, V of pixel `x` of a YUYV row (the chroma of its pair).
#[inline]
fn yuyv_at(row: &[u8], x: usize) -> (u8, u8, u8) {
    let pair = &row[4 * (x / 2)..][..4];
    (row[2 * x], pair[1], pair[3])
}

/// What the signal is made of: the frame's format, the method and the laser's colour.
impl SignalKind {
    /// Whether the signal is the squared magnitude (DIM of a coloured laser).
    #[inline]
    pub(crate) fn squared(self) -> bool {
        self.method == Method::Dim
            && self.format != PixelFormat::Gray8
            && self.colour != LaserColour::White
    }

    /// The signal of a magnitude.
    #[inline]
    pub(crate) fn value(self, m: u8) -> u16 {
        let m = u16::from(m);
        if self.squared() { m * m / 9 } else { m }
    }

    /// The smallest magnitude whose signal reaches `v` (256: none).
    pub(crate) fn magnitude_for(self, v: u16) -> u16 {
        (0..=255u8)
            .find(|&m| self.value(m) >= v)
            .map_or(256, u16::from)
    }
}

/// The magnitude of pixel `x` of a row (the per-pixel form of [`magnitudes`]).
#[inline(always)]
fn magnitude(k: SignalKind, row: &[u8], reference: &[u8], x: usize) -> u8 {
    match k.format {
        PixelFormat::Gray8 => match k.method {
            Method::Lim => row[x],
            Method::Dim => row[x].saturating_sub(reference[x]),
        },
        PixelFormat::Yuyv => {
            let (y, u, v) = yuyv_at(row, x);
            match k.method {
                Method::Lim => yuyv_lim(k.colour, y, u, v),
                Method::Dim => {
                    let (ry, ru, rv) = yuyv_at(reference, x);
                    yuyv_dim(k.colour, [y, u, v], [ry, ru, rv])
                }
            }
        }
        PixelFormat::Rgb24 => {
            let p = &row[3 * x..][..3];
            match k.method {
                Method::Lim => rgb_lim(k.colour, p),
                Method::Dim => rgb_dim(k.colour, p, &reference[3 * x..][..3]),
            }
        }
    }
}

/// LIM magnitude of an RGB pixel: the laser channel's excess over the others' mean (white:
/// luma).
#[inline(always)]
fn rgb_lim(c: LaserColour, p: &[u8]) -> u8 {
    match channels(c) {
        Some((k, a, b)) => p[k].saturating_sub(((u16::from(p[a]) + u16::from(p[b])) / 2) as u8),
        None => luma(p),
    }
}

/// DIM magnitude of an RGB pixel: the light added to the laser's channel, plus the white light
/// added with it (the least added to the other two channels: a saturated laser turns white in a
/// camera's colour processing, and a rise in one other channel alone is not the laser's);
/// white: the luma's change.
#[inline(always)]
fn rgb_dim(c: LaserColour, p: &[u8], r: &[u8]) -> u8 {
    match channels(c) {
        Some((k, a, b)) => {
            let own = p[k].saturating_sub(r[k]);
            let white = p[a].saturating_sub(r[a]).min(p[b].saturating_sub(r[b]));
            own.saturating_add(white)
        }
        None => luma(p).saturating_sub(luma(r)),
    }
}

/// LIM magnitude of a YUYV pixel from its pair's chroma (white: Y).
#[inline(always)]
fn yuyv_lim(c: LaserColour, y: u8, u: u8, v: u8) -> u8 {
    if c == LaserColour::White {
        return y;
    }
    let (wb, wr) = excess_weights(c);
    let (cb, cr) = (i16::from(u) - 128, i16::from(v) - 128);
    ((wb * cb + wr * cr) >> 4).clamp(0, 255) as u8
}

/// DIM magnitude of a YUYV pixel: the light added to the laser's channel, `ΔY + chroma(Δ)`.
#[inline(always)]
fn yuyv_dim(c: LaserColour, now: [u8; 3], before: [u8; 3]) -> u8 {
    let (wb, wr) = chroma_weights(c);
    let d = |i: usize| i16::from(now[i]) - i16::from(before[i]);
    (d(0) + ((wb * d(1) + wr * d(2)) >> 6)).clamp(0, 255) as u8
}

/// Magnitudes of the pixels `x0 .. x0 + out.len()` of one row. `reference` must be given for
/// DIM (the caller checks). The luma kernels read 16 pixels at a time through fixed-size arrays
/// so that the even-byte gather of YUYV becomes a vector mask-and-pack.
#[inline]
pub(crate) fn magnitudes(k: SignalKind, row: &[u8], reference: &[u8], x0: usize, out: &mut [u8]) {
    let n = out.len();
    match (k.format, k.method, k.colour) {
        (PixelFormat::Gray8, Method::Lim, _) => out.copy_from_slice(&row[x0..x0 + n]),
        (PixelFormat::Gray8, Method::Dim, _) => {
            for ((o, &v), &r) in out
                .iter_mut()
                .zip(&row[x0..x0 + n])
                .zip(&reference[x0..x0 + n])
            {
                *o = v.saturating_sub(r);
            }
        }
        (PixelFormat::Yuyv, Method::Lim, LaserColour::White) => {
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
        (PixelFormat::Yuyv, Method::Dim, LaserColour::White) => {
            let (cur, refs) = (&row[2 * x0..2 * (x0 + n)], &reference[2 * x0..2 * (x0 + n)]);
            // The vector kernel where there is one, this portable loop for the rest.
            let fast = simd::yuyv_dim_white(cur, refs, out);
            let (out, cur, refs, n) = (
                &mut out[fast..],
                &cur[2 * fast..],
                &refs[2 * fast..],
                n - fast,
            );
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
        (PixelFormat::Yuyv, method, colour) => yuyv_colour(method, colour, row, reference, x0, out),
        (PixelFormat::Rgb24, method, colour) => rgb_colour(method, colour, row, reference, x0, out),
    }
}

/// [`magnitudes`] of RGB: 16 pixels (48 bytes) at a time through fixed-size arrays, so that
/// the three-way de-interleave becomes vector shuffles; the rest pixel by pixel.
#[inline]
fn rgb_colour(
    method: Method,
    colour: LaserColour,
    row: &[u8],
    reference: &[u8],
    x0: usize,
    out: &mut [u8],
) {
    let n = out.len();
    let (cur, refs) = (&row[3 * x0..3 * (x0 + n)], &reference[3 * x0..3 * (x0 + n)]);
    let mut outs = out.chunks_exact_mut(16);
    match method {
        Method::Lim => {
            for (o, p) in (&mut outs).zip(cur.chunks_exact(48)) {
                let p: &[u8; 48] = p.try_into().unwrap_or(&[0; 48]);
                match colour {
                    LaserColour::Red => excess::<0, 1, 2>(p, o),
                    LaserColour::Green => excess::<1, 0, 2>(p, o),
                    LaserColour::Blue => excess::<2, 0, 1>(p, o),
                    LaserColour::White => lumas(p, o),
                }
            }
        }
        Method::Dim => {
            for (o, (p, r)) in (&mut outs).zip(cur.chunks_exact(48).zip(refs.chunks_exact(48))) {
                let (p, r): (&[u8; 48], &[u8; 48]) = (
                    p.try_into().unwrap_or(&[0; 48]),
                    r.try_into().unwrap_or(&[0; 48]),
                );
                // The light added to every byte first (a plain vector loop), then per pixel.
                let mut d = [0u8; 48];
                for ((d, &p), &r) in d.iter_mut().zip(p).zip(r) {
                    *d = p.saturating_sub(r);
                }
                match colour {
                    LaserColour::Red => added::<0, 1, 2>(&d, o),
                    LaserColour::Green => added::<1, 0, 2>(&d, o),
                    LaserColour::Blue => added::<2, 0, 1>(&d, o),
                    LaserColour::White => {
                        let (mut a, mut b) = ([0u8; 16], [0u8; 16]);
                        lumas(p, &mut a);
                        lumas(r, &mut b);
                        for ((o, a), b) in o.iter_mut().zip(a).zip(b) {
                            *o = a.saturating_sub(b);
                        }
                    }
                }
            }
        }
    }
    let done = n - outs.into_remainder().len();
    let k = SignalKind {
        format: PixelFormat::Rgb24,
        method,
        colour,
    };
    for (i, o) in out.iter_mut().enumerate().skip(done) {
        *o = magnitude(k, row, reference, x0 + i);
    }
}

/// The DIM magnitude of 16 RGB pixels from the light added to each of their bytes: channel `K`
/// plus the lesser of `A` and `B` (constants, so that the picks are fixed shuffles). Worked out
/// for every byte at once — each byte plus the lesser of the bytes `A − K` and `B − K` away, in
/// plain vector loops over shifted copies — and then every third byte taken: SSE2 has no byte
/// shuffle to de-interleave RGB, but shifted loads are cheap.
#[inline(always)]
fn added<const K: usize, const A: usize, const B: usize>(d: &[u8; 48], out: &mut [u8]) {
    // Byte `j + K` with bytes `j + A` and `j + B`: every index within the 48.
    let mut e = [0u8; 48];
    for j in 0..46 {
        e[j + K] = d[j + K].saturating_add(d[j + A].min(d[j + B]));
    }
    for (i, o) in out.iter_mut().enumerate().take(16) {
        *o = e[3 * i + K];
    }
}

/// The luma of 16 RGB pixels.
#[inline(always)]
fn lumas(p: &[u8; 48], out: &mut [u8]) {
    for (i, o) in out.iter_mut().enumerate().take(16) {
        let (r, g, b) = (
            u16::from(p[3 * i]),
            u16::from(p[3 * i + 1]),
            u16::from(p[3 * i + 2]),
        );
        // `colour::luma` written out over 16 pixels, so that the vector unit takes them together.
        let [wr, wg, wb] = crate::colour::LUMA_WEIGHTS;
        *o = ((wr * r + wg * g + wb * b + 128) >> 8) as u8;
    }
}

/// The LIM magnitude of 16 RGB pixels: channel `K` minus the mean of `A` and `B`.
#[inline(always)]
fn excess<const K: usize, const A: usize, const B: usize>(p: &[u8; 48], out: &mut [u8]) {
    for (i, o) in out.iter_mut().enumerate().take(16) {
        let mean = ((u16::from(p[3 * i + A]) + u16::from(p[3 * i + B])) / 2) as u8;
        *o = p[3 * i + K].saturating_sub(mean);
    }
}

/// [`magnitudes`] of a coloured laser in YUYV: whole pairs, 8 at a time through fixed-size
/// arrays (the chroma shared by a pair is read once); an odd first or last pixel on its own.
#[inline]
fn yuyv_colour(
    method: Method,
    colour: LaserColour,
    row: &[u8],
    reference: &[u8],
    x0: usize,
    out: &mut [u8],
) {
    let k = SignalKind {
        format: PixelFormat::Yuyv,
        method,
        colour,
    };
    let mut x = x0;
    let mut out = out;
    if x % 2 == 1 && !out.is_empty() {
        out[0] = magnitude(k, row, reference, x);
        out = &mut out[1..];
        x += 1;
    }
    let pairs = out.len() / 2;
    let (cur, refs) = (
        &row[2 * x..2 * (x + 2 * pairs)],
        &reference[2 * x..2 * (x + 2 * pairs)],
    );
    let (head, tail) = out.split_at_mut(2 * pairs);
    match method {
        Method::Lim => {
            let (wb, wr) = excess_weights(colour);
            for (o, p) in head.chunks_exact_mut(2).zip(cur.chunks_exact(4)) {
                let (cb, cr) = (i16::from(p[1]) - 128, i16::from(p[3]) - 128);
                let v = ((wb * cb + wr * cr) >> 4).clamp(0, 255) as u8;
                o[0] = v;
                o[1] = v;
            }
        }
        Method::Dim => {
            let (wb, wr) = chroma_weights(colour);
            // The vector kernel where there is one, this portable loop for the rest.
            let fast = simd::yuyv_dim_colour(wb, wr, cur, refs, head);
            let (head, cur, refs, x) = (
                &mut head[fast..],
                &cur[2 * fast..],
                &refs[2 * fast..],
                x + fast,
            );
            let total = head.len();
            let mut outs = head.chunks_exact_mut(16);
            let mut groups = cur.chunks_exact(32).zip(refs.chunks_exact(32));
            for (o, (p, r)) in (&mut outs).zip(&mut groups) {
                let (p, r): (&[u8; 32], &[u8; 32]) = (
                    p.try_into().unwrap_or(&[0; 32]),
                    r.try_into().unwrap_or(&[0; 32]),
                );
                let d = |i: usize| i16::from(p[i]) - i16::from(r[i]);
                for j in 0..8 {
                    let c = (wb * d(4 * j + 1) + wr * d(4 * j + 3)) >> 6;
                    o[2 * j] = (d(4 * j) + c).clamp(0, 255) as u8;
                    o[2 * j + 1] = (d(4 * j + 2) + c).clamp(0, 255) as u8;
                }
            }
            let done = total - outs.into_remainder().len();
            for (i, o) in head.iter_mut().enumerate().skip(done) {
                *o = magnitude(k, row, reference, x + i);
            }
        }
    }
    if let Some(o) = tail.first_mut() {
        *o = magnitude(k, row, reference, x + 2 * pairs);
    }
}

/// The signal of the pixels `x0 .. x0 + out.len()` of one row, 256 at a time through a byte
/// buffer of magnitudes.
#[inline]
pub(crate) fn row(k: SignalKind, row: &[u8], reference: &[u8], x0: usize, out: &mut [u16]) {
    let mut buf = [0u8; 256];
    for (c, chunk) in out.chunks_mut(256).enumerate() {
        let m = &mut buf[..chunk.len()];
        magnitudes(k, row, reference, x0 + 256 * c, m);
        for (o, &v) in chunk.iter_mut().zip(m.iter()) {
            *o = k.value(v);
        }
    }
}

/// Signal of the single pixel `x` of a row, and whether its raw value is clipped (255 in any
/// channel of RGB, in Y of YUYV).
#[inline(always)]
pub(crate) fn pixel(k: SignalKind, row: &[u8], reference: &[u8], x: usize) -> (u16, bool) {
    let bpp = k.format.bytes_per_pixel();
    let p = &row[x * bpp..][..bpp];
    let clipped = match k.format {
        PixelFormat::Gray8 | PixelFormat::Yuyv => p[0] == 255,
        PixelFormat::Rgb24 => p.contains(&255),
    };
    (k.value(magnitude(k, row, reference, x)), clipped)
}

/// The signed change of the value in the laser's channel of every `step`-th pixel of `xs` in a
/// row, for the noise estimate of DIM, each given to `f`; pixels clipped to black or white in
/// both frames are left out (they show no noise, and a frame that is mostly black would
/// otherwise seem noise-free). Gray and white-laser YUYV read their bytes directly.
#[inline]
pub(crate) fn signed_changes(
    k: SignalKind,
    row: &[u8],
    reference: &[u8],
    xs: core::ops::Range<usize>,
    step: usize,
    mut f: impl FnMut(i16),
) {
    let mut take = |a: u8, b: u8| {
        if !((a == 0 || a == 255) && a == b) {
            f(i16::from(a) - i16::from(b));
        }
    };
    match (k.format, k.colour) {
        (PixelFormat::Gray8, _) => {
            for x in xs.step_by(step) {
                take(row[x], reference[x]);
            }
        }
        (PixelFormat::Yuyv, LaserColour::White) => {
            for x in xs.step_by(step) {
                take(row[2 * x], reference[2 * x]);
            }
        }
        (PixelFormat::Yuyv, c) => {
            for x in xs.step_by(step) {
                let ((y, u, v), (ry, ru, rv)) = (yuyv_at(row, x), yuyv_at(reference, x));
                take(yuv_value(c, y, u, v), yuv_value(c, ry, ru, rv));
            }
        }
        (PixelFormat::Rgb24, LaserColour::White) => {
            for x in xs.step_by(step) {
                take(luma(&row[3 * x..][..3]), luma(&reference[3 * x..][..3]));
            }
        }
        (PixelFormat::Rgb24, c) => {
            // The change of what the magnitude adds up: the laser's channel and the white
            // light with it (the lesser change of the other two).
            let (k, a, b) = channels(c).unwrap_or((0, 1, 2));
            for x in xs.step_by(step) {
                let (p, r) = (&row[3 * x..][..3], &reference[3 * x..][..3]);
                if (p[k] == 0 || p[k] == 255) && p[k] == r[k] {
                    continue;
                }
                let d = |i: usize| i16::from(p[i]) - i16::from(r[i]);
                f((d(k) + d(a).min(d(b))).clamp(-255, 255));
            }
        }
    }
}

/// The brightness of pixel `x` of a row in the laser's channel (gray, luma for white, the
/// channel itself in RGB, `Y + chroma` in YUYV): of the laser-off reference, how much light the
/// surface there returns, the albedo the stripe's profile is multiplied by.
#[inline]
pub(crate) fn level(k: SignalKind, row: &[u8], x: usize) -> u8 {
    match (k.format, channels(k.colour)) {
        (PixelFormat::Gray8, _) => row[x],
        (PixelFormat::Yuyv, None) => row[2 * x],
        (PixelFormat::Yuyv, Some(_)) => {
            let (y, u, v) = yuyv_at(row, x);
            yuv_value(k.colour, y, u, v)
        }
        (PixelFormat::Rgb24, None) => luma(&row[3 * x..][..3]),
        (PixelFormat::Rgb24, Some((c, _, _))) => row[3 * x + c],
    }
}

/// The LIM signal of one pixel (for the background histogram of LIM).
#[inline]
pub(crate) fn lim_of(k: SignalKind, row: &[u8], x: usize) -> u8 {
    let lim = SignalKind {
        method: Method::Lim,
        ..k
    };
    magnitude(lim, row, row, x)
}

/// Fills `sig` and `clipped` with the signal of the pixels at byte offsets `first`,
/// `first + step`, … of `frame` (and `reference`): one line of samples, down a column
/// (`step == stride`) or along a row. Gray and white-laser YUYV read their bytes directly; the
/// others each pixel on its row (a YUYV pixel's chroma is found from its place in the row).
pub(crate) fn fill(
    k: SignalKind,
    frame: &[u8],
    reference: &[u8],
    stride: usize,
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
    let bytes_are_signal = k.format == PixelFormat::Gray8
        || (k.format == PixelFormat::Yuyv && k.colour == LaserColour::White);
    match (bytes_are_signal, k.method) {
        (true, Method::Lim) => run(sig, clipped, first, step, |i| {
            (u16::from(frame[i]), frame[i] == 255)
        }),
        (true, Method::Dim) => run(sig, clipped, first, step, |i| {
            let v = frame[i];
            (u16::from(v.saturating_sub(reference[i])), v == 255)
        }),
        (false, _) => {
            let bpp = k.format.bytes_per_pixel();
            let (row0, x0) = (first - first % stride, (first % stride) / bpp);
            let down = step == stride;
            let mut n = 0;
            run(sig, clipped, first, step, |_| {
                let (start, x) = if down {
                    (row0 + n * stride, x0)
                } else {
                    (row0, x0 + n * step / bpp)
                };
                n += 1;
                let end = (start + stride).min(frame.len());
                pixel(k, &frame[start..end], &reference[start..end], x)
            });
        }
    }
}
