//! Motion-JPEG frames decoded straight into the layout the stripe extraction reads: YUYV (luma
//! and both chroma channels at the camera's 4:2:2 positions) or gray. A webcam's MJPEG frame is
//! already Y, Cb, Cr; decoding it to RGB and converting back would be two passes over the frame
//! that the stripe never needs.
//!
//! Baseline JPEG only (sequential, Huffman, 8-bit samples: `SOF0` and `SOF1`), which is what UVC
//! cameras send: one component (gray) or three with 4:2:2, 4:2:0 or 4:4:4 sampling, restart
//! intervals, and frames without Huffman tables (many webcams omit them and mean the standard
//! tables of ITU T.81 Annex K, which are used then). Progressive, lossless, arithmetic-coded and
//! 12-bit images are refused by name.
//!
//! Fixed memory: a [`JpegDecoder`] holds its tables (about 12 KiB) and is reused frame after frame;
//! it allocates nothing. The inverse DCT is the floating-point AAN factorisation of the IJG's
//! `jidctflt`, written over eight lanes at once so that it compiles to vector instructions on
//! x86-64 (SSE2) and aarch64 (NEON) alike; no input makes it panic (integer arithmetic wraps,
//! floats saturate into a byte).
//!
//! # Layers
//! ```text
//! decoder
//! huffman  idct
//! error
//! ```

#![no_std]
#![deny(missing_docs)]
#![deny(unsafe_code)]

mod decoder;
mod error;
mod huffman;
mod idct;

pub use decoder::JpegDecoder;
pub use error::JpegError;

/// The largest width or height decoded (pixels); a larger frame is refused before any work.
pub const MAX_SIDE: usize = 8192;

/// What the decoder writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// YUYV 4:2:2, `2 × width` bytes a row: chroma taken as it is for 4:2:2 images, repeated
    /// on two rows for 4:2:0, every other sample for 4:4:4, 128 for gray images.
    Yuyv,
    /// One byte of luma a pixel; the chroma is entropy-decoded (it must be) but not transformed.
    Gray,
}
