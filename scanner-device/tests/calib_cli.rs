//! The calibration commands from the outside, on rendered rig images: render → intrinsics →
//! board → calibration file; printable sheets at true scale; clear errors with the overlay still
//! written.

use std::path::Path;

use scanner_calib::board::BoardFile;
use scanner_calib::detect::{DetectConfig, find_markers};
use scanner_calib::file::CalibrationFile;

fn run(args: &[&str]) -> (bool, String, String) {
    scanner_tests::run(env!("CARGO_BIN_EXE_scanner-device"), args)
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).display().to_string()
}

#[test]
fn calibrate_the_rig_from_its_images() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ok, _, err) = run(&["render-calibration", "--out", &p(d, "")]);
    assert!(ok, "{err}");
    let grids: Vec<String> = (0..12).map(|i| p(d, &format!("grid-{i:02}.png"))).collect();
    let mut args = vec![
        "calibrate",
        "intrinsics",
        "--out",
        &*Box::leak(p(d, "camera.toml").into_boxed_str()),
    ];
    args.extend(grids.iter().map(String::as_str));
    let (ok, _, err) = run(&args);
    assert!(ok, "{err}");
    let report = json(&d.join("camera-report.json"));
    assert!(
        report["rms_px"].as_f64().is_some_and(|r| r < 0.5),
        "{report}"
    );
    assert_eq!(report["used"], 12, "{report}");
    // The rig's twelve shots sweep the target round the middle of the view: the border stays
    // unsampled, and the report says where.
    let coverage = &report["coverage"];
    assert!(coverage["cells"].as_u64() > Some(0), "{coverage}");
    assert_eq!(coverage["border"], 0, "{coverage}");
    assert_eq!(
        coverage["empty_corners"],
        serde_json::json!(["top left", "top right", "bottom left", "bottom right"]),
        "{coverage}"
    );
    // On rendered shots the lens model is the rig's and the noise independent: the halves
    // agree as the noise predicts (no warning), and the map asks for shots in the corners.
    let halves = &report["self_check"]["halves"];
    assert_eq!(halves["warning"], false, "{halves}");
    assert!(halves["ratio"].as_f64().unwrap() < 2.0, "{halves}");
    let more = report["self_check"]["more_shots"].as_array().unwrap();
    assert!(
        more.iter()
            .any(|r| r["region"].as_str().unwrap().contains(' ')),
        "{more:?}"
    );
    k3_is_fixed_without_the_border(d, &grids, &report);
    let (ok, out, err) = run(&[
        "calibrate",
        "board",
        "--camera",
        &p(d, "camera.toml"),
        "--out",
        &p(d, "calibration.toml"),
        "--overlay",
        &p(d, "overlay.png"),
        &p(d, "board.png"),
    ]);
    assert!(ok, "{err}\n{out}");
    let board = json(&d.join("calibration-report.json"));
    assert_eq!(board["sheets"][0]["side"], "left", "{board}");
    assert_eq!(
        (&board["sheets"][0]["used"], &board["sheets"][0]["markers"]),
        (&serde_json::json!(5), &serde_json::json!(6)),
        "{board}"
    );
    let cal = CalibrationFile::load(&d.join("calibration.toml")).unwrap();
    assert_eq!((cal.image.width, cal.image.height), (640, 480));
    // The file keeps what the head needs for the calibration's share of each point's
    // uncertainty: the intrinsics' covariance (k3 fixed: eight modes) and both sheets' spreads
    // (three modes each).
    let spread = cal.spread().expect("covariances kept").unwrap();
    assert_eq!(spread.modes(), 8 + 3 + 3);
    let board = cal.board().unwrap().unwrap();
    assert!((board.angle().to_degrees() - 90.0).abs() < 0.2);
    let regions = cal.regions.as_ref().unwrap();
    assert!(regions.left.len() >= 4 && regions.object.len() == 6);
    let overlay = image::open(d.join("overlay.png")).unwrap();
    assert_eq!((overlay.width(), overlay.height()), (640, 480));

    // The paper's procedure on the rendered crosses (tape readings 25 mm long).
    let (ok, out, err) = run(&[
        "calibrate",
        "distance",
        "--near",
        &p(d, "cross-near.png"),
        "--near-mm",
        "525",
        "--far",
        &p(d, "cross-far.png"),
        "--far-mm",
        "925",
        "--out",
        &p(d, "paper.toml"),
    ]);
    assert!(ok, "{err}");
    let paper = CalibrationFile::load(&d.join("paper.toml")).unwrap();
    assert!((paper.camera.fx / 560.0 - 1.0).abs() < 0.005, "{out}");

    // A camera calibrated at another size.
    let mut other = CalibrationFile::load(&d.join("camera.toml")).unwrap();
    other.image.width = 1280;
    other.image.height = 960;
    other.save(&d.join("other.toml")).unwrap();
    let (ok, _, err) = run(&[
        "calibrate",
        "board",
        "--camera",
        &p(d, "other.toml"),
        "--out",
        &p(d, "x.toml"),
        &p(d, "board.png"),
    ]);
    assert!(!ok);
    assert!(scanner_tests::has_kind(&err, "ImageSize"), "{err}");

    // No board in the image: a clear error, and the overlay is still written.
    image::GrayImage::from_pixel(640, 480, image::Luma([170]))
        .save(d.join("wall.png"))
        .unwrap();
    let (ok, _, err) = run(&[
        "calibrate",
        "board",
        "--camera",
        &p(d, "camera.toml"),
        "--out",
        &p(d, "y.toml"),
        "--overlay",
        &p(d, "wall-overlay.png"),
        &p(d, "wall.png"),
    ]);
    assert!(!ok);
    assert!(scanner_tests::has_kind(&err, "NoMarkers"), "{err}");
    assert!(d.join("wall-overlay.png").exists() && !d.join("y.toml").exists());

    // A board file that is not one.
    std::fs::write(d.join("bad.toml"), "marker_diameter = -3\n").unwrap();
    let (ok, _, err) = run(&[
        "calibrate",
        "board",
        "--board",
        &p(d, "bad.toml"),
        "--camera",
        &p(d, "camera.toml"),
        &p(d, "board.png"),
    ]);
    assert!(!ok);
    assert!(scanner_tests::has_kind(&err, "BoardFile"), "{err}");
}

/// With no feature on the image's border `calibrate intrinsics` fixes k3 at 0 and says so, and
/// the lens's distortion it finds is then right out where the board's markers and stripes lie
/// (0.5–0.6 of the focal length from the centre), where a fit with k3 free extrapolates worse.
fn k3_is_fixed_without_the_border(d: &Path, grids: &[String], report: &serde_json::Value) {
    assert_eq!(report["k3_fixed"], true, "{report}");
    assert_eq!(report["camera"]["k3"], 0.0, "{report}");
    let found = CalibrationFile::load(&d.join("camera.toml"))
        .unwrap()
        .camera()
        .unwrap();
    let truth = CalibrationFile::load(&d.join("truth-calibration.toml"))
        .unwrap()
        .camera()
        .unwrap();
    assert_eq!(found.distortion().k3, 0.0);
    let images: Vec<image::GrayImage> = grids
        .iter()
        .map(|g| image::open(g).unwrap().to_luma8())
        .collect();
    let target = scanner_calib::Target::Dots(scanner_calib::DotGrid::RIG);
    let free = scanner_calib::intrinsics(&images, &target, scanner_core::calib::Free::ALL)
        .unwrap()
        .camera;
    // The radial displacement at `r` (a ray's slope from the axis), pixels.
    let radial = |c: &scanner_core::Camera<f64>, r: f64| {
        let k = c.distortion();
        r * (k.k1 * r * r + k.k2 * r.powi(4) + k.k3 * r.powi(6)) * c.fx()
    };
    for r in [0.5, 0.6] {
        let (fixed, all) = (
            (radial(&found, r) - radial(&truth, r)).abs(),
            (radial(&free, r) - radial(&truth, r)).abs(),
        );
        println!("distortion at {r}: {fixed:.3} px off with k3 fixed, {all:.3} px with k3 free");
        assert!(
            fixed < 0.15 && fixed < all,
            "at {r}: {fixed} px fixed, {all} px free"
        );
    }
}

#[test]
fn printed_sheets_are_true_to_scale() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ok, _, err) = run(&["board", "--out", &p(d, ""), "--dpi", "100"]);
    assert!(ok, "{err}");
    let board = BoardFile::load(&d.join("board.toml")).unwrap();
    assert_eq!(board, BoardFile::default());
    let px_per_mm = 100.0 / 25.4;
    for (name, k) in [("left-sheet", 0), ("right-sheet", 1)] {
        let img = image::open(d.join(format!("{name}.png")))
            .unwrap()
            .to_luma8();
        assert_eq!(img.width(), (board.sheet.width * px_per_mm).round() as u32);
        let svg = std::fs::read_to_string(d.join(format!("{name}.svg"))).unwrap();
        assert!(svg.contains("width=\"420mm\"") && svg.contains("r=\"13.750\""));
        // The printed discs, found by the detector, sit where the layout says.
        // (The title's letters are small dark blobs too: keep marker-sized ones.)
        let disc = std::f64::consts::PI * (board.marker_diameter / 2.0 * px_per_mm).powi(2);
        let mut det = find_markers(&img, &DetectConfig::default());
        det.blobs.retain(|b| b.area > 0.5 * disc);
        let layout = if k == 0 {
            board.left.points()
        } else {
            board.right.points()
        };
        assert_eq!(det.blobs.len(), layout.len(), "{name}");
        for q in layout {
            let u = if k == 0 { board.sheet.width - q.x } else { q.x };
            let (x, y) = (
                u * px_per_mm - 0.5,
                (board.sheet.height / 2.0 + q.y) * px_per_mm - 0.5,
            );
            let best = det
                .blobs
                .iter()
                .map(|b| ((b.centre.x - x).powi(2) + (b.centre.y - y).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min);
            assert!(best < 0.05, "{name}: marker at ({x}, {y}) off by {best} px");
        }
    }
    assert!(d.join("cross.svg").exists() && d.join("cross.png").exists());
    // The printed intrinsics target is the grid `calibrate intrinsics` looks for, at its size.
    let target = image::open(d.join("target.png")).unwrap().to_luma8();
    let view = scanner_calib::find_grid(
        &target,
        &scanner_calib::Target::Dots(scanner_calib::DotGrid::RIG),
    )
    .expect("the printed target's grid");
    assert!(view.complete && view.found.len() == 63, "{view:?}");
}

#[test]
fn a_board_file_with_a_chessboard_sheet_end_to_end() {
    // The scene prints the board file's layout; calibration reads the same file.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut board = BoardFile::default();
    board.right.grid = None;
    board.right.chessboard = Some(scanner_calib::board::Chessboard {
        cols: 8,
        rows: 8,
        square: 30.0,
        u0: 60.0,
        v0: -90.0,
    });
    std::fs::write(d.join("board.toml"), board.to_toml().unwrap()).unwrap();
    std::fs::write(
        d.join("scene.toml"),
        "objects = []\n[board]\nlayout = \"board.toml\"\n",
    )
    .unwrap();
    let (ok, _, err) = run(&[
        "render-calibration",
        "--scene",
        &p(d, "scene.toml"),
        "--out",
        &p(d, "cal"),
    ]);
    assert!(ok, "{err}");
    // The true camera of the demo scene at 640×480, written as a camera file.
    let cam = scanner_rig::Scene::demo(640, 480).camera;
    CalibrationFile::from_camera(&cam, (640, 480), "the rig's camera".into(), None)
        .save(&d.join("camera.toml"))
        .unwrap();
    let (ok, out, err) = run(&[
        "calibrate",
        "board",
        "--board",
        &p(d, "board.toml"),
        "--camera",
        &p(d, "camera.toml"),
        "--out",
        &p(d, "calibration.toml"),
        "--overlay",
        &p(d, "overlay.png"),
        &p(d, "cal/board.png"),
    ]);
    assert!(ok, "{err}\n{out}");
    let board = json(&d.join("calibration-report.json"));
    assert_eq!(board["sheets"][1]["side"], "right", "{board}");
    assert_eq!(
        (&board["sheets"][1]["used"], &board["sheets"][1]["markers"]),
        (&serde_json::json!(49), &serde_json::json!(49)),
        "{board}"
    );
    // The printed sheet shows the squares.
    let (ok, _, err) = run(&[
        "board",
        "--board",
        &p(d, "board.toml"),
        "--out",
        &p(d, "print"),
    ]);
    assert!(ok, "{err}");
    assert!(
        std::fs::read_to_string(d.join("print/right-sheet.svg"))
            .unwrap()
            .matches("<rect")
            .count()
            > 32
    );
}

#[test]
fn a4_tiles_cover_every_marker_of_the_a3_sheets() {
    use scanner_calib::print::{a4_tiles, sheets};
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_scanner-device"))
        .args(["board", "--a4", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for (stem, sheet) in sheets(&BoardFile::default()) {
        let tiles = a4_tiles(&sheet);
        // A3 (420×297) on A4 landscape with margins and overlaps: 2×2 tiles.
        assert_eq!(tiles.len(), 4, "{stem}");
        for t in &tiles {
            let path = dir
                .path()
                .join(format!("{stem}-a4-{}-{}.svg", t.at.0 + 1, t.at.1 + 1));
            let svg = std::fs::read_to_string(&path).unwrap();
            assert!(
                svg.contains("width=\"297mm\" height=\"210mm\""),
                "{}",
                path.display()
            );
            assert!(svg.contains("measure this 100 mm bar") && svg.contains("of 2x2"));
            let [_, _, w, h] = t.area;
            assert!(
                w <= 277.0 && h <= 190.0,
                "a tile larger than an A4 page's print area"
            );
        }
        // Every disc (or square) lies whole inside some tile: nothing is lost at a cut.
        let shapes = sheet
            .dots
            .iter()
            .map(|&(x, y, d)| (x - d / 2.0, y - d / 2.0, d))
            .chain(sheet.squares.iter().copied());
        for (x, y, side) in shapes {
            assert!(
                tiles.iter().any(|t| {
                    let [x0, y0, w, h] = t.area;
                    x >= x0 && y >= y0 && x + side <= x0 + w && y + side <= y0 + h
                }),
                "{stem}: a mark at ({x}, {y}) is cut by every tile"
            );
        }
    }
}

#[test]
fn render_calibration_takes_3_to_64_shots() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for bad in ["2", "65", "-1", "many"] {
        let shots = format!("--shots={bad}");
        let (ok, _, err) = run(&["render-calibration", "--out", &p(d, ""), &shots]);
        assert!(
            !ok && scanner_tests::has_kind(&err, "Usage"),
            "--shots {bad}: {err}"
        );
    }
    assert!(
        std::fs::read_dir(d).unwrap().next().is_none(),
        "nothing written on bad input"
    );
    let (ok, _, err) = run(&["render-calibration", "--out", &p(d, ""), "--shots", "3"]);
    assert!(ok, "{err}");
    assert!(d.join("grid-02.png").exists() && !d.join("grid-03.png").exists());
}

/// A JSON report a command wrote.
fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// The paper's large set-up (sheets of 1.68 × 1.25 m, markers 480 mm apart, the board at
/// 3.2 m) is a board file like any other: it prints, and calibrates from its image; a sheet
/// whose picture would pass the limit is refused naming `--dpi`.
#[test]
fn the_papers_large_set_up_is_a_board_like_any_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scene, board) = scanner_tests::accuracy::scene(1280, 960, 3200.0, 4);
    assert!(board.sheet.width > 1500.0, "{:?}", board.sheet);
    std::fs::write(d.join("big.toml"), board.to_toml().unwrap()).unwrap();
    let (ok, _, err) = run(&[
        "board",
        "--board",
        &p(d, "big.toml"),
        "--out",
        &p(d, "print"),
        "--dpi",
        "25",
    ]);
    assert!(ok, "{err}");
    // A sheet of 9 m prints only at a resolution that keeps its picture within the limit.
    let mut huge = board.clone();
    huge.sheet.width = 9000.0;
    std::fs::write(d.join("huge.toml"), huge.to_toml().unwrap()).unwrap();
    let (ok, _, err) = run(&["board", "--board", &p(d, "huge.toml"), "--out", &p(d, "x")]);
    assert!(!ok && scanner_tests::has_kind(&err, "PngTooLarge"), "{err}");
    let rig = scanner_rig::Rig::new(scene).unwrap();
    rig.reference()
        .to_gray_image()
        .save(d.join("board.png"))
        .unwrap();
    rig.truth_calibration()
        .save(&d.join("camera.toml"))
        .unwrap();
    let (ok, out, err) = run(&[
        "calibrate",
        "board",
        "--board",
        &p(d, "big.toml"),
        "--camera",
        &p(d, "camera.toml"),
        "--out",
        &p(d, "calibration.toml"),
        &p(d, "board.png"),
    ]);
    assert!(ok, "{err}\n{out}");
    let cal = CalibrationFile::load(&d.join("calibration.toml")).unwrap();
    let got = cal.board().unwrap().unwrap();
    let truth = rig.board_planes();
    for (g, t) in [got.left(), got.right()].iter().zip(&truth) {
        assert!(
            g.normal().angle(t.normal()).to_degrees() < 0.1
                && (g.offset() - t.offset()).abs() < 0.002 * 3200.0,
            "{g:?} {t:?}"
        );
    }
}

/// `calibrate intrinsics --charuco` from the outside: eight rendered shots of a ChArUco board
/// (640×480) give a camera close to the rig's, every shot used; the ChArUco options without a
/// marker side, with a marker as large as the square, or with a dictionary OpenCV does not have
/// are refused with what to give.
#[test]
fn calibrate_intrinsics_from_charuco_shots() {
    use scanner_calib::aruco::{CharucoBoard, Dictionary};
    use scanner_rig::target::{Pattern, TargetPose};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut scene = scanner_rig::Scene::demo(640, 480);
    scene.sensor.read_noise = 2.0;
    let rig = scanner_rig::Rig::new(scene).unwrap();
    let board = CharucoBoard {
        cols: 9,
        rows: 7,
        square: 30.0,
        marker: 22.0,
        dictionary: Dictionary::named("DICT_5X5_100").unwrap(),
        first_id: 0,
    };
    let mut shots = Vec::new();
    for i in 0..8 {
        let mut pose = TargetPose::sweep(i, 8);
        pose.centre.z *= 0.7;
        let name = p(d, &format!("charuco-{i}.png"));
        rig.shot(&Pattern::Charuco(board), &pose, i as u64)
            .image
            .to_gray_image()
            .save(&name)
            .unwrap();
        shots.push(name);
    }
    let out = p(d, "camera.toml");
    let base = [
        "calibrate",
        "intrinsics",
        "--charuco",
        "9x7",
        "--square",
        "30",
        "--out",
        out.as_str(),
    ];
    let with = |extra: &[&str]| {
        let mut args: Vec<&str> = base.to_vec();
        args.extend_from_slice(extra);
        args.extend(shots.iter().map(String::as_str));
        run(&args)
    };
    let (ok, _, err) = with(&["--marker", "22", "--dictionary", "DICT_5X5_100"]);
    assert!(ok, "{err}");
    let report = json(&d.join("camera-report.json"));
    assert_eq!(report["used"], 8, "{report}");
    let fx = report["camera"]["fx"].as_f64().unwrap();
    let truth = rig.scene().camera.fx();
    println!(
        "ChArUco through the command line: fx {fx:.2} (rig {truth:.2}), rms {}",
        report["rms_px"]
    );
    assert!((fx / truth - 1.0).abs() < 0.005, "fx {fx} against {truth}");
    for (extra, says) in [
        (&["--dictionary", "DICT_5X5_100"][..], "--marker"),
        (
            &["--marker", "30", "--dictionary", "DICT_5X5_100"][..],
            "smaller than its square",
        ),
        (
            &["--marker", "22", "--dictionary", "DICT_9X9_50"][..],
            "predefined",
        ),
    ] {
        let (ok, _, err) = with(extra);
        assert!(!ok && err.contains(says), "{extra:?}: {err}");
    }
}
