//! The decoder ([`JpegDecoder`]): the markers of a frame, its blocks, and the pixels written out
//! in the layout asked for.

use crate::huffman::*;
use crate::idct::*;
use crate::{JpegError, MAX_SIDE, Output};

/// One component of the frame.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Component {
    pub(crate) id: u8,
    pub(crate) h: usize,
    pub(crate) v: usize,
    pub(crate) quant: usize,
    pub(crate) dc: usize,
    pub(crate) ac: usize,
}

/// A reusable baseline JPEG decoder, no allocation. Each frame starts from the standard Huffman
/// tables (a motion-JPEG frame without its own means them), so that tables a corrupt frame
/// defined never reach the next one; quantisation tables, which every frame carries, are kept.
pub struct JpegDecoder {
    pub(crate) quant: [[u16; 64]; 4],
    pub(crate) quant_defined: [bool; 4],
    pub(crate) dc: [Huffman; 4],
    pub(crate) ac: [Huffman; 4],
    /// The last frame defined Huffman tables of its own.
    pub(crate) custom_tables: bool,
}

impl Default for JpegDecoder {
    fn default() -> Self {
        Self::new()
    }
}

/// The frame header's facts the scan needs.
#[derive(Clone, Copy)]
pub(crate) struct Frame {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) components: [Component; 3],
    pub(crate) count: usize,
    pub(crate) h_max: usize,
    pub(crate) v_max: usize,
}

/// A big-endian `u16` at `at`.
pub(crate) fn be16(data: &[u8], at: usize) -> Option<usize> {
    Some(usize::from(*data.get(at)?) << 8 | usize::from(*data.get(at + 1)?))
}

impl JpegDecoder {
    /// A decoder with the standard Huffman tables and no quantisation tables yet.
    pub fn new() -> Self {
        let mut d = JpegDecoder {
            quant: [[0; 64]; 4],
            quant_defined: [false; 4],
            dc: [
                Huffman::EMPTY,
                Huffman::EMPTY,
                Huffman::EMPTY,
                Huffman::EMPTY,
            ],
            ac: [
                Huffman::EMPTY,
                Huffman::EMPTY,
                Huffman::EMPTY,
                Huffman::EMPTY,
            ],
            custom_tables: false,
        };
        d.standard_tables();
        d
    }

    /// The tables of T.81 Annex K in slots 0 (luma) and 1 (chroma), as a stream without its own
    /// tables means them.
    fn standard_tables(&mut self) {
        for slot in 2..4 {
            self.dc[slot].defined = false;
            self.ac[slot].defined = false;
        }
        // The standard tables are valid: building them cannot fail.
        let _ = self.dc[0].build(&STD_DC_LUMA.0, &STD_DC_LUMA.1);
        let _ = self.dc[1].build(&STD_DC_CHROMA.0, &STD_DC_CHROMA.1);
        let _ = self.ac[0].build(&STD_AC_LUMA.0, &STD_AC_LUMA.1);
        let _ = self.ac[1].build(&STD_AC_CHROMA.0, &STD_AC_CHROMA.1);
    }

    /// Decodes one frame of `width × height` pixels into `out` (see [`Output`]), rows packed.
    ///
    /// # Errors
    /// [`JpegError`] naming what is wrong and where; `out` may then hold part of the frame.
    pub fn decode(
        &mut self,
        data: &[u8],
        width: usize,
        height: usize,
        output: Output,
        out: &mut [u8],
    ) -> Result<(), JpegError> {
        if data.get(..2) != Some(&[0xFF, 0xD8]) {
            return Err(JpegError::NotJpeg);
        }
        if self.custom_tables {
            self.standard_tables();
            self.custom_tables = false;
        }
        let mut frame: Option<Frame> = None;
        let mut restart_interval = 0usize;
        let mut pos = 2;
        loop {
            // The next marker, after any fill bytes.
            if data.get(pos) != Some(&0xFF) {
                return Err(match data.get(pos) {
                    None => JpegError::Truncated { at: pos },
                    Some(_) => JpegError::BadSegment {
                        marker: 0,
                        at: pos,
                        what: "a marker was expected here",
                    },
                });
            }
            while data.get(pos + 1) == Some(&0xFF) {
                pos += 1;
            }
            let at = pos;
            let marker = *data.get(pos + 1).ok_or(JpegError::Truncated { at })?;
            pos += 2;
            if matches!(marker, 0xD0..=0xD8 | 0x01) {
                continue; // no length: a stray restart marker, SOI or TEM
            }
            if marker == 0xD9 {
                return Err(JpegError::BadSegment {
                    marker,
                    at,
                    what: "the image ends before its data",
                });
            }
            let len = be16(data, pos).ok_or(JpegError::Truncated { at: pos })?;
            let body = data
                .get(pos + 2..pos + len.max(2))
                .ok_or(JpegError::Truncated { at: data.len() })?;
            if len < 2 {
                return Err(JpegError::BadSegment {
                    marker,
                    at,
                    what: "length shorter than itself",
                });
            }
            let bad = |what| JpegError::BadSegment { marker, at, what };
            match marker {
                0xDB => self
                    .quant_tables(body)
                    .ok_or_else(|| bad("bad quantisation table"))?,
                0xC4 => {
                    self.custom_tables = true;
                    self.huffman_tables(body)
                        .ok_or_else(|| bad("bad Huffman table"))?;
                }
                0xDD => {
                    restart_interval = be16(body, 0).ok_or_else(|| bad("too short"))?;
                }
                0xC0 | 0xC1 => {
                    let f = frame_header(body, at)?;
                    if (f.width, f.height) != (width, height) {
                        return Err(JpegError::Size {
                            width: f.width,
                            height: f.height,
                            want_width: width,
                            want_height: height,
                        });
                    }
                    frame = Some(f);
                }
                0xC2 | 0xC6 | 0xCA | 0xCE => {
                    return Err(JpegError::Unsupported {
                        what: "progressive JPEG",
                        at,
                    });
                }
                0xC3 | 0xC7 | 0xCB | 0xCF => {
                    return Err(JpegError::Unsupported {
                        what: "lossless JPEG",
                        at,
                    });
                }
                0xC5 | 0xC9 | 0xCC | 0xCD => {
                    return Err(JpegError::Unsupported {
                        what: "arithmetic-coded JPEG",
                        at,
                    });
                }
                0xDA => {
                    let mut f = frame.ok_or_else(|| bad("image data before the frame header"))?;
                    self.scan_header(body, at, &mut f)?;
                    let needed = match output {
                        Output::Yuyv => 2 * width * height,
                        Output::Gray => width * height,
                    };
                    if out.len() < needed {
                        return Err(JpegError::OutputTooSmall {
                            len: out.len(),
                            needed,
                        });
                    }
                    return self.scan(
                        &f,
                        restart_interval,
                        Bits::new(data, pos + len),
                        output,
                        &mut out[..needed],
                    );
                }
                _ => {} // APPn, COM, DNL and the like: skipped
            }
            pos += len;
        }
    }

    /// `DQT`: 8- or 16-bit tables, in zig-zag order.
    fn quant_tables(&mut self, mut body: &[u8]) -> Option<()> {
        while let [pq_tq, rest @ ..] = body {
            let (precision, slot) = (pq_tq >> 4, usize::from(pq_tq & 15));
            if slot > 3 || precision > 1 {
                return None;
            }
            let n = if precision == 0 { 64 } else { 128 };
            let values = rest.get(..n)?;
            for (k, q) in self.quant[slot].iter_mut().enumerate() {
                *q = if precision == 0 {
                    u16::from(values[k])
                } else {
                    u16::from(values[2 * k]) << 8 | u16::from(values[2 * k + 1])
                };
            }
            self.quant_defined[slot] = true;
            body = &rest[n..];
        }
        Some(())
    }

    /// `DHT`: one or more tables.
    fn huffman_tables(&mut self, mut body: &[u8]) -> Option<()> {
        while let [tc_th, rest @ ..] = body {
            let (class, slot) = (tc_th >> 4, usize::from(tc_th & 15));
            if slot > 3 || class > 1 {
                return None;
            }
            let counts: &[u8; 16] = rest.get(..16)?.try_into().ok()?;
            let total: usize = counts.iter().map(|&c| usize::from(c)).sum();
            let symbols = rest.get(16..16 + total)?;
            let table = if class == 0 {
                &mut self.dc[slot]
            } else {
                &mut self.ac[slot]
            };
            table.build(counts, symbols)?;
            body = &rest[16 + total..];
        }
        Some(())
    }

    /// `SOS`: which tables each component uses; only an interleaved scan of all components
    /// (baseline's one scan) is read.
    fn scan_header(&self, body: &[u8], at: usize, f: &mut Frame) -> Result<(), JpegError> {
        let bad = |what| JpegError::BadSegment {
            marker: 0xDA,
            at,
            what,
        };
        let n = usize::from(*body.first().ok_or(bad("too short"))?);
        if n != f.count {
            return Err(bad(
                "a scan of some components only (several scans are not read)",
            ));
        }
        for i in 0..n {
            let id = *body.get(1 + 2 * i).ok_or(bad("too short"))?;
            let tables = *body.get(2 + 2 * i).ok_or(bad("too short"))?;
            let c = f.components[..f.count]
                .iter_mut()
                .find(|c| c.id == id)
                .ok_or(bad("a component the frame does not have"))?;
            c.dc = usize::from(tables >> 4);
            c.ac = usize::from(tables & 15);
            if c.dc > 3 || c.ac > 3 {
                return Err(bad("table number above 3"));
            }
            if !self.dc[c.dc].defined || !self.ac[c.ac].defined {
                return Err(bad("a Huffman table that was never defined"));
            }
            if !self.quant_defined[c.quant] {
                return Err(bad("a quantisation table that was never defined"));
            }
        }
        Ok(())
    }

    /// The entropy-coded data of one interleaved scan, block by block into `out`.
    fn scan(
        &self,
        f: &Frame,
        restart_interval: usize,
        mut bits: Bits<'_>,
        output: Output,
        out: &mut [u8],
    ) -> Result<(), JpegError> {
        let (mcu_w, mcu_h) = (8 * f.h_max, 8 * f.v_max);
        let (mcus_x, mcus_y) = (f.width.div_ceil(mcu_w), f.height.div_ceil(mcu_h));
        let total = mcus_x * mcus_y;
        let mut pred = [0i32; 3];
        let mut coef = [[0f32; 8]; 8];
        let quant: [[f32; 64]; 3] =
            core::array::from_fn(|i| aan_quant(&self.quant[f.components[i].quant]));
        let mut pixels: Pixels = [[0; 8]; 8];
        if output == Output::Yuyv && f.count == 1 {
            for pair in out.chunks_exact_mut(2) {
                pair[1] = 128;
            }
        }
        for mcu in 0..total {
            if restart_interval > 0 && mcu > 0 && mcu % restart_interval == 0 {
                if !bits.restart() {
                    return Err(JpegError::Corrupt {
                        mcu,
                        what: "the restart marker is missing",
                    });
                }
                pred = [0; 3];
            }
            let (mx, my) = (mcu % mcus_x, mcu / mcus_x);
            for (ci, c) in f.components[..f.count].iter().enumerate() {
                let (dc, ac, q) = (&self.dc[c.dc], &self.ac[c.ac], &quant[ci]);
                for by in 0..c.v {
                    for bx in 0..c.h {
                        let last = block(&mut bits, dc, ac, q, &mut pred[ci], &mut coef).ok_or(
                            JpegError::Corrupt {
                                mcu,
                                what: "a code no table has, or a coefficient past the block",
                            },
                        )?;
                        let x0 = (mx * c.h + bx) * 8;
                        let y0 = (my * c.v + by) * 8;
                        let chroma = ci > 0;
                        if chroma && output == Output::Gray {
                            coef = [[0.0; 8]; 8];
                            continue;
                        }
                        idct(&mut coef, last, &mut pixels);
                        if chroma {
                            let (sx, sy) = (f.h_max / c.h, f.v_max / c.v);
                            put_chroma(&pixels, out, f, x0, y0, sx, sy, 2 * ci - 1);
                        } else {
                            put_luma(&pixels, out, f, x0, y0, output);
                        }
                    }
                }
            }
            if bits.overrun() {
                return Err(JpegError::Corrupt {
                    mcu,
                    what: "the data ends before the last block",
                });
            }
        }
        Ok(())
    }
}

/// `SOF0`/`SOF1` (at byte `at`): size and components, checked against what the decoder reads.
pub(crate) fn frame_header(body: &[u8], at: usize) -> Result<Frame, JpegError> {
    let bad = |what| JpegError::BadSegment {
        marker: 0xC0,
        at,
        what,
    };
    let unsupported = |what| JpegError::Unsupported { what, at };
    if body.len() < 6 {
        return Err(bad("too short"));
    }
    if body[0] != 8 {
        return Err(unsupported("12-bit samples"));
    }
    let height = be16(body, 1).ok_or(bad("too short"))?;
    let width = be16(body, 3).ok_or(bad("too short"))?;
    if width == 0 || height == 0 {
        return Err(bad(
            "zero width or height (a height set later by DNL is not read)",
        ));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(unsupported("wider or taller than 8192 pixels"));
    }
    let count = usize::from(body[5]);
    if count != 1 && count != 3 {
        return Err(unsupported("neither 1 nor 3 components"));
    }
    let mut components = [Component::default(); 3];
    for (i, c) in components.iter_mut().take(count).enumerate() {
        let b = body.get(6 + 3 * i..9 + 3 * i).ok_or(bad("too short"))?;
        *c = Component {
            id: b[0],
            h: usize::from(b[1] >> 4),
            v: usize::from(b[1] & 15),
            quant: usize::from(b[2]),
            dc: 0,
            ac: 0,
        };
        if c.quant > 3 {
            return Err(bad("quantisation table number above 3"));
        }
    }
    let (h_max, v_max) = if count == 1 {
        // One component is never interleaved: its blocks are read one at a time.
        components[0].h = 1;
        components[0].v = 1;
        (1, 1)
    } else {
        let (y, cb, cr) = (components[0], components[1], components[2]);
        let chroma_ok = cb.h == 1 && cb.v == 1 && cr.h == 1 && cr.v == 1;
        if !chroma_ok || !(1..=2).contains(&y.h) || !(1..=2).contains(&y.v) || y.v > y.h {
            return Err(unsupported(
                "chroma sampling other than 4:2:2, 4:2:0 or 4:4:4",
            ));
        }
        (y.h, y.v)
    };
    Ok(Frame {
        width,
        height,
        components,
        count,
        h_max,
        v_max,
    })
}

/// One block's coefficients, dequantised and scaled (`q` from [`aan_quant`]), into `coef`
/// (transposed; all zero on entry); returns the zig-zag index of the last one decoded (0: only
/// the DC term). `None` for a code no table has or a run past the block's end.
#[inline(always)]
pub(crate) fn block(
    bits: &mut Bits<'_>,
    dc: &Huffman,
    ac: &Huffman,
    q: &[f32; 64],
    pred: &mut i32,
    coef: &mut [Lanes; 8],
) -> Option<usize> {
    bits.refill();
    let size = u32::from(bits.symbol(dc)? & 15);
    *pred = pred.wrapping_add(bits.value(size));
    coef[0][0] = *pred as f32 * q[0];
    let mut last = 0;
    let mut k = 1;
    while k < 64 {
        if bits.count < 32 {
            bits.refill();
        }
        let fast = ac.fast_ac[bits.peek(LOOKUP_BITS) as usize];
        if fast != 0 {
            bits.consume(u32::from(fast as u16 & 15));
            k += usize::from((fast as u16 >> 4) & 15);
            if k > 63 {
                return None;
            }
            let at = usize::from(TRANSPOSED[k]);
            coef[at / 8][at % 8] = f32::from(fast >> 8) * q[k];
            last = k;
            k += 1;
            continue;
        }
        let rs = bits.symbol(ac)?;
        let (run, size) = (usize::from(rs >> 4), u32::from(rs & 15));
        if size == 0 {
            if run != 15 {
                break; // end of block
            }
            k += 16;
            continue;
        }
        k += run;
        if k > 63 {
            return None;
        }
        let at = usize::from(TRANSPOSED[k]);
        coef[at / 8][at % 8] = bits.value(size) as f32 * q[k];
        last = k;
        k += 1;
    }
    Some(last)
}

/// A luma block at pixel `(x0, y0)` into the output, clipped at the image's edges.
#[inline(always)]
pub(crate) fn put_luma(
    px: &Pixels,
    out: &mut [u8],
    f: &Frame,
    x0: usize,
    y0: usize,
    output: Output,
) {
    let step = match output {
        Output::Yuyv => 2,
        Output::Gray => 1,
    };
    let cols = f.width.saturating_sub(x0).min(8);
    let rows = f.height.saturating_sub(y0).min(8);
    for (r, src) in px.iter().enumerate().take(rows) {
        let start = ((y0 + r) * f.width + x0) * step;
        match (output, out.get_mut(start..start + 16)) {
            // A whole row of the block, the common case, in fixed-size steps.
            (Output::Yuyv, Some(d)) if cols == 8 => {
                for (c, &v) in src.iter().enumerate() {
                    d[2 * c] = v;
                }
            }
            (Output::Gray, _) if cols == 8 => out[start..start + 8].copy_from_slice(src),
            _ => {
                for (c, &v) in src.iter().enumerate().take(cols) {
                    out[start + step * c] = v;
                }
            }
        }
    }
}

/// A chroma block of component samples at `(x0, y0)` into the YUYV output's `U` (`offset` 1)
/// or `V` (3) bytes: each sample covers `sx × sy` pixels; a YUYV pair takes the sample over
/// its first pixel.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn put_chroma(
    px: &Pixels,
    out: &mut [u8],
    f: &Frame,
    x0: usize,
    y0: usize,
    sx: usize,
    sy: usize,
    offset: usize,
) {
    // Component samples → YUYV pairs: one each (sx = 2), or every other sample (sx = 1).
    let (first_pair, every) = (x0 * sx / 2, 2 / sx);
    let pairs = (f.width / 2).saturating_sub(first_pair).min(8 / every);
    for (r, src) in px.iter().enumerate() {
        for dy in 0..sy {
            let y = (y0 + r) * sy + dy;
            if y >= f.height {
                return;
            }
            let start = y * 2 * f.width + 4 * first_pair + offset;
            match out.get_mut(start..start + 29) {
                // Eight whole pairs, the common case, in fixed-size steps.
                Some(d) if pairs == 8 => {
                    for (c, &v) in src.iter().enumerate() {
                        d[4 * c] = v;
                    }
                }
                _ => {
                    for p in 0..pairs {
                        out[start + 4 * p] = src[every * p];
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inverse DCT by its definition (T.81 A.3.3), in `f64`.
    fn reference_idct(coef: &[[f64; 8]; 8]) -> [[f64; 8]; 8] {
        let c = |u: usize| {
            if u == 0 {
                core::f64::consts::FRAC_1_SQRT_2
            } else {
                1.0
            }
        };
        let pi = core::f64::consts::PI;
        let mut out = [[0.0; 8]; 8];
        for (y, row) in out.iter_mut().enumerate() {
            for (x, px) in row.iter_mut().enumerate() {
                let mut sum = 0.0;
                for (v, coef_row) in coef.iter().enumerate() {
                    for (u, &f) in coef_row.iter().enumerate() {
                        sum += c(u)
                            * c(v)
                            * f
                            * libm::cos((2 * x + 1) as f64 * u as f64 * pi / 16.0)
                            * libm::cos((2 * y + 1) as f64 * v as f64 * pi / 16.0);
                    }
                }
                *px = sum / 4.0 + 128.0;
            }
        }
        out
    }

    #[test]
    fn the_inverse_dct_matches_its_definition_to_the_rounding() {
        let mut state = 0x1234_5678_u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let mut q = [0u16; 64];
        for (k, q) in q.iter_mut().enumerate() {
            *q = 1 + (k as u16 % 7);
        }
        let scaled = aan_quant(&q);
        for trial in 0..500 {
            // Quantised coefficients in zig-zag order: a few, most small, as in real blocks.
            let mut zz = [0i32; 64];
            let n = 1 + (next() % 64) as usize;
            for z in zz.iter_mut().take(n) {
                *z = (next() % 121) as i32 - 60;
            }
            if trial % 5 == 0 {
                zz[0] = (next() % 2001) as i32 - 1000;
            }
            let mut natural = [[0.0f64; 8]; 8];
            let mut coef = [[0f32; 8]; 8];
            let mut last = 0;
            for k in 0..64 {
                let at = usize::from(ZIGZAG[k]);
                natural[at / 8][at % 8] = f64::from(zz[k]) * f64::from(q[k]);
                let t = usize::from(TRANSPOSED[k]);
                coef[t / 8][t % 8] = zz[k] as f32 * scaled[k];
                if zz[k] != 0 {
                    last = k;
                }
            }
            let want = reference_idct(&natural);
            let mut got = [[0u8; 8]; 8];
            idct(&mut coef, last, &mut got);
            for y in 0..8 {
                for x in 0..8 {
                    let w = want[y][x].clamp(0.0, 255.0);
                    let d = (f64::from(got[y][x]) - w).abs();
                    assert!(d <= 0.51, "trial {trial} ({y}, {x}): {} vs {w}", got[y][x]);
                }
            }
            assert_eq!(coef, [[0.0; 8]; 8], "the block is left zeroed");
        }
    }

    /// Huffman tables of one frame (here one whose image never comes) do not reach the next.
    #[test]
    fn a_frames_own_huffman_tables_end_with_it() {
        let mut d = JpegDecoder::new();
        let standard = d.dc[0].lookup;
        // SOI, then DHT: DC table 0 with one code of length 1 (symbol 7), then EOI.
        let frame = [
            0xFF, 0xD8, 0xFF, 0xC4, 0x00, 0x14, 0x00, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
            0, 7, 0xFF, 0xD9,
        ];
        let mut out = [0u8; 16];
        assert!(d.decode(&frame, 2, 4, Output::Yuyv, &mut out).is_err());
        assert_ne!(d.dc[0].lookup, standard, "the frame's table was read");
        let _ = d.decode(&[0xFF, 0xD8, 0xFF, 0xD9], 2, 4, Output::Yuyv, &mut out);
        assert_eq!(
            d.dc[0].lookup, standard,
            "the next frame starts from the standard"
        );
    }

    #[test]
    fn over_full_huffman_tables_are_refused() {
        let mut t = Huffman::EMPTY;
        // Three codes of one bit cannot be.
        let mut counts = [0u8; 16];
        counts[0] = 3;
        assert!(t.build(&counts, &[1, 2, 3]).is_none());
        // Counts that do not match the symbols given.
        counts[0] = 2;
        assert!(t.build(&counts, &[1]).is_none());
        assert!(t.build(&counts, &[1, 2]).is_some());
    }

    #[test]
    fn the_standard_tables_decode_their_own_codes() {
        let d = JpegDecoder::new();
        // The luminance DC code for size 0 is `00`, for size 5 `110`, for 11 `111111110`.
        for (bits, len, symbol) in [(0b00u32, 2, 0u8), (0b110, 3, 5), (0b1_1111_1110, 9, 11)] {
            let word = [(bits << (32 - len)).to_be_bytes(), [0; 4]].concat();
            let mut b = Bits::new(&word, 0);
            b.refill();
            assert_eq!(b.symbol(&d.dc[0]), Some(symbol));
            assert_eq!(b.count, 64 - len);
        }
    }
}
