//! ChArUco boards on the real photographs of `tests/data/real-two-plane` (two boards of OpenCV's
//! layout, 7×5 squares of 25 mm, markers of 19 mm, `DICT_4X4_50` above and `DICT_5X5_50`
//! below) and the bad input a user can give: a board file naming the wrong dictionary, two
//! boards sharing IDs (in the file, or in the picture), a board too small in the picture.

use std::path::{Path, PathBuf};

use image::GrayImage;
use scanner_calib::aruco::{CharucoBoard, Dictionary, quads};
use scanner_calib::board::{BoardError, BoardFile};
use scanner_calib::charuco::find_charuco;
use scanner_calib::file::CalibrationFile;
use scanner_calib::{CalibError, board_planes};
use scanner_core::Camera;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/real-two-plane")
}

fn photo() -> GrayImage {
    image::open(data().join("20220331_faa7cdf/laser-off.png"))
        .unwrap()
        .to_luma8()
}

fn camera() -> Camera<f64> {
    CalibrationFile::load(&data().join("20220331_faa7cdf/calibration.toml"))
        .unwrap()
        .camera()
        .unwrap()
}

fn board_text() -> String {
    std::fs::read_to_string(data().join("board.toml")).unwrap()
}

fn board(text: &str) -> Result<BoardFile, BoardError> {
    BoardFile::parse(text, "board.toml")
}

fn charuco(dict: &str) -> CharucoBoard {
    CharucoBoard {
        cols: 7,
        rows: 5,
        square: 25.0,
        marker: 19.0,
        dictionary: Dictionary::named(dict).unwrap(),
        first_id: 0,
    }
}

/// Every marker of both boards is read with its ID (no other ID of the dictionary is), and every
/// inner corner of each board is named, by our own decoder.
#[test]
fn every_marker_and_corner_of_both_real_boards_is_found() {
    for pair in ["20220331_faa7cdf", "20220405_9eb8eaa"] {
        let img = image::open(data().join(pair).join("laser-off.png"))
            .unwrap()
            .to_luma8();
        let q = quads(&img, scanner_calib::aruco::MIN_QUAD_SIDE_PX);
        for dict in ["DICT_4X4_50", "DICT_5X5_50"] {
            let found = find_charuco(&img, &q, &charuco(dict));
            let ids: Vec<usize> = found.markers.markers.iter().map(|m| m.id).collect();
            println!(
                "{pair} {dict}: {} markers, {} corners, {} quads unread",
                ids.len(),
                found.corners.len(),
                found.markers.unread
            );
            assert_eq!(ids, (0..17).collect::<Vec<_>>(), "{pair} {dict}");
            assert!(found.markers.repeated.is_empty() && found.misplaced.is_empty());
            let corners: Vec<usize> = found.corners.iter().map(|c| c.0).collect();
            assert_eq!(corners, (0..24).collect::<Vec<_>>(), "{pair} {dict}");
        }
        // A dictionary of the same cell count but more codes still reads the same IDs; one of
        // another size reads none.
        let all = scanner_calib::aruco::find_aruco(
            &img,
            &q,
            &Dictionary::named("DICT_4X4_1000").unwrap(),
        );
        assert_eq!(all.markers.len(), 17, "{pair}: DICT_4X4_1000");
        let none =
            scanner_calib::aruco::find_aruco(&img, &q, &Dictionary::named("DICT_6X6_250").unwrap());
        assert!(
            none.markers.is_empty(),
            "{pair}: DICT_6X6_250 {:?}",
            none.markers
        );
    }
}

/// A board file naming a dictionary that is not printed: refused with what the picture shows.
#[test]
fn a_board_of_the_wrong_dictionary_is_refused_with_the_one_seen() {
    let text = board_text().replace(
        "dictionary = \"DICT_4X4_50\"",
        "dictionary = \"DICT_6X6_50\"",
    );
    let b = board(&text).unwrap();
    let out = board_planes(&photo(), &b, &camera());
    match out.result {
        Err(CalibError::OtherDictionary {
            dictionary, others, ..
        }) => {
            assert_eq!(dictionary, "DICT_6X6_50");
            assert!(others.ends_with("markers of DICT_4X4"), "{others}");
        }
        other => panic!("expected a ChArUco error, got {other:?}"),
    }
    // IDs past the dictionary, however far, are refused when the file is read.
    for first in ["40", "18446744073709551615"] {
        let text = board_text().replace(
            "dictionary = \"DICT_5X5_50\"",
            &format!("dictionary = \"DICT_5X5_50\", first_id = {first}"),
        );
        assert!(matches!(
            board(&text),
            Err(BoardError::IdsPastDictionary { .. })
        ));
    }
    // An unknown dictionary name is refused when the file is read.
    let text = board_text().replace("DICT_5X5_50", "DICT_5X5_60");
    assert!(
        matches!(board(&text), Err(BoardError::UnknownDictionary { dictionary, .. }) if dictionary == "DICT_5X5_60")
    );
}

/// Two sheets of one dictionary whose IDs overlap: refused when the board file is read; and two
/// boards sharing IDs in the picture (the upper board pasted over the lower one): refused, the
/// repeated IDs named.
#[test]
fn two_boards_that_share_ids_are_refused() {
    let text = board_text().replace("DICT_5X5_50", "DICT_4X4_50");
    match board(&text) {
        Err(BoardError::SharedIds {
            dictionary, left, ..
        }) => {
            assert_eq!((dictionary.as_str(), left), ("DICT_4X4_50", (0, 16)));
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    // IDs 17–33 on the right sheet: accepted.
    let text = board_text().replace(
        "dictionary = \"DICT_5X5_50\"",
        "dictionary = \"DICT_4X4_50\", first_id = 17",
    );
    board(&text).unwrap();

    // The upper board (rows 90–580) pasted below it (at rows 600–1090), over the lower board.
    let mut img = photo();
    let copy = img.clone();
    for y in 90..580 {
        for x in 600..1500 {
            img.put_pixel(x, y + 510, *copy.get_pixel(x, y));
        }
    }
    let b = board(&board_text()).unwrap();
    let out = board_planes(&img, &b, &camera());
    match out.result {
        Err(CalibError::RepeatedIds { ids, .. }) => assert!(ids.len() >= 10, "{ids:?}"),
        other => panic!("expected a ChArUco error, got {other:?}"),
    }
    let left = out.charuco[0].as_ref().unwrap();
    assert!(left.markers.repeated.len() >= 10, "{:?}", left.markers);
}

/// The photograph shrunk until the markers' cells are under 2.5 px: refused as too small, with
/// the size needed.
#[test]
fn a_board_too_small_in_the_picture_is_refused_with_the_size_needed() {
    let img = photo();
    let k = 10u32;
    let small = image::imageops::resize(
        &img,
        1920 / k,
        1200 / k,
        image::imageops::FilterType::Triangle,
    );
    let c = camera();
    let s = 1.0 / f64::from(k);
    let pp = c.principal_point();
    let small_cam = Camera::new(
        c.fx() * s,
        c.fy() * s,
        (pp.x + 0.5) * s - 0.5,
        (pp.y + 0.5) * s - 0.5,
        scanner_core::camera::Distortion::none(),
    )
    .unwrap();
    let b = board(&board_text()).unwrap();
    let out = board_planes(&small, &b, &small_cam);
    match out.result {
        Err(CalibError::MarkersTooSmall {
            side_px, needed_px, ..
        }) => assert!(side_px < needed_px, "{side_px} {needed_px}"),
        other => panic!("expected a ChArUco error, got {other:?}"),
    }
}

/// `board --charuco`'s sheets, printed to pictures, are read back by our decoder: every corner
/// of each sheet, each where the board file lays it on the paper (upright, not mirrored: a
/// mirrored print would not read), and every marker with the sheet's own IDs. The real
/// recording's board file prints readable sheets too.
#[test]
fn printed_charuco_sheets_read_back_where_the_board_file_lays_them() {
    for (name, b) in [
        ("charuco_default", BoardFile::charuco_default()),
        ("real-two-plane", board(&board_text()).unwrap()),
    ] {
        b.check().unwrap();
        for k in 0..2 {
            let sheet_layout = [&b.left, &b.right][k];
            let c = sheet_layout.charuco.as_ref().unwrap();
            // 10 px/mm: every square's edge on a pixel's edge (the picture's squares are not
            // smoothed), and the pixel centres half a pixel in.
            let px_per_mm = 10.0;
            let img = image::DynamicImage::ImageRgb8(
                scanner_calib::print::Sheet::board(&b, k)
                    .png(px_per_mm)
                    .unwrap(),
            )
            .to_luma8();
            let q = quads(&img, scanner_calib::aruco::MIN_QUAD_SIDE_PX);
            let found = find_charuco(&img, &q, &c.board().unwrap());
            let layout = sheet_layout.points();
            assert_eq!(found.corners.len(), layout.len(), "{name} sheet {k}");
            let ids: Vec<usize> = found.markers.markers.iter().map(|m| m.id).collect();
            assert_eq!(ids, c.board().unwrap().ids().collect::<Vec<_>>());
            // Paper position of each corner, in pixels (up to the pixel convention's offset).
            let (w, h) = (b.sheet.width, b.sheet.height);
            let diffs: Vec<(f64, f64)> = found
                .corners
                .iter()
                .map(|&(i, p)| {
                    let x = if k == 0 { w - layout[i].x } else { layout[i].x };
                    let y = h / 2.0 + layout[i].y;
                    (p.x + 0.5 - x * px_per_mm, p.y + 0.5 - y * px_per_mm)
                })
                .collect();
            let n = diffs.len() as f64;
            let mean = (
                diffs.iter().map(|d| d.0).sum::<f64>() / n,
                diffs.iter().map(|d| d.1).sum::<f64>() / n,
            );
            let rms = (diffs
                .iter()
                .map(|d| (d.0 - mean.0).powi(2) + (d.1 - mean.1).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
            println!(
                "{name} sheet {k}: {} corners, {rms:.3} px RMS about an offset of ({:.2}, {:.2}) px",
                found.corners.len(),
                mean.0,
                mean.1
            );
            assert!(
                rms < 0.1 && mean.0.abs() < 1.0 && mean.1.abs() < 1.0,
                "{name} sheet {k}"
            );
        }
    }
    // Laid mirrored, a sheet is refused when the board file is read.
    let text = board_text().replace("x = \"+v\", y = \"+u\"", "x = \"-v\", y = \"+u\"");
    assert!(matches!(board(&text), Err(BoardError::Mirrored { .. })));
}

/// Intrinsics from rendered shots of a ChArUco board (9×7 squares of 30 mm, 22 mm markers of
/// `DICT_5X5_100`; 1280×960, sensor noise σ = 2 DN): the twelve poses of the dot grid's sweep
/// and two close-ups that show only part of the board, every one used. Stated: the corners'
/// error against their true projections and the camera's against the rig's, beside a plain
/// chessboard of the same squares on the same poses. (OpenCV 5.0.0's `CharucoDetector` on
/// these ChArUco shots, measured once: corners mean 0.087 px, worst 0.35 px, and fewer
/// corners of a partial view.)
#[test]
fn charuco_intrinsics_on_rendered_shots_with_partial_views() {
    use scanner_calib::{Target, find_grid, intrinsics};
    use scanner_core::calib::Free;
    use scanner_core::nalgebra::Point3;
    use scanner_rig::target::{Pattern, TargetPose};
    use scanner_rig::{Rig, Scene};

    let mut scene = Scene::demo(1280, 960);
    scene.sensor.read_noise = 2.0;
    scene.sensor.shot_noise = 0.0;
    let rig = Rig::new(scene).unwrap();
    let b = CharucoBoard {
        cols: 9,
        rows: 7,
        square: 30.0,
        marker: 22.0,
        dictionary: Dictionary::named("DICT_5X5_100").unwrap(),
        first_id: 0,
    };
    let mut poses: Vec<TargetPose> = (0..12).map(|i| TargetPose::sweep(i, 12)).collect();
    // Close-ups with the board running off the picture's left and bottom edges.
    poses.push(TargetPose {
        centre: Point3::new(-250.0, 20.0, 450.0),
        turn_deg: [10.0, 20.0, 5.0],
    });
    poses.push(TargetPose {
        centre: Point3::new(30.0, 120.0, 430.0),
        turn_deg: [-20.0, -10.0, -5.0],
    });
    let chess = Target::Chessboard {
        cols: 9,
        rows: 7,
        square: 30.0,
    };
    for (name, pattern, target) in [
        ("ChArUco", Pattern::Charuco(b), Target::Charuco(b)),
        (
            "chessboard",
            Pattern::Chessboard {
                cols: 9,
                rows: 7,
                square: 30.0,
            },
            chess,
        ),
    ] {
        let shots: Vec<_> = poses
            .iter()
            .enumerate()
            .map(|(i, p)| rig.shot(&pattern, p, i as u64))
            .collect();
        let images: Vec<GrayImage> = shots.iter().map(|s| s.image.to_gray_image()).collect();
        // The corners against their truth.
        let mut errs = Vec::new();
        let mut partial = 0;
        for (i, (shot, img)) in shots.iter().zip(&images).enumerate() {
            let Ok(grid) = find_grid(img, &target) else {
                assert!(name != "ChArUco", "{name} shot {i}: not found");
                continue;
            };
            if grid.found.len() < target.points().len() {
                partial += 1;
            }
            for &(k, p) in &grid.found {
                errs.push((p - shot.features[k].projected).norm());
            }
        }
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        let worst = errs.iter().copied().fold(0.0, f64::max);
        let fit = intrinsics(&images, &target, Free::ALL).unwrap();
        let (c, t) = (fit.camera, rig.scene().camera);
        let (efx, efy) = (
            (c.fx() / t.fx() - 1.0) * 100.0,
            (c.fy() / t.fy() - 1.0) * 100.0,
        );
        let epp = (c.principal_point() - t.principal_point()).norm();
        let used = fit.views.iter().filter(|v| v.is_ok()).count();
        println!(
            "{name}: {used} of {} shots used ({partial} partial), corners mean {mean:.4} px, worst \
             {worst:.4} px; rms {:.4} px; fx {efx:+.4} %, fy {efy:+.4} %, principal point {epp:.3} px",
            poses.len(),
            fit.rms_px
        );
        if name == "ChArUco" {
            assert_eq!(used, poses.len(), "every ChArUco shot used");
            assert!(partial >= 2, "the close-ups show part of the board");
            // The worst: a corner 44 px from the picture's edge in a close-up, one marker beside it.
            assert!(mean < 0.07 && worst < 1.0, "corners {mean} {worst}");
            assert!(efx.abs() < 0.2 && efy.abs() < 0.2 && epp < 1.0);
            assert!(fit.rms_px < 0.1);
        }
    }
}

/// An object in front of the board (a gray blob painted over the middle of the lower board, as
/// a scan's laser-off frame has it): the corners it hides are missing, the rest name themselves,
/// the upper plane stays within 0.05° of OpenCV's and the lower within 0.25°. The real sheet is
/// not flat (its corners fit their layout at 0.66 px RMS, edges against middle): OpenCV's own
/// corners without the middle ones move its plane by 0.14° (solvePnP, measured once).
#[test]
fn an_object_hiding_part_of_a_charuco_sheet_leaves_the_rest_named() {
    let mut img = photo();
    let (cx, cy, rx, ry) = (1000.0, 820.0, 170.0, 140.0);
    for y in 0..img.height() {
        for x in 0..img.width() {
            let (dx, dy) = ((f64::from(x) - cx) / rx, (f64::from(y) - cy) / ry);
            if dx * dx + dy * dy <= 1.0 {
                img.put_pixel(x, y, image::Luma([90]));
            }
        }
    }
    let b = board(&board_text()).unwrap();
    let out = board_planes(&img, &b, &camera());
    let fit = out.result.unwrap();
    let theirs = CalibrationFile::load(&data().join("20220331_faa7cdf/calibration.toml"))
        .unwrap()
        .board
        .unwrap();
    for (k, sheet) in [&theirs.left, &theirs.right].iter().enumerate() {
        let n = fit.sheets[k].plane.normal();
        let dot: f64 = (0..3).map(|i| n[i] * sheet.normal[i]).sum();
        let angle = dot.abs().min(1.0).acos().to_degrees();
        println!(
            "sheet {k}: {} of 24 corners used, plane {angle:.4}° off OpenCV's",
            fit.sheets[k].used()
        );
        assert!(angle < [0.05, 0.25][k], "sheet {k}: {angle}°");
    }
    assert_eq!(fit.sheets[0].used(), 24);
    assert!(
        (10..24).contains(&fit.sheets[1].used()),
        "{}",
        fit.sheets[1].used()
    );
}

/// Any picture, of any size, noise or flat or tiny or a plain chessboard: the ChArUco search
/// answers without a panic (the quads at any size, the markers, the corners), and finds no
/// corner where there is no marker.
#[test]
fn any_picture_is_searched_for_charuco_corners_without_a_panic() {
    let board = charuco("DICT_4X4_50");
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for (w, h) in [(1, 1), (7, 7), (8, 8), (9, 200), (300, 3), (120, 90)] {
        for fill in 0..3 {
            let img = GrayImage::from_fn(w, h, |x, y| {
                image::Luma([match fill {
                    0 => (next() & 0xff) as u8,
                    1 => 128,
                    _ => {
                        if (x / 6 + y / 6) % 2 == 0 {
                            0
                        } else {
                            255
                        }
                    }
                }])
            });
            let found = find_charuco(&img, &quads(&img, 0.0), &board);
            assert!(found.corners.is_empty(), "{w}×{h} fill {fill}");
        }
    }
}
