//! Calibration from rendered images of the virtual rig, checked against the rig's truth.

use scanner_core::geometry::Plane;
use scanner_core::nalgebra::{Point3, Vector3};
use scanner_device::calib::board::BoardFile;
use scanner_device::calib::detect::{DetectConfig, find_markers};
use scanner_device::rig::{Rig, Scene, SurfaceId};

/// The demo scene at `w`×`h` with the default board file and sensor noise σ = 2 DN.
fn scene(w: u32, h: u32) -> Scene {
    let mut s = Scene::demo(w, h);
    s.board.markers = BoardFile::default().rig_markers();
    s.sensor.read_noise = 2.0;
    s.sensor.shot_noise = 0.0;
    s
}

#[test]
fn markers_are_found_at_their_disc_centroids() {
    let rig = Rig::new(scene(1280, 960)).unwrap();
    let img = rig.reference().to_gray_image();
    let det = find_markers(&img, &DetectConfig::default());
    let truth = rig.markers();
    let mut errs = Vec::new();
    for t in truth.iter().filter(|t| t.visible) {
        let best = det
            .blobs
            .iter()
            .map(|b| (b.centre - t.disc_px).norm())
            .fold(f64::INFINITY, f64::min);
        errs.push(best);
        println!(
            "{:?} {} err {best:.4} vs centre {:.4}",
            t.surface,
            t.index,
            (t.centre_px - t.disc_px).norm()
        );
    }
    println!("blobs {} rejected {:?}", det.blobs.len(), det.rejected);
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    println!("mean {mean:.4}");
    assert!(mean < 0.05);
}

/// Normal error (degrees) and offset error (% of `distance`) of a plane, the offset measured at
/// the centre of the sheet's true markers.
fn plane_errors(
    got: &Plane<f64>,
    truth: &Plane<f64>,
    at: &Point3<f64>,
    distance: f64,
) -> (f64, f64) {
    let angle = got.normal().angle(truth.normal()).to_degrees();
    assert!(truth.signed_distance(at).abs() < 1e-6);
    (angle, got.signed_distance(at).abs() / distance * 100.0)
}

fn sheet_centre(rig: &Rig, k: usize) -> Point3<f64> {
    let m: Vec<_> = rig
        .markers()
        .into_iter()
        .filter(|m| m.surface == [SurfaceId::Left, SurfaceId::Right][k])
        .collect();
    Point3::from(m.iter().fold(Vector3::zeros(), |s, m| s + m.centre.coords) / m.len() as f64)
}

#[test]
fn board_planes_from_a_rendered_board_with_the_true_camera() {
    let rig = Rig::new(scene(1280, 960)).unwrap();
    let img = rig.reference().to_gray_image();
    let board = BoardFile::default();
    let out = scanner_device::calib::board_planes(&img, &board, &rig.scene().camera);
    for (k, a) in out.assignments.iter().enumerate() {
        if let Some(a) = a {
            println!("assignment {k}: rms {}", a.rms_px);
            for (i, b) in a.blob_of.iter().enumerate() {
                let t = rig
                    .markers()
                    .into_iter()
                    .find(|m| m.index == i && m.surface == [SurfaceId::Left, SurfaceId::Right][k])
                    .unwrap();
                println!(
                    "sheet {k} marker {i}: blob {:?} truth {:?}",
                    b.map(|b| out.detections.blobs[b].centre),
                    t.disc_px
                );
            }
        }
    }
    let fit = out.result.unwrap();
    let truth = rig.board_planes();
    for k in 0..2 {
        let c = sheet_centre(&rig, k);
        let (a, o) = plane_errors(&fit.sheets[k].plane, &truth[k], &c, 800.0);
        println!(
            "sheet {k}: normal {a:.4}°, offset {o:.4} %, rms {:.4}, missing {:?}",
            fit.sheets[k].rms_px,
            fit.sheets[k].missing()
        );
        if let Some(p) = &fit.paper[k] {
            let (a, o) = plane_errors(p, &truth[k], &c, 800.0);
            println!("   paper: normal {a:.4}°, offset {o:.4} %");
        }
    }
}

#[test]
fn debug_identify() {
    use scanner_device::calib::identify::{Orientation, identify};
    let rig = Rig::new(scene(1280, 960)).unwrap();
    let img = rig.reference().to_gray_image();
    let det = find_markers(&img, &DetectConfig::default());
    let board = BoardFile::default();
    for b in &det.blobs {
        println!("blob {:?} area {}", b.centre, b.area);
    }
    let r = identify(
        &det.blobs,
        &[],
        &board.right.points(),
        Orientation {
            mirrored: false,
            u_along_x: Some(1),
        },
    );
    println!("{r:?}");
    let mut ex = vec![false; det.blobs.len()];
    for i in [0usize, 2, 4, 7, 8, 9] {
        ex[i] = true;
    }
    let r = identify(
        &det.blobs,
        &ex,
        &board.right.points(),
        Orientation {
            mirrored: false,
            u_along_x: Some(1),
        },
    );
    println!("{r:?}");
}
