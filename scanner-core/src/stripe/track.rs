//! The pass over the frame: each row's 3×1 sums update every line's strongest peak and its
//! strongest rival ([`track`]), in column mode or row mode.

use super::Extractor;
use super::config::Roi;
use super::lines::Io;
use super::signal;

/// one at least `sep` lines away from it. Branch-free on purpose: it is the inner loop.
#[inline(always)]
pub(super) fn track(
    t: u16,
    at: u16,
    sep: u16,
    best: &mut u16,
    best_at: &mut u16,
    second: &mut u16,
    second_at: &mut u16,
) {
    let far_b = at.wrapping_sub(*best_at) > sep;
    let far_s = at.wrapping_sub(*second_at) > sep;
    // Ties move the peak forward: on a clipped plateau it then ends at the plateau's far end and
    // the plateau's own shoulders stay within `sep` instead of looking like a rival.
    let gt = t >= *best;
    let cand_b = if far_b { *best } else { 0 };
    let cand_s = if far_s { *second } else { 0 };
    let (demote, demote_at) = if cand_b >= cand_s {
        (cand_b, *best_at)
    } else {
        (cand_s, *second_at)
    };
    let rival = far_b & (t > *second);
    let new_second = if gt {
        demote
    } else if rival {
        t
    } else {
        *second
    };
    let new_second_at = if gt {
        demote_at
    } else if rival {
        at
    } else {
        *second_at
    };
    *second = new_second;
    *second_at = new_second_at;
    *best_at = if gt { at } else { *best_at };
    *best = if gt { t } else { *best };
}

/// The three rows of a rolling buffer for row `r`: the one to write (slot `r % 3`) and the two
/// before it, newest first.
pub(super) fn ring<T, const W: usize>(
    rows: &mut [[T; W]; 3],
    r: usize,
) -> (&mut [T; W], &[T; W], &[T; W]) {
    let [s0, s1, s2] = rows;
    match r % 3 {
        0 => (s0, &*s2, &*s1),
        1 => (s1, &*s0, &*s2),
        _ => (s2, &*s1, &*s0),
    }
}

/// Per-line state from some line on: best, its position, second, its position.
pub(super) type Span<'a> = (&'a mut [u16], &'a mut [u16], &'a mut [u16], &'a mut [u16]);

/// [`track`] for the lines of `state` whose sums `t` reach `floor`.
#[inline(never)]
pub(super) fn track_span(state: Span<'_>, t: &[u16], at: u16, sep: u16, floor: u16) {
    let (best, best_at, second, second_at) = state;
    for (i, &v) in t.iter().enumerate() {
        if v >= floor {
            track(
                v,
                at,
                sep,
                &mut best[i],
                &mut best_at[i],
                &mut second[i],
                &mut second_at[i],
            );
        }
    }
}

impl<const W: usize> Extractor<W> {
    /// Column mode: rows in memory order, per-column state.
    ///
    /// The 3×1 sums of each row are formed 64 columns at a time and the block is skipped unless
    /// one of them reaches `floor`: on a frame the stripe covers a few rows of each column, so the
    /// bookkeeping of [`track`] runs for a few per cent of the chunks and the pass runs at about
    /// the speed of reading the frame.
    pub(super) fn track_columns(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16) {
        const BLOCK: usize = 64;
        let Roi {
            x,
            y,
            width,
            height,
        } = io.roi;
        self.reset(width);
        for r in 0..height {
            let (newest, older, oldest) = ring(&mut self.rows.0, r);
            signal::row(
                io.kind,
                io.frame.row(y + r),
                io.reference.row(y + r),
                x,
                &mut newest[..width],
            );
            if r < 2 {
                continue;
            }
            let at = (r - 1) as u16;
            let newest = &*newest;
            // Blocks of 64 columns: sums, and an OR of `sum − (floor − 1)` (saturating) that is
            // non-zero iff a sum reaches the floor; one horizontal reduction per block.
            let below = floor.saturating_sub(1);
            let mut b = 0;
            while b < width {
                let n = (width - b).min(BLOCK);
                let mut t = [0u16; BLOCK];
                let mut hit = 0u16;
                let rows = newest[b..b + n]
                    .iter()
                    .zip(&older[b..b + n])
                    .zip(&oldest[b..b + n]);
                for (t, ((&p, &q), &o)) in t.iter_mut().zip(rows) {
                    *t = p + q + o;
                    hit |= t.saturating_sub(below);
                }
                if hit != 0 {
                    let state = (
                        &mut self.best[b..],
                        &mut self.best_at[b..],
                        &mut self.second[b..],
                        &mut self.second_at[b..],
                    );
                    track_span(state, &t[..n], at, sep, floor);
                }
                b += n;
            }
        }
    }

    /// [`Self::track_columns`] on the pixels' one-byte magnitudes, for at most
    /// [`BYTE_PASS_WIDTH`] columns.
    ///
    /// A 3×1 sum reaches `floor` only if one of its three samples reaches `⌈floor / 3⌉`, so each
    /// row, as it is made, marks in a 64-bit mask the blocks of 64 columns holding a magnitude
    /// whose signal reaches that (one compare per pixel, in bytes). A centre row then forms exact
    /// sums only in the blocks its three rows mark (through a table from magnitude to signal); on
    /// a frame that is nearly all background that is a few blocks per row.
    pub(super) fn track_columns_u8(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16) {
        if io.kind.squared() {
            let mut table = [0u16; 256];
            for (m, v) in table.iter_mut().enumerate() {
                *v = io.kind.value(m as u8);
            }
            self.track_bytes(io, sep, floor, |m| table[usize::from(m)]);
        } else {
            self.track_bytes(io, sep, floor, u16::from);
        }
    }

    /// [`Self::track_columns_u8`] with the signal of a magnitude given by `value` (monomorphic:
    /// the linear signals keep plain sums).
    #[inline(always)]
    pub(super) fn track_bytes(
        &mut self,
        io: &Io<'_, '_>,
        sep: u16,
        floor: u16,
        value: impl Fn(u8) -> u16,
    ) {
        const BLOCK: usize = 64;
        let Roi {
            x,
            y,
            width,
            height,
        } = io.roi;
        self.reset(width);
        let mark = io.kind.magnitude_for(floor.div_ceil(3));
        if mark > 255 {
            return;
        }
        let below = (mark as u8).saturating_sub(1);
        let mut lit = [0u64; 3];
        for r in 0..height {
            let (newest, older, oldest) = ring(&mut self.bytes.0, r);
            signal::magnitudes(
                io.kind,
                io.frame.row(y + r),
                io.reference.row(y + r),
                x,
                &mut newest[..width],
            );
            let mut marks = 0u64;
            for (b, chunk) in newest[..width].chunks(BLOCK).enumerate() {
                let mut hit = 0u8;
                for &v in chunk {
                    hit |= v.saturating_sub(below);
                }
                marks |= u64::from(hit != 0) << b;
            }
            lit[r % 3] = marks;
            if r < 2 {
                continue;
            }
            let at = (r - 1) as u16;
            let newest = &*newest;
            let mut blocks = lit[0] | lit[1] | lit[2];
            while blocks != 0 {
                let b = blocks.trailing_zeros() as usize * BLOCK;
                blocks &= blocks - 1;
                for c in b..(b + BLOCK).min(width) {
                    let sum = value(newest[c]) + value(older[c]) + value(oldest[c]);
                    if sum >= floor {
                        track(
                            sum,
                            at,
                            sep,
                            &mut self.best[c],
                            &mut self.best_at[c],
                            &mut self.second[c],
                            &mut self.second_at[c],
                        );
                    }
                }
            }
        }
    }

    /// Row mode: each row is one line, read contiguously.
    pub(super) fn track_rows(&mut self, io: &Io<'_, '_>, sep: u16, floor: u16) {
        let Roi {
            x,
            y,
            width,
            height,
        } = io.roi;
        self.reset(height);
        for r in 0..height {
            let buf = &mut self.rows.0[0][..width];
            signal::row(
                io.kind,
                io.frame.row(y + r),
                io.reference.row(y + r),
                x,
                buf,
            );
            let (mut b, mut ba, mut s, mut sa) = (0, 0, 0, 0);
            for (i, w) in buf.windows(3).enumerate() {
                let t = w[0] + w[1] + w[2];
                if t >= floor {
                    track(t, (i + 1) as u16, sep, &mut b, &mut ba, &mut s, &mut sa);
                }
            }
            self.best[r] = b;
            self.best_at[r] = ba;
            self.second[r] = s;
            self.second_at[r] = sa;
        }
    }
}
