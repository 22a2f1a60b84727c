//! Reading an image file, with its size checked against [`MAX_IMAGE_SIDE`] from the file's header
//! before any pixel is decoded (a crafted 20000×20000 PNG is refused at a few bytes, not at 2 GB).
//! Every image the head and the calibration read from disk comes through here.

use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageReader};

/// The longest side of an image taken from a file or a camera, pixels: the head's per-frame
/// buffers hold a line per point of a frame (the wire's [`scanner_wire::MAX_POINTS`]).
pub const MAX_IMAGE_SIDE: u32 = scanner_wire::MAX_POINTS as u32;

/// Most bytes the decoder may allocate for one image (an RGBA image of the largest size, 16-bit
/// channels: 4096² × 8 = 128 MiB).
pub const MAX_DECODE_BYTES: u64 = (MAX_IMAGE_SIDE as u64) * (MAX_IMAGE_SIDE as u64) * 8;

/// Why an image file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ImageFileError {
    /// The path is a folder.
    #[error("{} is a folder, not an image file", path.display())]
    Folder {
        /// The path.
        path: PathBuf,
    },
    /// The file cannot be opened or decoded.
    #[error("cannot read image {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// The header gives a size over the limit (or an empty image).
    #[error(
        "image {} is {width}×{height} pixels: each side must be 1 to {MAX_IMAGE_SIDE}",
        path.display()
    )]
    Size {
        /// The file.
        path: PathBuf,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
    },
}

fn limits() -> image::Limits {
    let mut l = image::Limits::default();
    l.max_image_width = Some(MAX_IMAGE_SIDE);
    l.max_image_height = Some(MAX_IMAGE_SIDE);
    l.max_alloc = Some(MAX_DECODE_BYTES);
    l
}

/// The size of an image file (its header read only), checked: sides of 1 to
/// [`MAX_IMAGE_SIDE`].
///
/// # Errors
/// [`ImageFileError`] naming the file: a folder, unreadable, or too large.
pub fn dimensions(path: &Path) -> Result<(u32, u32), ImageFileError> {
    if path.is_dir() {
        return Err(ImageFileError::Folder {
            path: path.to_path_buf(),
        });
    }
    let read = |source| ImageFileError::Read {
        path: path.to_path_buf(),
        source,
    };
    let (width, height) = ImageReader::open(path)
        .map_err(|e| read(image::ImageError::IoError(e)))?
        .with_guessed_format()
        .map_err(|e| read(image::ImageError::IoError(e)))?
        .into_dimensions()
        .map_err(read)?;
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(ImageFileError::Size {
            path: path.to_path_buf(),
            width,
            height,
        });
    }
    Ok((width, height))
}

/// Reads an image file whose sides are at most [`MAX_IMAGE_SIDE`].
///
/// # Errors
/// [`ImageFileError`] naming the file: a folder, unreadable or undecodable, or too large.
pub fn open(path: &Path) -> Result<DynamicImage, ImageFileError> {
    dimensions(path)?;
    let read = |source| ImageFileError::Read {
        path: path.to_path_buf(),
        source,
    };
    let reader = || {
        ImageReader::open(path)
            .map_err(|e| read(image::ImageError::IoError(e)))?
            .with_guessed_format()
            .map_err(|e| read(image::ImageError::IoError(e)))
    };
    let mut r = reader()?;
    r.limits(limits());
    r.decode().map_err(read)
}

/// Decodes an in-memory image of a known format under the same limits (a camera's JPEG frame).
///
/// # Errors
/// The decoder's error, also when the image is over the limits.
pub fn decode(data: &[u8], format: image::ImageFormat) -> Result<DynamicImage, image::ImageError> {
    let mut r = ImageReader::with_format(std::io::Cursor::new(data), format);
    r.limits(limits());
    r.decode()
}
