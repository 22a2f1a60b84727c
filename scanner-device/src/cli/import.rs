//! `import` and `import-fabscan`: another program's calibration into a calibration file.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use scanner_calib::import::{Format, ImportOptions, Imported};

/// `scanner-device import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The file: a FabScanPi config (`*.config.json`) or a Horus `calibration.json` (camera,
    /// laser planes, platform), or a camera alone: OpenCV FileStorage (`.yml`, `.yaml`, `.xml`)
    /// or NumPy (`.npz`, from `np.savez`)
    pub file: PathBuf,
    /// The calibration file to write.
    #[arg(long, default_value = "calibration.toml")]
    pub out: PathBuf,
    /// A camera file's image size, `WIDTHxHEIGHT` (an .npz holds none; a FileStorage file
    /// usually says it)
    #[arg(long, value_parser = size)]
    pub size: Option<(u32, u32)>,
    /// Put the imported camera into this calibration file, its laser planes, platform and board
    /// kept (a camera file gives the camera alone)
    #[arg(long)]
    pub into: Option<PathBuf>,
    /// Horus: the platform's radius, mm (Horus keeps it in its machine settings)
    /// [default: 100]
    #[arg(long)]
    pub radius: Option<f64>,
    /// Horus: how high above the platform objects are scanned, mm [default: 200]
    #[arg(long)]
    pub height: Option<f64>,
    /// Horus: the motor's steps in one turn [default: 3200, a Ciclop's]
    #[arg(long)]
    pub steps_per_turn: Option<u32>,
    /// Horus: whether the platform turns clockwise seen from above [default: false, the way
    /// Horus turns its points back]
    #[arg(long)]
    pub clockwise: Option<bool>,
}

fn size(s: &str) -> Result<(u32, u32), crate::source::SizeError> {
    crate::source::parse_size(s)
}

/// Runs `import`.
///
/// # Errors
/// The file cannot be imported or written.
pub fn import(a: &ImportArgs) -> anyhow::Result<()> {
    let opts = ImportOptions {
        size: a.size,
        radius: a.radius,
        height: a.height,
        steps_per_turn: a.steps_per_turn,
        clockwise: a.clockwise,
    };
    let imported = scanner_calib::import::import(&a.file, &opts)?;
    let file = match &a.into {
        None => imported.file.clone(),
        Some(into) => {
            let base = scanner_calib::file::CalibrationFile::load(into).with_context(|| {
                format!("the calibration to put the camera into, {}", into.display())
            })?;
            scanner_calib::import::with_camera(&base, &imported, &a.file.display().to_string())?
        }
    };
    write(&file, &imported, &a.out)
}

/// Runs `import-fabscan`.
///
/// # Errors
/// The config cannot be imported or written.
pub fn import_fabscan(config: &Path, out: &Path) -> anyhow::Result<()> {
    let imported = scanner_calib::import::import_fabscan(config)?;
    write(&imported.file, &imported, out)
}

/// Writes the calibration and says what went in.
fn write(
    file: &scanner_calib::file::CalibrationFile,
    imported: &Imported,
    out: &Path,
) -> anyhow::Result<()> {
    file.save(out)?;
    let o = imported.turn;
    let turned = match imported.format {
        Format::FabScanPi | Format::Horus => format!(
            " (the program turned them: rotate {}, hflip {}, vflip {})",
            o.rotate, o.hflip, o.vflip
        ),
        Format::OpenCvYaml | Format::OpenCvXml | Format::NumPy => String::new(),
    };
    crate::outln!(
        "wrote {} from a {}: {}×{} stored frames{turned}, camera fx {:.2} fy {:.2} px, {} laser plane(s), platform {}",
        out.display(),
        imported.format.name(),
        file.image.width,
        file.image.height,
        file.camera.fx,
        file.camera.fy,
        file.lasers.len(),
        if file.platform.is_some() { "yes" } else { "no" }
    );
    Ok(())
}
