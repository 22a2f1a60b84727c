//! End to end on rendered frames: the virtual rig's demo scene (with sensor noise) → stripe
//! extraction (DIM, gray) → board points on the true board → least-squares laser plane →
//! triangulation, against the rig's ground truth. Calibration from images comes with issue 5;
//! here the board planes and the camera are the rig's true ones.

use scanner_core::geometry::{Board, LaserFitConfig, Limits, Surface, laser, triangulate};
use scanner_core::nalgebra::Point2;
use scanner_core::stripe::{Axis, Extractor, Frame, Method, PixelFormat, StripeConfig};
use scanner_rig::{Rig, Scene, SurfaceId};

#[test]
fn rendered_sweep_triangulates_onto_the_truth() {
    let (w, h) = (640usize, 480usize);
    let rig = Rig::new(Scene::demo(w as u32, h as u32)).unwrap();
    let camera = rig.scene().camera.cast::<f32>();
    let [left, right] = rig.board_planes();
    let board = Board::new(left, right).unwrap().cast::<f32>();
    let limits = Limits::<f32>::default();
    let reference = rig.reference().to_format(PixelFormat::Gray8);
    let reference = Frame::packed(&reference, w, h, PixelFormat::Gray8).unwrap();
    let mut ex = Box::new(Extractor::<1024>::new());
    let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    let (mut errors, mut planes, mut object_points, mut wrong_class) = (Vec::new(), 0, 0, 0);
    let frames = rig.scene().laser.frames;
    for k in (0..frames).step_by(3) {
        let data = rig.frame(k).unwrap().to_format(PixelFormat::Gray8);
        let frame = Frame::packed(&data, w, h, PixelFormat::Gray8).unwrap();
        let res = ex.extract(&frame, Some(&reference), &cfg).unwrap();
        let pixels: Vec<(usize, Point2<f32>)> = res
            .valid()
            .map(|(x, p)| (x, Point2::new(x as f32, p.centre)))
            .collect();
        let (mut bl, mut br) = (Vec::new(), Vec::new());
        for (_, px) in &pixels {
            if let Ok((p, s)) = triangulate::board_point(&camera, &board, px, &limits) {
                if s == Surface::Left {
                    bl.push(p)
                } else {
                    br.push(p)
                }
            }
        }
        let Ok(fit) = laser::least_squares(&bl, &br, &LaserFitConfig::default()) else {
            continue;
        };
        planes += 1;
        let truth = rig.truth(k).unwrap();
        for (x, px) in &pixels {
            let Some(t) = truth[*x] else { continue };
            let Ok((p, class)) = triangulate::triangulate(&camera, &board, &fit.plane, px, &limits)
            else {
                continue;
            };
            let on_object = matches!(t.surface, SurfaceId::Object(_));
            if on_object != (class == Surface::Object) {
                wrong_class += 1;
            }
            if on_object {
                object_points += 1;
                errors.push((p.cast::<f64>() - t.point).norm());
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let p95 = errors[errors.len() * 95 / 100];
    println!(
        "{planes} laser planes, {object_points} object points: error median {median:.3} mm, p95 {p95:.3} mm, {wrong_class} misclassified"
    );
    assert!(
        planes >= frames / 3 - 1,
        "laser plane found in only {planes} frames"
    );
    assert!(object_points > 300, "only {object_points} object points");
    // 640×480 (f = 560 px), objects at ~500 mm: one pixel is ~0.9 mm there
    assert!(
        median < 0.15 && p95 < 0.6,
        "median {median} mm, p95 {p95} mm"
    );
    assert!(
        wrong_class * 50 < object_points,
        "{wrong_class} points on the wrong surface"
    );
}
