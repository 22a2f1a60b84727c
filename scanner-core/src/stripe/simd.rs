//! Explicit vector kernels for the magnitudes the compiler does not vectorise well: the
//! difference method on YUYV, with a coloured laser `ΔY + ((w_b ΔCb + w_r ΔCr) >> 6)` clamped to
//! a byte, where every pair of pixels shares its chroma, and with a white one the rise of `Y`
//! (every other byte). Written out per instruction set:
//! - x86-64, SSE2 (the baseline, so always on): each 16-bit word of YUYV is one pixel, `Y` its
//!   low byte and its pair's `Cb` or `Cr` its high byte, so a mask and a shift split them with no
//!   shuffle; the pair's chroma term by one multiply-add (`pmaddwd`), repeated for both pixels by
//!   a pack and an unpack, then packed to bytes with saturation (which is the clamp);
//! - aarch64, NEON (the head's Raspberry Pi): `ld4` loads 16 pairs split into `Y0, Cb, Y1, Cr`,
//!   widening subtracts and multiplies, `sqxtun` narrows with the clamp, `st2` interleaves;
//! - anything else: none (the caller's portable loop does every pixel).
//!
//! Each kernel does whole blocks only and returns how many pixels it did; the caller finishes
//! the rest. The results are bit-identical to the scalar formula (tested against it below and,
//! for NEON, under emulation in CI).
#![allow(unsafe_code)]

/// The DIM magnitudes of a coloured laser for the YUYV pixels of `cur` against `refs` (both
/// start on a pair; `out.len()` pixels at most), chroma weights `(wb, wr)` ×64. Returns the number
/// of pixels written (a multiple of the kernel's block, maybe 0).
#[inline]
pub(super) fn yuyv_dim_colour(wb: i16, wr: i16, cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
    imp::yuyv_dim_colour(wb, wr, cur, refs, out)
}

/// The DIM magnitudes of a white laser (the rise of `Y`) for the YUYV pixels of `cur` against
/// `refs`; as [`yuyv_dim_colour`].
#[inline]
pub(super) fn yuyv_dim_white(cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
    imp::yuyv_dim_white(cur, refs, out)
}

#[cfg(target_arch = "x86_64")]
mod imp {
    use core::arch::x86_64::{
        __m128i, _mm_add_epi16, _mm_and_si128, _mm_loadu_si128, _mm_madd_epi16, _mm_packs_epi32,
        _mm_packus_epi16, _mm_set_epi16, _mm_set1_epi16, _mm_srai_epi32, _mm_srli_epi16,
        _mm_storeu_si128, _mm_sub_epi16, _mm_subs_epu8, _mm_unpackhi_epi16, _mm_unpacklo_epi16,
    };

    /// Pixels per block: 32 bytes of YUYV.
    const BLOCK: usize = 16;

    /// Loads 16 bytes.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn load(b: &[u8]) -> __m128i {
        let b: &[u8; 16] = b.try_into().unwrap_or(&[0; 16]);
        // SAFETY: `b` is 16 readable bytes; the load is unaligned.
        unsafe { _mm_loadu_si128(b.as_ptr().cast()) }
    }

    /// 4 pairs of each frame: `ΔY` of the 8 pixels as `i16`, and each pair's chroma term as
    /// `i32`. Every 16-bit word of YUYV is one pixel: `Y` its low byte, its pair's `Cb` (even
    /// words) or `Cr` (odd words) its high byte.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn four(p: __m128i, r: __m128i, w: __m128i) -> (__m128i, __m128i) {
        let low = _mm_set1_epi16(0xff);
        let dy = _mm_sub_epi16(_mm_and_si128(p, low), _mm_and_si128(r, low));
        let dc = _mm_sub_epi16(_mm_srli_epi16::<8>(p), _mm_srli_epi16::<8>(r));
        // wb·ΔCb + wr·ΔCr of each pair in one multiply-add
        (dy, _mm_srai_epi32::<6>(_mm_madd_epi16(dc, w)))
    }

    /// The magnitudes of 16 pixels (32 bytes of each frame).
    #[inline]
    #[target_feature(enable = "sse2")]
    fn block(p: &[u8], r: &[u8], w: __m128i) -> __m128i {
        let (ya, ca) = four(load(&p[..16]), load(&r[..16]), w);
        let (yb, cb) = four(load(&p[16..]), load(&r[16..]), w);
        // the 8 chroma terms as i16, each repeated for the two pixels of its pair
        let c = _mm_packs_epi32(ca, cb);
        let a = _mm_add_epi16(ya, _mm_unpacklo_epi16(c, c));
        let b = _mm_add_epi16(yb, _mm_unpackhi_epi16(c, c));
        // saturating to 0..=255 is the clamp
        _mm_packus_epi16(a, b)
    }

    /// The `Y` bytes of 16 pixels (32 bytes).
    #[inline]
    #[target_feature(enable = "sse2")]
    fn lumas(p: &[u8]) -> __m128i {
        let low = _mm_set1_epi16(0xff);
        _mm_packus_epi16(
            _mm_and_si128(load(&p[..16]), low),
            _mm_and_si128(load(&p[16..]), low),
        )
    }

    /// Stores 16 bytes.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn store(o: &mut [u8], v: __m128i) {
        if let Ok(o) = <&mut [u8; 16]>::try_from(o) {
            // SAFETY: `o` is 16 writable bytes; the store is unaligned.
            unsafe { _mm_storeu_si128(o.as_mut_ptr().cast(), v) };
        }
    }

    /// Runs `block` over whole blocks of 16 pixels; returns the pixels done.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn blocks(
        cur: &[u8],
        refs: &[u8],
        out: &mut [u8],
        block: impl Fn(&[u8], &[u8]) -> __m128i,
    ) -> usize {
        let mut done = 0;
        let all = out.chunks_exact_mut(BLOCK).zip(
            cur.chunks_exact(2 * BLOCK)
                .zip(refs.chunks_exact(2 * BLOCK)),
        );
        for (o, (p, r)) in all {
            store(o, block(p, r));
            done += BLOCK;
        }
        done
    }

    pub(super) fn yuyv_dim_colour(
        wb: i16,
        wr: i16,
        cur: &[u8],
        refs: &[u8],
        out: &mut [u8],
    ) -> usize {
        // SAFETY: SSE2 is part of every x86-64 processor (the target's baseline).
        unsafe { kernel(wb, wr, cur, refs, out) }
    }

    pub(super) fn yuyv_dim_white(cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
        #[target_feature(enable = "sse2")]
        fn kernel(cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
            blocks(cur, refs, out, |p, r| _mm_subs_epu8(lumas(p), lumas(r)))
        }
        // SAFETY: SSE2 is part of every x86-64 processor (the target's baseline).
        unsafe { kernel(cur, refs, out) }
    }

    #[target_feature(enable = "sse2")]
    fn kernel(wb: i16, wr: i16, cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
        let w = _mm_set_epi16(wr, wb, wr, wb, wr, wb, wr, wb);
        blocks(cur, refs, out, |p, r| block(p, r, w))
    }
}

#[cfg(target_arch = "aarch64")]
mod imp {
    use core::arch::aarch64::{
        int16x8_t, uint8x16x2_t, vaddq_s16, vdupq_n_s16, vget_high_u8, vget_low_u8, vld2q_u8,
        vld4q_u8, vmlaq_s16, vmulq_s16, vqmovun_high_s16, vqmovun_s16, vqsubq_u8,
        vreinterpretq_s16_u16, vshrq_n_s16, vst1q_u8, vst2q_u8, vsubl_u8,
    };
    use core::arch::aarch64::{uint8x8_t, uint8x16_t};

    /// Pixels per block: 64 bytes of YUYV.
    const BLOCK: usize = 32;

    /// `a − b` widened to `i16`.
    #[inline]
    #[target_feature(enable = "neon")]
    fn diff(a: uint8x8_t, b: uint8x8_t) -> int16x8_t {
        vreinterpretq_s16_u16(vsubl_u8(a, b))
    }

    /// `ΔY + c` of 16 pixels, each half narrowed with saturation.
    #[inline]
    #[target_feature(enable = "neon")]
    fn plus(y: uint8x16_t, ry: uint8x16_t, c: (int16x8_t, int16x8_t)) -> uint8x16_t {
        let lo = vaddq_s16(diff(vget_low_u8(y), vget_low_u8(ry)), c.0);
        let hi = vaddq_s16(diff(vget_high_u8(y), vget_high_u8(ry)), c.1);
        vqmovun_high_s16(vqmovun_s16(lo), hi)
    }

    pub(super) fn yuyv_dim_colour(
        wb: i16,
        wr: i16,
        cur: &[u8],
        refs: &[u8],
        out: &mut [u8],
    ) -> usize {
        // SAFETY: NEON is part of every AArch64 processor (the target's baseline).
        unsafe { kernel(wb, wr, cur, refs, out) }
    }

    pub(super) fn yuyv_dim_white(cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
        #[target_feature(enable = "neon")]
        fn kernel(cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
            const WHITE: usize = 16;
            let mut done = 0;
            let all = out.chunks_exact_mut(WHITE).zip(
                cur.chunks_exact(2 * WHITE)
                    .zip(refs.chunks_exact(2 * WHITE)),
            );
            for (o, (p, r)) in all {
                // SAFETY: `p` and `r` are 32 readable bytes, `o` 16 writable ones (exact chunks).
                unsafe {
                    let (p, r) = (vld2q_u8(p.as_ptr()), vld2q_u8(r.as_ptr()));
                    vst1q_u8(o.as_mut_ptr(), vqsubq_u8(p.0, r.0));
                }
                done += WHITE;
            }
            done
        }
        // SAFETY: NEON is part of every AArch64 processor (the target's baseline).
        unsafe { kernel(cur, refs, out) }
    }

    #[target_feature(enable = "neon")]
    fn kernel(wb: i16, wr: i16, cur: &[u8], refs: &[u8], out: &mut [u8]) -> usize {
        let (wb, wr) = (vdupq_n_s16(wb), vdupq_n_s16(wr));
        let mut done = 0;
        let blocks = out.chunks_exact_mut(BLOCK).zip(
            cur.chunks_exact(2 * BLOCK)
                .zip(refs.chunks_exact(2 * BLOCK)),
        );
        for (o, (p, r)) in blocks {
            // SAFETY: `p` and `r` are 64 readable bytes each (exact chunks).
            let (p, r) = unsafe { (vld4q_u8(p.as_ptr()), vld4q_u8(r.as_ptr())) };
            // lanes: .0 = Y0, .1 = Cb, .2 = Y1, .3 = Cr of 16 pairs
            let chroma = |lo: bool| {
                let half = |v: uint8x16_t| if lo { vget_low_u8(v) } else { vget_high_u8(v) };
                let cb = diff(half(p.1), half(r.1));
                let cr = diff(half(p.3), half(r.3));
                vshrq_n_s16::<6>(vmlaq_s16(vmulq_s16(wb, cb), wr, cr))
            };
            let c = (chroma(true), chroma(false));
            let v = uint8x16x2_t(plus(p.0, r.0, c), plus(p.2, r.2, c));
            // SAFETY: `o` is 32 writable bytes (an exact chunk).
            unsafe { vst2q_u8(o.as_mut_ptr(), v) };
            done += BLOCK;
        }
        done
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
mod imp {
    pub(super) fn yuyv_dim_colour(_: i16, _: i16, _: &[u8], _: &[u8], _: &mut [u8]) -> usize {
        0
    }
    pub(super) fn yuyv_dim_white(_: &[u8], _: &[u8], _: &mut [u8]) -> usize {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::{yuyv_dim_colour, yuyv_dim_white};

    /// A deterministic byte stream.
    fn bytes(seed: u64, out: &mut [u8]) {
        let mut x = seed | 1;
        for b in out {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *b = (x >> 24) as u8;
        }
    }

    /// The scalar formula the kernels replace.
    fn scalar(wb: i16, wr: i16, p: &[u8], r: &[u8], x: usize) -> u8 {
        let d = |i: usize| i16::from(p[i]) - i16::from(r[i]);
        let pair = 4 * (x / 2);
        let c = (wb * d(pair + 1) + wr * d(pair + 3)) >> 6;
        (d(2 * x) + c).clamp(0, 255) as u8
    }

    #[test]
    fn kernel_is_bit_identical_to_the_formula_on_every_weight_and_length() {
        const N: usize = 300;
        let (mut p, mut r) = ([0u8; 2 * N], [0u8; 2 * N]);
        // the weights of red, green and blue; the last round swings every byte fully both ways
        for (seed, weights) in [(0u64, (0i16, 90i16)), (1, (-22, -46)), (2, (113, 0))] {
            for round in 0..4u64 {
                bytes(seed * 10 + round, &mut p);
                bytes(seed * 10 + round + 100, &mut r);
                if round == 3 {
                    for (i, (p, r)) in p.iter_mut().zip(r.iter_mut()).enumerate() {
                        (*p, *r) = if (i / 4) % 2 == 0 { (255, 0) } else { (0, 255) };
                    }
                }
                for n in [0, 1, 15, 16, 17, 31, 32, 33, 64, 100, N] {
                    let mut out = [0u8; N];
                    let (wb, wr) = weights;
                    let done = yuyv_dim_colour(wb, wr, &p[..2 * n], &r[..2 * n], &mut out[..n]);
                    assert!(done <= n);
                    #[cfg(target_arch = "x86_64")]
                    assert_eq!(done, n / 16 * 16, "SSE2 does every whole block of 16");
                    #[cfg(target_arch = "aarch64")]
                    assert_eq!(done, n / 32 * 32, "NEON does every whole block of 32");
                    for (x, &o) in out[..done].iter().enumerate() {
                        assert_eq!(
                            o,
                            scalar(wb, wr, &p, &r, x),
                            "pixel {x} of {n}, weights {weights:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn white_kernel_is_the_rise_of_y() {
        const N: usize = 300;
        let (mut p, mut r) = ([0u8; 2 * N], [0u8; 2 * N]);
        for seed in 0..4u64 {
            bytes(seed + 7, &mut p);
            bytes(seed + 70, &mut r);
            for n in [0, 1, 15, 16, 17, 33, 64, 100, N] {
                let mut out = [0u8; N];
                let done = yuyv_dim_white(&p[..2 * n], &r[..2 * n], &mut out[..n]);
                #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
                assert_eq!(done, n / 16 * 16, "every whole block of 16");
                for (x, &o) in out[..done].iter().enumerate() {
                    assert_eq!(o, p[2 * x].saturating_sub(r[2 * x]), "pixel {x} of {n}");
                }
            }
        }
    }
}
