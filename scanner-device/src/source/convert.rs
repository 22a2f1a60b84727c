//! Camera buffers to the pixel formats the pipeline reads. Pure functions, tested on recorded
//! buffers, so that the V4L2 path's format handling is checked without a camera.
//!
//! Camera formats (V4L2 FourCC): `YUYV` (4:2:2, luma every other byte), `GREY` (8-bit), `RGB3`
//! (24-bit RGB), `MJPG` (motion JPEG: each buffer a JPEG image). Buffers may have padded rows
//! (`stride` ≥ the packed row).

use scanner_core::colour::{luma, rgb_pair_to_yuyv, yuv_to_rgb};
use scanner_core::stripe::PixelFormat;
use scanner_jpeg::{JpegDecoder, JpegError, Output};

/// A camera's pixel format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraFormat {
    /// `YUYV`.
    Yuyv,
    /// `GREY`.
    Grey,
    /// `RGB3`.
    Rgb3,
    /// `MJPG`.
    Mjpeg,
}

/// A camera pixel format this head does not read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unsupported camera pixel format {0:?}: this head reads YUYV, GREY, RGB3 and MJPG")]
pub struct UnsupportedFormat(pub String);

impl CameraFormat {
    /// From a FourCC code.
    pub fn from_fourcc(code: [u8; 4]) -> Option<CameraFormat> {
        match &code {
            b"YUYV" => Some(CameraFormat::Yuyv),
            b"GREY" => Some(CameraFormat::Grey),
            b"RGB3" => Some(CameraFormat::Rgb3),
            b"MJPG" => Some(CameraFormat::Mjpeg),
            _ => None,
        }
    }

    /// From a FourCC given as text (`--fourcc YUYV`): the one check of a user's format name.
    ///
    /// # Errors
    /// [`UnsupportedFormat`] naming what was given and what this head reads.
    pub fn parse(s: &str) -> Result<CameraFormat, UnsupportedFormat> {
        let b = s.as_bytes();
        (b.len() == 4)
            .then(|| CameraFormat::from_fourcc([b[0], b[1], b[2], b[3]]))
            .flatten()
            .ok_or_else(|| UnsupportedFormat(s.chars().take(16).collect()))
    }

    /// The pixel format its frames are read in when none is asked: as the camera sends them
    /// (GREY as gray, YUYV in place, RGB3 as RGB), MJPEG decoded to YUYV (a JPEG is Y, Cb, Cr
    /// already: no colour conversion) — colour kept, so that the laser's colour counts.
    pub fn native(self) -> PixelFormat {
        match self {
            CameraFormat::Grey => PixelFormat::Gray8,
            CameraFormat::Yuyv | CameraFormat::Mjpeg => PixelFormat::Yuyv,
            CameraFormat::Rgb3 => PixelFormat::Rgb24,
        }
    }

    /// The FourCC code.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            CameraFormat::Yuyv => *b"YUYV",
            CameraFormat::Grey => *b"GREY",
            CameraFormat::Rgb3 => *b"RGB3",
            CameraFormat::Mjpeg => *b"MJPG",
        }
    }

    fn bytes_per_pixel(self) -> usize {
        match self {
            CameraFormat::Yuyv => 2,
            CameraFormat::Grey => 1,
            CameraFormat::Rgb3 => 3,
            CameraFormat::Mjpeg => 0,
        }
    }
}

/// Why a buffer could not be converted.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConvertError {
    /// The buffer is shorter than its size says.
    #[error(
        "camera buffer of {got} bytes, {want} expected for {width}×{height} {format:?} (stride {stride})"
    )]
    Short {
        /// Bytes received.
        got: usize,
        /// Bytes needed.
        want: usize,
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Format.
        format: CameraFormat,
        /// Row stride.
        stride: usize,
    },
    /// A MJPEG frame that does not decode, or decodes to another size.
    #[error("MJPEG frame: {0}")]
    Jpeg(JpegError),
    /// An odd width for YUYV.
    #[error("YUYV needs an even width, got {0}")]
    OddWidth(usize),
    /// A frame size over the JPEG decoder's limit ([`scanner_jpeg::MAX_SIDE`] a side),
    /// refused before its buffer is allocated.
    #[error("a {width}×{height} MJPEG stream: at most {max} pixels a side are decoded", max = scanner_jpeg::MAX_SIDE)]
    TooLarge {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
    },
}

/// Converts camera buffers frame after frame, keeping what MJPEG needs between them: the JPEG
/// decoder (its tables built once) and, for RGB, the decoded YUYV. Once `out` has its size, a frame allocates
/// nothing.
pub struct Converter {
    jpeg: Box<JpegDecoder>,
    yuyv: Vec<u8>,
}

impl Default for Converter {
    fn default() -> Self {
        Self::new()
    }
}

impl Converter {
    /// A converter with the standard JPEG tables.
    pub fn new() -> Self {
        Converter {
            jpeg: Box::new(JpegDecoder::new()),
            yuyv: Vec::new(),
        }
    }

    /// Converts one camera buffer to `want` into `out` (resized to fit, rows packed). MJPEG
    /// decodes straight into YUYV or gray; RGB goes through YUYV.
    ///
    /// # Errors
    /// [`ConvertError`] naming what is wrong with the buffer.
    #[allow(clippy::too_many_arguments)]
    pub fn convert(
        &mut self,
        format: CameraFormat,
        data: &[u8],
        width: usize,
        height: usize,
        stride: usize,
        want: PixelFormat,
        out: &mut Vec<u8>,
    ) -> Result<(), ConvertError> {
        if format != CameraFormat::Mjpeg {
            return convert(format, data, width, height, stride, want, out);
        }
        if want != PixelFormat::Gray8 && !width.is_multiple_of(2) {
            return Err(ConvertError::OddWidth(width));
        }
        if width > scanner_jpeg::MAX_SIDE || height > scanner_jpeg::MAX_SIDE {
            return Err(ConvertError::TooLarge { width, height });
        }
        let (output, target) = match want {
            PixelFormat::Gray8 => (Output::Gray, &mut *out),
            PixelFormat::Yuyv => (Output::Yuyv, &mut *out),
            PixelFormat::Rgb24 => (Output::Yuyv, &mut self.yuyv),
        };
        let bytes = match output {
            Output::Gray => 1,
            Output::Yuyv => 2,
        };
        target.resize(bytes * width * height, 0);
        self.jpeg
            .decode(data, width, height, output, target)
            .map_err(ConvertError::Jpeg)?;
        if want == PixelFormat::Rgb24 {
            convert(
                CameraFormat::Yuyv,
                &self.yuyv,
                width,
                height,
                2 * width,
                want,
                out,
            )?;
        }
        Ok(())
    }
}

/// Converts one raw camera buffer (YUYV, GREY, RGB3) to `want` into `out` (resized to fit, rows
/// packed); MJPEG needs a [`Converter`].
///
/// # Errors
/// [`ConvertError`] naming what is wrong with the buffer.
pub fn convert(
    format: CameraFormat,
    data: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    want: PixelFormat,
    out: &mut Vec<u8>,
) -> Result<(), ConvertError> {
    if format == CameraFormat::Mjpeg {
        return Converter::new().convert(format, data, width, height, stride, want, out);
    }
    let bpp = format.bytes_per_pixel();
    let stride = stride.max(bpp * width);
    let need = if height == 0 {
        0
    } else {
        stride * (height - 1) + bpp * width
    };
    if data.len() < need {
        return Err(ConvertError::Short {
            got: data.len(),
            want: need,
            width,
            height,
            format,
            stride,
        });
    }
    if (format == CameraFormat::Yuyv || want == PixelFormat::Yuyv) && !width.is_multiple_of(2) {
        return Err(ConvertError::OddWidth(width));
    }
    out.clear();
    out.reserve(want.bytes_per_pixel() * width * height);
    for y in 0..height {
        let row = &data[y * stride..y * stride + bpp * width];
        match (format, want) {
            (CameraFormat::Yuyv, PixelFormat::Yuyv)
            | (CameraFormat::Grey, PixelFormat::Gray8)
            | (CameraFormat::Rgb3, PixelFormat::Rgb24) => out.extend_from_slice(row),
            (CameraFormat::Yuyv, PixelFormat::Gray8) => out.extend(row.iter().step_by(2)),
            (CameraFormat::Grey, PixelFormat::Rgb24) => {
                row.iter().for_each(|&v| out.extend([v, v, v]))
            }
            (CameraFormat::Grey, PixelFormat::Yuyv) => {
                row.iter().for_each(|&v| out.extend([v, 128]))
            }
            (CameraFormat::Rgb3, PixelFormat::Gray8) => {
                out.extend(row.chunks_exact(3).map(|p| luma([p[0], p[1], p[2]])));
            }
            (CameraFormat::Rgb3, PixelFormat::Yuyv) => {
                for p in row.chunks_exact(6) {
                    out.extend(rgb_pair_to_yuyv([p[0], p[1], p[2]], [p[3], p[4], p[5]]));
                }
            }
            (CameraFormat::Yuyv, PixelFormat::Rgb24) => {
                for q in row.chunks_exact(4) {
                    out.extend(yuv_to_rgb(q[0], q[1], q[3]));
                    out.extend(yuv_to_rgb(q[2], q[1], q[3]));
                }
            }
            (CameraFormat::Mjpeg, _) => {} // decoded above, never here
        }
    }
    Ok(())
}
