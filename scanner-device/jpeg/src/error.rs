//! Why a frame was not decoded ([`JpegError`]).

use core::fmt;

/// Why a frame was not decoded. `at` is the byte offset in the frame where it was seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum JpegError {
    /// The data does not start with the JPEG start-of-image marker.
    NotJpeg,
    /// The data ends inside a segment or before the image data.
    Truncated {
        /// Where the data ran out.
        at: usize,
    },
    /// A kind of JPEG this decoder does not read.
    Unsupported {
        /// What it is.
        what: &'static str,
        /// Where it was declared.
        at: usize,
    },
    /// A segment whose contents are inconsistent.
    BadSegment {
        /// Its marker (the byte after `0xFF`).
        marker: u8,
        /// Where the segment starts.
        at: usize,
        /// What is wrong with it.
        what: &'static str,
    },
    /// The image is not the size the stream announced.
    Size {
        /// The image's width.
        width: usize,
        /// The image's height.
        height: usize,
        /// The width expected.
        want_width: usize,
        /// The height expected.
        want_height: usize,
    },
    /// The output buffer is shorter than the image needs.
    OutputTooSmall {
        /// Its length.
        len: usize,
        /// Bytes needed.
        needed: usize,
    },
    /// The entropy-coded data is corrupt: a code no table has, a coefficient past the block's
    /// end, a missing restart marker, or the data running out before the last block.
    Corrupt {
        /// The MCU (block group, in reading order) where it was found.
        mcu: usize,
        /// What was found.
        what: &'static str,
    },
}

impl fmt::Display for JpegError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NotJpeg => f.write_str("not a JPEG image (no start-of-image marker FF D8)"),
            Self::Truncated { at } => write!(f, "the JPEG data ends early, at byte {at}"),
            Self::Unsupported { what, at } => {
                write!(
                    f,
                    "{what} (byte {at}): this decoder reads baseline JPEG, as webcams send"
                )
            }
            Self::BadSegment { marker, at, what } => {
                write!(f, "bad JPEG segment FF {marker:02X} at byte {at}: {what}")
            }
            Self::Size {
                width,
                height,
                want_width,
                want_height,
            } => write!(
                f,
                "the JPEG image is {width}×{height}, the stream is {want_width}×{want_height}"
            ),
            Self::OutputTooSmall { len, needed } => write!(
                f,
                "output buffer of {len} bytes, {needed} needed for the image"
            ),
            Self::Corrupt { mcu, what } => {
                write!(f, "corrupt JPEG data in block group {mcu}: {what}")
            }
        }
    }
}
