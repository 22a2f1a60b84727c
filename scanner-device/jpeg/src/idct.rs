//! The inverse DCT: the floating-point AAN factorisation of the IJG's `jidctflt`, over eight lanes
//! at once so that it compiles to vector instructions.

use crate::huffman::ZIGZAG;

/// [`transposed`] of every zig-zag index.
pub(crate) const TRANSPOSED: [u8; 64] = {
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
pub(crate) type Lanes = [f32; 8];

/// The 1-D inverse DCT (Arai, Agui and Nakajima's factorisation, as the IJG's `jidctflt`) of
/// eight lanes at once: `s[k]` holds term `k` of every lane; `out[k]` gets sample `k`. The
/// terms carry the AAN scale factors already ([`aan_quant`]). One loop over the lanes with
/// contiguous loads and stores, which the compiler vectorises.
#[inline(always)]
pub(crate) fn idct_lanes(s: &[Lanes; 8], out: &mut [Lanes; 8]) {
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
pub(crate) fn aan_quant(q: &[u16; 64]) -> [f32; 64] {
    // cos(kπ/16)·√2 for k ≥ 1, 1 for k = 0.
    pub(crate) const AAN: [f32; 8] = [
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
pub(crate) const fn transposed(k: usize) -> u8 {
    let at = ZIGZAG[k];
    (at % 8) * 8 + at / 8
}

/// Eight rows of eight pixels.
pub(crate) type Pixels = [[u8; 8]; 8];

/// The 8 × 8 inverse DCT of a transposed block of scaled coefficients into `pixels`
/// (level-shifted, rounded, clamped), then `coef` zeroed for the next block. A block of only
/// its DC term is one value.
#[inline(always)]
pub(crate) fn idct(coef: &mut [Lanes; 8], last: usize, pixels: &mut Pixels) {
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
pub(crate) fn to_byte(v: f32) -> u8 {
    pub(crate) const MAGIC: f32 = 12_582_912.0;
    let i = ((v + (128.0 + MAGIC)).to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    i.clamp(0, 255) as u8
}
