//! Image files as frames: one file, or a folder of them in name order.

use scanner_core::stripe::PixelFormat;

use super::{FrameSource, OwnedFrame, SourceError, SourceOptions, laser_off_reference};

/// Reads an image file as a frame in `format`.
///
/// # Errors
/// [`SourceError::Image`] or [`SourceError::Convert`] naming the file.
pub fn load_frame(
    path: &std::path::Path,
    format: PixelFormat,
    index: u64,
) -> Result<OwnedFrame, SourceError> {
    let jpeg = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("jpg") || e.eq_ignore_ascii_case("jpeg"));
    if jpeg && format != PixelFormat::Rgb24 {
        return load_jpeg(path, format, index);
    }
    let img = scanner_io::image_file::open(path).map_err(SourceError::Image)?;
    let rgb = img.to_rgb8();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let mut data = Vec::new();
    crate::source::convert::convert(
        crate::source::convert::CameraFormat::Rgb3,
        rgb.as_raw(),
        w,
        h,
        3 * w,
        format,
        &mut data,
    )
    .map_err(|source| SourceError::Convert {
        what: path.display().to_string(),
        source,
    })?;
    Ok(OwnedFrame {
        time_us: None,
        data,
        width: w,
        height: h,
        format,
        index,
    })
}

/// A JPEG file straight into gray or YUYV by the head's own decoder (a camera's motion-JPEG
/// frame is decoded the same way): no RGB between, and the blocks that hold nothing but their
/// mean (a dark frame is mostly such blocks) skip the inverse transform.
fn load_jpeg(
    path: &std::path::Path,
    format: PixelFormat,
    index: u64,
) -> Result<OwnedFrame, SourceError> {
    let (w, h) = scanner_io::image_file::dimensions(path).map_err(SourceError::Image)?;
    let data = std::fs::read(path).map_err(|source| {
        SourceError::Image(scanner_io::image_file::ImageFileError::Read {
            path: path.to_path_buf(),
            source: image::ImageError::IoError(source),
        })
    })?;
    let (w, h) = (w as usize, h as usize);
    let mut out = Vec::new();
    crate::source::convert::Converter::new()
        .convert(
            crate::source::convert::CameraFormat::Mjpeg,
            &data,
            w,
            h,
            0,
            format,
            &mut out,
        )
        .map_err(|source| SourceError::Convert {
            what: path.display().to_string(),
            source,
        })?;
    Ok(OwnedFrame {
        time_us: None,
        data: out,
        width: w,
        height: h,
        format,
        index,
    })
}

/// The images of a folder in name order (PNG and JPEG); `reference.*` is the reference frame.
#[derive(Debug)]
pub struct ImageDir {
    dir: std::path::PathBuf,
    files: Vec<std::path::PathBuf>,
    reference: Option<std::path::PathBuf>,
    format: PixelFormat,
    size: (usize, usize),
    next: usize,
    reference_frames: usize,
}

/// The pixel format of an image file's frames when none is asked: gray for a gray image, RGB
/// for any other (the laser's colour kept).
///
/// # Errors
/// [`SourceError::Image`] naming the file.
pub fn native_format(path: &std::path::Path) -> Result<PixelFormat, SourceError> {
    let img = scanner_io::image_file::open(path).map_err(SourceError::Image)?;
    Ok(match img.color() {
        image::ColorType::L8
        | image::ColorType::L16
        | image::ColorType::La8
        | image::ColorType::La16 => PixelFormat::Gray8,
        _ => PixelFormat::Rgb24,
    })
}

impl ImageDir {
    /// The folder's images (PNG and JPEG, in name order) and its reference image, if any.
    ///
    /// # Errors
    /// [`SourceError::Folder`] for an unreadable folder, [`SourceError::Images`] for one without
    /// images.
    fn list(
        dir: &std::path::Path,
        reference: Option<std::path::PathBuf>,
    ) -> Result<(Vec<std::path::PathBuf>, Option<std::path::PathBuf>), SourceError> {
        let io = |source: std::io::Error| SourceError::Folder {
            path: dir.to_path_buf(),
            source,
        };
        let mut files = Vec::new();
        let mut reference = reference;
        for entry in std::fs::read_dir(dir).map_err(io)? {
            let path = entry.map_err(io)?.path();
            let ext = path
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if !matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")) {
                continue;
            }
            if path.file_stem().and_then(|s| s.to_str()) == Some("reference") {
                reference.get_or_insert(path);
                continue;
            }
            files.push(path);
        }
        files.sort();
        if files.is_empty() {
            return Err(SourceError::Images(format!(
                "{}: no PNG or JPEG images",
                dir.display()
            )));
        }
        Ok((files, reference))
    }

    /// The pixel format of the folder's frames when none is asked ([`native_format`] of its
    /// first image).
    ///
    /// # Errors
    /// As [`ImageDir::open`].
    pub fn native_format(dir: &std::path::Path) -> Result<PixelFormat, SourceError> {
        let (files, _) = Self::list(dir, None)?;
        native_format(&files[0])
    }

    /// Lists a folder.
    ///
    /// # Errors
    /// [`SourceError::Folder`] for an unreadable folder, [`SourceError::Images`] for one without
    /// images, or the first image's error for an unreadable first
    /// image.
    pub fn open(
        dir: &std::path::Path,
        format: PixelFormat,
        opts: &SourceOptions,
    ) -> Result<ImageDir, SourceError> {
        let (files, reference) = Self::list(dir, opts.reference.clone())?;
        let f = load_frame(&files[0], format, 0)?;
        Ok(ImageDir {
            dir: dir.to_path_buf(),
            files,
            reference,
            format,
            size: (f.width, f.height),
            next: 0,
            reference_frames: opts.reference_frames(),
        })
    }
}

impl FrameSource for ImageDir {
    fn describe(&self) -> String {
        format!(
            "{} images in {} ({}×{})",
            self.files.len(),
            self.dir.display(),
            self.size.0,
            self.size.1
        )
    }

    fn format(&self) -> PixelFormat {
        self.format
    }

    fn frames_left(&self) -> Option<usize> {
        Some(self.files.len().saturating_sub(self.next))
    }

    fn size(&self) -> (usize, usize) {
        self.size
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let r = match &self.reference {
            Some(p) => load_frame(p, self.format, u64::MAX)?,
            // Without a laser-off photo the first images make the reference: some must be left.
            None if self.files.len() <= self.reference_frames => {
                return Err(SourceError::Images(format!(
                    "{}: {} image(s) and no reference: without a laser-off photo the first {} images are averaged into the reference, which leaves none to scan; give --reference FILE (a photo of the same view with the laser off) or put it in the folder as reference.png",
                    self.dir.display(),
                    self.files.len(),
                    self.reference_frames
                )));
            }
            None => {
                let n = self.reference_frames.min(self.files.len());
                let frames = self.files[..n]
                    .iter()
                    .map(|p| load_frame(p, self.format, u64::MAX))
                    .collect::<Result<Vec<_>, _>>()?;
                self.next = n;
                laser_off_reference(&frames)?
            }
        };
        if (r.width, r.height) != self.size {
            return Err(SourceError::Images(format!(
                "the reference is {}×{}, the images {}×{}",
                r.width, r.height, self.size.0, self.size.1
            )));
        }
        Ok(r)
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        let Some(path) = self.files.get(self.next) else {
            return Ok(None);
        };
        let f = load_frame(path, self.format, self.next as u64)?;
        if (f.width, f.height) != self.size {
            return Err(SourceError::Images(format!(
                "{} is {}×{}, the first image {}×{}",
                path.display(),
                f.width,
                f.height,
                self.size.0,
                self.size.1
            )));
        }
        self.next += 1;
        Ok(Some(f))
    }
}
