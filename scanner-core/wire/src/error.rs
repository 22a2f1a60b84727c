//! Why encoding or decoding failed ([`WireError`]).

use core::fmt;

use crate::{MAX_ENCODED, VERSION};

/// Why encoding or decoding failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// The output buffer is too small.
    BufferFull,
    /// The bytes end before the message does.
    Truncated,
    /// Not valid COBS.
    BadCobs,
    /// The CRC does not match.
    BadCrc,
    /// A protocol version this build does not read.
    UnknownVersion(u8),
    /// The payload is not a message of this version.
    BadPayload,
    /// The point data is inconsistent with its count.
    BadPoints,
    /// A frame longer than [`MAX_ENCODED`].
    Oversize,
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BufferFull => f.write_str("output buffer too small"),
            Self::Truncated => f.write_str("data ends inside a message"),
            Self::BadCobs => f.write_str("bad COBS framing"),
            Self::BadCrc => f.write_str("CRC mismatch"),
            Self::UnknownVersion(v) => write!(
                f,
                "unknown protocol version {v} (this build reads 1 and {VERSION})"
            ),
            Self::BadPayload => f.write_str("payload is not a valid message"),
            Self::BadPoints => f.write_str("point data inconsistent with its count"),
            Self::Oversize => write!(f, "frame longer than {MAX_ENCODED} bytes"),
        }
    }
}

impl core::error::Error for WireError {}
