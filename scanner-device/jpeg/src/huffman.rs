//! The entropy coding: canonical Huffman tables (T.81 Annex C, the standard ones of Annex K)
//! and the bit reader that decodes a block's coefficients from them.

/// Zig-zag order: the `k`-th coefficient of a block's stream is at `ZIGZAG[k]` in row-major
/// order.
pub(crate) const ZIGZAG: [u8; 64] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
];

/// Bits of code the lookup table resolves at once; longer codes take the slow path.
pub(crate) const LOOKUP_BITS: u32 = 9;

/// One Huffman table, canonical codes from their lengths (T.81 Annex C).
#[derive(Clone)]
pub(crate) struct Huffman {
    /// For the next `LOOKUP_BITS` bits: `length << 8 | symbol`, or 0 for a longer code.
    pub(crate) lookup: [u16; 1 << LOOKUP_BITS],
    /// For an AC table, when the next `LOOKUP_BITS` bits hold a whole coefficient — its code
    /// and its value bits, the value within ±127 —: `value << 8 | run << 4 | bits used`; else 0.
    pub(crate) fast_ac: [i16; 1 << LOOKUP_BITS],
    /// The largest code of each length (index 1..=16), −1 where none.
    pub(crate) max_code: [i32; 17],
    /// Subtracted from a code of each length to index `symbols`.
    pub(crate) offset: [i32; 17],
    pub(crate) symbols: [u8; 256],
    pub(crate) defined: bool,
}

impl Huffman {
    pub(crate) const EMPTY: Huffman = Huffman {
        lookup: [0; 1 << LOOKUP_BITS],
        fast_ac: [0; 1 << LOOKUP_BITS],
        max_code: [-1; 17],
        offset: [0; 17],
        symbols: [0; 256],
        defined: false,
    };

    /// Builds the table from the count of codes of each length 1..=16 and the symbols in code
    /// order; `None` when the counts are more than the lengths can hold.
    pub(crate) fn build(&mut self, counts: &[u8; 16], symbols: &[u8]) -> Option<()> {
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
pub(crate) struct Bits<'a> {
    pub(crate) data: &'a [u8],
    pub(crate) pos: usize,
    /// Bits not yet consumed, at the top of the word.
    pub(crate) word: u64,
    pub(crate) count: u32,
    /// Zero bits made up past a marker or the end.
    pub(crate) padding: u32,
    pub(crate) stopped: bool,
}

impl<'a> Bits<'a> {
    pub(crate) fn new(data: &'a [u8], pos: usize) -> Self {
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
    pub(crate) fn refill(&mut self) {
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
    pub(crate) fn peek(&self, n: u32) -> u32 {
        (self.word >> (64 - n)) as u32
    }

    #[inline(always)]
    pub(crate) fn consume(&mut self, n: u32) {
        self.word <<= n;
        self.count -= n;
    }

    /// Whether bits past the data were consumed.
    pub(crate) fn overrun(&self) -> bool {
        self.padding > self.count
    }

    /// One Huffman symbol; needs 16 bits in the word.
    #[inline(always)]
    pub(crate) fn symbol(&mut self, table: &Huffman) -> Option<u8> {
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
    pub(crate) fn value(&mut self, size: u32) -> i32 {
        if size == 0 {
            return 0;
        }
        let v = self.peek(size);
        self.consume(size);
        extend(v, size)
    }

    /// Skips to the restart marker that must come next; `false` when it is not there.
    pub(crate) fn restart(&mut self) -> bool {
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
pub(crate) fn extend(v: u32, size: u32) -> i32 {
    let v = v as i32;
    if v < 1 << (size - 1) {
        v - (1 << size) + 1
    } else {
        v
    }
}

/// The luminance DC table of T.81 Annex K.3 (counts by length, then symbols).
pub(crate) const STD_DC_LUMA: ([u8; 16], [u8; 12]) = (
    [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
);
/// The chrominance DC table of T.81 Annex K.3.
pub(crate) const STD_DC_CHROMA: ([u8; 16], [u8; 12]) = (
    [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
);
/// The luminance AC table of T.81 Annex K.3.
pub(crate) const STD_AC_LUMA: ([u8; 16], [u8; 162]) = (
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
pub(crate) const STD_AC_CHROMA: ([u8; 16], [u8; 162]) = (
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
