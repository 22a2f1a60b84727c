//! The laser's colour as the first laser frame shows it against the reference (for a fixed
//! laser's dark frames, against black): the light it adds, in which channel, and whether its
//! core is so bright that the camera shows it white.
//!
//! The stripe is the brightest light added in the frame: pixels whose largest channel rises by
//! at least half the frame's largest rise (and [`MIN_RISE`]). Its colour is the channel that
//! carries most of the light added where no channel is clipped (the core of a bright line is
//! white in every camera; its fringe keeps the hue). A line is saturated when an eighth of its
//! pixels are clipped white (all three channels; in YUYV its luma, which no pure colour
//! reaches): read by its colour alone such a core may show nothing (a camera's white has no
//! excess of one channel), so a scan then reads it by brightness when that finds the line on
//! more lines.

use scanner_core::stripe::{LaserColour, Method, PixelFormat};

use crate::source::OwnedFrame;

/// The least rise of a channel that counts as laser light, DN (well above a webcam's noise).
pub const MIN_RISE: u8 = 40;

/// The fewest stripe pixels that tell a colour.
pub const MIN_PIXELS: u32 = 20;

/// A level at or above which a channel is clipped, DN.
const CLIPPED: u8 = 245;

/// How much more light the laser's channel must carry than either other, to name it.
const DOMINANCE: f64 = 1.4;

/// What the first laser frame shows of the laser's colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourSeen {
    /// The colour: red, green or blue, or white when no channel carries most of the light.
    pub colour: LaserColour,
    /// Whether the line's core is clipped white (an eighth of its pixels or more).
    pub saturated: bool,
    /// The stripe's pixels the colour was told from.
    pub pixels: u32,
}

/// Why the colour given does not fit the frames.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "the first laser frame shows a {} laser line, but --laser {} was given: it would find noise, not the line (leave --laser out to read it as the frames show it)",
    seen.name(),
    given.name()
)]
pub struct ColourMismatch {
    /// The colour given.
    pub given: LaserColour,
    /// The colour seen.
    pub seen: LaserColour,
}

/// The colour of the light `frame` adds to `reference` (same size and format), or `None` for
/// gray frames, frames of other sizes, or too few pixels lit.
pub fn seen(frame: &OwnedFrame, reference: &OwnedFrame) -> Option<ColourSeen> {
    if frame.format != reference.format
        || frame.data.len() != reference.data.len()
        || frame.format == PixelFormat::Gray8
    {
        return None;
    }
    // each pixel's colour and the light it gained, as RGB
    let pixels = rgb_pixels(frame).zip(rgb_pixels(reference));
    let rise = |p: [u8; 3], r: [u8; 3]| -> [u8; 3] { [0, 1, 2].map(|c| p[c].saturating_sub(r[c])) };
    let mut top = 0u8;
    let mut histogram = [0u32; 256];
    for (p, r) in pixels.clone() {
        let m = rise(p, r).into_iter().max().unwrap_or(0);
        histogram[usize::from(m)] += 1;
    }
    // the frame's largest rise, a few stray pixels aside
    let mut count = 0u32;
    for m in (0..256).rev() {
        count += histogram[m];
        if count >= MIN_PIXELS {
            top = m as u8;
            break;
        }
    }
    let threshold = MIN_RISE.max(top / 2);
    if top < MIN_RISE {
        return None;
    }
    let (mut lit, mut white) = (0u32, 0u32);
    let mut sums = [0f64; 3];
    for (i, (p, r)) in pixels.enumerate() {
        let d = rise(p, r);
        if d.into_iter().max().unwrap_or(0) < threshold {
            continue;
        }
        lit += 1;
        if clipped_white(frame, i) {
            white += 1;
        } else if p.iter().all(|&v| v < CLIPPED) {
            for c in 0..3 {
                sums[c] += f64::from(d[c]);
            }
        }
    }
    if lit < MIN_PIXELS {
        return None;
    }
    let colour = [LaserColour::Red, LaserColour::Green, LaserColour::Blue]
        .into_iter()
        .enumerate()
        .find(|&(c, _)| (0..3).all(|o| o == c || sums[c] >= DOMINANCE * sums[o]) && sums[c] > 0.0)
        .map_or(LaserColour::White, |(_, colour)| colour);
    Some(ColourSeen {
        colour,
        saturated: white >= MIN_PIXELS.max(lit / 8),
        pixels: lit,
    })
}

/// The colour a scan reads with: the one `given`, or when none is given the one seen, and red
/// (the common line laser) when the frames show none or no channel carries most of the light.
/// A saturated line read frame by frame (`Method::Lim`: dark frames, nothing subtracted) is read
/// by brightness (white), its clipped core having no colour of its own, unless its colour finds
/// the stripe on half as many lines again (`valid`: the share of lines the first frame gives a
/// stripe on, read in a colour). The difference method keeps the colour: its signal counts the
/// white light a clipped core adds.
///
/// # Errors
/// [`ColourMismatch`] when the colour given is another than the frames show (white, which
/// goes by brightness, fits any).
pub fn chosen(
    given: Option<LaserColour>,
    seen: Option<ColourSeen>,
    method: Method,
    valid: impl Fn(LaserColour) -> f64,
) -> Result<LaserColour, ColourMismatch> {
    match (given, seen) {
        (Some(g), Some(s))
            if g != LaserColour::White && s.colour != LaserColour::White && g != s.colour =>
        {
            Err(ColourMismatch {
                given: g,
                seen: s.colour,
            })
        }
        (Some(g), _) => Ok(g),
        (None, Some(s)) if s.colour != LaserColour::White => {
            let by_brightness = s.saturated
                && method == Method::Lim
                && valid(s.colour) < 1.5 * valid(LaserColour::White);
            Ok(if by_brightness {
                LaserColour::White
            } else {
                s.colour
            })
        }
        (None, _) => Ok(LaserColour::Red),
    }
}

/// Whether pixel `i` of a frame is clipped white: every channel of RGB, the luma of YUYV.
fn clipped_white(f: &OwnedFrame, i: usize) -> bool {
    match f.format {
        PixelFormat::Rgb24 => f.data[3 * i..][..3].iter().all(|&v| v >= CLIPPED),
        PixelFormat::Yuyv => f.data[2 * i] >= CLIPPED,
        PixelFormat::Gray8 => f.data[i] >= CLIPPED,
    }
}

/// A frame's pixels as RGB (YUYV: BT.601 full range, each pair's chroma).
fn rgb_pixels(f: &OwnedFrame) -> impl Iterator<Item = [u8; 3]> + Clone + '_ {
    let (w, format) = (f.width, f.format);
    (0..f.width * f.height).map(move |i| match format {
        PixelFormat::Rgb24 => [f.data[3 * i], f.data[3 * i + 1], f.data[3 * i + 2]],
        PixelFormat::Yuyv => {
            let (row, x) = (i / w, i % w);
            let base = row * w * 2;
            let pair = base + 4 * (x / 2);
            let y = f32::from(f.data[base + 2 * x]);
            let (u, v) = (
                f32::from(f.data[pair + 1]) - 128.0,
                f32::from(f.data[pair + 3]) - 128.0,
            );
            let c = |x: f32| x.round().clamp(0.0, 255.0) as u8;
            [
                c(y + 1.402 * v),
                c(y - 0.344 * u - 0.714 * v),
                c(y + 1.772 * u),
            ]
        }
        PixelFormat::Gray8 => [f.data[i]; 3],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark 64×32 RGB frame with a horizontal line of `core` on row 16 and `fringe` on the
    /// rows beside it.
    fn line(core: [u8; 3], fringe: [u8; 3]) -> (OwnedFrame, OwnedFrame) {
        let (w, h) = (64, 32);
        let mut data = vec![8u8; w * h * 3];
        for x in 0..w {
            for (y, c) in [(15, fringe), (16, core), (17, fringe)] {
                data[3 * (y * w + x)..][..3].copy_from_slice(&c);
            }
        }
        let frame = OwnedFrame {
            data,
            width: w,
            height: h,
            format: PixelFormat::Rgb24,
            index: 0,
            time_us: None,
        };
        let black = OwnedFrame {
            data: vec![0; w * h * 3],
            ..frame.clone()
        };
        (frame, black)
    }

    #[test]
    fn colours_are_told_and_a_clipped_core_is_saturated() {
        let (f, r) = line([40, 220, 50], [10, 120, 20]);
        let s = seen(&f, &r).unwrap();
        assert_eq!((s.colour, s.saturated), (LaserColour::Green, false));
        let (f, r) = line([255, 255, 255], [60, 200, 70]);
        let s = seen(&f, &r).unwrap();
        assert_eq!((s.colour, s.saturated), (LaserColour::Green, true));
        let (f, r) = line([230, 30, 20], [120, 10, 10]);
        assert_eq!(seen(&f, &r).unwrap().colour, LaserColour::Red);
        let (f, r) = line([200, 200, 210], [100, 100, 100]);
        assert_eq!(seen(&f, &r).unwrap().colour, LaserColour::White);
        // nothing lit: no colour
        let (f, r) = line([20, 20, 20], [10, 10, 10]);
        assert_eq!(seen(&f, &r), None);
    }

    #[test]
    fn the_colour_given_must_fit_the_frames() {
        let green = ColourSeen {
            colour: LaserColour::Green,
            saturated: true,
            pixels: 100,
        };
        // frame by frame, a clipped line by brightness unless its colour finds it on many more
        // lines; the difference method keeps the colour
        let more_green = |c: LaserColour| if c == LaserColour::Green { 0.8 } else { 0.2 };
        let as_many = |_: LaserColour| 0.5;
        assert_eq!(
            chosen(None, Some(green), Method::Lim, as_many),
            Ok(LaserColour::White)
        );
        assert_eq!(
            chosen(None, Some(green), Method::Lim, more_green),
            Ok(LaserColour::Green)
        );
        assert_eq!(
            chosen(None, Some(green), Method::Dim, as_many),
            Ok(LaserColour::Green)
        );
        let unclipped = ColourSeen {
            saturated: false,
            ..green
        };
        assert_eq!(
            chosen(None, Some(unclipped), Method::Lim, as_many),
            Ok(LaserColour::Green)
        );
        assert!(chosen(Some(LaserColour::Red), Some(green), Method::Lim, as_many).is_err());
        assert_eq!(
            chosen(Some(LaserColour::White), Some(green), Method::Lim, as_many),
            Ok(LaserColour::White)
        );
        assert_eq!(
            chosen(None, None, Method::Dim, as_many),
            Ok(LaserColour::Red)
        );
    }
}
