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
    /// The folder's images (PNG and JPEG, in frame order: [`frame_order`]) and its reference
    /// image, if any.
    ///
    /// # Errors
    /// [`SourceError::Folder`] for an unreadable folder, [`SourceError::Images`] for one without
    /// images, or with two names of one place in the order (`7.png` and `07.png`).
    fn list(
        dir: &std::path::Path,
        reference: Option<std::path::PathBuf>,
        series: Option<&str>,
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
        let patterns = series_patterns(&files);
        let mut found: Vec<(String, usize)> = Vec::new();
        for p in &patterns {
            match found.iter_mut().find(|(q, _)| q == p) {
                Some(f) => f.1 += 1,
                None => found.push((p.clone(), 1)),
            }
        }
        found.sort();
        match series {
            Some(given) if !found.iter().any(|(p, _)| p == given) => {
                return Err(SourceError::NoSuchSeries {
                    dir: dir.to_path_buf(),
                    given: given.to_string(),
                    found,
                });
            }
            Some(given) => {
                let mut keep = patterns.iter().map(|p| p == given);
                files.retain(|_| keep.next().unwrap_or(false));
            }
            None if parallel_series(&files, &patterns, &found) => {
                return Err(SourceError::Series {
                    dir: dir.to_path_buf(),
                    found,
                });
            }
            None => {}
        }
        files.sort_by_key(|p| frame_order(p));
        if let Some(w) = files
            .windows(2)
            .find(|w| frame_order(&w[0]) == frame_order(&w[1]))
        {
            return Err(SourceError::Images(format!(
                "{} and {} name the same place in the frames' order: rename one",
                w[0].display(),
                w[1].display()
            )));
        }
        if files.is_empty() {
            return Err(SourceError::NoImages(dir.to_path_buf()));
        }
        Ok((files, reference))
    }

    /// The pixel format of the folder's frames when none is asked ([`native_format`] of its
    /// first image).
    ///
    /// # Errors
    /// As [`ImageDir::open`].
    pub fn native_format(
        dir: &std::path::Path,
        series: Option<&str>,
    ) -> Result<PixelFormat, SourceError> {
        let (files, _) = Self::list(dir, None, series)?;
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
        let (files, reference) = Self::list(dir, opts.reference.clone(), opts.series.as_deref())?;
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
                return Err(SourceError::NoReference {
                    dir: self.dir.clone(),
                    images: self.files.len(),
                    averaged: self.reference_frames,
                });
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

/// One run of a file name as the frames' order reads it: text, or a number.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
enum NamePart {
    /// A number: its digits without leading zeros, compared by count first (so by value).
    Number(usize, String),
    /// Text between numbers.
    Text(String),
}

/// Each file's series: its name with the frame number as `*`. Names of one shape (the same
/// text between their numbers) are one series but where another of their numbers differs (a
/// laser's index): the frame number is the number that takes the most values among them (the
/// last of equals). So `laser0_frame12.png` and `laser1_frame12.png` are of `laser0_frame*.png`
/// and `laser1_frame*.png`, FabScanPi's `20210213-230202_000.jpg` of `20210213-230202_*.jpg`.
fn series_patterns(files: &[std::path::PathBuf]) -> Vec<String> {
    // each name's runs of text and of digits
    let runs: Vec<Vec<(bool, String)>> = files
        .iter()
        .map(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let mut out: Vec<(bool, String)> = Vec::new();
            for c in name.chars() {
                let d = c.is_ascii_digit();
                match out.last_mut() {
                    Some((digits, run)) if *digits == d => run.push(c),
                    _ => out.push((d, c.to_string())),
                }
            }
            out
        })
        .collect();
    let shape = |r: &[(bool, String)]| -> Vec<Option<String>> {
        r.iter().map(|(d, t)| (!*d).then(|| t.clone())).collect()
    };
    // per shape, the position of its frame number
    let mut frame_at: Vec<(Vec<Option<String>>, Option<usize>)> = Vec::new();
    for r in &runs {
        let s = shape(r);
        if frame_at.iter().any(|(t, _)| *t == s) {
            continue;
        }
        let same: Vec<&Vec<(bool, String)>> = runs.iter().filter(|q| shape(q) == s).collect();
        let at = (0..r.len())
            .filter(|&i| r[i].0)
            .map(|i| {
                let mut values: Vec<&str> = same.iter().map(|q| q[i].1.as_str()).collect();
                values.sort_unstable();
                values.dedup();
                (values.len(), i)
            })
            .max()
            .map(|(_, i)| i);
        frame_at.push((s, at));
    }
    runs.iter()
        .map(|r| {
            let s = shape(r);
            let at = frame_at.iter().find(|(t, _)| *t == s).and_then(|(_, a)| *a);
            r.iter()
                .enumerate()
                .map(|(i, (_, t))| if Some(i) == at { "*" } else { t.as_str() })
                .collect()
        })
        .collect()
}

/// Whether two of a folder's series run side by side (two lasers' frames, interleaved): the
/// smaller has at least three quarters of the larger's frames, and at least half of its frame
/// numbers are also the other's. Series that do not (a few laser-off frames `a*.png` before
/// the laser's `b*.png`, a named frame before a numbered run) are one sequence in name order.
fn parallel_series(
    files: &[std::path::PathBuf],
    patterns: &[String],
    found: &[(String, usize)],
) -> bool {
    let numbers = |series: &str| -> std::collections::BTreeSet<String> {
        let Some((head, tail)) = series.split_once('*') else {
            return Default::default();
        };
        files
            .iter()
            .zip(patterns)
            .filter(|(_, p)| *p == series)
            .filter_map(|(f, _)| {
                let name = f.file_name()?.to_str()?;
                Some(name.strip_prefix(head)?.strip_suffix(tail)?.to_string())
            })
            .collect()
    };
    found.iter().enumerate().any(|(i, (a, na))| {
        found[i + 1..].iter().any(|(b, nb)| {
            let (small, large) = if na <= nb { (a, b) } else { (b, a) };
            let (n_small, n_large) = (*na.min(nb), *na.max(nb));
            if 4 * n_small < 3 * n_large {
                return false;
            }
            let (s, l) = (numbers(small), numbers(large));
            !s.is_empty() && 2 * s.intersection(&l).count() >= s.len()
        })
    })
}

/// The series of a folder and their frames, as words: `laser0_*.jpg (100 frames), …`.
pub(crate) fn series_list(found: &[(String, usize)]) -> String {
    found
        .iter()
        .map(|(p, n)| format!("{p} ({n} frame{})", if *n == 1 { "" } else { "s" }))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The frames' order of a file: its name's runs of text and of digits, the digits read as
/// numbers, so that `2.png` comes before `10.png` (a folder of `1.png … 320.png` in byte order
/// would put 10 before 2, and the turn's angles out of place).
fn frame_order(path: &std::path::Path) -> Vec<NamePart> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut parts = Vec::new();
    let mut run = String::new();
    let mut digits = false;
    let flush = |run: &mut String, digits: bool, parts: &mut Vec<NamePart>| {
        if run.is_empty() {
            return;
        }
        let r = std::mem::take(run);
        parts.push(if digits {
            let n = r.trim_start_matches('0').to_string();
            NamePart::Number(n.len(), n)
        } else {
            NamePart::Text(r)
        });
    };
    for c in name.chars() {
        if c.is_ascii_digit() != digits {
            flush(&mut run, digits, &mut parts);
            digits = c.is_ascii_digit();
        }
        run.push(c);
    }
    flush(&mut run, digits, &mut parts);
    parts
}

#[cfg(test)]
mod tests {
    use super::ImageDir;

    /// Frames `1.png … 120.png` come in the order of their numbers; two names of one number are
    /// refused, naming both.
    #[test]
    fn numbered_frames_come_in_numeric_order_and_twins_are_refused() {
        let d = tempfile::tempdir().unwrap();
        for k in (1..=120).rev() {
            std::fs::write(d.path().join(format!("{k}.png")), b"").unwrap();
        }
        std::fs::write(d.path().join("notes.txt"), b"").unwrap();
        let (files, reference) = ImageDir::list(d.path(), None, None).unwrap();
        assert!(reference.is_none());
        let names: Vec<String> = files
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        let want: Vec<String> = (1..=120).map(|k| format!("{k}.png")).collect();
        assert_eq!(names, want);
        // text around the numbers, zero-padded or not, orders the same way
        let e = tempfile::tempdir().unwrap();
        for name in ["scan_10_b.jpg", "scan_2_b.jpg", "scan_0003_b.jpg"] {
            std::fs::write(e.path().join(name), b"").unwrap();
        }
        let (files, _) = ImageDir::list(e.path(), None, None).unwrap();
        assert_eq!(
            names_of(&files),
            ["scan_2_b.jpg", "scan_0003_b.jpg", "scan_10_b.jpg"]
        );
        std::fs::write(e.path().join("scan_02_b.jpg"), b"").unwrap();
        let err = ImageDir::list(e.path(), None, None).unwrap_err();
        assert!(
            matches!(err, crate::source::SourceError::Images(_)),
            "{err}"
        );
    }

    fn names_of(files: &[std::path::PathBuf]) -> Vec<String> {
        files
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect()
    }

    /// Two lasers' frames in one folder, named either way round, are two series: refused
    /// without `--series`, naming both; with it, one series in its frames' order; a pattern
    /// the folder has not, refused naming what it has. One recording's names are one series,
    /// and so are series that do not run side by side.
    #[test]
    fn a_folder_of_two_series_is_read_one_series_at_a_time() {
        use crate::source::SourceError;
        type Name = fn(u32, u32) -> String;
        let names: [(Name, &str, &str); 2] = [
            (
                |l: u32, k: u32| format!("laser{l}_frame{k}.png"),
                "laser0_frame*.png",
                "laser1_frame*.png",
            ),
            (
                |l: u32, k: u32| format!("frame{k:03}_laser{l}.png"),
                "frame*_laser0.png",
                "frame*_laser1.png",
            ),
        ];
        for (name, first, second) in names {
            let d = tempfile::tempdir().unwrap();
            for k in 1..=12 {
                for l in 0..2 {
                    std::fs::write(d.path().join(name(l, k)), b"").unwrap();
                }
            }
            match ImageDir::list(d.path(), None, None) {
                Err(SourceError::Series { found, .. }) => {
                    assert_eq!(found, [(first.to_string(), 12), (second.to_string(), 12)])
                }
                other => panic!("{other:?}"),
            }
            let (files, _) = ImageDir::list(d.path(), None, Some(second)).unwrap();
            let want: Vec<String> = (1..=12).map(|k| name(1, k)).collect();
            assert_eq!(names_of(&files), want);
            match ImageDir::list(d.path(), None, Some("laser2_*.png")) {
                Err(SourceError::NoSuchSeries { given, found, .. }) => {
                    assert_eq!(given, "laser2_*.png");
                    assert_eq!(found.len(), 2);
                }
                other => panic!("{other:?}"),
            }
        }
        // FabScanPi's names: one series, the date and time fixed, the frame number varying
        let f = tempfile::tempdir().unwrap();
        for k in 0..=100 {
            std::fs::write(f.path().join(format!("20210213-230202_{k:03}.jpg")), b"").unwrap();
        }
        let (files, _) = ImageDir::list(f.path(), None, None).unwrap();
        assert_eq!(files.len(), 101);
        assert_eq!(
            super::series_patterns(&files)[0..1],
            ["20210213-230202_*.jpg"]
        );
        // a few laser-off frames before the laser's, a named frame before a numbered run: one
        // sequence in name order
        let g = tempfile::tempdir().unwrap();
        let names = [
            "a0.png", "a1.png", "b0.png", "b1.png", "b2.png", "b3.png", "b4.png",
        ];
        for n in names.iter().chain(&["c-cross.png"]) {
            std::fs::write(g.path().join(n), b"").unwrap();
        }
        let (files, _) = ImageDir::list(g.path(), None, None).unwrap();
        assert_eq!(files.len(), 8);
    }
}
