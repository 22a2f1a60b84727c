//! Another program's calibration read into a calibration file of ours: a turntable scanner's
//! whole calibration (FabScanPi's config, Horus's `calibration.json`: camera, laser planes,
//! platform) or a camera's alone (OpenCV's FileStorage YAML or XML, NumPy's `.npz`), each
//! checked as any calibration file is before it is used.
//!
//! A camera-only file gives the intrinsics; the laser planes and the platform then come from
//! another calibration file ([`with_camera`]) or from the scanner's own calibration frames.

mod fabscan;
mod horus;
mod npz;
mod opencv;

use std::path::Path;

use scanner_core::{Camera, Distortion};

use crate::file::{CalibrationFile, VERSION};
use crate::fixed::{FixedError, FrameTurn, unturn};
use crate::short;

/// The largest file an import reads, bytes (a calibration is a few kilobytes; an `.npz` with
/// each shot's pose a few tens).
pub const MAX_IMPORT_BYTES: u64 = 1 << 20;

/// The platform's radius Horus assumes (its machine settings' default diameter, 200 mm), mm.
pub const HORUS_RADIUS_MM: f64 = 100.0;

/// How high above the platform Horus scans by default (its machine settings' height), mm.
pub const HORUS_HEIGHT_MM: f64 = 200.0;

/// Motor steps in one turn of a Ciclop's platform (a 1.8° stepper at 1/16 microsteps; Horus
/// itself drives the motor in degrees).
pub const HORUS_STEPS_PER_TURN: u32 = 3200;

/// Why another program's calibration cannot be imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// Not readable.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Not JSON of the shape the program writes.
    #[error("{path} is not {format}")]
    Json {
        /// The file.
        path: String,
        /// What it was read as.
        format: &'static str,
        /// What is wrong.
        #[source]
        source: serde_json::Error,
    },
    /// Not of the format its name or its first bytes say (a line, a tag or a header that
    /// does not parse).
    #[error("{path}: {why}")]
    Unreadable {
        /// The file.
        path: String,
        /// What is wrong, and where.
        why: String,
    },
    /// An archive (`.npz`) that cannot be opened.
    #[error("{path} is not a NumPy .npz archive")]
    Zip {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: zip::result::ZipError,
    },
    /// A value the calibration needs is not in the file.
    #[error("{path} has no {what} (it holds: {found})")]
    Missing {
        /// The file.
        path: String,
        /// What is missing, with the names looked for.
        what: &'static str,
        /// The names the file holds.
        found: String,
    },
    /// A camera file that does not give the image size, and none given.
    #[error(
        "{path} does not say the image size its camera was calibrated at: give it (--size WIDTHxHEIGHT)"
    )]
    NoSize {
        /// The file.
        path: String,
    },
    /// A file of no format the import knows.
    #[error(
        "{path}: not a FabScanPi config, a Horus calibration.json, an OpenCV FileStorage file (.yml, .yaml, .xml) or a NumPy .npz"
    )]
    UnknownFormat {
        /// The file.
        path: String,
    },
    /// Read, but its values fail the checks of any calibration file (a NaN, a plane through the
    /// camera, 0 steps).
    #[error(transparent)]
    Checked(crate::file::FileError),
    /// Readable, but its frames' turn or a flag is unusable.
    #[error("{path}: {reason}")]
    Unusable {
        /// The file.
        path: String,
        /// What is wrong.
        reason: FixedError,
    },
    /// Readable, but a value is unusable.
    #[error("{path}: {why}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
}

/// The file formats an import reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// FabScanPi's `<name>.config.json`: camera, laser planes, platform, the frames' turn.
    FabScanPi,
    /// Horus's `calibration.json` (Ciclop): camera, the left and right laser planes, platform.
    Horus,
    /// OpenCV's FileStorage YAML (`cv::FileStorage`, `%YAML:1.0`): a camera.
    OpenCvYaml,
    /// OpenCV's FileStorage XML (`<opencv_storage>`): a camera.
    OpenCvXml,
    /// NumPy's `.npz` (`np.savez`): a camera.
    NumPy,
}

impl Format {
    /// Its name for people and reports.
    pub const fn name(self) -> &'static str {
        match self {
            Format::FabScanPi => "FabScanPi config",
            Format::Horus => "Horus calibration",
            Format::OpenCvYaml => "OpenCV YAML",
            Format::OpenCvXml => "OpenCV XML",
            Format::NumPy => "NumPy .npz",
        }
    }
}

/// What the file does not say and an import may need: the image size of a camera file, the
/// platform's radius, height and steps of a Horus calibration (kept by Horus in its machine
/// settings, not in the calibration), and the way its platform turns.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImportOptions {
    /// The image size the camera was calibrated at (a camera file without `image_width` and
    /// `image_height`, or to check one with them).
    pub size: Option<(u32, u32)>,
    /// The platform's radius, mm (Horus: default [`HORUS_RADIUS_MM`]).
    pub radius: Option<f64>,
    /// How high above the platform's top the scanner sees objects, mm (Horus: default
    /// [`HORUS_HEIGHT_MM`]).
    pub height: Option<f64>,
    /// Motor steps in one turn (Horus: default [`HORUS_STEPS_PER_TURN`]).
    pub steps_per_turn: Option<u32>,
    /// Whether the platform turns clockwise seen from above (default: the way the program turns
    /// its points back).
    pub clockwise: Option<bool>,
}

/// What an import gives: the calibration for the stored frames and how they are turned.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The format read.
    pub format: Format,
    /// The calibration, stored frames' coordinates (checked as any calibration file).
    pub file: CalibrationFile,
    /// How the scanner turned its frames (what the import undid).
    pub turn: FrameTurn,
}

/// Reads another program's calibration, its format told by its name and its first bytes.
///
/// # Errors
/// [`ImportError`] naming the file and what is wrong with it.
pub fn import(path: &Path, opts: &ImportOptions) -> Result<Imported, ImportError> {
    let name = path.display().to_string();
    let bytes = read(path)?;
    match format_of(path, &bytes) {
        Some(Format::NumPy) => npz::import(&name, &bytes, opts),
        Some(Format::OpenCvYaml) => opencv::import(&name, &text(&name, &bytes)?, false, opts),
        Some(Format::OpenCvXml) => opencv::import(&name, &text(&name, &bytes)?, true, opts),
        Some(Format::Horus) => horus::import(&name, &text(&name, &bytes)?, opts),
        Some(Format::FabScanPi) => fabscan::import(&name, &text(&name, &bytes)?),
        None => Err(ImportError::UnknownFormat { path: name }),
    }
}

/// Reads a FabScanPi config (`<name>.config.json`): its camera, laser planes and platform, for
/// the frames as the camera stores them.
///
/// # Errors
/// [`ImportError`] naming the file and the value that is wrong (a NaN or a plane through the
/// camera, a step count of 0 included).
pub fn import_fabscan(path: &Path) -> Result<Imported, ImportError> {
    let name = path.display().to_string();
    let bytes = read(path)?;
    fabscan::import(&name, &text(&name, &bytes)?)
}

/// `file` with the camera of `camera` (an imported camera file): the laser planes, the platform
/// and the board kept. The two must be for one image size.
///
/// # Errors
/// [`ImportError::Invalid`] when the sizes differ.
pub fn with_camera(
    file: &CalibrationFile,
    camera: &Imported,
    path: &str,
) -> Result<CalibrationFile, ImportError> {
    let (a, b) = (&file.image, &camera.file.image);
    if (a.width, a.height) != (b.width, b.height) {
        return Err(ImportError::Invalid {
            path: path.to_string(),
            why: format!(
                "the camera is for {}×{} frames, the calibration it goes into for {}×{}",
                b.width, b.height, a.width, a.height
            ),
        });
    }
    let mut out = file.clone();
    out.camera = camera.file.camera.clone();
    Ok(out)
}

/// The file's bytes, its size checked first.
fn read(path: &Path) -> Result<Vec<u8>, ImportError> {
    let io = |source| ImportError::Io {
        path: path.display().to_string(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if meta.is_dir() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "it is a folder, not a file",
        )));
    }
    if meta.len() > MAX_IMPORT_BYTES {
        return Err(ImportError::Unreadable {
            path: path.display().to_string(),
            why: format!(
                "{} bytes, more than the {MAX_IMPORT_BYTES} a calibration file may have",
                meta.len()
            ),
        });
    }
    std::fs::read(path).map_err(io)
}

fn text(path: &str, bytes: &[u8]) -> Result<String, ImportError> {
    String::from_utf8(bytes.to_vec()).map_err(|e| ImportError::Unreadable {
        path: path.to_string(),
        why: format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
    })
}

/// The format of a file: a zip archive is NumPy's `.npz`; `%YAML` or a `.yml`/`.yaml` name
/// OpenCV's YAML; `<?xml` or `<opencv_storage>` its XML; JSON with `calibration_settings`
/// Horus's, with `calibration` and `turntable` FabScanPi's.
fn format_of(path: &Path, bytes: &[u8]) -> Option<Format> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(b"PK\x05\x06") || ext == "npz" {
        return Some(Format::NumPy);
    }
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(256)]);
    let head = head.trim_start_matches('\u{feff}').trim_start();
    if head.starts_with("%YAML") || ext == "yml" || ext == "yaml" {
        return Some(Format::OpenCvYaml);
    }
    if head.starts_with("<?xml") || head.starts_with("<opencv_storage") || ext == "xml" {
        return Some(Format::OpenCvXml);
    }
    if head.starts_with('{') {
        let v: serde_json::Value = serde_json::from_slice(bytes).ok()?;
        if v.get("calibration_settings").is_some() {
            return Some(Format::Horus);
        }
        if v.get("calibration").is_some() {
            return Some(Format::FabScanPi);
        }
    }
    None
}

/// A pinhole camera from a 3×3 camera matrix and OpenCV's distortion coefficients
/// (`k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [τx τy]]]]`): the model has `k1 k2 p1 p2 k3`, so
/// any further coefficient must be 0.
fn camera(path: &str, k: [[f64; 3]; 3], d: &[f64]) -> Result<Camera<f64>, ImportError> {
    let invalid = |why: String| ImportError::Invalid {
        path: path.to_string(),
        why,
    };
    if k[0][1] != 0.0 || k[1][0] != 0.0 || k[2] != [0.0, 0.0, 1.0] {
        return Err(invalid(format!(
            "the camera matrix {k:?} is not a pinhole camera's (skew or a bad last row)"
        )));
    }
    if ![4, 5, 8, 12, 14].contains(&d.len()) {
        return Err(invalid(format!(
            "{} distortion coefficients: OpenCV's models have 4, 5, 8, 12 or 14",
            d.len()
        )));
    }
    if let Some((i, v)) = d.iter().enumerate().skip(5).find(|(_, v)| **v != 0.0) {
        return Err(invalid(format!(
            "distortion coefficient {i} is {} (a rational, thin-prism or tilted model): only k1, k2, p1, p2 and k3 are modelled",
            short(*v)
        )));
    }
    Camera::new(
        k[0][0],
        k[1][1],
        k[0][2],
        k[1][2],
        Distortion {
            k1: d[0],
            k2: d[1],
            p1: d[2],
            p2: d[3],
            k3: d.get(4).copied().unwrap_or(0.0),
        },
    )
    .map_err(|e| invalid(format!("the camera matrix: {e}")))
}

/// A calibration made in the program's turned frames, turned back to the stored frames and
/// checked as any calibration file.
fn finish(
    path: &str,
    format: Format,
    turned: &CalibrationFile,
    turn: FrameTurn,
    stored: (u32, u32),
) -> Result<Imported, ImportError> {
    let file = unturn(turned, turn, stored).map_err(|reason| ImportError::Unusable {
        path: path.to_string(),
        reason,
    })?;
    checked(path, format, &file, turn)
}

/// A calibration checked as any calibration file is when read.
fn checked(
    path: &str,
    format: Format,
    file: &CalibrationFile,
    turn: FrameTurn,
) -> Result<Imported, ImportError> {
    let text = toml::to_string(file).map_err(|e| ImportError::Invalid {
        path: path.to_string(),
        why: format!("cannot be written: {e}"),
    })?;
    let file = CalibrationFile::parse(&text, path).map_err(ImportError::Checked)?;
    debug_assert_eq!(file.version, VERSION);
    Ok(Imported { format, file, turn })
}

/// A camera file's calibration: the camera alone, for `size` (the file's own, or the one
/// given; both must agree).
fn camera_only(
    path: &str,
    format: Format,
    camera: &Camera<f64>,
    found: Option<(u32, u32)>,
    opts: &ImportOptions,
) -> Result<Imported, ImportError> {
    let size = match (found, opts.size) {
        (Some(f), Some(g)) if f != g => {
            return Err(ImportError::Invalid {
                path: path.to_string(),
                why: format!("the file says {}×{}, --size {}×{}", f.0, f.1, g.0, g.1),
            });
        }
        (Some(s), _) | (None, Some(s)) => s,
        (None, None) => {
            return Err(ImportError::NoSize {
                path: path.to_string(),
            });
        }
    };
    let file =
        CalibrationFile::from_camera(camera, size, format!("{} {path}", format.name()), None);
    checked(path, format, &file, FrameTurn::default())
}

/// The names a file holds, for an error: at most 12, in its order.
fn names<'a>(all: impl Iterator<Item = &'a str>) -> String {
    let all: Vec<&str> = all.collect();
    let mut out = all.iter().take(12).copied().collect::<Vec<_>>().join(", ");
    if all.len() > 12 {
        out.push_str(&format!(" and {} more", all.len() - 12));
    }
    if out.is_empty() {
        out.push_str("nothing");
    }
    out
}

/// The first of `keys` that `has` holds.
fn first_of<'a>(keys: &[&'a str], has: impl Fn(&str) -> bool) -> Option<&'a str> {
    keys.iter().copied().find(|k| has(k))
}

/// The names a camera matrix goes by in OpenCV's samples and NumPy scripts.
const CAMERA_KEYS: [&str; 9] = [
    "camera_matrix",
    "cameraMatrix",
    "Camera_Matrix",
    "mtx",
    "K",
    "M",
    "intrinsic",
    "intrinsics",
    "intrinsic_matrix",
];

/// The names distortion coefficients go by.
const DISTORTION_KEYS: [&str; 9] = [
    "distortion_coefficients",
    "dist_coeffs",
    "distCoeffs",
    "Distortion_Coefficients",
    "distortion_coeffs",
    "distortion",
    "dist",
    "D",
    "d",
];

/// Both of the camera's arrays of a camera file: the matrix (3×3) and the distortion (a row
/// or a column), each looked up under its usual names.
fn camera_arrays<'a>(
    path: &str,
    keys: impl Iterator<Item = &'a str> + Clone,
    get: impl Fn(&str) -> Option<(usize, usize, Vec<f64>)>,
) -> Result<([[f64; 3]; 3], Vec<f64>), ImportError> {
    let has = |k: &str| keys.clone().any(|n| n == k);
    let missing = |what| ImportError::Missing {
        path: path.to_string(),
        what,
        found: names(keys.clone()),
    };
    let kname = first_of(&CAMERA_KEYS, has)
        .ok_or_else(|| missing("camera matrix (camera_matrix, cameraMatrix, mtx or K)"))?;
    let dname = first_of(&DISTORTION_KEYS, has).ok_or_else(|| {
        missing(
            "distortion coefficients (distortion_coefficients, dist_coeffs, distCoeffs or dist)",
        )
    })?;
    let invalid = |why: String| ImportError::Invalid {
        path: path.to_string(),
        why,
    };
    let (rows, cols, m) = get(kname).ok_or_else(|| invalid(format!("{kname} is not a matrix")))?;
    if (rows, cols) != (3, 3) || m.len() != 9 {
        return Err(invalid(format!(
            "{kname} is {rows}×{cols}, a camera matrix is 3×3"
        )));
    }
    let (rows, cols, d) = get(dname).ok_or_else(|| invalid(format!("{dname} is not a matrix")))?;
    if rows != 1 && cols != 1 {
        return Err(invalid(format!(
            "{dname} is {rows}×{cols}, distortion coefficients are a row or a column"
        )));
    }
    if let Some(bad) = m.iter().chain(&d).find(|v| !v.is_finite()) {
        return Err(invalid(format!("a value of {kname} or {dname} is {bad}")));
    }
    Ok((
        [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
        d,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_are_told_by_their_first_bytes_and_names() {
        let p = |n: &str| std::path::PathBuf::from(n);
        assert_eq!(
            format_of(&p("a.bin"), b"PK\x03\x04rest"),
            Some(Format::NumPy)
        );
        assert_eq!(
            format_of(&p("cam.txt"), b"%YAML:1.0\n---\n"),
            Some(Format::OpenCvYaml)
        );
        assert_eq!(
            format_of(&p("cam.yml"), b"K: 1\n"),
            Some(Format::OpenCvYaml)
        );
        assert_eq!(
            format_of(&p("cam"), b"<?xml version=\"1.0\"?>\n<opencv_storage>"),
            Some(Format::OpenCvXml)
        );
        assert_eq!(
            format_of(&p("c.json"), br#"{"calibration_settings": {}}"#),
            Some(Format::Horus)
        );
        assert_eq!(
            format_of(&p("c.json"), br#"{"calibration": {}, "turntable": {}}"#),
            Some(Format::FabScanPi)
        );
        assert_eq!(format_of(&p("c.json"), br#"{"other": 1}"#), None);
        assert_eq!(format_of(&p("c.txt"), b"hello"), None);
    }

    #[test]
    fn extra_distortion_terms_must_be_zero() {
        let k = [[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]];
        assert!(camera("f", k, &[0.1, 0.0, 0.0, 0.0]).is_ok());
        assert!(camera("f", k, &[0.1, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0]).is_ok());
        let e = camera("f", k, &[0.1, 0.0, 0.0, 0.0, 0.01, 0.2, 0.0, 0.0]).unwrap_err();
        assert!(matches!(e, ImportError::Invalid { .. }), "{e:?}");
        let e = camera("f", k, &[0.1, 0.0, 0.0]).unwrap_err();
        assert!(matches!(e, ImportError::Invalid { .. }), "{e:?}");
        let skew = [[500.0, 2.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]];
        assert!(matches!(
            camera("f", skew, &[0.0; 5]),
            Err(ImportError::Invalid { .. })
        ));
    }
}
