//! The accuracy report (the paper's Table 3) as a test harness, so that the report command and a
//! quick test run the same code: the paper's setup on the virtual rig at several distances —
//! calibrate from rendered images, scan two spheres and a tilted plane, measure.
//!
//! `cargo run --release -p scanner-tests --example accuracy_report` prints it.

use scanner_calib::board::{BoardFile, Cross, MarkerGrid, SheetLayout, SheetSize};
use scanner_calib::{DotGrid, Target, board_planes, intrinsics_auto};
use scanner_core::Camera;
use scanner_core::geometry::Board;
use scanner_core::nalgebra::{Matrix4, Point2, Point3, Unit, Vector3, Vector4};
use scanner_core::pipeline::{Head, HeadConfig};
use scanner_core::stripe::{Axis, Extractor, Frame, Method, PixelFormat, StripeConfig};
use scanner_rig::{Object, Rig, Scene, Shape};
use scanner_wire::points::dequantise;

/// The paper's mean errors (mm) at 280, 400, 800, 1600 and 3200 mm.
pub const PAPER_MEAN_MM: [(f64, f64); 5] = [
    (280.0, 0.16),
    (400.0, 0.24),
    (800.0, 0.49),
    (1600.0, 0.99),
    (3200.0, 1.97),
];

/// The laser's strength against the sensor's noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Light {
    /// The scene's laser and sensor.
    Normal,
    /// More sensor noise: a weak stripe (see [`run_distance`]).
    Weak,
}

/// One row of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Camera–board distance, mm.
    pub distance: f64,
    /// "layout" or "paper".
    pub board: &'static str,
    /// The laser's strength against the sensor's noise.
    pub light: Light,
    /// Points measured.
    pub points: usize,
    /// Mean point-to-surface error, mm.
    pub mean_mm: f64,
    /// 99th percentile, mm.
    pub p99_mm: f64,
    /// Sphere diameter errors, mm (each sphere).
    pub diameter_mm: [f64; 2],
    /// Sphere-centre spacing error, mm.
    pub spacing_mm: f64,
    /// Flatness of the tilted plate: peak to valley of the residuals about the fitted plane over
    /// its inner 90 %, the 0.3 % largest left out, mm.
    pub flatness_mm: f64,
    /// Share of the points with an error above 0.1 % of the distance that lie on the plate's
    /// outer 3 % rim, %.
    pub rim_pct: f64,
    /// Object points within 0.1 % of the distance of their surface, over those a plain centroid
    /// of every column's signal (above the same threshold) triangulated with the *true* camera
    /// and laser plane gives, %.
    pub coverage_pct: f64,
    /// Points sent as object points that lie on the board (nearer a board sheet than any
    /// object), and the median of their distances from it, mm.
    pub board_sent: (usize, f64),
}

/// The board file of the paper's layout with marker spacing `s` (mm).
pub fn paper_board(s: f64) -> BoardFile {
    let grid = MarkerGrid {
        cols: 3,
        rows: 2,
        u0: 0.6 * s,
        v0: -s,
        du: s,
        dv: 2.0 * s,
    };
    let sheet = SheetLayout {
        markers: None,
        grid: Some(grid),
        chessboard: None,
        charuco: None,
    };
    BoardFile {
        marker_diameter: 0.25 * s,
        sheet: SheetSize {
            width: 3.5 * s,
            height: 2.6 * s,
        },
        left: sheet.clone(),
        right: sheet,
        cross: Cross {
            arm: 200.0,
            dot: 12.0,
        },
    }
}

/// The scene at distance `d`: the paper's board (marker spacing `d/6.67`, 40 mm at 280), two
/// spheres and a tilted plane between the marker rows, a hand-held laser sweeping over them.
pub fn scene(width: u32, height: u32, d: f64, frames: usize) -> (Scene, BoardFile) {
    let s = if d <= 300.0 { d / 7.0 } else { d * 0.15 };
    let board = paper_board(s);
    let mut sc = Scene::demo(width, height);
    sc.board.distance = d;
    sc.board.markers = (&board).into();
    let sphere = |x: f64, y: f64, z: f64| Object {
        shape: Shape::Sphere {
            centre: Point3::new(x * d, y * d, z * d),
            radius: 0.055 * d,
        },
        albedo: [0.7, 0.65, 0.6],
        texture: None,
    };
    // Tilted back (facing up, towards the laser held above the camera).
    let tilt = Unit::new_normalize(Vector3::new(0.0, -(0.5f64.sin()), -0.5f64.cos()));
    let ex = Vector3::x();
    let ey = tilt.cross(&ex).normalize();
    sc.objects = vec![
        sphere(-0.14, 0.02, 0.62),
        sphere(0.0, 0.03, 0.6),
        Object {
            shape: Shape::Rectangle {
                centre: Point3::new(0.14 * d, 0.02 * d, 0.62 * d),
                axes: [ex, ey],
                half: [0.045 * d, 0.06 * d],
            },
            albedo: [0.75, 0.75, 0.75],
            texture: None,
        },
    ];
    sc.laser.source = Point3::new(0.025 * d, -0.19 * d, 0.04 * d);
    sc.laser.sweep = (-0.16 * d, 0.2 * d);
    sc.laser.frames = frames;
    sc.laser.jitter_mm = 0.0025 * d;
    sc.laser.sigma_mm = 0.00075 * d;
    (sc, board)
}

/// Intrinsics from 12 rendered dot-grid images of the demo camera at this size, as `calibrate
/// intrinsics` finds them, and whether `k3` was fixed (no shot reaching the image's border).
pub fn calibrate_camera(width: u32, height: u32) -> (Camera<f64>, bool) {
    let rig = Rig::new(Scene::demo(width, height)).expect("demo rig");
    let grid = DotGrid::RIG;
    let images = rig.dot_grid_shots(&grid, 12);
    let (outcome, k3_fixed) = intrinsics_auto(&images, &Target::Dots(grid));
    (outcome.into_fit().expect("intrinsics").camera, k3_fixed)
}

/// Least-squares sphere (algebraic, then the radius from the centre): centre and radius.
pub fn fit_sphere(pts: &[Point3<f64>]) -> Option<(Point3<f64>, f64)> {
    // x² + y² + z² + D x + E y + F z + G = 0
    let mut ata = Matrix4::<f64>::zeros();
    let mut atb = Vector4::<f64>::zeros();
    for p in pts {
        let row = Vector4::new(p.x, p.y, p.z, 1.0);
        ata += row * row.transpose();
        atb += row * -(p.coords.norm_squared());
    }
    let sol = ata.cholesky()?.solve(&atb);
    let c = Point3::new(-sol[0] / 2.0, -sol[1] / 2.0, -sol[2] / 2.0);
    let r2 = c.coords.norm_squared() - sol[3];
    (r2 > 0.0).then(|| (c, r2.sqrt()))
}

/// Flatness of the plate in the manner of the independent measurement: the points over the
/// inner 90 % of the plate (each half size × 0.9), the range of their residuals about their
/// least-squares plane after leaving out the 0.3 % largest (VDI/VDE 2634-2 allows 0.3 %), mm;
/// and how many points that kept.
fn plate_flatness(pts: &[Point3<f64>], plate: &Shape) -> (f64, usize) {
    let Shape::Rectangle { centre, axes, half } = plate else {
        return (f64::NAN, 0);
    };
    let inner: Vec<Point3<f64>> = pts
        .iter()
        .copied()
        .filter(|p| {
            let v = p - centre;
            (0..2).all(|k| v.dot(&axes[k]).abs() <= 0.9 * half[k])
        })
        .collect();
    let Ok(f) = scanner_core::geometry::fit_plane(inner.iter().copied()) else {
        return (f64::NAN, 0);
    };
    let mut r: Vec<f64> = inner.iter().map(|p| f.plane.signed_distance(p)).collect();
    r.sort_by(f64::total_cmp);
    // trim 0.3 % in all, from whichever end lies further from the median
    let mut trim = r.len() * 3 / 1000;
    let (mut lo, mut hi) = (0, r.len());
    let med = r.get(r.len() / 2).copied().unwrap_or(0.0);
    while trim > 0 && hi > lo + 1 {
        if (r[hi - 1] - med) > (med - r[lo]) {
            hi -= 1;
        } else {
            lo += 1;
        }
        trim -= 1;
    }
    let kept = &r[lo..hi];
    match (kept.first(), kept.last()) {
        (Some(a), Some(b)) => (b - a, kept.len()),
        _ => (f64::NAN, 0),
    }
}

/// Share of `bad` (points with an error above 0.1 % of the distance `d`) that lie on the plate's
/// rim: within 1 % of the distance of its plane, and projected within the outer 3 % of its size
/// from an edge (or up to 3 % outside it), %.
fn rim_share(bad: &[Point3<f64>], plate: &Shape, d: f64) -> f64 {
    let Shape::Rectangle { centre, axes, half } = plate else {
        return f64::NAN;
    };
    if bad.is_empty() {
        return 0.0;
    }
    let normal = axes[0].cross(&axes[1]);
    let on_rim = bad
        .iter()
        .filter(|p| {
            let v = *p - centre;
            let u = [0, 1].map(|k| v.dot(&axes[k]).abs() / half[k]);
            v.dot(&normal).abs() < 0.01 * d
                && u.iter().all(|&x| x <= 1.06)
                && u.iter().any(|&x| x >= 0.94)
        })
        .count();
    100.0 * on_rim as f64 / bad.len() as f64
}

/// Object columns over the sweep where a plain centroid finds the stripe within 0.1 % of the
/// distance `d` of the truth, triangulated with the true camera and laser plane: per column the
/// largest difference-image sample, if above the extractor's automatic threshold, and the
/// centroid of the contiguous run above half of it. The yardstick of the head's coverage.
fn naive_coverage(rig: &Rig, rendered: &[Vec<u8>], reference: &[u8], d: f64) -> usize {
    let scene = rig.scene();
    let (w, h) = (scene.width as usize, scene.height as usize);
    let objects: Vec<&Shape> = scene.objects.iter().map(|o| &o.shape).collect();
    let board = rig.board_planes();
    let ref_frame = Frame::packed(reference, w, h, PixelFormat::Gray8).expect("reference");
    let mut ex = Box::new(Extractor::<4096>::new());
    let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    let mut count = 0;
    for (k, data) in rendered.iter().enumerate() {
        let f = Frame::packed(data, w, h, PixelFormat::Gray8).expect("frame");
        let threshold = ex
            .extract(&f, Some(&ref_frame), &cfg)
            .map_or(u16::MAX, |e| e.threshold);
        let Ok((_, plane)) = rig.laser(k) else {
            continue;
        };
        for x in 0..w {
            let sig = |y: usize| i32::from(data[y * w + x]) - i32::from(reference[y * w + x]);
            let top = (0..h).max_by_key(|&y| sig(y)).unwrap_or(0);
            let peak = sig(top);
            if peak < i32::from(threshold) {
                continue;
            }
            let (mut a, mut b) = (top, top);
            while a > 0 && 2 * sig(a - 1) > peak {
                a -= 1;
            }
            while b + 1 < h && 2 * sig(b + 1) > peak {
                b += 1;
            }
            let (num, den) = (a..=b).fold((0.0, 0.0), |(n, m), y| {
                let v = f64::from(sig(y));
                (n + v * y as f64, m + v)
            });
            let px = Point2::new(x as f64, num / den);
            let Ok(ray) = scene.camera.pixel_to_ray(&px) else {
                continue;
            };
            let Ok(p) = plane.intersect_ray(&ray, 0.01) else {
                continue;
            };
            let to_object = objects
                .iter()
                .filter_map(|o| o.distance(&p))
                .fold(f64::INFINITY, f64::min);
            let to_board = board
                .iter()
                .map(|pl| pl.signed_distance(&p).abs())
                .fold(f64::INFINITY, f64::min);
            if to_object <= 0.001 * d && to_object < to_board {
                count += 1;
            }
        }
    }
    count
}

/// Runs the report at distance `d` for both board constructions.
pub fn run_distance(
    camera: &Camera<f64>,
    width: u32,
    height: u32,
    d: f64,
    frames: usize,
    light: Light,
) -> Vec<Row> {
    let (mut scene, board) = scene(width, height, d, frames);
    if light == Light::Weak {
        // the independent measurement's weak case: a stripe about 30 DN above the background
        // (this scene's already is at 3200 mm) in noise of σ ≈ 3 DN (read noise 2.4 DN with the
        // shot noise of the lit board, against 1.5 DN)
        scene.sensor.read_noise = 2.4;
    }
    let rig = Rig::new(scene.clone()).expect("rig");
    let reference = rig.reference();
    let outcome = board_planes(&reference.to_gray_image(), &board, camera);
    let fit = outcome
        .result
        .expect("board calibration from the rendered board");
    let mut boards = vec![(
        "layout",
        Board::new(fit.sheets[0].plane, fit.sheets[1].plane).expect("board"),
    )];
    if let [Some(l), Some(r)] = fit.paper {
        boards.push(("paper", Board::new(l, r).expect("paper board")));
    }
    let refg = reference.to_format(PixelFormat::Gray8);
    let (w, h) = (width as usize, height as usize);
    let ref_frame =
        scanner_core::stripe::Frame::packed(&refg, w, h, PixelFormat::Gray8).expect("frame");
    let rendered: Vec<Vec<u8>> = (0..frames)
        .map(|k| rig.frame(k).expect("frame").to_format(PixelFormat::Gray8))
        .collect();
    let truth_objects: Vec<Shape> = scene.objects.iter().map(|o| o.shape.clone()).collect();
    let board_truth = rig.board_planes();
    let naive = naive_coverage(&rig, &rendered, &refg, d);
    let mut rows = Vec::new();
    for (name, b) in boards {
        let mut head = Box::new(Head::<4096>::new(
            camera.cast(),
            b.cast(),
            HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        ));
        let mut pts: Vec<Point3<f64>> = Vec::new();
        for data in &rendered {
            let f =
                scanner_core::stripe::Frame::packed(data, w, h, PixelFormat::Gray8).expect("frame");
            if let Ok(out) = head.process(&f, Some(&ref_frame)) {
                pts.extend(out.points.iter().map(|q| {
                    Point3::new(
                        f64::from(dequantise(q[0])),
                        f64::from(dequantise(q[1])),
                        f64::from(dequantise(q[2])),
                    )
                }));
            }
        }
        // Each point to its object (the nearest true surface).
        let mut errs = Vec::new();
        let mut per: Vec<Vec<Point3<f64>>> = vec![Vec::new(); truth_objects.len()];
        for p in &pts {
            let (k, dist) = truth_objects
                .iter()
                .enumerate()
                .map(|(k, s)| (k, s.distance(p).unwrap_or(f64::INFINITY)))
                .fold((0, f64::INFINITY), |a, x| if x.1 < a.1 { x } else { a });
            errs.push(rig.surface_distance(p));
            if dist < 0.01 * d {
                per[k].push(*p);
            }
        }
        let errs_unsorted = errs.clone();
        errs.sort_by(f64::total_cmp);
        let mean = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
        let p99 = errs.get(errs.len() * 99 / 100).copied().unwrap_or(f64::NAN);
        let sphere_truth = |k: usize| match &truth_objects[k] {
            Shape::Sphere { centre, radius } => (*centre, *radius),
            _ => (Point3::origin(), f64::NAN),
        };
        let fits: Vec<Option<(Point3<f64>, f64)>> = (0..2).map(|k| fit_sphere(&per[k])).collect();
        let diameter =
            [0, 1].map(|k| fits[k].map_or(f64::NAN, |(_, r)| 2.0 * (r - sphere_truth(k).1)));
        let spacing = match (fits[0], fits[1]) {
            (Some((a, _)), Some((b, _))) => {
                (a - b).norm() - (sphere_truth(0).0 - sphere_truth(1).0).norm()
            }
            _ => f64::NAN,
        };
        let (flatness, _) = plate_flatness(&per[2], &truth_objects[2]);
        let bad: Vec<Point3<f64>> = pts
            .iter()
            .zip(&errs_unsorted)
            .filter(|(_, e)| **e > 0.001 * d)
            .map(|(p, _)| *p)
            .collect();
        let rim = rim_share(&bad, &truth_objects[2], d);
        let board_dist = |p: &Point3<f64>| {
            board_truth
                .iter()
                .map(|pl| pl.signed_distance(p).abs())
                .fold(f64::INFINITY, f64::min)
        };
        let object_dist = |p: &Point3<f64>| {
            truth_objects
                .iter()
                .filter_map(|o| o.distance(p))
                .fold(f64::INFINITY, f64::min)
        };
        let good_objects = pts
            .iter()
            .filter(|p| object_dist(p) <= 0.001 * d && object_dist(p) < board_dist(p))
            .count();
        let mut on_board: Vec<f64> = pts
            .iter()
            .filter(|p| board_dist(p) < object_dist(p))
            .map(board_dist)
            .collect();
        on_board.sort_by(f64::total_cmp);
        let board_sent = (
            on_board.len(),
            on_board.get(on_board.len() / 2).copied().unwrap_or(0.0),
        );
        rows.push(Row {
            distance: d,
            board: name,
            light,
            points: pts.len(),
            mean_mm: mean,
            p99_mm: p99,
            diameter_mm: diameter,
            spacing_mm: spacing,
            flatness_mm: flatness,
            rim_pct: rim,
            coverage_pct: 100.0 * good_objects as f64 / naive.max(1) as f64,
            board_sent,
        });
    }
    rows
}

/// The report as a Markdown table.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| distance | board planes | points | mean error | p99 error | sphere diameter error | sphere spacing error | plate flatness (inner 90 %) | bad points on the plate's rim | coverage of a plain centroid's | board points sent (median off the board) | paper's mean error |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let pct = |v: f64| 100.0 * v / r.distance;
        let paper = PAPER_MEAN_MM
            .iter()
            .find(|(d, _)| *d == r.distance)
            .map_or("—".to_string(), |(d, m)| {
                format!("{m} mm ({:.3} %)", 100.0 * m / d)
            });
        s += &format!(
            "| {} mm{} | {} | {} | {:.3} mm ({:.4} %) | {:.3} mm ({:.4} %) | {:+.3} / {:+.3} mm ({:.4} %) | {:+.3} mm ({:.4} %) | {:.3} mm ({:.3} %) | {:.0} % | {:.0} % | {} ({:.2} mm) | {paper} |\n",
            r.distance,
            if r.light == Light::Weak {
                ", weak laser"
            } else {
                ""
            },
            r.board,
            r.points,
            r.mean_mm,
            pct(r.mean_mm),
            r.p99_mm,
            pct(r.p99_mm),
            r.diameter_mm[0],
            r.diameter_mm[1],
            pct(r.diameter_mm[0].abs().max(r.diameter_mm[1].abs())),
            r.spacing_mm,
            pct(r.spacing_mm.abs()),
            r.flatness_mm,
            pct(r.flatness_mm),
            r.rim_pct,
            r.coverage_pct,
            r.board_sent.0,
            r.board_sent.1,
        );
    }
    s
}

/// Runs a head built with the rig's true calibration and `cfg` over every laser frame of `rig`
/// (gray, with the rig's laser-off reference), handing `each` the frame number and the points
/// (mm, camera frame) with their coded uncertainties of each frame that gave points: the edge,
/// fringe and uncertainty tests measure the head this way, with only the stripe left to err.
pub fn scan_truth(rig: &Rig, cfg: HeadConfig, each: impl FnMut(usize, &[(Point3<f64>, u8)])) {
    let cal = rig.truth_calibration();
    let mut head = Box::new(Head::<4096>::new(
        cal.camera().expect("the rig's camera").cast(),
        cal.board()
            .expect("the rig's board")
            .expect("two planes")
            .cast(),
        cfg,
    ));
    scan_with(rig, &mut head, each);
}

/// Runs `head` over every laser frame of `rig` as [`scan_truth`] does.
pub fn scan_with(
    rig: &Rig,
    head: &mut Head<4096>,
    mut each: impl FnMut(usize, &[(Point3<f64>, u8)]),
) {
    let scene = rig.scene();
    let (w, h) = (scene.width as usize, scene.height as usize);
    let reference = rig.reference().to_format(PixelFormat::Gray8);
    let rf = Frame::packed(&reference, w, h, PixelFormat::Gray8).expect("reference");
    let mut pts = Vec::new();
    for k in 0..scene.laser.frames {
        let data = rig
            .frame(k)
            .expect("a rig frame")
            .to_format(PixelFormat::Gray8);
        let f = Frame::packed(&data, w, h, PixelFormat::Gray8).expect("frame");
        let Ok(o) = head.process(&f, Some(&rf)) else {
            continue;
        };
        pts.clear();
        pts.extend(
            o.points
                .iter()
                .zip(o.uncertainty)
                .map(|(q, &u)| (Point3::from(q.map(|v| f64::from(dequantise(v)))), u)),
        );
        each(k, &pts);
    }
}
