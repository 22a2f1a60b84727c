//! Calibration from rendered images of the virtual rig (never from its true values), checked
//! against the rig's truth: marker detection, identification, intrinsics, board planes, the
//! paper's image distance, and the errors on bad input.

#![allow(clippy::needless_range_loop)] // k indexes the left/right pairs of several arrays

use scanner_calib::board::BoardFile;
use scanner_calib::detect::{DetectConfig, find_markers};
use scanner_calib::{CalibError, DotGrid, Target, board_planes, image_distance, intrinsics};
use scanner_core::calib::Free;
use scanner_core::geometry::Plane;
use scanner_core::nalgebra::{Point3, Vector3};
use scanner_rig::target::{Pattern, TargetPose};
use scanner_rig::{Rig, Scene, SurfaceId};

const W: u32 = 1280;
const H: u32 = 960;

/// The demo scene with the default board file and sensor noise σ = 2 DN.
fn scene(w: u32, h: u32) -> Scene {
    let mut s = Scene::demo(w, h);
    s.board.markers = scanner_rig::Markers::from(&BoardFile::default());
    s.sensor.read_noise = 2.0;
    s.sensor.shot_noise = 0.0;
    s
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
    let surface = [SurfaceId::Left, SurfaceId::Right][k];
    let m: Vec<_> = rig
        .markers()
        .into_iter()
        .filter(|m| m.surface == surface)
        .collect();
    Point3::from(m.iter().fold(Vector3::zeros(), |s, m| s + m.centre.coords) / m.len() as f64)
}

/// Dot-grid shots for intrinsics: a 9×7 grid, 30 mm pitch, 12 mm dots, turned up to ±35° at
/// 550–850 mm, spread over the image.
fn grid_shots(rig: &Rig, n: usize) -> (DotGrid, Vec<image::GrayImage>) {
    (DotGrid::RIG, rig.dot_grid_shots(&DotGrid::RIG, n))
}

#[test]
fn markers_are_found_at_their_disc_centroids() {
    let rig = Rig::new(scene(W, H)).unwrap();
    let img = rig.reference().to_gray_image();
    let det = find_markers(&img, &DetectConfig::default());
    let (mut errs, mut ecc) = (Vec::new(), Vec::new());
    for t in rig.markers().iter().filter(|t| t.visible) {
        let best = det
            .blobs
            .iter()
            .map(|b| (b.centre - t.disc_px).norm())
            .fold(f64::INFINITY, f64::min);
        errs.push(best);
        ecc.push((t.centre_px - t.disc_px).norm());
    }
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    let worst = errs.iter().copied().fold(0.0, f64::max);
    let ecc_mean = ecc.iter().sum::<f64>() / ecc.len() as f64;
    println!(
        "{} visible markers: centre error mean {mean:.4} px, worst {worst:.4} px (eccentricity of the discs' images: mean {ecc_mean:.3} px)",
        errs.len()
    );
    assert!(errs.len() >= 10);
    assert!(mean <= 0.05 && worst < 0.1, "mean {mean}, worst {worst}");
}

#[test]
fn calibration_from_rendered_images_meets_the_targets() {
    // Intrinsics from 12 dot-grid shots, then the board planes from the board image with that
    // camera: nothing from the rig's truth but the images.
    let rig = Rig::new(scene(W, H)).unwrap();
    let (grid, images) = grid_shots(&rig, 12);
    let fit = intrinsics(&images, &Target::Dots(grid), Free::ALL).unwrap();
    let (c, t) = (fit.camera, rig.scene().camera);
    let (efx, efy) = (
        (c.fx() / t.fx() - 1.0) * 100.0,
        (c.fy() / t.fy() - 1.0) * 100.0,
    );
    let epp = (c.principal_point() - t.principal_point()).norm();
    println!(
        "intrinsics: rms {:.4} px over {} views; fx {efx:+.4} %, fy {efy:+.4} %, principal point {epp:.3} px",
        fit.rms_px,
        fit.views.len()
    );
    assert!(fit.views.iter().all(|v| v.is_ok()));
    assert!(efx.abs() < 0.2 && efy.abs() < 0.2 && epp < 1.0);
    assert!(fit.rms_px < 0.1);

    let img = rig.reference().to_gray_image();
    let out = board_planes(&img, &BoardFile::default(), &c);
    let board = out.result.unwrap();
    let truth = rig.board_planes();
    for k in 0..2 {
        let (a, o) = plane_errors(
            &board.sheets[k].plane,
            &truth[k],
            &sheet_centre(&rig, k),
            800.0,
        );
        println!(
            "sheet {k}: normal {a:.4}°, offset {o:.4} % of 800 mm, rms {:.4} px, missing {:?}",
            board.sheets[k].rms_px,
            board.sheets[k].missing()
        );
        assert!(a < 0.05 && o < 0.05, "sheet {k}: normal {a}°, offset {o} %");
    }
    // The hidden markers (one per sheet behind the objects) are reported missing.
    let hidden: Vec<_> = rig
        .markers()
        .into_iter()
        .filter(|m| !m.visible)
        .map(|m| (m.surface, m.index))
        .collect();
    for (surface, index) in hidden {
        let k = if surface == SurfaceId::Left { 0 } else { 1 };
        assert!(
            board.sheets[k].missing().contains(&index),
            "{surface:?} {index} hidden but used"
        );
    }
    let angle = board.board.angle().to_degrees();
    println!("angle between the planes {angle:.4}° (built: 90°)");
    assert!((angle - 90.0).abs() < 0.1);
}

#[test]
fn paper_lines_and_layout_pose_on_an_unobstructed_board() {
    let mut s = scene(W, H);
    s.objects.clear();
    let rig = Rig::new(s).unwrap();
    let img = rig.reference().to_gray_image();
    let out = board_planes(&img, &BoardFile::default(), &rig.scene().camera);
    let board = out.result.unwrap();
    let truth = rig.board_planes();
    for k in 0..2 {
        let c = sheet_centre(&rig, k);
        let (a, o) = plane_errors(&board.sheets[k].plane, &truth[k], &c, 800.0);
        let paper = board.paper[k].expect("all six markers are visible");
        let (pa, po) = plane_errors(&paper, &truth[k], &c, 800.0);
        println!(
            "sheet {k}: layout pose normal {a:.4}° offset {o:.4} %; paper lines normal {pa:.4}° offset {po:.4} %"
        );
        assert!(board.sheets[k].missing().is_empty());
        assert!(a < 0.05 && o < 0.05);
        assert!(
            pa < 1.0 && po < 0.5,
            "paper construction far off: {pa}° {po} %"
        );
    }
}

#[test]
fn the_paper_procedure_on_rendered_cross_images() {
    let mut s = scene(W, H);
    s.camera = scanner_core::Camera::new(
        1120.0,
        1120.0,
        639.5,
        479.5,
        scanner_core::Distortion::none(),
    )
    .unwrap();
    let rig = Rig::new(s).unwrap();
    let cross = BoardFile::default().cross;
    let pattern = Pattern::Cross {
        arm: cross.arm,
        dot: cross.dot,
    };
    let eps = 25.0;
    let shot = |z: f64| {
        let pose = TargetPose {
            centre: Point3::new(0.0, 0.0, z),
            turn_deg: [0.0; 3],
        };
        rig.shot(&pattern, &pose, z as u64).image.to_gray_image()
    };
    let (near, far) = (shot(500.0), shot(900.0));
    let d = image_distance(&cross, (&near, 500.0 + eps), (&far, 900.0 + eps)).unwrap();
    println!(
        "d_z {:.2} px (true 1120), ε {:.2} mm (true {eps})",
        d.d_z, d.epsilon_mm
    );
    assert!((d.d_z / 1120.0 - 1.0).abs() < 0.002);
    assert!((d.epsilon_mm - eps).abs() < 2.0);
}

#[test]
fn bad_input_names_what_was_expected_and_found() {
    let rig = Rig::new(scene(640, 480)).unwrap();
    let cam = rig.scene().camera;
    // No board: a blank wall.
    let blank = image::GrayImage::from_pixel(640, 480, image::Luma([180]));
    let e = board_planes(&blank, &BoardFile::default(), &cam)
        .result
        .unwrap_err();
    assert!(matches!(e, CalibError::NoMarkers { .. }), "{e}");
    // Too few markers: the right half of the image covered.
    let mut half = rig.reference().to_gray_image();
    for (x, _, p) in half.enumerate_pixels_mut() {
        if x >= 320 {
            *p = image::Luma([180]);
        }
    }
    let e = board_planes(&half, &BoardFile::default(), &cam)
        .result
        .unwrap_err();
    assert!(
        matches!(&e, CalibError::TooFewMarkers { what, .. } if what.contains("right")),
        "{e}"
    );
    // A board file that disagrees with the printed board: a 3×3 grid.
    let mut other = BoardFile::default();
    for s in [&mut other.left, &mut other.right] {
        s.grid = Some(scanner_calib::board::MarkerGrid {
            cols: 3,
            rows: 3,
            u0: 66.0,
            v0: -110.0,
            du: 110.0,
            dv: 110.0,
        });
    }
    let e = board_planes(&rig.reference().to_gray_image(), &other, &cam).result;
    assert!(
        e.is_err()
            || e.as_ref()
                .is_ok_and(|b| b.sheets.iter().all(|s| s.missing().len() >= 3)),
        "{e:?}"
    );
    // An image of another size than the calibration.
    let e = scanner_calib::check_size((1280, 960), &blank).unwrap_err();
    assert_eq!(
        e.to_string(),
        "image is 640×480 but the camera was calibrated at 1280×960"
    );
    // Intrinsics from images without a grid.
    let grid = DotGrid {
        cols: 9,
        rows: 7,
        pitch: 30.0,
        dot: 12.0,
    };
    let e = intrinsics(
        &[blank.clone(), blank.clone(), blank],
        &Target::Dots(grid),
        Free::ALL,
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("0 of 3 images usable (grid found, not refused)"),
        "{e}"
    );
}

#[test]
fn chessboard_corners_are_found_where_they_project() {
    use scanner_calib::corners::{CornerConfig, find_corners};
    let rig = Rig::new(scene(W, H)).unwrap();
    let pattern = Pattern::Chessboard {
        cols: 10,
        rows: 8,
        square: 25.0,
    };
    let mut errs = Vec::new();
    for (i, turn) in [[0.0, 0.0, 5.0], [30.0, -20.0, 0.0], [-25.0, 35.0, -10.0]]
        .iter()
        .enumerate()
    {
        let pose = TargetPose {
            centre: Point3::new(20.0, -10.0, 700.0),
            turn_deg: *turn,
        };
        let shot = rig.shot(&pattern, &pose, i as u64);
        let corners = find_corners(&shot.image.to_gray_image(), &CornerConfig::default());
        let mut matched = 0;
        for f in &shot.features {
            let best = corners
                .iter()
                .map(|c| (c.centre - f.projected).norm())
                .fold(f64::INFINITY, f64::min);
            if best < 1.0 {
                errs.push(best);
                matched += 1;
            }
        }
        println!(
            "shot {i}: {} corners found, {matched} of {} true ones matched",
            corners.len(),
            shot.features.len()
        );
        assert_eq!(matched, shot.features.len());
        assert!(
            corners.len() <= shot.features.len() + 2,
            "clutter: {}",
            corners.len()
        );
    }
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    let worst = errs.iter().copied().fold(0.0, f64::max);
    println!("chessboard corners: mean error {mean:.4} px, worst {worst:.4} px");
    assert!(mean < 0.05 && worst < 0.3, "{mean} {worst}");
}

#[test]
fn a_sheet_may_carry_a_chessboard() {
    use scanner_calib::board::Chessboard;
    let mut board = BoardFile::default();
    board.right.grid = None;
    board.right.chessboard = Some(Chessboard {
        cols: 8,
        rows: 8,
        square: 30.0,
        u0: 60.0,
        v0: -90.0,
    });
    board.check().unwrap();
    let mut s = scene(W, H);
    s.board.markers = scanner_rig::Markers::from(&board);
    // A chessboard mostly hidden by the object is a periodic grid with its ends out of sight:
    // which square is which can then be ambiguous (see the README). The board is left clear.
    s.objects.clear();
    let rig = Rig::new(s).unwrap();
    let img = rig.reference().to_gray_image();
    let out = board_planes(&img, &board, &rig.scene().camera);
    let fit = out.result.unwrap();
    let truth = rig.board_planes();
    for k in 0..2 {
        let (a, o) = plane_errors(
            &fit.sheets[k].plane,
            &truth[k],
            &sheet_centre(&rig, k),
            800.0,
        );
        let used = fit.sheets[k].markers.len() - fit.sheets[k].missing().len();
        println!(
            "sheet {k}: {used}/{} markers, normal {a:.4}°, offset {o:.4} %, rms {:.4} px",
            fit.sheets[k].markers.len(),
            fit.sheets[k].rms_px
        );
        assert!(a < 0.05 && o < 0.05, "sheet {k}: {a}° {o} %");
    }
    assert!(fit.sheets[1].missing().is_empty());
}

#[test]
fn intrinsics_from_rendered_chessboards() {
    let rig = Rig::new(scene(W, H)).unwrap();
    let pattern = Pattern::Chessboard {
        cols: 10,
        rows: 8,
        square: 25.0,
    };
    let n = 12;
    let images: Vec<_> = (0..n)
        .map(|i| {
            let pose = TargetPose::sweep(i, n);
            rig.shot(&pattern, &pose, i as u64).image.to_gray_image()
        })
        .collect();
    let fit = intrinsics(
        &images,
        &Target::Chessboard {
            cols: 10,
            rows: 8,
            square: 25.0,
        },
        Free::ALL,
    )
    .unwrap();
    let (c, t) = (fit.camera, rig.scene().camera);
    let (efx, efy) = (
        (c.fx() / t.fx() - 1.0) * 100.0,
        (c.fy() / t.fy() - 1.0) * 100.0,
    );
    let epp = (c.principal_point() - t.principal_point()).norm();
    println!(
        "chessboard intrinsics: rms {:.4} px; fx {efx:+.4} %, fy {efy:+.4} %, principal point {epp:.3} px",
        fit.rms_px
    );
    assert!(fit.views.iter().all(|v| v.is_ok()));
    assert!(efx.abs() < 0.2 && efy.abs() < 0.2 && epp < 1.0);
}

#[test]
fn a_marker_partly_behind_the_object_is_dropped_however_little_it_pulls() {
    // The 360° demo's board: the bunny's foot hides the top of the left sheet's marker 3 (found
    // a pixel low) and reaches into the right one's surroundings (0.19 px low). With six markers
    // a sheet's pose absorbs most of such an error (residual 0.23 px, rms 0.13 px): kept, it
    // tilted the left plane by 0.036° and put the planes 0.08–0.14 mm nearer the camera, which
    // moved every scanned depth by about as much.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/bunny-360.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let scene = Scene::from_toml_in(&text, std::path::Path::new(path).parent().unwrap())
        .unwrap()
        .view(0)
        .unwrap();
    let rig = Rig::new(scene).unwrap();
    let camera = rig.scene().camera;
    let img = rig.reference().to_gray_image();
    let board = board_planes(&img, &BoardFile::default(), &camera)
        .result
        .unwrap();
    let truth = rig.board_planes();
    for k in 0..2 {
        let sheet = &board.sheets[k];
        let (a, o) = plane_errors(&sheet.plane, &truth[k], &sheet_centre(&rig, k), 800.0);
        println!(
            "sheet {k}: normal {a:.4}°, offset {o:.4} % of 800 mm, rms {:.4} px, missing or dropped {:?}",
            sheet.rms_px,
            sheet.missing()
        );
        assert_eq!(sheet.missing(), vec![3], "sheet {k}");
        assert!(sheet.rms_px < 0.05, "sheet {k}: rms {}", sheet.rms_px);
        assert!(
            o < 0.0125 && a < 0.02,
            "sheet {k}: normal {a}°, offset {o} %"
        );
    }
}
