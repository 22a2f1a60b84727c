//! A shadow sweep's plan: each pixel's lit and shadowed values from two readings of the sweep
//! beforehand, and how deep the shadow is.

use anyhow::Result;
use scanner_core::stripe::PixelFormat;

use crate::source::{FrameSource, SourceOptions};

use super::{ScanArgs, ScanRefusal, open_source};

/// `source` with each pixel's value lit without the shadow for its reference and its value in
/// the shadow's core for [`FrameSource::darkest`], from two readings of the sweep beforehand
/// (of its frames kept in memory up to [`crate::source::MAX_KEPT_SWEEP`], which the scan then
/// reads too; else of two more openings of the same source): the brightest and the darkest of
/// each byte, then the mean of the values in the top quarter of that range and of those in the
/// bottom quarter. The extremes alone stand a few noise σ beyond the values they stand for,
/// which would widen every band by a third of a pixel on the rig; the means do not.
pub(super) fn sweep_extremes(
    a: &ScanArgs,
    format: PixelFormat,
    opts: &SourceOptions,
    source: Box<dyn FrameSource>,
) -> Result<Box<dyn FrameSource>> {
    let mut first = open_source(a, format, opts)?;
    let mut both: Option<(crate::source::OwnedFrame, crate::source::OwnedFrame)> = None;
    // the frames, kept for the second reading and the scan while they fit
    let (mut kept, mut kept_bytes) = (Some(Vec::new()), 0usize);
    while let Some(frame) = first.next_frame()? {
        match &mut both {
            None => both = Some((frame.clone(), frame.clone())),
            Some((hi, lo)) => {
                for ((h, l), v) in hi.data.iter_mut().zip(&mut lo.data).zip(&frame.data) {
                    *h = (*h).max(*v);
                    *l = (*l).min(*v);
                }
            }
        }
        kept_bytes += frame.data.len();
        if kept_bytes > crate::source::MAX_KEPT_SWEEP {
            kept = None;
        }
        if let Some(k) = &mut kept {
            k.push(frame);
        }
    }
    let Some((mut hi, mut lo)) = both else {
        return Err(ScanRefusal::NoShadowFrames(a.source.clone()).into());
    };
    let n = hi.data.len();
    let (mut sums, mut counts) = (
        [vec![0u32; n], vec![0u32; n]],
        [vec![0u32; n], vec![0u32; n]],
    );
    let mut tally = |frame: &crate::source::OwnedFrame| {
        for (i, &v) in frame.data.iter().enumerate() {
            let (h, l) = (u32::from(hi.data[i]), u32::from(lo.data[i]));
            let quarter = (h - l) / 8;
            let v32 = u32::from(v);
            if v32 >= h - quarter {
                sums[0][i] += v32;
                counts[0][i] += 1;
            }
            if v32 <= l + quarter {
                sums[1][i] += v32;
                counts[1][i] += 1;
            }
        }
    };
    match &kept {
        Some(frames) => frames.iter().for_each(&mut tally),
        None => {
            let mut second = open_source(a, format, opts)?;
            while let Some(frame) = second.next_frame()? {
                tally(&frame);
            }
        }
    }
    for (k, f) in [&mut hi, &mut lo].into_iter().enumerate() {
        for (i, b) in f.data.iter_mut().enumerate() {
            if let Some(mean) = (sums[k][i] + counts[k][i] / 2).checked_div(counts[k][i]) {
                *b = mean as u8;
            }
        }
        f.index = u64::MAX;
        f.time_us = None;
    }
    let depth = shadow_depth(&hi, &lo)?;
    if depth < MIN_SHADOW_DEPTH {
        return Err(ScanRefusal::FaintShadow(depth).into());
    }
    Ok(Box::new(crate::source::Extremes::new(source, hi, lo, kept)))
}

/// Least share of the light a shadow sweep's shadow must take where it passes: a sharp shadow
/// takes the lamp's whole share (55 % on the rig's desk lamp, whose light is 1.2 times the
/// room's; more in a dim room), a lamp wider than the rod as the object sees it is never wholly
/// hidden (on the rig: 39 % for a 24 mm bulb 250 mm behind an 8 mm rod, 25 % for a 40 mm one)
/// and its edges are a blur; strong other light washes any shadow out.
pub const MIN_SHADOW_DEPTH: f64 = 0.4;

/// The median share of the light the shadow takes at its deepest (`1 − darkest / brightest`,
/// luma) over the pixels where it took more than 8 % (where it passed).
pub(super) fn shadow_depth(
    hi: &crate::source::OwnedFrame,
    lo: &crate::source::OwnedFrame,
) -> Result<f64> {
    let (h, l) = (hi.view()?, lo.view()?);
    let mut depth = vec![0u8; hi.width * hi.height];
    scanner_core::stripe::shadow::contrast(&l, (&h, None), &mut depth, u8::MAX)?;
    let mut passed: Vec<u8> = depth.into_iter().filter(|&d| d > 20).collect();
    if passed.is_empty() {
        return Ok(0.0);
    }
    let mid = passed.len() / 2;
    Ok(f64::from(*passed.select_nth_unstable(mid).1) / 255.0)
}
