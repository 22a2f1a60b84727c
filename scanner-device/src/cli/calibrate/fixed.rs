//! `calibrate fixed`: a turntable scanner's camera, fixed lasers and platform from its own
//! calibration frames.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use image::GrayImage;
use scanner_io::outln;

use scanner_calib::file::CalibrationFile;
use scanner_calib::{Target, intrinsics_auto, short};

use crate::calibrate::load_gray;
use crate::report::{self, write_json};

/// A frame whose mean luma is under this is dark: a laser frame, not a lit shot.
pub(super) const DARK_MEAN: f64 = 20.0;

/// Most lasers a turntable scanner has.
pub(super) const MAX_FIXED_LASERS: usize = 8;

/// `calibrate fixed`: the intrinsics from the lit shots, each laser's plane from the dark frames
/// after them, the platform from the lit shots' poses.
pub(super) fn fixed_command(
    target: &Target,
    images: &[PathBuf],
    (origin_distance, steps_per_turn, radius, clockwise): (f64, u32, f64, bool),
    out: &Path,
) -> Result<()> {
    let Target::Chessboard { cols, rows, square } = *target else {
        bail!(
            "calibrate fixed takes a chessboard: give --chessboard-corners or --chessboard-squares"
        );
    };
    if !(origin_distance.is_finite() && origin_distance.abs() <= 1000.0) {
        bail!(
            "--origin-distance {} mm: give the pattern's lowest corners' height above the platform",
            short(origin_distance)
        );
    }
    if steps_per_turn == 0 || steps_per_turn > scanner_calib::file::MAX_STEPS_PER_TURN {
        bail!(
            "--steps-per-turn {steps_per_turn}: a turntable's is 1 to {}",
            scanner_calib::file::MAX_STEPS_PER_TURN
        );
    }
    let mut gray = Vec::with_capacity(images.len());
    for p in images {
        gray.push(load_gray(p)?);
    }
    let dark: Vec<bool> = gray
        .iter()
        .map(|g| {
            let n = g.as_raw().len().max(1) as f64;
            g.as_raw().iter().map(|&v| f64::from(v)).sum::<f64>() / n < DARK_MEAN
        })
        .collect();
    let lit: Vec<usize> = (0..gray.len()).filter(|&i| !dark[i]).collect();
    let lit_images: Vec<GrayImage> = lit.iter().map(|&i| gray[i].clone()).collect();
    let (outcome, k3_fixed) = intrinsics_auto(&lit_images, target);
    let fit = outcome
        .into_fit()
        .context("the intrinsics from the lit shots of the pattern")?;
    let camera = fit.camera;
    // each lit shot's pose, and the dark frames after it (laser 0 first)
    let mut poses = Vec::new();
    let mut lasers: Vec<Vec<scanner_core::nalgebra::Point3<f64>>> = Vec::new();
    let mut shots = [0usize; MAX_FIXED_LASERS];
    for (k, view) in fit.views.iter().enumerate() {
        let Ok(v) = view else { continue };
        poses.push(v.pose);
        let at = lit[k];
        for (laser, j) in (at + 1..images.len()).take_while(|&j| dark[j]).enumerate() {
            if laser >= MAX_FIXED_LASERS {
                bail!(
                    "{}: more than {MAX_FIXED_LASERS} dark frames after a lit shot",
                    images[j].display()
                );
            }
            let rgb = scanner_io::image_file::open(&images[j])?.to_rgb8();
            let points =
                scanner_calib::fixed::laser_points(&camera, (cols, rows, square), &v.pose, &rgb)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", images[j].display()))?;
            if lasers.len() <= laser {
                lasers.resize_with(laser + 1, Vec::new);
            }
            if !points.is_empty() {
                shots[laser] += 1;
            }
            lasers[laser].extend(points);
        }
    }
    if lasers.is_empty() {
        bail!(
            "no dark laser frame follows a lit shot whose pattern was found: take one with each laser alone after a lit shot, without moving the pattern"
        );
    }
    let platform =
        scanner_calib::fixed::fit_platform((cols, rows, square), &poses, origin_distance)
            .map_err(|e| anyhow::anyhow!("the platform: {e}"))?;
    let mut file = CalibrationFile::from_camera(
        &camera,
        fit.size,
        format!(
            "intrinsics, fixed lasers and platform from {} lit shots of a {}x{} chessboard ({} mm squares){}",
            poses.len(),
            cols - 1,
            rows - 1,
            short(square),
            if k3_fixed { ", k3 fixed at 0" } else { "" }
        ),
        Some(fit.rms_px),
    );
    let mut laser_data = Vec::new();
    for (n, points) in lasers.iter().enumerate() {
        let l = scanner_calib::fixed::fit_laser(points).map_err(|e| {
            anyhow::anyhow!(
                "laser {n} (from {} frames with its stripe on the pattern): {e}",
                shots[n]
            )
        })?;
        file.lasers.push(scanner_calib::file::PlaneEq {
            normal: (*l.plane.normal()).into(),
            offset: l.plane.offset(),
        });
        outln!(
            "laser {n}: {} points from {} frames, {} dropped, rms {:.3} mm; plane normal [{:.5}, {:.5}, {:.5}], offset {:.3} mm",
            l.points,
            shots[n],
            l.dropped,
            l.rms_mm,
            l.plane.normal().x,
            l.plane.normal().y,
            l.plane.normal().z,
            l.plane.offset()
        );
        laser_data.push(serde_json::json!({
            "laser": n, "frames": shots[n], "points": l.points, "dropped": l.dropped,
            "rms_mm": l.rms_mm, "normal": [l.plane.normal().x, l.plane.normal().y, l.plane.normal().z],
            "offset_mm": l.plane.offset(),
        }));
    }
    let pl = platform.platform;
    let r = pl.rotation();
    file.platform = Some(scanner_calib::file::PlatformSection {
        rotation: [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]),
        origin: pl.origin().coords.into(),
        radius,
        steps_per_turn,
        clockwise,
        height: 0.0,
    });
    // the checks any calibration file gets
    let text = toml::to_string(&file).context("the calibration as TOML")?;
    let file = CalibrationFile::parse(&text, &out.display().to_string())?;
    file.save(out)?;
    let a = pl.axis();
    outln!(
        "camera: fx {:.3} fy {:.3} cx {:.3} cy {:.3}, rms {:.3} px over {} shots",
        camera.fx(),
        camera.fy(),
        camera.principal_point().x,
        camera.principal_point().y,
        fit.rms_px,
        poses.len()
    );
    outln!(
        "platform: axis [{:.5}, {:.5}, {:.5}], origin [{:.2}, {:.2}, {:.2}] mm, from {} turns spanning {:.1}°, corners {:.3} mm rms off their circles",
        a.x,
        a.y,
        a.z,
        pl.origin().x,
        pl.origin().y,
        pl.origin().z,
        platform.poses,
        platform.span_deg,
        platform.circle_rms_mm
    );
    let report = serde_json::json!({
        "camera": {"fx": camera.fx(), "fy": camera.fy(), "cx": camera.principal_point().x,
                   "cy": camera.principal_point().y, "rms_px": fit.rms_px, "shots": poses.len(),
                   "k3_fixed": k3_fixed},
        "lasers": laser_data,
        "platform": {"axis": [a.x, a.y, a.z], "origin": [pl.origin().x, pl.origin().y, pl.origin().z],
                     "poses": platform.poses, "span_deg": platform.span_deg,
                     "clockwise": clockwise,
                     "turns_clockwise": platform.turns.0, "turns_counter_clockwise": platform.turns.1,
                     "circle_rms_mm": platform.circle_rms_mm},
        "images": images.len(), "dark": dark.iter().filter(|&&d| d).count(),
    });
    let path = report::beside(out);
    write_json(&path, &report)?;
    outln!("wrote {} and {}", out.display(), path.display());
    Ok(())
}
