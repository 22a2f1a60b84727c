//! A shadow as a stripe: the share of the lamp's light a shadow takes from each pixel.
//!
//! A shadow sweep (Bouguet and Perona's desk scanner: a rod's shadow from a small lamp) has no
//! laser. Against a frame of the scene lit without the shadow (`lit`: one taken before the sweep,
//! or each pixel's brightest over it) and, when known, one with the lamp's light all hidden
//! (`dark`: each pixel's darkest over the sweep, or a frame with the lamp off), each pixel's
//! *contrast* is `255 · (lit − frame) / (lit − dark)` in luma: 0 where the lamp's light is all
//! there, 255 where it is all gone. Dividing by the lamp's own share takes the surface's
//! brightness, its tilt to the lamp and the ambient light out, so the band has the same height
//! everywhere and its half-height crossings are where half the lamp is hidden — the mean of the
//! pixel's shadowed and lit values, Bouguet and Perona's edge. Without `dark` the ambient light
//! is taken for none (`dark` = 0): the band is lower where the lamp's share is (a surface turned
//! from the lamp), which moves its edges there. The band is then read by the stripe extractor
//! (light-intensity method, gray) as a wide stripe, and each of its edges ([`super::Locate`]) is
//! a plane of light through the lamp.

use super::frame::{Frame, FrameError, PixelFormat};

/// Pixels where the lamp adds less than this (luma, lit − dark) get no contrast: too little of
/// its light reaches them (the objects' own shadows, black print) for a shadow to show.
pub const MIN_LIT: u8 = 16;

/// The luma of pixel `x` of a row.
#[inline]
fn luma(format: PixelFormat, row: &[u8], x: usize) -> u8 {
    match format {
        PixelFormat::Gray8 => row[x],
        PixelFormat::Yuyv => row[2 * x],
        PixelFormat::Rgb24 => crate::colour::luma([row[3 * x], row[3 * x + 1], row[3 * x + 2]]),
    }
}

/// The shadow's contrast of `frame` against `lit` and `dark` into `out` (gray, `frame.width()`
/// per row, packed): `255 · (lit − frame) / (lit − dark)` in luma (`dark` 0 when not given),
/// 0 where the frame is brighter or the lamp adds less than [`MIN_LIT`], at most 255. Returns
/// how many pixels are brighter than `lit` by more than `brighter` (a shadow-free frame with a
/// shadow in it shows as many).
///
/// # Errors
/// [`FrameError::ReferenceMismatch`] when the frames differ in shape;
/// [`FrameError::BufferTooShort`] when `out` is shorter than width × height.
pub fn contrast(
    frame: &Frame<'_>,
    (lit, dark): (&Frame<'_>, Option<&Frame<'_>>),
    out: &mut [u8],
    brighter: u8,
) -> Result<usize, FrameError> {
    if !frame.same_shape(lit) || dark.is_some_and(|d| !frame.same_shape(d)) {
        return Err(FrameError::ReferenceMismatch);
    }
    let (w, h) = (frame.width(), frame.height());
    let len = out.len();
    let out = out
        .get_mut(..w * h)
        .ok_or(FrameError::BufferTooShort { len, needed: w * h })?;
    let format = frame.format();
    let mut count = 0;
    for (y, dst) in out.chunks_exact_mut(w).enumerate() {
        let (f, l) = (frame.row(y), lit.row(y));
        let k = dark.map(|d| d.row(y));
        for (x, d) in dst.iter_mut().enumerate() {
            let (a, b) = (u32::from(luma(format, l, x)), u32::from(luma(format, f, x)));
            let floor = k.map_or(0, |k| u32::from(luma(format, k, x))).min(a);
            count += usize::from(b > a + u32::from(brighter));
            let lamp = a - floor;
            *d = if lamp < u32::from(MIN_LIT) || b >= a {
                0
            } else {
                ((255 * (a - b) + lamp / 2) / lamp).min(255) as u8
            };
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contrast_is_the_share_of_light_taken() {
        let lit = [200u8, 100, 10, 50];
        let frame = [100u8, 100, 0, 60];
        let (f, l) = (
            Frame::packed(&frame, 4, 1, PixelFormat::Gray8).unwrap(),
            Frame::packed(&lit, 4, 1, PixelFormat::Gray8).unwrap(),
        );
        let mut out = [9u8; 4];
        // one pixel brighter than lit by more than 5
        assert_eq!(contrast(&f, (&l, None), &mut out, 5), Ok(1));
        // half taken; none; too dark to tell; brighter than lit
        assert_eq!(out, [128, 0, 0, 0]);
        assert_eq!(contrast(&f, (&l, None), &mut out, 10), Ok(0));
        // with the lamp's light all hidden at 40, 100 and 0: half of 160 taken is all of it
        let dark = [40u8, 100, 0, 0];
        let k = Frame::packed(&dark, 4, 1, PixelFormat::Gray8).unwrap();
        contrast(&f, (&l, Some(&k)), &mut out, 10).unwrap();
        assert_eq!(out, [159, 0, 0, 0]);
        assert_eq!(
            contrast(&f, (&l, None), &mut [0u8; 3], 5),
            Err(FrameError::BufferTooShort { len: 3, needed: 4 })
        );
        let wide = [0u8; 8];
        let other = Frame::packed(&wide, 8, 1, PixelFormat::Gray8).unwrap();
        assert_eq!(
            contrast(&f, (&other, None), &mut out, 5),
            Err(FrameError::ReferenceMismatch)
        );
    }
}
