//! FabScanPi's config (`<name>.config.json`): its camera, laser planes, platform and the turn of
//! its frames (`camera.rotate`, `hflip`, `vflip`).

use scanner_core::geometry::Plane;
use scanner_core::nalgebra::Vector3;

use super::{Format, ImportError, Imported};
use crate::file::{CalibrationFile, PlaneEq, PlatformSection};
use crate::fixed::{FixedError, FrameTurn};
use crate::short;

/// The parts of FabScanPi's config the import reads.
#[derive(Debug, serde::Deserialize)]
struct FabScanConfig {
    calibration: FabScanCalibration,
    camera: FabScanCamera,
    turntable: FabScanTurntable,
}

#[derive(Debug, serde::Deserialize)]
struct FabScanCalibration {
    camera_matrix: [[f64; 3]; 3],
    distortion_vector: [f64; 5],
    #[serde(default)]
    laser_planes: Vec<FabScanPlane>,
    platform_translation: [f64; 3],
    platform_rotation: [[f64; 3]; 3],
}

#[derive(Debug, serde::Deserialize)]
struct FabScanPlane {
    distance: f64,
    normal: [f64; 3],
}

#[derive(Debug, serde::Deserialize)]
struct FabScanCamera {
    resolution: FabScanResolution,
    #[serde(default)]
    rotate: Flag,
    #[serde(default)]
    hflip: Flag,
    #[serde(default)]
    vflip: Flag,
}

#[derive(Debug, serde::Deserialize)]
struct FabScanResolution {
    width: u32,
    height: u32,
}

#[derive(Debug, serde::Deserialize)]
struct FabScanTurntable {
    steps: u32,
    #[serde(default)]
    radius: f64,
    #[serde(default)]
    height: f64,
}

/// FabScanPi's booleans are the strings "True" and "False" (or JSON booleans).
#[derive(Debug, Default, serde::Deserialize)]
#[serde(untagged)]
enum Flag {
    Bool(bool),
    Text(String),
    #[default]
    Missing,
}

impl Flag {
    fn get(&self, name: &'static str) -> Result<bool, FixedError> {
        match self {
            Flag::Bool(b) => Ok(*b),
            Flag::Text(t) if t.eq_ignore_ascii_case("true") => Ok(true),
            Flag::Text(t) if t.eq_ignore_ascii_case("false") => Ok(false),
            Flag::Text(t) => Err(FixedError::Flag {
                name,
                value: t.chars().take(40).collect(),
            }),
            Flag::Missing => Ok(false),
        }
    }
}

/// A FabScanPi config's text (`<name>.config.json` at `name`): its camera, laser planes and
/// platform, for the frames as the camera stores them.
pub(super) fn import(name: &str, text: &str) -> Result<Imported, ImportError> {
    let cfg: FabScanConfig = serde_json::from_str(text).map_err(|source| ImportError::Json {
        path: name.to_string(),
        format: "a FabScanPi config",
        source,
    })?;
    let invalid = |why: String| ImportError::Invalid {
        path: name.to_string(),
        why,
    };
    let unusable = |reason: FixedError| ImportError::Unusable {
        path: name.to_string(),
        reason,
    };
    let orientation = FrameTurn {
        rotate: cfg.camera.rotate.get("rotate").map_err(unusable)?,
        hflip: cfg.camera.hflip.get("hflip").map_err(unusable)?,
        vflip: cfg.camera.vflip.get("vflip").map_err(unusable)?,
    };
    let stored = (cfg.camera.resolution.width, cfg.camera.resolution.height);
    let (_, _, turned_size) = orientation.map(stored);
    let camera = super::camera(
        name,
        cfg.calibration.camera_matrix,
        &cfg.calibration.distortion_vector,
    )?;
    let mut turned = CalibrationFile::from_camera(
        &camera,
        turned_size,
        format!("FabScanPi config {name}"),
        None,
    );
    for (i, l) in cfg.calibration.laser_planes.iter().enumerate() {
        // FabScanPi: normal · X = distance
        let plane = Plane::new(Vector3::from(l.normal), -l.distance).map_err(|e| {
            invalid(format!(
                "calibration.laser_planes[{i}]: {e} (normal {:?}, distance {})",
                l.normal,
                short(l.distance)
            ))
        })?;
        turned.lasers.push(PlaneEq {
            normal: (*plane.normal()).into(),
            offset: plane.offset(),
        });
    }
    turned.platform = Some(PlatformSection {
        rotation: cfg.calibration.platform_rotation,
        origin: cfg.calibration.platform_translation,
        radius: cfg.turntable.radius,
        steps_per_turn: cfg.turntable.steps,
        // FabScanPi undoes a frame's turn by turning its points +angle about its z: the
        // platform turns the other way
        clockwise: true,
        height: cfg.turntable.height,
    });
    super::finish(name, Format::FabScanPi, &turned, orientation, stored)
}
