//! A frame's points ([`Points`]) and their compact coding: quantised to
//! [`UNIT_MM`](crate::UNIT_MM) and coded as zigzag varints of second-order differences.
//!
//! Consecutive stripe points are neighbours on a smooth curve, so each is predicted from the two
//! before it, `p̂ᵢ = 2·pᵢ₋₁ − pᵢ₋₂` (`p̂₁ = p₀`, `p̂₀ = 0`), and only the residual `pᵢ − p̂ᵢ` is
//! sent, per coordinate, as a zigzag LEB128 varint (the same integer coding postcard uses). On a
//! smooth surface the residuals are a few hundredths of a millimetre: one byte per coordinate.

use serde::{Deserialize, Serialize};

use crate::WireError;

/// One frame's points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Points<'a> {
    /// Scan id.
    pub scan_id: u32,
    /// Frame number in the scan (gaps: skipped or lost frames).
    pub frame: u32,
    /// Capture time since the scan started, microseconds.
    pub time_us: u64,
    /// The laser plane `[nx, ny, nz, d]` of this frame.
    pub plane: [f32; 4],
    /// Number of points.
    pub count: u32,
    /// Coordinates: [`encode`] coding of the quantised points.
    #[serde(borrow)]
    pub xyz: &'a [u8],
    /// Colour, 3 bytes (RGB) per point, or empty.
    #[serde(borrow)]
    pub rgb: &'a [u8],
    /// Standard uncertainty, one byte per point ([`uncertainty_code`]), or empty.
    #[serde(borrow)]
    pub uncertainty: &'a [u8],
}

/// Quantises millimetres to wire units, `None` for a value outside `i32` or not finite.
pub fn quantise(mm: f32) -> Option<i32> {
    let q = libm::roundf(mm * (1.0 / crate::UNIT_MM));
    (q.is_finite() && q >= i32::MIN as f32 && q <= i32::MAX as f32).then_some(q as i32)
}

/// Wire units to millimetres.
pub fn dequantise(q: i32) -> f32 {
    (q as f64 * f64::from(crate::UNIT_MM)) as f32
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(u: u64) -> i64 {
    ((u >> 1) as i64) ^ -((u & 1) as i64)
}

fn put_varint(mut u: u64, out: &mut [u8], pos: &mut usize) -> Result<(), WireError> {
    loop {
        let byte = (u & 0x7f) as u8;
        u >>= 7;
        let slot = out.get_mut(*pos).ok_or(WireError::BufferFull)?;
        *pos += 1;
        if u == 0 {
            *slot = byte;
            return Ok(());
        }
        *slot = byte | 0x80;
    }
}

fn get_varint(data: &[u8], pos: &mut usize) -> Result<u64, WireError> {
    let mut u = 0u64;
    for shift in (0..64).step_by(7) {
        let b = *data.get(*pos).ok_or(WireError::Truncated)?;
        *pos += 1;
        u |= u64::from(b & 0x7f) << shift;
        if b & 0x80 == 0 {
            return Ok(u);
        }
    }
    Err(WireError::BadPoints)
}

/// Encodes quantised points into `out`; returns the bytes written.
///
/// # Errors
/// [`WireError::BufferFull`] if `out` is too small (at most 15 bytes per point are needed).
pub fn encode(points: &[[i32; 3]], out: &mut [u8]) -> Result<usize, WireError> {
    let mut pos = 0;
    let (mut a, mut b) = ([0i64; 3], [0i64; 3]); // pᵢ₋₂, pᵢ₋₁
    for (i, p) in points.iter().enumerate() {
        for k in 0..3 {
            let pred = match i {
                0 => 0,
                1 => b[k],
                _ => 2 * b[k] - a[k],
            };
            put_varint(zigzag(i64::from(p[k]) - pred), out, &mut pos)?;
        }
        a = b;
        b = p.map(i64::from);
    }
    Ok(pos)
}

/// Decodes `count` points from `data`, calling `f` with each.
///
/// # Errors
/// [`WireError::Truncated`] if `data` ends early, [`WireError::BadPoints`] for a varint that
/// does not end, a point outside `i32`, or bytes left over.
pub fn decode(data: &[u8], count: usize, mut f: impl FnMut([i32; 3])) -> Result<(), WireError> {
    let mut pos = 0;
    let (mut a, mut b) = ([0i64; 3], [0i64; 3]);
    for i in 0..count {
        let mut p = [0i32; 3];
        for k in 0..3 {
            let pred = match i {
                0 => 0,
                1 => b[k],
                _ => 2 * b[k] - a[k],
            };
            let v = unzigzag(get_varint(data, &mut pos)?)
                .checked_add(pred)
                .ok_or(WireError::BadPoints)?;
            p[k] = i32::try_from(v).map_err(|_| WireError::BadPoints)?;
        }
        a = b;
        b = p.map(i64::from);
        f(p);
    }
    if pos == data.len() {
        Ok(())
    } else {
        Err(WireError::BadPoints)
    }
}

/// Codes per octave of [`uncertainty_code`]: one code is a step of 2^(1/16), 4.4 %.
const CODES_PER_OCTAVE: f32 = 16.0;

/// A point's standard uncertainty (mm) as its wire byte: `round(16 · log₂(u / 1 µm))`, clamped
/// to 0…255 (1 µm to 63 mm in steps of 4.4 %). Not finite or not positive: 255 (unknown, as
/// large as the code says).
pub fn uncertainty_code(mm: f32) -> u8 {
    let um = mm * 1000.0;
    if !(um.is_finite() && um > 0.0) {
        return u8::MAX;
    }
    libm::roundf(CODES_PER_OCTAVE * libm::log2f(um)).clamp(0.0, 255.0) as u8
}

/// The standard uncertainty a wire byte stands for, mm ([`uncertainty_code`]'s inverse).
pub fn uncertainty_mm(code: u8) -> f32 {
    libm::exp2f(f32::from(code) / CODES_PER_OCTAVE) / 1000.0
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn points_golden_frame() {
        crate::golden::check(
            Message::Points(Points {
                scan_id: 5,
                frame: 17,
                time_us: 1_234_567,
                plane: [0.6, 0.0, -0.8, 400.0],
                count: 2,
                xyz: &[2, 4, 6, 1, 3, 5],
                rgb: &[255, 0, 0, 200, 10, 10],
                uncertainty: &[12, 40],
            }),
            &[
                0, 12, 2, 1, 5, 17, 135, 173, 75, 154, 153, 25, 63, 1, 1, 1, 5, 205, 204, 76, 191,
                1, 13, 200, 67, 2, 6, 2, 4, 6, 1, 3, 5, 6, 255, 1, 11, 200, 10, 10, 2, 12, 40, 31,
                228, 169, 100, 0,
            ],
        );
    }
}
