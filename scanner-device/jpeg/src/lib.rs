//! Motion-JPEG frames decoded straight into the layout the stripe extraction reads: YUYV (luma
//! and both chroma channels at the camera's 4:2:2 positions) or gray. A webcam's MJPEG frame is
//! already Y, Cb, Cr; decoding it to RGB and converting back would be two passes over the frame
//! that the stripe never needs.
//!
//! Baseline JPEG only (sequential, Huffman, 8-bit samples: `SOF0` and `SOF1`), which is what UVC
//! cameras send: one component (gray) or three with 4:2:2, 4:2:0 or 4:4:4 sampling, restart
//! intervals, and frames without Huffman tables (many webcams omit them and mean the standard
//! tables of ITU T.81 Annex K, which are used then). Progressive, lossless, arithmetic-coded and
//! 12-bit images are refused by name.
//!
//! Fixed memory: a [`JpegDecoder`] holds its tables (about 12 KiB) and is reused frame after frame;
//! it allocates nothing. The inverse DCT is the floating-point AAN factorisation of the IJG's
//! `jidctflt`, written over eight lanes at once so that it compiles to vector instructions on
//! x86-64 (SSE2) and aarch64 (NEON) alike; no input makes it panic (integer arithmetic wraps,
//! floats saturate into a byte).

#![no_std]
#![deny(missing_docs)]
#![deny(unsafe_code)]

use core::fmt;

/// The largest width or height decoded (pixels); a larger frame is refused before any work.
pub const MAX_SIDE: usize = 8192;

/// What the decoder writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// YUYV 4:2:2, `2 × width` bytes a row: chroma taken as it is for 4:2:2 images, repeated
    /// on two rows for 4:2:0, every other sample for 4:4:4, 128 for gray images.
    Yuyv,
    /// One byte of luma a pixel; the chroma is entropy-decoded (it must be) but not transformed.
    Gray,
}

/// Why a frame was not decoded. `at` is the byte offset in the frame where it was seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum JpegError {
    /// The data does not start with the JPEG start-of-image marker.
    NotJpeg,
    /// The data ends inside a segment or before the image data.
    Truncated {
        /// Where the data ran out.
        at: usize,
    },
    /// A kind of JPEG this decoder does not read.
    Unsupported {
        /// What it is.
        what: &'static str,
        /// Where it was declared.
        at: usize,
    },
    /// A segment whose contents are inconsistent.
    BadSegment {
        /// Its marker (the byte after `0xFF`).
        marker: u8,
        /// Where the segment starts.
        at: usize,
        /// What is wrong with it.
        what: &'static str,
    },
    /// The image is not the size the stream announced.
    Size {
        /// The image's width.
        width: usize,
        /// The image's height.
        height: usize,
        /// The width expected.
        want_width: usize,
        /// The height expected.
        want_height: usize,
    },
    /// The output buffer is shorter than the image needs.
    OutputTooSmall {
        /// Its length.
        len: usize,
        /// Bytes needed.
        needed: usize,
    },
    /// The entropy-coded data is corrupt: a code no table has, a coefficient past the block's
    /// end, a missing restart marker, or the data running out before the last block.
    Corrupt {
        /// The MCU (block group, in reading order) where it was found.
        mcu: usize,
        /// What was found.
        what: &'static str,
    },
}

impl fmt::Display for JpegError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NotJpeg => f.write_str("not a JPEG image (no start-of-image marker FF D8)"),
            Self::Truncated { at } => write!(f, "the JPEG data ends early, at byte {at}"),
            Self::Unsupported { what, at } => {
                write!(
                    f,
                    "{what} (byte {at}): this decoder reads baseline JPEG, as webcams send"
                )
            }
            Self::BadSegment { marker, at, what } => {
                write!(f, "bad JPEG segment FF {marker:02X} at byte {at}: {what}")
            }
            Self::Size {
                width,
                height,
                want_width,
                want_height,
            } => write!(
                f,
                "the JPEG image is {width}×{height}, the stream is {want_width}×{want_height}"
            ),
            Self::OutputTooSmall { len, needed } => write!(
                f,
                "output buffer of {len} bytes, {needed} needed for the image"
            ),
            Self::Corrupt { mcu, what } => {
                write!(f, "corrupt JPEG data in block group {mcu}: {what}")
            }
        }
    }
}

/// Zig-zag order: the `k`-th coefficient of a block's stream is at `ZIGZAG[k]` in row-major
/// order.
const ZIGZAG: [u8; 64] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
];

/// Bits of code the lookup table resolves at once; longer codes take the slow path.
const LOOKUP_BITS: u32 = 9;

/// One Huffman table, canonical codes from their lengths (T.81 Annex C).
#[derive(Clone)]
struct Huffman {
    /// For the next `LOOKUP_BITS` bits: `length << 8 | symbol`, or 0 for a longer code.
    lookup: [u16; 1 << LOOKUP_BITS],
    /// For an AC table, when the next `LOOKUP_BITS` bits hold a whole coefficient — its code
    /// and its value bits, the value within ±127 —: `value << 8 | run << 4 | bits used`; else 0.
    fast_ac: [i16; 1 << LOOKUP_BITS],
    /// The largest code of each length (index 1..=16), −1 where none.
    max_code: [i32; 17],
    /// Subtracted from a code of each length to index `symbols`.
    offset: [i32; 17],
    symbols: [u8; 256],
    defined: bool,
}

impl Huffman {
    const EMPTY: Huffman = Huffman {
        lookup: [0; 1 << LOOKUP_BITS],
        fast_ac: [0; 1 << LOOKUP_BITS],
        max_code: [-1; 17],
        offset: [0; 17],
        symbols: [0; 256],
        defined: false,
    };

    /// Builds the table from the count of codes of each length 1..=16 and the symbols in code
    /// order; `None` when the counts are more than the lengths can hold.
    fn build(&mut self, counts: &[u8; 16], symbols: &[u8]) -> Option<()> {
        let total: usize = counts.iter().map(|&c| usize::from(c)).sum();
        if total > 256 || symbols.len() != total {
            return None;
        }
        self.symbols[..total].copy_from_slice(symbols);
        self.lookup = [0; 1 << LOOKUP_BITS];
        let mut code: u32 = 0;
        let mut k: usize = 0;
        for len in 1..=16u32 {
            let n = u32::from(counts[len as usize - 1]);
            self.offset[len as usize] = k as i32 - code as i32;
            for _ in 0..n {
                // All codes of this length must fit in it.
                if code >= 1 << len {
                    return None;
                }
                if len <= LOOKUP_BITS {
                    let shift = LOOKUP_BITS - len;
                    let first = (code << shift) as usize;
                    let entry = (len as u16) << 8 | u16::from(self.symbols[k]);
                    self.lookup[first..first + (1 << shift)].fill(entry);
                }
                code += 1;
                k += 1;
            }
            self.max_code[len as usize] = if n > 0 { code as i32 - 1 } else { -1 };
            code <<= 1;
        }
        for (i, fast) in self.fast_ac.iter_mut().enumerate() {
            let entry = self.lookup[i];
            let (len, run, size) = (
                u32::from(entry >> 8),
                (entry >> 4) & 15,
                u32::from(entry & 15),
            );
            *fast = 0;
            if entry != 0 && size != 0 && len + size <= LOOKUP_BITS {
                let raw = (i as u32 >> (LOOKUP_BITS - len - size)) & ((1 << size) - 1);
                let v = extend(raw, size);
                if (-128..=127).contains(&v) {
                    *fast = (v << 8) as i16 | (run << 4) as i16 | (len + size) as i16;
                }
            }
        }
        self.defined = true;
        Some(())
    }
}

/// The bits of the entropy-coded data, most significant first, with the `FF 00` stuffing
/// removed. A marker (or the end of the data) stops it; past that it reads zeros and counts
/// them, so that a block decoded from bits that were not there is caught.
struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
    /// Bits not yet consumed, at the top of the word.
    word: u64,
    count: u32,
    /// Zero bits made up past a marker or the end.
    padding: u32,
    stopped: bool,
}

impl<'a> Bits<'a> {
    fn new(data: &'a [u8], pos: usize) -> Self {
        Bits {
            data,
            pos,
            word: 0,
            count: 0,
            padding: 0,
            stopped: false,
        }
    }

    /// Tops the word up to at least 57 bits.
    #[inline(always)]
    fn refill(&mut self) {
        while self.count <= 56 {
            let byte = match self.data.get(self.pos) {
                Some(&b) if b != 0xFF && !self.stopped => {
                    self.pos += 1;
                    b
                }
                // A stuffed `FF 00` is the byte `FF`; any other `FF` begins a marker.
                Some(0xFF) if !self.stopped && self.data.get(self.pos + 1) == Some(&0) => {
                    self.pos += 2;
                    0xFF
                }
                _ => {
                    self.stopped = true;
                    self.padding += 8;
                    0
                }
            };
            self.word |= u64::from(byte) << (56 - self.count);
            self.count += 8;
        }
    }

    #[inline(always)]
    fn peek(&self, n: u32) -> u32 {
        (self.word >> (64 - n)) as u32
    }

    #[inline(always)]
    fn consume(&mut self, n: u32) {
        self.word <<= n;
        self.count -= n;
    }

    /// Whether bits past the data were consumed.
    fn overrun(&self) -> bool {
        self.padding > self.count
    }

    /// One Huffman symbol; needs 16 bits in the word.
    #[inline(always)]
    fn symbol(&mut self, table: &Huffman) -> Option<u8> {
        let entry = table.lookup[self.peek(LOOKUP_BITS) as usize];
        if entry != 0 {
            self.consume(u32::from(entry >> 8));
            return Some(entry as u8);
        }
        for len in LOOKUP_BITS + 1..=16 {
            let code = self.peek(len) as i32;
            if code <= table.max_code[len as usize] {
                self.consume(len);
                let i = code + table.offset[len as usize];
                return table.symbols.get(i as usize).copied();
            }
        }
        None
    }

    /// The signed value of `size` bits; needs `size` bits in the word.
    #[inline(always)]
    fn value(&mut self, size: u32) -> i32 {
        if size == 0 {
            return 0;
        }
        let v = self.peek(size);
        self.consume(size);
        extend(v, size)
    }

    /// Skips to the restart marker that must come next; `false` when it is not there.
    fn restart(&mut self) -> bool {
        self.refill();
        if self.overrun() {
            return false;
        }
        let mut p = self.pos;
        while self.data.get(p) == Some(&0xFF) && self.data.get(p + 1) == Some(&0xFF) {
            p += 1;
        }
        match (self.data.get(p), self.data.get(p + 1)) {
            (Some(0xFF), Some(0xD0..=0xD7)) => {
                *self = Bits::new(self.data, p + 2);
                true
            }
            _ => false,
        }
    }
}

/// The signed value of the `size` bits `v` (T.81 F.2.2.1, EXTEND), `size` ≥ 1.
#[inline(always)]
fn extend(v: u32, size: u32) -> i32 {
    let v = v as i32;
    if v < 1 << (size - 1) {
        v - (1 << size) + 1
    } else {
        v
    }
}

/// One component of the frame.
#[derive(Debug, Clone, Copy, Default)]
struct Component {
    id: u8,
    h: usize,
    v: usize,
    quant: usize,
    dc: usize,
    ac: usize,
}

/// A reusable baseline JPEG decoder, no allocation. Each frame starts from the standard Huffman
/// tables (a motion-JPEG frame without its own means them), so that tables a corrupt frame
/// defined never reach the next one; quantisation tables, which every frame carries, are kept.
pub struct JpegDecoder {
    quant: [[u16; 64]; 4],
    quant_defined: [bool; 4],
    dc: [Huffman; 4],
    ac: [Huffman; 4],
    /// The last frame defined Huffman tables of its own.
    custom_tables: bool,
}

impl Default for JpegDecoder {
    fn default() -> Self {
        Self::new()
    }
}

/// The luminance DC table of T.81 Annex K.3 (counts by length, then symbols).
const STD_DC_LUMA: ([u8; 16], [u8; 12]) = (
    [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
);
/// The chrominance DC table of T.81 Annex K.3.
const STD_DC_CHROMA: ([u8; 16], [u8; 12]) = (
    [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
);
/// The luminance AC table of T.81 Annex K.3.
const STD_AC_LUMA: ([u8; 16], [u8; 162]) = (
    [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d],
    [
        0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61,
        0x07, 0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52,
        0xd1, 0xf0, 0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25,
        0x26, 0x27, 0x28, 0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45,
        0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64,
        0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83,
        0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99,
        0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6,
        0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3,
        0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8,
        0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
    ],
);
/// The chrominance AC table of T.81 Annex K.3.
const STD_AC_CHROMA: ([u8; 16], [u8; 162]) = (
    [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77],
    [
        0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61,
        0x71, 0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33,
        0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18,
        0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44,
        0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63,
        0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a,
        0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97,
        0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4,
        0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca,
        0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7,
        0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
    ],
);

/// The frame header's facts the scan needs.
#[derive(Clone, Copy)]
struct Frame {
    width: usize,
    height: usize,
    components: [Component; 3],
    count: usize,
    h_max: usize,
    v_max: usize,
}

/// A big-endian `u16` at `at`.
fn be16(data: &[u8], at: usize) -> Option<usize> {
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
                    self.scan_header(body, &mut f)
                        .map_err(|what| JpegError::BadSegment { marker, at, what })?;
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
    fn scan_header(&self, body: &[u8], f: &mut Frame) -> Result<(), &'static str> {
        let n = usize::from(*body.first().ok_or("too short")?);
        if n != f.count {
            return Err("a scan of some components only (several scans are not read)");
        }
        for i in 0..n {
            let id = *body.get(1 + 2 * i).ok_or("too short")?;
            let tables = *body.get(2 + 2 * i).ok_or("too short")?;
            let c = f.components[..f.count]
                .iter_mut()
                .find(|c| c.id == id)
                .ok_or("a component the frame does not have")?;
            c.dc = usize::from(tables >> 4);
            c.ac = usize::from(tables & 15);
            if c.dc > 3 || c.ac > 3 {
                return Err("table number above 3");
            }
            if !self.dc[c.dc].defined || !self.ac[c.ac].defined {
                return Err("a Huffman table that was never defined");
            }
            if !self.quant_defined[c.quant] {
                return Err("a quantisation table that was never defined");
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
fn frame_header(body: &[u8], at: usize) -> Result<Frame, JpegError> {
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
fn block(
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

/// [`transposed`] of every zig-zag index.
const TRANSPOSED: [u8; 64] = {
    let mut t = [0u8; 64];
    let mut k = 0;
    while k < 64 {
        t[k] = transposed(k);
        k += 1;
    }
    t
};

/// Eight lanes, one per row or column of a block: the inverse DCT works on eight of them at
/// once, lane by lane, which the compiler turns into vector instructions (SSE, NEON).
type Lanes = [f32; 8];

/// The 1-D inverse DCT (Arai, Agui and Nakajima's factorisation, as the IJG's `jidctflt`) of
/// eight lanes at once: `s[k]` holds term `k` of every lane; `out[k]` gets sample `k`. The
/// terms carry the AAN scale factors already ([`aan_quant`]). One loop over the lanes with
/// contiguous loads and stores, which the compiler vectorises.
#[inline(always)]
fn idct_lanes(s: &[Lanes; 8], out: &mut [Lanes; 8]) {
    use core::f32::consts::SQRT_2;
    for i in 0..8 {
        // Even part.
        let tmp10 = s[0][i] + s[4][i];
        let tmp11 = s[0][i] - s[4][i];
        let tmp13 = s[2][i] + s[6][i];
        let tmp12 = (s[2][i] - s[6][i]) * SQRT_2 - tmp13;
        let (e0, e3) = (tmp10 + tmp13, tmp10 - tmp13);
        let (e1, e2) = (tmp11 + tmp12, tmp11 - tmp12);
        // Odd part.
        let z13 = s[5][i] + s[3][i];
        let z10 = s[5][i] - s[3][i];
        let z11 = s[1][i] + s[7][i];
        let z12 = s[1][i] - s[7][i];
        let o7 = z11 + z13;
        let tmp11 = (z11 - z13) * SQRT_2;
        let z5 = (z10 + z12) * 1.847_759_1;
        let tmp10 = z12 * 1.082_392_2 - z5;
        let tmp12 = z10 * -2.613_126 + z5;
        let o6 = tmp12 - o7;
        let o5 = tmp11 - o6;
        let o4 = tmp10 + o5;
        out[0][i] = e0 + o7;
        out[1][i] = e1 + o6;
        out[2][i] = e2 + o5;
        out[3][i] = e3 - o4;
        out[4][i] = e3 + o4;
        out[5][i] = e2 - o5;
        out[6][i] = e1 - o6;
        out[7][i] = e0 - o7;
    }
}

/// A quantisation table (zig-zag order) as the multipliers of the coefficients: each times
/// the AAN scale factors of its row and column and the 1/8 of the 2-D transform.
fn aan_quant(q: &[u16; 64]) -> [f32; 64] {
    // cos(kπ/16)·√2 for k ≥ 1, 1 for k = 0.
    const AAN: [f32; 8] = [
        1.0,
        1.387_039_8,
        1.306_563,
        1.175_875_6,
        1.0,
        0.785_694_96,
        0.541_196_1,
        0.275_899_38,
    ];
    core::array::from_fn(|k| {
        let at = usize::from(ZIGZAG[k]);
        f32::from(q[k]) * AAN[at / 8] * AAN[at % 8] / 8.0
    })
}

/// The position of zig-zag coefficient `k` in a transposed block (`column × 8 + row`): the
/// first pass of [`idct`] then combines columns, with the rows as its lanes.
const fn transposed(k: usize) -> u8 {
    let at = ZIGZAG[k];
    (at % 8) * 8 + at / 8
}

/// Eight rows of eight pixels.
type Pixels = [[u8; 8]; 8];

/// The 8 × 8 inverse DCT of a transposed block of scaled coefficients into `pixels`
/// (level-shifted, rounded, clamped), then `coef` zeroed for the next block. A block of only
/// its DC term is one value.
#[inline(always)]
fn idct(coef: &mut [Lanes; 8], last: usize, pixels: &mut Pixels) {
    if last == 0 {
        *pixels = [[to_byte(coef[0][0]); 8]; 8];
        coef[0][0] = 0.0;
        return;
    }
    // Across each row (lanes: the rows), then transposed, then down each column.
    let mut rows = [[0f32; 8]; 8];
    idct_lanes(coef, &mut rows);
    let mut t = [[0f32; 8]; 8];
    for (i, t) in t.iter_mut().enumerate() {
        for (j, t) in t.iter_mut().enumerate() {
            *t = rows[j][i];
        }
    }
    let mut out = [[0f32; 8]; 8];
    idct_lanes(&t, &mut out);
    for (dst, src) in pixels.iter_mut().zip(&out) {
        for c in 0..8 {
            dst[c] = to_byte(src[c]);
        }
    }
    *coef = [[0.0; 8]; 8];
}

/// A sample of the transform (centred on 0) as a byte: +128, rounded to nearest by adding
/// 1.5 · 2²³ (the integer then sits in the mantissa's low bits), clamped as an integer — all
/// of it vector operations, whatever the value (a hostile one gives 0 or 255).
#[inline(always)]
fn to_byte(v: f32) -> u8 {
    const MAGIC: f32 = 12_582_912.0;
    let i = ((v + (128.0 + MAGIC)).to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    i.clamp(0, 255) as u8
}

/// A luma block at pixel `(x0, y0)` into the output, clipped at the image's edges.
#[inline(always)]
fn put_luma(px: &Pixels, out: &mut [u8], f: &Frame, x0: usize, y0: usize, output: Output) {
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
fn put_chroma(
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
