//! A frame as a USB webcam sends it: motion JPEG with 4:2:2 chroma.

/// An RGB frame as a USB webcam's motion-JPEG frame: baseline JPEG with 4:2:2 chroma (what UVC
/// cameras send), standard Huffman tables, at `quality` (1–100).
///
/// # Errors
/// [`MjpegError`]: a side over 65 535 pixels, or the encoder's (a buffer of the wrong length).
pub fn mjpeg(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, MjpegError> {
    let side = |n: u32| u16::try_from(n).map_err(|_| MjpegError::TooLarge(width, height));
    let (w, h) = (side(width)?, side(height)?);
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality);
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_2);
    encoder.encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)?;
    Ok(out)
}

/// Why a frame could not be encoded as a webcam's motion-JPEG frame ([`mjpeg`]).
#[derive(Debug, thiserror::Error)]
pub enum MjpegError {
    /// A side longer than JPEG holds.
    #[error("a {0}×{1} frame: JPEG holds at most 65535 pixels a side")]
    TooLarge(u32, u32),
    /// The encoder refused the pixels.
    #[error("the JPEG encoder: {0}")]
    Encoder(#[from] jpeg_encoder::EncodingError),
}
