//! Where a rig view's point errors come from: `cargo run --release -p scanner-tests --example
//! point_errors -- VIEW_DIR SCENE K`, where VIEW_DIR is a receive output folder of view K of
//! SCENE (e.g. `OUT/view3` of `scripts/scan-rig-360 OUT`). Replays the view's journal and
//! compares, point by point, its distance from the true surface (placed by the view's true pose)
//! with the distance of the point that the same camera ray gives on the frame's *true* laser
//! plane: the first is the whole error, the second what is left when the frame's laser plane
//! (found from the stripe on the board) is exact — the stripe's centre on the object and the
//! calibration. Also the angle between each frame's plane and the true one.
//!
//! With a calibration from images the camera frame is the calibrated one, so the true plane
//! need not fit better (on the 360° demo's view 0 it fits worse: 0.153 mm median against the
//! whole 0.094 mm); with the rig's true calibration it isolates the stripe.

use std::path::{Path, PathBuf};

use scanner_core::nalgebra::{Point3, Vector3};
use scanner_rig::{Rig, Scene, Shape};
use scanner_wire::Message;

fn main() {
    if let Err(e) = run() {
        eprintln!("point_errors: {e}");
        std::process::exit(1);
    }
}

fn run() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dir, scene_path, k] = &args[..] else {
        return Err(anyhow::anyhow!("usage: point_errors VIEW_DIR SCENE K"));
    };
    let (dir, scene_path) = (PathBuf::from(dir), PathBuf::from(scene_path));
    let k: usize = k.parse().map_err(|e| anyhow::anyhow!("view {k}: {e}"))?;
    let text = std::fs::read_to_string(&scene_path)
        .map_err(|e| anyhow::anyhow!("{}: {e}", scene_path.display()))?;
    let scene = Scene::from_toml_in(&text, scene_path.parent().unwrap_or(Path::new(".")))
        .map_err(|e| anyhow::anyhow!("{}: {e}", scene_path.display()))?;
    let view = scene.view(k).map_err(|e| anyhow::anyhow!("{e}"))?;
    let Some(Shape::Mesh(placed)) = view.objects.first().map(|o| o.shape.clone()) else {
        return Err(anyhow::anyhow!("the scene's first object is not a mesh"));
    };
    let rig = Rig::new(view).map_err(|e| anyhow::anyhow!("{e}"))?;
    let journal = dir.join("journal.stream");
    let bytes =
        std::fs::read(&journal).map_err(|e| anyhow::anyhow!("{}: {e}", journal.display()))?;
    let mut decoder = Box::new(scanner_wire::Decoder::<{ scanner_wire::MAX_ENCODED }>::new());
    let (mut whole, mut on_true, mut tilt, mut along) = (vec![], vec![], vec![], vec![]);
    decoder.feed(&bytes, |m| {
        let Ok(Message::Points(p)) = m else { return };
        let Ok((_, truth)) = rig.laser(p.frame as usize) else {
            return;
        };
        let n = Vector3::new(p.plane[0], p.plane[1], p.plane[2]).cast::<f64>();
        tilt.push(n.angle(truth.normal()).to_degrees());
        let _ = scanner_wire::points::decode(p.xyz, p.count as usize, |q| {
            let x: Point3<f64> = q
                .map(|v| f64::from(scanner_wire::points::dequantise(v)))
                .into();
            let Some(c) = placed.closest(&x) else { return };
            whole.push((x - c).norm());
            // signed along the camera ray: + farther than the surface
            let ray = x.coords.normalize();
            along.push((x - c).dot(&ray).signum() * (x - c).norm());
            if let Ok(y) = truth.intersect_ray(&ray, 0.01) {
                on_true.push(placed.distance(&y));
            }
        });
    });
    if whole.is_empty() {
        return Err(anyhow::anyhow!("{}: no points", journal.display()));
    }
    let quantile = |v: &mut Vec<f64>, f: f64| {
        v.sort_by(f64::total_cmp);
        v.get(((v.len().max(1) - 1) as f64 * f) as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    let mean = along.iter().sum::<f64>() / along.len() as f64;
    println!(
        "view {k}: {} points; off the truth median {:.4} mm, p90 {:.4} mm; on the frames' true laser planes median {:.4} mm, p90 {:.4} mm; planes off the true ones median {:.4}°, p90 {:.4}°; mean signed error along the ray {mean:+.4} mm (+ farther)",
        whole.len(),
        quantile(&mut whole, 0.5),
        quantile(&mut whole, 0.9),
        quantile(&mut on_true, 0.5),
        quantile(&mut on_true, 0.9),
        quantile(&mut tilt, 0.5),
        quantile(&mut tilt, 0.9),
    );
    Ok(())
}
