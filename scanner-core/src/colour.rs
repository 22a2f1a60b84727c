//! BT.601 full-range colour conversions, the one implementation every part of the project uses
//! (camera buffers, the rig's frames, the head's point colours, the stripe signal's luma).
//!
//! `Y = 0.299 R + 0.587 G + 0.114 B`, `U = 128 + 0.564 (B − Y)`, `V = 128 + 0.713 (R − Y)`;
//! back: `R = Y + 1.402 (V − 128)`, `G = Y − 0.344 (U − 128) − 0.714 (V − 128)`,
//! `B = Y + 1.772 (U − 128)`. Integer arithmetic in 1/256 steps, rounded.

/// The luma weights of R, G and B in 1/256 steps (they sum to 256, so a luma fits 16 bits:
/// `77·255 + 150·255 + 29·255 + 128 = 65408`, which lets vector code work in `u16` lanes).
pub const LUMA_WEIGHTS: [u16; 3] = [77, 150, 29];

/// The luma of an RGB pixel.
#[inline]
pub fn luma(p: [u8; 3]) -> u8 {
    let [r, g, b] = LUMA_WEIGHTS;
    ((r * u16::from(p[0]) + g * u16::from(p[1]) + b * u16::from(p[2]) + 128) >> 8) as u8
}

/// A pair of RGB pixels as YUYV: each pixel's luma, the pair's mean chroma.
#[inline]
pub fn rgb_pair_to_yuyv(a: [u8; 3], b: [u8; 3]) -> [u8; 4] {
    let mean = |i: usize| (i32::from(a[i]) + i32::from(b[i]) + 1) / 2;
    let (r, g, bl) = (mean(0), mean(1), mean(2));
    let [wr, wg, wb] = LUMA_WEIGHTS.map(i32::from);
    let y = (wr * r + wg * g + wb * bl + 128) >> 8;
    let chroma = |d: i32, k: i32| (128 + ((k * d + 128) >> 8)).clamp(0, 255) as u8;
    [luma(a), chroma(bl - y, 144), luma(b), chroma(r - y, 183)]
}

/// RGB of a YUV pixel (the chroma of its YUYV pair).
#[inline]
pub fn yuv_to_rgb(y: u8, u: u8, v: u8) -> [u8; 3] {
    let (y, cb, cr) = (i32::from(y), i32::from(u) - 128, i32::from(v) - 128);
    let c = |x: i32| ((x + 128) >> 8).clamp(0, 255) as u8;
    [
        c(256 * y + 359 * cr),
        c(256 * y - 88 * cb - 183 * cr),
        c(256 * y + 454 * cb),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grays_stay_gray_and_primaries_round_trip_within_a_few_levels() {
        for v in [0u8, 1, 127, 128, 254, 255] {
            assert_eq!(luma([v; 3]), v);
            let [y0, u, y1, vv] = rgb_pair_to_yuyv([v; 3], [v; 3]);
            assert_eq!((y0, u, y1, vv), (v, 128, v, 128));
            assert_eq!(yuv_to_rgb(v, 128, 128), [v; 3]);
        }
        for rgb in [
            [255, 0, 0],
            [0, 255, 0],
            [0, 0, 255],
            [200, 120, 40],
            [10, 200, 90],
        ] {
            let [y, u, _, v] = rgb_pair_to_yuyv(rgb, rgb);
            let back = yuv_to_rgb(y, u, v);
            for k in 0..3 {
                assert!(
                    (i16::from(back[k]) - i16::from(rgb[k])).abs() <= 3,
                    "{rgb:?} → {back:?}"
                );
            }
        }
    }
}
