//! Frame views: 8-bit gray, YUYV 4:2:2 and RGB24 with a row stride, read in place.

use core::fmt;

/// Pixel layout of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    /// One byte per pixel.
    Gray8,
    /// YUYV 4:2:2: two bytes per pixel, luma `Y` at even byte offsets (read in place).
    Yuyv,
    /// Three bytes per pixel, R, G, B.
    Rgb24,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub const fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Gray8 => 1,
            Self::Yuyv => 2,
            Self::Rgb24 => 3,
        }
    }
}

/// Why a frame, a reference or a region of interest was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameError {
    /// Width or height is zero.
    Empty,
    /// The stride is shorter than a row of pixels.
    StrideTooShort {
        /// Given stride, bytes.
        stride: usize,
        /// Bytes one row needs.
        needed: usize,
    },
    /// The buffer is shorter than `stride × (height − 1) + row bytes`.
    BufferTooShort {
        /// Given length, bytes.
        len: usize,
        /// Bytes needed.
        needed: usize,
    },
    /// YUYV needs an even width.
    OddYuyvWidth,
    /// The reference frame differs from the frame in size or format.
    ReferenceMismatch,
    /// The region of interest is empty or leaves the frame.
    BadRoi,
    /// More lines or a longer profile than the extractor's capacity.
    TooLarge {
        /// Lines or samples asked for.
        asked: usize,
        /// Capacity of the extractor.
        capacity: usize,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Empty => f.write_str("frame has zero width or height"),
            Self::StrideTooShort { stride, needed } => {
                write!(
                    f,
                    "row stride {stride} B is shorter than a row ({needed} B)"
                )
            }
            Self::BufferTooShort { len, needed } => {
                write!(f, "frame buffer has {len} B, needs {needed} B")
            }
            Self::OddYuyvWidth => f.write_str("YUYV frame width must be even"),
            Self::ReferenceMismatch => {
                f.write_str("reference frame differs from the frame in size or format")
            }
            Self::BadRoi => f.write_str("region of interest is empty or outside the frame"),
            Self::TooLarge { asked, capacity } => {
                write!(f, "{asked} exceeds the extractor capacity {capacity}")
            }
        }
    }
}

impl core::error::Error for FrameError {}

/// A borrowed frame: pixels in rows of `stride` bytes.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    data: &'a [u8],
    width: usize,
    height: usize,
    stride: usize,
    format: PixelFormat,
}

impl<'a> Frame<'a> {
    /// A view over `data`.
    ///
    /// # Errors
    /// [`FrameError`] when the sizes do not fit the buffer.
    pub fn new(
        data: &'a [u8],
        width: usize,
        height: usize,
        stride: usize,
        format: PixelFormat,
    ) -> Result<Self, FrameError> {
        if width == 0 || height == 0 {
            return Err(FrameError::Empty);
        }
        if format == PixelFormat::Yuyv && !width.is_multiple_of(2) {
            return Err(FrameError::OddYuyvWidth);
        }
        let row = width
            .checked_mul(format.bytes_per_pixel())
            .ok_or(FrameError::TooLarge {
                asked: width,
                capacity: usize::MAX / 4,
            })?;
        if stride < row {
            return Err(FrameError::StrideTooShort {
                stride,
                needed: row,
            });
        }
        let needed = stride
            .checked_mul(height - 1)
            .and_then(|v| v.checked_add(row))
            .ok_or(FrameError::BufferTooShort {
                len: data.len(),
                needed: usize::MAX,
            })?;
        if data.len() < needed {
            return Err(FrameError::BufferTooShort {
                len: data.len(),
                needed,
            });
        }
        Ok(Self {
            data,
            width,
            height,
            stride,
            format,
        })
    }

    /// A tightly packed frame (stride = row bytes).
    ///
    /// # Errors
    /// As [`Frame::new`].
    pub fn packed(
        data: &'a [u8],
        width: usize,
        height: usize,
        format: PixelFormat,
    ) -> Result<Self, FrameError> {
        Self::new(
            data,
            width,
            height,
            width.saturating_mul(format.bytes_per_pixel()),
            format,
        )
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Row stride in bytes.
    pub fn stride(&self) -> usize {
        self.stride
    }
    /// Pixel format.
    pub fn format(&self) -> PixelFormat {
        self.format
    }

    /// The bytes of row `y`, exactly `width × bytes per pixel` long.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [u8] {
        &self.data[y * self.stride..][..self.width * self.format.bytes_per_pixel()]
    }

    /// The whole buffer.
    pub(crate) fn data(&self) -> &'a [u8] {
        self.data
    }

    /// `true` if `other` has the same size and format.
    pub fn same_shape(&self, other: &Frame<'_>) -> bool {
        self.width == other.width && self.height == other.height && self.format == other.format
    }
}
