//! Horus's `calibration.json` (the Ciclop's software: its "calibration_settings" saved as a
//! profile, every setting an object with its `value`): the camera matrix and distortion of the
//! turned frames, the left and right laser planes (`normal · X = distance`, camera
//! coordinates, mm) and the platform's pose (`rotation_matrix` R and `translation_vector` t:
//! a platform point `Xp` is `R Xp + t` in the camera). Horus turns each frame as it reads it —
//! transposed (`camera_rotate`), then flipped left–right (`camera_hflip`) and top–bottom
//! (`camera_vflip`) — and `camera_width` × `camera_height` is the size the camera sends.
//! Settings a saved file leaves out keep Horus's defaults (rotate and hflip on, vflip off).
//! The platform's size is in Horus's machine settings, not here: it is given or assumed.

use serde::Deserialize;

use scanner_core::geometry::Plane;
use scanner_core::nalgebra::Vector3;

use super::{
    Format, HORUS_HEIGHT_MM, HORUS_RADIUS_MM, HORUS_STEPS_PER_TURN, ImportError, ImportOptions,
    Imported,
};
use crate::file::{CalibrationFile, PlaneEq, PlatformSection};
use crate::fixed::FrameTurn;
use crate::short;

/// A Horus setting: its value (and limits, not read).
#[derive(Debug, Deserialize)]
struct Setting<T> {
    value: T,
}

#[derive(Debug, Deserialize)]
struct HorusFile {
    calibration_settings: Settings,
}

#[derive(Debug, Deserialize)]
struct Settings {
    camera_width: Setting<u32>,
    camera_height: Setting<u32>,
    camera_rotate: Option<Setting<bool>>,
    camera_hflip: Option<Setting<bool>>,
    camera_vflip: Option<Setting<bool>>,
    camera_matrix: Setting<[[f64; 3]; 3]>,
    distortion_vector: Setting<Vec<f64>>,
    distance_left: Option<Setting<f64>>,
    normal_left: Option<Setting<[f64; 3]>>,
    distance_right: Option<Setting<f64>>,
    normal_right: Option<Setting<[f64; 3]>>,
    rotation_matrix: Option<Setting<[[f64; 3]; 3]>>,
    translation_vector: Option<Setting<[f64; 3]>>,
}

/// A Horus `calibration.json`'s text: its camera, laser planes (left: laser 0, right: laser 1)
/// and platform, for the frames as the camera sends them.
pub(super) fn import(
    name: &str,
    text: &str,
    opts: &ImportOptions,
) -> Result<Imported, ImportError> {
    let file: HorusFile = serde_json::from_str(text).map_err(|source| ImportError::Json {
        path: name.to_string(),
        format: "a Horus calibration",
        source,
    })?;
    let s = file.calibration_settings;
    let invalid = |why: String| ImportError::Invalid {
        path: name.to_string(),
        why,
    };
    let flag = |f: &Option<Setting<bool>>, default: bool| f.as_ref().map_or(default, |f| f.value);
    let turn = FrameTurn {
        rotate: flag(&s.camera_rotate, true),
        hflip: flag(&s.camera_hflip, true),
        vflip: flag(&s.camera_vflip, false),
    };
    let stored = (s.camera_width.value, s.camera_height.value);
    let (_, _, turned_size) = turn.map(stored);
    let camera = super::camera(name, s.camera_matrix.value, &s.distortion_vector.value)?;
    let mut turned = CalibrationFile::from_camera(
        &camera,
        turned_size,
        format!("Horus calibration {name}"),
        None,
    );
    // Horus leaves a plane it has not calibrated at 0: both or neither (a scan names its
    // laser by its place in the list)
    let plane = |side: &str, n: &Option<Setting<[f64; 3]>>, d: &Option<Setting<f64>>| {
        let (n, d) = (n.as_ref().map(|n| n.value), d.as_ref().map(|d| d.value));
        match (n, d) {
            (Some(n), Some(d)) if n != [0.0; 3] => {
                Plane::new(Vector3::from(n), -d).map(Some).map_err(|e| {
                    invalid(format!(
                        "the {side} laser's plane: {e} (normal_{side} {n:?}, distance_{side} {})",
                        short(d)
                    ))
                })
            }
            _ => Ok(None),
        }
    };
    let left = plane("left", &s.normal_left, &s.distance_left)?;
    let right = plane("right", &s.normal_right, &s.distance_right)?;
    match (left, right) {
        (Some(l), Some(r)) => {
            for p in [l, r] {
                turned.lasers.push(PlaneEq {
                    normal: (*p.normal()).into(),
                    offset: p.offset(),
                });
            }
        }
        (None, None) => {}
        (Some(_), None) | (None, Some(_)) => {
            return Err(invalid(
                "one laser's plane is calibrated and the other's is not (0): calibrate both in Horus, as a scan names a laser by its place (left 0, right 1)".into(),
            ));
        }
    }
    let r = s.rotation_matrix.map(|r| r.value);
    let t = s.translation_vector.map(|t| t.value);
    if let (Some(r), Some(t)) = (r, t)
        && r != [[0.0; 3]; 3]
    {
        turned.platform = Some(PlatformSection {
            rotation: r,
            origin: t,
            radius: opts.radius.unwrap_or(HORUS_RADIUS_MM),
            steps_per_turn: opts.steps_per_turn.unwrap_or(HORUS_STEPS_PER_TURN),
            // Horus turns a frame's points back by −θ about the platform's z
            // (point_cloud_generation.py): the platform turns +θ, counter-clockwise
            clockwise: opts.clockwise.unwrap_or(false),
            height: opts.height.unwrap_or(HORUS_HEIGHT_MM),
        });
    }
    super::finish(name, Format::Horus, &turned, turn, stored)
}
