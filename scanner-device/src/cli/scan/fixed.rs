//! A fixed-laser scan's plan: the laser and its platform from the calibration file, the turn
//! per frame, the motor that turns the platform.

use anyhow::{Context, Result};
use scanner_core::pipeline::HeadConfig;

use crate::source::FrameSource;

use scanner_calib::file::CalibrationFile;
use scanner_core::stripe::Method;

use super::{FirmwareArg, ScanArgs, ScanRefusal};

/// The source's frames on a platform the motor board at `spec` turns.
pub(super) fn turning(
    a: &ScanArgs,
    spec: &str,
    source: Box<dyn FrameSource>,
) -> Result<Box<dyn FrameSource>> {
    let (Some(laser), Some(steps), Some(cal)) = (a.fixed_laser, a.steps_per_frame, &a.calibration)
    else {
        return Err(ScanRefusal::MotorWithoutFixedLaser.into());
    };
    let file = CalibrationFile::load(cal)?;
    let Some(platform) = file.platform else {
        return Err(ScanRefusal::NoPlatform {
            option: "--motor",
            path: cal.to_path_buf(),
        }
        .into());
    };
    let serial = scanner_io::link_spec::SerialSpec::parse(spec)
        .map_err(|e| anyhow::anyhow!("--motor {spec:?}: {e}"))?
        .ok_or_else(|| anyhow::anyhow!("--motor {spec:?}: give serial:PATH[@BAUD]"))?;
    let port = serialport::new(serial.path, serial.baud)
        .timeout(std::time::Duration::from_millis(20))
        .open()
        .with_context(|| format!("--motor: opening {}", serial.path))?;
    let firmware = match a.firmware {
        FirmwareArg::Fabscan => crate::motor::Firmware::FabScan,
        FirmwareArg::Horus => crate::motor::Firmware::Horus,
    };
    let controller = crate::motor::Controller::connect(
        port,
        firmware,
        platform.steps_per_turn,
        std::time::Duration::from_millis(a.motor_timeout_ms),
    )
    .with_context(|| format!("--motor {spec}"))?;
    // one turn and the frame that closes it, unless --frames says otherwise
    let per_turn = platform.steps_per_turn.div_ceil(steps.max(1));
    let frames = a.frames.unwrap_or(per_turn + 1);
    Ok(Box::new(crate::motor::Turning::new(
        source,
        controller,
        u8::try_from(laser).unwrap_or(u8::MAX),
        i64::from(steps),
        frames,
    )))
}

/// A fixed laser read from a calibration file: its plane, its platform's known surfaces (what
/// is not the object) and the message that tells the host the platform and the turn.
pub(super) struct Fixed {
    pub(super) plane: scanner_core::geometry::Plane<f64>,
    pub(super) board: scanner_core::geometry::Board<f64>,
    pub(super) message: scanner_wire::FixedLaser,
    /// The part of the picture where the platform's cylinder shows (its radius and the
    /// scanner's height), when both are known.
    pub(super) roi: Option<scanner_core::stripe::Roi>,
    /// The markers on the platform each frame's turn is measured by (`--markers`).
    pub(super) markers: Option<crate::marker_turn::MarkerPlatform>,
}

/// The platform's radius taken when the calibration does not know it, mm.
pub(super) const UNKNOWN_RADIUS_MM: f64 = 1000.0;

/// Laser `n` of the calibration file at `path` over its platform, with the turn per frame
/// the options give.
pub(super) fn read_fixed(path: &std::path::Path, n: usize, a: &ScanArgs) -> Result<Fixed> {
    let file = CalibrationFile::load(path)?;
    let name = path.display();
    let Some(laser) = file.lasers.get(n) else {
        return Err(ScanRefusal::NoSuchLaser {
            index: n,
            path: path.to_path_buf(),
            lasers: file.lasers.len(),
        }
        .into());
    };
    let Some(section) = file.platform else {
        return Err(ScanRefusal::NoPlatform {
            option: "--fixed-laser",
            path: path.to_path_buf(),
        }
        .into());
    };
    let plane = laser
        .plane()
        .with_context(|| format!("[[laser]] {n} in {name}"))?;
    let platform = section
        .platform()
        .with_context(|| format!("[platform] in {name}"))?;
    let radius = if section.radius > 0.0 {
        section.radius
    } else {
        UNKNOWN_RADIUS_MM
    };
    let board = platform
        .known_surfaces(radius)
        .with_context(|| format!("[platform] in {name}: the camera looks down its axis"))?;
    // the calibration's direction for the motor's steps and a count of frames
    let sense = if section.clockwise { -1.0 } else { 1.0 };
    let turn = match (a.turn_deg, a.steps_per_frame, a.frames_per_turn) {
        (Some(d), _, _) if d.is_finite() && d != 0.0 && d.abs() <= 180.0 => d.to_radians(),
        (Some(d), _, _) => {
            return Err(ScanRefusal::TurnDeg(d).into());
        }
        (_, Some(0), _) => return Err(ScanRefusal::NoSteps.into()),
        (_, Some(s), _) if s <= section.steps_per_turn / 2 => {
            sense * std::f64::consts::TAU * f64::from(s) / f64::from(section.steps_per_turn)
        }
        (_, Some(s), _) => {
            return Err(ScanRefusal::StepsOverHalf {
                steps: s,
                per_turn: section.steps_per_turn,
            }
            .into());
        }
        (_, _, Some(f)) if f >= 2 => sense * std::f64::consts::TAU / f64::from(f),
        (_, _, Some(f)) => return Err(ScanRefusal::FramesPerTurn(f).into()),
        // each frame's turn comes measured by the markers
        _ if a.markers.is_some() => 0.0,
        _ => return Err(ScanRefusal::NoTurn.into()),
    };
    let markers = a
        .markers
        .as_ref()
        .map(|name| {
            scanner_calib::aruco::Dictionary::named(name)
                .map(|dictionary| crate::marker_turn::MarkerPlatform {
                    dictionary,
                    platform,
                })
                .ok_or_else(|| ScanRefusal::UnknownDictionary(name.clone()))
        })
        .transpose()?;
    let r = platform.rotation();
    let o = platform.origin();
    let camera = file.camera().with_context(|| format!("camera in {name}"))?;
    let roi = (section.radius > 0.0 && section.height > 0.0).then(|| {
        platform_roi(
            &camera,
            &platform,
            (section.radius, section.height),
            (file.image.width, file.image.height),
        )
    });
    Ok(Fixed {
        markers,
        roi: roi.flatten(),
        plane,
        board,
        message: scanner_wire::FixedLaser {
            scan_id: 0,
            laser: u8::try_from(n).unwrap_or(u8::MAX),
            // row-major
            rotation: std::array::from_fn(|k| r[(k / 3, k % 3)] as f32),
            origin: [o.x as f32, o.y as f32, o.z as f32],
            turn: turn as f32,
            radius: section.radius as f32,
        },
    })
}

/// The smallest rectangle of the picture that holds the cylinder of `radius` and `height` on
/// the platform (its circles at the top and bottom, 32 points each, projected), with a margin of
/// 8 px; `None` when a point does not project (behind the camera) or nothing is left.
pub(super) fn platform_roi(
    camera: &scanner_core::Camera<f64>,
    platform: &scanner_core::geometry::Platform<f64>,
    (radius, height): (f64, f64),
    (w, h): (u32, u32),
) -> Option<scanner_core::stripe::Roi> {
    use scanner_core::nalgebra::Vector3;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for k in 0..32 {
        let a = std::f64::consts::TAU * f64::from(k) / 32.0;
        for z in [0.0, height] {
            let local = Vector3::new(radius * a.cos(), radius * a.sin(), z);
            let p = platform.origin() + platform.rotation() * local;
            let px = camera.project(&p).ok()?;
            lo = [lo[0].min(px.x), lo[1].min(px.y)];
            hi = [hi[0].max(px.x), hi[1].max(px.y)];
        }
    }
    let clamp = |v: f64, n: u32| (v.max(0.0) as usize).min(n as usize);
    let (x0, y0) = (clamp(lo[0] - 8.0, w), clamp(lo[1] - 8.0, h));
    let (x1, y1) = (clamp(hi[0] + 9.0, w), clamp(hi[1] + 9.0, h));
    (x1 > x0 + 1 && y1 > y0 + 1).then_some(scanner_core::stripe::Roi {
        x: x0,
        y: y0,
        width: x1 - x0,
        height: y1 - y0,
    })
}

/// The pipeline's settings for a fixed laser: its plane; the light-intensity method (the frames
/// are dark: nothing to subtract); stripes up to 64 px wide with a halo around them (a laser
/// close to a plaster or skin-like surface glows); the platform's top within 1 mm is the
/// platform.
pub(super) fn fixed_head(mut head: HeadConfig, f: &Fixed) -> HeadConfig {
    head.fixed_plane = Some(scanner_core::pipeline::FixedPlane {
        plane: f.plane.cast(),
        sigma: 0.05,
    });
    head.stripe.method = Method::Lim;
    head.stripe.max_width = 64.0;
    head.stripe.max_plateau = 40;
    head.stripe.half_window = scanner_core::stripe::MAX_HALF_WINDOW;
    head.stripe.separation = 24;
    head.stripe.ambiguity = 0.8;
    head.limits.board_tol = 1.0;
    head.stripe.roi = f.roi;
    head
}
